//! `debug=colors` end to end: the debug scene read back with an independent reader (the `gltf`
//! crate) against the scene written without it. Every corner keeps its position, UV, normal and
//! tangent; every triangle has one colour, the colour of its class; the colours' counts are the
//! report's; kept tangents stay the file's; the output passes the glTF-Validator.

use serde_json::Value;
use std::collections::BTreeMap;
use tspace::scene::folder::Folder;
use tspace::scene::gltf::load::{NoResources, Resources};
use tspace::scene::gltf::process;
use tspace::scene::input::{self, InputKind};
use tspace::scene::options::Debug;
use tspace::scene::uri::PartSet;
use tspace::scene::{Processed, SceneOptions};
use tspace_testkit::{assert_valid_output, fixture, glb_json};

/// One primitive as the `gltf` crate reads it, corner by corner.
#[derive(Debug, Default)]
struct Corners {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    tangents: Vec<[f32; 4]>,
    colors: Vec<[f32; 3]>,
}

fn read_corners(bytes: &[u8]) -> Vec<Corners> {
    let gltf = gltf::Gltf::from_slice(bytes).expect("the gltf crate reads the output");
    let blob = gltf.blob.clone().unwrap_or_default();
    let mut out = Vec::new();
    for mesh in gltf.document.meshes() {
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|_| Some(&blob[..]));
            let Some(positions) = reader.read_positions() else {
                out.push(Corners::default());
                continue;
            };
            let positions: Vec<[f32; 3]> = positions.collect();
            let order: Vec<usize> = match reader.read_indices() {
                Some(indices) => indices.into_u32().map(|i| i as usize).collect(),
                None => (0..positions.len()).collect(),
            };
            out.push(Corners {
                normals: per_corner(
                    &order,
                    reader.read_normals().map_or(Vec::new(), Iterator::collect),
                ),
                uvs: per_corner(
                    &order,
                    reader
                        .read_tex_coords(0)
                        .map_or(Vec::new(), |t| t.into_f32().collect()),
                ),
                tangents: per_corner(
                    &order,
                    reader.read_tangents().map_or(Vec::new(), Iterator::collect),
                ),
                colors: per_corner(
                    &order,
                    reader
                        .read_colors(0)
                        .map_or(Vec::new(), |c| c.into_rgb_f32().collect()),
                ),
                positions: per_corner(&order, positions),
            });
        }
    }
    out
}

fn per_corner<T: Copy>(order: &[usize], values: Vec<T>) -> Vec<T> {
    if values.is_empty() {
        return values;
    }
    order.iter().map(|&v| values[v]).collect()
}

fn debug_colors(options: SceneOptions) -> SceneOptions {
    SceneOptions {
        debug: Debug::Colors,
        ..options
    }
}

fn run<'a>(bytes: &'a [u8], resources: &dyn Resources<'a>, options: &SceneOptions) -> Processed {
    process(bytes, resources, options).unwrap_or_else(|e| panic!("{e}"))
}

/// The report's colours: `#rrggbb` → (class, triangles).
fn report_classes(processed: &Processed) -> BTreeMap<String, (String, u64)> {
    let report: Value = serde_json::from_str(&processed.report.to_json_pretty()).unwrap();
    report["debug_colors"]["classes"]
        .as_array()
        .expect("debug_colors.classes")
        .iter()
        .map(|c| {
            (
                c["color"].as_str().unwrap().to_owned(),
                (
                    c["class"].as_str().unwrap().to_owned(),
                    c["triangles"].as_u64().unwrap(),
                ),
            )
        })
        .collect()
}

