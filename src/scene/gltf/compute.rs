//! Reading a primitive's geometry and running the tangent core on it: once per distinct set of
//! accessors, for the base mesh and for every morph target that moves it, and the audit of
//! tangents a file already has.

use super::accessor::{self, AccessorError, ComponentType, Data};
use super::plan::{GeometryKey, Topology};
use crate::scene::error::{ProblemCode, SceneError};
use crate::scene::report::{Audit, TallyReport};
use std::borrow::Cow;
use tspace_json::Node;
use tspace_tangent::{
    self as tangent, Cancel, CoreError, MeshInput, Options, SplitPlan, Tally, Tangents,
};

/// Limits on the geometry one scene may hold.
#[derive(Clone, Copy, Debug)]
pub struct GeometryLimits {
    /// The most vertices one accessor may have.
    pub max_vertices: usize,
    /// The most triangles in the whole scene (counted over computations).
    pub max_triangles: usize,
}

/// The geometry of one [`GeometryKey`], as the core takes it: borrowed from the scene's buffers
/// where the data needs no decoding (see `accessor::floats_in_place`), else decoded.
pub struct Geometry<'a> {
    pub positions: Cow<'a, [[f32; 3]]>,
    pub normals: Option<Cow<'a, [[f32; 3]]>>,
    pub uvs: Option<Cow<'a, [[f32; 2]]>>,
    /// A triangle list (strips and fans unrolled), or `None` for non-indexed triangles.
    pub indices: Option<Cow<'a, [u32]>>,
}

impl Geometry<'_> {
    pub fn input(&self) -> MeshInput<'_> {
        MeshInput {
            positions: &self.positions,
            normals: self.normals.as_deref(),
            uvs: self.uvs.as_deref(),
            indices: self.indices.as_deref(),
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.indices
            .as_ref()
            .map_or(self.positions.len(), |i| i.len())
            / 3
    }

    /// The vertex of each corner.
    pub fn corner_vertex(&self, corner: usize) -> usize {
        self.indices
            .as_ref()
            .map_or(corner, |i| i.get(corner).map_or(0, |&v| v as usize))
    }
}

/// The result of one computation.
pub struct Computed<'a> {
    pub geometry: Geometry<'a>,
    pub tangents: Tangents,
    /// Per morph target: tangent deltas per output vertex, when the target moves POSITION or
    /// NORMAL.
    pub target_deltas: Vec<Option<Vec<[f32; 3]>>>,
    pub morph_handedness_changes: u64,
}

impl Computed<'_> {
    /// True when the primitive's vertices, indices and mode can stay as they are: nothing was
    /// split and no strip or fan had to be unrolled. Generated normals number the vertices in
    /// the order the corners first use them, so with those the numbering must also turn out to
    /// be the input's own (a triangle soup's, or a mesh whose vertices no two differently
    /// facing triangles share): then the input's accessors are kept and only NORMAL and
    /// TANGENT are added.
    pub fn keeps_vertices(&self, topology: Topology) -> bool {
        let source = &self.tangents.split.source_vertex;
        topology == Topology::Triangles
            && source.len() == self.geometry.positions.len()
            && (self.tangents.normals.is_none() || source.iter().zip(0u32..).all(|(&v, i)| v == i))
    }
}

pub fn accessor_error(error: AccessorError) -> SceneError {
    // Decoding errors come wrapped in the accessor's path; the limit is the innermost cause.
    let mut cause = &error;
    while let AccessorError::In { error: inner, .. } = cause {
        cause = inner;
    }
    match cause {
        AccessorError::TooManyElements { .. } => {
            SceneError::new(ProblemCode::TooManyVertices, error.to_string())
        }
        _ => SceneError::new(ProblemCode::InvalidAccessor, error.to_string()),
    }
}

fn core_error(path: &str, error: CoreError) -> SceneError {
    match error {
        CoreError::Cancelled => SceneError::cancelled(),
        CoreError::TooLarge { .. } => {
            SceneError::new(ProblemCode::TooManyVertices, format!("{path}: {error}"))
        }
        _ => SceneError::new(ProblemCode::InvalidPrimitive, format!("{path}: {error}")),
    }
}

