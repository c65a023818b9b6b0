//! Normals for meshes that have none: flat (one per triangle, as glTF requires of a mesh without
//! normals) or smooth across edges flatter than a crease angle, optionally only within
//! smoothing groups.
//!
//! Smoothing works edge by edge, as modelling tools' "auto smooth" and smoothing groups do: two
//! triangles sharing an edge (its two end positions, welded) are smoothed together when their
//! faces meet at less than the crease angle (and they are in the same non-zero smoothing group,
//! when groups are given). The corners around one position that are connected by such edges
//! form a fan sharing one normal, the angle-weighted sum of its faces' normals. Edges with more
//! than two triangles are kept hard, as Blender does: which two of them belong together is not
//! known. Comparing edges rather than every pair of corners at a position keeps the work at
//! O(n log n) whatever a vertex's valence (a fan of a million triangles around one apex is one
//! sort, not 10¹² comparisons).
//!
//! Either way, corners of one vertex that end up with bit-identical normals keep sharing it, so
//! the result is expressed like a split plan: new vertices as copies of input vertices.

use super::math::{normalize_or_zero, unit};
use super::weld::{Key, NONE, weld_vertices};
use super::{CoreError, MeshInput, NormalMode};
use glam::Vec3;
use std::collections::HashMap;

/// Normals generated for a mesh without them, with the vertex split they need: a vertex whose
/// corners received different normals is duplicated, one copy per normal.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GeneratedNormals {
    /// One unit normal per new vertex.
    pub normals: Vec<[f32; 3]>,
    /// For every new vertex, the input vertex it copies (in order of first use).
    pub source_vertex: Vec<u32>,
    /// The new index buffer: one entry per input corner, same order.
    pub indices: Vec<u32>,
}

/// Generates normals for `input` (whose own [`MeshInput::normals`] and
/// [`MeshInput::uvs`] are ignored) the way [`NormalMode`] says.
///
/// `smoothing_groups`, when given, has one entry per triangle and follows the convention of
/// OBJ's `s` statement and 3ds Max: triangles of group 0 are flat; a triangle of group `n > 0`
/// is smoothed only with triangles of group `n`, across edges that also pass the crease angle
/// of [`NormalMode::SmoothByAngle`] (a crease of 180° or more smooths a whole group). With
/// [`NormalMode::Flat`] the groups change nothing.
pub fn generate_normals(
    input: &MeshInput<'_>,
    mode: NormalMode,
    smoothing_groups: Option<&[u32]>,
) -> Result<GeneratedNormals, CoreError> {
    super::check_lengths(input, false)?;
    let triangle_count = input.indices.map_or(input.positions.len(), <[u32]>::len) / 3;
    if let Some(groups) = smoothing_groups {
        if groups.len() != triangle_count {
            return Err(CoreError::AttributeLength {
                attribute: "smoothing_groups",
                expected: triangle_count,
                found: groups.len(),
            });
        }
    }
    Ok(generate(input, mode, smoothing_groups))
}

/// Unit face normal, or `None` for a triangle without area.
fn face_normal(positions: &[[f32; 3]], tri: [usize; 3]) -> Option<[f32; 3]> {
    let [a, b, c] = tri.map(|v| positions[v]);
    super::math::face_normal(a, b, c)
}

fn corner_angle(positions: &[[f32; 3]], tri: [usize; 3], i: usize) -> f32 {
    let here = Vec3::from(positions[tri[i]]);
    let edge = |k: usize| normalize_or_zero((Vec3::from(positions[tri[k]]) - here).to_array());
    let angle = Vec3::from(edge((i + 1) % 3))
        .dot(Vec3::from(edge((i + 2) % 3)))
        .clamp(-1.0, 1.0)
        .acos();
    if angle.is_finite() { angle } else { 0.0 }
}

/// Union-find over corners, joining toward the smaller index so that a fan's representative
/// is its first corner, whatever order the joins come in.
struct Fans {
    parent: Vec<u32>,
}

impl Fans {
    fn new(corners: usize) -> Self {
        Fans {
            parent: (0..corners as u32).collect(),
        }
    }

