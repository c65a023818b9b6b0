//! Per-triangle passes in batches: a method's per-triangle set-up (a frame, a face) takes several
//! square roots and divisions, which one triangle at a time keep the divider busy for most of
//! the pass. Gathered into columns, [`BATCH`] triangles at a time, the same arithmetic runs as
//! vectorized loops. The diagnostics' triangle checks ride along: they read the same corners.
//!
//! A method's loops run over the batch's [`TriangleColumns::lanes`], whole vectors; past the last
//! triangle of a short batch they compute on stale inputs, whose results are never read.

use super::diagnostics::{TriangleCheck, TriangleTallies};
use super::math::Mesh;

/// Triangles per batch.
pub(crate) const BATCH: usize = 64;

/// The widest vector's lanes (AVX-512, 32-bit): a short batch is computed in multiples of it.
const LANES: usize = 16;

/// The corners of a batch of triangles, in columns.
pub(crate) struct TriangleColumns {
    /// `p[corner][axis][k]`: position of corner `corner` of the batch's triangle `k`.
    p: [[[f32; BATCH]; 3]; 3],
    uv: [[[f32; BATCH]; 2]; 3],
    /// What [`TriangleCheck::events`] found in each triangle.
    events: [u8; BATCH],
    /// The first triangle of the batch, and how many there are.
    start: usize,
    len: usize,
}

impl Default for TriangleColumns {
    fn default() -> TriangleColumns {
        TriangleColumns {
            p: [[[0.0; BATCH]; 3]; 3],
            uv: [[[0.0; BATCH]; 2]; 3],
            events: [0; BATCH],
            start: 0,
            len: 0,
        }
    }
}

impl TriangleColumns {
    /// Gathers the `len` (at most [`BATCH`]) triangles from `start` on.
    pub fn gather(&mut self, mesh: &Mesh<'_>, start: usize, len: usize) {
        let len = len.min(BATCH);
        (self.start, self.len) = (start, len);
        let whole = len - len % 4;
        for k in (0..whole).step_by(4) {
            for corner in 0..3 {
                let vertices = four_corners(mesh, start + k, corner);
                gather_four(mesh.positions, vertices, &mut self.p[corner], k);
                match mesh.uvs {
                    Some(uvs) => gather_four_uvs(uvs, vertices, &mut self.uv[corner], k),
                    None => {
                        for column in &mut self.uv[corner] {
                            column[k..k + 4].fill(0.0);
                        }
                    }
                }
            }
        }
        for k in whole..len {
            for (corner, &v) in mesh.triangle(start + k).iter().enumerate() {
                let p = mesh.positions[v];
                let uv = mesh.uv(v);
                (
                    self.p[corner][0][k],
                    self.p[corner][1][k],
                    self.p[corner][2][k],
                ) = (p[0], p[1], p[2]);
                (self.uv[corner][0][k], self.uv[corner][1][k]) = (uv[0], uv[1]);
            }
        }
    }

    /// The first gathered triangle, and how many were gathered.
    pub fn range(&self) -> std::ops::Range<usize> {
        self.start..self.start + self.len
    }

    /// How many of the batch's places a method's loops run over: the gathered triangles,
    /// rounded up to a whole vector. A mesh of one triangle (as glTF files made of thousands of
    /// one-triangle primitives have) then costs one vector's work, not a batch's sixty-four.
    #[inline(always)]
    pub fn lanes(&self) -> usize {
        self.len.next_multiple_of(LANES).min(BATCH)
    }

    /// The normals of the gathered triangles' corners, as `n[corner][axis][k]`.
    #[inline(always)]
    pub fn gather_normals(&self, mesh: &Mesh<'_>, n: &mut [[[f32; BATCH]; 3]; 3]) {
        let whole = self.len - self.len % 4;
        for k in (0..whole).step_by(4) {
            for (corner, n) in n.iter_mut().enumerate() {
                gather_four(
                    mesh.normals,
                    four_corners(mesh, self.start + k, corner),
                    n,
                    k,
                );
            }
        }
        for (triangle, k) in (self.start + whole..self.start + self.len).zip(whole..) {
            for (corner, &v) in mesh.triangle(triangle).iter().enumerate() {
                let normal = mesh.normals[v];
                (n[corner][0][k], n[corner][1][k], n[corner][2][k]) =
                    (normal[0], normal[1], normal[2]);
            }
        }
    }

