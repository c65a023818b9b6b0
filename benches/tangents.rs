//! Benchmarks of the tangent core against `bevy_mikktspace` and meshoptimizer: throughput,
//! parallel speedup, scratch heap, and tangent error against time.
//!
//! `cargo bench --bench tangents` (or plain `cargo bench`) runs a generated UV sphere and torus
//! of about 20k, 200k and 2M triangles and the largest corpus meshes (`../shared/corpus`,
//! skipped with a note when absent) through every contender, prints the tables and writes
//! `bench-results/{throughput,time_vs_error}.csv` and `bench-results/time_vs_error.svg` (copied
//! to `docs/` after a complete run).
//!
//! Settings, by environment variable:
//! - `TSPACE_BENCH_QUICK=1`: only the 20k shapes (and the corpus), few samples: a smoke test.
//! - `TSPACE_BENCH_SIZES=20000,200000`: which shape sizes to run.
//! - `TSPACE_BENCH_CORPUS=0`: leave out the corpus meshes.
//! - `TSPACE_BENCH_CONTENDERS=mikk_1t,bevy`: only these contenders (ids as in the CSV header),
//!   e.g. to profile one of them.
//! - `TSPACE_BENCH_FILTER=torus`, or `cargo bench --bench tangents -- torus`: only meshes whose
//!   name contains the text.
//!
//! Timing is meant to hold up on a small, busy machine: the contenders run in interleaved
//! rounds (the order rotating every round), so a burst of background load hits them all alike,
//! and the tables show medians. A first, untimed run of each contender per mesh warms caches
//! and is the one whose heap use and error are measured.

mod support;

use tspace_testkit::shapes;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;
use support::alloc::{CountingAllocator, HeapUse, peak_during};
use support::chart;
use support::contenders::{
    BenchMesh, Contender, ErrorStats, Family, deviation, error_against_exact, run,
};
use support::corpus;
use support::cpu;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

const FULL_SIZES: [usize; 3] = [20_000, 200_000, 2_000_000];

/// Targets from the issue, checked at the end of a run.
// Issue 20's targets for the core: ≥ 20× bevy_mikktspace and ≥ 1.3× meshoptimizer's
// `Compatible` on every mesh, and `fast` ≥ 1.2× `mikktspace` (it does less work).
const TARGET_MIKK_OVER_BEVY: f64 = 20.0;
const TARGET_MIKK_OVER_MESHOPT: f64 = 1.3;
const TARGET_FAST_OVER_MIKK: f64 = 1.2;
const TARGET_PARALLEL_SPEEDUP: f64 = 1.7;
const TARGET_EXTRA_HEAP_PER_TRIANGLE: f64 = 150.0;
/// The parallel speedup target applies to the large meshes only: on small ones the fixed cost
/// of waking the pool is a visible share.
const SPEEDUP_TARGET_MIN_TRIANGLES: usize = 1_000_000;
/// Smallest mesh for which the idle-core speedup estimate is shown (see
/// `MeshReport::idle_two_core_speedup`).
const IDLE_ESTIMATE_MIN_TRIANGLES: usize = 100_000;

struct Config {
    sizes: Vec<usize>,
    corpus: bool,
    filter: Option<String>,
    contenders: Vec<Contender>,
    quick: bool,
    /// Time each contender may spend on one mesh once it has its minimum samples.
    budget_seconds: f64,
    min_samples: usize,
    max_samples: usize,
}

