//! Replays the fuzzers' saved inputs through the same functions the fuzz targets call
//! (`tspace_testkit::fuzz`), on stable, as part of the normal test suite: every file in
//! `fuzz/seeds/<target>/`, `fuzz/corpus/<target>/` and `fuzz/regressions/<target>/`. A panic in
//! any of them fails the test, naming the file.
//!
//! Run with `cargo test --release --test fuzz_replay`. The seeds themselves are made by the
//! ignored test `make_seeds` (see fuzz/README.md).

#[allow(unused_imports)]
use serde_json::{Value, json};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tspace::scene::gltf::glb;
use tspace::scene::gltf::write::base64;
use tspace_testkit::fuzz as fuzz_targets;

type Target = fn(&[u8]);

const TARGETS: [(&str, Target); 6] = [
    ("glb", fuzz_targets::glb),
    ("gltf", fuzz_targets::gltf),
    ("obj", fuzz_targets::obj),
    ("parts", fuzz_targets::parts),
    ("draco", fuzz_targets::draco),
    ("core", fuzz_targets::core),
];

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

#[test]
fn saved_inputs_do_not_panic() {
    let start = Instant::now();
    let mut failures = Vec::new();
    let mut total = 0;
    let quiet = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    for (name, target) in TARGETS {
        let mut count = 0;
        for kind in ["seeds", "corpus", "regressions"] {
            for file in files_in(&fuzz_dir().join(kind).join(name)) {
                let data = std::fs::read(&file).unwrap();
                count += 1;
                if let Err(panic) = catch_unwind(AssertUnwindSafe(|| target(&data))) {
                    let message = panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                        .unwrap_or_default();
                    failures.push(format!("{}: {message}", file.display()));
                }
            }
        }
        println!("{name}: {count} inputs");
        total += count;
    }
    std::panic::set_hook(quiet);
    println!("{total} inputs in {:.2} s", start.elapsed().as_secs_f64());
    assert!(total > 0, "no saved inputs found under {:?}", fuzz_dir());
    assert!(
        failures.is_empty(),
        "{} inputs panicked:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The Draco seeds reach the decoder's far side: each decodes (so mutations start from streams
/// that work, not from refusals).
#[test]
fn draco_seeds_decode() {
    let seeds = files_in(&fuzz_dir().join("seeds/draco"));
    assert!(seeds.len() >= 9, "{} Draco seeds", seeds.len());
    for seed in seeds {
        let data = std::fs::read(&seed).unwrap();
        let decoded = fuzz_targets::draco_decoded_accessors(&data)
            .unwrap_or_else(|e| panic!("{}: {e}", seed.display()));
        assert!(decoded >= 2, "{}: {decoded} accessors", seed.display());
    }
}

// ---------------------------------------------------------------------------------------------
// Seed generation: `cargo test --release --test fuzz_replay -- --ignored make_seeds`.

/// The fixtures, and the shared corpus when it is there.
fn fixture(path: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fixtures")
            .join(path),
    )
    .unwrap()
}

fn shared(path: &str) -> Option<Vec<u8>> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/corpus")
            .join(path),
    )
    .ok()
}

/// A `.gltf` whose only buffer is the file `bin`, as a GLB and as a `.gltf` with a data URI.
fn packed(gltf: &[u8], bin: &[u8]) -> (Vec<u8>, Vec<u8>) {
    let mut doc: Value = serde_json::from_slice(gltf).unwrap();
    assert_eq!(doc["buffers"].as_array().unwrap().len(), 1);
    doc["buffers"][0]
        .as_object_mut()
        .unwrap()
        .remove("uri")
        .unwrap();
    let glb_bytes = glb::write(&serde_json::to_vec(&doc).unwrap(), Some(bin), &[]).unwrap();
    doc["buffers"][0]["uri"] = json!(format!(
        "data:application/octet-stream;base64,{}",
        base64(bin)
    ));
    (glb_bytes, serde_json::to_vec(&doc).unwrap())
}

/// A quad with normals and UVs, compressed with EXT_meshopt_compression, as a GLB.
fn meshopt_quad() -> Vec<u8> {
    tspace_testkit::glb_builder::meshopt_quad()
}

