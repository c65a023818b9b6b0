//! UV-layout pictures on whole scenes: the legend's counts are the report's, a 2M-triangle mesh
//! gives a bounded SVG that still renders, and (where `../shared/corpus` is present) the real
//! assets the issue names draw with the counts their reports give.

use serde_json::Value;
use std::path::Path;
use tspace::scene::folder::Folder;
use tspace::scene::input::{self, InputKind};
use tspace::scene::layout::Layout;
use tspace::scene::pictures::{self, PictureFormat, Selection, Subject};
use tspace::scene::{Processed, SceneOptions};
use tspace_testkit::glb_builder::shape_glb;
use tspace_testkit::shapes::uv_sphere;

/// The largest SVG a panel may make, whatever its mesh: the grid's rows of runs are bounded by
/// the grid, and a sphere's runs are few.
const SPHERE_SVG_BOUND: usize = 256 * 1024;

/// With `TSPACE_PICTURES_OUT=<dir>`, the pictures the tests draw are written there to be looked
/// at.
fn keep(name: &str, bytes: &[u8]) {
    if let Ok(dir) = std::env::var("TSPACE_PICTURES_OUT") {
        let _ = std::fs::create_dir_all(&dir);
        let _ = std::fs::write(Path::new(&dir).join(name), bytes);
    }
}

fn drawn(kind: InputKind, bytes: &[u8], folder: Option<&Path>) -> Processed {
    let options = SceneOptions {
        layouts: true,
        write: false,
        ..SceneOptions::default()
    };
    match folder {
        Some(folder) => {
            let folder = Folder::of_file(folder, 1 << 30);
            input::process(kind, bytes, &folder, &options).unwrap()
        }
        None => input::process(
            kind,
            bytes,
            &tspace::scene::gltf::load::NoResources,
            &options,
        )
        .unwrap(),
    }
}

fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Every count the legend gives, checked against the report of the primitive it draws.
fn assert_legend_matches_report(svg: &str, layout: &Layout, report: &Value) {
    let first = &layout.primitives[0];
    let primitive = report["primitives"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["mesh"] == first.mesh && p["primitive"] == first.primitive)
        .unwrap();
    let d = &primitive["diagnostics"];
    let count = |name: &str| d[name]["count"].as_u64().unwrap();
    let noun = |n: u64, one: &str, many: &str| {
        if n == 1 {
            format!("{n} {one}")
        } else {
            format!("{} {many}", thousands(n))
        }
    };
    let expected = [
        format!(
            "mirrored UVs: {} (",
            noun(count("mirrored_uv_triangles"), "triangle", "triangles")
        ),
        format!(
            "zero UV area: {} (",
            noun(count("zero_uv_area_triangles"), "triangle", "triangles")
        ),
        format!(
            "degenerate (ringed): {} with a duplicate position, {} with no area, {} non-finite",
            noun(
                count("duplicate_position_triangles"),
                "triangle",
                "triangles"
            ),
            thousands(count("zero_area_triangles")),
            thousands(count("non_finite_triangles"))
        ),
        format!(
            "repaired tangents: {} in",
            noun(count("fallback_tangents"), "corner", "corners")
        ),
        format!(
            "handedness flips: {} (",
            noun(count("handedness_flip_vertices"), "vertex", "vertices")
        ),
    ];
    for line in expected {
        assert!(svg.contains(&line), "{line:?} not in the legend");
    }
    assert_eq!(
        d["triangles"].as_u64().unwrap(),
        layout.triangle_count() as u64
    );
}

#[test]
fn a_two_million_triangle_sphere_gives_a_bounded_svg_that_renders() {
    let sphere = uv_sphere(1000, 1001);
    assert_eq!(sphere.triangle_count(), 2_000_000);
    let processed = drawn(InputKind::Glb, &shape_glb(&sphere), None);
    let layout = &processed.layouts[0];
    let subject = Subject { file: "sphere.glb" };
    let svg = pictures::svg(&subject, &processed.layouts);
    assert!(
        svg.len() < SPHERE_SVG_BOUND,
        "the SVG has {} bytes",
        svg.len()
    );
    assert!(svg.contains("drawn on a 1024×1024 grid"));
    let report = serde_json::to_value(&processed.report).unwrap();
    assert_legend_matches_report(&svg, layout, &report);
    let png = pictures::png(&svg).unwrap();
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"));
    keep("sphere-2M.svg", svg.as_bytes());
    keep("sphere-2M.png", &png);
    eprintln!(
        "2M-triangle sphere: SVG {} bytes, PNG {} bytes",
        svg.len(),
        png.len()
    );
}

