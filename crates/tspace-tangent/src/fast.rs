//! The `fast` method: each triangle's dP/du and dP/dv (the UV-edge matrix inverse, as in Lengyel
//! and Eberly), accumulated per welded vertex with angle or area weights, then Gram–Schmidt
//! against the normal. Mirrored triangles accumulate separately from the others, so a vertex on
//! a mirror seam is split instead of averaging two opposite frames into nothing.

use super::Weighting;
use super::diagnostics::{Diagnostics, FallbackCounts, TriangleCheck};
use super::fallback::{self, Problem};
use super::fill::{Zeroable, zeroed};
use super::math::{
    Mesh, cross, dot, encode, is_finite3, length, normalize_or_zero, normalize_or_zero_branchless,
    same_position, scale, sub,
};
use super::output::{Copies, SharedSplit};
use super::split::SplitPlan;
use super::triangles::{BATCH, TriangleColumns, per_triangle_fold, per_triangle_pass};
use super::vectors::widest_vectors;
use super::weld::{CornerTable, NONE, weld_mesh};
use glam::Vec3;
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

// SAFETY: floats only; zero bytes are `Face::default()`.
unsafe impl Zeroable for Face {}

/// arccos to within 7e-5 rad (Abramowitz and Stegun 4.4.45). Weights need no more, and this is
/// a few multiplications where the exact one (as MikkTSpace must use) costs a libm call.
#[inline(always)]
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
#[inline(always)]
fn corner_angles(p: &[[f32; 3]; 3]) -> [f32; 3] {
    let e01 = normalize_or_zero_branchless(sub(p[1], p[0]));
    let e12 = normalize_or_zero_branchless(sub(p[2], p[1]));
    let e20 = normalize_or_zero_branchless(sub(p[0], p[2]));
    [
        acos_approx(-dot(e01, e20)),
        acos_approx(-dot(e12, e01)),
        acos_approx(-dot(e20, e12)),
    ]
}

/// Branch-free (every value is computed, then the right ones selected), so that the loop over a
/// batch (see [`super::triangles`]) vectorizes.
#[inline(always)]
fn face(p: &[[f32; 3]; 3], uv: &[[f32; 2]; 3], weighting: Weighting) -> Face {
    let [p0, p1, p2] = *p;
    let degenerate = same_position(p0, p1) | same_position(p1, p2) | same_position(p2, p0);
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
        normalize_or_zero_branchless(scale(s, sign)),
        normalize_or_zero_branchless(scale(t, sign)),
    );
    let usable = !degenerate & (sign != 0.0) & is_finite3(s) & is_finite3(t) & (dot(s, s) != 0.0);
    // Weights are computed here, where the triangle's positions are at hand, rather than per
    // corner later, which would fetch them again in welded-vertex order.
    let weights = match weighting {
        Weighting::Area => {
            let area = length(cross(e1, e2));
            [if area.is_finite() { area } else { 0.0 }; 3]
        }
        Weighting::Angle => corner_angles(p),
    };
    if usable {
        Face {
            s,
            t,
            sign,
            weights,
        }
    } else {
        Face::default()
    }
}

/// Faces of a batch of triangles, in columns until they are copied out.
struct FaceColumns {
    s: [[f32; BATCH]; 3],
    t: [[f32; BATCH]; 3],
    sign: [f32; BATCH],
    weights: [[f32; BATCH]; 3],
}

impl Default for FaceColumns {
    fn default() -> FaceColumns {
        FaceColumns {
            s: [[0.0; BATCH]; 3],
            t: [[0.0; BATCH]; 3],
            sign: [0.0; BATCH],
            weights: [[0.0; BATCH]; 3],
        }
    }
}

impl FaceColumns {
    widest_vectors! {
        /// Faces and check events of the gathered `triangles`; the faces go to `faces` (one per
        /// triangle of the batch).
        fn compute / compute_avx512 / compute_avx2 (
            &mut self,
            triangles: &mut TriangleColumns,
            check: &TriangleCheck<'_>,
            weighting: Weighting,
            faces: &mut [Face],
        ) => compute_portable
    }