/// A linear COLOR_0 as the report's sRGB `#rrggbb`.
fn hex_of(linear: [f32; 3]) -> String {
    let srgb = linear.map(|c| {
        let s = if c <= 0.003_130_8 {
            c * 12.92
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as u8
    });
    format!("#{:02x}{:02x}{:02x}", srgb[0], srgb[1], srgb[2])
}

/// Checks the debug scene against the plain one, corner by corner, and the colour counts
/// against the report; returns the class of every triangle, per primitive.
fn check_against_plain(name: &str, plain: &[u8], painted: &Processed) -> Vec<Vec<String>> {
    let debug_bytes = painted.bytes.as_deref().expect("written");
    assert_valid_output(name, debug_bytes);
    let classes = report_classes(painted);
    let plain = read_corners(plain);
    let debug = read_corners(debug_bytes);
    assert_eq!(plain.len(), debug.len());
    let mut counted: BTreeMap<String, u64> = BTreeMap::new();
    let mut per_primitive = Vec::new();
    for (p, (a, b)) in plain.iter().zip(&debug).enumerate() {
        assert_eq!(a.positions, b.positions, "{name} primitive {p}: positions");
        assert_eq!(a.normals, b.normals, "{name} primitive {p}: normals");
        assert_eq!(a.uvs, b.uvs, "{name} primitive {p}: uvs");
        assert_eq!(a.tangents, b.tangents, "{name} primitive {p}: tangents");
        let mut triangle_classes = Vec::new();
        for (t, corners) in b.colors.chunks_exact(3).enumerate() {
            assert!(
                corners[0] == corners[1] && corners[1] == corners[2],
                "{name} primitive {p} triangle {t}: corners of different colours"
            );
            let hex = hex_of(corners[0]);
            let Some((class, _)) = classes.get(&hex) else {
                panic!("{name} primitive {p} triangle {t}: {hex} is no class's colour");
            };
            *counted.entry(hex).or_default() += 1;
            triangle_classes.push(class.clone());
        }
        per_primitive.push(triangle_classes);
    }
    for (hex, (class, triangles)) in &classes {
        assert_eq!(
            counted.get(hex).copied().unwrap_or(0),
            *triangles,
            "{name}: {class} triangles"
        );
    }
    per_primitive
}

fn mirror_test() -> (Vec<u8>, Vec<u8>) {
    (
        fixture("NormalTangentMirrorTest/NormalTangentMirrorTest.gltf"),
        fixture("NormalTangentMirrorTest/NormalTangentMirrorTest.bin"),
    )
}

/// Generated tangents: mirrored triangles are the ones whose UVs wind the other way, found
/// here from the UVs alone; the rest are ordinary.
#[test]
fn generated_tangents_paint_mirrored_triangles_by_their_uv_winding() {
    let (gltf, bin) = mirror_test();
    let mut parts = PartSet::new();
    parts.insert("NormalTangentMirrorTest.bin", &bin).unwrap();
    let options = SceneOptions {
        overwrite: true,
        ..SceneOptions::default()
    };
    let plain = run(&gltf, &parts, &options);
    let painted = run(&gltf, &parts, &debug_colors(options));
    let plain_bytes = plain.bytes.as_deref().unwrap();
    let classes = check_against_plain("mirror", plain_bytes, &painted);
    let debug = read_corners(painted.bytes.as_deref().unwrap());
    let mut mirrored = 0;
    for (corners, classes) in debug.iter().zip(&classes) {
        for (t, class) in classes.iter().enumerate() {
            let uv = &corners.uvs[3 * t..3 * t + 3];
            let d1 = [uv[1][0] - uv[0][0], uv[1][1] - uv[0][1]];
            let d2 = [uv[2][0] - uv[0][0], uv[2][1] - uv[0][1]];
            // v runs down in glTF: an unmirrored front face has a negative raw UV area.
            let expected = if d1[0] * d2[1] - d1[1] * d2[0] > 0.0 {
                mirrored += 1;
                "mirrored_uv"
            } else {
                "ordinary"
            };
            assert_eq!(class, expected, "triangle {t}");
        }
    }
    assert!(mirrored > 0, "the fixture has mirrored triangles");

    // What the debug scene says of itself: the unlit material, listed, on every primitive;
    // the original material still there; the report's finding and note.
    let json = glb_json(painted.bytes.as_deref().unwrap());
    let materials = json["materials"].as_array().unwrap();
    let input: Value = serde_json::from_slice(&gltf).unwrap();
    let before = input["materials"].as_array().unwrap();
    assert_eq!(materials.len(), before.len() + 1);
    assert_eq!(&materials[..before.len()], &before[..]);
    let debug_material = &materials[before.len()];
    assert!(debug_material["extensions"]["KHR_materials_unlit"].is_object());
    let used = json["extensionsUsed"].as_array().unwrap();
    assert!(used.iter().any(|e| e == "KHR_materials_unlit"));
    assert!(
        json.get("extensionsRequired")
            .and_then(Value::as_array)
            .is_none_or(|r| !r.iter().any(|e| e == "KHR_materials_unlit"))
    );
    for primitive in json["meshes"][0]["primitives"].as_array().unwrap() {
        assert_eq!(primitive["material"], before.len());
    }
    let report = &painted.report;
    let debug = report.debug_colors.as_ref().expect("debug_colors");
    assert_eq!(debug.material, Some(before.len()));
    assert!(
        report
            .findings
            .iter()
            .any(|f| f.code == "debug_colors" && f.message.contains("not for shipping"))
    );
    assert!(
        report.primitives[0]
            .notes
            .iter()
            .any(|n| n.contains("material 0") && n.contains("replaced"))
    );
    assert!(plain.report.debug_colors.is_none());
}

/// Kept tangents are audited and painted, and stay the file's own, corner by corner.
#[test]
fn kept_tangents_are_painted_and_stay_the_files() {
    let (gltf, bin) = mirror_test();
    let mut parts = PartSet::new();
    parts.insert("NormalTangentMirrorTest.bin", &bin).unwrap();
    let plain = run(&gltf, &parts, &SceneOptions::default());
    let painted = run(&gltf, &parts, &debug_colors(SceneOptions::default()));
    assert_eq!(painted.report.summary.audited, 1);
    let classes = check_against_plain("mirror kept", plain.bytes.as_deref().unwrap(), &painted);
    assert!(classes[0].iter().any(|c| c == "mirrored_uv"));
}

/// A Draco scene with every class: degenerate, zero-UV, repaired, mirrored and ordinary
/// triangles, vertices added where classes meet, shared between primitives.
#[test]
fn every_class_of_a_draco_scene_is_painted_as_counted() {
    let glb = fixture("compressed/Lantern_draco_sequential.glb");
    // Overwritten, so that the plain output is decoded too (kept tangents would keep Draco).
    let options = SceneOptions {
        all: true,
        overwrite: true,
        ..SceneOptions::default()
    };
    let plain = run(&glb, &NoResources, &options);
    let painted = run(&glb, &NoResources, &debug_colors(options));
    let classes = check_against_plain("lantern", plain.bytes.as_deref().unwrap(), &painted);
    let debug = painted.report.debug_colors.as_ref().unwrap();
    assert!(debug.vertices_added > 0);
    for class in debug.classes.iter() {
        assert!(class.triangles > 0, "{} has triangles", class.class);
        assert!(classes.iter().flatten().any(|c| c == class.class));
    }
    let json = glb_json(painted.bytes.as_deref().unwrap());
    assert!(json.get("extensionsRequired").is_none(), "Draco is gone");
    let used = json["extensionsUsed"].as_array().unwrap();
    assert_eq!(used, &[Value::from("KHR_materials_unlit")]);
}

/// Nothing computed, nothing painted: the scene comes back as it would without the option.
#[test]
fn a_scene_without_computed_primitives_is_not_touched() {
    let glb = fixture("Box/Box.glb");
    let painted = run(&glb, &NoResources, &debug_colors(SceneOptions::default()));
    assert_eq!(painted.bytes.as_deref(), Some(&glb[..]));
    let debug = painted.report.debug_colors.as_ref().unwrap();
    assert_eq!((debug.primitives, debug.material), (0, None));
}

/// Meshopt-compressed output carries COLOR_0 compressed like the rest.
#[test]
fn compressed_output_is_painted_too() {
    let glb = fixture("compressed/WaterBottle_draco.glb");
    let options = SceneOptions {
        all: true,
        compress: tspace::scene::options::Compression::Meshopt,
        ..SceneOptions::default()
    };
    let painted = run(&glb, &NoResources, &debug_colors(options));
    let bytes = painted.bytes.as_deref().unwrap();
    assert_valid_output("bottle meshopt debug", bytes);
    let json = glb_json(bytes);
    let color = json["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"]
        .as_u64()
        .unwrap() as usize;
    let view = json["accessors"][color]["bufferView"].as_u64().unwrap() as usize;
    assert!(json["bufferViews"][view]["extensions"]["EXT_meshopt_compression"].is_object());
}

/// The corpus assets the issue names, where `../shared/corpus` is present: painted with the
/// report's counts, the same corners as the plain output, and valid.
#[test]
fn corpus_assets_are_painted_as_their_reports_count() {
    let corpus = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    for asset in [
        "gltf_DamagedHelmet/glTF-Binary/DamagedHelmet.glb",
        "gltf_SciFiHelmet_no_images/SciFiHelmet.gltf",
        "obj_spot/spot_triangulated.obj",
    ] {
        let path = corpus.join(asset);
        let Ok(bytes) = std::fs::read(&path) else {
            eprintln!("skipped: {asset} is not in ../shared/corpus");
            continue;
        };
        let kind = InputKind::from_file_name(asset).unwrap();
        let folder = Folder::of_file(&path, 1 << 30);
        let processed = |options: &SceneOptions| {
            input::process(kind, &bytes, &folder, options).unwrap_or_else(|e| panic!("{e}"))
        };
        let plain = processed(&SceneOptions::default());
        let painted = processed(&debug_colors(SceneOptions::default()));
        let classes = check_against_plain(asset, plain.bytes.as_deref().unwrap(), &painted);
        let summary = &painted.report.summary;
        let count = |name: &str| classes.iter().flatten().filter(|c| *c == name).count() as u64;
        assert_eq!(
            count("mirrored_uv") > 0,
            summary.mirrored_uv_triangles > 0,
            "{asset}"
        );
        assert!(
            count("degenerate") <= summary.degenerate_triangles,
            "{asset}: degenerate"
        );
        assert!(
            count("zero_uv_area") <= summary.zero_uv_area_triangles,
            "{asset}: zero UV area"
        );
    }
}
