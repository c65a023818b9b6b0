//! `KHR_draco_mesh_compression` end to end, on the Draco fixtures made with glTF-Transform
//! (`fixtures/compressed/`, see its README):
//!
//! - the decode oracle: every decoded index and attribute value equals what Google's own
//!   decoder (npm `draco3dgltf`, `tools/draco-reference/decode.mjs`) gives for the same
//!   accessor type; skips with one line where Node.js or the package is missing;
//! - the round trip: processed with `overwrite` + `all`, every output is validator-clean, holds
//!   no Draco, and its tangents agree corner by corner with bevy_mikktspace run on its geometry.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use tspace::scene::SceneOptions;
use tspace::scene::gltf::accessor::ComponentType;
use tspace::scene::gltf::draco::{self, DracoLimits};
use tspace::scene::gltf::load::{self, LoadLimits, NoResources};
use tspace::scene::gltf::process;
use tspace::scene::report::MeshCompression;
use tspace_testkit::fixtures::{assert_valid_output, glb_json, workspace_root};
use tspace_testkit::meshes::load_gltf;
use tspace_testkit::{angle_degrees, reference_is_valid, reference_tangents};

/// Every fixture whose document carries the extension.
fn draco_fixtures() -> Vec<PathBuf> {
    let dir = workspace_root().join("fixtures/compressed");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "glb"))
        .filter(|p| {
            let json = glb_json(&std::fs::read(p).unwrap());
            json["extensionsUsed"]
                .as_array()
                .is_some_and(|u| u.iter().any(|e| e == draco::EXTENSION))
        })
        .collect();
    files.sort();
    assert!(
        files.len() >= 8,
        "expected the Draco fixtures in {}",
        dir.display()
    );
    files
}

fn name(path: &Path) -> String {
    path.file_name().unwrap().to_string_lossy().into_owned()
}

const LIMITS: DracoLimits = DracoLimits {
    max_vertices: 1 << 24,
    max_triangles: 1 << 24,
    max_bytes: 1 << 30,
};

/// Google's decoder on `path`, or `None` (after saying why) where it cannot run.
fn reference_decode(path: &Path) -> Option<Value> {
    let root = workspace_root();
    let install = Command::new("bash")
        .arg(root.join("scripts/install-draco-reference"))
        .output();
    let script = root.join("tools/draco-reference/decode.mjs");
    let installed = root.join("tools/draco-reference/node_modules/draco3dgltf");
    if !installed.is_dir() {
        eprintln!(
            "draco oracle: skipped, the reference decoder is not installed ({:?})",
            install.map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
        );
        return None;
    }
    let output = match Command::new("node").arg(&script).arg(path).output() {
        Ok(o) if o.status.success() => o,
        Ok(o) => panic!(
            "{}: decode.mjs failed: {}",
            path.display(),
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => {
            eprintln!("draco oracle: skipped, node cannot run ({e})");
            return None;
        }
    };
    Some(serde_json::from_slice(&output.stdout).expect("decode.mjs prints JSON"))
}

/// The values of tightly packed `bytes` of `component_type`, as f64.
fn values(bytes: &[u8], component_type: ComponentType) -> Vec<f64> {
    bytes
        .chunks_exact(component_type.size())
        .map(|b| match component_type {
            ComponentType::I8 => f64::from(b[0] as i8),
            ComponentType::U8 => f64::from(b[0]),
            ComponentType::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            ComponentType::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            ComponentType::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            ComponentType::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        })
        .collect()
}

#[test]
fn decoded_values_equal_the_reference_decoders() {
    let mut compared = 0usize;
    for path in draco_fixtures() {
        let Some(reference) = reference_decode(&path) else {
            return;
        };
        let bytes = std::fs::read(&path).unwrap();
        let limits = LoadLimits {
            max_buffer_bytes: 1 << 30,
        };
        let loaded = load::load(&bytes, &NoResources, &limits).unwrap();
        let root = loaded.doc.root();
        let buffers = loaded.buffer_slices();
        let json = glb_json(&bytes);
        for primitive in reference["primitives"].as_array().unwrap() {
            let (m, p) = (
                primitive["mesh"].as_u64().unwrap() as usize,
                primitive["primitive"].as_u64().unwrap() as usize,
            );
            let at = format!("{} meshes[{m}].primitives[{p}]", name(&path));
            assert!(primitive["error"].is_null(), "{at}: {}", primitive["error"]);
            let node = root.get("meshes").unwrap().index(m).unwrap();
            let node = node.get("primitives").unwrap().index(p).unwrap();
            let ours = draco::decode_primitive(root, node, &at, &buffers, &LIMITS)
                .unwrap_or_else(|e| panic!("{at}: {e}"));
            let mut expected: Vec<(u64, &Value)> = primitive["attributes"]
                .as_object()
                .unwrap()
                .values()
                .map(|a| (a["accessor"].as_u64().unwrap(), &a["values"]))
                .collect();
            if primitive["indices"].is_object() {
                let indices = &primitive["indices"];
                expected.push((indices["accessor"].as_u64().unwrap(), &indices["values"]));
            }
            assert_eq!(ours.len(), expected.len(), "{at}: decoded accessors");
            for (accessor, want) in expected {
                let (_, decoded) = ours
                    .iter()
                    .find(|(a, _)| *a as u64 == accessor)
                    .unwrap_or_else(|| panic!("{at}: accessors[{accessor}] not decoded"));
                let code = json["accessors"][accessor as usize]["componentType"]
                    .as_u64()
                    .unwrap();
                let got = values(&decoded.bytes, ComponentType::from_code(code).unwrap());
                // serde_json's default parser may be one f64 ulp off; the f32 is exact.
                let want: Vec<f64> = want
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| f64::from(v.as_f64().unwrap() as f32))
                    .collect();
                // Bit for bit: decode.mjs spells a negative zero -0.0, so it reads back as one.
                assert_eq!(got.len(), want.len(), "{at}: accessors[{accessor}] length");
                let differing: Vec<(usize, f64, f64)> = (got.iter().zip(&want).enumerate())
                    .filter(|(_, (a, b))| a.to_bits() != b.to_bits())
                    .map(|(i, (a, b))| (i, *a, *b))
                    .collect();
                assert!(
                    differing.is_empty(),
                    "{at}: accessors[{accessor}]: {} values differ (index, ours, reference): {:?}",
                    differing.len(),
                    &differing[..differing.len().min(5)]
                );
                compared += got.len();
            }
        }
    }
    eprintln!("draco oracle: {compared} values equal Google's decoder's");
}