impl Config {
    fn from_env_and_args() -> Config {
        let flag = |name: &str| std::env::var(name).is_ok_and(|v| !v.is_empty() && v != "0");
        let quick = flag("TSPACE_BENCH_QUICK");
        let sizes = match std::env::var("TSPACE_BENCH_SIZES") {
            Ok(list) => list
                .split(',')
                .filter_map(|s| match s.trim().replace('_', "").parse::<usize>() {
                    Ok(n) if n > 0 => Some(n),
                    _ => {
                        eprintln!("note: ignoring size {s:?} in TSPACE_BENCH_SIZES");
                        None
                    }
                })
                .collect(),
            Err(_) if quick => vec![FULL_SIZES[0]],
            Err(_) => FULL_SIZES.to_vec(),
        };
        let corpus = std::env::var("TSPACE_BENCH_CORPUS").map_or(true, |v| v != "0");
        // `cargo bench` passes `--bench`; any other plain argument is a name filter.
        let filter = std::env::args()
            .skip(1)
            .find(|a| !a.starts_with('-'))
            .or_else(|| std::env::var("TSPACE_BENCH_FILTER").ok())
            .filter(|f| !f.is_empty());
        let contenders = match std::env::var("TSPACE_BENCH_CONTENDERS") {
            Ok(list) => {
                let wanted: Vec<&str> = list.split(',').map(str::trim).collect();
                for id in &wanted {
                    if !Contender::ALL.iter().any(|&c| csv_id(c) == *id) {
                        eprintln!("note: unknown contender {id:?} in TSPACE_BENCH_CONTENDERS");
                    }
                }
                Contender::ALL
                    .into_iter()
                    .filter(|&c| wanted.contains(&csv_id(c)))
                    .collect()
            }
            Err(_) => Contender::ALL.to_vec(),
        };
        Config {
            sizes,
            corpus,
            filter,
            contenders,
            quick,
            budget_seconds: if quick { 0.3 } else { 2.0 },
            min_samples: if quick { 3 } else { 7 },
            max_samples: if quick { 15 } else { 41 },
        }
    }

    fn selects(&self, name: &str) -> bool {
        self.filter.as_deref().is_none_or(|f| name.contains(f))
    }

    /// Whether this run covers everything, so its chart may replace the committed one.
    fn is_complete(&self) -> bool {
        !self.quick
            && self.filter.is_none()
            && self.corpus
            && self.sizes == FULL_SIZES
            && self.contenders == Contender::ALL
    }
}

/// Everything measured for one contender on one mesh.
struct Measured {
    contender: Contender,
    /// Seconds per run, timed rounds only.
    samples: Vec<f64>,
    /// Scheduler accounting of the same runs, where the system provides it.
    usage: Vec<cpu::Usage>,
    /// Seconds of the untimed first run, to size the sampling.
    first_run: f64,
    heap: Option<HeapUse>,
    error: Option<ErrorStats>,
    failure: Option<String>,
}

fn median(values: impl Iterator<Item = f64>) -> Option<f64> {
    let mut s: Vec<f64> = values.collect();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(s[n / 2]),
        _ => Some((s[n / 2 - 1] + s[n / 2]) / 2.0),
    }
}

impl Measured {
    fn median(&self) -> Option<f64> {
        median(self.samples.iter().copied())
    }

    /// Median time the run would take on `cores` otherwise idle cores, from CPU accounting.
    fn idle_estimate(&self, cores: usize) -> Option<f64> {
        median(self.usage.iter().map(|u| u.idle_estimate(cores)))
    }

    fn wants_more(&self, config: &Config) -> bool {
        if self.failure.is_some() {
            return false;
        }
        // A contender that takes seconds per run (bevy_mikktspace on 2M triangles) settles for
        // fewer samples; the whole run must stay within minutes.
        let min = if self.first_run > 1.0 {
            3
        } else {
            config.min_samples
        };
        let spent: f64 = self.samples.iter().sum();
        self.samples.len() < min
            || (spent < config.budget_seconds && self.samples.len() < config.max_samples)
    }
}

struct MeshReport {
    name: String,
    family: Family,
    nominal_triangles: Option<usize>,
    triangles: usize,
    measured: Vec<Measured>,
    /// Largest angle between tspace's MikkTSpace and bevy_mikktspace tangents: both implement
    /// the same algorithm, so this should be tiny.
    mikk_vs_bevy_degrees: Option<f64>,
    /// How far meshopt's `Compatible` mode lands from bevy_mikktspace: the largest angle, and
    /// the share of corners more than 0.01° away (the tolerance for "the same").
    compatible_vs_bevy: Option<(f64, f64)>,
}

impl MeshReport {
    fn get(&self, contender: Contender) -> Option<&Measured> {
        self.measured.iter().find(|m| m.contender == contender)
    }

    /// Million triangles per second, from the median time.
    fn throughput(&self, contender: Contender) -> Option<f64> {
        let median = self.get(contender)?.median()?;
        Some(self.triangles as f64 / median / 1e6)
    }

    /// How many times faster `a` is than `b`.
    fn speed_ratio(&self, a: Contender, b: Contender) -> Option<f64> {
        Some(self.throughput(a)? / self.throughput(b)?)
    }