/// Normals as they are, or unit ones from a quantized accessor (normalized integers are not
/// unit after decoding).
fn read_normals<'a>(
    root: &Node,
    index: usize,
    data: Data<'a>,
    limits: &GeometryLimits,
) -> Result<Cow<'a, [[f32; 3]]>, SceneError> {
    let described = data.accessor(root, index).map_err(accessor_error)?;
    if described.component_type == ComponentType::F32 {
        return data
            .floats_borrowed::<3>(root, index, limits.max_vertices)
            .map_err(accessor_error);
    }
    let mut normals =
        accessor::read_floats::<3>(&described, limits.max_vertices).map_err(accessor_error)?;
    normalize(&mut normals);
    Ok(Cow::Owned(normals))
}

/// Scales every non-zero vector to unit length; a zero one stays as it is.
fn normalize(vectors: &mut [[f32; 3]]) {
    for v in vectors {
        let length = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if length > 0.0 {
            *v = [v[0] / length, v[1] / length, v[2] / length];
        }
    }
}

/// Turns strips and fans into triangle lists (glTF 2.0 §3.7.2.1), and checks a list's length.
fn triangle_list(
    topology: Topology,
    indices: Option<Cow<'_, [u32]>>,
    vertex_count: usize,
) -> Option<Cow<'_, [u32]>> {
    let sequence = |indices: Option<Cow<'_, [u32]>>| -> Vec<u32> {
        indices.map_or_else(|| (0..vertex_count as u32).collect(), Cow::into_owned)
    };
    match topology {
        Topology::Triangles => indices,
        Topology::Strip => {
            let s = sequence(indices);
            let n = s.len().saturating_sub(2);
            let mut out = Vec::with_capacity(n * 3);
            for i in 0..n {
                // Every other triangle is wound the other way so that all face the same side.
                let (a, b) = if i % 2 == 0 { (1, 2) } else { (2, 1) };
                out.extend([s[i], s[i + a], s[i + b]]);
            }
            Some(Cow::Owned(out))
        }
        Topology::Fan => {
            let s = sequence(indices);
            let n = s.len().saturating_sub(2);
            let mut out = Vec::with_capacity(n * 3);
            for i in 0..n {
                out.extend([s[i + 1], s[i + 2], s[0]]);
            }
            Some(Cow::Owned(out))
        }
    }
}

/// Reads the geometry a key names.
pub fn read_geometry<'a>(
    root: &Node,
    key: &GeometryKey,
    data: Data<'a>,
    limits: &GeometryLimits,
) -> Result<Geometry<'a>, SceneError> {
    let positions = data
        .floats_borrowed::<3>(root, key.position, limits.max_vertices)
        .map_err(accessor_error)?;
    let normals = key
        .normal
        .map(|n| read_normals(root, n, data, limits))
        .transpose()?;
    let uvs = key
        .texcoord
        .map(|t| data.floats_borrowed::<2>(root, t, limits.max_vertices))
        .transpose()
        .map_err(accessor_error)?;
    // Index lists are bounded by corners, which may be up to three per triangle.
    let max_corners = limits.max_triangles.saturating_mul(3);
    let indices = key
        .indices
        .map(|i| data.indices_borrowed(root, i, max_corners))
        .transpose()
        .map_err(accessor_error)?;
    let indices = triangle_list(key.topology, indices, positions.len());
    Ok(Geometry {
        positions,
        normals,
        uvs,
        indices,
    })
}

/// Drops a strip's leftover vertices and a list's stray indices, which are not triangles; a
/// non-indexed list has nothing to drop from, so whole triangles are required of it.
fn keep_whole_triangles(
    geometry: &mut Geometry<'_>,
    topology: Topology,
    path: &str,
) -> Result<(), SceneError> {
    if let Some(indices) = &mut geometry.indices {
        let whole = indices.len() / 3 * 3;
        if whole != indices.len() {
            indices.to_mut().truncate(whole);
        }
    } else if topology == Topology::Triangles && !geometry.positions.len().is_multiple_of(3) {
        return Err(SceneError::new(
            ProblemCode::InvalidPrimitive,
            format!(
                "{path}: {} vertices without indices do not make whole triangles",
                geometry.positions.len()
            ),
        ));
    }
    Ok(())
}

/// A morph target's displacements, one per vertex, for the attributes it moves.
struct Displacement {
    positions: Option<Vec<[f32; 3]>>,
    normals: Option<Vec<[f32; 3]>>,
}

