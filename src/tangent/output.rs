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
//! Workers share the per-vertex and per-corner arrays; each entry has one writer, and relaxed
//! atomic loads and stores compile to plain ones, so this costs nothing over `&mut` slices.

use super::diagnostics::{Diagnostics, Tally};
use super::fill::filled;
use super::math::{any_orthogonal, unit};
use super::split::SplitPlan;
use super::weld::NONE;
use std::sync::atomic::{AtomicU8, AtomicU32, Ordering::Relaxed};

/// Bit 0: a corner with `w > 0` was seen; bit 1: `w < 0`.
const POSITIVE: u8 = 1;
const NEGATIVE: u8 = 2;

pub(crate) struct SharedSplit<'a> {
    indices: &'a [u32],
    vertex_tangents: Vec<[AtomicU32; 4]>,
    /// Handedness seen per input vertex; 0 while the vertex is unused.
    signs: Vec<AtomicU8>,
    /// The first duplicate of each input vertex, in its owner's [`Copies`].
    first_copy: Vec<AtomicU32>,
    /// The output index of every corner (duplicates are filled in at the end).
    split_indices: Vec<AtomicU32>,
    /// The handedness of every corner, for the mixed-handedness triangle count.
    corner_signs: Vec<AtomicU8>,
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
        let corners = indices.len();
        SharedSplit {
            indices,
            vertex_tangents: filled(vertex_count, parallel, || [const { AtomicU32::new(0) }; 4]),
            signs: filled(vertex_count, parallel, || AtomicU8::new(0)),
            first_copy: filled(vertex_count, parallel, || AtomicU32::new(NONE)),
            split_indices: filled(corners, parallel, || AtomicU32::new(0)),
            corner_signs: filled(corners, parallel, || AtomicU8::new(0)),
        }
    }

    /// Records the final tangent of `corner`. Every corner is put exactly once, and all corners
    /// of one input vertex by the same worker with the same `copies`.
    #[inline]
    pub fn put(&self, copies: &mut Copies, corner: usize, tangent: [f32; 4]) {
        let v = self.indices[corner] as usize;
        let sign = if tangent[3] > 0.0 { POSITIVE } else { NEGATIVE };
        self.corner_signs[corner].store(sign, Relaxed);
        let seen = self.signs[v].load(Relaxed);
        self.signs[v].store(seen | sign, Relaxed);
        // Float equality: -0 and 0 are the same tangent (tangents are never NaN here).
        if seen == 0 {
            store4(&self.vertex_tangents[v], tangent);
        } else if load4(&self.vertex_tangents[v]) != tangent {
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
            return;
        }
        self.split_indices[corner].store(v as u32, Relaxed);
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
        source_vertex.extend(0..vertex_count as u32);
        let mut vertex_tangents: Vec<[f32; 4]> = self
            .vertex_tangents
            .into_iter()
            .map(|lanes| lanes.map(|lane| f32::from_bits(lane.into_inner())))
            .collect();
        vertex_tangents.reserve(added);
        let mut indices: Vec<u32> = self
            .split_indices
            .into_iter()
            .map(AtomicU32::into_inner)
            .collect();
        for part in parts {
            let base = source_vertex.len() as u32;
            for &(corner, local) in &part.corners {
                indices[corner as usize] = base + local;
            }
            source_vertex.extend_from_slice(&part.source);
            vertex_tangents.extend_from_slice(&part.tangent);
        }

        let mut flips = Tally::default();
        for (v, sign) in self.signs.iter().enumerate() {
            match sign.load(Relaxed) {
                0 => {
                    // Vertices no triangle uses still need a valid tangent in the output.
                    let n = unit(normals[v]).unwrap_or([0.0, 0.0, 1.0]);
                    let t = any_orthogonal(n);
                    vertex_tangents[v] = [t[0], t[1], t[2], 1.0];
                }
                s if s == POSITIVE | NEGATIVE => flips.add(v as u32),
                _ => {}
            }
        }
        let mut mixed = Tally::default();
        for (t, corners) in self.corner_signs.chunks_exact(3).enumerate() {
            let a = corners[0].load(Relaxed);
            if a != corners[1].load(Relaxed) || a != corners[2].load(Relaxed) {
                mixed.add(t as u32);
            }
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