    /// Triangle `k` of the batch: its positions and texture coordinates (zeros without UVs).
    #[inline(always)]
    pub fn corners(&self, k: usize) -> ([[f32; 3]; 3], [[f32; 2]; 3]) {
        let [p0, p1, p2] = &self.p;
        let [t0, t1, t2] = &self.uv;
        // Element by element: `map` over the arrays is not inlined.
        let p = [
            [p0[0][k], p0[1][k], p0[2][k]],
            [p1[0][k], p1[1][k], p1[2][k]],
            [p2[0][k], p2[1][k], p2[2][k]],
        ];
        let uv = [
            [t0[0][k], t0[1][k]],
            [t1[0][k], t1[1][k]],
            [t2[0][k], t2[1][k]],
        ];
        (p, uv)
    }

    /// Runs the diagnostics' triangle checks over the batch. Always inlined, so that it is
    /// compiled with the vector features of the method's loop that calls it.
    #[inline(always)]
    pub fn check(&mut self, check: &TriangleCheck<'_>) {
        for k in 0..self.lanes() {
            let (p, uv) = self.corners(k);
            self.events[k] = check.events(&p, &uv);
        }
    }

    /// Adds what [`TriangleColumns::check`] found to `tallies`, triangle by triangle.
    pub fn tally(&self, mesh: &Mesh<'_>, check: &TriangleCheck<'_>, tallies: &mut TriangleTallies) {
        for (k, &events) in self.events[..self.len].iter().enumerate() {
            let t = self.start + k;
            // Asked first, so that the common mesh does not read the indices again.
            if check.has_non_finite() && check.touches_non_finite(mesh.triangle(t)) {
                tallies.add_non_finite(t);
            } else {
                check.record(tallies, t, events);
            }
        }
    }
}

/// The vertices at corner `corner` of triangles `first..first + 4`.
#[inline(always)]
fn four_corners(mesh: &Mesh<'_>, first: usize, corner: usize) -> [usize; 4] {
    let i = &mesh.indices[3 * first..3 * first + 12];
    [i[corner], i[3 + corner], i[6 + corner], i[9 + corner]].map(|v| v as usize)
}

/// `columns[axis][k..k + 4]` = `vectors[vertices[j]][axis]`: four vectors of an array of
/// structures turned into three columns. On x86-64 that is four 16-byte loads and a 4x4
/// transpose (SSE, which every x86-64 CPU has) where it was twelve loads and twelve stores of a
/// float; the gathers were a twentieth of the MikkTSpace pass.
#[inline(always)]
fn gather_four(
    vectors: &[[f32; 3]],
    vertices: [usize; 4],
    columns: &mut [[f32; BATCH]; 3],
    k: usize,
) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        let [xs, ys, zs] = columns;
        let (xs, ys, zs) = (&mut xs[k..k + 4], &mut ys[k..k + 4], &mut zs[k..k + 4]);
        // SAFETY: a 16-byte load at vector `v` reads it and the first float of vector `v + 1`,
        // which exists where `v + 1 < len`; the last vector is built from its floats instead.
        // The stores write four floats into the four-float slices above. (One block for all:
        // the compilers the crate supports differ in which of the intrinsics need one.)
        unsafe {
            let load = |v: usize| {
                if v + 1 < vectors.len() {
                    _mm_loadu_ps(vectors.as_ptr().add(v).cast())
                } else {
                    let [x, y, z] = vectors[v];
                    _mm_setr_ps(x, y, z, 0.0)
                }
            };
            let [a, b, c, d] = vertices.map(load);
            let (ab_low, cd_low) = (_mm_unpacklo_ps(a, b), _mm_unpacklo_ps(c, d));
            let (ab_high, cd_high) = (_mm_unpackhi_ps(a, b), _mm_unpackhi_ps(c, d));
            _mm_storeu_ps(xs.as_mut_ptr(), _mm_movelh_ps(ab_low, cd_low));
            _mm_storeu_ps(ys.as_mut_ptr(), _mm_movehl_ps(cd_low, ab_low));
            _mm_storeu_ps(zs.as_mut_ptr(), _mm_movelh_ps(ab_high, cd_high));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    gather_four_portable(vectors, vertices, columns, k);
}