    /// The speedup `parallel` would have over `single` on two idle cores, estimated from the
    /// scheduler's CPU accounting (see `support::cpu`). Left out on small meshes, where rayon's
    /// idle workers spinning between jobs is a large share of the pool's CPU time and the
    /// estimate means little.
    fn idle_two_core_speedup(&self, parallel: Contender, single: Contender) -> Option<f64> {
        if self.triangles < IDLE_ESTIMATE_MIN_TRIANGLES {
            return None;
        }
        let single = self.get(single)?.idle_estimate(1)?;
        let parallel = self.get(parallel)?.idle_estimate(2)?;
        Some(single / parallel)
    }

    /// Share of the single-threaded contenders' timed wall-clock time during which the bench
    /// thread was ready to run but another process held the CPU: how much the machine's other
    /// load disturbed this mesh.
    fn wait_share(&self) -> Option<f64> {
        let single = || self.measured.iter().filter(|m| !m.contender.is_parallel());
        let wall: f64 = single().flat_map(|m| &m.samples).sum();
        let waited: f64 = single()
            .flat_map(|m| &m.usage)
            .map(|u| u.caller_waited)
            .sum();
        let any = single().any(|m| !m.usage.is_empty());
        (any && wall > 0.0).then(|| waited / wall)
    }

    /// Share of the pool threads' time, in the parallel contenders' runs, spent ready to run but
    /// waiting for a CPU: when other processes hold the second core, this is where it shows.
    fn pool_wait_share(&self) -> Option<f64> {
        let usage = || {
            self.measured
                .iter()
                .filter(|m| m.contender.is_parallel())
                .flat_map(|m| &m.usage)
        };
        let waited: f64 = usage().map(|u| u.others_waited).sum();
        let busy: f64 = usage().map(|u| u.others_cpu).sum();
        (waited + busy > 0.0).then(|| waited / (waited + busy))
    }

    fn extra_heap_per_triangle(&self, contender: Contender) -> Option<f64> {
        let heap = self.get(contender)?.heap?;
        Some(heap.extra() as f64 / self.triangles as f64)
    }

    fn size_label(&self) -> String {
        self.nominal_triangles
            .map_or_else(|| format_count(self.triangles), format_count)
    }
}

fn format_count(n: usize) -> String {
    if n >= 1_000_000 {
        format!("{}M", (n as f64 / 1e6 * 10.0).round() / 10.0)
    } else if n >= 1000 {
        format!("{}k", (n as f64 / 1e3).round())
    } else {
        n.to_string()
    }
}

fn from_shape(shape: shapes::Shape, nominal: usize) -> BenchMesh {
    let family = if shape.name.starts_with("sphere") {
        Family::Sphere
    } else {
        Family::Torus
    };
    BenchMesh {
        name: shape.name,
        family,
        nominal_triangles: Some(nominal),
        positions: shape.positions,
        normals: shape.normals,
        uvs: shape.uvs,
        indices: shape.indices,
        exact_tangents: Some(shape.exact_tangents),
    }
}

