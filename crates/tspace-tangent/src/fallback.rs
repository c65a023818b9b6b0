//! The last line of defence: every corner leaves the core with a finite, unit tangent orthogonal
//! to its normal.
//!
//! The rule, in order, for a corner whose tangent fails that test:
//! 1. if the tangent is finite and keeps some length (> 1e-3) in the plane of the normal, it is
//!    projected into that plane and normalized (this fixes tangents computed against a normal
//!    that was not unit length);
//! 2. otherwise the corner's own triangle's dP/du, projected into the plane, if it has length;
//! 3. otherwise the normal crossed with its least-aligned world axis (see `any_orthogonal`).
//!
//! "Its normal" is the input normal, normalized; where that is zero or not finite, the face
//! normal of the corner's triangle; where that fails too, +Z.
//!
//! A corner that had no tangent at all takes its orientation from its own triangle's UV winding
//! (the reference would leave it at "not preserving").

use super::diagnostics::FallbackCounts;
use super::math::{
    Mesh, any_orthogonal, dot, face_normal, is_finite3, length, reject, scale, sub, unit,
};
use rayon::prelude::*;

/// Tolerances a tangent must meet to be passed through untouched. They are tighter than the
/// guarantees we document (unit within 1e-5, orthogonal within 1e-4) to leave room for rounding.
const UNIT_TOLERANCE: f32 = 4e-6;
const ORTHOGONAL_TOLERANCE: f32 = 4e-5;

