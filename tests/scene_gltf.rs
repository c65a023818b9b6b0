//! The glTF scene layer end to end: fixtures in, GLB or `.gltf` out, checked with an independent
//! reader (the `gltf` crate), the Khronos glTF-Validator where it is installed, and a structural
//! diff of the JSON against the input.

use serde_json::Value;
use tspace::scene::gltf::load::NoResources;
use tspace::scene::gltf::process;
use tspace::scene::uri::PartSet;
use tspace::scene::{OutputFormat, Processed, SceneOptions};
use tspace_tangent::Method;
#[allow(unused_imports)]
use tspace_testkit::{assert_valid_output as assert_valid, fixture, glb_json};

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
    assert!(
        done.report.primitives[0]
            .reason
            .is_some_and(|r| r == "no_normal_map")
    );
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

/// Analysing a scene warns of the images processing it would: each one not supplied, by code.
#[test]
fn analysis_warns_of_the_images_processing_would() {
    let missing = |write| {
        let done = run_gltf(
            "Avocado",
            "Avocado",
            SceneOptions {
                write,
                ..SceneOptions::default()
            },
        );
        let images: Vec<_> = done
            .report
            .findings
            .iter()
            .filter(|f| f.code == "image_not_supplied")
            .map(|f| f.message.split(',').next().unwrap_or("").to_owned())
            .collect();
        (images, done.report.summary.findings)
    };
    let (analysed, analysed_counts) = missing(false);
    let (processed, processed_counts) = missing(true);
    assert_eq!(analysed.len(), 3, "{analysed:?}");
    assert_eq!(analysed, processed);
    assert_eq!(analysed_counts, processed_counts);
}

/// The report holds indices in 32 bits, but a material index is reported as the file spells it,
/// even one no material array could reach.
#[test]
fn a_dangling_material_index_is_reported_as_written() {
    let mut gltf: Value =
        serde_json::from_slice(&fixture("BoxTextured_embedded/BoxTextured.gltf")).unwrap();
    gltf["meshes"][0]["primitives"][0]["material"] = serde_json::json!(99_999_999_999u64);
    let bytes = serde_json::to_vec(&gltf).unwrap();
    let done = process(&bytes, &NoResources, &SceneOptions::default()).unwrap();
    let entry = &done.report.primitives[0];
    assert_eq!(entry.material, Some(99_999_999_999));
    assert_eq!(entry.action, "skipped");
    let json: Value = serde_json::from_str(&done.report.to_json_pretty()).unwrap();
    assert_eq!(json["primitives"][0]["material"], 99_999_999_999u64);
}