/// Reads a target's displacements, or `None` when it moves neither POSITION nor NORMAL (and so
/// leaves the tangents as they are).
fn read_displacement(
    root: &Node,
    (position, normal): (Option<usize>, Option<usize>),
    data: Data<'_>,
    limits: &GeometryLimits,
    vertex_count: usize,
    path: &str,
) -> Result<Option<Displacement>, SceneError> {
    if position.is_none() && normal.is_none() {
        return Ok(None);
    }
    let read = |index: Option<usize>| {
        index
            .map(|i| data.floats::<3>(root, i, limits.max_vertices))
            .transpose()
            .map_err(accessor_error)
    };
    let displacement = Displacement {
        positions: read(position)?,
        normals: read(normal)?,
    };
    for (name, delta) in [
        ("POSITION", &displacement.positions),
        ("NORMAL", &displacement.normals),
    ] {
        if delta.as_ref().is_some_and(|d| d.len() != vertex_count) {
            return Err(SceneError::new(
                ProblemCode::InvalidPrimitive,
                format!("{path}.{name} does not have one element per vertex"),
            ));
        }
    }
    Ok(Some(displacement))
}

fn displaced(base: &[[f32; 3]], displacement: &Option<Vec<[f32; 3]>>) -> Vec<[f32; 3]> {
    match displacement {
        None => base.to_vec(),
        Some(d) => base
            .iter()
            .zip(d)
            .map(|(a, d)| [a[0] + d[0], a[1] + d[1], a[2] + d[2]])
            .collect(),
    }
}

/// Tangents of the mesh as the target deforms it: same UVs and triangles, so corner for corner
/// comparable with the base.
fn morphed_tangents(
    geometry: &Geometry<'_>,
    displacement: &Displacement,
    run: &Run<'_>,
) -> Result<Tangents, CoreError> {
    let positions = displaced(&geometry.positions, &displacement.positions);
    let normals = geometry.normals.as_ref().map(|n| {
        let mut morphed = displaced(n, &displacement.normals);
        normalize(&mut morphed);
        morphed
    });
    tangent::generate_cancellable(
        &MeshInput {
            positions: &positions,
            normals: normals.as_deref(),
            uvs: geometry.uvs.as_deref(),
            indices: geometry.indices.as_deref(),
        },
        run.options,
        run.cancel,
    )
}

/// Per output vertex of the base, the morphed tangent minus the base one, and how many corners
/// flip handedness under the target. glTF gives a target one TANGENT displacement per vertex,
/// so a vertex whose corners disagree once morphed takes its first corner's. `indices` are the
/// geometry's, for which both were computed.
fn tangent_deltas(
    base: &SplitPlan,
    morphed: &Tangents,
    indices: Option<&[u32]>,
) -> (Vec<[f32; 3]>, u64) {
    let mut deltas = vec![[0.0f32; 3]; base.vertex_tangents.len()];
    let mut seen = vec![false; base.vertex_tangents.len()];
    let mut handedness_changes = 0;
    for (corner, &v) in base.indices_for(indices).iter().enumerate() {
        let v = v as usize;
        let (Some(done), Some(b)) = (seen.get_mut(v), base.vertex_tangents.get(v)) else {
            continue;
        };
        let m = morphed.corner_tangent(corner, indices);
        if m[3] != b[3] {
            handedness_changes += 1;
        }
        if !*done {
            *done = true;
            deltas[v] = [m[0] - b[0], m[1] - b[1], m[2] - b[2]];
        }
    }
    (deltas, handedness_changes)
}

/// How to run the core on one geometry.
pub struct Run<'a> {
    pub options: &'a Options,
    pub limits: &'a GeometryLimits,
    /// Stops the core, and the morph targets not yet begun.
    pub cancel: &'a Cancel,
}