    #[inline(always)]
    fn compute_portable(
        &mut self,
        triangles: &mut TriangleColumns,
        check: &TriangleCheck<'_>,
        weighting: Weighting,
        faces: &mut [Face],
    ) {
        let [sx, sy, sz] = &mut self.s;
        let [tx, ty, tz] = &mut self.t;
        let [w0, w1, w2] = &mut self.weights;
        for k in 0..triangles.lanes() {
            let (p, uv) = triangles.corners(k);
            let f = face(&p, &uv, weighting);
            (sx[k], sy[k], sz[k]) = (f.s[0], f.s[1], f.s[2]);
            (tx[k], ty[k], tz[k]) = (f.t[0], f.t[1], f.t[2]);
            (w0[k], w1[k], w2[k]) = (f.weights[0], f.weights[1], f.weights[2]);
            self.sign[k] = f.sign;
        }
        triangles.check(check);
        for (k, face) in faces.iter_mut().enumerate().take(BATCH) {
            *face = Face {
                s: [sx[k], sy[k], sz[k]],
                t: [tx[k], ty[k], tz[k]],
                sign: self.sign[k],
                weights: [w0[k], w1[k], w2[k]],
            };
        }
    }
}

/// What the corners of one welded vertex add up to, on each side of a mirror seam. Corners are
/// added in ascending order on both paths below, so their sums agree bit for bit.
#[derive(Clone, Copy)]
struct VertexSums {
    /// `[preserving, mirrored]` weighted sums of dP/du and dP/dv.
    s: [Vec3; 2],
    t: [Vec3; 2],
    /// Bit `side`: some corner's triangle lies on that side.
    sides_used: u8,
    /// Some corner's triangle has no side (no UV area); it takes the strongest side's tangent.
    unsigned: bool,
    /// The vertex of the first corner added, whose normal the vertex's tangents are made
    /// against (the welded vertices' normals are equal, but may differ in the sign of a zero).
    first_vertex: u32,
}

impl VertexSums {
    const EMPTY: VertexSums = VertexSums {
        s: [Vec3::ZERO; 2],
        t: [Vec3::ZERO; 2],
        sides_used: 0,
        unsigned: false,
        first_vertex: NONE,
    };

    #[inline(always)]
    fn add(&mut self, face: &Face, corner: usize, vertex: u32) {
        if self.first_vertex == NONE {
            self.first_vertex = vertex;
        }
        if face.sign == 0.0 {
            self.unsigned = true;
            return;
        }
        let side = usize::from(face.sign < 0.0);
        self.sides_used |= 1 << side;
        let w = face.weights[corner];
        self.s[side] += Vec3::from(face.s) * w;
        self.t[side] += Vec3::from(face.t) * w;
    }

    /// The side a corner of `face` takes: its own, or the strongest when it has none.
    #[inline(always)]
    fn side_of(&self, sign: f32) -> usize {
        if sign == 0.0 {
            usize::from(self.s[1].length_squared() > self.s[0].length_squared())
        } else {
            usize::from(sign < 0.0)
        }
    }

    /// The side every corner takes, when they all take one.
    fn only_side(&self) -> Option<usize> {
        let taken = self.sides_taken();
        (taken.count_ones() == 1).then(|| taken.trailing_zeros() as usize)
    }

    /// The sides some corner takes (bit `side`).
    fn sides_taken(&self) -> u8 {
        if self.unsigned {
            self.sides_used | 1 << self.side_of(0.0)
        } else {
            self.sides_used
        }
    }

