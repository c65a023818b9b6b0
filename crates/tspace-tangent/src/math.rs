//! Small vector helpers on `[f32; 3]`, and the mesh view shared by the methods.
//!
//! The `[f32; 3]` arithmetic mirrors the operation order of the MikkTSpace reference, which the
//! bit-identical results depend on (`normalize_or_zero` multiplies by the reciprocal length and
//! leaves near-zero vectors alone, unlike glam's). Off that path, in f64, glam's `DVec3` does.

use glam::DVec3;

/// A validated, indexed triangle list with normals: what every method works on.
#[derive(Clone, Copy)]
pub(crate) struct Mesh<'a> {
    pub positions: &'a [[f32; 3]],
    pub normals: &'a [[f32; 3]],
    pub uvs: Option<&'a [[f32; 2]]>,
    /// Every entry is `< positions.len()`, and the length is a multiple of three.
    pub indices: &'a [u32],
}

impl Mesh<'_> {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// The three vertex indices of triangle `t`.
    #[inline]
    pub fn triangle(&self, t: usize) -> [usize; 3] {
        let i = &self.indices[3 * t..3 * t + 3];
        [i[0] as usize, i[1] as usize, i[2] as usize]
    }

    #[inline]
    pub fn uv(&self, v: usize) -> [f32; 2] {
        self.uvs.map_or([0.0; 2], |uvs| uvs[v])
    }
}

/// A method's result for one corner is written straight into the output buffer as `[x, y, z, w]`
/// with `w = +1` where the UV frame preserves orientation and `-1` where it is mirrored, before
/// the UV-origin convention is applied. `w = 0` marks a corner the method left without a tangent
/// (the reference leaves such corners at its (1,0,0) default).
pub(crate) const UNASSIGNED: [f32; 4] = [1.0, 0.0, 0.0, 0.0];

#[inline]
pub(crate) fn encode(tangent: [f32; 3], orientation_preserving: bool) -> [f32; 4] {
    let w = if orientation_preserving { 1.0 } else { -1.0 };
    [tangent[0], tangent[1], tangent[2], w]
}

#[inline]
pub(crate) fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
pub(crate) fn add(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline]
pub(crate) fn scale(a: [f32; 3], s: f32) -> [f32; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline]
pub(crate) fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub(crate) fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline]
pub(crate) fn length(a: [f32; 3]) -> f32 {
    dot(a, a).sqrt()
}

/// `|x| > FLT_MIN`, the reference's test for "not zero" (false for NaN).
#[inline]
pub(crate) fn not_zero(x: f32) -> bool {
    x.abs() > f32::MIN_POSITIVE
}

/// The reference's normalization: multiply by the reciprocal length unless every component is
/// (nearly) zero, in which case the vector is returned unchanged.
#[inline]
pub(crate) fn normalize_or_zero(a: [f32; 3]) -> [f32; 3] {
    if not_zero(a[0]) || not_zero(a[1]) || not_zero(a[2]) {
        scale(a, 1.0 / length(a))
    } else {
        a
    }
}

/// [`normalize_or_zero`] written as a select, so that a loop around it vectorizes (same
/// results).
#[inline(always)]
pub(crate) fn normalize_or_zero_branchless(a: [f32; 3]) -> [f32; 3] {
    let keep = not_zero(a[0]) | not_zero(a[1]) | not_zero(a[2]);
    let scaled = scale(a, 1.0 / length(a));
    if keep { scaled } else { a }
}

/// `a` with its component along `n` removed: `a - (n·a) n`.
#[inline]
pub(crate) fn reject(a: [f32; 3], n: [f32; 3]) -> [f32; 3] {
    sub(a, scale(n, dot(n, a)))
}

#[inline]
pub(crate) fn is_finite3(a: [f32; 3]) -> bool {
    a[0].is_finite() && a[1].is_finite() && a[2].is_finite()
}

/// Float equality of two positions, as the reference compares them (`-0 == 0`, NaN never equal).
#[inline]
pub(crate) fn same_position(a: [f32; 3], b: [f32; 3]) -> bool {
    a[0] == b[0] && a[1] == b[1] && a[2] == b[2]
}

/// A unit vector orthogonal to the unit vector `n`, from the world axis least aligned with it.
/// Continuous except where the choice of axis changes.
#[inline]
pub(crate) fn any_orthogonal(n: [f32; 3]) -> [f32; 3] {
    let (ax, ay, az) = (n[0].abs(), n[1].abs(), n[2].abs());
    let axis = if ax <= ay && ax <= az {
        [1.0, 0.0, 0.0]
    } else if ay <= az {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let t = cross(n, axis);
    let len = length(t);
    if len > 0.0 && len.is_finite() {
        scale(t, 1.0 / len)
    } else {
        [1.0, 0.0, 0.0]
    }
}

/// `v` scaled to unit length, computed in f64 so that subnormal and huge vectors normalize too;
/// `None` for zero and non-finite vectors.
#[inline]
pub(crate) fn unit(v: [f32; 3]) -> Option<[f32; 3]> {
    if !is_finite3(v) {
        return None;
    }
    let v = DVec3::from(v.map(f64::from));
    let len = v.length();
    if len == 0.0 {
        return None;
    }
    Some((v / len).to_array().map(|x| x as f32))
}

/// The unit normal of a triangle, computed in f64 so that tiny and huge triangles work too;
/// `None` when the triangle has no area or a non-finite corner.
pub(crate) fn face_normal(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Option<[f32; 3]> {
    let [a, b, c] = [a, b, c].map(|p| DVec3::from(p.map(f64::from)));
    let n = (b - a).cross(c - a);
    let len = n.length();
    if len > 0.0 && len.is_finite() {
        Some((n / len).to_array().map(|x| x as f32))
    } else {
        None
    }
}