/// Runs every contender on one mesh: a first run each for heap, error and cross-checks, then
/// interleaved timed rounds.
fn bench_mesh(mesh: &BenchMesh, config: &Config) -> MeshReport {
    let started = Instant::now();
    let triangles = mesh.triangle_count();
    eprintln!("{} ({triangles} triangles)...", mesh.name);
    let mut measured: Vec<Measured> = config
        .contenders
        .iter()
        .map(|&contender| Measured {
            contender,
            samples: Vec::new(),
            usage: Vec::new(),
            first_run: 0.0,
            heap: None,
            error: None,
            failure: None,
        })
        .collect();

    // The outputs to compare with bevy_mikktspace are kept until every contender has run.
    let mut mikk_corners = None;
    let mut bevy_corners = None;
    let mut compatible_corners = None;
    for m in &mut measured {
        let start = Instant::now();
        let (output, heap) = peak_during(|| run(m.contender, mesh));
        m.first_run = start.elapsed().as_secs_f64();
        let output = match output {
            Ok(output) => output,
            Err(e) => {
                eprintln!(
                    "  note: {} failed on {}: {e}",
                    m.contender.label(),
                    mesh.name
                );
                m.failure = Some(e);
                continue;
            }
        };
        if m.contender.heap_is_visible() {
            m.heap = Some(heap);
        }
        if let Some(exact) = &mesh.exact_tangents {
            m.error = error_against_exact(&output.corners(mesh), &mesh.indices, exact);
        }
        match m.contender {
            Contender::MikkSingle => mikk_corners = Some(output),
            Contender::Bevy => bevy_corners = Some(output),
            Contender::MeshoptCompatible => compatible_corners = Some(output),
            _ => {}
        }
    }
    let against_bevy = |other: &Option<support::contenders::Output>| match (other, &bevy_corners) {
        (Some(other), Some(bevy)) => Some(deviation(&other.corners(mesh), &bevy.corners(mesh))),
        _ => None,
    };
    let mikk_vs_bevy_degrees = against_bevy(&mikk_corners).map(|(max, _)| max);
    let compatible_vs_bevy = against_bevy(&compatible_corners);
    drop((mikk_corners, bevy_corners, compatible_corners));

    let count = measured.len();
    for round in 0.. {
        let mut ran_any = false;
        for k in 0..count {
            let m = &mut measured[(k + round) % count];
            if !m.wants_more(config) {
                continue;
            }
            ran_any = true;
            let before = cpu::snapshot();
            let start = Instant::now();
            let output = std::hint::black_box(run(m.contender, mesh));
            let seconds = start.elapsed().as_secs_f64();
            let after = cpu::snapshot();
            // Freeing the output stays outside the timed region, for every contender alike.
            match output {
                Ok(output) => {
                    m.samples.push(seconds);
                    if let (Some(before), Some(after)) = (before, after) {
                        m.usage.extend(cpu::usage_between(&before, &after));
                    }
                    drop(output);
                }
                Err(e) => m.failure = Some(e),
            }
        }
        if !ran_any {
            break;
        }
    }

    let report = MeshReport {
        name: mesh.name.clone(),
        family: mesh.family,
        nominal_triangles: mesh.nominal_triangles,
        triangles,
        measured,
        mikk_vs_bevy_degrees,
        compatible_vs_bevy,
    };
    let mut line = String::new();
    for c in [
        Contender::MikkSingle,
        Contender::MikkParallel,
        Contender::FastSingle,
        Contender::Bevy,
        Contender::MeshoptCompatible,
    ] {
        let _ = write!(line, " {} {}", c.label(), fmt(report.throughput(c), 2));
    }
    eprintln!(
        "  M tris/s:{line}  ({:.1} s)",
        started.elapsed().as_secs_f64()
    );
    report
}

fn fmt(value: Option<f64>, decimals: usize) -> String {
    value.map_or_else(|| "-".to_string(), |v| format!("{v:.decimals$}"))
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".to_string())
}

fn throughput_table(reports: &[MeshReport]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Throughput, M triangles/s (median of interleaved runs; 1t = one thread, par = rayon)"
    );
    let _ = write!(out, "{:<20} {:>9}", "mesh", "tris");
    for c in Contender::ALL {
        let _ = write!(out, " {:>9}", c.label());
    }
    let _ = writeln!(out, " {:>8}", "runs");
    for r in reports {
        let _ = write!(out, "{:<20} {:>9}", r.name, r.triangles);
        for c in Contender::ALL {
            let _ = write!(out, " {:>9}", fmt(r.throughput(c), 2));
        }
        // Fewest samples of any contender, usually bevy_mikktspace's.
        let runs = r
            .measured
            .iter()
            .map(|m| m.samples.len())
            .min()
            .unwrap_or(0);
        let _ = writeln!(out, " {runs:>8}");
    }
    out
}

