//! Runs the tangent core on one mesh in a loop, for a profiler to sample:
//!
//! ```sh
//! cargo build --release -p tspace-testkit --example core-loop
//! perf record -e cpu-clock -F 10000 -g target/release/examples/core-loop \
//!     ../shared/corpus/gltf_SciFiHelmet_no_images/SciFiHelmet.gltf 5
//! ```
//!
//! Arguments: a glTF/GLB file (every triangle primitive with normals and texture coordinates,
//! concatenated as the `tangents` bench does) or `sphere:N` / `torus:N` for a generated shape of
//! about N triangles; then the seconds to run (default 3); then `parallel` to spread each call
//! over the rayon pool (`RAYON_NUM_THREADS` sets its size). Prints the median time of a call.
//!
//! The `tangents` bench fixes glibc's allocator thresholds so that every call reuses the last
//! one's memory; to profile the core as the bench measures it, run this with
//! `GLIBC_TUNABLES=glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=2147483647`.
//!
//! `CORE_LOOP_IDLE_MS=3` sleeps that long before every call, untimed, to measure a call as the
//! service's worker makes it: after the milliseconds its request spent on the network, with
//! the CPU idle. Back to back, every call finds the CPU running (see "A call after idle" in
//! docs/benchmarks.md).
//!
//! `CORE_LOOP_METHOD=fast` (or `axis`) runs that method instead of MikkTSpace.
//!
//! `CORE_LOOP_REMAP=1` times meshoptimizer's `generateVertexRemap` instead, on the same vertices
//! (position, normal and texture coordinate in one 32-byte record): the peer of the core's weld,
//! whose share of a call a profile gives.

use std::time::Instant;
use tspace_tangent::{MeshInput, Method, Options, generate};

struct Mesh {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

fn load(what: &str) -> Result<Mesh, String> {
    if let Some((kind, size)) = what.split_once(':') {
        let triangles: usize = size.parse().map_err(|e| format!("{what}: {e}"))?;
        let [sphere, torus] = tspace_testkit::shapes::shapes_of_size(triangles);
        let shape = match kind {
            "sphere" => sphere,
            "torus" => torus,
            _ => return Err(format!("{what}: not sphere:N or torus:N")),
        };
        return Ok(Mesh {
            positions: shape.positions,
            normals: shape.normals,
            uvs: shape.uvs,
            indices: shape.indices,
        });
    }
    let mut mesh = Mesh {
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        indices: Vec::new(),
    };
    for primitive in tspace_testkit::meshes::load_gltf(std::path::Path::new(what))? {
        let (Some(normals), Some(uvs)) = (primitive.normals, primitive.uvs) else {
            continue;
        };
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(primitive.positions);
        mesh.normals.extend(normals);
        mesh.uvs.extend(uvs);
        mesh.indices
            .extend(primitive.indices.iter().map(|i| i + base));
    }
    Ok(mesh)
}

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let what = args
        .next()
        .ok_or("usage: core-loop FILE|sphere:N|torus:N [SECONDS] [parallel]")?;
    let seconds: f64 = args
        .next()
        .map_or(Ok(3.0), |s| s.parse().map_err(|e| format!("{e}")))?;
    let parallel = match args.next().as_deref() {
        None => false,
        Some("parallel") => true,
        Some(other) => return Err(format!("{other}: not `parallel`")),
    };
    let mesh = load(&what)?;
    let input = MeshInput {
        positions: &mesh.positions,
        normals: Some(&mesh.normals),
        uvs: Some(&mesh.uvs),
        indices: Some(&mesh.indices),
    };
    let method = match std::env::var("CORE_LOOP_METHOD") {
        Ok(name) => Method::from_name(&name)
            .ok_or_else(|| format!("CORE_LOOP_METHOD={name}: not a method"))?,
        Err(_) => Method::default(),
    };
    let options = Options {
        parallel,
        method,
        ..Options::default()
    };
    let idle = match std::env::var("CORE_LOOP_IDLE_MS") {
        Ok(ms) => {
            let seconds = ms.parse::<f64>().map_err(|e| e.to_string()).and_then(|ms| {
                std::time::Duration::try_from_secs_f64(ms / 1e3).map_err(|e| e.to_string())
            });
            Some(seconds.map_err(|e| format!("CORE_LOOP_IDLE_MS={ms}: {e}"))?)
        }
        Err(_) => None,
    };
    if std::env::var_os("CORE_LOOP_REMAP").is_some() {
        return time_meshopt_remap(&mesh, seconds);
    }
    let times = time_calls(seconds, idle, || {
        let result = generate(&input, &options).map_err(|e| e.to_string())?;
        std::hint::black_box(result);
        Ok(())
    })?;
    let at = |fraction: f64| times[((times.len() - 1) as f64 * fraction) as usize] * 1e3;
    println!(
        "{what}: {} triangles, {} vertices, {} calls, median {:.3} ms, best {:.3} ms \
         (tenth {:.3}, ninetieth {:.3})",
        mesh.indices.len() / 3,
        mesh.positions.len(),
        times.len(),
        at(0.5),
        times[0] * 1e3,
        at(0.1),
        at(0.9),
    );
    Ok(())
}

/// Times `meshopt::generate_vertex_remap` over the mesh's vertices, compared whole as bytes (it
/// welds what is bitwise equal, where the core welds what is equal as floats: the same classes
/// unless a mesh holds -0 or NaN).
fn time_meshopt_remap(mesh: &Mesh, seconds: f64) -> Result<(), String> {
    let vertices: Vec<[f32; 8]> = (mesh.positions.iter().zip(&mesh.normals).zip(&mesh.uvs))
        .map(|((p, n), t)| [p[0], p[1], p[2], n[0], n[1], n[2], t[0], t[1]])
        .collect();
    let mut classes = 0;
    let times = time_calls(seconds, None, || {
        let (count, remap) = meshopt::generate_vertex_remap(&vertices, None);
        classes = count;
        std::hint::black_box(remap);
        Ok(())
    })?;
    println!(
        "meshopt generateVertexRemap: {} vertices, {classes} classes, {} calls, median {:.3} ms",
        vertices.len(),
        times.len(),
        times[times.len() / 2] * 1e3
    );
    Ok(())
}

/// Makes `call` for `seconds` (at least once), each after `idle` untimed if given, and returns
/// each call's time in seconds, sorted.
fn time_calls(
    seconds: f64,
    idle: Option<std::time::Duration>,
    mut call: impl FnMut() -> Result<(), String>,
) -> Result<Vec<f64>, String> {
    let mut times = Vec::new();
    let start = Instant::now();
    while times.is_empty() || start.elapsed().as_secs_f64() < seconds {
        if let Some(idle) = idle {
            std::thread::sleep(idle);
        }
        let t = Instant::now();
        call()?;
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    Ok(times)
}
