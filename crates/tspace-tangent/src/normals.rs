//! Normals for meshes that have none: flat (one per triangle, as glTF requires of a mesh without
//! normals) or smooth across edges flatter than a crease angle.
//!
//! Either way, corners of one vertex that end up with bit-identical normals keep sharing it, so
//! the result is expressed like a split plan: new vertices as copies of input vertices.

use super::math::{normalize_or_zero, unit};
use super::weld::{CornerTable, Key, weld_vertices};
use super::{MeshInput, NormalMode, SplitPlan};
use glam::Vec3;
use std::collections::HashMap;

pub(crate) struct GeneratedNormals {
    /// One normal per new vertex.
    pub normals: Vec<[f32; 3]>,
    /// New vertices as copies of input vertices, and the new index buffer (no tangents yet).
    pub split: SplitPlan,
}

/// Unit face normal, or +Z for a triangle without area.
fn face_normal(positions: &[[f32; 3]], tri: [usize; 3]) -> [f32; 3] {
    let [a, b, c] = tri.map(|v| positions[v]);
    super::math::face_normal(a, b, c).unwrap_or([0.0, 0.0, 1.0])
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

pub(crate) fn generate(input: &MeshInput<'_>, mode: NormalMode) -> GeneratedNormals {
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
    let triangle_count = indices.len() / 3;
    let faces: Vec<[f32; 3]> = (0..triangle_count)
        .map(|t| face_normal(positions, triangle(t)))
        .collect();

    let corner_normals: Vec<[f32; 3]> = match mode {
        NormalMode::Flat => indices
            .iter()
            .enumerate()
            .map(|(c, _)| faces[c / 3])
            .collect(),
        NormalMode::SmoothByAngle { crease_degrees } => {
            let cos_crease = crease_degrees.to_radians().cos();
            let weld = weld_vertices(
                &Key {
                    positions,
                    normals: None,
                    uvs: None,
                },
                false,
            );
            let corner_class: Vec<u32> = indices
                .iter()
                .map(|&v| weld.class_of_vertex[v as usize])
                .collect();
            let table =
                CornerTable::build_filtered(&corner_class, weld.class_count, |_| true, false);
            let mut normals = vec![[0.0f32; 3]; indices.len()];
            for class in 0..weld.class_count {
                let corners = table.of(class);
                for &c in corners {
                    let own = Vec3::from(faces[c as usize / 3]);
                    let mut sum = Vec3::ZERO;
                    for &d in corners {
                        let other = Vec3::from(faces[d as usize / 3]);
                        if d == c || own.dot(other) >= cos_crease {
                            let w =
                                corner_angle(positions, triangle(d as usize / 3), d as usize % 3);
                            sum += other * w;
                        }
                    }
                    normals[c as usize] = unit(sum.to_array()).unwrap_or(own.to_array());
                }
            }
            normals
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
        split: SplitPlan {
            source_vertex,
            indices: new_indices,
            vertex_tangents: Vec::new(),
        },
    }
}