/// A 1x1 PNG.
const PNG: &str = "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8BQDwAEhQGAhKmMIQAAAABJRU5ErkJggg==";

/// A quad with a mirrored second triangle, as a `.gltf` using two external buffers (one with a
/// percent-encoded name) and an external image: for `parts`.
fn external_quad() -> (Vec<u8>, Vec<u8>, Vec<u8>) {
    let floats = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let positions = floats(&[0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.]);
    let mut rest = floats(&[0., 0., 1., 0., 0., 1., 0., 0., 1., 0., 0., 1.]);
    rest.extend(floats(&[0., 0., 1., 0., 1., 1., 2., 0.]));
    rest.extend([0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()));
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "buffers": [{"byteLength": 48, "uri": "positions.bin"},
            {"byteLength": rest.len(), "uri": "rest%20of%20it.bin"}],
        "bufferViews": [
            {"buffer": 0, "byteLength": 48},
            {"buffer": 1, "byteLength": 48},
            {"buffer": 1, "byteOffset": 48, "byteLength": 32},
            {"buffer": 1, "byteOffset": 80, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
            "indices": 3, "material": 0}]}],
        "materials": [{"normalTexture": {"index": 0}}],
        "textures": [{"source": 0}],
        "images": [{"uri": "textures/normal.png"}],
    });
    (serde_json::to_vec(&doc).unwrap(), positions, rest)
}

/// Compact core meshes (see `tspace_testkit::fuzz::core`): byte 0 vertex count, byte 1 flags,
/// byte 2 crease, then 8 one-byte floats per vertex (1.0 is 8), then indices.
fn core_seeds() -> Vec<(&'static str, Vec<u8>)> {
    let quad: [[i8; 8]; 4] = [
        [0, 0, 0, 0, 0, 8, 0, 0],
        [8, 0, 0, 0, 0, 8, 8, 0],
        [8, 8, 0, 0, 0, 8, 8, 8],
        [0, 8, 0, 0, 0, 8, 0, 8],
    ];
    let compact = |vertices: &[[i8; 8]], flags: u8, crease: u8, indices: &[u8]| {
        let mut out = vec![vertices.len() as u8, flags | 1, crease];
        out.extend(vertices.iter().flatten().map(|&b| b as u8));
        out.extend_from_slice(indices);
        out
    };
    let mut mirrored = quad;
    mirrored[3][6] = 16;
    mirrored[3][7] = 0;
    let cube: Vec<[i8; 8]> = (0..8)
        .map(|v| {
            let c = |bit: i32| if v >> bit & 1 == 1 { 8 } else { -8 };
            [
                c(0),
                c(1),
                c(2),
                c(0),
                c(1),
                c(2),
                (v & 1) as i8 * 8,
                (v >> 1 & 1) as i8 * 8,
            ]
        })
        .collect();
    let cube_indices = [
        0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6,
        1, 3, 5, 3, 7, 5,
    ];
    let mut broken = quad;
    broken[1][0] = 0x80u8 as i8; // NaN position
    broken[2][3] = 0; // zero normal
    broken[2][5] = 0;
    broken[3][6] = 0x83u8 as i8; // subnormal UV
    let mut raw = vec![4u8, 0, 0];
    for v in &quad {
        for &x in v {
            raw.extend((f32::from(x) / 8.0).to_le_bytes());
        }
    }
    raw.extend([0, 1, 2, 0, 2, 3]);
    vec![
        ("quad", compact(&quad, 0, 0, &[0, 1, 2, 0, 2, 3])),
        (
            "quad_mirrored",
            compact(&mirrored, 0, 0, &[0, 1, 2, 0, 2, 3]),
        ),
        (
            "quad_bottom_left_area",
            compact(&quad, 2 | 4, 0, &[0, 1, 2, 0, 2, 3]),
        ),
        ("cube_smooth_60", compact(&cube, 8, 60, &cube_indices)),
        ("cube_smooth_nan", compact(&cube, 8, 255, &cube_indices)),
        ("cube_no_uvs", compact(&cube, 0x10, 0, &cube_indices)),
        (
            "broken",
            compact(&broken, 0, 0, &[0, 1, 2, 0, 2, 3, 3, 3, 3]),
        ),
        ("out_of_range", compact(&quad, 0, 0, &[0, 1, 2, 0, 2, 0xFF])),
        ("not_triangles", compact(&quad, 0x20, 0, &[0, 1, 2, 0])),
        ("raw_quad", raw),
    ]
}