fn ratio_table(reports: &[MeshReport]) -> String {
    use Contender::*;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Ratios of throughput (higher is better for the first named); targets: mikk/bevy >= {TARGET_MIKK_OVER_BEVY}, \
         mikk/mo-compat >= {TARGET_MIKK_OVER_MESHOPT}, fast/mikk >= {TARGET_FAST_OVER_MIKK}, mikk par x >= {TARGET_PARALLEL_SPEEDUP} on 2M"
    );
    let _ = writeln!(
        out,
        "(par x: measured wall-clock speedup; idle x: speedup on two idle cores estimated from the \
         scheduler's CPU time, from 100k triangles; wait %: share of the single-thread runs' time the \
         bench thread waited for a CPU held by other processes; pool wait %: the same for rayon's \
         threads in the parallel runs)"
    );
    let _ = writeln!(
        out,
        "{:<20} {:>10} {:>14} {:>10} {:>14} {:>11} {:>11} {:>11} {:>11} {:>8} {:>11} {:>15} {:>20} {:>9}",
        "mesh",
        "mikk/bevy",
        "mikk/mo-compat",
        "fast/mikk",
        "fast/mo-compat",
        "mikk par x",
        "fast par x",
        "mikk idle x",
        "fast idle x",
        "wait %",
        "pool wait %",
        "mikk~bevy max°",
        "mo-compat~bevy max°",
        ">0.01° %"
    );
    for r in reports {
        let _ = writeln!(
            out,
            "{:<20} {:>10} {:>14} {:>10} {:>14} {:>11} {:>11} {:>11} {:>11} {:>8} {:>11} {:>15} {:>20} {:>9}",
            r.name,
            fmt(r.speed_ratio(MikkSingle, Bevy), 1),
            fmt(r.speed_ratio(MikkSingle, MeshoptCompatible), 2),
            fmt(r.speed_ratio(FastSingle, MikkSingle), 2),
            fmt(r.speed_ratio(FastSingle, MeshoptCompatible), 2),
            fmt(r.speed_ratio(MikkParallel, MikkSingle), 2),
            fmt(r.speed_ratio(FastParallel, FastSingle), 2),
            fmt(r.idle_two_core_speedup(MikkParallel, MikkSingle), 2),
            fmt(r.idle_two_core_speedup(FastParallel, FastSingle), 2),
            fmt(r.wait_share().map(|w| w * 100.0), 1),
            fmt(r.pool_wait_share().map(|w| w * 100.0), 1),
            r.mikk_vs_bevy_degrees
                .map_or_else(|| "-".to_string(), |d| format!("{d:.2e}")),
            r.compatible_vs_bevy
                .map_or_else(|| "-".to_string(), |(d, _)| format!("{d:.2e}")),
            fmt(r.compatible_vs_bevy.map(|(_, share)| share * 100.0), 3),
        );
    }
    out
}

fn memory_table(reports: &[MeshReport]) -> String {
    let heap_contenders: Vec<Contender> = Contender::ALL
        .into_iter()
        .filter(|c| c.heap_is_visible())
        .collect();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Extra heap: peak during the call beyond input and returned output, bytes/triangle \
         (target <= {TARGET_EXTRA_HEAP_PER_TRIANGLE} for tspace; meshopt allocates in C++, not seen)"
    );
    let _ = write!(out, "{:<20} {:>9}", "mesh", "tris");
    for c in &heap_contenders {
        let _ = write!(out, " {:>9}", c.label());
    }
    let _ = writeln!(out, " {:>14}", "mikk output");
    for r in reports {
        let _ = write!(out, "{:<20} {:>9}", r.name, r.triangles);
        for &c in &heap_contenders {
            let _ = write!(out, " {:>9}", fmt(r.extra_heap_per_triangle(c), 1));
        }
        let output = r
            .get(Contender::MikkSingle)
            .and_then(|m| m.heap)
            .map(|h| h.retained as f64 / r.triangles as f64);
        let _ = writeln!(out, " {:>14}", fmt(output, 1));
    }
    out
}

/// The single-threaded contenders, in the order of the error table and chart.
const ERROR_METHODS: [Contender; 7] = [
    Contender::MikkSingle,
    Contender::FastSingle,
    Contender::FastAreaSingle,
    Contender::AxisSingle,
    Contender::Bevy,
    Contender::Meshopt,
    Contender::MeshoptCompatible,
];

fn error_table(reports: &[MeshReport]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Time against error: angle between each corner's tangent and its vertex's exact dP/du \
         (poles skipped), single thread"
    );
    let _ = writeln!(
        out,
        "{:<18} {:<20} {:>10} {:>9} {:>11} {:>11} {:>11}",
        "mesh", "method", "time ms", "M tris/s", "mean°", "p99°", "max°"
    );
    for r in reports.iter().filter(|r| r.family != Family::Corpus) {
        for c in ERROR_METHODS {
            let Some(m) = r.get(c) else { continue };
            let time_ms = m.median().map(|s| s * 1e3);
            let error = m.error;
            let _ = writeln!(
                out,
                "{:<18} {:<20} {:>10} {:>9} {:>11} {:>11} {:>11}",
                r.name,
                c.method_name(),
                fmt(time_ms, 2),
                fmt(r.throughput(c), 2),
                error.map_or_else(|| "-".into(), |e| format!("{:.3e}", e.mean)),
                error.map_or_else(|| "-".into(), |e| format!("{:.3e}", e.p99)),
                error.map_or_else(|| "-".into(), |e| format!("{:.3e}", e.max)),
            );
        }
    }
    out
}

