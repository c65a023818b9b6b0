//! The split plan: where corners that share a vertex received different tangents, the vertex is
//! duplicated; corners with identical tangents keep sharing it.
//!
//! The plan is expressed as indices into the caller's vertices, so that any other attribute (skin
//! weights, colours, morph targets) can be duplicated the same way. Original vertices keep their
//! index; duplicates are appended after them, in an order that depends only on the mesh (never on
//! the number of threads): by first use here, by welded vertex where MikkTSpace builds the plan
//! as it goes (see `output.rs`). Triangle order and corner order are unchanged.

use super::diagnostics::{Diagnostics, Tally};
use super::math::{any_orthogonal, unit};
use super::weld::NONE;
use std::borrow::Cow;

/// How to rebuild the vertex buffer so that each vertex carries exactly one tangent.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SplitPlan {
    /// For every output vertex, the input vertex it copies. When the input had normals, the
    /// first `vertex_count` entries are `0, 1, 2, …` (every input vertex keeps its place, used or
    /// not). When normals were generated, vertices are first split by normal, and the list maps
    /// each output vertex (in order of first use) back to its input vertex.
    pub source_vertex: Vec<u32>,
    /// The new index buffer: one entry per input corner, same order. `None` where no vertex was
    /// added and the normals were given, as in most meshes: every corner keeps its input
    /// vertex, so the input's own indices (`0, 1, 2, …` for a triangle list without indices)
    /// are the plan's, and a copy of them would cost 4 bytes a corner of fresh memory (24 MB of
    /// the 2M-triangle sphere's peak) and a pass, for a caller that keeps the input's index
    /// buffer anyway. [`SplitPlan::vertex_of`] and [`SplitPlan::indices_for`] read either.
    pub indices: Option<Vec<u32>>,
    /// The tangent of every output vertex.
    pub vertex_tangents: Vec<[f32; 4]>,
}

impl SplitPlan {
    /// True when no vertex was added (the plan is the identity).
    pub fn is_identity(&self, vertex_count: usize) -> bool {
        self.source_vertex.len() == vertex_count
    }

    /// The plan's own index buffer, to change: made from the input's indices (as
    /// [`SplitPlan::indices_for`] reads them) where the plan had none.
    pub fn indices_mut(&mut self, input_indices: Option<&[u32]>) -> &mut Vec<u32> {
        if self.indices.is_none() {
            self.indices = Some(self.indices_for(input_indices).into_owned());
        }
        self.indices.get_or_insert_with(Vec::new)
    }

    /// The output vertex of `corner`, for the input's indices `input_indices` (`None` where the
    /// input was a triangle list without indices), which the plan was made for.
    pub fn vertex_of(&self, corner: usize, input_indices: Option<&[u32]>) -> usize {
        match (&self.indices, input_indices) {
            (Some(indices), _) => indices[corner] as usize,
            (None, Some(input)) => input[corner] as usize,
            (None, None) => corner,
        }
    }

    /// The whole new index buffer, for the input's indices `input_indices` (`None` where the
    /// input was a triangle list without indices, whose corners are then its vertices): the
    /// plan's own, or the input's where they stand.
    pub fn indices_for<'a>(&'a self, input_indices: Option<&'a [u32]>) -> Cow<'a, [u32]> {
        match (&self.indices, input_indices) {
            (Some(indices), _) => Cow::Borrowed(indices),
            (None, Some(input)) => Cow::Borrowed(input),
            (None, None) => Cow::Owned((0..self.source_vertex.len() as u32).collect()),
        }
    }
}

