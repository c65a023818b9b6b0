//! The MikkTSpace oracle on real meshes: every triangle primitive with normals and texture
//! coordinates, in `fixtures/` (always) and in the shared corpus (`../shared/corpus`, when it is
//! there), is compared corner by corner with the reference (`bevy_mikktspace` 1.0).
//!
//! Plus two checks against tangents authored in files: NormalTangentMirrorTest (mirrored UVs) and
//! the Draco sphere pair, both processed with the glTF convention.
//!
//! Run with `cargo test --release --test oracle -- --nocapture` to see the per-mesh summaries.

use std::path::{Path, PathBuf};
use std::time::Instant;
use tspace_tangent::diagnostics::SAMPLE_SIZE;
use tspace_tangent::{FallbackCounts, MeshInput, Options, UvOrigin, generate};
use tspace_testkit::meshes::{Primitive, load_gltf, load_obj};
use tspace_testkit::{angle_degrees, reference_is_valid, reference_tangents};

fn fixtures_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures")
}

/// The shared corpus, when this checkout has it next to it.
fn corpus_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "note: {} not found; skipping the corpus meshes",
            dir.display()
        );
        None
    }
}

/// Meshes in `fixtures/` (see `fixtures/README.md`).
const FIXTURES: &[&str] = &[
    "NormalTangentMirrorTest/NormalTangentMirrorTest.gltf",
    "Avocado/Avocado.gltf",
    "MultiUVTest/MultiUVTest.gltf",
    "BoxTextured_embedded/BoxTextured.gltf",
    "WaterBottle/WaterBottle.gltf",
    "Lantern/Lantern.gltf",
    "spider/spider.obj",
];

/// Known-good corpus files with triangles, normals and texture coordinates that are not also in
/// `fixtures/` (the fixtures are byte-identical copies of corpus files).
const CORPUS: &[&str] = &[
    "gltf_NormalTangentTest/glTF/NormalTangentTest.gltf",
    "gltf_NormalTangentTest/glTF-Binary/NormalTangentTest.glb",
    "gltf_NormalTangentTest/glTF-Embedded/NormalTangentTest.gltf",
    "gltf_DamagedHelmet/glTF-Binary/DamagedHelmet.glb",
    "gltf_Suzanne_no_images/Suzanne.gltf",
    "gltf_SciFiHelmet_no_images/SciFiHelmet.gltf",
    "gltf_BoomBox_no_images/BoomBox.gltf",
    "gltf_SheenCloth_glb/SheenCloth.glb",
    "gltf_draco_sphere_tangent_pair/sphere.gltf",
    "gltf_draco_sphere_tangent_pair/sphere_no_tangents.gltf",
    "gltf_MorphPrimitivesTest/MorphPrimitivesTest.gltf",
    "gltf_TextureCoordinateTest_embedded/TextureCoordinateTest.gltf",
    "obj_draco_edge_cases/cube_att.obj",
    "obj_draco_edge_cases/cube_quads.obj",
    "obj_trimesh_negative_indices/negative_indices.obj",
];

fn load(path: &Path) -> Vec<Primitive> {
    let result = if path.extension().is_some_and(|e| e == "obj") {
        load_obj(path).map(|p| vec![p])
    } else {
        load_gltf(path)
    };
    result.unwrap_or_else(|e| panic!("{e}"))
}

/// Corners where the reference and we disagree, for the report.
#[derive(Debug)]
struct Mismatch {
    corner: usize,
    vertex: u32,
    reference: Option<[f32; 4]>,
    ours: [f32; 4],
    angle: f64,
}

