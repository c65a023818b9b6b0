//! OBJ-to-glTF conversion (`tspace::scene::obj_gltf`) checked by the Khronos glTF-Validator: the
//! converted fixtures and a synthetic OBJ exercising every material mapping have no errors, the
//! URIs of images not supplied are well-formed, and a converted OBJ run through the glTF
//! pipeline still validates. Every test skips (one line on stderr) where Node.js or npm is
//! missing.

// common/mod.rs re-exports helpers this binary does not use.
#[allow(unused_imports)]
use std::path::Path;

use tspace::scene::SceneOptions;
use tspace::scene::gltf::glb;
use tspace::scene::gltf::process;
use tspace::scene::obj::{Limits, parse_mtl, parse_obj};
use tspace::scene::obj_gltf::{ConvertLimits, Converted, NormalRequest, obj_to_gltf};
use tspace::scene::uri::PartSet;
use tspace_testkit::validator::{ValidatorReport, validate};

/// A 4x4 red RGB PNG (stored with correct CRCs, so the validator reads its header).
const PNG: &[u8] =
    b"\x89\x50\x4e\x47\x0d\x0a\x1a\x0a\x00\x00\x00\x0d\x49\x48\x44\x52\x00\x00\x00\x04\
\x00\x00\x00\x04\x08\x02\x00\x00\x00\x26\x93\x09\x29\x00\x00\x00\x10\x49\x44\x41\x54\x78\x9c\x63\
\xf8\xcf\xc0\x00\x47\x0c\xc4\x71\x00\xae\x93\x0f\xf1\xd0\x5f\x23\x9e\x00\x00\x00\x00\x49\x45\x4e\
\x44\xae\x42\x60\x82";

/// An 8x8 grey baseline JPEG: JFIF, an all-ones quantization table, one-symbol Huffman tables,
/// and one block coded as "DC difference 0, end of block".
const JPEG: &[u8] = b"\xff\xd8\xff\xe0\x00\x10\x4a\x46\x49\x46\x00\x01\x01\x00\x00\x01\x00\x01\x00\
\x00\xff\xdb\x00\x43\x00\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\
\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\
\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\x01\xff\xc0\
\x00\x0b\x08\x00\x08\x00\x08\x01\x01\x11\x00\xff\xc4\x00\x14\x00\x01\x00\x00\x00\x00\x00\x00\x00\
\x00\x00\x00\x00\x00\x00\x00\x00\x00\xff\xc4\x00\x14\x10\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00\
\x00\x00\x00\x00\x00\x00\x00\xff\xda\x00\x08\x01\x01\x00\x00\x3f\x00\x3f\xff\xd9";

/// The RIFF and VP8L headers of a 1x1 lossless WebP (what the validator reads).
const WEBP: &[u8] = b"RIFF\x14\x00\x00\x00WEBPVP8L\x08\x00\x00\x00\x2f\x00\x00\x00\x00\x00\x00\x00";

fn fixture(path: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fixtures")
            .join(path),
    )
    .unwrap_or_else(|e| panic!("fixture {path}: {e}"))
}

fn convert(obj: &[u8], mtl: Option<&[u8]>, parts: &PartSet<'_>) -> Converted {
    let obj = parse_obj(obj, &Limits::default()).unwrap();
    let mtl = mtl.map(|m| parse_mtl(m).unwrap());
    obj_to_gltf(
        &obj,
        mtl.as_ref(),
        parts,
        NormalRequest::default(),
        &ConvertLimits::default(),
    )
    .unwrap()
}

fn to_glb(c: &Converted) -> Vec<u8> {
    glb::write(c.json.as_bytes(), Some(&c.bin), &[]).unwrap()
}

/// No errors, and no warnings but the one every normal-mapped primitive without tangents gets
/// (the tangent step is what adds them).
fn assert_clean(report: &ValidatorReport) {
    assert_eq!(
        report.error_codes(),
        Vec::<&str>::new(),
        "{}",
        report.summary()
    );
    for code in report.warning_codes() {
        assert_eq!(
            code,
            "MESH_PRIMITIVE_GENERATED_TANGENT_SPACE",
            "{}",
            report.summary()
        );
    }
}

