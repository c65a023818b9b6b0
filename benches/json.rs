//! The JSON of a JSON-heavy scene, read the ways tspace reads it, against serde_json on the
//! same text in the same process:
//!
//! - the input's document whole (`tspace_json::Document::parse`, every value kept with its
//!   span, for edits that leave the rest of the text as it was), against
//!   `serde_json::from_slice::<Value>`;
//! - tspace's own output, measured for the storage report (`sizes::measure_text`: the members
//!   measuring reads, found without a tree), after which the scene's report says what the file
//!   holds;
//! - the output checked and nothing kept (what a pruned parse does with the members it leaves
//!   out, and an edit with each text it inserts), against `serde_json::from_slice::<IgnoredAny>`,
//!   which checks the syntax and keeps nothing either (it does not look for repeated keys,
//!   which tspace refuses).
//!
//! The scene is `tspace_testkit::json_heavy(50_000)` (50,000 one-triangle primitives, each with
//! its own accessors: 29 MB of JSON in, 38 MB out). `cargo bench --bench json`;
//! `TSPACE_BENCH_ROUNDS=N` sets the rounds (default 15), `TSPACE_BENCH_QUICK=1` takes 5,000
//! primitives. The readers run in turn every round, so that background load hits them alike;
//! medians are printed and written to `bench-results/json.csv`.

use serde::de::IgnoredAny;
use std::fmt::Write as _;
use std::time::Instant;
use tspace::scene::SceneOptions;
use tspace::scene::gltf::{glb, load::NoResources, sizes};
use tspace::scene::input::{self, InputKind};
use tspace_testkit::fixtures::workspace_root;

fn rounds() -> usize {
    std::env::var("TSPACE_BENCH_ROUNDS")
        .ok()
        .and_then(|r| r.parse().ok())
        .filter(|&r| r > 0)
        .unwrap_or(15)
}

fn median(mut times: Vec<f64>) -> f64 {
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

/// One way of reading one text.
struct Reader<'a> {
    name: &'static str,
    text: &'a [u8],
    read: fn(&[u8]),
    times: Vec<f64>,
}

fn main() {
    let quick = std::env::var_os("TSPACE_BENCH_QUICK").is_some();
    let primitives = if quick { 5_000 } else { 50_000 };
    let scene = tspace_testkit::json_heavy::json_heavy(primitives);
    let processed = input::process(
        InputKind::Glb,
        &scene,
        &NoResources,
        &SceneOptions::default(),
    )
    .expect("the JSON-heavy scene processes");
    let output = processed.bytes.expect("the output, whole");
    let json_in = glb::parse(&scene).expect("the input is a GLB").json;
    let json_out = glb::parse(&output).expect("the output is a GLB").json;

    let mut readers = vec![
        Reader {
            name: "input, whole: tspace_json::Document::parse",
            text: json_in,
            read: |text| {
                std::hint::black_box(tspace_json::Document::parse(text).expect("parses"));
            },
            times: Vec::new(),
        },
        Reader {
            name: "input, whole: serde_json Value",
            text: json_in,
            read: |text| {
                let value: serde_json::Value = serde_json::from_slice(text).expect("parses");
                std::hint::black_box(value);
            },
            times: Vec::new(),
        },
        Reader {
            name: "output, measured for the storage report",
            text: json_out,
            read: |text| {
                std::hint::black_box(sizes::measure_text(text).expect("measures"));
            },
            times: Vec::new(),
        },
        Reader {
            name: "output, checked only: tspace_json",
            text: json_out,
            read: |text| {
                let nothing = tspace_json::parse_pruned(text, &|_, _| false);
                std::hint::black_box(nothing.expect("parses"));
            },
            times: Vec::new(),
        },
        Reader {
            name: "output, checked only: serde_json IgnoredAny",
            text: json_out,
            read: |text| {
                let nothing: IgnoredAny = serde_json::from_slice(text).expect("parses");
                std::hint::black_box(nothing);
            },
            times: Vec::new(),
        },
    ];
    // One untimed read each, then the rounds.
    for reader in &readers {
        (reader.read)(reader.text);
    }
    for _ in 0..rounds() {
        for reader in &mut readers {
            let start = Instant::now();
            (reader.read)(reader.text);
            reader.times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }

    println!(
        "JSON of {primitives} one-triangle primitives: {:.1} MB in, {:.1} MB out; medians of {} rounds",
        json_in.len() as f64 / 1e6,
        json_out.len() as f64 / 1e6,
        rounds()
    );
    let mut csv = String::from("reader,megabytes,median_ms,megabytes_per_s\n");
    let medians: Vec<f64> = readers.iter().map(|r| median(r.times.clone())).collect();
    for (reader, &ms) in readers.iter().zip(&medians) {
        let mb = reader.text.len() as f64 / 1e6;
        println!(
            "  {:<46} {ms:>8.1} ms  {:>6.0} MB/s",
            reader.name,
            mb / (ms / 1e3)
        );
        let _ = writeln!(
            csv,
            "{},{mb:.3},{ms:.3},{:.1}",
            reader.name,
            mb / (ms / 1e3)
        );
    }
    println!(
        "  ratios: whole parse / serde_json Value {:.2}; measured / whole (per byte) {:.2}; checked only / serde_json IgnoredAny {:.2}",
        medians[0] / medians[1],
        (medians[2] / json_out.len() as f64) / (medians[0] / json_in.len() as f64),
        medians[3] / medians[4],
    );
    let dir = workspace_root().join("bench-results");
    std::fs::create_dir_all(&dir).expect("bench-results");
    std::fs::write(dir.join("json.csv"), csv).expect("writes the CSV");
    println!("wrote {}", dir.join("json.csv").display());
}
