//! The JSON report: per primitive, what was done or skipped and why, the core's diagnostics, and
//! for kept tangents an audit against MikkTSpace. Field names are snake_case and stable; counts
//! come with the first few offending indices so that a user can find them in a viewer.
//!
//! Counts alone do not say what to do, so every count that is not zero also becomes a
//! [`Finding`] with a severity and one line of meaning, from two tables (the diagnostics' and
//! [`NOTICES`]): a pipeline gates on `summary.findings` without knowing which of twenty counts
//! matter.
//! The report is versioned (`report_version`); the fields version 2 renamed stay, marked
//! deprecated in `docs/report.md`, until version 3.

use serde::Serialize;
use std::sync::Arc;
use tspace_tangent::{Diagnostics, FallbackCounts, Tally};
use utoipa::ToSchema;

/// The report's shape: raised when a field is renamed or removed, not when one is added.
pub const REPORT_VERSION: u32 = 2;

/// The report of one scene.
#[derive(Clone, Debug, Default, Serialize, ToSchema)]
pub struct Report {
    /// [`REPORT_VERSION`]: 2 added `findings` and renamed `first_corners` to `first`.
    pub report_version: u32,
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
    /// Everything worth a look, errors first: each non-zero count of a primitive's diagnostics
    /// and audit, and each scene-level notice, with its severity and meaning.
    pub findings: Vec<Finding>,
    /// Deprecated since report version 2 (the scene-level `findings` carry the same messages
    /// with a code and a severity); kept until version 3.
    pub warnings: Vec<String>,
    /// With `debug=colors`: what was painted. Its presence says the written scene is for
    /// looking, not for shipping.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub debug_colors: Option<DebugColorsReport>,
    /// The scene's notices, in the order they were raised; [`Report::finish`] makes them
    /// findings.
    #[serde(skip)]
    pub notices: Vec<Notice>,
}

/// What `debug=colors` painted: each computed primitive's triangles coloured by class in
/// COLOR_0, shown by one unlit material.
#[derive(Clone, Debug, Default, Serialize, ToSchema)]
pub struct DebugColorsReport {
    /// Primitives painted (every primitive tspace gave tangents or audited).
    pub primitives: u64,
    /// The index of the material the painted primitives now use; absent when none was painted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub material: Option<usize>,
    /// Vertices added so that triangles of different classes do not share one (beyond the
    /// tangents' own split, which `summary.vertices_added` counts).
    pub vertices_added: u64,
    /// Every class, in order of precedence from lowest: a triangle in several takes the last.
    pub classes: Vec<DebugClassReport>,
}

/// One colour of the debug scene.
#[derive(Clone, Debug, Default, Serialize, ToSchema)]
pub struct DebugClassReport {
    /// `ordinary`, `mirrored_uv`, `repaired_tangent`, `zero_uv_area` or `degenerate`.
    pub class: &'static str,
    /// The colour as `#rrggbb` sRGB (COLOR_0 stores it linear).
    pub color: String,
    /// Triangles painted so, over the computations (shared geometry counted once).
    pub triangles: u64,
}

#[derive(Clone, Debug, Default, Serialize, ToSchema)]
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
    /// Triangles with no area in space (two corners at one position, or collinear).
    pub degenerate_triangles: u64,
    /// Triangles with area in space but none in UV space: their tangent direction is undefined.
    pub zero_uv_area_triangles: u64,
    pub mirrored_uv_triangles: u64,
    /// Audited primitives whose tangents disagree with MikkTSpace (w or more than 1°).
    pub audits_disagreeing: u64,
    /// Bytes of the buffer views the meshes read, compressed ones at their compressed size.
    pub mesh_bytes_in: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh_bytes_out: Option<u64>,
    /// How many findings of each severity the report lists.
    pub findings: SeverityCounts,
}

/// Findings counted by severity.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, ToSchema)]
pub struct SeverityCounts {
    pub error: u64,
    pub warning: u64,
    pub info: u64,
}

#[derive(Clone, Debug, Default, Serialize, ToSchema)]
pub struct Dropped {
    pub accessors: u64,
    pub buffer_views: u64,
    /// Set when nothing was dropped because an extension tspace does not know is in use and
    /// might refer to them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kept_because: Option<String>,
}

// A scene may have a hundred thousand primitives, each with an entry held beside the scene's
// tree at the scene layer's peak; a change that grows it should be a decision.
const _: () = assert!(std::mem::size_of::<PrimitiveReport>() == 120);

