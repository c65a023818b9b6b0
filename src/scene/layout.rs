//! The texture layout of a computed geometry: what a UV-layout picture draws.

use tspace_tangent::Marks;

/// One computed geometry in texture space: its texture coordinates, its triangles, and what the
/// core found in each.
#[derive(Clone, Debug)]
pub struct Layout {
    /// Every primitive that shares this geometry, in document order.
    pub primitives: Vec<PrimitiveRef>,
    /// The texture-coordinate set drawn (`TEXCOORD_n`): the one the tangents follow.
    pub texcoord: u32,
    pub uvs: Vec<[f32; 2]>,
    /// A triangle list, or `None` when every three vertices form a triangle.
    pub indices: Option<Vec<u32>>,
    pub marks: Marks,
    /// Corners given a fallback tangent (the report's `fallback_tangents.count`).
    pub repaired_corners: u64,
}

/// Where a primitive is: `meshes[mesh].primitives[primitive]`, and its mesh's name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PrimitiveRef {
    pub mesh: usize,
    pub primitive: usize,
    pub mesh_name: Option<String>,
}

impl Layout {
    /// The vertices of triangle `t`.
    pub fn triangle(&self, t: usize) -> [usize; 3] {
        let corner = |c: usize| {
            self.indices
                .as_ref()
                .map_or(c, |i| i.get(c).map_or(0, |&v| v as usize))
        };
        [corner(3 * t), corner(3 * t + 1), corner(3 * t + 2)]
    }

    pub fn triangle_count(&self) -> usize {
        self.marks.triangles.len()
    }
}