/// Runs the core on a key's geometry and on each of its morph targets.
pub fn compute<'a>(
    root: &Node,
    key: &GeometryKey,
    data: Data<'a>,
    run: &Run<'_>,
    path: &str,
) -> Result<Computed<'a>, SceneError> {
    let limits = run.limits;
    let mut geometry = read_geometry(root, key, data, limits)?;
    keep_whole_triangles(&mut geometry, key.topology, path)?;
    let tangents = tangent::generate_cancellable(&geometry.input(), run.options, run.cancel)
        .map_err(|e| core_error(path, e))?;

    let mut target_deltas = Vec::with_capacity(key.targets.len());
    let mut morph_handedness_changes = 0;
    for (t, &target) in key.targets.iter().enumerate() {
        let target_path = format!("{path}.targets[{t}]");
        let vertex_count = geometry.positions.len();
        let Some(displacement) =
            read_displacement(root, target, data, limits, vertex_count, &target_path)?
        else {
            target_deltas.push(None);
            continue;
        };
        let morphed = morphed_tangents(&geometry, &displacement, run)
            .map_err(|e| core_error(&target_path, e))?;
        let indices = geometry.indices.as_deref();
        let (deltas, handedness_changes) = tangent_deltas(&tangents.split, &morphed, indices);
        morph_handedness_changes += handedness_changes;
        target_deltas.push(Some(deltas));
    }
    Ok(Computed {
        geometry,
        tangents,
        target_deltas,
        morph_handedness_changes,
    })
}

fn angle_degrees(a: [f32; 3], b: [f32; 3]) -> f32 {
    let la = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let lb = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
    if la == 0.0 || lb == 0.0 || !la.is_finite() || !lb.is_finite() {
        return 180.0;
    }
    let cos = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (la * lb);
    cos.clamp(-1.0, 1.0).acos().to_degrees()
}

/// A kept tangent as a renderer uses it: made orthogonal to the normal (Gram-Schmidt), as the
/// glTF sample viewer's shaders and MikkTSpace's own output are. Comparing the raw vector would
/// count the tilt that a renderer removes as disagreement. Without a usable normal it stays.
fn as_rendered(t: [f32; 3], normal: Option<&[f32; 3]>) -> [f32; 3] {
    let Some(n) = normal else { return t };
    let nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    if nn <= 0.0 || !nn.is_finite() {
        return t;
    }
    let along = (t[0] * n[0] + t[1] * n[1] + t[2] * n[2]) / nn;
    [
        t[0] - along * n[0],
        t[1] - along * n[1],
        t[2] - along * n[2],
    ]
}