#[derive(Debug, Default)]
struct Comparison {
    name: String,
    corners: usize,
    /// Corners where the reference is valid and we agree within tolerance.
    matched: usize,
    bit_exact: usize,
    worst_angle: f64,
    /// Reference valid, and our `w` differs or the angle exceeds 0.01°.
    mismatches: Vec<Mismatch>,
    /// Corners where the reference's tangent is not valid (absent, zero, non-finite, not unit or
    /// not orthogonal to the normal).
    reference_invalid: usize,
    /// The reference-invalid corners, by kind: no tangent at all, a zero vector, a non-finite
    /// vector, and a vector that is not unit or not orthogonal to the normal.
    reference_none: usize,
    reference_zero: usize,
    reference_non_finite: usize,
    reference_skewed: usize,
    /// The first reference-invalid corners, as many as [`Tally::first`] keeps.
    reference_invalid_first: Vec<u32>,
    /// Corners whose tangent from us is not valid (there must be none).
    ours_invalid: Vec<Mismatch>,
    /// `diagnostics.fallback_tangents`.
    fallbacks: FallbackCounts,
    millis: u128,
}

/// Whether our tangent meets the documented guarantees against `normal`.
fn ours_is_valid(t: [f32; 4], normal: [f32; 3]) -> bool {
    let finite = t.iter().all(|x| x.is_finite());
    let len = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
    let nl = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
    let d = (t[0] * normal[0] + t[1] * normal[1] + t[2] * normal[2]) / nl;
    // A zero or non-finite normal has no plane to be orthogonal to: the core then uses the face
    // normal, which this check does not recompute.
    let normal_usable = nl.is_finite() && nl > 0.0;
    finite && (len - 1.0).abs() <= 1e-5 && (!normal_usable || d.abs() <= 1e-4) && t[3].abs() == 1.0
}

fn compare_with_reference(p: &Primitive) -> Option<Comparison> {
    let (Some(normals), Some(uvs)) = (&p.normals, &p.uvs) else {
        return None;
    };
    let start = Instant::now();
    let reference = reference_tangents(&p.positions, normals, uvs, &p.indices);
    let input = MeshInput {
        positions: &p.positions,
        normals: Some(normals),
        uvs: Some(uvs),
        indices: Some(&p.indices),
    };
    let options = Options {
        uv_origin: UvOrigin::BottomLeft,
        parallel: true,
        ..Default::default()
    };
    let ours = generate(&input, &options).unwrap_or_else(|e| panic!("{}: {e}", p.name));
    let ours_by_corner = ours.corner_tangents(input.indices);
    assert_eq!(ours_by_corner.len(), p.indices.len(), "{}", p.name);

    let mut c = Comparison {
        name: p.name.clone(),
        corners: p.indices.len(),
        fallbacks: ours.diagnostics.fallback_tangents.clone(),
        ..Default::default()
    };
    for (corner, (r, o)) in reference.iter().zip(&ours_by_corner).enumerate() {
        let vertex = p.indices[corner];
        let n = normals[vertex as usize];
        let record = |angle| Mismatch {
            corner,
            vertex,
            reference: *r,
            ours: *o,
            angle,
        };
        if !ours_is_valid(*o, n) {
            c.ours_invalid.push(record(f64::NAN));
        }
        if !reference_is_valid(*r, n) {
            c.reference_invalid += 1;
            if c.reference_invalid_first.len() < SAMPLE_SIZE {
                c.reference_invalid_first.push(corner as u32);
            }
            match r {
                None => c.reference_none += 1,
                Some(t) if !t.iter().all(|x| x.is_finite()) => c.reference_non_finite += 1,
                Some(t) if t[..3].iter().all(|&x| x == 0.0) => c.reference_zero += 1,
                Some(_) => c.reference_skewed += 1,
            }
            continue;
        }
        let rt = r.unwrap();
        let angle = if rt == *o {
            0.0
        } else {
            angle_degrees([rt[0], rt[1], rt[2]], [o[0], o[1], o[2]])
        };
        c.worst_angle = c.worst_angle.max(angle);
        if rt[3] != o[3] || angle > 0.01 {
            c.mismatches.push(record(angle));
        } else {
            c.matched += 1;
            c.bit_exact += usize::from(rt == *o);
        }
    }
    c.millis = start.elapsed().as_millis();
    Some(c)
}