fn overwrite_all() -> SceneOptions {
    SceneOptions {
        overwrite: true,
        all: true,
        ..SceneOptions::default()
    }
}

#[test]
fn draco_fixtures_round_trip_with_reference_tangents() {
    for path in draco_fixtures() {
        let file = name(&path);
        let input = std::fs::read(&path).unwrap();
        let processed = process(&input, &NoResources, &overwrite_all())
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        let summary = &processed.report.summary;
        if summary.generated == 0 {
            // Box has no texture coordinates, so MikkTSpace has nothing to work with.
            let reasons: Vec<_> = processed
                .report
                .primitives
                .iter()
                .map(|p| p.reason.map(|r| r.as_str()))
                .collect();
            assert!(
                reasons.iter().all(|r| *r == Some("no_texcoords")),
                "{file}: nothing generated ({reasons:?})"
            );
            continue;
        }
        // The report says what happened to the sizes, and why.
        assert!(summary.mesh_bytes_out.unwrap() > 0 && summary.mesh_bytes_in > 0);
        for p in processed
            .report
            .primitives
            .iter()
            .filter(|p| p.action != "skipped")
        {
            let storage = p.storage.as_ref().unwrap();
            assert_eq!(storage.compression_in, MeshCompression::Draco, "{file}");
            assert_eq!(
                storage.compression_out,
                Some(MeshCompression::None),
                "{file}"
            );
            assert!(storage.why.unwrap().as_str().contains("Draco"), "{file}");
            assert!(storage.bytes_out.unwrap() > 0, "{file}");
        }
        let bytes = processed.bytes.unwrap();
        assert_valid_output(&file, &bytes);
        let json = glb_json(&bytes);
        for list in ["extensionsUsed", "extensionsRequired"] {
            let names = json[list].as_array().cloned().unwrap_or_default();
            assert!(
                !names.iter().any(|e| e == draco::EXTENSION),
                "{file}: {list} still names Draco"
            );
        }
        let out = std::env::temp_dir().join(format!("tspace-draco-{}-{file}", std::process::id()));
        std::fs::write(&out, &bytes).unwrap();
        let primitives = load_gltf(&out).unwrap_or_else(|e| panic!("{file}: {e}"));
        std::fs::remove_file(&out).ok();
        let mut corners = 0;
        for p in primitives {
            let (Some(normals), Some(uvs), Some(tangents)) = (&p.normals, &p.uvs, &p.tangents)
            else {
                continue;
            };
            let reference = reference_tangents(&p.positions, normals, uvs, &p.indices);
            for (corner, r) in reference.iter().enumerate() {
                let vertex = p.indices[corner] as usize;
                let ours = tangents[vertex];
                if !reference_is_valid(*r, normals[vertex]) {
                    continue;
                }
                let r = r.unwrap();
                // glTF's UV origin is the top left: tspace negates the reference's w.
                assert_eq!(ours[3], -r[3], "{}: corner {corner} handedness", p.name);
                let angle = angle_degrees([r[0], r[1], r[2]], [ours[0], ours[1], ours[2]]);
                assert!(angle <= 0.01, "{}: corner {corner} is {angle}° off", p.name);
                corners += 1;
            }
        }
        assert!(corners > 0, "{file}: no corner compared");
    }
}

