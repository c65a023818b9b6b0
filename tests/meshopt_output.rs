//! `compress=auto|none|meshopt`: EXT_meshopt_compression output. gltfpack's `-cc` fixture comes
//! back compressed (auto), validator-clean, decoding through tspace's own loader to tangents
//! within 1° of the reference and at most 1.25 times its mesh bytes; `none` writes no meshopt;
//! `meshopt` on an uncompressed fixture decodes to the accessor values `none` writes. The last
//! test checks the output with meshoptimizer's own decoder (the one three.js uses) and
//! glTF-Transform's `copy`, and skips with one line when node or those packages are missing.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use tspace::scene::gltf::load::{self, LoadLimits, NoResources};
use tspace::scene::gltf::process;
use tspace::scene::options::Compression;
use tspace::scene::report::TangentComponent;
use tspace::scene::{Processed, SceneOptions};
use tspace_testkit::fixtures::{assert_valid_output, glb_json, workspace_root};
use tspace_testkit::written::{read_primitives, worst_angle_to_reference};

const CC: &str = "WaterBottle_gltfpack_cc.glb";
const QUANTIZED: &str = "WaterBottle_gltfpack_quantized.glb";
const MESHOPT_EXT: &str = "EXT_meshopt_compression";

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(workspace_root().join("fixtures/compressed").join(name)).unwrap()
}

fn run(name: &str, compress: Compression) -> Processed {
    let options = SceneOptions {
        overwrite: true,
        all: true,
        compress,
        ..SceneOptions::default()
    };
    process(&fixture(name), &NoResources, &options).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The bytes a mesh's views take in the file (a meshopt view at its compressed length), as
/// scripts/make-helmet-variants and scripts/mesh-bytes count them.
fn mesh_bytes(json: &Value) -> u64 {
    let views = json["bufferViews"].as_array().unwrap();
    let mut used = std::collections::BTreeSet::new();
    for mesh in json["meshes"].as_array().unwrap() {
        for p in mesh["primitives"].as_array().unwrap() {
            let mut accessors: Vec<&Value> =
                p["attributes"].as_object().unwrap().values().collect();
            accessors.extend(p.get("indices"));
            for t in p
                .get("targets")
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
            {
                accessors.extend(t.as_object().unwrap().values());
            }
            for a in accessors {
                let a = &json["accessors"][a.as_u64().unwrap() as usize];
                if let Some(v) = a["bufferView"].as_u64() {
                    used.insert(v as usize);
                }
            }
        }
    }
    used.iter()
        .map(|&v| {
            let view = &views[v];
            view["extensions"][MESHOPT_EXT]["byteLength"]
                .as_u64()
                .or(view["byteLength"].as_u64())
                .unwrap()
        })
        .sum()
}

/// Every view that a mesh accessor reads.
fn mesh_views(json: &Value) -> Vec<&Value> {
    let views = json["bufferViews"].as_array().unwrap();
    let mut out = Vec::new();
    for mesh in json["meshes"].as_array().unwrap() {
        for p in mesh["primitives"].as_array().unwrap() {
            let mut accessors: Vec<&Value> =
                p["attributes"].as_object().unwrap().values().collect();
            accessors.extend(p.get("indices"));
            for a in accessors {
                let a = &json["accessors"][a.as_u64().unwrap() as usize];
                out.push(&views[a["bufferView"].as_u64().unwrap() as usize]);
            }
        }
    }
    out
}

/// The same triangles in the same order, each with its winding (meshoptimizer's triangle codec
/// may start a triangle at another corner).
fn same_triangles(a: &[u32], b: &[u32]) -> bool {
    a.len() == b.len()
        && a.chunks(3)
            .zip(b.chunks(3))
            .all(|(x, y)| (0..3).any(|r| (0..3).all(|k| x[k] == y[(k + r) % 3])))
}

/// Two outputs decode to the same primitives: every attribute's elements byte for byte (but
/// those named in `except`), the same triangles.
fn assert_same_values(what: &str, a: &[u8], b: &[u8], except: &[&str]) {
    let (a, b) = (read_primitives(a), read_primitives(b));
    assert_eq!(a.len(), b.len(), "{what}");
    for (pa, pb) in a.iter().zip(&b) {
        let mut names_a: Vec<_> = pa.attributes.iter().map(|(k, _)| k).collect();
        let mut names_b: Vec<_> = pb.attributes.iter().map(|(k, _)| k).collect();
        names_a.sort();
        names_b.sort();
        assert_eq!(names_a, names_b, "{what}");
        for (name, values) in &pa.attributes {
            if except.contains(&name.as_str()) {
                continue;
            }
            let other = &pb.attributes.iter().find(|(k, _)| k == name).unwrap().1;
            assert!(values == other, "{what}: {name} differs");
        }
        assert!(same_triangles(&pa.indices, &pb.indices), "{what}: indices");
    }
}

#[test]
fn gltfpack_cc_comes_back_compressed_exact_and_compact() {
    let input = fixture(CC);
    let processed = run(CC, Compression::Auto);
    let report = &processed.report;
    assert_eq!(
        report.dropped.kept_because, None,
        "orphans dropped in a meshopt file"
    );
    assert!(report.dropped.accessors > 0 && report.dropped.buffer_views > 0);
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.starts_with("EXT_meshopt_compression: ")),
        "{:?}",
        report.warnings
    );
    let bytes = processed.bytes.unwrap();
    assert_valid_output(CC, &bytes);
    let json = glb_json(&bytes);
    for list in ["extensionsUsed", "extensionsRequired"] {
        assert!(
            json[list]
                .as_array()
                .unwrap()
                .contains(&Value::from(MESHOPT_EXT)),
            "{list}"
        );
    }
    for view in mesh_views(&json) {
        assert!(view["extensions"][MESHOPT_EXT].is_object(), "{view}");
        assert_eq!(view["buffer"], 1, "{view}");
    }
    let fallback = &json["buffers"][1];
    assert_eq!(fallback["extensions"][MESHOPT_EXT]["fallback"], true);
    assert!(fallback.get("uri").is_none());
    assert_eq!(json["buffers"].as_array().unwrap().len(), 2);

    let (before, after) = (mesh_bytes(&glb_json(&input)), mesh_bytes(&json));
    eprintln!("{CC}: mesh bytes {before} in, {after} out");
    assert!(
        after as f64 <= 1.25 * before as f64,
        "{after} > 1.25 x {before}"
    );

    for p in read_primitives(&bytes) {
        let worst = worst_angle_to_reference(&p);
        assert!(worst <= 1.0, "{CC}: {worst}°");
    }
    // The NORMAL views are OCTAHEDRAL-filtered, so the new TANGENT takes that representation
    // and filter too (within 0.75° of the float tangent, the grid's bound); the rest is the same
    // values compressed or not.
    let tangent = report.primitives[0].tangent.unwrap();
    assert_eq!(tangent.component_type, TangentComponent::Byte);
    assert!(tangent.max_quantization_degrees.unwrap() <= 0.75);
    let tangent_view = {
        let accessor = json["meshes"][0]["primitives"][0]["attributes"]["TANGENT"]
            .as_u64()
            .unwrap() as usize;
        json["accessors"][accessor]["bufferView"].as_u64().unwrap() as usize
    };
    assert_eq!(
        json["bufferViews"][tangent_view]["extensions"][MESHOPT_EXT]["filter"],
        "OCTAHEDRAL"
    );
    let plain = run(CC, Compression::None).bytes.unwrap();
    assert_same_values("auto vs none", &bytes, &plain, &["TANGENT"]);
}

