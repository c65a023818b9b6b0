//! What a picture of a mesh should mark: every triangle's findings and every vertex whose
//! tangents flip handedness, for the whole mesh where [`Diagnostics`](crate::Diagnostics) keeps
//! counts and the first few indices.
//!
//! A separate pass over a mesh already computed, so that [`crate::generate`] stays as lean as it
//! is for the callers who only want tangents. It uses the same triangle test as the diagnostics,
//! so what a picture shows and what a report counts cannot disagree.

use super::diagnostics::TriangleCheck;
use super::math::is_finite3;
use super::{Cancel, MeshInput, Options, Tangents};

/// The findings of one triangle, as bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TriangleMarks(u8);

impl TriangleMarks {
    /// Two corners at exactly the same position.
    pub const DUPLICATE_POSITION: u8 = 1;
    /// No area (collinear corners, slivers).
    pub const ZERO_AREA: u8 = 2;
    /// No area in texture space.
    pub const ZERO_UV_AREA: u8 = 4;
    /// Texture coordinates winding the other way (mirrored UVs).
    pub const MIRRORED_UV: u8 = 8;
    /// A NaN or infinite position, normal or texture coordinate.
    pub const NON_FINITE: u8 = 16;
    /// At least one corner was given a fallback tangent.
    pub const REPAIRED: u8 = 32;

    /// Marks made of the bits above (for callers that build their own).
    pub fn from_bits(bits: u8) -> Self {
        TriangleMarks(bits)
    }

    /// Whether any of `bits` is set.
    pub fn has(self, bits: u8) -> bool {
        self.0 & bits != 0
    }

    /// No area in space, or numbers that are not numbers: invisible in a render, whatever its
    /// texture coordinates do.
    pub fn is_degenerate(self) -> bool {
        self.has(Self::DUPLICATE_POSITION | Self::ZERO_AREA | Self::NON_FINITE)
    }

    /// The bits.
    pub fn bits(self) -> u8 {
        self.0
    }
}

/// [`marks`]'s answer.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Marks {
    /// One entry per triangle, in input order.
    pub triangles: Vec<TriangleMarks>,
    /// Input vertices whose corners received tangents of both handedness, ascending.
    pub flip_vertices: Vec<u32>,
}

impl Marks {
    /// How many triangles have any of `bits`.
    pub fn count(&self, bits: u8) -> u64 {
        self.triangles.iter().filter(|m| m.has(bits)).count() as u64
    }
}

/// Marks every triangle and vertex of `input`, whose tangents `tangents` are (as [`crate::generate`]
/// returned them for the same input and options).
///
/// The triangle findings are those [`crate::Diagnostics`] counts (`duplicate_position_triangles`
/// and the others), with a triangle of non-finite values marked as that alone, as there; a
/// triangle is marked repaired when one of its corners is in
/// [`FallbackCounts::all_corners`](crate::FallbackCounts::all_corners). A flip vertex is an input
/// vertex whose corners' tangents have both signs of `w`: with normals given, the vertices
/// `handedness_flip_vertices` counts. The input must be one [`crate::generate`] accepted.
pub fn marks(input: &MeshInput<'_>, options: &Options, tangents: &Tangents) -> Marks {
    let positions = input.positions;
    let vertex_count = positions.len();
    let corner_count = input.indices.map_or(vertex_count, <[u32]>::len);
    let vertex = |corner: usize| -> usize {
        input
            .indices
            .map_or(corner, |i| i.get(corner).map_or(0, |&v| v as usize))
            .min(vertex_count.saturating_sub(1))
    };
    let finite = |v: usize| {
        is_finite3(positions[v])
            && input.normals.is_none_or(|n| is_finite3(n[v]))
            && input
                .uvs
                .is_none_or(|uv| uv[v][0].is_finite() && uv[v][1].is_finite())
    };
    let non_finite_vertex: Vec<bool> = if (0..vertex_count).all(finite) {
        Vec::new()
    } else {
        (0..vertex_count).map(|v| !finite(v)).collect()
    };
    let check = TriangleCheck {
        uv_origin: options.uv_origin,
        has_uvs: input.uvs.is_some(),
        non_finite_vertex: &non_finite_vertex,
        cancel: &Cancel::default(),
    };
    let mut triangles: Vec<TriangleMarks> = (0..corner_count / 3)
        .map(|t| {
            if vertex_count == 0 {
                return TriangleMarks::default();
            }
            let corners = [vertex(3 * t), vertex(3 * t + 1), vertex(3 * t + 2)];
            if check.touches_non_finite(corners) {
                return TriangleMarks(TriangleMarks::NON_FINITE);
            }
            let p = corners.map(|v| positions[v]);
            let uv = corners.map(|v| input.uvs.map_or([0.0; 2], |uvs| uvs[v]));
            TriangleMarks(check.events(&p, &uv))
        })
        .collect();
    for &corner in &tangents.diagnostics.fallback_tangents.all_corners {
        if let Some(marks) = triangles.get_mut(corner as usize / 3) {
            marks.0 |= TriangleMarks::REPAIRED;
        }
    }
    Marks {
        triangles,
        flip_vertices: flip_vertices(tangents, input.indices, vertex_count, corner_count, vertex),
    }
}