/// The verdict on each target, with the worst case.
fn targets_summary(reports: &[MeshReport]) -> String {
    use Contender::*;
    let mut out = String::new();
    let _ = writeln!(out, "Targets");
    let mut check = |name: &str, values: Vec<(String, f64)>, ok: &dyn Fn(f64) -> bool| {
        if values.is_empty() {
            let _ = writeln!(out, "  {name}: not measured in this run");
            return;
        }
        let failing: Vec<String> = values
            .iter()
            .filter(|(_, v)| !ok(*v))
            .map(|(mesh, v)| format!("{mesh} {v:.2}"))
            .collect();
        let (lo, hi) = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |acc, (_, v)| {
                (acc.0.min(*v), acc.1.max(*v))
            });
        let verdict = if failing.is_empty() {
            "MET".to_string()
        } else {
            format!("MISSED on {}", failing.join(", "))
        };
        let _ = writeln!(
            out,
            "  {name}: {verdict} (range {lo:.2} .. {hi:.2} over {} meshes)",
            values.len()
        );
    };
    let series = |f: &dyn Fn(&MeshReport) -> Option<f64>, only_large: bool| {
        reports
            .iter()
            .filter(|r| !only_large || r.triangles >= SPEEDUP_TARGET_MIN_TRIANGLES)
            .filter_map(|r| Some((r.name.clone(), f(r)?)))
            .collect::<Vec<_>>()
    };
    check(
        &format!("mikktspace 1t >= {TARGET_MIKK_OVER_BEVY}x bevy_mikktspace"),
        series(&|r| r.speed_ratio(MikkSingle, Bevy), false),
        &|v| v >= TARGET_MIKK_OVER_BEVY,
    );
    check(
        &format!("mikktspace 1t >= {TARGET_MIKK_OVER_MESHOPT}x meshopt Compatible"),
        series(&|r| r.speed_ratio(MikkSingle, MeshoptCompatible), false),
        &|v| v >= TARGET_MIKK_OVER_MESHOPT,
    );
    check(
        &format!("fast 1t >= {TARGET_FAST_OVER_MIKK}x mikktspace 1t"),
        series(&|r| r.speed_ratio(FastSingle, MikkSingle), false),
        &|v| v >= TARGET_FAST_OVER_MIKK,
    );
    check(
        "fast 1t faster than meshopt Compatible",
        series(&|r| r.speed_ratio(FastSingle, MeshoptCompatible), false),
        &|v| v > 1.0,
    );
    check(
        "mikktspace parallel speedup >= 1.7x on 2M triangles (measured)",
        series(&|r| r.speed_ratio(MikkParallel, MikkSingle), true),
        &|v| v >= TARGET_PARALLEL_SPEEDUP,
    );
    check(
        "mikktspace parallel speedup >= 1.7x on 2M triangles (idle-core estimate)",
        series(&|r| r.idle_two_core_speedup(MikkParallel, MikkSingle), true),
        &|v| v >= TARGET_PARALLEL_SPEEDUP,
    );
    for c in [
        MikkSingle,
        MikkParallel,
        FastSingle,
        FastParallel,
        AxisSingle,
    ] {
        check(
            &format!("extra heap of {} <= 150 B/tri", c.label()),
            series(&|r| r.extra_heap_per_triangle(c), false),
            &|v| v <= TARGET_EXTRA_HEAP_PER_TRIANGLE,
        );
    }
    out
}

