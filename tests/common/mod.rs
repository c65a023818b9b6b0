//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod meshes;
pub mod process;
pub mod scene;
#[path = "../../benches/shapes.rs"]
pub mod shapes;
pub mod validator;

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

pub use shapes::angle_degrees;

/// Whether the reference's tangent is one we pass through: finite, unit, orthogonal to `normal`.
pub fn reference_is_valid(t: Option<[f32; 4]>, normal: [f32; 3]) -> bool {
    let Some(t) = t else { return false };
    let len2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
    let nl = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
    let d = (t[0] * normal[0] + t[1] * normal[1] + t[2] * normal[2]) / nl;
    t.iter().all(|x| x.is_finite()) && (len2 - 1.0).abs() < 8e-6 && d.abs() < 4e-5
}

/// The bytes of a file in `fixtures/`.
pub fn fixture(path: &str) -> Vec<u8> {
    let full = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(path);
    std::fs::read(&full).unwrap_or_else(|e| panic!("fixture {path}: {e}"))
}

/// The JSON chunk of a GLB, parsed.
pub fn glb_json(bytes: &[u8]) -> serde_json::Value {
    let glb = tspace::scene::gltf::glb::parse(bytes).expect("a GLB");
    serde_json::from_slice(glb.json).expect("JSON")
}

/// Validates an output with the glTF-Validator (when installed) and asserts it has no errors
/// but the missing-image ones the fixtures cause on purpose (they ship without their images).
pub fn assert_valid_output(name: &str, bytes: &[u8]) -> Option<validator::ValidatorReport> {
    let report = validator::validate(name, bytes)?;
    eprintln!("validator, {name}: {}", report.summary());
    for m in &report.messages {
        eprintln!(
            "  {:?} {} {:?} {}",
            m.severity, m.code, m.pointer, m.message
        );
    }
    let errors: Vec<_> = report
        .messages_of(validator::Severity::Error)
        .filter(|m| {
            !(m.code == "IO_ERROR"
                && m.pointer
                    .as_deref()
                    .is_some_and(|p| p.starts_with("/images/")))
        })
        .map(|m| format!("{} at {:?}: {}", m.code, m.pointer, m.message))
        .collect();
    assert!(errors.is_empty(), "{name}: validator errors {errors:#?}");
    Some(report)
}
