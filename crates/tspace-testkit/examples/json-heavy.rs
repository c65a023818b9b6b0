//! Writes the JSON-heavy scene to a file, to measure the binary on it:
//!
//! ```sh
//! cargo run --release -p tspace-testkit --example json-heavy -- 50000 /tmp/json-heavy.glb
//! /usr/bin/time -v target/release/tspace process /tmp/json-heavy.glb -o /tmp/out.glb -q
//! ```

fn main() {
    let mut args = std::env::args().skip(1);
    let (Some(count), Some(path)) = (args.next(), args.next()) else {
        eprintln!("usage: json-heavy PRIMITIVES OUT.glb");
        std::process::exit(2);
    };
    let Ok(count) = count.parse::<usize>() else {
        eprintln!("json-heavy: {count} is not a number of primitives");
        std::process::exit(2);
    };
    let glb = tspace_testkit::json_heavy::json_heavy(count);
    if let Err(e) = std::fs::write(&path, &glb) {
        eprintln!("json-heavy: {path}: {e}");
        std::process::exit(1);
    }
    println!("{path}: {count} primitives, {} bytes", glb.len());
}