#[test]
fn a_missing_buffer_is_named() {
    let gltf = fixture("Avocado/Avocado.gltf");
    let error = process(&gltf, &NoResources, &SceneOptions::default())
        .err()
        .unwrap();
    assert_eq!(error.code, "missing-resource");
    assert!(error.message.contains("Avocado.bin"));
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
    assert!(
        skipped.report.primitives[0]
            .reason
            .is_some_and(|r| r == "no_texcoords")
    );
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

// ---- Synthetic scenes: one property each ----

use serde_json::json;
use tspace_testkit::glb_builder::{Builder, normal_mapped, texture_stub};

/// A unit quad in the z = 0 plane, two triangles sharing the 0–2 diagonal.
const QUAD_POSITIONS: [f32; 12] = [0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.];
const QUAD_NORMALS: [f32; 12] = [0., 0., 1., 0., 0., 1., 0., 0., 1., 0., 0., 1.];
/// Texture coordinates that mirror the second triangle, so vertices 0 and 2 must split.
const MIRRORED_UVS: [f32; 8] = [0., 0., 1., 0., 1., 1., 2., 0.];

fn process_glb(bytes: &[u8], options: SceneOptions) -> Processed {
    process(bytes, &NoResources, &options).unwrap_or_else(|e| panic!("{e}"))
}

/// The values of accessor `index` of a GLB, read by the `gltf` crate.
fn read_accessor_f32(bytes: &[u8], index: usize) -> Vec<f32> {
    let gltf = gltf::Gltf::from_slice(bytes).unwrap();
    let blob = gltf.blob.clone().unwrap();
    let accessor = gltf.accessors().nth(index).unwrap();
    let iter = gltf::accessor::Iter::<f32>::new(accessor.clone(), |_| Some(&blob[..]));
    match accessor.dimensions() {
        gltf::accessor::Dimensions::Scalar => iter.unwrap().collect(),
        gltf::accessor::Dimensions::Vec3 => {
            gltf::accessor::Iter::<[f32; 3]>::new(accessor, |_| Some(&blob[..]))
                .unwrap()
                .flatten()
                .collect()
        }
        gltf::accessor::Dimensions::Mat4 => {
            gltf::accessor::Iter::<[[f32; 4]; 4]>::new(accessor, |_| Some(&blob[..]))
                .unwrap()
                .flat_map(|m| m.into_iter().flatten())
                .collect()
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_split_remaps_every_attribute_and_renumbers_every_reference() {
    let mut b = Builder::default();
    let position = b.floats(&QUAD_POSITIONS, "VEC3", true);
    let normal = b.floats(&QUAD_NORMALS, "VEC3", false);
    let uv = b.floats(&MIRRORED_UVS, "VEC2", false);
    let colors = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [9, 99, 199]];
    let color = b.colors_u8(&colors);
    let indices = b.indices(&[0, 1, 2, 0, 2, 3]);
    // Accessors after the mesh's, so dropping the mesh's old ones renumbers these.
    let times = b.floats(&[0.0, 1.0], "SCALAR", true);
    let moves = b.floats(&[0., 0., 0., 1., 2., 3.], "VEC3", false);
    let identity: Vec<f32> = (0..16)
        .map(|i| if i % 5 == 0 { 1.0 } else { 0.0 })
        .collect();
    let bind = b.floats(&identity, "MAT4", false);
    let mut doc = json!({
        "scene": 0, "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"name": "joint"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal,
            "TEXCOORD_0": uv, "COLOR_0": color}, "indices": indices, "material": 0}]}],
        "materials": normal_mapped(0),
        "skins": [{"inverseBindMatrices": bind, "joints": [1]}],
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}],
            "samplers": [{"input": times, "output": moves}]}],
        "extras": {"kept": [1.50, 2e3]}
    });
    texture_stub(&mut doc);
    let input = b.glb(doc);
    let done = process_glb(&input, SceneOptions::default());
    let report = &done.report;
    assert_eq!(
        report.summary.vertices_added, 2,
        "{:?}",
        report.primitives[0].diagnostics
    );
    assert_eq!(report.dropped.accessors, 5, "{:?}", report.dropped);
    let bytes = done.bytes.unwrap();
    assert_valid("split.glb", &bytes);

    let json = glb_json(&bytes);
    // The skin and the animation still find their data, under new numbers.
    let sampler = &json["animations"][0]["samplers"][0];
    assert_eq!(
        read_accessor_f32(&bytes, sampler["input"].as_u64().unwrap() as usize),
        vec![0.0, 1.0]
    );
    assert_eq!(
        read_accessor_f32(&bytes, sampler["output"].as_u64().unwrap() as usize),
        vec![0., 0., 0., 1., 2., 3.]
    );
    let bind_index = json["skins"][0]["inverseBindMatrices"].as_u64().unwrap() as usize;
    assert_eq!(read_accessor_f32(&bytes, bind_index), identity);
    // Number spelling in untouched members survives.
    let text =
        String::from_utf8_lossy(tspace::scene::gltf::glb::parse(&bytes).unwrap().json).into_owned();
    assert!(
        text.contains("[1.5,2000.0]") || text.contains("[1.50,2e3]"),
        "{text}"
    );

    // Every corner keeps its colour and position; the tangents are per corner what the core gives.
    let gltf = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = gltf.blob.clone().unwrap();
    let primitive = gltf.meshes().next().unwrap().primitives().next().unwrap();
    let reader = primitive.reader(|_| Some(&blob[..]));
    let out_colors: Vec<[u8; 3]> = reader.read_colors(0).unwrap().into_rgb_u8().collect();
    let out_positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    let out_indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
    assert_eq!(out_positions.len(), 6);
    for (corner, &v) in [0u32, 1, 2, 0, 2, 3].iter().zip(&out_indices) {
        assert_eq!(out_colors[v as usize], colors[*corner as usize]);
        let p = &QUAD_POSITIONS[*corner as usize * 3..][..3];
        assert_eq!(out_positions[v as usize], [p[0], p[1], p[2]]);
    }
    let tangents: Vec<[f32; 4]> = reader.read_tangents().unwrap().collect();
    let w: Vec<f32> = out_indices
        .iter()
        .map(|&v| tangents[v as usize][3])
        .collect();
    assert_eq!(&w[..3], &[w[0]; 3]);
    assert_eq!(&w[3..], &[-w[0]; 3]);
}

