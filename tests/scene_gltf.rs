//! The glTF scene layer end to end: fixtures in, GLB or `.gltf` out, checked with an independent
//! reader (the `gltf` crate), the Khronos glTF-Validator where it is installed, and a structural
//! diff of the JSON against the input.

#[allow(unused_imports)]
mod common;

use common::validator::{self, ValidatorReport};
use serde_json::Value;
use std::path::Path;
use tspace::scene::gltf::load::NoResources;
use tspace::scene::gltf::write::OutputFormat;
use tspace::scene::gltf::{Processed, SceneOptions, process};
use tspace::scene::uri::PartSet;
use tspace::tangent::Method;

fn fixture(path: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fixtures")
            .join(path),
    )
    .unwrap_or_else(|e| panic!("fixture {path}: {e}"))
}

/// Processes a `.gltf` fixture with its `.bin` supplied as a part.
fn run_gltf(dir: &str, name: &str, options: SceneOptions) -> Processed {
    let gltf = fixture(&format!("{dir}/{name}.gltf"));
    let bin = fixture(&format!("{dir}/{name}.bin"));
    let mut parts = PartSet::new();
    parts.insert(format!("{name}.bin"), &bin).unwrap();
    process(&gltf, &parts, &options).unwrap_or_else(|e| panic!("{dir}: {e}"))
}

fn overwrite() -> SceneOptions {
    SceneOptions {
        overwrite: true,
        ..SceneOptions::default()
    }
}

/// The JSON chunk of a GLB, parsed.
fn glb_json(bytes: &[u8]) -> Value {
    let glb = tspace::scene::gltf::glb::parse(bytes).expect("a GLB");
    serde_json::from_slice(glb.json).expect("JSON")
}

/// The validator's verdict, ignoring the images the fixtures deliberately lack.
fn assert_valid(name: &str, bytes: &[u8]) -> Option<ValidatorReport> {
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

/// Reads every corner's TANGENT and normal through the `gltf` crate (an independent reader).
fn corner_tangents(bytes: &[u8]) -> Vec<Vec<[f32; 4]>> {
    let gltf = gltf::Gltf::from_slice(bytes).expect("gltf crate reads the output");
    let buffers: Vec<Vec<u8>> = gltf
        .buffers()
        .map(|b| match b.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().expect("BIN chunk"),
            gltf::buffer::Source::Uri(uri) => {
                tspace::scene::uri::decode_data_uri(uri)
                    .expect("data URI")
                    .unwrap()
                    .bytes
            }
        })
        .collect();
    let document = &gltf.document;
    let mut out = Vec::new();
    for mesh in document.meshes() {
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let Some(tangents) = reader.read_tangents() else {
                out.push(Vec::new());
                continue;
            };
            let tangents: Vec<[f32; 4]> = tangents.collect();
            let corners: Vec<[f32; 4]> = match reader.read_indices() {
                Some(indices) => indices.into_u32().map(|i| tangents[i as usize]).collect(),
                None => tangents,
            };
            out.push(corners);
        }
    }
    out
}

#[test]
fn mirrored_uvs_come_back_with_the_authored_signs() {
    let gltf = fixture("NormalTangentMirrorTest/NormalTangentMirrorTest.gltf");
    let bin = fixture("NormalTangentMirrorTest/NormalTangentMirrorTest.bin");
    let mut parts = PartSet::new();
    parts.insert("NormalTangentMirrorTest.bin", &bin).unwrap();
    let original = corner_tangents_of_gltf(&gltf, &bin);

    // Kept by default, and the audit finds them MikkTSpace's.
    let kept = process(&gltf, &parts, &SceneOptions::default()).unwrap();
    let entry = &kept.report.primitives[0];
    assert_eq!(entry.action, "audited");
    let audit = entry.audit.as_ref().unwrap();
    assert_eq!(audit.w_disagreements.count, 0, "{audit:?}");

    let done = process(&gltf, &parts, &overwrite()).unwrap();
    assert_eq!(done.report.primitives[0].action, "overwritten");
    let bytes = done.bytes.unwrap();
    assert_valid("NormalTangentMirrorTest.glb", &bytes);
    let ours = corner_tangents(&bytes);
    assert_eq!(ours[0].len(), original.len());
    let mut flips = 0;
    for (a, b) in ours[0].iter().zip(&original) {
        if a[3] != b[3] {
            flips += 1;
        }
    }
    assert_eq!(
        flips, 0,
        "w differs from the authored tangents at {flips} corners"
    );
}

