//! Scale stability on real data: every mesh with texture coordinates in the fixtures and the
//! corpus (`../shared/corpus`, when present), scaled by 1e-6 and 1e6 and translated by 1e6.
//! Tangents must stay valid (finite, unit, orthogonal to the normal, w = ±1), and the largest angle
//! change against the untransformed result is printed per mesh, as a table.
//!
//! Uniform scaling changes no angle, so MikkTSpace's answer is the same up to rounding; a
//! translation by 1e6 leaves f32 positions about 0.06 apart at best, so small meshes lose their
//! shape there and their tangents may legitimately move. The test asserts validity everywhere and
//! closeness only where the transformed positions still resolve the mesh (scaling).

use std::path::Path;
use tspace_tangent::{MeshInput, Options, generate};
#[allow(unused_imports)]
use tspace_testkit::meshes::{Primitive, load_gltf, load_obj};

const FIXTURES: &[&str] = &[
    "NormalTangentMirrorTest/NormalTangentMirrorTest.gltf",
    "Avocado/Avocado.gltf",
    "WaterBottle/WaterBottle.gltf",
    "Lantern/Lantern.gltf",
    "MultiUVTest/MultiUVTest.gltf",
    "BoxTextured_embedded/BoxTextured.gltf",
    "spider/spider.obj",
    "negative_indices/negative_indices.obj",
];

const CORPUS: &[&str] = &[
    "gltf_DamagedHelmet/glTF-Binary/DamagedHelmet.glb",
    "gltf_SciFiHelmet_no_images/SciFiHelmet.gltf",
    "gltf_BoomBox_no_images/BoomBox.gltf",
    "gltf_SheenCloth_glb/SheenCloth.glb",
    "gltf_Suzanne_no_images/Suzanne.gltf",
    "gltf_NormalTangentTest/glTF-Binary/NormalTangentTest.glb",
    "gltf_draco_sphere_tangent_pair/sphere.gltf",
    "obj_spot/spot_triangulated.obj",
];

type Transform = fn([f32; 3]) -> [f32; 3];

fn load(path: &Path) -> Vec<Primitive> {
    let result = if path.extension().is_some_and(|e| e == "obj") {
        load_obj(path).map(|p| vec![p])
    } else {
        load_gltf(path)
    };
    result.unwrap_or_default()
}

fn tangents(p: &Primitive, positions: &[[f32; 3]]) -> Vec<[f32; 4]> {
    let input = MeshInput {
        positions,
        normals: p.normals.as_deref(),
        uvs: p.uvs.as_deref(),
        indices: Some(&p.indices),
    };
    generate(&input, &Options::default())
        .expect("valid mesh")
        .corner_tangents(input.indices)
}

fn angle(a: [f32; 4], b: [f32; 4]) -> f64 {
    let dot: f64 = (0..3).map(|i| f64::from(a[i]) * f64::from(b[i])).sum();
    dot.clamp(-1.0, 1.0).acos().to_degrees()
}

fn check_valid(name: &str, label: &str, p: &Primitive, out: &[[f32; 4]]) {
    for (corner, t) in out.iter().enumerate() {
        let length = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        assert!(
            t.iter().all(|c| c.is_finite()) && (length - 1.0).abs() < 1e-5 && t[3].abs() == 1.0,
            "{name} {label}: corner {corner} has {t:?}"
        );
        if let Some(normals) = &p.normals {
            let n = normals[p.indices[corner] as usize];
            let ln = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if ln > 0.5 && ln.is_finite() {
                let cos = (t[0] * n[0] + t[1] * n[1] + t[2] * n[2]) / ln;
                assert!(
                    cos.abs() < 1e-4,
                    "{name} {label}: corner {corner} not orthogonal ({cos})"
                );
            }
        }
    }
}

#[test]
fn tangents_survive_extreme_scales_and_offsets() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files: Vec<_> = FIXTURES
        .iter()
        .map(|f| root.join("fixtures").join(f))
        .collect();
    let corpus = root.join("../shared/corpus");
    if corpus.is_dir() {
        files.extend(CORPUS.iter().map(|f| corpus.join(f)).filter(|p| p.exists()));
    } else {
        eprintln!("scale_stability: ../shared/corpus not found; fixtures only");
    }
    println!(
        "{:<60} {:>9} {:>12} {:>12} {:>14}",
        "mesh", "corners", "x1e-6 max°", "x1e6 max°", "+1e6 max°"
    );
    for path in files {
        for p in load(&path) {
            if p.uvs.is_none() || p.indices.is_empty() {
                continue;
            }
            let name = p.name.clone();
            let base = tangents(&p, &p.positions);
            check_valid(&name, "as is", &p, &base);
            let mut worst = Vec::new();
            let transforms: [(&str, Transform); 3] = [
                ("x1e-6", |v| [v[0] * 1e-6, v[1] * 1e-6, v[2] * 1e-6]),
                ("x1e6", |v| [v[0] * 1e6, v[1] * 1e6, v[2] * 1e6]),
                ("+1e6", |v| [v[0] + 1e6, v[1] + 1e6, v[2] + 1e6]),
            ];
            for (label, transform) in transforms {
                let moved: Vec<[f32; 3]> = p.positions.iter().map(|&v| transform(v)).collect();
                let out = tangents(&p, &moved);
                check_valid(&name, label, &p, &out);
                let max = base
                    .iter()
                    .zip(&out)
                    .map(|(&a, &b)| angle(a, b))
                    .fold(0.0f64, f64::max);
                worst.push(max);
            }
            println!(
                "{:<60} {:>9} {:>12.4} {:>12.4} {:>14.4}",
                name,
                base.len(),
                worst[0],
                worst[1],
                worst[2]
            );
            // Scaling by a power of ten is not exact in binary, so allow rounding-level change.
            assert!(
                worst[0] < 0.5 && worst[1] < 0.5,
                "{name}: scaling moved a tangent by {worst:?}°"
            );
        }
    }
}