fn spider_parts() -> PartSet<'static> {
    let mut parts = PartSet::new();
    for name in [
        "wal67ar_small.jpg",
        "wal69ar_small.jpg",
        "SpiderTex.jpg",
        "drkwood2.jpg",
        "engineflare1.jpg",
    ] {
        parts.insert(name, JPEG).unwrap();
    }
    parts
}

/// Normal maps, `-o`/`-s`, `Ke` above 1, `d` below 1, clamped values, WebP, vertex colours, a
/// textured material on faces without UVs, a missing material and a zero normal.
const SYNTHETIC_OBJ: &str = "mtllib synthetic.mtl\n\
    v 0 0 0 1 0 0\nv 2 0 0 0 1 0\nv 2 1 0 0 0 2\nv 0 1 -1\n\
    vt 0 0\nvt 1 0\nvt 1 0.25\nvt 0 1\nvn 0 0 2\nvn 0 0 0\n\
    o first\nusemtl glass\nf 1/1/1 2/2/1 3/3/1 4/4/1\nf 1//1 2//1 3//1\n\
    o second\nusemtl bumpy\nf 1/1/1 3/3/1 4/4/1\nusemtl webp\nf 1/1 2/2 3/3\n\
    usemtl nowhere\nf 1 2 3\nusemtl bumpy\nf 1/1/2 2/2/1 3/3/1\n";

const SYNTHETIC_MTL: &str = "newmtl glass\nKd 0.1 0.2 0.3\nd 0.25\nPr 0.4\nPm 0.75\nKe 2 1 0.5\n\
    map_Kd -o 0.25 0.5 -s 2 3 textures/my diffuse.png\nnorm -bm 0.5 ..\\normals\\n.png\n\
    newmtl bumpy\nKs 0 0 0\nNs 500\nKd 2 -1 0.5\nmap_Bump -bm 2 bump.jpg\n\
    newmtl webp\nmap_Kd -s 2 2 w.webp\n";

#[test]
fn converted_fixtures_have_no_errors() {
    let spider = convert(
        &fixture("spider/spider.obj"),
        Some(&fixture("spider/spider.mtl")),
        &spider_parts(),
    );
    assert_eq!(spider.stats.images_embedded, 4);
    let concave = convert(
        &fixture("concave_polygon/concave_polygon.obj"),
        Some(&fixture("concave_polygon/concave_polygon.mtl")),
        &PartSet::new(),
    );
    let negative = convert(
        &fixture("negative_indices/negative_indices.obj"),
        None,
        &PartSet::new(),
    );
    // NaN and infinite positions on some triangles (as in Draco's inf_nan.obj test file): the
    // validator rejects non-finite accessor values, so those triangles are dropped.
    let non_finite = convert(
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 1 1\nv 1 inf 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
          f 1/1 2/2 3/3\nf 2/2 3/3 4/1\nf 1/1 5/2 3/3\n",
        None,
        &PartSet::new(),
    );
    assert_eq!(non_finite.stats.triangles, 1);
    for (name, converted) in [
        ("spider.glb", &spider),
        ("concave_polygon.glb", &concave),
        ("negative_indices.glb", &negative),
        ("non_finite.glb", &non_finite),
    ] {
        let Some(report) = validate(name, &to_glb(converted)) else {
            return;
        };
        assert_clean(&report);
    }
}

#[test]
fn every_material_mapping_validates() {
    let mut parts = PartSet::new();
    parts.insert("my diffuse.png", PNG).unwrap();
    parts.insert("n.png", PNG).unwrap();
    parts.insert("bump.jpg", JPEG).unwrap();
    parts.insert("w.webp", WEBP).unwrap();
    let c = convert(
        SYNTHETIC_OBJ.as_bytes(),
        Some(SYNTHETIC_MTL.as_bytes()),
        &parts,
    );
    assert_eq!(c.stats.images_embedded, 4);
    for extension in [
        "KHR_materials_emissive_strength",
        "KHR_texture_transform",
        "EXT_texture_webp",
    ] {
        assert!(c.json.contains(extension), "{extension}");
    }
    let Some(report) = validate("synthetic.glb", &to_glb(&c)) else {
        return;
    };
    assert_clean(&report);
    assert!(
        report.warning_codes().len() >= 2,
        "the normal-mapped primitives have no tangents yet: {}",
        report.summary()
    );
}

