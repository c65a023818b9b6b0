//! KHR_mesh_quantization: where NORMAL is a normalized BYTE or SHORT, the TANGENT tspace writes
//! takes the same type, within the quantization's own bound of the reference, on gltfpack's
//! quantized fixtures (`fixtures/compressed/`, see its README). `tangents=float` keeps float.

use tspace::scene::gltf::accessor::ComponentType;
use tspace::scene::gltf::load::NoResources;
use tspace::scene::gltf::process;
use tspace::scene::report::TangentComponent;
use tspace::scene::{SceneOptions, TangentType};
use tspace_testkit::fixtures::{assert_valid_output, workspace_root};
use tspace_testkit::written::{read_primitives, worst_angle_to_reference};

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
            assert_eq!(tangent.component_type, TangentComponent::Byte, "{name}");
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
            let worst = worst_angle_to_reference(&p);
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
        TangentComponent::Float
    );
    let bytes = processed.bytes.unwrap();
    assert_valid_output(name, &bytes);
    for p in read_primitives(&bytes) {
        assert_eq!(p.tangent_type, ComponentType::F32);
        assert!(worst_angle_to_reference(&p) <= 0.01, "{name}");
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
        TangentComponent::Float
    );
}