/// A bent sheet of two triangles without normals, each triangle with three vertices of its
/// own (a triangle soup), numbered by `indices`.
fn soup_without_normals(indices: &[u16]) -> (Vec<u8>, [usize; 3]) {
    let mut b = Builder::default();
    let positions = [
        0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 0., 0., 1., 1., 0., 0., 1., 1.,
    ];
    let uvs = [0., 0., 1., 0., 1., 1., 0., 0., 1., 1., 0., 1.];
    let position = b.floats(&positions, "VEC3", true);
    let uv = b.floats(&uvs, "VEC2", false);
    let index = b.indices(indices);
    let mut doc = json!({
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": position, "TEXCOORD_0": uv},
            "indices": index, "material": 0}]}],
        "materials": normal_mapped(0),
    });
    texture_stub(&mut doc);
    (b.glb(doc), [position, uv, index])
}

#[test]
fn generated_normals_keep_the_input_vertices_when_nothing_splits() {
    // Flat normals give a triangle soup's vertices one normal each: nothing splits, so the
    // input's accessors stay as they are and only NORMAL and TANGENT are added.
    let (input, [position, uv, index]) = soup_without_normals(&[0, 1, 2, 3, 4, 5]);
    let done = process_glb(&input, SceneOptions::default());
    assert_eq!(done.report.primitives[0].action, "generated");
    assert_eq!(done.report.summary.vertices_added, 0);
    assert_eq!(
        done.report.dropped.accessors, 0,
        "{:?}",
        done.report.dropped
    );
    let kept = done.bytes.unwrap();
    assert_valid("soup.glb", &kept);
    let json = glb_json(&kept);
    let primitive = &json["meshes"][0]["primitives"][0];
    assert_eq!(primitive["attributes"]["POSITION"], position);
    assert_eq!(primitive["attributes"]["TEXCOORD_0"], uv);
    assert_eq!(primitive["indices"], index);
    let normal = primitive["attributes"]["NORMAL"].as_u64().unwrap() as usize;
    // The second triangle's face normal is (1, -1, 1) / √3.
    let s = 1.0 / 3f32.sqrt();
    let expected = [
        [0., 0., 1.],
        [0., 0., 1.],
        [0., 0., 1.],
        [s, -s, s],
        [s, -s, s],
        [s, -s, s],
    ];
    let normals = read_accessor_f32(&kept, normal);
    assert_eq!(normals.len(), 18);
    for (got, want) in normals.iter().zip(expected.concat()) {
        assert!((got - want).abs() < 1e-6, "{normals:?}");
    }

    // Numbered in another order than the corners first use the vertices, the soup is written
    // anew in that order; every corner still gets the same tangent.
    let rotated = [1u16, 2, 0, 4, 5, 3];
    let (input, _) = soup_without_normals(&rotated);
    let rewritten = process_glb(&input, SceneOptions::default()).bytes.unwrap();
    assert_valid("soup-renumbered.glb", &rewritten);
    let json = glb_json(&rewritten);
    assert_ne!(
        json["meshes"][0]["primitives"][0]["attributes"]["POSITION"],
        position
    );
    let by_vertex = &corner_tangents(&kept)[0];
    let expected: Vec<[f32; 4]> = rotated.iter().map(|&v| by_vertex[v as usize]).collect();
    assert_eq!(corner_tangents(&rewritten)[0], expected);
}

#[test]
fn primitives_sharing_accessors_are_computed_once() {
    let mut b = Builder::default();
    let position = b.floats(&QUAD_POSITIONS, "VEC3", true);
    let normal = b.floats(&QUAD_NORMALS, "VEC3", false);
    let uv = b.floats(&[0., 0., 1., 0., 1., 1., 0., 1.], "VEC2", false);
    let indices = b.indices(&[0, 1, 2, 0, 2, 3]);
    let primitive = json!({"attributes": {"POSITION": position, "NORMAL": normal, "TEXCOORD_0": uv},
        "indices": indices, "material": 0});
    let mut doc = json!({
        "scene": 0, "scenes": [{"nodes": [0, 1]}], "nodes": [{"mesh": 0}, {"mesh": 1}],
        "meshes": [{"primitives": [primitive.clone()]}, {"primitives": [primitive]}],
        "materials": normal_mapped(0),
    });
    texture_stub(&mut doc);
    let done = process_glb(&b.glb(doc), SceneOptions::default());
    assert_eq!(done.report.summary.computations, 1);
    assert_eq!(done.report.summary.generated, 2);
    // The computation's totals count once, though two primitives use it.
    assert_eq!(done.report.summary.triangles, 2);
    assert_eq!(done.report.primitives[1].shared_with, Some([0, 0]));
    let bytes = done.bytes.unwrap();
    assert_valid("shared.glb", &bytes);
    let json = glb_json(&bytes);
    let tangent = |m: usize| json["meshes"][m]["primitives"][0]["attributes"]["TANGENT"].clone();
    assert_eq!(tangent(0), tangent(1));
    assert_eq!(json["accessors"].as_array().unwrap().len(), 5);
}

