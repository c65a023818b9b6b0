//! Writes the JSON-heavy scene to a file, to measure the binary on it:
//!
//! ```sh
//! cargo run --release -p tspace-testkit --example json-heavy -- 50000 /tmp/json-heavy.glb
//! /usr/bin/time -v target/release/tspace process /tmp/json-heavy.glb -o /tmp/out.glb -q
//! ```
//!
//! `--without-normals` leaves NORMAL out, so that tspace generates one per primitive;
//! `--shared` makes every primitive name the same triangle's accessors.

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let without_normals = args.iter().any(|a| a == "--without-normals");
    let shared = args.iter().any(|a| a == "--shared");
    args.retain(|a| a != "--without-normals" && a != "--shared");
    let mut args = args.into_iter();
    let (Some(count), Some(path)) = (args.next(), args.next()) else {
        eprintln!("usage: json-heavy [--without-normals | --shared] PRIMITIVES OUT.glb");
        std::process::exit(2);
    };
    let Ok(count) = count.parse::<usize>() else {
        eprintln!("json-heavy: {count} is not a number of primitives");
        std::process::exit(2);
    };
    let glb = if shared {
        tspace_testkit::json_heavy::json_heavy_shared(count)
    } else if without_normals {
        tspace_testkit::json_heavy::json_heavy_without_normals(count)
    } else {
        tspace_testkit::json_heavy::json_heavy(count)
    };
    if let Err(e) = std::fs::write(&path, &glb) {
        eprintln!("json-heavy: {path}: {e}");
        std::process::exit(1);
    }
    println!("{path}: {count} primitives, {} bytes", glb.len());
}
