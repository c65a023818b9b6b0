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
        for k in 0..len {
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
        for (k, triangle) in (self.start..self.start + self.len).enumerate() {
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
/// `parallel`; the tallies are the same either way.
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