#[test]
fn strips_and_fans_match_the_same_triangles_as_a_list() {
    let run = |mode: u64, indices: &[u16]| -> Vec<[f32; 4]> {
        let mut b = Builder::default();
        let position = b.floats(&QUAD_POSITIONS, "VEC3", true);
        let normal = b.floats(&QUAD_NORMALS, "VEC3", false);
        let uv = b.floats(&[0., 0., 1., 0., 1., 1., 0., 1.], "VEC2", false);
        let indices = b.indices(indices);
        let mut doc = json!({
            "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal,
                "TEXCOORD_0": uv}, "indices": indices, "material": 0, "mode": mode}]}],
            "materials": normal_mapped(0),
        });
        texture_stub(&mut doc);
        let done = process_glb(&b.glb(doc), SceneOptions::default());
        let bytes = done.bytes.unwrap();
        assert_valid("strip.glb", &bytes);
        assert_eq!(
            glb_json(&bytes)["meshes"][0]["primitives"][0]["mode"],
            json!(4)
        );
        corner_tangents(&bytes).remove(0)
    };
    let list = run(4, &[0, 1, 3, 1, 2, 3]);
    assert_eq!(run(5, &[0, 1, 3, 2]), list);
    let fan_list = run(4, &[1, 2, 0, 2, 3, 0]);
    assert_eq!(run(6, &[0, 1, 2, 3]), fan_list);
}

#[test]
fn the_normal_maps_uv_set_decides_the_tangent() {
    let mut b = Builder::default();
    let position = b.floats(&QUAD_POSITIONS, "VEC3", true);
    let normal = b.floats(&QUAD_NORMALS, "VEC3", false);
    let uv0 = b.floats(&[0., 0., 1., 0., 1., 1., 0., 1.], "VEC2", false);
    // Set 1 is set 0 turned a quarter: u runs along +y.
    let uv1 = b.floats(&[0., 0., 0., -1., 1., -1., 1., 0.], "VEC2", false);
    let indices = b.indices(&[0, 1, 2, 0, 2, 3]);
    let mut doc = json!({
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal,
            "TEXCOORD_0": uv0, "TEXCOORD_1": uv1}, "indices": indices, "material": 0}]}],
        "materials": normal_mapped(1),
    });
    texture_stub(&mut doc);
    let done = process_glb(&b.glb(doc), SceneOptions::default());
    assert_eq!(done.report.primitives[0].texcoord, 1);
    let bytes = done.bytes.unwrap();
    assert_valid("uv1.glb", &bytes);
    for t in &corner_tangents(&bytes)[0] {
        assert!((t[1] - 1.0).abs() < 1e-6 && t[0].abs() < 1e-6, "{t:?}");
    }
}