    /// The tangent of `side` (Gram–Schmidt against the first corner's normal), and whether it
    /// passes the validity check there.
    fn tangent(&self, side: usize, mesh: &Mesh<'_>) -> ([f32; 4], bool) {
        let normal = mesh.normals[self.first_vertex as usize];
        let check_normal = fallback::check_normal(normal);
        let normal = Vec3::from(normal);
        let s = self.s[side];
        // normalize_or_zero is the reference's, which leaves a near-zero vector as it is for
        // the fallback to find.
        let tangent = normalize_or_zero((s - normal * normal.dot(s)).to_array());
        let handedness = normal.cross(Vec3::from(tangent)).dot(self.t[side]);
        let orientation_preserving = if handedness != 0.0 {
            handedness > 0.0
        } else {
            side == 0
        };
        let t = encode(tangent, orientation_preserving);
        (t, check_normal.is_some_and(|n| fallback::passes(&t, &n)))
    }
}

/// Vertices whose tangents [`FinishColumns`] computes at once.
const FINISH_LANES: usize = 16;

/// Each vertex's tangent on one side, a block of vertices at a time in columns: the steps of
/// [`VertexSums::tangent`], lane by lane (so the same bits), for vertices whose normal the
/// check takes as it is, as nearly all are. One vertex at a time, its chain of a square root,
/// a division and the checks after them was a third of DamagedHelmet's call (about 40 cycles a
/// vertex), and nothing else was there for the CPU to overlap it with.
struct FinishColumns {
    normal: [[f32; FINISH_LANES]; 3],
    s: [[f32; FINISH_LANES]; 3],
    t: [[f32; FINISH_LANES]; 3],
    /// The side taken (0 preserving, 1 mirrored), which decides `w` where the frame does not.
    side: [u32; FINISH_LANES],
    /// Each lane's tangent as a whole, read back one vertex at a time.
    tangent: [[f32; 4]; FINISH_LANES],
    valid: [bool; FINISH_LANES],
    /// Whether the normal is tested as it is, so that the lane's result stands.
    lane_ok: [bool; FINISH_LANES],
}

impl Default for FinishColumns {
    fn default() -> FinishColumns {
        FinishColumns {
            normal: [[0.0; FINISH_LANES]; 3],
            s: [[0.0; FINISH_LANES]; 3],
            t: [[0.0; FINISH_LANES]; 3],
            side: [0; FINISH_LANES],
            tangent: [[0.0; 4]; FINISH_LANES],
            valid: [false; FINISH_LANES],
            lane_ok: [false; FINISH_LANES],
        }
    }
}

impl FinishColumns {
    /// Places the tangent of `side` of `sums` in lane `k`.
    #[inline(always)]
    fn put(&mut self, k: usize, sums: &VertexSums, side: usize, mesh: &Mesh<'_>) {
        // An empty vertex takes no tangent; its lane computes one from zeros, not read.
        let normal = mesh
            .normals
            .get(sums.first_vertex as usize)
            .copied()
            .unwrap_or([0.0; 3]);
        let (s, t) = (sums.s[side].to_array(), sums.t[side].to_array());
        for axis in 0..3 {
            self.normal[axis][k] = normal[axis];
            self.s[axis][k] = s[axis];
            self.t[axis][k] = t[axis];
        }
        self.side[k] = side as u32;
    }

    /// Lane `k`'s tangent and whether it is valid, if its normal let the columns decide.
    #[inline(always)]
    fn get(&self, k: usize) -> Option<([f32; 4], bool)> {
        self.lane_ok[k].then(|| (self.tangent[k], self.valid[k]))
    }

    widest_vectors! {
        /// Every lane's tangent, as [`VertexSums::tangent`] makes it.
        fn compute / compute_avx512 / compute_avx2 (&mut self) => compute_portable
    }