#[test]
fn none_writes_no_meshopt() {
    let processed = run(CC, Compression::None);
    let bytes = processed.bytes.unwrap();
    assert_valid_output(CC, &bytes);
    let json = glb_json(&bytes);
    let text = serde_json::to_string(&json).unwrap();
    assert!(!text.contains("meshopt"), "{text}");
    assert_eq!(json["buffers"].as_array().unwrap().len(), 1);
    assert!(
        processed
            .report
            .warnings
            .iter()
            .all(|w| !w.contains("EXT_meshopt_compression")),
        "{:?}",
        processed.report.warnings
    );
    for p in read_primitives(&bytes) {
        assert!(worst_angle_to_reference(&p) <= 1.0);
    }
}

#[test]
fn meshopt_on_an_uncompressed_file_decodes_to_what_none_writes() {
    let input = fixture(QUANTIZED);
    assert!(!String::from_utf8_lossy(&input).contains("meshopt"));
    let compressed = run(QUANTIZED, Compression::Meshopt).bytes.unwrap();
    let plain = run(QUANTIZED, Compression::None).bytes.unwrap();
    // `none` on an uncompressed input is the input's own layout, as `auto` is.
    assert_eq!(plain, run(QUANTIZED, Compression::Auto).bytes.unwrap());
    assert_valid_output(QUANTIZED, &compressed);
    let json = glb_json(&compressed);
    assert!(
        json["extensionsRequired"]
            .as_array()
            .unwrap()
            .contains(&Value::from(MESHOPT_EXT))
    );
    for view in mesh_views(&json) {
        assert!(view["extensions"][MESHOPT_EXT].is_object(), "{view}");
    }
    eprintln!(
        "{QUANTIZED}: mesh bytes {} with none, {} with meshopt",
        mesh_bytes(&glb_json(&plain)),
        mesh_bytes(&json)
    );
    assert!(mesh_bytes(&json) < mesh_bytes(&glb_json(&plain)));
    assert_same_values("meshopt vs none", &compressed, &plain, &[]);
}