/// The input vertices whose corners' tangents have both signs of `w`.
fn flip_vertices(
    tangents: &Tangents,
    input_indices: Option<&[u32]>,
    vertex_count: usize,
    corner_count: usize,
    vertex: impl Fn(usize) -> usize,
) -> Vec<u32> {
    const POSITIVE: u8 = 1;
    const NEGATIVE: u8 = 2;
    let mut signs = vec![0u8; vertex_count];
    let split = &tangents.split;
    let output_vertices = split.indices_for(input_indices);
    for (corner, &output_vertex) in output_vertices.iter().enumerate().take(corner_count) {
        let Some(tangent) = split.vertex_tangents.get(output_vertex as usize) else {
            continue;
        };
        if let Some(sign) = signs.get_mut(vertex(corner)) {
            *sign |= if tangent[3] < 0.0 { NEGATIVE } else { POSITIVE };
        }
    }
    signs
        .iter()
        .enumerate()
        .filter(|&(_, &s)| s == POSITIVE | NEGATIVE)
        .map(|(v, _)| v as u32)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;

    /// Two quads side by side, the right one's UVs mirrored, plus a triangle with two corners at
    /// one position.
    /// Positions, normals, UVs and indices.
    type Mesh = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[f32; 2]>, Vec<u32>);

    fn mirrored_pair() -> Mesh {
        let positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [3.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [3.0, 1.0, 0.0],
        ];
        let normals = vec![[0.0, 0.0, 1.0]; 9];
        // u runs right on the left quad and back left on the right one: the shared edge
        // (vertices 1 and 2) is a mirror seam.
        let uvs = vec![
            [0.0, 1.0],
            [1.0, 1.0],
            [1.0, 0.0],
            [0.0, 0.0],
            [0.0, 1.0],
            [0.0, 0.0],
            [0.5, 0.5],
            [0.6, 0.5],
            [0.5, 0.6],
        ];
        // The last triangle has two corners at one position, and vertices of its own: they get
        // no tangent from anywhere, so fallbacks.
        let indices = vec![0, 1, 2, 0, 2, 3, 1, 4, 5, 1, 5, 2, 6, 7, 8];
        (positions, normals, uvs, indices)
    }

    /// The mesh's tangents, with default options, and its marks.
    fn computed(mesh: &Mesh) -> (Tangents, Marks) {
        let (positions, normals, uvs, indices) = mesh;
        let input = MeshInput {
            positions,
            normals: Some(normals),
            uvs: Some(uvs),
            indices: Some(indices),
        };
        let options = Options::default();
        let tangents = generate(&input, &options).unwrap();
        let marks = marks(&input, &options, &tangents);
        (tangents, marks)
    }

    #[test]
    fn marks_agree_with_the_diagnostics() {
        let (tangents, marks) = computed(&mirrored_pair());
        let d = &tangents.diagnostics;
        assert_eq!(marks.triangles.len(), 5);
        assert_eq!(
            marks.count(TriangleMarks::MIRRORED_UV),
            d.mirrored_uv_triangles.count
        );
        // The right quad's two, and the degenerate triangle's: findings overlap.
        assert_eq!(marks.count(TriangleMarks::MIRRORED_UV), 3);
        assert!(marks.triangles[2].has(TriangleMarks::MIRRORED_UV));
        assert!(!marks.triangles[0].has(TriangleMarks::MIRRORED_UV));
        assert_eq!(
            marks.count(TriangleMarks::DUPLICATE_POSITION),
            d.duplicate_position_triangles.count
        );
        assert!(marks.triangles[4].is_degenerate());
        let repaired_triangles: Vec<u32> = d
            .fallback_tangents
            .all_corners
            .iter()
            .map(|c| c / 3)
            .collect();
        assert!(repaired_triangles.contains(&4), "{repaired_triangles:?}");
        assert!(marks.triangles[4].has(TriangleMarks::REPAIRED));
        assert_eq!(
            marks.flip_vertices.len() as u64,
            d.handedness_flip_vertices.count
        );
        assert_eq!(marks.flip_vertices, vec![1, 2]);
    }

    #[test]
    fn a_non_finite_triangle_is_marked_as_that_alone() {
        let mut mesh = mirrored_pair();
        mesh.0[4][0] = f32::NAN;
        let (tangents, marks) = computed(&mesh);
        assert_eq!(
            marks.count(TriangleMarks::NON_FINITE),
            tangents.diagnostics.non_finite_triangles.count
        );
        assert!(marks.triangles[2].has(TriangleMarks::NON_FINITE));
        assert!(!marks.triangles[2].has(TriangleMarks::MIRRORED_UV));
    }
}