/// Builds the plan and fills the split and handedness counts of `diagnostics`.
pub(crate) fn plan(
    indices: &[u32],
    vertex_count: usize,
    corner_tangents: &[[f32; 4]],
    normals: &[[f32; 3]],
    diagnostics: &mut Diagnostics,
) -> SplitPlan {
    let mut source_vertex: Vec<u32> = (0..vertex_count as u32).collect();
    let mut vertex_tangents: Vec<[f32; 4]> = vec![[0.0; 4]; vertex_count];
    // Chains of duplicates: next_copy[v] is the next output vertex copying the same input vertex.
    let mut next_copy: Vec<u32> = vec![NONE; vertex_count];
    // Bit 0: a corner with w = +1 was seen; bit 1: w = -1.
    let mut signs = vec![0u8; vertex_count];
    // Made at the first copy: until then every corner keeps its vertex, so the corners before
    // it are the input's indices, and a plan without copies has none of its own.
    let mut out_indices: Option<Vec<u32>> = None;

    for (corner, (&v, tangent)) in indices.iter().zip(corner_tangents).enumerate() {
        let v = v as usize;
        let first_use = signs[v] == 0;
        signs[v] |= if tangent[3] > 0.0 { 1 } else { 2 };
        if first_use {
            vertex_tangents[v] = *tangent;
            if let Some(out) = &mut out_indices {
                out.push(v as u32);
            }
            continue;
        }
        let mut at = v;
        loop {
            // Float equality: -0 and 0 are the same tangent (tangents are never NaN here).
            if vertex_tangents[at] == *tangent {
                if let Some(out) = &mut out_indices {
                    out.push(at as u32);
                }
                break;
            }
            if next_copy[at] == NONE {
                let copy = source_vertex.len();
                source_vertex.push(v as u32);
                vertex_tangents.push(*tangent);
                next_copy.push(NONE);
                next_copy[at] = copy as u32;
                out_indices
                    .get_or_insert_with(|| {
                        let mut out = Vec::with_capacity(indices.len());
                        out.extend_from_slice(&indices[..corner]);
                        out
                    })
                    .push(copy as u32);
                break;
            }
            at = next_copy[at] as usize;
        }
    }

    // Vertices no triangle uses still need a valid tangent in the output.
    for v in 0..vertex_count {
        if signs[v] == 0 {
            let n = unit(normals[v]).unwrap_or([0.0, 0.0, 1.0]);
            let t = any_orthogonal(n);
            vertex_tangents[v] = [t[0], t[1], t[2], 1.0];
        }
    }

    let mut flips = Tally::default();
    for (v, &s) in signs.iter().enumerate() {
        if s == 3 {
            flips.add(v as u32);
        }
    }
    let mut mixed = Tally::default();
    for (t, corners) in corner_tangents.chunks_exact(3).enumerate() {
        if corners[0][3] != corners[1][3] || corners[0][3] != corners[2][3] {
            mixed.add(t as u32);
        }
    }
    diagnostics.handedness_flip_vertices = flips;
    diagnostics.mixed_handedness_triangles = mixed;
    diagnostics.vertices_in = vertex_count as u64;
    diagnostics.vertices_out = source_vertex.len() as u64;
    diagnostics.vertices_added = (source_vertex.len() - vertex_count) as u64;

    SplitPlan {
        source_vertex,
        indices: out_indices,
        vertex_tangents,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_only_where_tangents_differ() {
        let indices = [0, 1, 2, 2, 1, 3];
        let a = [1.0, 0.0, 0.0, 1.0];
        let b = [0.0, 1.0, 0.0, -1.0];
        let tangents = [a, a, a, a, b, b];
        let normals = [[0.0, 0.0, 1.0]; 4];
        let mut d = Diagnostics::default();
        let plan = plan(&indices, 4, &tangents, &normals, &mut d);
        assert_eq!(plan.source_vertex, vec![0, 1, 2, 3, 1]);
        assert_eq!(plan.indices, Some(vec![0, 1, 2, 2, 4, 3]));
        assert_eq!(plan.vertex_tangents[4], b);
        assert_eq!(plan.vertex_tangents[3], b);
        assert_eq!(d.vertices_added, 1);
        assert_eq!(d.handedness_flip_vertices.first, vec![1]);
        assert_eq!(d.mixed_handedness_triangles.first, vec![1]);
    }

    #[test]
    fn unused_vertices_get_a_valid_tangent() {
        let mut d = Diagnostics::default();
        let plan = plan(
            &[0, 0, 0],
            2,
            &[[1.0, 0.0, 0.0, 1.0]; 3],
            &[[0.0, 0.0, 1.0]; 2],
            &mut d,
        );
        assert_eq!(plan.source_vertex, vec![0, 1]);
        assert_eq!(
            plan.indices, None,
            "nothing split: the input's indices stand"
        );
        assert_eq!(plan.vertex_of(2, Some(&[0, 0, 0])), 0);
        assert_eq!(plan.indices_for(None).as_ref(), [0, 1]);
        let mut refined = plan.clone();
        refined.indices_mut(Some(&[0, 0, 0]))[2] = 1;
        assert_eq!(refined.indices, Some(vec![0, 0, 1]));
        let t = plan.vertex_tangents[1];
        assert!((t[0] * t[0] + t[1] * t[1] + t[2] * t[2] - 1.0).abs() < 1e-6 && t[2] == 0.0);
    }
}
