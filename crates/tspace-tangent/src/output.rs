//! The split plan, built while the tangents are produced instead of from a per-corner buffer.
//!
//! A method that works vertex by vertex hands every finished corner tangent to [`SharedSplit::put`].
//! The corners of one input vertex all belong to one welded vertex, so exactly one worker ever
//! touches a given input vertex: its first tangent becomes the vertex's own, and each different
//! tangent a duplicate in that worker's own [`Copies`]. Once every worker is done, the copies are
//! numbered after the input vertices, worker after worker, so the plan is the same however many
//! threads built it. This saves the per-corner tangent buffer (16 bytes a corner) and the pass
//! over it that [`super::split::plan`] makes.
//!
//! Workers share the per-vertex arrays; each entry has one writer, and relaxed atomic loads and
//! stores compile to plain ones, so this costs nothing over `&mut` slices. Nothing is written
//! per corner: a corner that keeps its vertex keeps its index, and the handedness counts are
//! read off the finished plan.

use super::diagnostics::{Diagnostics, Tally};
use super::fill::filled;
use super::math::{any_orthogonal, unit};
use super::split::SplitPlan;
use super::weld::NONE;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

pub(crate) struct SharedSplit<'a> {
    indices: &'a [u32],
    /// The tangent of every input vertex; `w == 0` (never the `w` of a finished tangent) while
    /// no corner has used it.
    vertex_tangents: Vec<[AtomicU32; 4]>,
    /// The first duplicate of each input vertex, in its owner's [`Copies`].
    first_copy: Vec<AtomicU32>,
    /// Whether [`SharedSplit::finish`] may use the thread pool.
    parallel: bool,
}

/// Duplicated vertices made by one worker, numbered locally.
#[derive(Default)]
pub(crate) struct Copies {
    source: Vec<u32>,
    tangent: Vec<[f32; 4]>,
    next: Vec<u32>,
    /// Corners that use a duplicate: (corner, local number).
    corners: Vec<(u32, u32)>,
}

impl Copies {
    /// Renumbers the copies in the order of `key(source vertex, the corner that made it)`. A
    /// worker that put its corners in triangle order then numbers its copies as one that went
    /// welded vertex by welded vertex (keyed by class, then corner), so the plan does not depend
    /// on which way it went.
    pub fn reorder_by<K: Ord>(&mut self, key: impl Fn(u32, u32) -> K) {
        let count = self.source.len();
        if count < 2 {
            return;
        }
        // A copy is made by the first corner that uses it, and corners are listed as put.
        let mut made_by = vec![NONE; count];
        for &(corner, local) in &self.corners {
            let maker = &mut made_by[local as usize];
            if *maker == NONE {
                *maker = corner;
            }
        }
        let mut order: Vec<u32> = (0..count as u32).collect();
        order.sort_by_key(|&local| key(self.source[local as usize], made_by[local as usize]));
        let mut renumbered = vec![0u32; count];
        for (new, &old) in order.iter().enumerate() {
            renumbered[old as usize] = new as u32;
        }
        let renumber = |link: u32| {
            if link == NONE {
                NONE
            } else {
                renumbered[link as usize]
            }
        };
        self.source = order.iter().map(|&old| self.source[old as usize]).collect();
        self.tangent = order
            .iter()
            .map(|&old| self.tangent[old as usize])
            .collect();
        self.next = order
            .iter()
            .map(|&old| renumber(self.next[old as usize]))
            .collect();
        for (_, local) in &mut self.corners {
            *local = renumbered[*local as usize];
        }
    }
}

/// The tangents' words as the floats they hold, where they lie. Collected into a new vector,
/// both were held at once (16 bytes a vertex more at the peak); converted in place, a value at
/// a time, the copy was two thirds of [`SharedSplit::finish`] (SciFiHelmet's finish 4% of the
/// call: the conversion of each value was a call).
fn into_floats(tangents: Vec<[AtomicU32; 4]>) -> Vec<[f32; 4]> {
    const _: () = assert!(
        size_of::<[AtomicU32; 4]>() == size_of::<[f32; 4]>()
            && align_of::<[AtomicU32; 4]>() == align_of::<[f32; 4]>()
    );
    let mut tangents = std::mem::ManuallyDrop::new(tangents);
    let (block, len, capacity) = (tangents.as_mut_ptr(), tangents.len(), tangents.capacity());
    // SAFETY: the block was allocated by a `Vec` of `capacity` values of the same size and
    // alignment as `[f32; 4]` (checked above), `len` of them initialized; an `AtomicU32` has the
    // bit validity of a `u32`, and every bit pattern is a valid `f32`. The original vector is
    // never dropped, so the new one is the block's only owner.
    unsafe { Vec::from_raw_parts(block.cast::<[f32; 4]>(), len, capacity) }
}