/// Boxed parts keep an entry small when they are absent: a scene may have a hundred thousand
/// primitives.
#[derive(Clone, Debug, Default, Serialize, ToSchema)]
pub struct PrimitiveReport {
    // Positions in 32 bits (`scene::index32`).
    #[schema(value_type = usize)]
    pub mesh: u32,
    #[schema(value_type = usize)]
    pub primitive: u32,
    // Shared by the mesh's primitives: a scene may have a hundred thousand in one mesh.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>)]
    pub mesh_name: Option<MeshName>,
    // As the file spells it, whether or not that material exists: 64 bits, unlike the positions.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<usize>)]
    pub material: Option<u64>,
    /// `generated`, `overwritten`, `audited` (existing tangents kept and compared) or `skipped`.
    #[schema(value_type = String)]
    pub action: PrimitiveAction,
    /// For `skipped`: a stable code and a sentence.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>)]
    pub reason: Option<SkipCode>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>)]
    pub message: Option<Box<str>>,
    /// What in the material asked for a tangent frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>)]
    pub uses: Option<FrameUse>,
    pub texcoord: u32,
    /// The first primitive `[mesh, primitive]` with the same geometry, whose result this one
    /// shares, when it is not this one.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<[usize; 2]>)]
    pub shared_with: Option<[u32; 2]>,
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
    // Boxed: it is written once the output is, when the input's tree is gone, so that an
    // entry held through the write (the writer's peak) is 24 bytes smaller.
    /// How the primitive's geometry is stored, in and out.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub storage: Option<Box<StorageReport>>,
    #[serde(skip_serializing_if = "Notes::is_empty")]
    #[schema(value_type = Vec<String>)]
    pub notes: Notes,
}

/// What became of a primitive, written as its name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PrimitiveAction {
    Generated,
    /// Tangents it had were replaced (`overwrite`).
    Overwritten,
    /// Existing tangents kept and compared with MikkTSpace.
    Audited,
    #[default]
    Skipped,
}

impl PrimitiveAction {
    pub fn as_str(self) -> &'static str {
        match self {
            PrimitiveAction::Generated => "generated",
            PrimitiveAction::Overwritten => "overwritten",
            PrimitiveAction::Audited => "audited",
            PrimitiveAction::Skipped => "skipped",
        }
    }
}

/// What in a material asks for a tangent frame, written as the glTF name of the texture or
/// extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameUse {
    NormalTexture,
    ClearcoatNormalTexture,
    Anisotropy,
}

impl FrameUse {
    pub fn as_str(self) -> &'static str {
        match self {
            FrameUse::NormalTexture => "normalTexture",
            FrameUse::ClearcoatNormalTexture => "KHR_materials_clearcoat.clearcoatNormalTexture",
            FrameUse::Anisotropy => "KHR_materials_anisotropy",
        }
    }
}

/// The report's words for values it holds as enums (a scene may have a hundred thousand
/// entries): written, displayed and compared as those words.
macro_rules! written_as_str {
    ($($name:ident),*) => {$(
        impl Serialize for $name {
            fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                serializer.serialize_str(self.as_str())
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.as_str())
            }
        }

        impl PartialEq<&str> for $name {
            fn eq(&self, other: &&str) -> bool {
                self.as_str() == *other
            }
        }
    )*};
}

/// A mesh's name, shared by its primitives' entries and plans: one pointer, where an `Arc<str>`
/// is two, and a scene may have a hundred thousand primitives in one mesh. Reads as a `str`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MeshName(Arc<Box<str>>);

impl From<&str> for MeshName {
    fn from(name: &str) -> MeshName {
        MeshName(Arc::new(name.into()))
    }
}

impl std::ops::Deref for MeshName {
    type Target = str;

    fn deref(&self) -> &str {
        &self.0
    }
}

impl Serialize for MeshName {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self)
    }
}

/// Why a primitive was skipped, written as a stable code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SkipCode {
    NotTriangles,
    NoMaterial,
    NoNormalMap,
    HasTangents,
    NoPositions,
    NoTexcoords,
}

impl SkipCode {
    pub fn as_str(self) -> &'static str {
        match self {
            SkipCode::NotTriangles => "not_triangles",
            SkipCode::NoMaterial => "no_material",
            SkipCode::NoNormalMap => "no_normal_map",
            SkipCode::HasTangents => "has_tangents",
            SkipCode::NoPositions => "no_positions",
            SkipCode::NoTexcoords => "no_texcoords",
        }
    }
}

