//! The oracle: `bevy_mikktspace` 1.0, a byte-exact port of the MikkTSpace C reference, run on
//! an indexed mesh, and what counts as a valid tangent from it.

/// Runs the reference (`bevy_mikktspace` 1.0, a byte-exact port of the C code) on an indexed
/// mesh. `None` marks corners the reference leaves at its default.
pub fn reference_tangents(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    uvs: &[[f32; 2]],
    indices: &[u32],
) -> Vec<Option<[f32; 4]>> {
    struct Geometry<'a> {
        positions: &'a [[f32; 3]],
        normals: &'a [[f32; 3]],
        uvs: &'a [[f32; 2]],
        indices: &'a [u32],
        out: Vec<Option<[f32; 4]>>,
    }
    impl bevy_mikktspace::Geometry for Geometry<'_> {
        fn num_faces(&self) -> usize {
            self.indices.len() / 3
        }
        fn num_vertices_of_face(&self, _face: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            self.positions[self.indices[face * 3 + vert] as usize]
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            self.normals[self.indices[face * 3 + vert] as usize]
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            self.uvs[self.indices[face * 3 + vert] as usize]
        }
        fn set_tangent(
            &mut self,
            tangent: Option<bevy_mikktspace::TangentSpace>,
            face: usize,
            vert: usize,
        ) {
            self.out[face * 3 + vert] = tangent.map(|t| t.tangent_encoded());
        }
    }
    let mut g = Geometry {
        positions,
        normals,
        uvs,
        indices,
        out: vec![None; indices.len()],
    };
    bevy_mikktspace::generate_tangents(&mut g).expect("the reference does not fail");
    g.out
}

/// Whether the reference's tangent is one we pass through: finite, unit, orthogonal to `normal`.
pub fn reference_is_valid(t: Option<[f32; 4]>, normal: [f32; 3]) -> bool {
    let Some(t) = t else { return false };
    let len2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
    let nl = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
    let d = (t[0] * normal[0] + t[1] * normal[1] + t[2] * normal[2]) / nl;
    t.iter().all(|x| x.is_finite()) && (len2 - 1.0).abs() < 8e-6 && d.abs() < 4e-5
}