/// [`gather_four`] for texture coordinates.
#[inline(always)]
fn gather_four_uvs(
    uvs: &[[f32; 2]],
    vertices: [usize; 4],
    columns: &mut [[f32; BATCH]; 2],
    k: usize,
) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        let [us, vs] = columns;
        let (us, vs) = (&mut us[k..k + 4], &mut vs[k..k + 4]);
        let [a, b, c, d] = vertices.map(|v| uvs[v]);
        // SAFETY: the stores write four floats into the four-float slices above. (The pairs
        // are built from floats rather than loaded as one 8-byte value, which would be a
        // misaligned `f64`; the compiler makes 8-byte loads of them all the same.)
        unsafe {
            let ab = _mm_setr_ps(a[0], a[1], b[0], b[1]);
            let cd = _mm_setr_ps(c[0], c[1], d[0], d[1]);
            _mm_storeu_ps(us.as_mut_ptr(), _mm_shuffle_ps::<0b10_00_10_00>(ab, cd));
            _mm_storeu_ps(vs.as_mut_ptr(), _mm_shuffle_ps::<0b11_01_11_01>(ab, cd));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    gather_four_portable(uvs, vertices, columns, k);
}

/// [`gather_four`] and [`gather_four_uvs`] one float at a time, on other architectures.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn gather_four_portable<const N: usize>(
    vectors: &[[f32; N]],
    vertices: [usize; 4],
    columns: &mut [[f32; BATCH]; N],
    k: usize,
) {
    for (j, &v) in vertices.iter().enumerate() {
        for (column, &x) in columns.iter_mut().zip(&vectors[v]) {
            column[k + j] = x;
        }
    }
}

/// What a per-triangle pass writes: one slice of per-triangle items, or two side by side.
pub(crate) trait PerTriangle: Send + Sized {
    fn len(&self) -> usize;
    fn split_at(self, mid: usize) -> (Self, Self);
}

impl<T: Send> PerTriangle for &mut [T] {
    fn len(&self) -> usize {
        <[T]>::len(self)
    }

    fn split_at(self, mid: usize) -> (Self, Self) {
        self.split_at_mut(mid)
    }
}

impl<A: Send, B: Send> PerTriangle for (&mut [A], &mut [B]) {
    fn len(&self) -> usize {
        self.0.len().min(self.1.len())
    }

    fn split_at(self, mid: usize) -> (Self, Self) {
        let (a, rest_a) = self.0.split_at_mut(mid);
        let (b, rest_b) = self.1.split_at_mut(mid);
        ((a, b), (rest_a, rest_b))
    }
}

/// Triangles per run: the unit of parallel work, and how often a pass looks for cancellation.
const RUN: usize = 16384;

/// Runs a per-triangle pass over every triangle: `batch` fills `out`'s items for each gathered
/// batch of triangles, given scratch `S` of its own per run of triangles, and the diagnostics'
/// triangle checks are tallied alongside. Runs of triangles go to the thread pool when
/// `parallel`; the tallies are the same either way. A run is skipped, its items left as they
/// were, only once `check.cancel` is set (the triangle pass's records rely on that: see
/// `mikktspace::RecordSlots`); otherwise every item of `out` is handed to `batch`.
pub(crate) fn per_triangle_pass<O: PerTriangle, S: Default>(
    mesh: &Mesh<'_>,
    check: &TriangleCheck<'_>,
    out: O,
    parallel: bool,
    batch: impl Fn(&mut S, &mut TriangleColumns, O) + Sync,
) -> TriangleTallies {
    let mut runs = Vec::with_capacity(out.len() / RUN + 1);
    let (mut first, mut rest) = (0, out);
    while rest.len() > RUN {
        let (run, later) = rest.split_at(RUN);
        runs.push((first, run));
        (first, rest) = (first + RUN, later);
    }
    runs.push((first, rest));
    let run_pass = |(first, mut out): (usize, O)| {
        let mut tallies = TriangleTallies::default();
        let mut triangles = TriangleColumns::default();
        let mut scratch = S::default();
        let mut start = first;
        if check.cancel.is_cancelled() {
            return tallies;
        }
        while out.len() > 0 {
            let len = out.len().min(BATCH);
            let (items, later) = out.split_at(len);
            triangles.gather(mesh, start, len);
            batch(&mut scratch, &mut triangles, items);
            triangles.tally(mesh, check, &mut tallies);
            (start, out) = (start + len, later);
        }
        tallies
    };
    if parallel {
        use rayon::prelude::*;
        let tallies: Vec<TriangleTallies> = runs.into_par_iter().map(run_pass).collect();
        tallies.into_iter().sum()
    } else {
        runs.into_iter().map(run_pass).sum()
    }
}