#[test]
fn morph_targets_get_tangent_deltas_from_the_morphed_mesh() {
    // A 4x4 grid that the target bends upwards.
    let n = 4;
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut deltas = Vec::new();
    let mut normal_deltas = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f32 / 3.0, j as f32 / 3.0);
            positions.extend([x, y, 0.0]);
            normals.extend([0.0, 0.0, 1.0]);
            uvs.extend([x, y]);
            deltas.extend([0.0, 0.0, 0.5 * x * x]);
            // The bent surface's normal, as a delta from +z.
            let length = (x * x + 1.0f32).sqrt();
            normal_deltas.extend([-x / length, 0.0, 1.0 / length - 1.0]);
        }
    }
    let mut indices = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = (j * n + i) as u16;
            let n = n as u16;
            indices.extend([v, v + 1, v + n + 1, v, v + n + 1, v + n]);
        }
    }
    let mut b = Builder::default();
    let position = b.floats(&positions, "VEC3", true);
    let normal = b.floats(&normals, "VEC3", false);
    let uv = b.floats(&uvs, "VEC2", false);
    let delta = b.floats(&deltas, "VEC3", true);
    let normal_delta = b.floats(&normal_deltas, "VEC3", false);
    let index = b.indices(&indices);
    let mut doc = json!({
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal,
            "TEXCOORD_0": uv}, "indices": index, "material": 0,
            "targets": [{"POSITION": delta, "NORMAL": normal_delta}]}], "weights": [0.0]}],
        "materials": normal_mapped(0),
    });
    texture_stub(&mut doc);
    let done = process_glb(&b.glb(doc), SceneOptions::default());
    let morph = done.report.primitives[0].morph_targets.clone().unwrap();
    assert_eq!((morph.targets, morph.with_tangent_deltas), (1, 1));
    let bytes = done.bytes.unwrap();
    assert_valid("morph.glb", &bytes);
    let json = glb_json(&bytes);
    let primitive = &json["meshes"][0]["primitives"][0];
    let base_index = primitive["attributes"]["TANGENT"].as_u64().unwrap() as usize;
    let delta_index = primitive["targets"][0]["TANGENT"].as_u64().unwrap() as usize;

    // Base plus delta is MikkTSpace on the morphed mesh.
    let morphed: Vec<[f32; 3]> = positions
        .chunks(3)
        .zip(deltas.chunks(3))
        .map(|(p, d)| [p[0] + d[0], p[1] + d[1], p[2] + d[2]])
        .collect();
    let normals3: Vec<[f32; 3]> = normals
        .chunks(3)
        .zip(normal_deltas.chunks(3))
        .map(|(n, d)| {
            let m = [n[0] + d[0], n[1] + d[1], n[2] + d[2]];
            let l = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
            [m[0] / l, m[1] / l, m[2] / l]
        })
        .collect();
    let uvs2: Vec<[f32; 2]> = uvs.chunks(2).map(|c| [c[0], c[1]]).collect();
    let indices32: Vec<u32> = indices.iter().map(|&i| u32::from(i)).collect();
    let expected = tspace_tangent::generate(
        &tspace_tangent::MeshInput {
            positions: &morphed,
            normals: Some(&normals3),
            uvs: Some(&uvs2),
            indices: Some(&indices32),
        },
        &tspace_tangent::Options::default(),
    )
    .unwrap();
    let gltf = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = gltf.blob.clone().unwrap();
    let base: Vec<[f32; 4]> =
        gltf::accessor::Iter::new(gltf.accessors().nth(base_index).unwrap(), |_| {
            Some(&blob[..])
        })
        .unwrap()
        .collect();
    let delta_out: Vec<[f32; 3]> =
        gltf::accessor::Iter::new(gltf.accessors().nth(delta_index).unwrap(), |_| {
            Some(&blob[..])
        })
        .unwrap()
        .collect();
    let out_indices: Vec<u32> = gltf
        .meshes()
        .next()
        .unwrap()
        .primitives()
        .next()
        .unwrap()
        .reader(|_| Some(&blob[..]))
        .read_indices()
        .unwrap()
        .into_u32()
        .collect();
    let mut max_error = 0.0f32;
    for (corner, &v) in out_indices.iter().enumerate() {
        let t = expected.corner_tangent(corner, Some(&indices32));
        let (b, d) = (base[v as usize], delta_out[v as usize]);
        for k in 0..3 {
            max_error = max_error.max((b[k] + d[k] - t[k]).abs());
        }
    }
    assert!(
        max_error < 1e-5,
        "base + delta is {max_error} away from the morphed tangents"
    );
    assert!(
        delta_out.iter().any(|d| d[2].abs() > 0.05),
        "the bend must tilt the tangents"
    );
}

