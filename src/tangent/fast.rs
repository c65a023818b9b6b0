//! The `fast` method: each triangle's dP/du and dP/dv (the UV-edge matrix inverse, as in Lengyel
//! and Eberly), accumulated per welded vertex with angle or area weights, then Gram–Schmidt
//! against the normal. Mirrored triangles accumulate separately from the others, so a vertex on
//! a mirror seam is split instead of averaging two opposite frames into nothing.

use super::Weighting;
use super::diagnostics::{Diagnostics, FallbackCounts, TriangleCheck, TriangleTallies};
use super::fallback::{self, Problem};
use super::fill::filled;
use super::math::{
    Mesh, add, cross, dot, encode, is_finite3, length, normalize_or_zero, reject, same_position,
    scale, sub,
};
use super::output::{Copies, SharedSplit};
use super::split::SplitPlan;
use super::weld::{CornerTable, weld_mesh};
use rayon::prelude::*;

#[derive(Clone, Copy, Default)]
struct Face {
    /// Unit dP/du and dP/dv.
    s: [f32; 3],
    t: [f32; 3],
    /// +1 or -1 by the sign of the UV area; 0 when the triangle contributes nothing.
    sign: f32,
    /// The weight of each corner: its angle (angle weighting) or twice the triangle's area.
    weights: [f32; 3],
}

/// arccos to within 7e-5 rad (Abramowitz and Stegun 4.4.45). Weights need no more, and this is
/// a few multiplications where the exact one (as MikkTSpace must use) costs a libm call.
fn acos_approx(x: f32) -> f32 {
    let x = x.clamp(-1.0, 1.0);
    let a = x.abs();
    let r =
        (1.0 - a).sqrt() * (1.570_728_8 + a * (-0.212_114_4 + a * (0.074_261 - 0.018_729_3 * a)));
    let angle = if x < 0.0 { std::f32::consts::PI - r } else { r };
    if angle.is_finite() { angle } else { 0.0 }
}

/// The three corner angles of a triangle, from its three unit edges: each edge serves two
/// corners (negated for one of them, which is exact), so three normalizations do for six.
fn corner_angles(p: &[[f32; 3]; 3]) -> [f32; 3] {
    let e01 = normalize_or_zero(sub(p[1], p[0]));
    let e12 = normalize_or_zero(sub(p[2], p[1]));
    let e20 = normalize_or_zero(sub(p[0], p[2]));
    [
        acos_approx(-dot(e01, e20)),
        acos_approx(-dot(e12, e01)),
        acos_approx(-dot(e20, e12)),
    ]
}

fn face(p: &[[f32; 3]; 3], uv: &[[f32; 2]; 3], weighting: Weighting) -> Face {
    let [p0, p1, p2] = *p;
    if same_position(p0, p1) || same_position(p1, p2) || same_position(p2, p0) {
        return Face::default();
    }
    let [t0, t1, t2] = *uv;
    let (e1, e2) = (sub(p1, p0), sub(p2, p0));
    let (du1, dv1, du2, dv2) = (t1[0] - t0[0], t1[1] - t0[1], t2[0] - t0[0], t2[1] - t0[1]);
    let det = du1 * dv2 - dv1 * du2;
    // dP/du = (e1 dv2 - e2 dv1) / det, dP/dv = (e2 du1 - e1 du2) / det; only directions matter.
    let s = sub(scale(e1, dv2), scale(e2, dv1));
    let t = sub(scale(e2, du1), scale(e1, du2));
    let sign = if det > 0.0 {
        1.0
    } else if det < 0.0 {
        -1.0
    } else {
        0.0
    };
    let (s, t) = (
        normalize_or_zero(scale(s, sign)),
        normalize_or_zero(scale(t, sign)),
    );
    if sign == 0.0 || !is_finite3(s) || !is_finite3(t) || dot(s, s) == 0.0 {
        return Face::default();
    }
    // Weights are computed here, where the triangle's positions are at hand, rather than per
    // corner later, which would fetch them again in welded-vertex order.
    let weights = match weighting {
        Weighting::Area => {
            let area = length(cross(e1, e2));
            [if area.is_finite() { area } else { 0.0 }; 3]
        }
        Weighting::Angle => corner_angles(p),
    };
    Face {
        s,
        t,
        sign,
        weights,
    }
}