    #[inline(always)]
    fn compute_portable(&mut self) {
        for k in 0..FINISH_LANES {
            let n = [self.normal[0][k], self.normal[1][k], self.normal[2][k]];
            let s = [self.s[0][k], self.s[1][k], self.s[2][k]];
            let t = [self.t[0][k], self.t[1][k], self.t[2][k]];
            // `s - normal * normal.dot(s)`, then the reference's normalization.
            let d = dot(n, s);
            let tangent =
                normalize_or_zero_branchless([s[0] - n[0] * d, s[1] - n[1] * d, s[2] - n[2] * d]);
            let handedness = dot(cross(n, tangent), t);
            let preserving = (handedness > 0.0) | ((handedness == 0.0) & (self.side[k] == 0));
            let w = if preserving { 1.0 } else { -1.0 };
            self.tangent[k] = [tangent[0], tangent[1], tangent[2], w];
            let (tolerance, tested_as_it_is) = fallback::normal_tolerance(n);
            self.valid[k] = fallback::passes_within(tangent, n, tolerance);
            self.lane_ok[k] = tested_as_it_is;
        }
    }
}

/// A vertex's tangents and verdicts on its two sides (only the sides its corners take are set).
type SideTangents = ([[f32; 4]; 2], [bool; 2]);

/// The tangents of the vertices of `block` (at most [`FINISH_LANES`]) on the sides their
/// corners take: the side a vertex takes alone (or side 0) in `columns`, the second side of a
/// vertex on a mirror seam and any vertex whose normal must be normalized for its check one by
/// one.
#[inline(always)]
fn finish_block(
    columns: &mut FinishColumns,
    block: &[VertexSums],
    mesh: &Mesh<'_>,
    finished: &mut [SideTangents; FINISH_LANES],
) {
    for (k, sums) in block.iter().enumerate() {
        let first = usize::from(sums.sides_taken() == 0b10);
        columns.put(k, sums, first, mesh);
    }
    columns.compute();
    for (k, (sums, tangents)) in block.iter().zip(finished.iter_mut()).enumerate() {
        // The caller's array holds the block before's; a side not taken is left zero.
        *tangents = ([[0.0; 4]; 2], [false; 2]);
        let taken = sums.sides_taken();
        let first = columns.side[k] as usize;
        for side in 0..2 {
            if taken & (1 << side) != 0 {
                let computed = if side == first { columns.get(k) } else { None };
                (tangents.0[side], tangents.1[side]) =
                    computed.unwrap_or_else(|| sums.tangent(side, mesh));
            }
        }
    }
}

/// Each vertex's tangents on the sides its corners take ([`finish_block`]), and where they take
/// one side and its tangent is valid, the finished tangent into `uniform`.
fn finish_sums(
    sums: &[VertexSums],
    mesh: &Mesh<'_>,
    flip_w: bool,
    uniform: &mut [[f32; 4]],
) -> Vec<SideTangents> {
    let mut finished = Vec::with_capacity(sums.len());
    let mut columns = FinishColumns::default();
    let mut tangents = [([[0.0; 4]; 2], [false; 2]); FINISH_LANES];
    for (block, uniform) in sums
        .chunks(FINISH_LANES)
        .zip(uniform.chunks_mut(FINISH_LANES))
    {
        finish_block(&mut columns, block, mesh, &mut tangents);
        for ((sums, uniform), &tangents) in block.iter().zip(uniform).zip(&tangents) {
            if let Some(side) = sums.only_side()
                && tangents.1[side]
            {
                *uniform = fallback::with_w_convention(tangents.0[side], flip_w);
            }
            finished.push(tangents);
        }
    }
    finished
}

/// Fast tangents as a split plan: invalid ones repaired (counted in `diagnostics`), `w` negated
/// when `flip_w` is set.
///
/// On one thread the triangle pass adds each face into its vertices' sums as it goes, and a
/// pass over the corners in triangle order hands out the tangents: no per-triangle faces, no
/// table of corners by vertex. On several threads the faces are kept and each thread sums the
/// vertices it owns from a corner table. Both add corners in ascending order and number the
/// split's copies by vertex, so they give the same bits.
pub(crate) fn generate(
    mesh: &Mesh<'_>,
    weighting: Weighting,
    parallel: bool,
    flip_w: bool,
    check: &TriangleCheck<'_>,
    diagnostics: &mut Diagnostics,
) -> SplitPlan {
    if parallel {
        generate_by_vertex(mesh, weighting, flip_w, check, diagnostics)
    } else {
        generate_by_triangle(mesh, weighting, flip_w, check, diagnostics)
    }
}

