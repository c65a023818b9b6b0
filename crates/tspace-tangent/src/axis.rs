//! Tangents without texture coordinates: the normal crossed with the world axis least aligned
//! with it (the "any vector" trick). Smooth wherever the normals are, valid everywhere, and never
//! the default: a normal map cannot have been baked against it.

use super::fallback::effective_normal;
use super::math::{Mesh, any_orthogonal, encode};

pub(crate) fn generate(mesh: &Mesh<'_>) -> Vec<[f32; 4]> {
    (0..mesh.indices.len())
        .map(|corner| encode(any_orthogonal(effective_normal(mesh, corner)), true))
        .collect()
}
