//! No quadratic traps: meshes that make the MikkTSpace reference search or recurse in O(N²) or
//! O(N) depth (all-degenerate meshes, one vertex shared by a huge fan, long sliver strips) must
//! take time linear in their size here. Each case is timed at N and N/2 in the same test; the
//! ratio must stay well under the 4 a quadratic algorithm would show. Best of five runs each,
//! alternating sizes, one test at a time, and a failing ratio measured again (three attempts),
//! to keep a noisy machine from deciding.

use std::sync::Mutex;
use std::time::{Duration, Instant};
use tspace_tangent::{MeshInput, Method, Options, generate};

struct Mesh {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

/// `n` triangles that all collapse to points or lines, sharing vertices.
fn degenerate(n: usize) -> Mesh {
    let vertices = n / 2 + 3;
    let positions = (0..vertices).map(|i| [(i % 7) as f32, 0.0, 0.0]).collect();
    let mut indices = Vec::with_capacity(n * 3);
    for t in 0..n as u32 {
        let a = t % vertices as u32;
        // Two corners on one vertex: zero area, zero UV area.
        indices.extend([a, a, (a + 1) % vertices as u32]);
    }
    Mesh {
        positions,
        normals: vec![[0.0, 0.0, 1.0]; vertices],
        uvs: (0..vertices).map(|i| [(i % 5) as f32, 0.0]).collect(),
        indices,
    }
}

/// `n` triangles around vertex 0: one vertex with `n` corners.
fn fan(n: usize) -> Mesh {
    let mut positions = vec![[0.0, 0.0, 0.0]];
    let mut uvs = vec![[0.5, 0.5]];
    for i in 0..=n {
        let a = i as f32 / n as f32 * std::f32::consts::TAU;
        positions.push([a.cos(), a.sin(), 0.0]);
        uvs.push([0.5 + 0.5 * a.cos(), 0.5 + 0.5 * a.sin()]);
    }
    let indices = (0..n as u32).flat_map(|i| [0, i + 1, i + 2]).collect();
    Mesh {
        normals: vec![[0.0, 0.0, 1.0]; positions.len()],
        positions,
        uvs,
        indices,
    }
}

/// A strip of `n` slivers: triangles whose height is a millionth of their length.
fn slivers(n: usize) -> Mesh {
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for i in 0..n / 2 + 2 {
        let x = i as f32;
        positions.push([x, 0.0, 0.0]);
        positions.push([x + 0.5, 1e-6, 0.0]);
        uvs.push([x, 0.0]);
        uvs.push([x + 0.5, 1e-6]);
    }
    let indices = (0..n as u32).flat_map(|i| [i, i + 1, i + 2]).collect();
    Mesh {
        normals: vec![[0.0, 0.0, 1.0]; positions.len()],
        positions,
        uvs,
        indices,
    }
}

fn run_once(mesh: &Mesh, options: &Options) -> Duration {
    let input = MeshInput {
        positions: &mesh.positions,
        normals: Some(&mesh.normals),
        uvs: Some(&mesh.uvs),
        indices: Some(&mesh.indices),
    };
    let started = Instant::now();
    let out = generate(&input, options).expect("valid input");
    let elapsed = started.elapsed();
    assert_eq!(out.corner_tangents(input.indices).len(), mesh.indices.len());
    elapsed
}

/// The tests of this file time one at a time: run side by side on two cores, they made each
/// other's timings (and so the ratios) swing by 2×.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Best times of the half and the full mesh, measured alternately so that a burst of noise
/// from elsewhere on the machine hits both sizes alike.
fn best_times(half: &Mesh, full: &Mesh, method: Method) -> (Duration, Duration) {
    let options = Options {
        method,
        ..Options::default()
    };
    let mut best = (Duration::MAX, Duration::MAX);
    for _ in 0..5 {
        best.0 = best.0.min(run_once(half, &options));
        best.1 = best.1.min(run_once(full, &options));
    }
    best
}

fn assert_linear(name: &str, make: fn(usize) -> Mesh, n: usize) {
    let _serial = ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    let (half_mesh, full_mesh) = (make(n / 2), make(n));
    for method in [Method::MikkTSpace, Method::Fast] {
        // Linear is 2; quadratic would be 4, on every attempt. A ratio over the bound is
        // measured again (up to three times in all), so that one disturbed measurement on a
        // shared machine does not decide; a quadratic algorithm fails all three.
        let mut ratios = Vec::new();
        let mut last = (Duration::ZERO, Duration::ZERO);
        for _ in 0..3 {
            last = best_times(&half_mesh, &full_mesh, method);
            let ratio = last.1.as_secs_f64() / last.0.as_secs_f64().max(1e-6);
            ratios.push(ratio);
            // Tiny absolute times are all noise.
            if ratio < 3.2 || last.1 < Duration::from_millis(5) {
                break;
            }
        }
        eprintln!(
            "{name} ({}): {} triangles {:?}, {} triangles {:?}, ratios {ratios:.2?}",
            method.name(),
            n / 2,
            last.0,
            n,
            last.1
        );
        let ratio = ratios.last().copied().unwrap_or_default();
        assert!(
            ratio < 3.2 || last.1 < Duration::from_millis(5),
            "{name} with {} scales like N^{:.1} (ratios {ratios:.2?})",
            method.name(),
            ratio.log2()
        );
    }
}

#[test]
fn degenerate_triangles_are_linear() {
    assert_linear("200k degenerate triangles", degenerate, 200_000);
}

#[test]
fn a_huge_fan_around_one_vertex_is_linear() {
    assert_linear("fan of 100k triangles", fan, 100_000);
}

#[test]
fn a_long_sliver_strip_is_linear() {
    assert_linear("strip of 200k slivers", slivers, 200_000);
}