fn throughput_csv(reports: &[MeshReport]) -> String {
    use Contender::*;
    let mut out = String::from("mesh,family,triangles");
    for c in Contender::ALL {
        let id = csv_id(c);
        let _ = write!(out, ",{id}_mtris_per_s,{id}_median_ms,{id}_runs");
    }
    out.push_str(
        ",mikk_over_bevy,mikk_over_meshopt_compatible,fast_over_mikk,fast_over_meshopt_compatible,\
         mikk_parallel_speedup,fast_parallel_speedup,mikk_parallel_idle_estimate,\
         fast_parallel_idle_estimate,cpu_wait_share,pool_wait_share,mikk_extra_heap_bytes_per_tri,\
         mikk_parallel_extra_heap_bytes_per_tri,mikk_vs_bevy_max_deg,\
         meshopt_compatible_vs_bevy_max_deg,meshopt_compatible_vs_bevy_share_over_0_01_deg\n",
    );
    let num = |v: Option<f64>| v.map_or_else(String::new, |v| format!("{v:.6}"));
    for r in reports {
        let _ = write!(out, "{},{},{}", r.name, r.family.name(), r.triangles);
        for c in Contender::ALL {
            let m = r.get(c);
            let _ = write!(
                out,
                ",{},{},{}",
                num(r.throughput(c)),
                num(m.and_then(Measured::median).map(|s| s * 1e3)),
                m.map_or(0, |m| m.samples.len())
            );
        }
        let _ = writeln!(
            out,
            ",{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            num(r.speed_ratio(MikkSingle, Bevy)),
            num(r.speed_ratio(MikkSingle, MeshoptCompatible)),
            num(r.speed_ratio(FastSingle, MikkSingle)),
            num(r.speed_ratio(FastSingle, MeshoptCompatible)),
            num(r.speed_ratio(MikkParallel, MikkSingle)),
            num(r.speed_ratio(FastParallel, FastSingle)),
            num(r.idle_two_core_speedup(MikkParallel, MikkSingle)),
            num(r.idle_two_core_speedup(FastParallel, FastSingle)),
            num(r.wait_share()),
            num(r.pool_wait_share()),
            num(r.extra_heap_per_triangle(MikkSingle)),
            num(r.extra_heap_per_triangle(MikkParallel)),
            num(r.mikk_vs_bevy_degrees),
            num(r.compatible_vs_bevy.map(|(max, _)| max)),
            num(r.compatible_vs_bevy.map(|(_, share)| share)),
        );
    }
    out
}

fn csv_id(c: Contender) -> &'static str {
    match c {
        Contender::MikkSingle => "mikk_1t",
        Contender::MikkParallel => "mikk_par",
        Contender::FastSingle => "fast_1t",
        Contender::FastParallel => "fast_par",
        Contender::FastAreaSingle => "fast_area_1t",
        Contender::AxisSingle => "axis_1t",
        Contender::Bevy => "bevy",
        Contender::Meshopt => "meshopt",
        Contender::MeshoptCompatible => "meshopt_compatible",
    }
}

fn error_csv(reports: &[MeshReport]) -> String {
    let mut out = String::from(
        "mesh,family,triangles,method,time_ms,mtris_per_s,mean_deg,p99_deg,max_deg,corners\n",
    );
    let num = |v: Option<f64>| v.map_or_else(String::new, |v| format!("{v:.6e}"));
    for r in reports.iter().filter(|r| r.family != Family::Corpus) {
        for c in ERROR_METHODS {
            let Some(m) = r.get(c) else { continue };
            let e = m.error;
            let _ = writeln!(
                out,
                "{},{},{},{},{},{},{},{},{},{}",
                r.name,
                r.family.name(),
                r.triangles,
                c.method_name(),
                num(m.median().map(|s| s * 1e3)),
                num(r.throughput(c)),
                num(e.map(|e| e.mean)),
                num(e.map(|e| e.p99)),
                num(e.map(|e| e.max)),
                e.map_or(0, |e| e.corners),
            );
        }
    }
    out
}

fn chart_points(reports: &[MeshReport]) -> Vec<chart::Point> {
    let mut points = Vec::new();
    for c in ERROR_METHODS {
        for r in reports.iter().filter(|r| r.family != Family::Corpus) {
            let Some(m) = r.get(c) else { continue };
            let (Some(median), Some(error)) = (m.median(), m.error) else {
                continue;
            };
            points.push(chart::Point {
                method: c.method_name(),
                family: r.family,
                size_label: r.size_label(),
                time_ms: median * 1e3,
                mean_error_degrees: error.mean,
            });
        }
    }
    points
}

/// Writes a result file; a failure is reported and the bench goes on.
fn write_result(path: &Path, contents: &str) {
    match std::fs::write(path, contents) {
        Ok(()) => println!("wrote {}", path.display()),
        Err(e) => eprintln!("warning: cannot write {}: {e}", path.display()),
    }
}

