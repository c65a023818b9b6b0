//! KHR_mesh_quantization: where NORMAL is a normalized BYTE or SHORT, the TANGENT tspace writes
//! takes the same type, within the quantization's own bound of the reference, on gltfpack's
//! quantized fixtures (`fixtures/compressed/`, see its README). `tangents=float` keeps float.

use tspace::scene::gltf::accessor::{self, ComponentType};
use tspace::scene::gltf::load::{self, LoadLimits, NoResources};
use tspace::scene::gltf::process;
use tspace::scene::{SceneOptions, TangentType};
use tspace_testkit::fixtures::{assert_valid_output, workspace_root};
use tspace_testkit::{angle_degrees, reference_is_valid, reference_tangents};

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(workspace_root().join("fixtures/compressed").join(name)).unwrap()
}

fn overwrite(tangents: TangentType) -> SceneOptions {
    SceneOptions {
        overwrite: true,
        all: true,
        tangents,
        ..SceneOptions::default()
    }
}

/// Half a step on each of three components: the furthest a rounded unit vector can turn.
fn quantization_bound_degrees(max: f32) -> f64 {
    (3f64.sqrt() / 2.0 / f64::from(max)).asin().to_degrees()
}

/// Every primitive of a written GLB, read back with tspace's own accessor reader (the `gltf`
/// crate's readers do not dequantize): positions, unit normals, UVs of the normal map, indices,
/// and the TANGENT with its component type.
struct Read {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
    tangents: Vec<[f32; 4]>,
    tangent_type: ComponentType,
}

fn read_primitives(bytes: &[u8]) -> Vec<Read> {
    let limits = LoadLimits {
        max_buffer_bytes: 1 << 30,
    };
    let loaded = load::load(bytes, &NoResources, &limits).unwrap();
    let root = loaded.doc.root();
    let buffers = loaded.buffer_slices();
    let index = |n: Option<&tspace_json::Node>| n.and_then(|n| n.as_u64()).unwrap() as usize;
    let mut out = Vec::new();
    for mesh in root.get("meshes").unwrap().as_array().unwrap() {
        for primitive in mesh.get("primitives").unwrap().as_array().unwrap() {
            let attributes = primitive.get("attributes").unwrap();
            let floats3 = |key| {
                accessor::read_floats_json::<3>(root, index(attributes.get(key)), &buffers, 1 << 24)
                    .unwrap()
            };
            let tangent = index(attributes.get("TANGENT"));
            let described = accessor::accessor_from_json(root, tangent, &buffers).unwrap();
            let mut normals = floats3("NORMAL");
            for n in &mut normals {
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                *n = [n[0] / l, n[1] / l, n[2] / l];
            }
            out.push(Read {
                positions: floats3("POSITION"),
                normals,
                uvs: accessor::read_floats_json::<2>(
                    root,
                    index(attributes.get("TEXCOORD_0")),
                    &buffers,
                    1 << 24,
                )
                .unwrap(),
                indices: accessor::read_indices_json(
                    root,
                    index(primitive.get("indices")),
                    &buffers,
                    1 << 24,
                )
                .unwrap(),
                tangents: accessor::read_floats::<4>(&described, 1 << 24).unwrap(),
                tangent_type: described.component_type,
            });
        }
    }
    out
}

/// The largest angle between the written tangents and the reference on the written geometry;
/// handedness must agree everywhere the reference is valid.
fn worst_angle(p: &Read) -> f64 {
    let reference = reference_tangents(&p.positions, &p.normals, &p.uvs, &p.indices);
    let mut worst = 0f64;
    for (corner, r) in reference.iter().enumerate() {
        let v = p.indices[corner] as usize;
        if !reference_is_valid(*r, p.normals[v]) {
            continue;
        }
        let (r, ours) = (r.unwrap(), p.tangents[v]);
        assert_eq!(ours[3], -r[3], "corner {corner}: handedness");
        worst = worst.max(angle_degrees(
            [r[0], r[1], r[2]],
            [ours[0], ours[1], ours[2]],
        ));
    }
    worst
}

#[test]
fn quantized_normals_get_tangents_of_their_own_type() {
    for name in [
        "WaterBottle_gltfpack_quantized.glb",
        "MorphPrimitivesTest_gltfpack_quantized.glb",
    ] {
        let processed = process(&fixture(name), &NoResources, &overwrite(TangentType::Auto))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        for p in &processed.report.primitives {
            let tangent = p.tangent.unwrap();
            assert_eq!(tangent.component_type, "byte", "{name}");
            let added = f64::from(tangent.max_quantization_degrees.unwrap());
            assert!(
                added <= quantization_bound_degrees(127.0),
                "{name}: {added}"
            );
        }
        let bytes = processed.bytes.unwrap();
        assert_valid_output(name, &bytes);
        for p in read_primitives(&bytes) {
            assert_eq!(p.tangent_type, ComponentType::I8, "{name}");
            // The reference runs on the written (dequantized) geometry; only rounding differs.
            let worst = worst_angle(&p);
            assert!(
                worst <= quantization_bound_degrees(127.0) + 0.01,
                "{name}: {worst}°"
            );
        }
    }
}

#[test]
fn float_tangents_when_asked() {
    let name = "WaterBottle_gltfpack_quantized.glb";
    let processed = process(&fixture(name), &NoResources, &overwrite(TangentType::Float)).unwrap();
    assert_eq!(
        processed.report.primitives[0]
            .tangent
            .unwrap()
            .component_type,
        "float"
    );
    let bytes = processed.bytes.unwrap();
    assert_valid_output(name, &bytes);
    for p in read_primitives(&bytes) {
        assert_eq!(p.tangent_type, ComponentType::F32);
        assert!(worst_angle(&p) <= 0.01, "{name}");
    }
}

#[test]
fn float_normals_keep_float_tangents() {
    let processed = process(
        &fixture("WaterBottle_draco.glb"),
        &NoResources,
        &overwrite(TangentType::Auto),
    )
    .unwrap();
    assert_eq!(
        processed.report.primitives[0]
            .tangent
            .unwrap()
            .component_type,
        "float"
    );
}