#[test]
fn external_buffers_merge_into_one_and_a_draco_fallback_replaces_the_extension() {
    // Positions in one file, everything else in another; a Draco extension with a fallback.
    let mut b = Builder::default();
    let position = b.floats(&QUAD_POSITIONS, "VEC3", true);
    let normal = b.floats(&QUAD_NORMALS, "VEC3", false);
    let uv = b.floats(&[0., 0., 1., 0., 1., 1., 0., 1.], "VEC2", false);
    let indices = b.indices(&[0, 1, 2, 0, 2, 3]);
    let first_len = 48;
    let mut doc = json!({
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "extensionsUsed": ["KHR_draco_mesh_compression"],
        "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal,
            "TEXCOORD_0": uv}, "indices": indices, "material": 0,
            "extensions": {"KHR_draco_mesh_compression": {"bufferView": 4,
                "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}}}}]}],
        "materials": normal_mapped(0),
    });
    texture_stub(&mut doc);
    let mut doc = b.document(doc);
    let rest = b.bin[first_len..].to_vec();
    let mut rest_padded = rest.clone();
    rest_padded.extend_from_slice(b"fake draco bytes");
    doc["buffers"] = json!([
        {"byteLength": first_len, "uri": "positions.bin"},
        {"byteLength": rest_padded.len(), "uri": "rest%20of%20it.bin", "name": "rest"}
    ]);
    let views = doc["bufferViews"].as_array_mut().unwrap();
    for view in views.iter_mut().skip(1) {
        view["buffer"] = json!(1);
        view["byteOffset"] = json!(view["byteOffset"].as_u64().unwrap() - first_len as u64);
    }
    views.push(json!({"buffer": 1, "byteOffset": rest.len(), "byteLength": 16}));
    let text = serde_json::to_vec(&doc).unwrap();
    let first = b.bin[..first_len].to_vec();
    let mut parts = PartSet::new();
    parts.insert("positions.bin", &first).unwrap();
    parts.insert("rest of it.bin", &rest_padded).unwrap();
    let done = process(&text, &parts, &SceneOptions::default()).unwrap();
    assert!(
        done.report.warnings.iter().any(|w| w.contains("merged")),
        "{:?}",
        done.report.warnings
    );
    assert!(
        done.report
            .warnings
            .iter()
            .any(|w| w.contains("KHR_draco_mesh_compression"))
    );
    let bytes = done.bytes.unwrap();
    assert_valid("merged.glb", &bytes);
    let json = glb_json(&bytes);
    assert_eq!(json["buffers"].as_array().unwrap().len(), 1);
    assert!(
        json["meshes"][0]["primitives"][0]
            .get("extensions")
            .is_none()
    );
    assert!(
        json.get("extensionsUsed")
            .is_none_or(|u| u.as_array().unwrap().is_empty())
    );
    assert_eq!(
        done.report.dropped.buffer_views, 1,
        "the Draco data is gone"
    );
}

#[test]
fn required_meshopt_compression_is_decoded() {
    // An interleaved quad (position, normal, uv) and its indices, compressed by meshoptimizer.
    let uvs = [0f32, 0., 1., 0., 1., 1., 0., 1.];
    let indices = [0u32, 1, 2, 0, 2, 3];
    let input = tspace_testkit::glb_builder::meshopt_quad();
    let done = process_glb(&input, SceneOptions::default());
    assert_eq!(done.report.primitives[0].action, "generated");
    let bytes = done.bytes.unwrap();
    assert_valid("meshopt.glb", &bytes);

    // The output is meshopt-compressed too (compress=auto): read the new TANGENT accessor back
    // through the loader, which decodes it, and compare with the core on the uncompressed quad.
    let json = glb_json(&bytes);
    let tangent = json["meshes"][0]["primitives"][0]["attributes"]["TANGENT"]
        .as_u64()
        .unwrap() as usize;
    let view =
        &json["bufferViews"][json["accessors"][tangent]["bufferView"].as_u64().unwrap() as usize];
    assert!(view["extensions"]["EXT_meshopt_compression"].is_object());
    let limits = tspace::scene::gltf::load::LoadLimits {
        max_buffer_bytes: 1 << 20,
    };
    let loaded = tspace::scene::gltf::load::load(&bytes, &NoResources, &limits).unwrap();
    let got: Vec<f32> = tspace::scene::gltf::accessor::read_floats_json::<4>(
        loaded.doc.root(),
        tangent,
        &loaded.buffer_slices(),
        4,
    )
    .unwrap()
    .into_iter()
    .flatten()
    .collect();
    let positions: Vec<[f32; 3]> = QUAD_POSITIONS
        .chunks(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let normals: Vec<[f32; 3]> = QUAD_NORMALS.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
    let uv2: Vec<[f32; 2]> = uvs.chunks(2).map(|c| [c[0], c[1]]).collect();
    let expected = tspace_tangent::generate(
        &tspace_tangent::MeshInput {
            positions: &positions,
            normals: Some(&normals),
            uvs: Some(&uv2),
            indices: Some(&indices),
        },
        &tspace_tangent::Options::default(),
    )
    .unwrap();
    let expected: Vec<f32> = expected
        .split
        .vertex_tangents
        .iter()
        .flatten()
        .copied()
        .collect();
    assert_eq!(got, expected);
}

#[test]
fn quantized_attributes_are_dequantized_and_remapped_in_their_own_types() {
    // KHR_mesh_quantization: i16 positions, i8 normalized normals, u16 normalized UVs, and the
    // mirrored UVs force a split, so each is copied into a new accessor of its own type.
    let mut b = Builder::default();
    let push = |b: &mut Builder, bytes: Vec<u8>, stride: Option<usize>| {
        while !b.bin.len().is_multiple_of(4) {
            b.bin.push(0);
        }
        let mut view = json!({"buffer": 0, "byteOffset": b.bin.len(), "byteLength": bytes.len()});
        if let Some(stride) = stride {
            view["byteStride"] = json!(stride);
        }
        b.bin.extend_from_slice(&bytes);
        b.views.push(view);
        b.views.len() - 1
    };
    let positions: [[i16; 3]; 4] = [[0, 0, 0], [100, 0, 0], [100, 100, 0], [0, 100, 0]];
    let bytes = positions
        .iter()
        .flat_map(|p| p.iter().flat_map(|c| c.to_le_bytes()).chain([0, 0]))
        .collect();
    let view = push(&mut b, bytes, Some(8));
    b.accessors.push(
        json!({"bufferView": view, "componentType": 5122, "count": 4, "type": "VEC3",
        "min": [0, 0, 0], "max": [100, 100, 0]}),
    );
    let bytes = (0..4).flat_map(|_| [0u8, 0, 127, 0]).collect();
    let view = push(&mut b, bytes, Some(4));
    b.accessors.push(json!({"bufferView": view, "componentType": 5120, "normalized": true, "count": 4, "type": "VEC3"}));
    let uvs: [[u16; 2]; 4] = [[0, 0], [32767, 0], [32767, 32767], [65535, 0]];
    let bytes = uvs
        .iter()
        .flat_map(|p| p.iter().flat_map(|c| c.to_le_bytes()))
        .collect();
    let view = push(&mut b, bytes, None);
    b.accessors.push(json!({"bufferView": view, "componentType": 5123, "normalized": true, "count": 4, "type": "VEC2"}));
    let indices = b.indices(&[0, 1, 2, 0, 2, 3]);
    let mut doc = json!({
        "extensionsUsed": ["KHR_mesh_quantization"], "extensionsRequired": ["KHR_mesh_quantization"],
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "scale": [0.01, 0.01, 0.01]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
            "indices": indices, "material": 0}]}],
        "materials": normal_mapped(0),
    });
    texture_stub(&mut doc);
    let done = process_glb(&b.glb(doc), SceneOptions::default());
    let diagnostics = done.report.primitives[0].diagnostics.clone().unwrap();
    assert_eq!(diagnostics.vertices_added, 2);
    // Quantized normals were renormalized before use, so none is reported as non-unit.
    assert_eq!(diagnostics.non_unit_normals.count, 0);
    let bytes = done.bytes.unwrap();
    assert_valid("quantized.glb", &bytes);
    let json = glb_json(&bytes);
    let attributes = &json["meshes"][0]["primitives"][0]["attributes"];
    let accessor =
        |name: &str| json["accessors"][attributes[name].as_u64().unwrap() as usize].clone();
    assert_eq!(accessor("POSITION")["componentType"], json!(5122));
    assert_eq!(accessor("POSITION")["max"], json!([100, 100, 0]));
    assert_eq!(accessor("NORMAL")["normalized"], json!(true));
    assert_eq!(accessor("TEXCOORD_0")["componentType"], json!(5123));
    assert_eq!(accessor("TEXCOORD_0")["count"], json!(6));
}