#[test]
fn a_primitive_left_alone_keeps_its_draco_stream() {
    // Without `all`, primitives without a normal map are skipped: the file comes back as it was.
    let path = workspace_root().join("fixtures/compressed/Box_draco_edgebreaker.glb");
    let input = std::fs::read(&path).unwrap();
    let processed = process(&input, &NoResources, &SceneOptions::default()).unwrap();
    assert_eq!(processed.report.summary.generated, 0);
    assert_eq!(processed.bytes.unwrap(), input);
}

#[test]
fn a_stream_over_the_requests_limits_is_refused_before_it_is_decoded() {
    // The box has no UVs, so the axis method; 24 points against a limit of 10.
    for file in ["Box_draco_sequential.glb", "Box_draco_edgebreaker.glb"] {
        let input = std::fs::read(workspace_root().join("fixtures/compressed").join(file)).unwrap();
        let options = SceneOptions {
            all: true,
            method: tspace_tangent::Method::Axis,
            limits: tspace::scene::SceneLimits {
                max_vertices: 10,
                ..tspace::scene::SceneLimits::default()
            },
            ..SceneOptions::default()
        };
        let error = process(&input, &NoResources, &options).err().unwrap();
        assert_eq!(error.code, "draco-too-large", "{error}");
        assert!(error.message.contains("meshes[0].primitives[0]"), "{error}");
    }
}

#[test]
fn a_changed_primitive_leaves_draco_and_its_neighbour_keeps_its_stream() {
    // MorphPrimitivesTest: two Draco primitives with a morph target each. Give the first a normal
    // map: it gets tangents (and deltas) and is written out of Draco; the second is left alone
    // and keeps its stream byte for byte, so the file still requires the extension.
    let input =
        std::fs::read(workspace_root().join("fixtures/compressed/MorphPrimitivesTest_draco.glb"))
            .unwrap();
    let parsed = tspace::scene::gltf::glb::parse(&input).unwrap();
    let mut doc: Value = serde_json::from_slice(parsed.json).unwrap();
    doc["materials"][0]["normalTexture"] = serde_json::json!({"index": 0});
    doc["textures"] = serde_json::json!([{"source": 0}]);
    doc["images"] = serde_json::json!([{"uri": "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8BQDwAEhQGAhKmMIQAAAABJRU5ErkJggg=="}]);
    let edited =
        tspace::scene::gltf::glb::write(&serde_json::to_vec(&doc).unwrap(), parsed.bin, &[])
            .unwrap();
    let stream = |json: &Value, bin: &[u8], primitive: usize| -> Vec<u8> {
        let ext = &json["meshes"][0]["primitives"][primitive]["extensions"][draco::EXTENSION];
        let view = &json["bufferViews"][ext["bufferView"].as_u64().unwrap() as usize];
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        bin[start..start + view["byteLength"].as_u64().unwrap() as usize].to_vec()
    };
    let kept = stream(&doc, parsed.bin.unwrap(), 1);

    let processed = process(&edited, &NoResources, &SceneOptions::default()).unwrap();
    let actions: Vec<_> = processed
        .report
        .primitives
        .iter()
        .map(|p| p.action)
        .collect();
    assert_eq!(actions, ["generated", "skipped"]);
    let storage: Vec<_> = processed
        .report
        .primitives
        .iter()
        .map(|p| p.storage.as_ref().unwrap().compression_out.unwrap())
        .collect();
    assert_eq!(storage, [MeshCompression::None, MeshCompression::Draco]);
    let bytes = processed.bytes.unwrap();
    assert_valid_output("MorphPrimitivesTest_draco mixed", &bytes);
    let out = tspace::scene::gltf::glb::parse(&bytes).unwrap();
    let json: Value = serde_json::from_slice(out.json).unwrap();
    assert!(
        json["extensionsRequired"]
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e == draco::EXTENSION)
    );
    let first = &json["meshes"][0]["primitives"][0];
    assert!(first["extensions"].get(draco::EXTENSION).is_none());
    assert!(first["attributes"]["TANGENT"].is_u64());
    assert!(first["targets"][0]["TANGENT"].is_u64());
    assert_eq!(stream(&json, out.bin.unwrap(), 1), kept);
}