    fn root(&mut self, mut c: u32) -> u32 {
        while self.parent[c as usize] != c {
            let up = self.parent[self.parent[c as usize] as usize];
            self.parent[c as usize] = up;
            c = up;
        }
        c
    }

    fn join(&mut self, a: u32, b: u32) {
        let (a, b) = (self.root(a), self.root(b));
        let (low, high) = if a < b { (a, b) } else { (b, a) };
        self.parent[high as usize] = low;
    }
}

/// One side of an edge: the edge (its two welded positions, lower first), and the side's
/// triangle's corners at each (16 bytes, as a mesh has three per triangle).
#[derive(Clone, Copy)]
struct EdgeSide {
    key: (u32, u32),
    at_low: u32,
    at_high: u32,
}

impl EdgeSide {
    fn triangle(&self) -> usize {
        self.at_low as usize / 3
    }
}

/// Per-corner smooth normals: corners joined into fans across smooth edges, each fan the
/// angle-weighted sum of its faces.
fn smooth_corner_normals(
    positions: &[[f32; 3]],
    indices: &[u32],
    faces: &[Option<[f32; 3]>],
    crease_degrees: f32,
    groups: Option<&[u32]>,
) -> Vec<[f32; 3]> {
    let cos_crease = crease_degrees.to_radians().cos();
    let weld = weld_vertices(
        &Key {
            positions,
            normals: None,
            uvs: None,
            finite: false,
        },
        false,
    );
    let class = |c: usize| weld.class_of_vertex[indices[c] as usize];
    let mut sides: Vec<EdgeSide> = Vec::with_capacity(indices.len());
    for t in 0..indices.len() / 3 {
        for i in 0..3 {
            let (c, d) = (3 * t + i, 3 * t + (i + 1) % 3);
            let (a, b) = (class(c), class(d));
            // A position that welds to nothing (NaN) or a collapsed edge joins no fan.
            if a == NONE || b == NONE || a == b {
                continue;
            }
            let (at_low, at_high) = if a < b { (c, d) } else { (d, c) };
            sides.push(EdgeSide {
                key: (a.min(b), a.max(b)),
                at_low: at_low as u32,
                at_high: at_high as u32,
            });
        }
    }
    // By edge, then by corner (so by triangle): the order, and so the result, depends on the
    // mesh alone.
    sides.sort_unstable_by_key(|s| (s.key, s.at_low));
    let group_of = |t: usize| groups.map_or(1, |g| g[t]);
    let smooth_across = |s: &EdgeSide, r: &EdgeSide| {
        let (t, u) = (s.triangle(), r.triangle());
        let (Some(n), Some(m)) = (faces[t], faces[u]) else {
            return false;
        };
        let same_group = group_of(t) != 0 && group_of(t) == group_of(u);
        same_group && t != u && Vec3::from(n).dot(Vec3::from(m)) >= cos_crease
    };
    let mut fans = Fans::new(indices.len());
    for edge in sides.chunk_by(|s, r| s.key == r.key) {
        if let [s, r] = edge {
            if smooth_across(s, r) {
                fans.join(s.at_low, r.at_low);
                fans.join(s.at_high, r.at_high);
            }
        }
    }

    // A fan whose faces all have the same normal (a lone corner, a flat region) takes that
    // normal as it is, so that it equals the flat one bit for bit; others, the weighted sum.
    let mut sums = vec![Vec3::ZERO; indices.len()];
    let mut uniform: Vec<Option<[f32; 3]>> = vec![None; indices.len()];
    let mut mixed = vec![false; indices.len()];
    for c in 0..indices.len() {
        let t = c / 3;
        if let Some(face) = faces[t] {
            let tri = [0, 1, 2].map(|k| indices[3 * t + k] as usize);
            let root = fans.root(c as u32) as usize;
            sums[root] += Vec3::from(face) * corner_angle(positions, tri, c % 3);
            match uniform[root] {
                None => uniform[root] = Some(face),
                Some(first) => mixed[root] |= first.map(f32::to_bits) != face.map(f32::to_bits),
            }
        }
    }
    (0..indices.len())
        .map(|c| {
            let own = faces[c / 3].unwrap_or([0.0, 0.0, 1.0]);
            let root = fans.root(c as u32) as usize;
            match uniform[root] {
                Some(face) if !mixed[root] => face,
                _ => unit(sums[root].to_array()).unwrap_or(own),
            }
        })
        .collect()
}