#[test]
fn unknown_extensions_and_extras_survive_and_keep_everything_in_place() {
    let mut b = Builder::default();
    let position = b.floats(&QUAD_POSITIONS, "VEC3", true);
    let normal = b.floats(&QUAD_NORMALS, "VEC3", false);
    let uv = b.floats(&MIRRORED_UVS, "VEC2", false);
    let indices = b.indices(&[0, 1, 2, 0, 2, 3]);
    let mut doc = json!({
        "extensionsUsed": ["EXT_made_up"],
        "extensions": {"EXT_made_up": {"accessor": 2, "note": "refers to an accessor by index"}},
        "scene": 0, "scenes": [{"nodes": [0], "extras": {"a": 1}}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal,
            "TEXCOORD_0": uv}, "indices": indices, "material": 0,
            "extras": {"keep": true}, "extensions": {"EXT_made_up": {"x": 1}}}]}],
        "materials": normal_mapped(0),
    });
    texture_stub(&mut doc);
    let done = process_glb(&b.glb(doc), SceneOptions::default());
    assert_eq!(done.report.summary.vertices_added, 2);
    // The split orphaned accessors, but EXT_made_up might refer to them: nothing is dropped.
    assert_eq!(done.report.dropped.accessors, 0);
    assert!(
        done.report
            .dropped
            .kept_because
            .as_deref()
            .is_some_and(|w| w.contains("EXT_made_up"))
    );
    let bytes = done.bytes.unwrap();
    let json = glb_json(&bytes);
    assert_eq!(json["extensions"]["EXT_made_up"]["accessor"], json!(2));
    assert_eq!(
        json["accessors"][2]["type"],
        json!("VEC2"),
        "accessor 2 is still the UVs"
    );
    let primitive = &json["meshes"][0]["primitives"][0];
    assert_eq!(primitive["extras"], json!({"keep": true}));
    assert_eq!(primitive["extensions"], json!({"EXT_made_up": {"x": 1}}));
    assert_eq!(json["scenes"][0]["extras"], json!({"a": 1}));
}