/// Compares a primitive's own tangents with MikkTSpace's.
pub fn audit(existing: &[[f32; 4]], computed: &Computed, quantized: bool) -> Result<Audit, String> {
    let geometry = &computed.geometry;
    if existing.len() != geometry.positions.len() {
        return Err("TANGENT does not have one element per vertex".into());
    }
    // Quantized tangents (8- or 16-bit) are only as unit and orthogonal as their precision.
    let tolerance = if quantized { 2e-2 } else { 1e-3 };
    let mut non_unit = Tally::default();
    let mut non_orthogonal = Tally::default();
    let mut invalid = Tally::default();
    for (v, t) in existing.iter().enumerate() {
        let xyz = [t[0], t[1], t[2]];
        if !t.iter().all(|c| c.is_finite()) || t[3].abs() != 1.0 {
            invalid.add(v as u32);
            continue;
        }
        let length = (xyz[0] * xyz[0] + xyz[1] * xyz[1] + xyz[2] * xyz[2]).sqrt();
        if (length - 1.0).abs() > tolerance {
            non_unit.add(v as u32);
        }
        if let Some(n) = geometry.normals.as_ref().and_then(|n| n.get(v)) {
            let ln = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if ln > 0.0 && length > 0.0 {
                let cos = (xyz[0] * n[0] + xyz[1] * n[1] + xyz[2] * n[2]) / (ln * length);
                if cos.abs() > tolerance {
                    non_orthogonal.add(v as u32);
                }
            }
        }
    }
    let corners = geometry.triangle_count() * 3;
    let mut angles = Vec::with_capacity(corners);
    let mut w_disagreements = Tally::default();
    let mut corners_disagreeing = 0u64;
    for corner in 0..corners {
        let Some(e) = existing.get(geometry.corner_vertex(corner)) else {
            continue;
        };
        let m = computed
            .tangents
            .corner_tangent(corner, geometry.indices.as_deref());
        let other_w = (e[3] < 0.0) != (m[3] < 0.0);
        if other_w {
            w_disagreements.add(corner as u32);
        }
        let vertex = geometry.corner_vertex(corner);
        let normal = geometry.normals.as_ref().and_then(|n| n.get(vertex));
        let seen = as_rendered([e[0], e[1], e[2]], normal);
        let angle = angle_degrees(seen, [m[0], m[1], m[2]]);
        if other_w || angle > 1.0 {
            corners_disagreeing += 1;
        }
        angles.push(angle);
    }
    let mut sorted = angles;
    sorted.sort_unstable_by(f32::total_cmp);
    let at = |q: f64| -> f32 {
        if sorted.is_empty() {
            return 0.0;
        }
        let i = ((sorted.len() - 1) as f64 * q).round() as usize;
        sorted.get(i).copied().unwrap_or(0.0)
    };
    let over_1 = sorted.iter().filter(|&&a| a > 1.0).count() as u64;
    // glTF asks tangents to be unit with w = ±1, not orthogonal to the normal (renderers
    // orthogonalize), so non_orthogonal alone is counted but is no verdict.
    let verdict = if !invalid.is_empty() || !non_unit.is_empty() {
        "invalid"
    } else if corners_disagreeing > 0 {
        "differs"
    } else {
        "matches"
    };
    Ok(Audit {
        verdict,
        corners: corners as u64,
        corners_disagreeing,
        w_disagreements: TallyReport::from(&w_disagreements),
        angle_median_degrees: at(0.5),
        angle_p99_degrees: at(0.99),
        angle_max_degrees: at(1.0),
        corners_over_1_degree: over_1,
        non_unit: TallyReport::from(&non_unit),
        non_orthogonal: TallyReport::from(&non_orthogonal),
        invalid: TallyReport::from(&invalid),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A quad in the XY plane facing +Z, UVs along X and Y: MikkTSpace's tangents are +X.
    fn quad() -> Computed<'static> {
        let geometry = Geometry {
            positions: Cow::Owned(vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ]),
            normals: Some(Cow::Owned(vec![[0.0, 0.0, 1.0]; 4])),
            uvs: Some(Cow::Owned(vec![
                [0.0, 1.0],
                [1.0, 1.0],
                [1.0, 0.0],
                [0.0, 0.0],
            ])),
            indices: Some(Cow::Owned(vec![0, 1, 2, 0, 2, 3])),
        };
        let tangents = tangent::generate(&geometry.input(), &Options::default()).unwrap();
        Computed {
            geometry,
            tangents,
            target_deltas: vec![],
            morph_handedness_changes: 0,
        }
    }

    #[test]
    fn audit_compares_tangents_as_rendered_and_tilt_alone_is_not_invalid() {
        let computed = quad();
        let reference = computed
            .tangents
            .corner_tangent(0, computed.geometry.indices.as_deref());
        assert!((reference[0] - 1.0).abs() < 1e-6, "{reference:?}");
        // Tilted 20° out of the surface toward the normal: a renderer's Gram-Schmidt step
        // removes the tilt, so it matches, but it is counted as not orthogonal.
        let (s, c) = 20f32.to_radians().sin_cos();
        let tilted = vec![[c, 0.0, s, reference[3]]; 4];
        let found = audit(&tilted, &computed, false).unwrap();
        assert_eq!(found.verdict, "matches");
        assert_eq!(found.corners_disagreeing, 0);
        assert_eq!(found.non_orthogonal.count, 4);
        // Turned 20° within the surface, and one vertex of the other handedness: differs.
        let mut turned = vec![[c, s, 0.0, reference[3]]; 4];
        turned[3][3] = -reference[3];
        let found = audit(&turned, &computed, false).unwrap();
        assert_eq!(found.verdict, "differs");
        assert_eq!(found.corners_disagreeing, 6);
        assert_eq!(found.w_disagreements.count, 1);
        // Not unit: invalid, whatever the angles.
        let long = vec![[2.0, 0.0, 0.0, reference[3]]; 4];
        assert_eq!(audit(&long, &computed, false).unwrap().verdict, "invalid");
    }

    #[test]
    fn strips_and_fans_unroll_with_consistent_winding() {
        let strip = triangle_list(Topology::Strip, None, 5).unwrap();
        assert_eq!(*strip, [0, 1, 2, 1, 3, 2, 2, 3, 4]);
        let fan = triangle_list(Topology::Fan, Some(Cow::Owned(vec![7, 8, 9, 10])), 11).unwrap();
        assert_eq!(*fan, [8, 9, 7, 9, 10, 7]);
        let short = triangle_list(Topology::Strip, Some(Cow::Owned(vec![1, 2])), 3).unwrap();
        assert!(short.is_empty());
        assert_eq!(triangle_list(Topology::Triangles, None, 3), None);
    }
}