/// The one-thread path: sums scattered from the triangle pass.
fn generate_by_triangle(
    mesh: &Mesh<'_>,
    weighting: Weighting,
    flip_w: bool,
    check: &TriangleCheck<'_>,
    diagnostics: &mut Diagnostics,
) -> SplitPlan {
    // Between passes, a cancelled computation stops; its caller returns nothing of it.
    let cancelled = || check.cancel.is_cancelled();
    let weld = weld_mesh(mesh, check.all_vertices_finite(), false);
    if cancelled() {
        return SplitPlan::default();
    }
    let mut sums = vec![VertexSums::EMPTY; weld.class_count];
    let mut signs = vec![0.0f32; mesh.triangle_count()];
    let triangles = per_triangle_fold(
        mesh,
        check,
        |columns: &mut FaceColumns, triangles: &mut TriangleColumns| {
            let range = triangles.range();
            let mut faces = [Face::default(); BATCH];
            columns.compute(triangles, check, weighting, &mut faces);
            for (triangle, face) in range.zip(&faces) {
                signs[triangle] = face.sign;
                for (corner, &vertex) in mesh.indices[3 * triangle..3 * triangle + 3]
                    .iter()
                    .enumerate()
                {
                    let class = weld.class_of_vertex[vertex as usize] as usize;
                    sums[class].add(face, corner, vertex);
                }
            }
        },
    );
    diagnostics.set_triangles(triangles);
    if cancelled() {
        return SplitPlan::default();
    }

    // Each vertex's tangents, one per side its corners take, worked out once; and, where its
    // corners take one side and that tangent is valid, the finished tangent every corner gets
    // (`w == 0` elsewhere, never the `w` of a finished tangent).
    let mut uniform = vec![[0.0f32; 4]; sums.len()];
    let finished = finish_sums(&sums, mesh, flip_w, &mut uniform);

    let shared = SharedSplit::new(mesh.indices, mesh.vertex_count(), false);
    let mut copies = Copies::default();
    let mut repairs = Vec::new();
    for (triangle, &sign) in signs.iter().enumerate() {
        for corner in 3 * triangle..3 * triangle + 3 {
            let vertex = mesh.indices[corner] as usize;
            let class = weld.class_of_vertex[vertex] as usize;
            // Most vertices: one tangent for all their corners, so no other corner of this
            // vertex can be given another, and a plain store does what `put` would, without
            // reading the vertex's sums, its finished tangents and its slot first.
            let only = uniform[class];
            if only[3] != 0.0 {
                shared.set_only_tangent(vertex, only);
                continue;
            }
            let side = sums[class].side_of(sign);
            let (tangents, valid) = &finished[class];
            let tangent = fallback::finish_corner(
                mesh,
                corner,
                tangents[side],
                valid[side],
                flip_w,
                &mut repairs,
            );
            shared.put(&mut copies, corner, tangent);
        }
    }
    copies.reorder_by(|vertex, corner| (weld.class_of_vertex[vertex as usize], corner));
    diagnostics.fallback_tangents = FallbackCounts::from_unordered(repairs);
    shared.finish(vec![copies], mesh.normals, diagnostics)
}