fn print_header() {
    eprintln!(
        "{:<58} {:>7} {:>7} {:>5} {:>9} {:>6} {:>6} {:>5} {:>6}",
        "mesh", "corners", "exact", "mism", "worst°", "refbad", "refnone", "fallb", "ms"
    );
}

fn print_row(c: &Comparison) {
    eprintln!(
        "{:<58} {:>7} {:>7} {:>5} {:>9.2e} {:>6} {:>6} {:>5} {:>6}",
        c.name,
        c.corners,
        c.bit_exact,
        c.mismatches.len(),
        c.worst_angle,
        c.reference_invalid,
        c.reference_none,
        c.fallbacks.corners.count,
        c.millis
    );
    if c.reference_invalid > 0 {
        let f = &c.fallbacks;
        eprintln!(
            "    reference invalid: {} none, {} zero, {} non-finite, {} not unit/orthogonal; \
             our fallbacks: {} unassigned, {} zero length, {} non-finite, {} not orthogonal; \
             first corners: reference {:?}, fallbacks {:?}",
            c.reference_none,
            c.reference_zero,
            c.reference_non_finite,
            c.reference_skewed,
            f.unassigned,
            f.zero_length,
            f.non_finite,
            f.not_orthogonal,
            c.reference_invalid_first,
            f.corners.first
        );
    }
    for m in c.mismatches.iter().take(20) {
        eprintln!(
            "    mismatch corner {} (triangle {}, vertex {}): reference {:?} ours {:?} angle {:.4}°",
            m.corner,
            m.corner / 3,
            m.vertex,
            m.reference,
            m.ours,
            m.angle
        );
    }
    for m in c.ours_invalid.iter().take(20) {
        eprintln!(
            "    INVALID corner {} (vertex {}): ours {:?}",
            m.corner, m.vertex, m.ours
        );
    }
}