fn corner_tangents_of_gltf(gltf_bytes: &[u8], bin: &[u8]) -> Vec<[f32; 4]> {
    let document = gltf::Gltf::from_slice(gltf_bytes).unwrap();
    let primitive = document
        .meshes()
        .next()
        .unwrap()
        .primitives()
        .next()
        .unwrap();
    let reader = primitive.reader(|_| Some(bin));
    let tangents: Vec<[f32; 4]> = reader.read_tangents().unwrap().collect();
    reader
        .read_indices()
        .unwrap()
        .into_u32()
        .map(|i| tangents[i as usize])
        .collect()
}

#[test]
fn glb_without_normal_maps_comes_back_byte_for_byte() {
    let input = fixture("Box/Box.glb");
    let done = process(&input, &NoResources, &SceneOptions::default()).unwrap();
    assert_eq!(done.report.primitives[0].action, "skipped");
    assert_eq!(done.report.primitives[0].reason, Some("no_normal_map"));
    assert_eq!(done.bytes.unwrap(), input);
}

#[test]
fn overwritten_fixtures_validate_and_change_only_what_they_must() {
    for (dir, name) in [
        ("Avocado", "Avocado"),
        ("WaterBottle", "WaterBottle"),
        ("Lantern", "Lantern"),
        ("NormalTangentMirrorTest", "NormalTangentMirrorTest"),
    ] {
        let done = run_gltf(dir, name, overwrite());
        let bytes = done.bytes.unwrap();
        assert_valid(&format!("{name}.glb"), &bytes);
        let input: Value = serde_json::from_slice(&fixture(&format!("{dir}/{name}.gltf"))).unwrap();
        let output = glb_json(&bytes);
        structural_diff(&input, &output, name);
        assert!(done.report.summary.generated >= 1, "{name}");
        // The replaced TANGENT accessors are gone, not left behind unreferenced.
        assert!(
            done.report.dropped.accessors >= 1,
            "{name}: {:?}",
            done.report.dropped
        );
    }
}

/// Everything but accessors, bufferViews, buffers and mesh primitives must be equal, and those
/// may only differ in the expected ways.
fn structural_diff(input: &Value, output: &Value, name: &str) {
    let (Value::Object(a), Value::Object(b)) = (input, output) else {
        panic!("{name}: not objects");
    };
    let a_keys: Vec<_> = a.keys().collect();
    let b_keys: Vec<_> = b.keys().collect();
    assert_eq!(
        a_keys, b_keys,
        "{name}: top-level keys or their order changed"
    );
    for (key, value) in a {
        match key.as_str() {
            "accessors" | "bufferViews" | "buffers" | "meshes" => {}
            _ => assert_eq!(Some(value), b.get(key), "{name}: {key} changed"),
        }
    }
    let meshes_in = a["meshes"].as_array().unwrap();
    let meshes_out = b["meshes"].as_array().unwrap();
    assert_eq!(meshes_in.len(), meshes_out.len());
    for (mi, mo) in meshes_in.iter().zip(meshes_out) {
        for (key, value) in mi.as_object().unwrap() {
            if key != "primitives" {
                assert_eq!(
                    Some(value),
                    mo.get(key),
                    "{name}: mesh member {key} changed"
                );
            }
        }
        for (pi, po) in mi["primitives"]
            .as_array()
            .unwrap()
            .iter()
            .zip(mo["primitives"].as_array().unwrap())
        {
            for (key, value) in pi.as_object().unwrap() {
                if key != "attributes" && key != "indices" {
                    assert_eq!(
                        Some(value),
                        po.get(key),
                        "{name}: primitive member {key} changed"
                    );
                }
            }
            let attributes_in: Vec<_> = pi["attributes"].as_object().unwrap().keys().collect();
            let attributes_out: Vec<_> = po["attributes"].as_object().unwrap().keys().collect();
            for k in &attributes_in {
                assert!(attributes_out.contains(k), "{name}: attribute {k} lost");
            }
        }
    }
    // Accessors kept their members (values may be renumbered, not rewritten).
    for accessor in b["accessors"].as_array().unwrap() {
        assert!(accessor.get("componentType").is_some() && accessor.get("count").is_some());
    }
}