/// The parallel path: faces kept per triangle, each vertex summed from its corners.
fn generate_by_vertex(
    mesh: &Mesh<'_>,
    weighting: Weighting,
    flip_w: bool,
    check: &TriangleCheck<'_>,
    diagnostics: &mut Diagnostics,
) -> SplitPlan {
    let parallel = true;
    let triangle_count = mesh.triangle_count();
    // Written in order, by the triangle pass, for every triangle.
    let mut faces = zeroed::<Face>(triangle_count);
    let triangles = per_triangle_pass(
        mesh,
        check,
        &mut faces[..],
        parallel,
        |columns: &mut FaceColumns, triangles, faces| {
            columns.compute(triangles, check, weighting, faces);
        },
    );
    diagnostics.set_triangles(triangles);
    // Between passes, a cancelled computation stops; its caller returns nothing of it.
    if check.cancel.is_cancelled() {
        return SplitPlan::default();
    }
    let weld = weld_mesh(mesh, check.all_vertices_finite(), parallel);
    if check.cancel.is_cancelled() {
        return SplitPlan::default();
    }
    let corner_class = weld.corner_classes(mesh.indices, parallel);
    let table = CornerTable::build_filtered(&corner_class, weld.class_count, |_| true, parallel);

    let shared = SharedSplit::new(mesh.indices, mesh.vertex_count(), parallel);
    // Per class: accumulate each handedness apart, then give every corner the sum of its side.
    let sum_class = |class: usize| {
        let mut sums = VertexSums::EMPTY;
        for &corner in table.of(class) {
            let corner = corner as usize;
            sums.add(&faces[corner / 3], corner % 3, mesh.indices[corner]);
        }
        sums
    };
    // The classes of a block, summed, are finished together (see `FinishColumns`), then written
    // in order, so that copies are made in the order of the classes as one by one.
    let write_block = |classes: &[u32],
                       block: &[VertexSums],
                       columns: &mut FinishColumns,
                       repairs: &mut Vec<(u32, Problem)>,
                       put: &mut dyn FnMut(usize, [f32; 4])| {
        let mut finished = [([[0.0; 4]; 2], [false; 2]); FINISH_LANES];
        finish_block(columns, block, mesh, &mut finished);
        for ((&class, sums), &(tangents, valid)) in classes.iter().zip(block).zip(&finished) {
            let corners = table.of(class as usize);
            // Most vertices: every corner takes one side, and its tangent is valid. Each input
            // vertex of the class is given it with a plain store, as on one thread, without
            // reading the corners' faces again or the vertices' slots.
            if let Some(side) = sums.only_side()
                && valid[side]
            {
                let t = fallback::with_w_convention(tangents[side], flip_w);
                let mut previous = NONE;
                for &corner in corners {
                    let vertex = mesh.indices[corner as usize];
                    if vertex != previous {
                        shared.set_only_tangent(vertex as usize, t);
                        previous = vertex;
                    }
                }
                continue;
            }
            for &corner in corners {
                let corner = corner as usize;
                let side = sums.side_of(faces[corner / 3].sign);
                put(
                    corner,
                    fallback::finish_corner(
                        mesh,
                        corner,
                        tangents[side],
                        valid[side],
                        flip_w,
                        repairs,
                    ),
                );
            }
        }
    };

    let run = |range: std::ops::Range<usize>| {
        let mut copies = Copies::default();
        let mut repairs = Vec::new();
        let mut put = |c: usize, t: [f32; 4]| shared.put(&mut copies, c, t);
        let mut columns = FinishColumns::default();
        let mut classes = [0u32; FINISH_LANES];
        let mut block = [VertexSums::EMPTY; FINISH_LANES];
        let mut len = 0;
        for class in range {
            if table.of(class).is_empty() {
                continue;
            }
            (classes[len], block[len]) = (class as u32, sum_class(class));
            len += 1;
            if len == FINISH_LANES {
                write_block(&classes, &block, &mut columns, &mut repairs, &mut put);
                len = 0;
            }
        }
        if len > 0 {
            write_block(
                &classes[..len],
                &block[..len],
                &mut columns,
                &mut repairs,
                &mut put,
            );
        }
        (copies, repairs)
    };
    let results: Vec<(Copies, Vec<(u32, Problem)>)> = table
        .chunks(rayon::current_num_threads() * 16)
        .into_par_iter()
        .map(run)
        .collect();
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

    /// The columns give every vertex the bits, and the verdict, that `VertexSums::tangent` gives
    /// it one at a time: vertices with one side, both sides, unsigned corners and none; normals
    /// nearly unit, a little off, far off, zero, tiny, huge and NaN; sums that cancel in the
    /// normal's plane or vanish, and signed zeros; over a count that leaves a partial block.
    #[test]
    fn finished_columns_match_the_vertex_by_vertex_tangent() {
        let mut random = crate::test_support::xorshift(0x510e_527f_ade6_82d1);
        let value = |r: u64| -> f32 {
            match r % 11 {
                0 => 0.0,
                1 => -0.0,
                2 => 1e-30,
                3 => 1e25,
                _ => ((r >> 8) % 2001) as f32 / 1000.0 - 1.0,
            }
        };
        let count = 5 * FINISH_LANES + 3;
        let mut normals = Vec::with_capacity(count);
        let mut sums = Vec::with_capacity(count);
        for v in 0..count {
            let r = random();
            let direction = [value(random()), value(random()), value(random())];
            let normal = match r % 9 {
                0 => [0.0; 3],
                1 => [f32::NAN, 0.0, 1.0],
                2 => crate::math::scale(direction, 1e-12),
                3 => crate::math::scale(direction, 3.0),
                4 => [0.0, 0.0, 1.0 + 3e-7],
                _ => crate::math::unit(direction).unwrap_or([0.0, 1.0, 0.0]),
            };
            normals.push(normal);
            let mut vertex = VertexSums::EMPTY;
            if r % 13 != 0 {
                vertex.first_vertex = v as u32;
                vertex.sides_used = [1, 2, 3][(r >> 4) as usize % 3];
                vertex.unsigned = (r >> 6) % 5 == 0;
                for side in 0..2 {
                    let s = [value(random()), value(random()), value(random())];
                    vertex.s[side] = if (r >> 9) % 7 == side as u64 {
                        // Along the normal: nothing left in its plane.
                        Vec3::from(crate::math::scale(normal, 2.0))
                    } else {
                        Vec3::from(s)
                    };
                    vertex.t[side] =
                        Vec3::from([value(random()), value(random()), value(random())]);
                }
            }
            sums.push(vertex);
        }
        let positions = vec![[0.0f32; 3]; count];
        let indices: Vec<u32> = Vec::new();
        let mesh = Mesh {
            positions: &positions,
            normals: &normals,
            uvs: None,
            indices: &indices,
        };
        for flip_w in [false, true] {
            let mut uniform = vec![[0.0f32; 4]; count];
            let finished = finish_sums(&sums, &mesh, flip_w, &mut uniform);
            for (v, vertex) in sums.iter().enumerate() {
                let taken = vertex.sides_taken();
                let mut expected = ([[0.0f32; 4]; 2], [false; 2]);
                for side in 0..2 {
                    if taken & (1 << side) != 0 {
                        (expected.0[side], expected.1[side]) = vertex.tangent(side, &mesh);
                    }
                }
                let bits = |t: &[[f32; 4]; 2]| t.map(|t| t.map(f32::to_bits));
                assert_eq!(bits(&finished[v].0), bits(&expected.0), "vertex {v}");
                assert_eq!(finished[v].1, expected.1, "vertex {v}");
                let only = vertex.only_side().filter(|&side| expected.1[side]);
                let expected_uniform = only.map_or([0.0; 4], |side| {
                    fallback::with_w_convention(expected.0[side], flip_w)
                });
                assert_eq!(
                    uniform[v].map(f32::to_bits),
                    expected_uniform.map(f32::to_bits)
                );
            }
        }
    }
}