/// Compares every usable primitive of `files` (relative to `dir`) and checks the results.
fn check_files(dir: &Path, files: &[&str]) {
    print_header();
    let mut failures = Vec::new();
    let mut compared = 0;
    for file in files {
        for p in load(&dir.join(file)) {
            let Some(c) = compare_with_reference(&p) else {
                eprintln!("{:<58} skipped: no normals or no UVs", p.name);
                continue;
            };
            compared += 1;
            print_row(&c);
            if !c.mismatches.is_empty() {
                failures.push(format!(
                    "{}: {} corners differ from the reference",
                    c.name,
                    c.mismatches.len()
                ));
            }
            if !c.ours_invalid.is_empty() {
                failures.push(format!(
                    "{}: {} corners have an invalid tangent",
                    c.name,
                    c.ours_invalid.len()
                ));
            }
            // Where the reference is invalid, the method's own result is the same invalid value
            // (none of these meshes has non-finite data, where we deliberately differ), so the
            // corner must have been repaired, and counted, by the fallback; and where the
            // reference is valid we reproduce it, so no other corner is repaired. Hence the same
            // count, and the same first corners.
            let fallbacks = &c.fallbacks.corners;
            if fallbacks.count != c.reference_invalid as u64
                || fallbacks.first != c.reference_invalid_first
            {
                failures.push(format!(
                    "{}: the reference is invalid at {} corners (first {:?}) but {} fallbacks \
                     were counted (first {:?})",
                    c.name,
                    c.reference_invalid,
                    c.reference_invalid_first,
                    fallbacks.count,
                    fallbacks.first
                ));
            }
        }
    }
    assert!(compared > 0, "no mesh was compared");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn fixtures_match_reference() {
    check_files(&fixtures_dir(), FIXTURES);
}

#[test]
fn corpus_matches_reference() {
    let Some(dir) = corpus_dir() else { return };
    check_files(&dir, CORPUS);
}

/// Angle statistics, in degrees.
fn angle_stats(mut angles: Vec<f64>) -> String {
    if angles.is_empty() {
        return "no corners".to_owned();
    }
    angles.sort_by(f64::total_cmp);
    let mean = angles.iter().sum::<f64>() / angles.len() as f64;
    let at = |q: f64| angles[((angles.len() - 1) as f64 * q).round() as usize];
    format!(
        "mean {mean:.4}°, median {:.4}°, p99 {:.4}°, max {:.4}°",
        at(0.5),
        at(0.99),
        at(1.0)
    )
}

/// Our tangents with the glTF convention against the authored ones: how many corners disagree in
/// `w`, and angle statistics over the corners that agree.
struct AuthoredComparison {
    corners: usize,
    w_disagree: Vec<usize>,
    angles: Vec<f64>,
}

fn compare_with_authored(p: &Primitive) -> AuthoredComparison {
    let authored = p.tangents.as_ref().expect("authored TANGENT");
    let input = MeshInput {
        positions: &p.positions,
        normals: p.normals.as_deref(),
        uvs: p.uvs.as_deref(),
        indices: Some(&p.indices),
    };
    // The glTF convention: top-left UV origin (the default).
    let ours = generate(&input, &Options::default()).unwrap();
    let mut out = AuthoredComparison {
        corners: p.indices.len(),
        w_disagree: Vec::new(),
        angles: Vec::new(),
    };
    for (corner, o) in ours.corner_tangents(input.indices).iter().enumerate() {
        let a = authored[p.indices[corner] as usize];
        if a[3].signum() != o[3] {
            out.w_disagree.push(corner);
        } else {
            out.angles
                .push(angle_degrees([a[0], a[1], a[2]], [o[0], o[1], o[2]]));
        }
    }
    out
}

#[test]
fn mirror_test_handedness_matches_authored() {
    let path = fixtures_dir().join("NormalTangentMirrorTest/NormalTangentMirrorTest.gltf");
    let prims = load(&path);
    assert_eq!(prims.len(), 1);
    let p = &prims[0];
    let authored = p.tangents.as_ref().unwrap();
    let negative_vertices = authored.iter().filter(|t| t[3] < 0.0).count();
    let c = compare_with_authored(p);
    eprintln!(
        "{}: {} corners ({} of {} vertices authored with w = -1), {} disagree in w; angle to authored: {}",
        p.name,
        c.corners,
        negative_vertices,
        authored.len(),
        c.w_disagree.len(),
        angle_stats(c.angles)
    );
    assert!(
        negative_vertices > 0,
        "the mirror test has mirrored vertices"
    );
    assert!(
        c.w_disagree.is_empty(),
        "corners whose w disagrees with the authored TANGENT: {:?}",
        &c.w_disagree[..c.w_disagree.len().min(20)]
    );
}

#[test]
fn draco_sphere_pair_matches_authored_handedness() {
    let Some(dir) = corpus_dir() else { return };
    let dir = dir.join("gltf_draco_sphere_tangent_pair");
    let with = load(&dir.join("sphere.gltf"));
    let without = load(&dir.join("sphere_no_tangents.gltf"));
    assert_eq!((with.len(), without.len()), (1, 1));
    let (with, without) = (&with[0], &without[0]);
    // The two files share one buffer: same geometry, one with TANGENT and one without.
    assert!(without.tangents.is_none());
    assert_eq!(with.positions, without.positions);
    assert_eq!(with.normals, without.normals);
    assert_eq!(with.uvs, without.uvs);
    assert_eq!(with.indices, without.indices);

    let authored = with.tangents.as_ref().unwrap();
    let c = compare_with_authored(&Primitive {
        tangents: Some(authored.clone()),
        ..without.clone()
    });
    eprintln!(
        "{}: {} corners, {} disagree in w; angle to authored: {}",
        with.name,
        c.corners,
        c.w_disagree.len(),
        angle_stats(c.angles)
    );
    assert!(
        c.w_disagree.is_empty(),
        "corners whose w disagrees with the authored TANGENT: {:?}",
        &c.w_disagree[..c.w_disagree.len().min(20)]
    );
}