#[test]
fn embedded_gltf_output_round_trips_through_an_independent_reader() {
    let done = run_gltf(
        "WaterBottle",
        "WaterBottle",
        SceneOptions {
            format: OutputFormat::GltfEmbedded,
            ..overwrite()
        },
    );
    let bytes = done.bytes.unwrap();
    let tangents = corner_tangents(&bytes);
    assert!(!tangents[0].is_empty());
    for t in &tangents[0] {
        let length = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        assert!((length - 1.0).abs() < 1e-5 && t[3].abs() == 1.0, "{t:?}");
    }
    assert_valid("WaterBottle.gltf", &bytes);
}

#[test]
fn analysis_reports_without_writing() {
    let done = run_gltf(
        "Lantern",
        "Lantern",
        SceneOptions {
            write: false,
            ..SceneOptions::default()
        },
    );
    assert!(done.bytes.is_none());
    assert_eq!(done.report.summary.audited, 3);
    let json = done.report.to_json_pretty();
    let parsed: Value = serde_json::from_str(&json).unwrap();
    assert_eq!(parsed["primitives"][0]["action"], "audited");
    assert!(parsed["primitives"][0]["audit"]["angle_p99_degrees"].is_number());
}

#[test]
fn missing_buffer_and_required_draco_are_named() {
    let gltf = fixture("Avocado/Avocado.gltf");
    let error = process(&gltf, &NoResources, &SceneOptions::default())
        .err()
        .unwrap();
    assert_eq!(error.code, "missing-resource");
    assert!(error.message.contains("Avocado.bin"));

    let draco = br#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],
        "extensionsRequired":["KHR_draco_mesh_compression"],"meshes":[]}"#;
    let error = process(draco, &NoResources, &SceneOptions::default())
        .err()
        .unwrap();
    assert_eq!(error.code, "draco-required");
    assert!(error.message.contains("KHR_draco_mesh_compression"));
}

#[test]
fn quantized_and_sparse_primitives_get_tangents_with_the_axis_method() {
    let quantized = fixture("quantized_triangle/triangle_mesh_quantized.gltf");
    let done = process(
        &quantized,
        &NoResources,
        &SceneOptions {
            all: true,
            method: Method::Axis,
            ..SceneOptions::default()
        },
    )
    .unwrap();
    assert_eq!(
        done.report.primitives[0].action, "generated",
        "{:?}",
        done.report.primitives[0]
    );
    // The `gltf` crate refuses KHR_mesh_quantization, so read the new accessor ourselves.
    let json = glb_json(&done.bytes.unwrap());
    let tangent = json["meshes"][0]["primitives"][0]["attributes"]["TANGENT"]
        .as_u64()
        .unwrap();
    let accessor = &json["accessors"][tangent as usize];
    assert_eq!(
        (accessor["count"].as_u64(), accessor["type"].as_str()),
        (Some(3), Some("VEC4"))
    );

    let gltf = fixture("SimpleSparseAccessor/SimpleSparseAccessor.gltf");
    let bin = fixture("SimpleSparseAccessor/SimpleSparseAccessor.bin");
    let mut parts = PartSet::new();
    parts.insert("SimpleSparseAccessor.bin", &bin).unwrap();
    let skipped = process(
        &gltf,
        &parts,
        &SceneOptions {
            all: true,
            ..SceneOptions::default()
        },
    )
    .unwrap();
    assert_eq!(skipped.report.primitives[0].reason, Some("no_texcoords"));
    let done = process(
        &gltf,
        &parts,
        &SceneOptions {
            all: true,
            method: Method::Axis,
            ..SceneOptions::default()
        },
    )
    .unwrap();
    let bytes = done.bytes.unwrap();
    assert_valid("SimpleSparseAccessor.glb", &bytes);
    // No normals in the input: flat ones were generated, and written.
    let json = glb_json(&bytes);
    assert!(json["meshes"][0]["primitives"][0]["attributes"]["NORMAL"].is_number());
}