fn obj_with_mtl(obj: &[u8], mtl: &[u8], old_name: &str) -> Vec<u8> {
    let text = String::from_utf8_lossy(obj).replace(&format!("mtllib {old_name}"), "mtllib a.mtl");
    let mut out = text.into_bytes();
    out.push(0xFF);
    out.extend_from_slice(mtl);
    out
}

#[test]
#[ignore = "writes fuzz/seeds; run by hand when the seed set changes"]
fn make_seeds() {
    let seeds = fuzz_dir().join("seeds");
    let write = |target: &str, name: &str, bytes: &[u8]| {
        let dir = seeds.join(target);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(name), bytes).unwrap();
    };
    let png = tspace::scene::uri::decode_base64(PNG.as_bytes()).unwrap();
    let parts = fuzz_targets::encode_parts;

    // Scenes: the small fixtures and corpus scenes with one buffer, as GLB and as .gltf.
    let mut scenes: Vec<(String, Vec<u8>, Vec<u8>)> = Vec::new();
    for (name, gltf, bin) in [
        ("Avocado", "Avocado/Avocado.gltf", "Avocado/Avocado.bin"),
        (
            "MultiUVTest",
            "MultiUVTest/MultiUVTest.gltf",
            "MultiUVTest/MultiUVTest.bin",
        ),
        (
            "SimpleSparseAccessor",
            "SimpleSparseAccessor/SimpleSparseAccessor.gltf",
            "SimpleSparseAccessor/SimpleSparseAccessor.bin",
        ),
    ] {
        scenes.push((name.into(), fixture(gltf), fixture(bin)));
    }
    let mut corpus_scenes = vec![
        (
            "AnimatedMorphCube".to_string(),
            "gltf_AnimatedMorphCube/AnimatedMorphCube".to_string(),
        ),
        (
            "MorphPrimitivesTest".into(),
            "gltf_MorphPrimitivesTest/MorphPrimitivesTest".into(),
        ),
        (
            "TextureTransformTest".into(),
            "gltf_TextureTransformTest_no_normals/TextureTransformTest".into(),
        ),
        (
            "IndexOutOfRange".into(),
            "gltf_assimp_invalid_inputs/IndexOutOfRange".into(),
        ),
    ];
    for mode in 0..16 {
        corpus_scenes.push((
            format!("PrimitiveMode_{mode:02}"),
            format!("gltf_AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_{mode:02}"),
        ));
    }
    for (name, stem) in corpus_scenes {
        if let (Some(gltf), Some(bin)) = (
            shared(&format!("{stem}.gltf")),
            shared(&format!("{stem}.bin")),
        ) {
            scenes.push((name, gltf, bin));
        }
    }
    for (name, gltf, bin) in &scenes {
        let (glb_bytes, embedded) = packed(gltf, bin);
        write("glb", &format!("{name}.glb"), &glb_bytes);
        write("gltf", &format!("{name}.gltf"), &embedded);
        if bin.len() < 8192 {
            write("gltf", &format!("{name}.glb"), &glb_bytes);
        }
    }
    for (target, name, bytes) in [
        ("glb", "Box.glb", Some(fixture("Box/Box.glb"))),
        ("gltf", "Box.glb", Some(fixture("Box/Box.glb"))),
        (
            "gltf",
            "BoxTextured.gltf",
            Some(fixture("BoxTextured_embedded/BoxTextured.gltf")),
        ),
        (
            "gltf",
            "triangle_mesh_quantized.gltf",
            Some(fixture("quantized_triangle/triangle_mesh_quantized.gltf")),
        ),
        (
            "gltf",
            "SimpleSparseAccessor_embedded.gltf",
            shared("gltf_SimpleSparseAccessor/glTF-Embedded/SimpleSparseAccessor.gltf"),
        ),
        (
            "glb",
            "BoxWithInfinites.glb",
            shared("gltf_assimp_invalid_inputs/BoxWithInfinites.glb"),
        ),
        (
            "glb",
            "BoxBadNormals.glb",
            shared("gltf_assimp_invalid_inputs/BoxBadNormals.glb"),
        ),
        (
            "glb",
            "Box_Draco.glb",
            shared("gltf_draco_Box/Box_Draco.glb"),
        ),
        ("glb", "meshopt_quad.glb", Some(meshopt_quad())),
        ("gltf", "meshopt_quad.glb", Some(meshopt_quad())),
    ] {
        if let Some(bytes) = bytes {
            write(target, name, &bytes);
        }
    }

    // OBJ: text, 0xFF, MTL (named a.mtl).
    write(
        "obj",
        "concave_polygon",
        &obj_with_mtl(
            &fixture("concave_polygon/concave_polygon.obj"),
            &fixture("concave_polygon/concave_polygon.mtl"),
            "concave_polygon.mtl",
        ),
    );
    write(
        "obj",
        "spider",
        &obj_with_mtl(
            &fixture("spider/spider.obj"),
            &fixture("spider/spider.mtl"),
            "spider.mtl",
        ),
    );
    write(
        "obj",
        "negative_indices",
        &fixture("negative_indices/negative_indices.obj"),
    );
    write(
        "obj",
        "normal_mapped_quad",
        b"mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
          vn 0 0 1\ng quad\nusemtl bumpy\nf 1/1/1 2/2/1 3/3/1 4/4/1\nusemtl plain\nf 1/1 3/3 4/4\n\
          l 1 2\np 3\ns 1\no other\nf -4//1 -3//1 -2//1\n\xFFnewmtl bumpy\nmap_Bump -bm 0.5 .\\n.png\n\
          map_Kd d.png\nnewmtl plain\nKd 1 0 0\n",
    );
    for name in [
        "triangle_with_degenerate_tex_coords.obj",
        "inf_nan.obj",
        "octagon.obj",
        "deg_faces.obj",
        "cube_quads.obj",
        "cube_att.obj",
    ] {
        if let Some(bytes) = shared(&format!("obj_draco_edge_cases/{name}")) {
            write("obj", name, &bytes);
        }
    }

    // Multipart uploads.
    let (quad, positions, rest) = external_quad();
    write(
        "parts",
        "external_quad",
        &parts(&[
            ("file", Some("quad.gltf"), &quad),
            ("a", Some("positions.bin"), &positions),
            ("b", Some("rest of it.bin"), &rest),
            ("c", Some("normal.png"), &png),
        ]),
    );
    write(
        "parts",
        "external_quad_by_extension",
        &parts(&[
            ("positions.bin", None, &positions),
            ("x", Some("quad.gltf"), &quad),
            ("rest of it.bin", None, &rest),
        ]),
    );
    write(
        "parts",
        "duplicate_names",
        &parts(&[
            ("scene", None, &quad),
            ("a", Some("positions.bin"), &positions),
            ("positions.bin", None, &positions),
        ]),
    );
    let avocado = fixture("Avocado/Avocado.gltf");
    let avocado_bin = fixture("Avocado/Avocado.bin");
    write(
        "parts",
        "avocado",
        &parts(&[
            ("model", None, &avocado),
            ("bin", Some("Avocado.bin"), &avocado_bin),
        ]),
    );
    let sparse = fixture("SimpleSparseAccessor/SimpleSparseAccessor.gltf");
    let sparse_bin = fixture("SimpleSparseAccessor/SimpleSparseAccessor.bin");
    write(
        "parts",
        "sparse_first_field",
        &parts(&[
            ("first", None, &sparse),
            ("SimpleSparseAccessor.bin", None, &sparse_bin),
        ]),
    );
    let obj = fixture("concave_polygon/concave_polygon.obj");
    let mtl = fixture("concave_polygon/concave_polygon.mtl");
    write(
        "parts",
        "obj_mtl",
        &parts(&[
            ("mtl", Some("concave_polygon.mtl"), &mtl),
            ("file", Some("concave_polygon.obj"), &obj),
        ]),
    );
    write(
        "parts",
        "glb_with_image",
        &parts(&[
            ("file", Some("scene.glb"), &meshopt_quad()),
            ("image", Some("normal.png"), &png),
        ]),
    );
    write(
        "parts",
        "declared_gltf_is_glb",
        &parts(&[("file", Some("scene.gltf"), &fixture("Box/Box.glb"))]),
    );

    for (name, bytes) in core_seeds() {
        write("core", name, &bytes);
    }
}