/// Fixes glibc's thresholds so that every contender's freed blocks are reused by its next call.
/// By default glibc raises its mapping and trimming thresholds to the largest block freed so
/// far, so whether a call's buffers come from the heap or from fresh pages (faulted in and
/// zeroed by the kernel, a tenth of a call or more) depends on what every earlier call
/// allocated: one more 1 MiB buffer in one contender made the whole run fault ten times as
/// often, slowing meshoptimizer's calls as well as ours, and two runs of one binary differed
/// by a third. `TSPACE_BENCH_MALLOC=default` leaves the thresholds alone.
fn keep_freed_memory_for_reuse() {
    if std::env::var("TSPACE_BENCH_MALLOC").is_ok_and(|v| v == "default") {
        println!("allocator: glibc's default thresholds (TSPACE_BENCH_MALLOC=default)");
        return;
    }
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes the allocator's thresholds; it is thread-safe.
    unsafe {
        // The largest mapping threshold glibc accepts on 64-bit: blocks up to 32 MiB come from
        // the heaps (the 2M meshes' largest arrays are mapped afresh every call, for every
        // contender alike), and a heap's free top is kept.
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
    }
    println!(
        "allocator: freed blocks under 32 MiB kept for reuse (TSPACE_BENCH_MALLOC=default to not)"
    );
}

fn main() {
    let config = Config::from_env_and_args();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let threads = std::thread::available_parallelism().map_or(1, usize::from);
    // Start rayon's pool now, so that neither its start-up time nor its memory is charged to
    // the first parallel contender.
    rayon::broadcast(|_| ());
    println!(
        "tspace tangent benchmarks: {threads} hardware threads, {} rayon threads, load average {} at start",
        rayon::current_num_threads(),
        load_average()
    );
    println!(
        "sizes {:?}, corpus {}, filter {:?}, per-contender budget {} s, {}..{} samples{}",
        config.sizes,
        if config.corpus { "on" } else { "off" },
        config.filter,
        config.budget_seconds,
        config.min_samples,
        config.max_samples,
        if config.quick { " (quick)" } else { "" }
    );
    keep_freed_memory_for_reuse();
    let started = Instant::now();

    let mut reports = Vec::new();
    for &size in &config.sizes {
        for shape in shapes::shapes_of_size(size) {
            let mesh = from_shape(shape, size);
            if config.selects(&mesh.name) {
                reports.push(bench_mesh(&mesh, &config));
            }
        }
    }
    if config.corpus {
        let folder = root.join("../shared/corpus");
        if folder.is_dir() {
            for (name, relative) in corpus::FILES {
                if !config.selects(name) {
                    continue;
                }
                match corpus::load(name, &folder.join(relative)) {
                    Ok(mesh) => reports.push(bench_mesh(&mesh, &config)),
                    Err(e) => eprintln!("note: skipping corpus mesh {name}: {e}"),
                }
            }
        } else {
            eprintln!(
                "note: corpus folder {} is absent; corpus meshes skipped",
                folder.display()
            );
        }
    }

    println!();
    println!("{}", throughput_table(&reports));
    println!("{}", ratio_table(&reports));
    println!("{}", memory_table(&reports));
    println!("{}", error_table(&reports));
    println!("{}", targets_summary(&reports));
    println!(
        "total {:.0} s, load average {} at end",
        started.elapsed().as_secs_f64(),
        load_average()
    );

    let results = root.join("bench-results");
    if let Err(e) = std::fs::create_dir_all(&results) {
        eprintln!("warning: cannot create {}: {e}", results.display());
        return;
    }
    write_result(&results.join("throughput.csv"), &throughput_csv(&reports));
    write_result(&results.join("time_vs_error.csv"), &error_csv(&reports));
    let points = chart_points(&reports);
    if points.is_empty() {
        return;
    }
    let svg = results.join("time_vs_error.svg");
    match chart::draw(&svg, &points, Contender::MikkSingle.method_name()) {
        Ok(()) => println!("wrote {}", svg.display()),
        Err(e) => {
            eprintln!("warning: cannot draw {}: {e}", svg.display());
            return;
        }
    }
    // Only a complete run may replace the chart the README links to.
    if config.is_complete() {
        let docs = root.join("docs");
        let copy = std::fs::create_dir_all(&docs)
            .and_then(|()| std::fs::copy(&svg, docs.join("time_vs_error.svg")));
        match copy {
            Ok(_) => println!("copied to {}", docs.join("time_vs_error.svg").display()),
            Err(e) => eprintln!("warning: cannot copy the chart to {}: {e}", docs.display()),
        }
    }
}