/// Written in pieces (as the command line writes), every fixture comes out as the same bytes
/// with the same report as written whole: GLB and `.gltf` inputs, passed through, split,
/// Draco and meshopt ones, and OBJ ones (whose pieces hold the GLB the OBJ became, and are put
/// together here against the OBJ's text, as a caller holding only that would), under the
/// default options and with everything recomputed.
#[test]
fn pieces_put_together_are_the_whole_output() {
    use tspace::scene::folder::Folder;
    use tspace::scene::input::{self, InputKind};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    let mut files: Vec<std::path::PathBuf> = Vec::new();
    for dir in std::fs::read_dir(&root).unwrap().flatten() {
        for file in std::fs::read_dir(dir.path())
            .into_iter()
            .flatten()
            .flatten()
        {
            let path = file.path();
            if InputKind::from_file_name(&path.to_string_lossy()).is_some() {
                files.push(path);
            }
        }
    }
    files.sort();
    assert!(files.len() > 20, "{} fixtures", files.len());
    let mut in_pieces = 0;
    let mut obj_in_pieces = 0;
    for path in &files {
        let bytes = std::fs::read(path).unwrap();
        let kind = InputKind::from_file_name(&path.to_string_lossy()).unwrap();
        let folder = Folder::of_file(path, 1 << 30);
        for options in [SceneOptions::default(), overwrite_all()] {
            let Ok(whole) = input::process(kind, &bytes, &folder, &options) else {
                continue;
            };
            let pieces_options = SceneOptions {
                in_pieces: true,
                ..options.clone()
            };
            let split = input::process(kind, &bytes, &folder, &pieces_options).unwrap();
            let put_together = match (&split.pieces, &split.bytes) {
                (Some(pieces), None) => {
                    in_pieces += 1;
                    if kind == InputKind::Obj {
                        assert!(pieces.hold_their_input(), "{}", path.display());
                        obj_in_pieces += 1;
                    }
                    pieces.to_vec(&bytes)
                }
                (None, Some(bytes)) => bytes.clone(),
                _ => panic!("{}: neither pieces nor bytes", path.display()),
            };
            assert!(
                put_together == whole.bytes.clone().unwrap(),
                "{}: the pieces differ from the whole output",
                path.display()
            );
            assert_eq!(
                split.report.to_json_pretty(),
                whole.report.to_json_pretty(),
                "{}",
                path.display()
            );
        }
    }
    assert!(in_pieces > 10, "only {in_pieces} outputs came in pieces");
    assert!(
        obj_in_pieces >= 4,
        "only {obj_in_pieces} OBJ outputs came in pieces"
    );
}

fn overwrite_all() -> SceneOptions {
    SceneOptions {
        overwrite: true,
        all: true,
        ..SceneOptions::default()
    }
}
