//! The JSON report: per primitive, what was done or skipped and why, the core's diagnostics, and
//! for kept tangents an audit against MikkTSpace. Field names are snake_case and stable; counts
//! come with the first few offending indices so that a user can find them in a viewer.

use serde::Serialize;
use tspace_tangent::{Diagnostics, FallbackCounts, Tally};

/// The report of one scene.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Report {
    pub tspace_version: &'static str,
    /// `glb`, `gltf` or `obj`.
    pub input_format: &'static str,
    /// The input's size: the file, plus the external buffers it referenced and the external
    /// images the output now embeds.
    pub input_bytes: u64,
    /// `glb` or `gltf`; absent when no scene was written (analysis only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub output_format: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub output_bytes: Option<u64>,
    pub method: &'static str,
    pub overwrite: bool,
    pub all: bool,
    pub summary: Summary,
    pub primitives: Vec<PrimitiveReport>,
    /// Accessors and buffer views the output no longer has because nothing references them
    /// after the split replaced them.
    pub dropped: Dropped,
    /// Scene-level notes: images that could not be embedded, extensions removed, conversion
    /// notes for OBJ input.
    pub warnings: Vec<String>,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct Summary {
    pub primitives: u64,
    pub generated: u64,
    pub audited: u64,
    pub skipped: u64,
    /// Distinct geometry computed (primitives that share accessors share one computation).
    pub computations: u64,
    pub triangles: u64,
    pub vertices_added: u64,
    pub fallback_tangents: u64,
    pub handedness_flip_vertices: u64,
    pub degenerate_triangles: u64,
    pub mirrored_uv_triangles: u64,
    /// Audited primitives whose tangents disagree with MikkTSpace (w or more than 1°).
    pub audits_disagreeing: u64,
    /// Bytes of the buffer views the meshes read, compressed ones at their compressed size.
    pub mesh_bytes_in: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh_bytes_out: Option<u64>,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct Dropped {
    pub accessors: u64,
    pub buffer_views: u64,
    /// Set when nothing was dropped because an extension tspace does not know is in use and
    /// might refer to them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kept_because: Option<String>,
}

/// Boxed parts keep an entry small when they are absent: a scene may have a hundred thousand
/// primitives.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PrimitiveReport {
    pub mesh: usize,
    pub primitive: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh_name: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub material: Option<usize>,
    /// `generated`, `overwritten`, `audited` (existing tangents kept and compared) or `skipped`.
    pub action: &'static str,
    /// For `skipped`: a stable code and a sentence.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub message: Option<String>,
    /// What in the material asked for a tangent frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uses: Option<&'static str>,
    pub texcoord: u32,
    /// The first primitive `[mesh, primitive]` with the same geometry, whose result this one
    /// shares, when it is not this one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shared_with: Option<[usize; 2]>,
    /// The core's findings; absent when `shared_with` is set (they are on that primitive).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diagnostics: Option<Box<DiagnosticsReport>>,
    /// The TANGENT written (generated or overwritten primitives only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tangent: Option<TangentReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub morph_targets: Option<Box<MorphReport>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub audit: Option<Box<Audit>>,
    /// How the primitive's geometry is stored, in and out.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub storage: Option<StorageReport>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

/// The core's [`Diagnostics`], for JSON.
#[derive(Clone, Debug, Default, Serialize)]
pub struct DiagnosticsReport {
    pub method: &'static str,
    pub triangles: u64,
    pub vertices_in: u64,
    pub vertices_out: u64,
    pub vertices_added: u64,
    /// `flat` or `smooth` when the primitive had no normals and they were generated.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub generated_normals: Option<&'static str>,
    pub duplicate_position_triangles: TallyReport,
    pub zero_area_triangles: TallyReport,
    pub zero_uv_area_triangles: TallyReport,
    pub mirrored_uv_triangles: TallyReport,
    pub non_finite_triangles: TallyReport,
    pub zero_normals: TallyReport,
    pub non_unit_normals: TallyReport,
    pub handedness_flip_vertices: TallyReport,
    pub mixed_handedness_triangles: TallyReport,
    pub fallback_tangents: FallbackReport,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct TallyReport {
    pub count: u64,
    /// The first few indices (triangles or vertices, as the name says), ascending.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub first: Vec<u32>,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct FallbackReport {
    pub count: u64,
    /// The first few corners (positions in the index list).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub first_corners: Vec<u32>,
    pub unassigned: u64,
    pub zero_length: u64,
    pub non_finite: u64,
    pub not_orthogonal: u64,
}

/// Tangent deltas computed for morph targets.
/// How a primitive's geometry is stored in the input and in the output, and what it takes.
#[derive(Clone, Debug, Default, Serialize)]
pub struct StorageReport {
    /// `none`, `draco` or `meshopt`.
    pub compression_in: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compression_out: Option<&'static str>,
    /// Bytes of the buffer views the primitive reads (each once; compressed at compressed size).
    pub bytes_in: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bytes_out: Option<u64>,
    /// Why the compression changed, when it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub why: Option<&'static str>,
}

/// The component type of a written TANGENT, and for a quantized one what quantizing cost.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct TangentReport {
    /// `float`, or the normals' own `byte` or `short` (normalized, KHR_mesh_quantization).
    pub component_type: &'static str,
    /// The largest angle between a computed tangent and its quantized value, in degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_quantization_degrees: Option<f32>,
}

impl TangentReport {
    pub fn new(quantized: Option<(crate::scene::gltf::quantize::Snorm, f32)>) -> TangentReport {
        use crate::scene::gltf::quantize::Snorm;
        match quantized {
            None => TangentReport {
                component_type: "float",
                max_quantization_degrees: None,
            },
            Some((snorm, degrees)) => TangentReport {
                component_type: match snorm {
                    Snorm::I8 => "byte",
                    Snorm::I16 => "short",
                },
                max_quantization_degrees: Some(degrees),
            },
        }
    }
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct MorphReport {
    pub targets: u64,
    /// Targets that got TANGENT deltas (those that move POSITION or NORMAL).
    pub with_tangent_deltas: u64,
    /// Corners whose handedness differs on the morphed mesh; a delta cannot express that, so
    /// the base handedness stays.
    pub handedness_changes: u64,
}

/// Existing tangents compared with what MikkTSpace gives for the same mesh.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Audit {
    /// `matches` (every w agrees and no angle above 1°), `differs`, or `invalid` (some tangents
    /// are not unit, not orthogonal to the normal, or not finite).
    pub verdict: &'static str,
    pub corners: u64,
    /// Corners whose w has the other sign from MikkTSpace's: a normal map baked in MikkTSpace
    /// shows inverted bumps there.
    pub w_disagreements: TallyReport,
    /// Angle between the existing and the MikkTSpace tangent, in degrees, over corners.
    pub angle_median_degrees: f32,
    pub angle_p99_degrees: f32,
    pub angle_max_degrees: f32,
    pub corners_over_1_degree: u64,
    /// Vertices whose tangent is more than 1e-3 from unit length.
    pub non_unit: TallyReport,
    /// Vertices whose tangent is more than 1e-3 (cosine) from orthogonal to the normal.
    pub non_orthogonal: TallyReport,
    /// Vertices with NaN or infinity, or w not ±1.
    pub invalid: TallyReport,
}

impl From<&Tally> for TallyReport {
    fn from(t: &Tally) -> Self {
        TallyReport {
            count: t.count,
            first: t.first.clone(),
        }
    }
}

impl From<&FallbackCounts> for FallbackReport {
    fn from(f: &FallbackCounts) -> Self {
        FallbackReport {
            count: f.corners.count,
            first_corners: f.corners.first.clone(),
            unassigned: f.unassigned,
            zero_length: f.zero_length,
            non_finite: f.non_finite,
            not_orthogonal: f.not_orthogonal,
        }
    }
}

impl From<&Diagnostics> for DiagnosticsReport {
    fn from(d: &Diagnostics) -> Self {
        use tspace_tangent::NormalMode;
        DiagnosticsReport {
            method: d.method.name(),
            triangles: d.triangles,
            vertices_in: d.vertices_in,
            vertices_out: d.vertices_out,
            vertices_added: d.vertices_added,
            generated_normals: d.generated_normals.map(|m| match m {
                NormalMode::Flat => "flat",
                NormalMode::SmoothByAngle { .. } => "smooth",
            }),
            duplicate_position_triangles: (&d.duplicate_position_triangles).into(),
            zero_area_triangles: (&d.zero_area_triangles).into(),
            zero_uv_area_triangles: (&d.zero_uv_area_triangles).into(),
            mirrored_uv_triangles: (&d.mirrored_uv_triangles).into(),
            non_finite_triangles: (&d.non_finite_triangles).into(),
            zero_normals: (&d.zero_normals).into(),
            non_unit_normals: (&d.non_unit_normals).into(),
            handedness_flip_vertices: (&d.handedness_flip_vertices).into(),
            mixed_handedness_triangles: (&d.mixed_handedness_triangles).into(),
            fallback_tangents: (&d.fallback_tangents).into(),
        }
    }
}

impl Report {
    /// One line for an HTTP header or a terminal: the summary alone.
    pub fn summary_line(&self) -> String {
        serde_json::to_string(&self.summary).unwrap_or_default()
    }

    /// The whole report, indented.
    pub fn to_json_pretty(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}