#[test]
fn shared_geometry_is_one_panel_and_a_selection_picks_it() {
    let bytes = tspace_testkit::fixture("NormalTangentMirrorTest/NormalTangentMirrorTest.gltf");
    let folder = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/NormalTangentMirrorTest/NormalTangentMirrorTest.gltf");
    let processed = drawn(InputKind::Gltf, &bytes, Some(&folder));
    assert_eq!(processed.layouts.len(), 1);
    let report = serde_json::to_value(&processed.report).unwrap();
    let svg = pictures::svg(&Subject { file: "mirror" }, &processed.layouts);
    assert_legend_matches_report(&svg, &processed.layouts[0], &report);
    let by_index = Selection::parse(Some("0"), Some("0")).unwrap();
    let by_name = Selection::parse(Some("NormalTangentTest_low"), None).unwrap();
    for selection in [by_index, by_name] {
        let picture = pictures::draw(
            &Subject { file: "mirror" },
            &processed.layouts,
            &selection,
            PictureFormat::Svg,
        )
        .unwrap();
        assert!(picture.starts_with(b"<svg "));
    }
    let none = Selection::parse(Some("no such mesh"), None).unwrap();
    let refused = pictures::draw(
        &Subject { file: "mirror" },
        &processed.layouts,
        &none,
        PictureFormat::Svg,
    )
    .unwrap_err();
    assert_eq!(
        refused.code,
        tspace::scene::error::ProblemCode::NothingToDraw
    );
}

/// The corpus assets the issue names, where `../shared/corpus` is present.
#[test]
fn corpus_assets_draw_with_their_reports_counts() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    let assets = [
        "gltf_DamagedHelmet/glTF-Binary/DamagedHelmet.glb",
        "gltf_SciFiHelmet_no_images/SciFiHelmet.gltf",
        "obj_spot/spot_triangulated.obj",
    ];
    for asset in assets {
        let path = corpus.join(asset);
        let Ok(bytes) = std::fs::read(&path) else {
            eprintln!("skipped: {asset} is not in ../shared/corpus");
            continue;
        };
        let kind = InputKind::from_file_name(asset).unwrap();
        let processed = drawn(kind, &bytes, Some(&path));
        let report = serde_json::to_value(&processed.report).unwrap();
        assert!(!processed.layouts.is_empty(), "{asset}");
        let svg = pictures::svg(&Subject { file: asset }, &processed.layouts);
        for layout in processed.layouts.iter().take(pictures::MAX_PANELS) {
            assert_legend_matches_report(&svg, layout, &report);
        }
        let png = pictures::png(&svg).unwrap();
        let name = Path::new(asset).file_stem().unwrap().to_string_lossy();
        keep(&format!("{name}.svg"), svg.as_bytes());
        keep(&format!("{name}.png"), &png);
    }
}

/// Hostile texture coordinates and a mesh name made of markup: the picture is still drawn, the
/// name shows as text, and the legend counts what the report counts.
#[test]
fn hostile_uvs_and_names_are_drawn_safely() {
    let mut sphere = uv_sphere(12, 8);
    sphere.name = "<script>alert(1)</script>\u{0007}".into();
    sphere.uvs[3] = [f32::NAN, 0.5];
    sphere.uvs[10] = [f32::INFINITY, f32::NEG_INFINITY];
    sphere.uvs[20] = [1e30, -1e30];
    let processed = drawn(InputKind::Glb, &shape_glb(&sphere), None);
    let svg = pictures::svg(&Subject { file: "a&b\".glb" }, &processed.layouts);
    assert!(!svg.contains("<script>"));
    assert!(svg.contains("&lt;script&gt;alert(1)&lt;/script&gt;"));
    assert!(!svg.contains('\u{0007}'));
    assert!(svg.contains("a&amp;b&quot;.glb"));
    assert!(
        svg.contains("are cut off"),
        "UVs at 1e30 are beyond the tiles drawn"
    );
    let report = serde_json::to_value(&processed.report).unwrap();
    assert_legend_matches_report(&svg, &processed.layouts[0], &report);
    assert!(pictures::png(&svg).is_ok());
}