written_as_str!(PrimitiveAction, FrameUse, StorageChange, SkipCode);

/// A short list held as one pointer, null while it is empty: a report holds a dozen per
/// primitive (the notes, and the first few indices of every tally) and a scene may have a
/// hundred thousand primitives, nearly all with every list empty, where a `Vec` takes 24
/// bytes. Pushing reallocates; these lists stay short. Written as a JSON array.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Thin<T>(Option<Box<Box<[T]>>>);

/// A primitive's notes.
pub type Notes = Thin<String>;

/// The first few indices of a tally, ascending.
pub type FirstFew = Thin<u32>;

impl<T> Default for Thin<T> {
    fn default() -> Self {
        Thin(None)
    }
}

impl<T> Thin<T> {
    pub fn new(list: &[T]) -> Self
    where
        T: Clone,
    {
        Thin::from(list.to_vec())
    }

    pub fn push(&mut self, item: T) {
        let mut items = self
            .0
            .take()
            .map_or_else(Vec::new, |items| items.into_vec());
        items.push(item);
        *self = Thin::from(items);
    }

    pub fn as_slice(&self) -> &[T] {
        self.0.as_deref().map_or(&[], |items| items)
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_none()
    }
}

impl<T> std::ops::Deref for Thin<T> {
    type Target = [T];

    fn deref(&self) -> &[T] {
        self.as_slice()
    }
}

impl<T> From<Vec<T>> for Thin<T> {
    fn from(items: Vec<T>) -> Self {
        Thin((!items.is_empty()).then(|| Box::new(items.into_boxed_slice())))
    }
}

impl<T: Serialize> Serialize for Thin<T> {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        self.as_slice().serialize(serializer)
    }
}

/// The core's [`Diagnostics`], for JSON.
#[derive(Clone, Debug, Default, Serialize, ToSchema)]
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

#[derive(Clone, Debug, Default, Serialize, ToSchema)]
pub struct TallyReport {
    pub count: u64,
    /// The first few indices (triangles or vertices, as the name says), ascending.
    #[serde(skip_serializing_if = "FirstFew::is_empty")]
    #[schema(value_type = Vec<u32>)]
    pub first: FirstFew,
}

#[derive(Clone, Debug, Default, Serialize, ToSchema)]
pub struct FallbackReport {
    pub count: u64,
    /// The first few corners (positions in the index list), ascending.
    #[serde(skip_serializing_if = "FirstFew::is_empty")]
    #[schema(value_type = Vec<u32>)]
    pub first: FirstFew,
    /// Deprecated since report version 2: `first`, under the name every other list has.
    #[serde(skip_serializing_if = "FirstFew::is_empty")]
    #[schema(value_type = Vec<u32>)]
    pub first_corners: FirstFew,
    pub unassigned: u64,
    pub zero_length: u64,
    pub non_finite: u64,
    pub not_orthogonal: u64,
}

/// How a primitive's geometry is compressed in a file. An enum rather than its name, so that a
/// report entry stays small (a scene may have a hundred thousand); written as the name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MeshCompression {
    #[default]
    None,
    Draco,
    Meshopt,
}

/// How a primitive's geometry is stored in the input and in the output, and what it takes.
#[derive(Clone, Debug, Default, Serialize, ToSchema)]
pub struct StorageReport {
    /// `none`, `draco` or `meshopt`.
    #[schema(value_type = String)]
    pub compression_in: MeshCompression,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>)]
    pub compression_out: Option<MeshCompression>,
    /// Bytes of the buffer views the primitive reads (each once; compressed at compressed size).
    pub bytes_in: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bytes_out: Option<u64>,
    /// Why the compression changed, when it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>)]
    pub why: Option<StorageChange>,
}

/// Why a primitive's compression changed, written as a sentence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StorageChange {
    OutOfDraco,
    DracoToMeshopt,
    Uncompressed,
    ToMeshopt,
}

impl StorageChange {
    pub fn as_str(self) -> &'static str {
        match self {
            StorageChange::OutOfDraco => {
                "written out of Draco: the primitive changed, and encoding Draco again would quantize it again"
            }
            StorageChange::DracoToMeshopt => {
                "written out of Draco (encoding it again would quantize it again), with lossless meshopt compression"
            }
            StorageChange::Uncompressed => "written uncompressed",
            StorageChange::ToMeshopt => "compressed with meshopt, as compress=meshopt asks",
        }
    }
}

