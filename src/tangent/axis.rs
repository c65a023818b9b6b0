//! Tangents without texture coordinates: the normal crossed with the world axis least aligned
//! with it (the "any vector" trick). Smooth wherever the normals are, valid everywhere, and never
//! the default: a normal map cannot have been baked against it.

use super::fallback::effective_normal;
use super::math::{CornerTangent, Mesh, any_orthogonal};

pub(crate) fn generate(mesh: &Mesh<'_>) -> Vec<CornerTangent> {
    (0..mesh.indices.len())
        .map(|corner| CornerTangent {
            tangent: any_orthogonal(effective_normal(mesh, corner)),
            orientation_preserving: true,
            assigned: true,
        })
        .collect()
}
