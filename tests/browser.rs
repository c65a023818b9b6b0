//! The page at `/` in a real browser: `tools/browser/page-test.mjs` drives Debian's chromium
//! (software WebGL) with playwright-core against a server started here, choosing
//! NormalTangentMirrorTest's .gltf and .bin (the counts `/v1/analyze` gives, the UV picture, a
//! 3D view that is not blank, with the mirrored triangles highlighted as the debug report counts
//! them, downloads of the scene with tangents and of the debug-coloured scene) and then the
//! .gltf alone (the missing buffer's problem title), with no console errors; where
//! `../shared/corpus` is present, DamagedHelmet, SciFiHelmet and spot too (the counts, a 3D view,
//! the highlights). Screenshots go to `target/browser-screenshots`.
//!
//! Skips, printing one line, where `scripts/install-browser` could not install chromium or
//! playwright-core; set `TSPACE_REQUIRE_BROWSER=1` to make that a failure.

use std::path::Path;
use std::process::Command;
use tspace::config::ServerConfig;
use tspace::server::start;

fn skip(line: &str) {
    assert!(
        std::env::var_os("TSPACE_REQUIRE_BROWSER").is_none(),
        "TSPACE_REQUIRE_BROWSER is set: {line}"
    );
    eprintln!("{line}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_page_shows_the_report_the_picture_and_a_download() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let modules = root.join("tools/browser/node_modules/playwright-core");
    let chromium = ["chromium", "chromium-browser"].iter().any(|name| {
        Command::new("sh")
            .args(["-c", &format!("command -v {name}")])
            .output()
            .is_ok_and(|o| o.status.success())
    });
    if !modules.exists() || !chromium {
        return skip(
            "browser: chromium or playwright-core not installed (scripts/install-browser), skipping",
        );
    }
    let running = start(ServerConfig::local()).await.expect("server starts");
    let base = format!("http://{}", running.addr);
    let script = root.join("tools/browser/page-test.mjs");
    let fixtures = root.join("fixtures");
    let shots = root.join("target/browser-screenshots");
    // The shared corpus beside the checkout, when it is there: its helmets and spot too.
    let corpus = root.join("../shared/corpus");
    let output = tokio::task::spawn_blocking(move || {
        let mut node = Command::new("node");
        node.arg(script).arg(base).arg(fixtures).arg(shots);
        if corpus.is_dir() {
            node.arg(corpus);
        }
        node.output()
    })
    .await
    .unwrap();
    running.shutdown().await.unwrap();
    let output = match output {
        Ok(output) => output,
        Err(e) => return skip(&format!("browser: node could not run ({e}), skipping")),
    };
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "the page test failed:\n{stdout}\n{stderr}"
    );
    eprint!("{stdout}");
}