/// Seeds for the `draco` target: every Draco primitive of `fixtures/compressed/`, as the header
/// [`fuzz_targets::draco`] reads (its POSITION, NORMAL and TEXCOORD_0 ids, the declared vertex
/// and triangle counts, u16 or u32 indices) and its stream. `cargo test --release --test fuzz_replay -- --ignored
/// make_draco_seeds`.
#[test]
#[ignore]
fn make_draco_seeds() {
    let dir = fuzz_dir().join("seeds/draco");
    std::fs::create_dir_all(&dir).unwrap();
    let compressed = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/compressed");
    for path in files_in(&compressed) {
        if path.extension().is_none_or(|e| e != "glb") {
            continue;
        }
        let bytes = std::fs::read(&path).unwrap();
        let parsed = glb::parse(&bytes).unwrap();
        let doc: Value = serde_json::from_slice(parsed.json).unwrap();
        let bin = parsed.bin.unwrap_or_default();
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        for (m, mesh) in doc["meshes"].as_array().into_iter().flatten().enumerate() {
            for (p, primitive) in mesh["primitives"].as_array().unwrap().iter().enumerate() {
                let ext = &primitive["extensions"]["KHR_draco_mesh_compression"];
                if !ext.is_object() {
                    continue;
                }
                let id = |semantic: &str| {
                    ext["attributes"][semantic]
                        .as_u64()
                        .map_or(0xFF, |i| i as u8)
                };
                let accessor = |i: &Value| &doc["accessors"][i.as_u64().unwrap() as usize];
                let position = accessor(&primitive["attributes"]["POSITION"]);
                let count = position["count"].as_u64().unwrap() as u16;
                let normal_i8 = primitive["attributes"]["NORMAL"].is_u64()
                    && accessor(&primitive["attributes"]["NORMAL"])["componentType"] == 5120;
                let uv = &primitive["attributes"]["TEXCOORD_0"];
                let uv_type = match uv.is_u64().then(|| accessor(uv)["componentType"].as_u64()) {
                    Some(Some(5123)) => 1u8,
                    Some(Some(5121)) => 2,
                    Some(Some(5122)) => 3,
                    _ => 0,
                };
                let indices = primitive["indices"].is_u64();
                let u32_indices =
                    indices && accessor(&primitive["indices"])["componentType"] == 5125;
                let flags =
                    u8::from(indices) | u8::from(u32_indices) << 1 | u8::from(normal_i8) << 2;
                let [lo, hi] = count.to_le_bytes();
                let triangles = if indices {
                    (accessor(&primitive["indices"])["count"].as_u64().unwrap() / 3) as u16
                } else {
                    0
                };
                let [t_lo, t_hi] = triangles.to_le_bytes();
                let mut seed = vec![
                    id("POSITION"),
                    id("NORMAL"),
                    id("TEXCOORD_0"),
                    uv_type,
                    lo,
                    hi,
                    flags,
                    t_lo,
                    t_hi,
                ];
                let view = &doc["bufferViews"][ext["bufferView"].as_u64().unwrap() as usize];
                let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
                let end = start + view["byteLength"].as_u64().unwrap() as usize;
                seed.extend_from_slice(&bin[start..end]);
                std::fs::write(dir.join(format!("{stem}_m{m}p{p}")), seed).unwrap();
            }
        }
    }
}
