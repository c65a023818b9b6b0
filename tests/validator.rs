//! The Khronos glTF-Validator harness (`tspace_testkit::validator`): the fixtures pass it with a
//! known baseline, and it does catch broken files. Every test skips (one line on stderr) where
//! Node.js or npm is missing.

// common/mod.rs re-exports helpers this binary does not use.
#[allow(unused_imports)]
use std::path::{Path, PathBuf};

use tspace_testkit::validator::{Severity, ValidatorReport, validate, validate_file};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures")
}

/// Every glTF/GLB fixture with the errors it is known to have besides missing images.
///
/// fixtures/README.md: the texture images are deliberately not copied, so each image a file
/// references is an `IO_ERROR` at `/images/N/uri`; [`is_missing_image`] accounts for those.
const FIXTURES: &[(&str, &[&str])] = &[
    ("Avocado/Avocado.gltf", &[]),
    ("Box/Box.glb", &[]),
    ("BoxTextured_embedded/BoxTextured.gltf", &[]),
    ("Lantern/Lantern.gltf", &[]),
    ("MultiUVTest/MultiUVTest.gltf", &[]),
    ("NormalTangentMirrorTest/NormalTangentMirrorTest.gltf", &[]),
    ("SimpleSparseAccessor/SimpleSparseAccessor.gltf", &[]),
    ("WaterBottle/WaterBottle.gltf", &[]),
    // The assimp test file packs SHORT VEC3 positions at a 6-byte stride; glTF wants vertex
    // attributes aligned to 4 bytes. A real defect of the upstream file, kept as a baseline.
    (
        "quantized_triangle/triangle_mesh_quantized.gltf",
        &["MESH_PRIMITIVE_ACCESSOR_UNALIGNED"],
    ),
    // Made with the peers' own tools (fixtures/compressed/README.md): all clean but for absent
    // images, which the baseline leaves out.
    ("compressed/Box_draco_edgebreaker.glb", &[]),
    ("compressed/Box_draco_sequential.glb", &[]),
    ("compressed/Box_gltf_transform_meshopt.glb", &[]),
    ("compressed/Lantern_draco_sequential.glb", &[]),
    ("compressed/MorphPrimitivesTest_draco.glb", &[]),
    ("compressed/MorphPrimitivesTest_gltfpack_quantized.glb", &[]),
    ("compressed/MultiUVTest_draco.glb", &[]),
    ("compressed/WaterBottle_draco.glb", &[]),
    ("compressed/WaterBottle_draco_qlow.glb", &[]),
    ("compressed/WaterBottle_draco_sequential_q16.glb", &[]),
    ("compressed/WaterBottle_draco_speed0.glb", &[]),
    ("compressed/WaterBottle_gltfpack_cc.glb", &[]),
    ("compressed/WaterBottle_gltfpack_quantized.glb", &[]),
    ("compressed/triangle_quantized_draco.glb", &[]),
];

/// An `IO_ERROR` for an image file that is not on disk (the fixtures ship no images).
fn is_missing_image(m: &tspace_testkit::validator::ValidatorMessage) -> bool {
    m.severity == Severity::Error
        && m.code == "IO_ERROR"
        && m.pointer.as_deref().is_some_and(|p| {
            p.strip_prefix("/images/")
                .and_then(|rest| rest.strip_suffix("/uri"))
                .is_some_and(|n| n.parse::<u32>().is_ok())
        })
        && m.message.contains("ENOENT")
}

