//! Compression benchmarks, as ratios against peers on the same files:
//!
//! - Draco decoding: tspace's decode of every Draco primitive of a file (`draco-gltf` plus the
//!   conversion into the accessors' types) against Google's decoder (npm `draco3dgltf`, WASM, run
//!   in node by `tools/draco-reference/decode.mjs --time`, which copies the same data out). Files:
//!   the Draco fixtures (`fixtures/compressed/`) and, when `../shared/corpus` and node are there,
//!   gltf-transform's Draco DamagedHelmet (made by `scripts/make-helmet-variants` into
//!   `bench-results/helmet/`). Node is skipped with a note where it is missing.
//! - Meshopt encoding: the streams tspace writes for the corpus DamagedHelmet (positions,
//!   normals, UVs and tangents in the split's vertex order, and the indices) encoded with the
//!   `meshopt` crate, against the tangents they follow (the core's default options).
//!
//! `cargo bench --bench compression`; `TSPACE_BENCH_ROUNDS=N` sets the timed rounds (default 30).
//! Medians are printed and written to `bench-results/compression.csv`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;
use tspace::scene::gltf::draco::{self, DracoLimits};
use tspace::scene::gltf::load::{self, LoadLimits, NoResources};
use tspace_testkit::fixtures::workspace_root;

fn rounds() -> usize {
    std::env::var("TSPACE_BENCH_ROUNDS")
        .ok()
        .and_then(|r| r.parse().ok())
        .filter(|&r| r > 0)
        .unwrap_or(30)
}

fn median(mut times: Vec<f64>) -> f64 {
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

/// Milliseconds of `f`, median over `rounds` after one untimed run.
fn time_ms(rounds: usize, mut f: impl FnMut()) -> f64 {
    f();
    median(
        (0..rounds)
            .map(|_| {
                let start = Instant::now();
                f();
                start.elapsed().as_secs_f64() * 1e3
            })
            .collect(),
    )
}

/// The Draco files: the fixtures, then the helmet when it can be made.
fn draco_files() -> Vec<PathBuf> {
    let root = workspace_root();
    let mut files: Vec<PathBuf> = std::fs::read_dir(root.join("fixtures/compressed"))
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.retain(|p| p.to_string_lossy().contains("draco"));
    files.sort();
    let helmet_dir = root.join("bench-results/helmet");
    let helmet = helmet_dir.join("helmet_draco.glb");
    if !helmet.exists() {
        let made = Command::new("bash")
            .arg(root.join("scripts/make-helmet-variants"))
            .arg(&helmet_dir)
            .output();
        if !made.as_ref().is_ok_and(|o| o.status.success()) {
            println!("(helmet_draco.glb not made: needs ../shared/corpus and node; skipped)");
        }
    }
    if helmet.exists() {
        files.push(helmet);
    }
    files
}

/// Decodes every Draco primitive of `bytes`; returns the triangles decoded.
fn decode_all(bytes: &[u8]) -> usize {
    let limits = LoadLimits {
        max_buffer_bytes: 1 << 30,
    };
    let loaded = load::load(bytes, &NoResources, &limits).expect("a Draco fixture loads");
    let root = loaded.doc.root();
    let buffers = loaded.buffer_slices();
    let draco_limits = DracoLimits {
        max_vertices: 1 << 24,
        max_triangles: 1 << 24,
        max_bytes: 1 << 30,
    };
    let mut triangles = 0;
    for mesh in root.get("meshes").and_then(|m| m.as_array()).unwrap_or(&[]) {
        for primitive in mesh
            .get("primitives")
            .and_then(|p| p.as_array())
            .unwrap_or(&[])
        {
            if draco::extension(primitive).is_none() {
                continue;
            }
            let decoded =
                draco::decode_primitive(root, primitive, "bench", &buffers, &draco_limits)
                    .expect("a Draco fixture decodes");
            let indices = primitive
                .get("indices")
                .and_then(|i| i.as_u64())
                .and_then(|i| decoded.iter().find(|(a, _)| *a as u64 == i));
            triangles += indices.map_or(0, |(_, d)| d.count / 3);
        }
    }
    triangles
}

/// Google's decoder on `file`, in milliseconds per whole-file decode, if node can run it.
fn reference_ms(file: &Path, rounds: usize) -> Option<f64> {
    let root = workspace_root();
    let _ = Command::new("bash")
        .arg(root.join("scripts/install-draco-reference"))
        .output();
    let output = Command::new("node")
        .arg(root.join("tools/draco-reference/decode.mjs"))
        .arg("--time")
        .arg(rounds.to_string())
        .arg(file)
        .output()
        .ok()
        .filter(|o| o.status.success())?;
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).ok()?;
    report["median_ms"].as_f64()
}

fn bench_draco(csv: &mut String, rounds: usize) {
    println!(
        "Draco decode, whole file (median of {rounds}); ratio = draco3dgltf time / tspace time"
    );
    println!(
        "{:<44} {:>9} {:>11} {:>13} {:>7}",
        "file", "triangles", "tspace ms", "draco3dgltf ms", "ratio"
    );
    for file in draco_files() {
        let bytes = std::fs::read(&file).expect("a listed file reads");
        let mut triangles = 0;
        let ours = time_ms(rounds, || triangles = decode_all(&bytes));
        let theirs = reference_ms(&file, rounds);
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        let (theirs_text, ratio_text) = match theirs {
            Some(t) => (format!("{t:.3}"), format!("{:.2}", t / ours)),
            None => ("(no node)".into(), "-".into()),
        };
        println!("{name:<44} {triangles:>9} {ours:>11.3} {theirs_text:>13} {ratio_text:>7}");
        let _ = writeln!(
            csv,
            "draco_decode,{name},{triangles},{ours:.4},{},{}",
            theirs.map_or(String::new(), |t| format!("{t:.4}")),
            theirs.map_or(String::new(), |t| format!("{:.3}", t / ours)),
        );
    }
}