/// A written TANGENT's component type, written as its name (`float`, `byte`, `short`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TangentComponent {
    #[default]
    Float,
    Byte,
    Short,
}

/// The component type of a written TANGENT, and for a quantized one what quantizing cost.
#[derive(Clone, Copy, Debug, Default, Serialize, ToSchema)]
pub struct TangentReport {
    /// `float`, or the normals' own `byte` or `short` (normalized, KHR_mesh_quantization).
    #[schema(value_type = String)]
    pub component_type: TangentComponent,
    /// The largest angle between a computed tangent and its quantized value, in degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_quantization_degrees: Option<f32>,
}

impl TangentReport {
    pub fn new(quantized: Option<(crate::scene::gltf::quantize::Snorm, f32)>) -> TangentReport {
        use crate::scene::gltf::quantize::Snorm;
        match quantized {
            None => TangentReport {
                component_type: TangentComponent::Float,
                max_quantization_degrees: None,
            },
            Some((snorm, degrees)) => TangentReport {
                component_type: match snorm {
                    Snorm::I8 => TangentComponent::Byte,
                    Snorm::I16 => TangentComponent::Short,
                },
                max_quantization_degrees: Some(degrees),
            },
        }
    }
}

#[derive(Clone, Debug, Default, Serialize, ToSchema)]
pub struct MorphReport {
    pub targets: u64,
    /// Targets that got TANGENT deltas (those that move POSITION or NORMAL).
    pub with_tangent_deltas: u64,
    /// Corners whose handedness differs on the morphed mesh; a delta cannot express that, so
    /// the base handedness stays.
    pub handedness_changes: u64,
}

/// Existing tangents compared with what MikkTSpace gives for the same mesh.
#[derive(Clone, Debug, Default, Serialize, ToSchema)]
pub struct Audit {
    /// `matches` (every w agrees and no angle above 1°), `differs`, or `invalid` (some tangents
    /// break glTF's rules: not unit, not finite, or w not ±1). Tangents not orthogonal to
    /// their normal are counted in `non_orthogonal` but are not invalid: glTF does not ask
    /// for it, and renderers orthogonalize.
    pub verdict: &'static str,
    pub corners: u64,
    /// Corners with the other w or more than 1° off: where a MikkTSpace-baked normal map
    /// renders wrong.
    pub corners_disagreeing: u64,
    /// Corners whose w has the other sign from MikkTSpace's: a normal map baked in MikkTSpace
    /// shows inverted bumps there.
    pub w_disagreements: TallyReport,
    /// Angle between the existing tangent, made orthogonal to the normal as a renderer does,
    /// and the MikkTSpace tangent, in degrees, over corners.
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
            first: FirstFew::new(&t.first),
        }
    }
}

impl From<&FallbackCounts> for FallbackReport {
    fn from(f: &FallbackCounts) -> Self {
        FallbackReport {
            count: f.corners.count,
            first: FirstFew::new(&f.corners.first),
            first_corners: FirstFew::new(&f.corners.first),
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

/// `n` with commas between thousands: 2,000,000.
pub fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// How much a finding matters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// Normal for real assets, said so that nothing is hidden (a mirrored UV layout).
    Info,
    /// Worth a look: the output is valid, but something will likely show in a render or was
    /// not carried over (UVs with no area, a missing texture, tangents that disagree).
    Warning,
    /// The input breaks glTF's rules where it matters to tangents (normals not unit, values
    /// not finite, kept tangents invalid): the output there is tspace's best repair.
    Error,
}

/// One thing the report wants a reader to see: what, how bad, how many, and where.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct Finding {
    /// Stable snake_case code; `docs/report.md` says what to do about each.
    pub code: &'static str,
    pub severity: Severity,
    /// One line: what it means here.
    pub message: String,
    /// How many triangles, vertices or corners (as the code says); absent for scene notices.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<u64>,
    /// `[mesh, primitive]`; absent for scene notices.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub primitive: Option<[usize; 2]>,
}

/// A scene-level notice from reading or writing (a texture not supplied, statements skipped):
/// a code from [`NOTICES`] and a sentence.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Notice {
    pub code: &'static str,
    pub message: String,
}