/// A per-triangle pass on one thread in triangle order, for a method that folds each gathered
/// batch into state shared by the whole mesh (sums per welded vertex) instead of writing
/// per-triangle items: `batch` sees the batch ([`TriangleColumns::range`] says which triangles)
/// and scratch `S`. Stops early, leaving the rest unfolded, once `check.cancel` is set.
pub(crate) fn per_triangle_fold<S: Default>(
    mesh: &Mesh<'_>,
    check: &TriangleCheck<'_>,
    mut batch: impl FnMut(&mut S, &mut TriangleColumns),
) -> TriangleTallies {
    let mut tallies = TriangleTallies::default();
    let mut triangles = TriangleColumns::default();
    let mut scratch = S::default();
    let count = mesh.triangle_count();
    let mut start = 0;
    while start < count {
        if start % RUN == 0 && check.cancel.is_cancelled() {
            break;
        }
        let len = (count - start).min(BATCH);
        triangles.gather(mesh, start, len);
        batch(&mut scratch, &mut triangles);
        triangles.tally(mesh, check, &mut tallies);
        start += len;
    }
    tallies
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The columns hold each triangle's corners as the mesh has them, for batches that start
    /// anywhere and end in a partial group of four, with the last vertex (which the 16-byte
    /// loads must not read past) among the corners, with and without texture coordinates.
    #[test]
    #[allow(clippy::needless_range_loop)] // `k` is a place in several columns at once
    fn gathered_columns_hold_the_corners() {
        let vertex_count = 50;
        let positions: Vec<[f32; 3]> = (0..vertex_count)
            .map(|v| [v as f32, v as f32 + 0.25, v as f32 + 0.5])
            .collect();
        let normals: Vec<[f32; 3]> = positions.iter().map(|p| p.map(|x| -x)).collect();
        let uvs: Vec<[f32; 2]> = (0..vertex_count)
            .map(|v| [v as f32 / 64.0, 1.0 - v as f32 / 64.0])
            .collect();
        // Corners that jump about and use the last vertex often.
        let indices: Vec<u32> = (0..3 * 150)
            .map(|c| {
                if c % 7 == 0 {
                    vertex_count as u32 - 1
                } else {
                    (c * 17 % vertex_count) as u32
                }
            })
            .collect();
        for uvs in [Some(&uvs[..]), None] {
            let mesh = Mesh {
                positions: &positions,
                normals: &normals,
                uvs,
                indices: &indices,
            };
            let mut columns = TriangleColumns::default();
            let mut n = [[[0.0; BATCH]; 3]; 3];
            for (start, len) in [
                (0, 64),
                (1, 5),
                (3, 64),
                (10, 1),
                (77, 13),
                (146, 4),
                (147, 3),
            ] {
                columns.gather(&mesh, start, len);
                columns.gather_normals(&mesh, &mut n);
                for k in 0..len {
                    let triangle = mesh.triangle(start + k);
                    let (p, uv) = columns.corners(k);
                    assert_eq!(
                        p,
                        triangle.map(|v| positions[v]),
                        "batch {start}+{len}, {k}"
                    );
                    assert_eq!(uv, triangle.map(|v| mesh.uv(v)), "batch {start}+{len}, {k}");
                    for (corner, &v) in triangle.iter().enumerate() {
                        let gathered = [0, 1, 2].map(|axis| n[corner][axis][k]);
                        assert_eq!(gathered, normals[v], "batch {start}+{len}, {k}");
                    }
                }
            }
        }
    }
}
