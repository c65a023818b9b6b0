//! OBJ (+ MTL) in, GLB with tangents out, through the one entry point the server and CLI use.

use tspace::scene::SceneOptions;
use tspace::scene::input::{InputKind, process};
use tspace::scene::uri::PartSet;
use tspace_tangent::Method;
#[allow(unused_imports)]
use tspace_testkit::{assert_valid_output, fixture, glb_json};

fn assert_valid(name: &str, bytes: &[u8]) {
    if let Some(report) = assert_valid_output(name, bytes) {
        let warnings = report.warning_codes();
        assert!(warnings.is_empty(), "{name}: warnings {warnings:?}");
    }
}

#[test]
fn an_obj_without_mtl_gets_tangents_everywhere() {
    let obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1 4/4/1\n";
    let kind = InputKind::sniff(obj).unwrap();
    assert_eq!(kind, InputKind::Obj);
    let done = process(kind, obj, &PartSet::new(), &SceneOptions::default()).unwrap();
    assert_eq!(done.report.input_format, "obj");
    assert_eq!(
        done.report.summary.generated, 1,
        "{:?}",
        done.report.primitives
    );
    let bytes = done.bytes.unwrap();
    assert_valid("quad.glb", &bytes);
    let json = glb_json(&bytes);
    let attributes = &json["meshes"][0]["primitives"][0]["attributes"];
    assert!(attributes["TANGENT"].is_number(), "{attributes}");
    // The quad's V runs up in OBJ and down in glTF; either way the tangent follows +u = +x,
    // and w says the bitangent follows +v of the OBJ, i.e. +y.
    let tangent = attributes["TANGENT"].as_u64().unwrap() as usize;
    let view = json["accessors"][tangent]["bufferView"].as_u64().unwrap() as usize;
    let offset = json["bufferViews"][view]["byteOffset"].as_u64().unwrap() as usize;
    let bin = tspace::scene::gltf::glb::parse(&bytes)
        .unwrap()
        .bin
        .unwrap();
    let t: Vec<f32> = bin[offset..offset + 16]
        .chunks(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(t, vec![1.0, 0.0, 0.0, 1.0]);
}

#[test]
fn spider_with_its_mtl_follows_the_materials() {
    let obj = fixture("spider/spider.obj");
    let mtl = fixture("spider/spider.mtl");
    let mut parts = PartSet::new();
    parts.insert("spider.mtl", &mtl).unwrap();
    // Its materials have colour maps but no normal maps: nothing needs tangents...
    let done = process(InputKind::Obj, &obj, &parts, &SceneOptions::default()).unwrap();
    assert_eq!(done.report.summary.generated, 0);
    assert!(
        done.report
            .primitives
            .iter()
            .all(|p| p.reason == Some("no_normal_map")),
        "{:?}",
        done.report.primitives
    );
    assert_valid("spider.glb", &done.bytes.unwrap());
    // ...unless asked.
    let all = SceneOptions {
        all: true,
        ..SceneOptions::default()
    };
    let done = process(InputKind::Obj, &obj, &parts, &all).unwrap();
    assert!(
        done.report.summary.generated >= 4,
        "{:?}",
        done.report.summary
    );
    assert_valid("spider-all.glb", &done.bytes.unwrap());
    // Without the MTL the file still converts, and says what is missing.
    let done = process(
        InputKind::Obj,
        &obj,
        &PartSet::new(),
        &SceneOptions::default(),
    )
    .unwrap();
    assert!(
        done.report
            .warnings
            .iter()
            .any(|w| w.contains("spider.mtl")),
        "{:?}",
        done.report.warnings
    );
}

#[test]
fn ngons_and_negative_indices_come_through() {
    let obj = fixture("negative_indices/negative_indices.obj");
    let done = process(
        InputKind::Obj,
        &obj,
        &PartSet::new(),
        &SceneOptions::default(),
    )
    .unwrap();
    assert_eq!(done.report.summary.generated, 1);
    assert_eq!(done.report.summary.triangles, 12);
    assert_valid("cube.glb", &done.bytes.unwrap());
}

#[test]
fn an_obj_without_uvs_is_converted_with_its_primitives_skipped_unless_axis() {
    let obj = fixture("concave_polygon/concave_polygon.obj");
    let all = SceneOptions {
        all: true,
        ..SceneOptions::default()
    };
    let skipped = process(InputKind::Obj, &obj, &PartSet::new(), &all).unwrap();
    let entry = &skipped.report.primitives[0];
    assert_eq!(
        (entry.action, entry.reason),
        ("skipped", Some("no_texcoords"))
    );
    assert!(skipped.bytes.is_some());
    let axis = SceneOptions {
        method: Method::Axis,
        ..SceneOptions::default()
    };
    let done = process(InputKind::Obj, &obj, &PartSet::new(), &axis).unwrap();
    assert!(done.report.summary.generated >= 1);
    assert_eq!(
        done.report.primitives[0]
            .diagnostics
            .as_ref()
            .unwrap()
            .method,
        "axis"
    );
    assert_valid("concave.glb", &done.bytes.unwrap());
}

#[test]
fn declared_kinds_must_match_the_bytes() {
    let glb = fixture("Box/Box.glb");
    let error = process(
        InputKind::Gltf,
        &glb,
        &PartSet::new(),
        &SceneOptions::default(),
    )
    .err()
    .unwrap();
    assert_eq!(error.code, "malformed-gltf");
    let error = process(
        InputKind::Obj,
        b"v 0 0 0\nf 1 2 3\n",
        &PartSet::new(),
        &SceneOptions::default(),
    )
    .err()
    .unwrap();
    assert_eq!(error.code, "malformed-obj");
}

#[test]
fn on_the_command_line_an_obj_finds_its_mtl_and_textures_beside_it() {
    use tspace::scene::folder::Folder;
    let dir = std::env::temp_dir().join(format!("tspace-obj-folder-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("maps")).unwrap();
    let png = tspace::scene::uri::decode_data_uri(
        "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8BQDwAEhQGAhKmMIQAAAABJRU5ErkJggg==",
    )
    .unwrap()
    .unwrap()
    .bytes;
    std::fs::write(dir.join("maps/bumps.png"), &png).unwrap();
    std::fs::write(
        dir.join("quad.mtl"),
        "newmtl m\nKd 1 1 1\nnorm .\\maps\\bumps.png\n",
    )
    .unwrap();
    let obj = b"mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nusemtl m\nf 1/1/1 2/2/1 3/3/1 4/4/1\n";
    let folder = Folder::new(&dir, 1 << 20);
    let done = process(InputKind::Obj, obj, &folder, &SceneOptions::default()).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(done.report.summary.generated, 1, "{:?}", done.report);
    assert!(
        done.report.warnings.is_empty(),
        "{:?}",
        done.report.warnings
    );
    let bytes = done.bytes.unwrap();
    assert_valid("folder.glb", &bytes);
    let json = glb_json(&bytes);
    assert_eq!(
        json["materials"][0]["normalTexture"]["index"],
        serde_json::json!(0)
    );
    assert_eq!(
        json["images"][0]["mimeType"],
        serde_json::json!("image/png")
    );
}