#[test]
fn images_not_supplied_are_well_formed_relative_uris() {
    let c = convert(
        SYNTHETIC_OBJ.as_bytes(),
        Some(SYNTHETIC_MTL.as_bytes()),
        &PartSet::new(),
    );
    assert!(c.json.contains("\"uri\":\"textures/my%20diffuse.png\""));
    let Some(report) = validate("synthetic.glb", &to_glb(&c)) else {
        return;
    };
    // Input from memory has no folder, so the validator cannot load any of the four images:
    // one IO_ERROR each, and nothing else (in particular no INVALID_URI).
    assert_eq!(
        report.error_codes(),
        ["IO_ERROR"; 4],
        "{}",
        report.summary()
    );
    for m in &report.messages {
        if m.code == "IO_ERROR" {
            let pointer = m.pointer.as_deref().unwrap_or("");
            assert!(
                pointer.starts_with("/images/") && pointer.ends_with("/uri"),
                "{pointer}"
            );
        }
    }
}

#[test]
fn converted_obj_through_the_glb_pipeline_still_validates() {
    let spider = convert(
        &fixture("spider/spider.obj"),
        Some(&fixture("spider/spider.mtl")),
        &spider_parts(),
    );
    let mut synthetic_parts = PartSet::new();
    synthetic_parts.insert("my diffuse.png", PNG).unwrap();
    synthetic_parts.insert("n.png", PNG).unwrap();
    synthetic_parts.insert("bump.jpg", JPEG).unwrap();
    synthetic_parts.insert("w.webp", WEBP).unwrap();
    let synthetic = convert(
        SYNTHETIC_OBJ.as_bytes(),
        Some(SYNTHETIC_MTL.as_bytes()),
        &synthetic_parts,
    );
    for (name, converted, all) in [("spider", &spider, true), ("synthetic", &synthetic, false)] {
        let input = to_glb(converted);
        let options = SceneOptions {
            all,
            ..SceneOptions::default()
        };
        let processed =
            process(&input, &PartSet::new(), &options).unwrap_or_else(|e| panic!("{name}: {e}"));
        let output = processed.bytes.expect("written");
        // The `gltf` crate cannot read a file requiring EXT_texture_webp: read the JSON.
        let json: serde_json::Value =
            serde_json::from_slice(glb::parse(&output).expect("a GLB").json).expect("JSON");
        let materials = json["materials"].as_array().cloned().unwrap_or_default();
        for (m, mesh) in json["meshes"].as_array().unwrap().iter().enumerate() {
            for primitive in mesh["primitives"].as_array().unwrap() {
                let mapped = primitive["material"]
                    .as_u64()
                    .is_some_and(|i| materials[i as usize].get("normalTexture").is_some());
                assert_eq!(
                    primitive["attributes"].get("TANGENT").is_some(),
                    all || mapped,
                    "{name}: mesh {m}: {primitive}"
                );
            }
        }
        let Some(report) = validate(&format!("{name}.processed.glb"), &output) else {
            return;
        };
        assert_eq!(
            report.error_codes(),
            Vec::<&str>::new(),
            "{}",
            report.summary()
        );
        assert_eq!(
            report.warning_codes(),
            Vec::<&str>::new(),
            "{}",
            report.summary()
        );
    }
}

/// Generated normals validate in every mode (unit length, one per vertex), for smoothing
/// groups and for an OBJ without any.
#[test]
fn generated_normals_validate_in_every_mode() {
    use tspace::scene::Normals;
    let groups = fixture("smoothing_groups/smoothing_groups.obj");
    // A cube without `s` or `vn`.
    let none = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n\
                 f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n"
        .to_vec();
    for normals in Normals::ALL.iter().copied() {
        for (name, text) in [("smoothing_groups", &groups), ("no_groups", &none)] {
            let obj = parse_obj(text, &Limits::default()).unwrap();
            let request = NormalRequest {
                normals,
                ..NormalRequest::default()
            };
            let c = obj_to_gltf(
                &obj,
                None,
                &PartSet::new(),
                request,
                &ConvertLimits::default(),
            )
            .unwrap();
            assert!(c.json.contains("\"NORMAL\""), "{name}");
            let Some(report) = validate(&format!("{name}-{}.glb", normals.name()), &to_glb(&c))
            else {
                return;
            };
            assert_clean(&report);
        }
    }
}