fn bench_meshopt(csv: &mut String, rounds: usize) {
    let path =
        workspace_root().join("../shared/corpus/gltf_DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
    let Ok(primitives) = tspace_testkit::meshes::load_gltf(&path) else {
        println!("meshopt encode: ../shared/corpus DamagedHelmet not found; skipped");
        return;
    };
    let Some(p) = primitives.into_iter().next() else {
        return;
    };
    let (Some(normals), Some(uvs)) = (p.normals, p.uvs) else {
        return;
    };
    let input = tspace_tangent::MeshInput {
        positions: &p.positions,
        normals: Some(&normals),
        uvs: Some(&uvs),
        indices: Some(&p.indices),
    };
    let options = tspace_tangent::Options::default();
    let mut tangents = tspace_tangent::generate(&input, &options).expect("the helmet computes");
    let tangent_ms = time_ms(rounds, || {
        tangents = tspace_tangent::generate(&input, &options).expect("the helmet computes");
    });
    let split = &tangents.split;
    let remap = |v: &[[f32; 3]]| -> Vec<[f32; 3]> {
        split.source_vertex.iter().map(|&s| v[s as usize]).collect()
    };
    let positions = remap(&p.positions);
    let normals = remap(&normals);
    let uvs: Vec<[f32; 2]> = split
        .source_vertex
        .iter()
        .map(|&s| uvs[s as usize])
        .collect();
    let vertices = split.vertex_tangents.len();
    // The same streams as gltfpack quantizes them (the -cc helmet's layout): positions u16x4,
    // normals and tangents i8x4, UVs u16x2.
    let unorm16 =
        |x: f32, lo: f32, hi: f32| ((x - lo) / (hi - lo).max(1e-12) * 65535.0).round() as u16;
    let (lo, hi) = positions
        .iter()
        .fold(([f32::MAX; 3], [f32::MIN; 3]), |(mut lo, mut hi), p| {
            for i in 0..3 {
                lo[i] = lo[i].min(p[i]);
                hi[i] = hi[i].max(p[i]);
            }
            (lo, hi)
        });
    let q_positions: Vec<[u16; 4]> = positions
        .iter()
        .map(|p| {
            [
                unorm16(p[0], lo[0], hi[0]),
                unorm16(p[1], lo[1], hi[1]),
                unorm16(p[2], lo[2], hi[2]),
                0,
            ]
        })
        .collect();
    let snorm8 = |x: f32| (x.clamp(-1.0, 1.0) * 127.0).round() as i8;
    let q_normals: Vec<[i8; 4]> = normals
        .iter()
        .map(|n| [snorm8(n[0]), snorm8(n[1]), snorm8(n[2]), 0])
        .collect();
    let q_tangents: Vec<[i8; 4]> = split
        .vertex_tangents
        .iter()
        .map(|t| [snorm8(t[0]), snorm8(t[1]), snorm8(t[2]), snorm8(t[3])])
        .collect();
    let q_uvs: Vec<[u16; 2]> = uvs
        .iter()
        .map(|t| [unorm16(t[0], 0.0, 1.0), unorm16(t[1], 0.0, 1.0)])
        .collect();
    let indices = &*split.indices_for(Some(&p.indices));
    // Version 0 of the vertex codec, the one EXT_meshopt_compression allows (tspace writes it).
    fn encoded<T>(vertices: &[T]) -> usize {
        meshopt::encode_vertex_buffer_level(vertices, 2, Some(0)).map_or(0, |b| b.len())
    }
    let encode_indices = || meshopt::encode_index_buffer(indices, vertices).map_or(0, |b| b.len());
    let float = || {
        encoded(&positions)
            + encoded(&normals)
            + encoded(&uvs)
            + encoded(&split.vertex_tangents)
            + encode_indices()
    };
    let quantized = || {
        encoded(&q_positions)
            + encoded(&q_normals)
            + encoded(&q_uvs)
            + encoded(&q_tangents)
            + encode_indices()
    };
    let streams: [(&str, &dyn Fn() -> usize); 2] = [("float", &float), ("quantized", &quantized)];
    println!(
        "\nmeshopt encode, DamagedHelmet's written streams ({vertices} vertices, {} triangles; median of {rounds}); tangents {tangent_ms:.3} ms",
        indices.len() / 3
    );
    for (layout, encode) in &streams {
        let mut bytes = 0;
        let encode_ms = time_ms(rounds, || bytes = encode());
        println!(
            "{layout:<10} encode {encode_ms:.3} ms, encode / tangents = {:.2} (target <= 1), {bytes} bytes",
            encode_ms / tangent_ms
        );
        let _ = writeln!(
            csv,
            "meshopt_encode_{layout},DamagedHelmet,{},{encode_ms:.4},{tangent_ms:.4},{:.3}",
            indices.len() / 3,
            encode_ms / tangent_ms
        );
    }
}

fn main() {
    let rounds = rounds();
    let mut csv = String::from("bench,file,triangles,ms,against_ms,ratio\n");
    bench_draco(&mut csv, rounds);
    bench_meshopt(&mut csv, rounds);
    let dir = workspace_root().join("bench-results");
    let _ = std::fs::create_dir_all(&dir);
    if std::fs::write(dir.join("compression.csv"), csv).is_ok() {
        println!("\nwritten: bench-results/compression.csv");
    }
}