pub(crate) fn generate(
    input: &MeshInput<'_>,
    mode: NormalMode,
    groups: Option<&[u32]>,
) -> GeneratedNormals {
    let positions = input.positions;
    let indices: Vec<u32> = match input.indices {
        Some(indices) => indices.to_vec(),
        None => (0..positions.len() as u32).collect(),
    };
    let triangle = |t: usize| {
        [
            indices[3 * t] as usize,
            indices[3 * t + 1] as usize,
            indices[3 * t + 2] as usize,
        ]
    };
    let faces: Vec<Option<[f32; 3]>> = (0..indices.len() / 3)
        .map(|t| face_normal(positions, triangle(t)))
        .collect();

    let corner_normals: Vec<[f32; 3]> = match mode {
        NormalMode::Flat => (0..indices.len())
            .map(|c| faces[c / 3].unwrap_or([0.0, 0.0, 1.0]))
            .collect(),
        NormalMode::SmoothByAngle { crease_degrees } => {
            smooth_corner_normals(positions, &indices, &faces, crease_degrees, groups)
        }
    };

    // Keep one vertex per (input vertex, normal) pair, in order of first use.
    let mut seen: HashMap<(u32, [u32; 3]), u32> = HashMap::with_capacity(indices.len());
    let mut source_vertex = Vec::new();
    let mut normals = Vec::new();
    let mut new_indices = Vec::with_capacity(indices.len());
    for (&v, n) in indices.iter().zip(&corner_normals) {
        let key = (v, n.map(|x| if x == 0.0 { 0 } else { x.to_bits() }));
        let next = source_vertex.len() as u32;
        let id = *seen.entry(key).or_insert(next);
        if id == next {
            source_vertex.push(v);
            normals.push(*n);
        }
        new_indices.push(id);
    }
    GeneratedNormals {
        normals,
        source_vertex,
        indices: new_indices,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const SMOOTH_60: NormalMode = NormalMode::SmoothByAngle {
        crease_degrees: 60.0,
    };

    fn run(
        positions: &[[f32; 3]],
        indices: &[u32],
        mode: NormalMode,
        groups: Option<&[u32]>,
    ) -> GeneratedNormals {
        let input = MeshInput {
            positions,
            normals: None,
            uvs: None,
            indices: Some(indices),
        };
        generate_normals(&input, mode, groups).unwrap()
    }

    fn corner_normal(g: &GeneratedNormals, corner: usize) -> [f32; 3] {
        g.normals[g.indices[corner] as usize]
    }

    /// A unit cube: 8 shared positions, 12 triangles, two per side, wound outward.
    fn cube() -> (Vec<[f32; 3]>, Vec<u32>) {
        let positions = (0..8)
            .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
            .collect();
        let quads = [
            [0, 2, 3, 1], // z = 0
            [4, 5, 7, 6], // z = 1
            [0, 1, 5, 4], // y = 0
            [2, 6, 7, 3], // y = 1
            [0, 4, 6, 2], // x = 0
            [1, 3, 7, 5], // x = 1
        ];
        let indices = quads
            .iter()
            .flat_map(|q| [q[0], q[1], q[2], q[0], q[2], q[3]])
            .collect();
        (positions, indices)
    }

    /// An open cylinder of `sides` quads around +Z, each side split in two triangles.
    fn cylinder(sides: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
        let mut positions = Vec::new();
        for i in 0..sides {
            let a = i as f32 / sides as f32 * std::f32::consts::TAU;
            positions.push([a.cos(), a.sin(), 0.0]);
            positions.push([a.cos(), a.sin(), 1.0]);
        }
        let mut indices = Vec::new();
        for i in 0..sides {
            let j = (i + 1) % sides;
            let [b0, t0, b1, t1] = [2 * i, 2 * i + 1, 2 * j, 2 * j + 1];
            indices.extend([b0, b1, t1, b0, t1, t0]);
        }
        (positions, indices)
    }

    #[test]
    fn a_cube_keeps_its_hard_edges_below_a_90_degree_crease_and_shares_coplanar_corners() {
        let (positions, indices) = cube();
        let g = run(&positions, &indices, SMOOTH_60, None);
        // Every side's two triangles share their diagonal's two vertices: 4 per side.
        assert_eq!(g.normals.len(), 24);
        for c in 0..indices.len() {
            let t = c / 3;
            let tri = [0, 1, 2].map(|k| indices[3 * t + k] as usize);
            assert_eq!(corner_normal(&g, c), face_normal(&positions, tri).unwrap());
        }
        assert_eq!(
            run(&positions, &indices, NormalMode::Flat, None)
                .normals
                .len(),
            24
        );
    }

    #[test]
    fn a_cube_in_one_smoothing_group_is_smooth_whatever_the_crease() {
        let (positions, indices) = cube();
        let all_smooth = NormalMode::SmoothByAngle {
            crease_degrees: 180.0,
        };
        let g = run(&positions, &indices, all_smooth, Some(&[1; 12]));
        assert_eq!(g.normals.len(), 8);
        for (v, n) in g.source_vertex.iter().zip(&g.normals) {
            // Each corner's normal points away from the centre, along the diagonal.
            let p = Vec3::from(positions[*v as usize]) - Vec3::splat(0.5);
            assert!(Vec3::from(*n).dot(p.normalize()) > 0.99, "{v}: {n:?}");
        }
    }

    #[test]
    fn group_zero_is_flat_and_groups_do_not_smooth_across_their_border() {
        let (positions, indices) = cylinder(16);
        // The cylinder's sides meet at 22.5°: smooth with a 60° crease.
        let smooth = run(&positions, &indices, SMOOTH_60, None);
        assert_eq!(smooth.normals.len(), 32);
        // Group 0 everywhere: as flat.
        let off = run(&positions, &indices, SMOOTH_60, Some(&[0; 32]));
        assert_eq!(off, run(&positions, &indices, NormalMode::Flat, None));
        // Two groups, half the sides each: the two borders (at sides 0 and 8) stay hard, so
        // their 4 positions have two normals each.
        let halves: Vec<u32> = (0..32).map(|t| 1 + t / 16).collect();
        let split = run(&positions, &indices, SMOOTH_60, Some(&halves));
        assert_eq!(split.normals.len(), 36);
        // Group numbers are labels: renumbering changes nothing.
        let renamed: Vec<u32> = halves.iter().map(|g| g * 1000).collect();
        assert_eq!(split, run(&positions, &indices, SMOOTH_60, Some(&renamed)));
    }

    #[test]
    fn a_crease_sharper_than_the_sides_keeps_them_flat() {
        let (positions, indices) = cylinder(6); // sides meet at 60°
        let g = run(
            &positions,
            &indices,
            NormalMode::SmoothByAngle {
                crease_degrees: 45.0,
            },
            None,
        );
        assert_eq!(g, run(&positions, &indices, NormalMode::Flat, None));
    }

    #[test]
    fn split_uv_seams_are_still_smoothed_because_positions_are_welded() {
        let (mut positions, mut indices) = cylinder(16);
        // Give sides 0 and 1 their own copy of the two positions they share, as a UV seam does.
        let copies = [positions[2], positions[3]];
        positions.extend(copies);
        for i in indices.iter_mut().take(6) {
            *i = match *i {
                2 => 32,
                3 => 33,
                other => other,
            };
        }
        let g = run(&positions, &indices, SMOOTH_60, None);
        assert_eq!(g.normals.len(), 34);
        let normal_of = |v: u32| {
            let at = g.source_vertex.iter().position(|&s| s == v).unwrap();
            g.normals[at]
        };
        assert_eq!(normal_of(2), normal_of(32));
    }

    #[test]
    fn an_edge_of_three_triangles_stays_hard_and_a_huge_fan_is_linear() {
        // Three coplanar-ish fins on one edge (0, 1): non-manifold, so no fan crosses it.
        let positions = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
            [0.5, 0.0, 1.0],
        ];
        let indices = [0, 1, 2, 1, 0, 3, 0, 1, 4];
        let g = run(&positions, &indices, SMOOTH_60, None);
        assert_eq!(g, run(&positions, &indices, NormalMode::Flat, None));

        // A cone of 200,000 triangles around one apex finishes at once (no pairwise search).
        let n = 200_000u32;
        let mut positions = vec![[0.0f32, 0.0, 1.0]];
        positions.extend((0..n).map(|i| {
            let a = i as f32 / n as f32 * std::f32::consts::TAU;
            [a.cos(), a.sin(), 0.0]
        }));
        let indices: Vec<u32> = (0..n).flat_map(|i| [0, 1 + i, 1 + (i + 1) % n]).collect();
        let g = run(&positions, &indices, SMOOTH_60, None);
        assert_eq!(g.indices.len(), indices.len());
    }

    #[test]
    fn wrong_group_count_is_an_error() {
        let (positions, indices) = cube();
        let input = MeshInput {
            positions: &positions,
            normals: None,
            uvs: None,
            indices: Some(&indices),
        };
        assert_eq!(
            generate_normals(&input, SMOOTH_60, Some(&[1; 11])),
            Err(CoreError::AttributeLength {
                attribute: "smoothing_groups",
                expected: 12,
                found: 11,
            })
        );
    }

    fn random_mesh() -> impl Strategy<Value = (Vec<[f32; 3]>, Vec<u32>, Vec<u32>)> {
        (3usize..12).prop_flat_map(|vertices| {
            let position = prop::array::uniform3(prop_oneof![
                4 => -2i8..=2,
                1 => Just(0i8),
            ]);
            (
                prop::collection::vec(position, vertices),
                prop::collection::vec(0..vertices as u32, 3..48),
            )
                .prop_flat_map(|(positions, mut indices)| {
                    indices.truncate(indices.len() / 3 * 3);
                    let triangles = indices.len() / 3;
                    let positions: Vec<[f32; 3]> =
                        positions.iter().map(|p| p.map(f32::from)).collect();
                    (
                        Just(positions),
                        Just(indices),
                        prop::collection::vec(0u32..3, triangles),
                    )
                })
        })
    }

    proptest! {
        /// Whatever the mesh: one unit normal per new vertex, every corner keeps its input
        /// vertex, and a triangle of group 0 keeps its face normal (+Z without area).
        #[test]
        fn smooth_normals_follow_their_edges(
            (positions, indices, groups) in random_mesh(),
            crease in 0.0f32..200.0,
        ) {
            let mode = NormalMode::SmoothByAngle { crease_degrees: crease };
            let g = run(&positions, &indices, mode, Some(&groups));
            prop_assert_eq!(g.indices.len(), indices.len());
            prop_assert_eq!(g.normals.len(), g.source_vertex.len());
            for (c, &v) in indices.iter().enumerate() {
                prop_assert_eq!(g.source_vertex[g.indices[c] as usize], v);
            }
            for n in &g.normals {
                let length = Vec3::from(*n).length();
                prop_assert!((length - 1.0).abs() < 1e-5, "{:?}", n);
            }
            let tri = |t: usize| [0, 1, 2].map(|k| indices[3 * t + k] as usize);
            let own = |t: usize| face_normal(&positions, tri(t)).unwrap_or([0.0, 0.0, 1.0]);
            for (t, _) in groups.iter().enumerate().filter(|(_, g)| **g == 0) {
                for k in 0..3 {
                    prop_assert_eq!(corner_normal(&g, 3 * t + k), own(t));
                }
            }
        }

        /// Without groups, a crease of 180° or more and one of "every group the same" agree.
        #[test]
        fn no_groups_is_one_group(
            (positions, indices, _) in random_mesh(),
            crease in 0.0f32..200.0,
        ) {
            let mode = NormalMode::SmoothByAngle { crease_degrees: crease };
            let ones = vec![7; indices.len() / 3];
            prop_assert_eq!(
                run(&positions, &indices, mode, None),
                run(&positions, &indices, mode, Some(&ones))
            );
        }
    }
}