/// The fixtures' glTF/GLB files, found on disk (so a new fixture cannot be forgotten here).
fn fixture_files() -> Vec<String> {
    let root = fixtures();
    let mut out = Vec::new();
    for dir in std::fs::read_dir(&root).expect("fixtures/") {
        let dir = dir.unwrap().path();
        if !dir.is_dir() {
            continue;
        }
        for f in std::fs::read_dir(&dir).unwrap() {
            let f = f.unwrap().path();
            if matches!(f.extension().and_then(|e| e.to_str()), Some("gltf" | "glb")) {
                let rel = f.strip_prefix(&root).unwrap();
                out.push(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    out.sort();
    out
}

/// `["A", "B", "A"]` as `A x2, B`.
fn tally(codes: Vec<&str>) -> String {
    let mut counts = std::collections::BTreeMap::new();
    for c in codes {
        *counts.entry(c).or_insert(0) += 1;
    }
    let parts: Vec<String> = counts
        .into_iter()
        .map(|(c, n)| {
            if n == 1 {
                c.to_string()
            } else {
                format!("{c} x{n}")
            }
        })
        .collect();
    parts.join(", ")
}

#[test]
fn every_fixture_is_listed() {
    let mut listed: Vec<String> = FIXTURES.iter().map(|(f, _)| f.to_string()).collect();
    listed.sort();
    assert_eq!(fixture_files(), listed, "fixtures/ and FIXTURES disagree");
}

#[test]
fn fixtures_validate_with_their_baseline() {
    let mut failures = Vec::new();
    for &(rel, known_errors) in FIXTURES {
        let path = fixtures().join(rel);
        let Some(report) = validate_file(&path) else {
            return;
        };
        let missing_images = report
            .messages
            .iter()
            .filter(|m| is_missing_image(m))
            .count();
        let errors: Vec<&str> = report
            .messages_of(Severity::Error)
            .filter(|m| !is_missing_image(m))
            .map(|m| m.code.as_str())
            .collect();
        // The baseline, printed so a run shows it (cargo test -- --nocapture).
        println!(
            "{rel}: {} errors ({missing_images} missing images, other {errors:?}), \
             warnings [{}], infos [{}], hints [{}]",
            report.num_errors,
            tally(report.warning_codes()),
            tally(report.codes(Severity::Info)),
            tally(report.codes(Severity::Hint)),
        );
        assert!(!report.truncated, "{}", report.summary());
        assert_eq!(
            report.num_errors as usize,
            report.error_codes().len(),
            "{}",
            report.summary()
        );
        if errors != known_errors {
            failures.push(format!(
                "{rel}: expected errors {known_errors:?} besides missing images, got {errors:?}\n{}",
                report.summary()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The GLB's JSON chunk as a value, and its BIN chunk.
fn split_glb(glb: &[u8]) -> (serde_json::Value, Vec<u8>) {
    let u32_at = |o: usize| u32::from_le_bytes(glb[o..o + 4].try_into().unwrap()) as usize;
    assert_eq!(&glb[0..4], b"glTF");
    let json_len = u32_at(12);
    assert_eq!(&glb[16..20], b"JSON");
    let json = serde_json::from_slice(&glb[20..20 + json_len]).expect("GLB JSON chunk");
    let bin_at = 20 + json_len;
    let bin_len = u32_at(bin_at);
    assert_eq!(&glb[bin_at + 4..bin_at + 8], b"BIN\0");
    (json, glb[bin_at + 8..bin_at + 8 + bin_len].to_vec())
}

/// A GLB from a JSON value and a BIN chunk (both padded to 4 bytes as the spec requires).
fn join_glb(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    j.resize(j.len().next_multiple_of(4), b' ');
    let mut b = bin.to_vec();
    b.resize(b.len().next_multiple_of(4), 0);
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

fn box_glb() -> Vec<u8> {
    std::fs::read(fixtures().join("Box/Box.glb")).unwrap()
}

#[test]
fn bytes_via_stdin_match_the_file_report() {
    let Some(report) = validate("Box.glb", &box_glb()) else {
        return;
    };
    assert_eq!(report.file, "Box.glb");
    assert_eq!(
        report.error_codes(),
        Vec::<&str>::new(),
        "{}",
        report.summary()
    );
    // Splitting and re-joining the GLB is lossless for the validator too.
    let (json, bin) = split_glb(&box_glb());
    let Some(again) = validate("Box-rejoined.glb", &join_glb(&json, &bin)) else {
        return;
    };
    assert_eq!(
        again.error_codes(),
        Vec::<&str>::new(),
        "{}",
        again.summary()
    );
}

#[test]
fn accessor_count_too_large_is_an_error() {
    let (mut json, bin) = split_glb(&box_glb());
    let count = json["accessors"][0]["count"].as_u64().unwrap();
    json["accessors"][0]["count"] = (count * 100).into();
    let Some(report) = validate("Box-count-patched.glb", &join_glb(&json, &bin)) else {
        return;
    };
    assert!(report.num_errors >= 1, "{}", report.summary());
    let too_long: Vec<_> = report
        .messages_of(Severity::Error)
        .filter(|m| m.code == "ACCESSOR_TOO_LONG")
        .collect();
    assert_eq!(too_long.len(), 1, "{}", report.summary());
    assert_eq!(too_long[0].pointer.as_deref(), Some("/accessors/0"));
}

#[test]
fn out_of_range_accessor_index_is_an_error() {
    // A .gltf with its buffer in a data URI, so it validates from stdin with nothing beside it.
    let text = std::fs::read(fixtures().join("BoxTextured_embedded/BoxTextured.gltf")).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&text).unwrap();
    let accessors = json["accessors"].as_array().unwrap().len();
    json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = (accessors + 7).into();
    let bytes = serde_json::to_vec(&json).unwrap();
    let Some(report) = validate("BoxTextured-bad-index.gltf", &bytes) else {
        return;
    };
    assert!(
        report.has_error("UNRESOLVED_REFERENCE"),
        "{}",
        report.summary()
    );
    assert!(
        report
            .messages_of(Severity::Error)
            .any(|m| m.pointer.as_deref() == Some("/meshes/0/primitives/0/attributes/POSITION")),
        "{}",
        report.summary()
    );
}

/// A scratch directory of this test's own under the target dir.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("validator-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn sparse_gltf_with_buffer_uri(uri: &str) -> Vec<u8> {
    let path = fixtures().join("SimpleSparseAccessor/SimpleSparseAccessor.gltf");
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    json["buffers"][0]["uri"] = uri.into();
    serde_json::to_vec(&json).unwrap()
}

fn buffer_io_errors(report: &ValidatorReport) -> Vec<&str> {
    report
        .messages_of(Severity::Error)
        .filter(|m| m.code == "IO_ERROR" && m.pointer.as_deref() == Some("/buffers/0/uri"))
        .map(|m| m.message.as_str())
        .collect()
}

#[test]
fn sidecar_bin_is_read_from_the_files_directory_and_no_further() {
    let dir = scratch("sidecar");
    let bin =
        std::fs::read(fixtures().join("SimpleSparseAccessor/SimpleSparseAccessor.bin")).unwrap();
    std::fs::create_dir_all(dir.join("inner")).unwrap();
    std::fs::write(dir.join("inner/data.bin"), &bin).unwrap();
    std::fs::write(dir.join("outside.bin"), &bin).unwrap();

    // Beside the file (in a subfolder, with a percent-encoded name): read.
    std::fs::write(dir.join("inner/data.bin").with_file_name("da ta.bin"), &bin).unwrap();
    std::fs::write(
        dir.join("inner/ok.gltf"),
        sparse_gltf_with_buffer_uri("da%20ta.bin"),
    )
    .unwrap();
    let Some(ok) = validate_file(&dir.join("inner/ok.gltf")) else {
        return;
    };
    assert_eq!(ok.error_codes(), Vec::<&str>::new(), "{}", ok.summary());

    // One level up from the validated file: refused, as an IO_ERROR on the buffer.
    std::fs::write(
        dir.join("inner/up.gltf"),
        sparse_gltf_with_buffer_uri("../outside.bin"),
    )
    .unwrap();
    let up = validate_file(&dir.join("inner/up.gltf")).unwrap();
    let errs = buffer_io_errors(&up);
    assert!(
        errs.len() == 1 && errs[0].contains("refused"),
        "{}",
        up.summary()
    );

    // From stdin there is no directory: external buffers are refused too.
    let stdin = validate("ok.gltf", &sparse_gltf_with_buffer_uri("data.bin")).unwrap();
    let errs = buffer_io_errors(&stdin);
    assert!(
        errs.len() == 1 && errs[0].contains("refused"),
        "{}",
        stdin.summary()
    );
    let _ = std::fs::remove_dir_all(&dir);
}
