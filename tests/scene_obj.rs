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

/// An OBJ alone (no MTL or textures), processed with `options`.
fn process_obj(obj: &[u8], options: &SceneOptions) -> tspace::scene::Processed {
    process(InputKind::Obj, obj, &PartSet::new(), options).unwrap()
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
            .all(|p| p.reason.is_some_and(|r| r == "no_normal_map")),
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
    let done = process_obj(&obj, &SceneOptions::default());
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
    let done = process_obj(&obj, &SceneOptions::default());
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
        (entry.action.as_str(), entry.reason.map(|r| r.as_str())),
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

/// Each position with the distinct normals written there.
type NormalsAt = Vec<([f32; 3], Vec<[f32; 3]>)>;

/// Per mesh (by name), the distinct normals written at each position, from the output GLB.
fn normals_by_position(bytes: &[u8]) -> std::collections::BTreeMap<String, NormalsAt> {
    let doc = gltf::Gltf::from_slice(bytes).unwrap();
    let json = glb_json(bytes);
    let blob = doc.blob.as_deref();
    let mut out = std::collections::BTreeMap::new();
    for mesh in doc.meshes() {
        let mut at: NormalsAt = Vec::new();
        for p in mesh.primitives() {
            let r = p.reader(|b| (b.index() == 0).then_some(blob).flatten());
            let normals: Vec<[f32; 3]> = r.read_normals().expect("NORMAL").collect();
            for (position, normal) in r.read_positions().unwrap().zip(normals) {
                match at.iter_mut().find(|(p, _)| *p == position) {
                    Some((_, list)) if list.contains(&normal) => {}
                    Some((_, list)) => list.push(normal),
                    None => at.push((position, vec![normal])),
                }
            }
        }
        let name = json["meshes"][mesh.index()]["name"].as_str().unwrap_or("");
        out.insert(name.to_owned(), at);
    }
    out
}

fn with_normals(normals: &str, angle: Option<&str>) -> SceneOptions {
    let mut options = SceneOptions::default();
    options.set("normals", normals).unwrap();
    if let Some(angle) = angle {
        options.set("normals_angle", angle).unwrap();
    }
    options
}

fn written_vertices(bytes: &[u8]) -> u64 {
    let json = glb_json(bytes);
    let accessors = json["accessors"].as_array().unwrap();
    let mut total = 0;
    for mesh in json["meshes"].as_array().unwrap() {
        for p in mesh["primitives"].as_array().unwrap() {
            let position = p["attributes"]["POSITION"].as_u64().unwrap() as usize;
            total += accessors[position]["count"].as_u64().unwrap();
        }
    }
    total
}

/// Keenan Crane's spot (5,856 triangles, UVs, no vn, no `s`) comes out smooth by default, with
/// about one vertex per UV corner instead of three per triangle; `normals=flat` still gives the
/// faceted version. Skips where the shared corpus is absent.
#[test]
fn spot_without_vn_is_smooth_by_default_and_faceted_on_request() {
    let Some(dir) = tspace_testkit::fixtures::corpus_dir() else {
        eprintln!("skipped: no shared corpus");
        return;
    };
    let obj = std::fs::read(dir.join("obj_spot/spot_triangulated.obj")).unwrap();
    let smooth = process_obj(&obj, &SceneOptions::default());
    assert_eq!(
        smooth.report.warnings,
        [
            "normals generated for 5856 triangles without vn: smooth, with edges sharper than 60° \
          kept hard (the OBJ has no smoothing groups); normals=flat for faceted, normals_angle to \
          change the angle"
        ]
    );
    let smooth_bytes = smooth.bytes.unwrap();
    // 3,225 distinct (v, vt) corners; a few more where the UV layout makes MikkTSpace split.
    let vertices = written_vertices(&smooth_bytes);
    assert!((3225..3400).contains(&vertices), "{vertices}");
    assert_valid("spot.glb", &smooth_bytes);

    let flat = process_obj(&obj, &with_normals("flat", None));
    assert!(flat.report.warnings[0].ends_with("flat (faceted), as normals=flat asks"));
    let flat_bytes = flat.bytes.unwrap();
    assert_eq!(written_vertices(&flat_bytes), 17568);
    assert_valid("spot-flat.glb", &flat_bytes);
}

/// `s off` stays faceted, one group is smooth across even right angles, two groups keep a
/// hard edge where they meet; `normals=smooth` ignores the groups and `normals=flat` all.
#[test]
fn smoothing_groups_are_honoured() {
    let obj = fixture("smoothing_groups/smoothing_groups.obj");
    let done = process_obj(&obj, &SceneOptions::default());
    assert_eq!(
        done.report.warnings,
        [
            "normals generated for 40 triangles without vn: smooth within the OBJ's smoothing \
          groups (s), flat where s is off; normals=smooth to smooth by angle instead, \
          normals=flat for faceted"
        ]
    );
    let bytes = done.bytes.unwrap();
    assert_valid("smoothing_groups.glb", &bytes);
    let meshes = normals_by_position(&bytes);
    let counts = |name: &str| -> Vec<usize> { meshes[name].iter().map(|(_, n)| n.len()).collect() };
    // Faceted: each cube corner shows its three faces' normals, each along an axis.
    assert_eq!(counts("flat_cube"), [3; 8]);
    for (_, normals) in &meshes["flat_cube"] {
        assert!(
            normals
                .iter()
                .all(|n| n.iter().filter(|c| c.abs() == 1.0).count() == 1)
        );
    }
    // Smooth: one normal per corner, along the diagonal out of the centre.
    assert_eq!(counts("smooth_cube"), [1; 8]);
    for (p, normals) in &meshes["smooth_cube"] {
        let out = [p[0] - 2.5, p[1] - 0.5, p[2] - 0.5];
        let n = normals[0];
        let cos = (n[0] * out[0] + n[1] * out[1] + n[2] * out[2]) / 0.75f32.sqrt();
        assert!(cos > 0.999, "{p:?}: {n:?}");
    }
    // Two groups: the 4 positions on their two borders have two normals, the 12 others one.
    let mut prism = counts("two_groups");
    prism.sort();
    assert_eq!(prism, [[1; 12].as_slice(), &[2; 4]].concat());

    // normals=smooth with the default 60° crease: the cubes' 90° edges stay hard, the prism's
    // 45° ones are smoothed, borders included.
    let smooth = process_obj(&obj, &with_normals("smooth", None));
    let meshes = normals_by_position(&smooth.bytes.unwrap());
    assert_eq!(
        meshes["smooth_cube"].iter().map(|(_, n)| n.len()).max(),
        Some(3)
    );
    assert!(meshes["two_groups"].iter().all(|(_, n)| n.len() == 1));
    // normals=flat: the prism is faceted too.
    let flat = process_obj(&obj, &with_normals("flat", None));
    let meshes = normals_by_position(&flat.bytes.unwrap());
    assert!(meshes["two_groups"].iter().all(|(_, n)| n.len() == 2));
}

/// Without `s` statements a cube keeps its hard edges at the default 60° crease, and is smooth
/// with a crease above 90°. Corners with vn keep theirs.
#[test]
fn without_smoothing_groups_the_crease_angle_decides() {
    let cube = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n\
                vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 -1\n\
                f 1/1/1 3/2/1 4/3/1 2/4/1\nf 5/1 6/2 8/3 7/4\nf 1/1 2/2 6/3 5/4\n\
                f 3/1 7/2 8/3 4/4\nf 1/1 5/2 7/3 3/4\nf 2/1 4/2 8/3 6/4\n";
    let count = |options: &SceneOptions| {
        let done = process(InputKind::Obj, cube.as_bytes(), &PartSet::new(), options).unwrap();
        let bytes = done.bytes.unwrap();
        assert_valid("cube.glb", &bytes);
        let meshes = normals_by_position(&bytes);
        let mut counts: Vec<usize> = meshes[""].iter().map(|(_, n)| n.len()).collect();
        counts.sort();
        (counts, done.report.warnings)
    };
    let (hard, warnings) = count(&SceneOptions::default());
    assert_eq!(hard, [3; 8]);
    assert!(warnings[0].starts_with("normals generated for 10 triangles without vn: smooth"));
    // Above 90° the five sides without vn are smooth; the bottom keeps its vn: 2 normals at
    // its 4 corners (the vn and the smooth one), 1 at the top 4.
    let (smooth, _) = count(&with_normals("auto", Some("91")));
    assert_eq!(smooth, [1, 1, 1, 1, 2, 2, 2, 2]);
}

/// A README or a CSV sent as a scene (sniffed as text, or named `.obj`) is not "an OBJ without
/// faces": it says it is not a scene, with what its lines begin with. An OBJ without faces still
/// says that.
#[test]
fn text_that_is_not_an_obj_says_so() {
    let readme =
        b"# tspace\n\nAdds tangents to glTF scenes.\n\n## Building\ncargo build --release\n";
    let csv = b"name,triangles,vertices\nspot,5856,3225\n";
    for (text, first) in [
        (&readme[..], "\"Adds\""),
        (&csv[..], "\"name,triangles,vertices\""),
    ] {
        let kind = InputKind::sniff(text).unwrap();
        let error = process(kind, text, &PartSet::new(), &SceneOptions::default())
            .err()
            .unwrap();
        assert_eq!(error.code, "unsupported-media-type");
        let detail = error.to_string();
        assert!(
            detail.contains("not a GLB, glTF or OBJ: nothing in it reads as an OBJ statement"),
            "{detail}"
        );
        assert!(detail.contains(first), "{detail}");
    }
    let error = process(
        InputKind::Obj,
        b"# only points\nv 0 0 0\np 1\n",
        &PartSet::new(),
        &SceneOptions::default(),
    )
    .err()
    .unwrap();
    assert_eq!(error.code, "obj-not-convertible");
    assert!(error.to_string().contains("no faces"), "{error}");
}