/// Fast tangents as a split plan: invalid ones repaired (counted in `diagnostics`), `w` negated
/// when `flip_w` is set.
pub(crate) fn generate(
    mesh: &Mesh<'_>,
    weighting: Weighting,
    parallel: bool,
    flip_w: bool,
    check: &TriangleCheck<'_>,
    diagnostics: &mut Diagnostics,
) -> SplitPlan {
    let triangle_count = mesh.triangle_count();
    let mut faces = filled(triangle_count, parallel, Face::default);
    // The diagnostics' triangle checks ride along: they read the same corners.
    const CHUNK: usize = 16384;
    let classify = |(chunk, faces): (usize, &mut [Face])| {
        let mut tallies = TriangleTallies::default();
        for (k, face_out) in faces.iter_mut().enumerate() {
            let t = chunk * CHUNK + k;
            let v = mesh.triangle(t);
            let p = [
                mesh.positions[v[0]],
                mesh.positions[v[1]],
                mesh.positions[v[2]],
            ];
            let uv = [mesh.uv(v[0]), mesh.uv(v[1]), mesh.uv(v[2])];
            *face_out = face(&p, &uv, weighting);
            check.check(&mut tallies, t, v, &p, &uv);
        }
        tallies
    };
    let triangles = if parallel {
        faces
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(classify)
            .collect::<Vec<_>>()
            .into_iter()
            .fold(TriangleTallies::default(), TriangleTallies::append)
    } else {
        faces
            .chunks_mut(CHUNK)
            .enumerate()
            .map(classify)
            .fold(TriangleTallies::default(), TriangleTallies::append)
    };
    diagnostics.set_triangles(triangles);
    let weld = weld_mesh(mesh, parallel);
    let corner_class: Vec<u32> = mesh
        .indices
        .iter()
        .map(|&v| weld.class_of_vertex[v as usize])
        .collect();
    let table = CornerTable::build_filtered(&corner_class, weld.class_count, |_| true, parallel);

    // Per class: accumulate each handedness apart, then give every corner the sum of its side.
    let evaluate =
        |class: usize, repairs: &mut Vec<(u32, Problem)>, put: &mut dyn FnMut(usize, [f32; 4])| {
            let corners = table.of(class);
            let normal = mesh.normals[mesh.indices[corners[0] as usize] as usize];
            let check_normal = fallback::check_normal(normal);
            // [preserving, mirrored] sums of s and t.
            let mut sums = [[[0.0f32; 3]; 2]; 2];
            for &corner in corners {
                let f = &faces[corner as usize / 3];
                if f.sign == 0.0 {
                    continue;
                }
                let side = usize::from(f.sign < 0.0);
                let w = f.weights[corner as usize % 3];
                sums[side][0] = add(sums[side][0], scale(f.s, w));
                sums[side][1] = add(sums[side][1], scale(f.t, w));
            }
            let strongest = usize::from(dot(sums[1][0], sums[1][0]) > dot(sums[0][0], sums[0][0]));
            // At most two tangents per vertex, one per side, each worked out once.
            let mut finished: [Option<([f32; 4], bool)>; 2] = [None; 2];
            for &corner in corners {
                let corner = corner as usize;
                let f = &faces[corner / 3];
                let side = if f.sign == 0.0 {
                    strongest
                } else {
                    usize::from(f.sign < 0.0)
                };
                let (t, valid) = *finished[side].get_or_insert_with(|| {
                    let tangent = normalize_or_zero(reject(sums[side][0], normal));
                    let handedness = dot(cross(normal, tangent), sums[side][1]);
                    let orientation_preserving = if handedness != 0.0 {
                        handedness > 0.0
                    } else {
                        side == 0
                    };
                    let t = encode(tangent, orientation_preserving);
                    (t, check_normal.is_some_and(|n| fallback::passes(&t, n)))
                });
                put(
                    corner,
                    fallback::finish_corner(mesh, corner, t, valid, flip_w, repairs),
                );
            }
        };

    let shared = SharedSplit::new(mesh.indices, mesh.vertex_count(), parallel);
    let run = |range: std::ops::Range<usize>| {
        let mut copies = Copies::default();
        let mut repairs = Vec::new();
        let mut put = |c: usize, t: [f32; 4]| shared.put(&mut copies, c, mesh.indices[c], t);
        for class in range {
            if !table.of(class).is_empty() {
                evaluate(class, &mut repairs, &mut put);
            }
        }
        (copies, repairs)
    };
    let results: Vec<(Copies, Vec<(u32, Problem)>)> = if parallel {
        table
            .chunks(rayon::current_num_threads() * 16)
            .into_par_iter()
            .map(run)
            .collect()
    } else {
        vec![run(0..weld.class_count)]
    };
    let mut parts = Vec::with_capacity(results.len());
    let mut all_repairs = Vec::new();
    for (copies, repairs) in results {
        parts.push(copies);
        all_repairs.extend(repairs);
    }
    diagnostics.fallback_tangents = FallbackCounts::from_unordered(all_repairs);
    shared.finish(parts, mesh.normals, diagnostics)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn approximate_arccosine_is_within_its_bound() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let x = -1.0 + 2.0 * f64::from(i) / 200_000.0;
            let error = (f64::from(acos_approx(x as f32)) - x.acos()).abs();
            worst = worst.max(error);
        }
        assert!(worst < 7.5e-5, "{worst}");
        assert_eq!(acos_approx(f32::NAN), 0.0);
    }
}