impl Notice {
    pub fn new(code: &'static str, message: impl Into<String>) -> Notice {
        debug_assert!(
            NOTICES.iter().any(|(c, _)| *c == code),
            "{code} is not in NOTICES"
        );
        Notice {
            code,
            message: message.into(),
        }
    }
}

/// Every scene notice's code and severity, in one table so the docs and tests can list them.
pub const NOTICES: &[(&str, Severity)] = &[
    // Reading an OBJ and its MTL.
    ("mtl_not_supplied", Severity::Warning),
    ("obj_statements_skipped", Severity::Info),
    ("obj_faces_repaired", Severity::Warning),
    ("materials_not_written", Severity::Warning),
    ("materials_missing", Severity::Warning),
    ("material_values_adjusted", Severity::Warning),
    ("untextured_material_copies", Severity::Info),
    ("texture_paths_reduced", Severity::Info),
    ("texture_paths_unusable", Severity::Warning),
    ("textures_not_supplied", Severity::Warning),
    ("textures_not_embeddable", Severity::Warning),
    ("texture_transforms_dropped", Severity::Warning),
    ("texture_maps_not_converted", Severity::Warning),
    ("invalid_normals_dropped", Severity::Error),
    ("invalid_texcoords_dropped", Severity::Error),
    ("non_finite_positions", Severity::Error),
    ("colors_clamped", Severity::Warning),
    ("normals_generated", Severity::Info),
    // Writing glTF.
    ("image_not_supplied", Severity::Warning),
    ("image_format_unknown", Severity::Warning),
    ("draco_removed", Severity::Info),
    ("output_compressed", Severity::Info),
    ("buffers_merged", Severity::Info),
    ("debug_colors", Severity::Warning),
    ("debug_colors_unused", Severity::Info),
];

/// The severity of a notice's code (an unknown code, which `Notice::new` rules out in tests,
/// counts as a warning rather than vanish).
pub fn notice_severity(code: &str) -> Severity {
    NOTICES
        .iter()
        .find(|(c, _)| *c == code)
        .map_or(Severity::Warning, |(_, s)| *s)
}

/// A finding a primitive's count makes: its code (the report's field name), severity, what a
/// non-zero count means, and the count.
type DiagnosticFinding = (
    &'static str,
    Severity,
    &'static str,
    fn(&DiagnosticsReport) -> u64,
);

/// The findings a primitive's diagnostics make.
const DIAGNOSTIC_FINDINGS: &[DiagnosticFinding] = &[
    (
        "non_finite_triangles",
        Severity::Error,
        "triangles with a NaN or infinite position, normal or UV: their tangents are a fallback",
        |d| d.non_finite_triangles.count,
    ),
    (
        "zero_normals",
        Severity::Error,
        "vertices whose normal has zero length: glTF requires unit normals; shading there is undefined",
        |d| d.zero_normals.count,
    ),
    (
        "non_unit_normals",
        Severity::Error,
        "vertices whose normal is not unit length: glTF requires unit normals (tangents use them normalized)",
        |d| d.non_unit_normals.count,
    ),
    (
        "zero_area_triangles",
        Severity::Warning,
        "triangles with no area (collinear corners): invisible, but their corners get fallback tangents",
        |d| d.zero_area_triangles.count,
    ),
    (
        "duplicate_position_triangles",
        Severity::Warning,
        "triangles with two corners at one position: invisible, but their corners get fallback tangents",
        |d| d.duplicate_position_triangles.count,
    ),
    (
        "zero_uv_area_triangles",
        Severity::Warning,
        "triangles whose UVs have no area: a normal map cannot be oriented on them; check the UV layout",
        |d| d.zero_uv_area_triangles.count,
    ),
    (
        "fallback_tangents",
        Severity::Warning,
        "corners MikkTSpace gave no valid tangent (the reference would write a broken one); tspace made a valid one orthogonal to the normal",
        |d| d.fallback_tangents.count,
    ),
    (
        "mixed_handedness_triangles",
        Severity::Warning,
        "triangles whose corners disagree on w (handedness): the normal map shows a seam across them",
        |d| d.mixed_handedness_triangles.count,
    ),
    (
        "mirrored_uv_triangles",
        Severity::Info,
        "triangles with mirrored UVs (w = -1): normal for a mirrored layout",
        |d| d.mirrored_uv_triangles.count,
    ),
    (
        "handedness_flip_vertices",
        Severity::Info,
        "vertices split because mirrored and unmirrored triangles share them",
        |d| d.handedness_flip_vertices.count,
    ),
];