#[inline]
fn load4(place: &[AtomicU32; 4]) -> [f32; 4] {
    place
        .each_ref()
        .map(|lane| f32::from_bits(lane.load(Relaxed)))
}

#[inline]
fn store4(place: &[AtomicU32; 4], value: [f32; 4]) {
    for (lane, x) in place.iter().zip(value) {
        lane.store(x.to_bits(), Relaxed);
    }
}

impl<'a> SharedSplit<'a> {
    pub fn new(indices: &'a [u32], vertex_count: usize, parallel: bool) -> SharedSplit<'a> {
        SharedSplit {
            indices,
            vertex_tangents: filled(vertex_count, parallel, || [const { AtomicU32::new(0) }; 4]),
            first_copy: filled(vertex_count, parallel, || AtomicU32::new(NONE)),
            parallel,
        }
    }

    /// Records the final tangent of `corner`. Every corner is put exactly once, and all corners
    /// of one input vertex by the same worker with the same `copies`.
    #[inline]
    pub fn put(&self, copies: &mut Copies, corner: usize, tangent: [f32; 4]) {
        let v = self.indices[corner] as usize;
        let current = load4(&self.vertex_tangents[v]);
        // Float equality: -0 and 0 are the same tangent (tangents are never NaN here).
        if current == tangent {
            return;
        }
        if current[3] == 0.0 {
            store4(&self.vertex_tangents[v], tangent);
            return;
        }
        let mut link = self.first_copy[v].load(Relaxed);
        let mut last = NONE;
        while link != NONE {
            if copies.tangent[link as usize] == tangent {
                copies.corners.push((corner as u32, link));
                return;
            }
            last = link;
            link = copies.next[link as usize];
        }
        let new = copies.source.len() as u32;
        copies.source.push(v as u32);
        copies.tangent.push(tangent);
        copies.next.push(NONE);
        if last == NONE {
            self.first_copy[v].store(new, Relaxed);
        } else {
            copies.next[last as usize] = new;
        }
        copies.corners.push((corner as u32, new));
    }

    /// Gives input vertex `v` its tangent, where the caller knows it is the only one any corner
    /// of `v` will be put: a plain store, without the read [`SharedSplit::put`] makes to find
    /// an earlier tangent (a cache miss per vertex where vertices are visited out of order, as
    /// in a triangle soup). Corners put afterwards with the same tangent keep the vertex.
    #[inline]
    pub fn set_only_tangent(&self, v: usize, tangent: [f32; 4]) {
        store4(&self.vertex_tangents[v], tangent);
    }

    /// Numbers the duplicates (`parts` in order) after the input vertices, gives unused vertices
    /// a valid tangent, and fills the split and handedness counts of `diagnostics`.
    pub fn finish(
        self,
        parts: Vec<Copies>,
        normals: &[[f32; 3]],
        diagnostics: &mut Diagnostics,
    ) -> SplitPlan {
        let vertex_count = self.vertex_tangents.len();
        let added: usize = parts.iter().map(|p| p.source.len()).sum();
        let mut source_vertex: Vec<u32> = Vec::with_capacity(vertex_count + added);
        if self.parallel {
            source_vertex.par_extend((0..vertex_count as u32).into_par_iter());
        } else {
            source_vertex.extend(0..vertex_count as u32);
        }
        let mut vertex_tangents = into_floats(self.vertex_tangents);
        vertex_tangents.reserve(added);
        // Where no vertex was added, every corner keeps its vertex: the input's indices stand.
        let mut indices: Option<Vec<u32>> = (added > 0).then(|| {
            let mut indices = Vec::with_capacity(self.indices.len());
            if self.parallel {
                indices.par_extend(self.indices.par_iter().copied());
            } else {
                indices.extend_from_slice(self.indices);
            }
            indices
        });
        // A vertex whose duplicate has the other handedness saw both.
        let mut flipped: Vec<u32> = Vec::new();
        for part in parts {
            let base = source_vertex.len() as u32;
            if let Some(indices) = &mut indices {
                for &(corner, local) in &part.corners {
                    indices[corner as usize] = base + local;
                }
            }
            for (&source, copy) in part.source.iter().zip(&part.tangent) {
                if (copy[3] > 0.0) != (vertex_tangents[source as usize][3] > 0.0) {
                    flipped.push(source);
                }
            }
            source_vertex.extend_from_slice(&part.source);
            vertex_tangents.extend_from_slice(&part.tangent);
        }
        flipped.sort_unstable();
        flipped.dedup();
        let mut flips = Tally::default();
        for v in flipped {
            flips.add(v);
        }

        // One pass over the vertices, on the thread pool: it gives vertices no triangle uses a
        // valid tangent, and finds which handedness the others have. (A separate scan for the
        // second, one thread reading every tangent while the others waited, was 2% of a 2M-
        // triangle sphere's two-thread call.) A `w` of zero is neither handedness: only a vertex
        // no triangle uses has one by now (every corner put gets ±1), and counted as the other,
        // one unused vertex sent a 2M-triangle sphere through the pass over the corners below
        // for nothing. The tangents given here are read by no corner, so that pass, which comes
        // after, sees what it would have before.
        let settle = |seen: (bool, bool), (tangent, normal): (&mut [f32; 4], &[f32; 3])| {
            let w = tangent[3];
            if w == 0.0 {
                // Vertices no triangle uses still need a valid tangent in the output.
                let n = unit(*normal).unwrap_or([0.0, 0.0, 1.0]);
                let t = any_orthogonal(n);
                *tangent = [t[0], t[1], t[2], 1.0];
            }
            (seen.0 | (w > 0.0), seen.1 | (w < 0.0))
        };
        let either = |a: (bool, bool), b: (bool, bool)| (a.0 | b.0, a.1 | b.1);
        let (inputs, copies) = vertex_tangents.split_at_mut(vertex_count);
        let seen = if self.parallel {
            inputs
                .par_iter_mut()
                .zip(normals)
                .fold(|| (false, false), settle)
                .reduce(|| (false, false), either)
        } else {
            inputs.iter_mut().zip(normals).fold((false, false), settle)
        };
        // The copies have tangents of their own, none unused.
        let seen = copies.iter().fold(seen, |(positive, negative), t| {
            (positive | (t[3] > 0.0), negative | (t[3] < 0.0))
        });

        // Triangles whose corners got tangents of different handedness, by runs of triangles.
        // Where every tangent has the same handedness, as in a mesh without mirrored texture
        // coordinates, no triangle can mix them, and the corners are not read.
        const RUN: usize = 16384;
        let mixed_in = |(run, corners): (usize, &[u32])| {
            let mut mixed = Tally::default();
            for (k, corners) in corners.chunks_exact(3).enumerate() {
                let positive = |i: usize| vertex_tangents[corners[i] as usize][3] > 0.0;
                if positive(0) != positive(1) || positive(0) != positive(2) {
                    mixed.add((run * RUN + k) as u32);
                }
            }
            mixed
        };
        let corner_vertices = indices.as_deref().unwrap_or(self.indices);
        let runs: Vec<Tally> = if !(seen.0 && seen.1) {
            Vec::new()
        } else if self.parallel {
            corner_vertices
                .par_chunks(3 * RUN)
                .enumerate()
                .map(mixed_in)
                .collect()
        } else {
            corner_vertices
                .chunks(3 * RUN)
                .enumerate()
                .map(mixed_in)
                .collect()
        };
        let mut mixed = Tally::default();
        for run in &runs {
            mixed.append(run);
        }
        diagnostics.handedness_flip_vertices = flips;
        diagnostics.mixed_handedness_triangles = mixed;
        diagnostics.vertices_in = vertex_count as u64;
        diagnostics.vertices_out = source_vertex.len() as u64;
        diagnostics.vertices_added = added as u64;
        SplitPlan {
            source_vertex,
            indices,
            vertex_tangents,
        }
    }
}
