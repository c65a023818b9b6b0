//! The `fast` method: each triangle's dP/du and dP/dv (the UV-edge matrix inverse, as in Lengyel
//! and Eberly), accumulated per welded vertex with angle or area weights, then Gram–Schmidt
//! against the normal. Mirrored triangles accumulate separately from the others, so a vertex on
//! a mirror seam is split instead of averaging two opposite frames into nothing.

use super::Weighting;
use super::diagnostics::{Diagnostics, FallbackCounts};
use super::fallback::{self, Problem};
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
    /// Twice the position area (for area weighting).
    area: f32,
}

fn face(mesh: &Mesh<'_>, triangle: usize) -> Face {
    let [a, b, c] = mesh.triangle(triangle);
    let (p0, p1, p2) = (mesh.positions[a], mesh.positions[b], mesh.positions[c]);
    if same_position(p0, p1) || same_position(p1, p2) || same_position(p2, p0) {
        return Face::default();
    }
    let (t0, t1, t2) = (mesh.uv(a), mesh.uv(b), mesh.uv(c));
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
    let area = length(cross(e1, e2));
    Face {
        s,
        t,
        sign,
        area: if area.is_finite() { area } else { 0.0 },
    }
}

fn corner_angle(mesh: &Mesh<'_>, corner: usize) -> f32 {
    let base = corner - corner % 3;
    let i = corner % 3;
    let here = mesh.positions[mesh.indices[corner] as usize];
    let next = mesh.positions[mesh.indices[base + (i + 1) % 3] as usize];
    let prev = mesh.positions[mesh.indices[base + (i + 2) % 3] as usize];
    let (a, b) = (
        normalize_or_zero(sub(next, here)),
        normalize_or_zero(sub(prev, here)),
    );
    let angle = dot(a, b).clamp(-1.0, 1.0).acos();
    if angle.is_finite() { angle } else { 0.0 }
}

/// Fast tangents as a split plan: invalid ones repaired (counted in `diagnostics`), `w` negated
/// when `flip_w` is set.
pub(crate) fn generate(
    mesh: &Mesh<'_>,
    weighting: Weighting,
    parallel: bool,
    flip_w: bool,
    diagnostics: &mut Diagnostics,
) -> SplitPlan {
    let triangle_count = mesh.triangle_count();
    let faces: Vec<Face> = if parallel {
        (0..triangle_count)
            .into_par_iter()
            .with_min_len(4096)
            .map(|t| face(mesh, t))
            .collect()
    } else {
        (0..triangle_count).map(|t| face(mesh, t)).collect()
    };
    let weld = weld_mesh(mesh);
    let corner_class: Vec<u32> = mesh
        .indices
        .iter()
        .map(|&v| weld.class_of_vertex[v as usize])
        .collect();
    let table = CornerTable::build_filtered(&corner_class, weld.class_count, |_| true, parallel);

    let weight = |corner: usize| -> f32 {
        match weighting {
            Weighting::Angle => corner_angle(mesh, corner),
            Weighting::Area => faces[corner / 3].area,
        }
    };

    // Per class: accumulate each handedness apart, then give every corner the sum of its side.
    let evaluate =
        |class: usize, repairs: &mut Vec<(u32, Problem)>, put: &mut dyn FnMut(usize, [f32; 4])| {
            let corners = table.of(class);
            let normal = mesh.normals[mesh.indices[corners[0] as usize] as usize];
            let normal_ok = fallback::is_nearly_unit(normal);
            // [preserving, mirrored] sums of s and t.
            let mut sums = [[[0.0f32; 3]; 2]; 2];
            for &corner in corners {
                let f = &faces[corner as usize / 3];
                if f.sign == 0.0 {
                    continue;
                }
                let side = usize::from(f.sign < 0.0);
                let w = weight(corner as usize);
                sums[side][0] = add(sums[side][0], scale(f.s, w));
                sums[side][1] = add(sums[side][1], scale(f.t, w));
            }
            let strongest = usize::from(dot(sums[1][0], sums[1][0]) > dot(sums[0][0], sums[0][0]));
            for &corner in corners {
                let corner = corner as usize;
                let f = &faces[corner / 3];
                let side = if f.sign == 0.0 {
                    strongest
                } else {
                    usize::from(f.sign < 0.0)
                };
                let tangent = normalize_or_zero(reject(sums[side][0], normal));
                let handedness = dot(cross(normal, tangent), sums[side][1]);
                let orientation_preserving = if handedness != 0.0 {
                    handedness > 0.0
                } else {
                    side == 0
                };
                let t = encode(tangent, orientation_preserving);
                let valid = normal_ok && fallback::passes(&t, normal);
                put(
                    corner,
                    fallback::finish_corner(mesh, corner, t, valid, flip_w, repairs),
                );
            }
        };

    let shared = SharedSplit::new(mesh.indices, mesh.vertex_count());
    let run = |range: std::ops::Range<usize>| {
        let mut copies = Copies::default();
        let mut repairs = Vec::new();
        let mut put = |c: usize, t: [f32; 4]| shared.put(&mut copies, c, t);
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