/// What an audit's counts mean for the tangents the file keeps.
fn audit_findings(audit: &Audit) -> Vec<(&'static str, Severity, u64, String)> {
    let mut found = Vec::new();
    let broken = audit.invalid.count + audit.non_unit.count;
    if broken > 0 {
        found.push((
            "audit_invalid",
            Severity::Error,
            broken,
            "vertices whose kept tangent breaks glTF's rules (not unit, not finite, or w not ±1); overwrite=true replaces them".to_owned(),
        ));
    }
    let disagreeing = audit.corners_disagreeing;
    if disagreeing > 0 {
        found.push((
            "audit_differs",
            Severity::Warning,
            disagreeing,
            format!(
                "corners where the kept tangents disagree with MikkTSpace ({} in w, {} by more than 1° as rendered): a normal map baked in MikkTSpace renders wrong there; overwrite=true replaces them",
                audit.w_disagreements.count, audit.corners_over_1_degree
            ),
        ));
    }
    if audit.non_orthogonal.count > 0 {
        found.push((
            "audit_non_orthogonal",
            Severity::Info,
            audit.non_orthogonal.count,
            "vertices whose kept tangent is not orthogonal to its normal: glTF does not require it and renderers orthogonalize".to_owned(),
        ));
    }
    found
}

impl Report {
    /// Fills `findings`, the summary's counts of them, and the deprecated `warnings` from the
    /// primitives' counts and the scene's notices. Called when the report is complete, and
    /// again if notices are added after (an OBJ's own come before the glTF path's).
    pub fn finish(&mut self) {
        let notices = &self.notices;
        let mut findings = Vec::new();
        for p in &self.primitives {
            let at = Some([p.mesh as usize, p.primitive as usize]);
            if let Some(d) = &p.diagnostics {
                for &(code, severity, meaning, count_of) in DIAGNOSTIC_FINDINGS {
                    let count = count_of(d);
                    if count > 0 {
                        findings.push(Finding {
                            code,
                            severity,
                            message: meaning.to_owned(),
                            count: Some(count),
                            primitive: at,
                        });
                    }
                }
            }
            if let Some(audit) = &p.audit {
                for (code, severity, count, message) in audit_findings(audit) {
                    findings.push(Finding {
                        code,
                        severity,
                        message,
                        count: Some(count),
                        primitive: at,
                    });
                }
            }
        }
        self.warnings = notices.iter().map(|n| n.message.clone()).collect();
        findings.extend(notices.iter().map(|n| Finding {
            code: n.code,
            severity: notice_severity(n.code),
            message: n.message.clone(),
            count: None,
            primitive: None,
        }));
        // Errors first; within a severity, the order they were found in.
        findings.sort_by_key(|f| std::cmp::Reverse(f.severity));
        let mut counts = SeverityCounts::default();
        for f in &findings {
            *match f.severity {
                Severity::Error => &mut counts.error,
                Severity::Warning => &mut counts.warning,
                Severity::Info => &mut counts.info,
            } += 1;
        }
        self.summary.findings = counts;
        self.findings = findings;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tally(count: u64) -> TallyReport {
        TallyReport {
            count,
            first: FirstFew::new(&[0]),
        }
    }

    #[test]
    fn an_entry_held_in_enums_and_thin_lists_is_written_as_the_words_it_stands_for() {
        let mut entry = PrimitiveReport {
            mesh: 2,
            primitive: 7,
            action: PrimitiveAction::Overwritten,
            uses: Some(FrameUse::ClearcoatNormalTexture),
            shared_with: Some([1, 3]),
            storage: Some(Box::new(StorageReport {
                why: Some(StorageChange::Uncompressed),
                ..StorageReport::default()
            })),
            ..PrimitiveReport::default()
        };
        let json = serde_json::to_value(&entry).unwrap();
        assert_eq!(json["mesh"], 2);
        assert_eq!(json["action"], "overwritten");
        assert_eq!(
            json["uses"],
            "KHR_materials_clearcoat.clearcoatNormalTexture"
        );
        assert_eq!(json["shared_with"], serde_json::json!([1, 3]));
        assert_eq!(json["storage"]["why"], "written uncompressed");
        assert!(json.get("notes").is_none(), "no notes, no member: {json}");

        entry.notes.push("first".into());
        entry.notes.push("second".into());
        assert_eq!(entry.notes.as_slice(), ["first", "second"]);
        let json = serde_json::to_value(&entry).unwrap();
        assert_eq!(json["notes"], serde_json::json!(["first", "second"]));
        assert_eq!(Notes::from(Vec::new()), Notes::default());
        assert_eq!(PrimitiveAction::default(), "skipped");
    }

    #[test]
    fn findings_come_errors_first_with_counts_and_the_deprecated_warnings_kept() {
        let mut report = Report::default();
        report.primitives.push(PrimitiveReport {
            mesh: 2,
            primitive: 1,
            diagnostics: Some(Box::new(DiagnosticsReport {
                mirrored_uv_triangles: tally(7),
                zero_uv_area_triangles: tally(3),
                non_unit_normals: tally(1),
                ..DiagnosticsReport::default()
            })),
            ..PrimitiveReport::default()
        });
        report.notices = vec![
            Notice::new("draco_removed", "gone"),
            Notice::new("image_not_supplied", "images[0] missing"),
        ];
        report.finish();
        let seen: Vec<_> = report
            .findings
            .iter()
            .map(|f| (f.code, f.severity, f.count, f.primitive))
            .collect();
        assert_eq!(
            seen,
            [
                ("non_unit_normals", Severity::Error, Some(1), Some([2, 1])),
                (
                    "zero_uv_area_triangles",
                    Severity::Warning,
                    Some(3),
                    Some([2, 1])
                ),
                ("image_not_supplied", Severity::Warning, None, None),
                (
                    "mirrored_uv_triangles",
                    Severity::Info,
                    Some(7),
                    Some([2, 1])
                ),
                ("draco_removed", Severity::Info, None, None),
            ]
        );
        assert_eq!(
            report.summary.findings,
            SeverityCounts {
                error: 1,
                warning: 2,
                info: 2
            }
        );
        assert_eq!(report.warnings, ["gone", "images[0] missing"]);
        // Finishing again (an OBJ adds its own notices after the glTF path) does not double.
        report.finish();
        assert_eq!(report.findings.len(), 5);
    }

    #[test]
    fn every_diagnostic_finding_reads_its_own_count() {
        // Every count different, so that a finding reading another field's shows.
        let d = DiagnosticsReport {
            duplicate_position_triangles: tally(1),
            zero_area_triangles: tally(2),
            zero_uv_area_triangles: tally(3),
            mirrored_uv_triangles: tally(4),
            non_finite_triangles: tally(5),
            zero_normals: tally(6),
            non_unit_normals: tally(7),
            handedness_flip_vertices: tally(8),
            mixed_handedness_triangles: tally(9),
            fallback_tangents: FallbackReport {
                count: 10,
                ..FallbackReport::default()
            },
            ..DiagnosticsReport::default()
        };
        let json = serde_json::to_value(&d).unwrap();
        for &(code, _, meaning, count_of) in DIAGNOSTIC_FINDINGS {
            assert_eq!(json[code]["count"], count_of(&d), "{code}");
            assert!(!meaning.is_empty());
        }
    }

    #[test]
    fn a_non_orthogonal_audit_is_information_and_an_invalid_one_an_error() {
        let tilted = Audit {
            verdict: "matches",
            non_orthogonal: tally(9),
            ..Audit::default()
        };
        let found: Vec<_> = audit_findings(&tilted).iter().map(|f| (f.0, f.1)).collect();
        assert_eq!(found, [("audit_non_orthogonal", Severity::Info)]);
        let broken = Audit {
            verdict: "invalid",
            corners_disagreeing: 3,
            invalid: tally(2),
            ..Audit::default()
        };
        let found: Vec<_> = audit_findings(&broken)
            .iter()
            .map(|f| (f.0, f.1, f.2))
            .collect();
        assert_eq!(
            found,
            [
                ("audit_invalid", Severity::Error, 2),
                ("audit_differs", Severity::Warning, 3)
            ]
        );
    }

    #[test]
    fn notice_codes_are_unique_and_documented() {
        let docs = include_str!("../../docs/report.md");
        for (i, (code, _)) in NOTICES.iter().enumerate() {
            assert!(!NOTICES[..i].iter().any(|(c, _)| c == code), "{code} twice");
            assert!(
                docs.contains(&format!("`{code}`")),
                "{code} not in docs/report.md"
            );
        }
        for &(code, _, _, _) in DIAGNOSTIC_FINDINGS {
            assert!(
                docs.contains(&format!("`{code}`")),
                "{code} not in docs/report.md"
            );
        }
    }
}