/// A GLB without images, textures, samplers and texture references (its BIN chunk as it was).
fn without_images(bytes: &[u8]) -> Vec<u8> {
    let mut json = glb_json(bytes);
    let doc = json.as_object_mut().unwrap();
    for key in ["images", "textures", "samplers"] {
        doc.remove(key);
    }
    for material in doc
        .get_mut("materials")
        .and_then(Value::as_array_mut)
        .into_iter()
        .flatten()
    {
        let m = material.as_object_mut().unwrap();
        m.retain(|k, _| !k.ends_with("Texture"));
        if let Some(pbr) = m
            .get_mut("pbrMetallicRoughness")
            .and_then(Value::as_object_mut)
        {
            pbr.retain(|k, _| !k.ends_with("Texture"));
        }
    }
    for list in ["extensionsUsed", "extensionsRequired"] {
        if let Some(names) = doc.get_mut(list).and_then(Value::as_array_mut) {
            names.retain(|n| n != "KHR_texture_transform");
        }
    }
    let bin = tspace::scene::gltf::glb::parse(bytes).unwrap().bin.unwrap();
    tspace::scene::gltf::glb::write(&serde_json::to_vec(&json).unwrap(), Some(bin), &[]).unwrap()
}

/// Runs `node` with `args`; `None` after one skip line when node is missing.
fn node_json(what: &str, args: &[&Path]) -> Option<Value> {
    let output = Command::new("node").args(args).output();
    match output {
        Ok(o) if o.status.success() => Some(serde_json::from_slice(&o.stdout).unwrap()),
        Ok(o) => panic!(
            "{what}: node failed: {}",
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => {
            eprintln!("{what}: node not found ({e}); skipping");
            None
        }
    }
}

/// meshoptimizer's decoder installed in tools/meshopt-decoder, or `None` after one skip line.
fn meshopt_decoder() -> Option<PathBuf> {
    let root = workspace_root();
    let install = Command::new("bash")
        .arg(root.join("scripts/install-meshopt-decoder"))
        .output();
    let dir = root.join("tools/meshopt-decoder");
    let installed = dir
        .join("node_modules/meshoptimizer/package.json")
        .is_file();
    if install.is_err() || !installed || Command::new("node").arg("--version").output().is_err() {
        eprintln!("meshopt-decoder: node or the meshoptimizer package is missing; skipping");
        return None;
    }
    Some(dir.join("decode.mjs"))
}

#[test]
fn three_js_decoder_and_gltf_transform_read_the_output() {
    let Some(decoder) = meshopt_decoder() else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("tspace-meshopt-output-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, compress) in [(CC, Compression::Auto), (QUANTIZED, Compression::Meshopt)] {
        let bytes = run(name, compress).bytes.unwrap();
        let path = dir.join(name);
        std::fs::write(&path, &bytes).unwrap();
        // The views, decoded by meshoptimizer's WASM decoder and by tspace's loader.
        let decoded = node_json("meshopt-decoder", &[&decoder, &path]).unwrap();
        eprintln!("{name}: decoded by {}", decoded["decoder"]);
        let json = glb_json(&bytes);
        let loaded = load::load(
            &bytes,
            &NoResources,
            &LoadLimits {
                max_buffer_bytes: 1 << 30,
            },
        )
        .unwrap();
        let views = decoded["views"].as_object().unwrap();
        assert!(!views.is_empty());
        for (v, data) in views {
            let view = &json["bufferViews"][v.parse::<usize>().unwrap()];
            let (b, at, len) = (
                view["buffer"].as_u64().unwrap() as usize,
                view["byteOffset"].as_u64().unwrap_or(0) as usize,
                view["byteLength"].as_u64().unwrap() as usize,
            );
            let ours = &loaded.buffers[b].bytes[at..at + len];
            let theirs =
                tspace::scene::uri::decode_base64(data.as_str().unwrap().as_bytes()).unwrap();
            assert!(
                ours == &theirs[..],
                "{name}: bufferViews[{v}] decodes differently"
            );
        }
        // glTF-Transform reads it (decoding every view) and writes it again.
        let cli = workspace_root().join("tools/peers/node_modules/.bin/gltf-transform");
        if !cli.is_file() {
            eprintln!(
                "gltf-transform: tools/peers is not installed (npm ci --prefix tools/peers); skipping"
            );
            continue;
        }
        // The fixtures ship without their images, which gltf-transform refuses to miss.
        let bare = dir.join(format!("bare-{name}"));
        std::fs::write(&bare, without_images(&bytes)).unwrap();
        let copy = dir.join(format!("copy-{name}"));
        let status = Command::new(&cli)
            .arg("copy")
            .arg(&bare)
            .arg(&copy)
            .output()
            .unwrap();
        assert!(
            status.status.success(),
            "{name}: gltf-transform copy: {}",
            String::from_utf8_lossy(&status.stderr)
        );
        assert_same_values(
            &format!("{name} through gltf-transform copy"),
            &bytes,
            &std::fs::read(&copy).unwrap(),
            &[],
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// gltfpack's `-cc` DamagedHelmet (not committed: `scripts/make-helmet-variants DIR`, then
/// `TSPACE_HELMET_CC=DIR/helmet_cc.glb`): compressed, validator-clean, tangents within 1° after
/// decoding, decoded alike by meshoptimizer's decoder; prints its mesh bytes in and out.
#[test]
fn helmet_cc_when_given() {
    let Some(path) = std::env::var_os("TSPACE_HELMET_CC") else {
        eprintln!("TSPACE_HELMET_CC is not set; skipping the helmet");
        return;
    };
    let input = std::fs::read(&path).unwrap();
    let options = SceneOptions::default();
    let processed = process(&input, &NoResources, &options).unwrap();
    let bytes = processed.bytes.unwrap();
    assert_valid_output("helmet_cc", &bytes);
    let (before, after) = (mesh_bytes(&glb_json(&input)), mesh_bytes(&glb_json(&bytes)));
    eprintln!(
        "helmet_cc: mesh bytes {before} in, {after} out ({:.3}x); file {} -> {}",
        after as f64 / before as f64,
        input.len(),
        bytes.len()
    );
    for view in mesh_views(&glb_json(&bytes)) {
        assert!(view["extensions"][MESHOPT_EXT].is_object(), "{view}");
    }
    for p in read_primitives(&bytes) {
        let worst = worst_angle_to_reference(&p);
        eprintln!("helmet_cc: worst angle to the reference {worst:.3}°");
        assert!(worst <= 1.0);
    }
    if let Some(decoder) = meshopt_decoder() {
        let out = std::env::temp_dir().join(format!("tspace-helmet-{}.glb", std::process::id()));
        std::fs::write(&out, &bytes).unwrap();
        let decoded = node_json("meshopt-decoder", &[&decoder, &out]).unwrap();
        let loaded = load::load(
            &bytes,
            &NoResources,
            &LoadLimits {
                max_buffer_bytes: 1 << 30,
            },
        )
        .unwrap();
        let json = glb_json(&bytes);
        for (v, data) in decoded["views"].as_object().unwrap() {
            let view = &json["bufferViews"][v.parse::<usize>().unwrap()];
            let at = view["byteOffset"].as_u64().unwrap_or(0) as usize;
            let len = view["byteLength"].as_u64().unwrap() as usize;
            let theirs =
                tspace::scene::uri::decode_base64(data.as_str().unwrap().as_bytes()).unwrap();
            assert!(
                loaded.buffers[1].bytes[at..at + len] == theirs[..],
                "view {v}"
            );
        }
        let _ = std::fs::remove_file(&out);
    }
}

#[test]
fn compression_applies_to_a_scene_that_needs_no_tangents() {
    // Box needs no tangents (no UVs), so with the default options the GLB comes back byte for
    // byte; asking for meshopt still compresses it, and none still decompresses the meshopt box.
    let box_glb = std::fs::read(workspace_root().join("fixtures/Box/Box.glb")).unwrap();
    let options = |compress| SceneOptions {
        compress,
        ..SceneOptions::default()
    };
    let same = process(&box_glb, &NoResources, &options(Compression::Auto)).unwrap();
    assert_eq!(same.bytes.unwrap(), box_glb);
    let compressed = process(&box_glb, &NoResources, &options(Compression::Meshopt)).unwrap();
    let bytes = compressed.bytes.unwrap();
    assert_valid_output("Box meshopt", &bytes);
    let json = glb_json(&bytes);
    assert!(
        mesh_views(&json)
            .iter()
            .all(|view| view["extensions"][MESHOPT_EXT].is_object())
    );
    let meshopt_box = fixture("Box_gltf_transform_meshopt.glb");
    let plain = process(&meshopt_box, &NoResources, &options(Compression::None)).unwrap();
    let bytes = plain.bytes.unwrap();
    assert_valid_output("Box_gltf_transform_meshopt none", &bytes);
    assert!(!String::from_utf8_lossy(&bytes).contains(MESHOPT_EXT));
}