/// The normal a corner's tangent must be orthogonal to.
pub(crate) fn effective_normal(mesh: &Mesh<'_>, corner: usize) -> [f32; 3] {
    let n = mesh.normals[mesh.indices[corner] as usize];
    if let Some(unit) = unit(n) {
        return unit;
    }
    let [a, b, c] = mesh.triangle(corner / 3);
    face_normal(mesh.positions[a], mesh.positions[b], mesh.positions[c]).unwrap_or([0.0, 0.0, 1.0])
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Problem {
    Unassigned,
    ZeroLength,
    NonFinite,
    NotOrthogonal,
}

fn check(tangent: &[f32; 4], normal: [f32; 3]) -> Option<Problem> {
    check_within(tangent, normal, ORTHOGONAL_TOLERANCE)
}

fn check_within(
    tangent: &[f32; 4],
    normal: [f32; 3],
    orthogonal_tolerance: f32,
) -> Option<Problem> {
    if tangent[3] == 0.0 {
        return Some(Problem::Unassigned);
    }
    let t = [tangent[0], tangent[1], tangent[2]];
    if !is_finite3(t) {
        return Some(Problem::NonFinite);
    }
    let len2 = dot(t, t);
    if len2 < 1e-12 {
        return Some(Problem::ZeroLength);
    }
    if (len2 - 1.0).abs() > 2.0 * UNIT_TOLERANCE || dot(t, normal).abs() > orthogonal_tolerance {
        return Some(Problem::NotOrthogonal);
    }
    None
}

/// A normal close enough to unit length (within 1e-6) that the orthogonality test against it
/// stands for the test against its normalization.
#[inline]
pub(crate) fn is_nearly_unit(n: [f32; 3]) -> bool {
    (dot(n, n) - 1.0).abs() < 1e-6
}

/// What a vertex's tangents are tested against with [`passes`], to know that [`repair_corner`]
/// would leave them alone.
#[derive(Clone, Copy)]
pub(crate) struct NormalCheck {
    normal: [f32; 3],
    orthogonal_tolerance: f32,
}

/// The test for a vertex with normal `n`, made once per vertex where [`repair_corner`] would redo
/// it per corner: against `n` itself when it is nearly unit; else against `n` as it is, with the
/// tolerance scaled by its length (`|t·n| <= tol |n|` is `|t·n/|n|| <= tol`, without the
/// division that normalizing takes, which was most of this test's time on meshes whose normals
/// are stored a little off unit length) and made 10% tighter than [`repair_corner`]'s, which
/// covers the f32 rounding (under 1e-6) so that a pass here is a pass there (a tangent failing
/// here only for that margin is checked there again and left alone). `None` when `n` has no
/// direction: then each corner needs the full check.
#[inline]
pub(crate) fn check_normal(n: [f32; 3]) -> Option<NormalCheck> {
    if is_nearly_unit(n) {
        return Some(NormalCheck {
            normal: n,
            orthogonal_tolerance: ORTHOGONAL_TOLERANCE,
        });
    }
    let len2 = dot(n, n);
    // Squares far from f32's limits: the f32 length is accurate to a few ulps.
    if (1e-20..=1e20).contains(&len2) {
        return Some(NormalCheck {
            normal: n,
            orthogonal_tolerance: 0.9 * ORTHOGONAL_TOLERANCE * len2.sqrt(),
        });
    }
    unit(n).map(|normal| NormalCheck {
        normal,
        orthogonal_tolerance: ORTHOGONAL_TOLERANCE,
    })
}

/// [`check_normal`] without a branch, for a loop over many normals to run as a vector loop: the
/// tolerance it sets against the normal as it is, and whether it does (in the rare other case,
/// a normal too short or too long to test as it is, it normalizes it first).
#[inline(always)]
pub(crate) fn normal_tolerance(n: [f32; 3]) -> (f32, bool) {
    let len2 = dot(n, n);
    let nearly_unit = is_nearly_unit(n);
    let scaled = 0.9 * ORTHOGONAL_TOLERANCE * len2.sqrt();
    let tolerance = if nearly_unit {
        ORTHOGONAL_TOLERANCE
    } else {
        scaled
    };
    (tolerance, nearly_unit | ((1e-20..=1e20).contains(&len2)))
}

/// [`passes`] for a tangent whose `w` is ±1 against `normal` at the `tolerance` of
/// [`normal_tolerance`], as one expression without a branch (the same tests: a finite tangent
/// has a finite squared length, and no comparison after the first meets NaN).
#[inline(always)]
pub(crate) fn passes_within(t: [f32; 3], normal: [f32; 3], tolerance: f32) -> bool {
    let finite = t[0].is_finite() & t[1].is_finite() & t[2].is_finite();
    let len2 = dot(t, t);
    finite
        & (len2 >= 1e-12)
        & ((len2 - 1.0).abs() <= 2.0 * UNIT_TOLERANCE)
        & (dot(t, normal).abs() <= tolerance)
}

/// The common case, decided without normalizing anything per corner.
#[inline]
pub(crate) fn passes(tangent: &[f32; 4], check: &NormalCheck) -> bool {
    check_within(tangent, check.normal, check.orthogonal_tolerance).is_none()
}

#[inline]
fn obviously_valid(mesh: &Mesh<'_>, corner: usize, tangent: &[f32; 4]) -> bool {
    let n = mesh.normals[mesh.indices[corner] as usize];
    is_nearly_unit(n) && check(tangent, n).is_none()
}

/// Projects `v` into the plane of the unit `normal` and normalizes it, if enough is left.
fn in_plane(v: [f32; 3], normal: [f32; 3]) -> Option<[f32; 3]> {
    let v = unit(v)?;
    let p = reject(v, normal);
    let len = length(p);
    if len > 1e-3 {
        // Twice: one projection of a nearly parallel vector can leave a residue of the normal.
        unit(reject(scale(p, 1.0 / len), normal))
    } else {
        None
    }
}

/// The triangle's dP/du and the sign of its UV area.
fn triangle_tangent(mesh: &Mesh<'_>, triangle: usize) -> ([f32; 3], f32) {
    let [a, b, c] = mesh.triangle(triangle);
    let (p0, p1, p2) = (mesh.positions[a], mesh.positions[b], mesh.positions[c]);
    let (t0, t1, t2) = (mesh.uv(a), mesh.uv(b), mesh.uv(c));
    let (e1, e2) = (sub(p1, p0), sub(p2, p0));
    let (du1, dv1, du2, dv2) = (t1[0] - t0[0], t1[1] - t0[1], t2[0] - t0[0], t2[1] - t0[1]);
    let det = du1 * dv2 - dv1 * du2;
    let s = sub(scale(e1, dv2), scale(e2, dv1));
    let sign = if det > 0.0 {
        1.0
    } else if det < 0.0 {
        -1.0
    } else {
        0.0
    };
    (scale(s, sign), det)
}

/// Replaces the tangent of `corner` if it is invalid, and says why it was.
pub(crate) fn repair_corner(
    mesh: &Mesh<'_>,
    corner: usize,
    tangent: &mut [f32; 4],
) -> Option<Problem> {
    if obviously_valid(mesh, corner, tangent) {
        return None;
    }
    let normal = effective_normal(mesh, corner);
    let problem = check(tangent, normal)?;
    let (own, det) = triangle_tangent(mesh, corner / 3);
    let projected = match problem {
        Problem::NotOrthogonal => in_plane([tangent[0], tangent[1], tangent[2]], normal),
        _ => None,
    };
    let replacement = projected
        .or_else(|| in_plane(own, normal))
        .unwrap_or_else(|| any_orthogonal(normal));
    let w = match problem {
        Problem::Unassigned => {
            if det > 0.0 {
                1.0
            } else {
                -1.0
            }
        }
        _ => tangent[3],
    };
    *tangent = [replacement[0], replacement[1], replacement[2], w];
    Some(problem)
}

/// The last step of a method's corner, shared by the methods that build the split plan as they
/// go: repair unless already `known_valid` (recording why in `repairs`), then apply the
/// UV-origin convention to `w`.
#[inline]
pub(crate) fn finish_corner(
    mesh: &Mesh<'_>,
    corner: usize,
    tangent: [f32; 4],
    known_valid: bool,
    flip_w: bool,
    repairs: &mut Vec<(u32, Problem)>,
) -> [f32; 4] {
    if known_valid {
        return with_w_convention(tangent, flip_w);
    }
    // Out of line, so that the common path above keeps the tangent in registers: negating `w`
    // in memory right after a call that takes its address made the next 16-byte load wait on a
    // failed store forward, a fifth of the per-vertex bookkeeping.
    repair_and_convert(mesh, corner, tangent, flip_w, repairs)
}

#[inline]
pub(crate) fn with_w_convention(tangent: [f32; 4], flip_w: bool) -> [f32; 4] {
    // Negation as a sign-bit mask over all four lanes: one vector xor, where negating the
    // fourth lane alone was assembled from partial stores that the caller's 16-byte load could
    // not forward from.
    let mask = if flip_w {
        [0, 0, 0, 1u32 << 31]
    } else {
        [0; 4]
    };
    let mut out = [0.0f32; 4];
    for ((o, t), m) in out.iter_mut().zip(tangent).zip(mask) {
        *o = f32::from_bits(t.to_bits() ^ m);
    }
    out
}

#[inline(never)]
fn repair_and_convert(
    mesh: &Mesh<'_>,
    corner: usize,
    mut tangent: [f32; 4],
    flip_w: bool,
    repairs: &mut Vec<(u32, Problem)>,
) -> [f32; 4] {
    if let Some(problem) = repair_corner(mesh, corner, &mut tangent) {
        repairs.push((corner as u32, problem));
    }
    with_w_convention(tangent, flip_w)
}

/// Replaces every invalid tangent and counts what was replaced.
pub(crate) fn repair(mesh: &Mesh<'_>, corners: &mut [[f32; 4]], parallel: bool) -> FallbackCounts {
    const CHUNK: usize = 16384;
    let run = |(chunk_index, chunk): (usize, &mut [[f32; 4]])| {
        let mut counts = FallbackCounts::default();
        for (k, tangent) in chunk.iter_mut().enumerate() {
            let corner = chunk_index * CHUNK + k;
            if let Some(problem) = repair_corner(mesh, corner, tangent) {
                counts.add(corner as u32, problem);
            }
        }
        counts
    };
    let parts: Vec<FallbackCounts> = if parallel {
        corners.par_chunks_mut(CHUNK).enumerate().map(run).collect()
    } else {
        corners.chunks_mut(CHUNK).enumerate().map(run).collect()
    };
    parts
        .into_iter()
        .fold(FallbackCounts::default(), |mut all, part| {
            all.corners.append(&part.corners);
            all.all_corners.extend(&part.all_corners);
            all.unassigned += part.unassigned;
            all.zero_length += part.zero_length;
            all.non_finite += part.non_finite;
            all.not_orthogonal += part.not_orthogonal;
            all
        })
}

impl FallbackCounts {
    pub(crate) fn add(&mut self, corner: u32, problem: Problem) {
        self.corners.add(corner);
        self.all_corners.push(corner);
        match problem {
            Problem::Unassigned => self.unassigned += 1,
            Problem::ZeroLength => self.zero_length += 1,
            Problem::NonFinite => self.non_finite += 1,
            Problem::NotOrthogonal => self.not_orthogonal += 1,
        }
    }

    /// Counts repairs recorded in any order (as parallel workers record them).
    pub(crate) fn from_unordered(mut repairs: Vec<(u32, Problem)>) -> FallbackCounts {
        repairs.sort_unstable_by_key(|&(corner, _)| corner);
        let mut counts = FallbackCounts::default();
        for (corner, problem) in repairs {
            counts.add(corner, problem);
        }
        counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::add;
    use proptest::prelude::*;

    /// A tangent almost orthogonal to `n`: its unit projection into `n`'s plane, tilted towards
    /// `n` by about `tilt`.
    fn near_orthogonal(n: [f32; 3], seed: [f32; 3], tilt: f32) -> Option<[f32; 4]> {
        let n = unit(n)?;
        let t = unit(add(unit(reject(seed, n))?, scale(n, tilt)))?;
        Some([t[0], t[1], t[2], 1.0])
    }

    proptest! {
        /// The per-vertex test may reject what the per-corner check accepts (that corner is then
        /// checked again), never the other way round: that is what keeps the output unchanged.
        #[test]
        fn a_vertex_pass_is_a_corner_pass(
            n in prop::array::uniform3(-3.0f32..3.0),
            seed in prop::array::uniform3(-1.0f32..1.0),
            tilt in -6e-5f32..6e-5,
        ) {
            let Some(tangent) = near_orthogonal(n, seed, tilt) else { return Ok(()) };
            let Some(vertex) = check_normal(n) else { return Ok(()) };
            if passes(&tangent, &vertex) {
                prop_assert_eq!(check(&tangent, unit(n).unwrap()), None);
            }
        }

        /// The test without branches decides as `check_normal` and `passes` do, for every
        /// normal it takes as it is (nearly unit, or of any length the check scales its
        /// tolerance by), and tangents on both sides of the tolerance.
        #[test]
        fn the_branchless_test_decides_as_the_normal_check(
            n in prop::array::uniform3(-3.0f32..3.0),
            scale_exponent in -12i32..12,
            seed in prop::array::uniform3(-1.0f32..1.0),
            tilt in -6e-5f32..6e-5,
            stretch in 0.999_99f32..1.000_01,
        ) {
            let n = scale(n, 2f32.powi(scale_exponent));
            let Some(t) = near_orthogonal(n, seed, tilt) else { return Ok(()) };
            let t = [t[0] * stretch, t[1] * stretch, t[2] * stretch];
            for normal in [n, unit(n).unwrap_or(n)] {
                let (tolerance, as_it_is) = normal_tolerance(normal);
                if !as_it_is {
                    continue;
                }
                let corner = [t[0], t[1], t[2], 1.0];
                let expected = check_normal(normal).is_some_and(|c| passes(&corner, &c));
                prop_assert_eq!(passes_within(t, normal, tolerance), expected);
            }
        }
    }
}
