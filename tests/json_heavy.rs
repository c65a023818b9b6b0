//! Issue 20's JSON-heavy target: a scene of many one-triangle primitives, each with accessors and
//! buffer views of its own (`tspace_testkit::json_heavy`), peaks at most ten times its size in
//! `tspace process` and in `tspace analyze`.
//!
//! The measure is the child's peak resident set, from `wait4`: what the target is about and what
//! an operator sees. The same command's peak on a one-primitive scene is taken off first, since
//! the binary's own pages (about 8 MiB) do not grow with the scene; on a body of a few megabytes
//! they would otherwise decide the ratio. Transparent huge pages are turned off in the children,
//! so that the kernel's policy cannot round the peak up by megabytes. The scene is small enough
//! to run in a second, and large enough that its per-primitive memory is most of the peak (the
//! ratio is the same at 50,000 primitives, 36 MB).
//!
//! A child's peak starts at its parent's when it is forked (Linux keeps the larger across
//! `exec`), and this test process holds far more than `tspace` does on a small scene. So each
//! command is started by a fresh copy of this test binary running [`peak_rss_helper`] alone,
//! which is small when it forks.

#![cfg(all(target_os = "linux", target_env = "gnu"))]

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

const PRIMITIVES: usize = 5_000;
const MAX_RATIO: f64 = 10.0;

/// A temporary folder, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("tspace-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Where [`peak_rss_helper`] finds its command: the file for standard output, then the
/// arguments, one a line.
const HELPER_ENV: &str = "TSPACE_TEST_PEAK_RSS_OF";

/// Runs `tspace ARGS` with its standard output in `stdout`; returns the exit code and the peak
/// resident set in bytes. Measured by a fresh process (see the module documentation).
fn run(args: &[&Path], stdout: &Path) -> (i32, u64) {
    let spec: Vec<String> = std::iter::once(stdout)
        .chain(args.iter().copied())
        .map(|p| p.to_str().unwrap().to_owned())
        .collect();
    let helper = Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "peak_rss_helper",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(HELPER_ENV, spec.join("\n"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&helper.stdout);
    // The harness may print the test's name on the same line first.
    let line = text
        .lines()
        .find_map(|l| l.split_once("tspace exit ").map(|(_, said)| said));
    let parsed = line.and_then(|l| {
        let (code, peak) = l.split_once(", peak ")?;
        Some((code.parse().ok()?, peak.parse().ok()?))
    });
    parsed.unwrap_or_else(|| panic!("the helper said: {text}"))
}

/// Not a test of its own: with [`HELPER_ENV`] set, runs `tspace` as it says and prints the exit
/// code and peak resident set; without it, nothing.
#[test]
// The child is reaped by `wait4`, which gives its peak; `Child::wait` would not.
#[allow(clippy::zombie_processes)]
fn peak_rss_helper() {
    let Ok(spec) = std::env::var(HELPER_ENV) else {
        return;
    };
    let mut lines = spec.lines();
    let stdout = Path::new(lines.next().unwrap());
    let args: Vec<&str> = lines.collect();
    let mut command = Command::new(env!("CARGO_BIN_EXE_tspace"));
    command
        .args(&args)
        .stdout(std::fs::File::create(stdout).unwrap())
        .stderr(Stdio::null());
    // SAFETY: prctl is async-signal-safe and touches only the child's own settings.
    unsafe {
        command.pre_exec(|| {
            libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0);
            Ok(())
        });
    }
    let child = command.spawn().unwrap();
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: an all-zero rusage is a valid value of that plain C struct.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `pid` is our own child, not yet waited for; both pointers are to live locals. The
    // child is reaped here, so `Child` is never waited for again.
    let waited = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(waited, pid, "wait4: {}", std::io::Error::last_os_error());
    assert!(
        libc::WIFEXITED(status),
        "tspace {args:?} did not exit: {status}"
    );
    // Linux gives the peak in KiB.
    let peak = usage.ru_maxrss as u64 * 1024;
    println!("tspace exit {}, peak {peak}", libc::WEXITSTATUS(status));
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / f64::from(1 << 20)
}

#[test]
fn a_json_heavy_scene_peaks_at_most_ten_times_its_size() {
    let dir = TempDir::new("json-heavy");
    let scene = dir.0.join("scene.glb");
    let tiny = dir.0.join("tiny.glb");
    let body = tspace_testkit::json_heavy::json_heavy(PRIMITIVES);
    std::fs::write(&scene, &body).unwrap();
    std::fs::write(&tiny, tspace_testkit::json_heavy::json_heavy(1)).unwrap();
    let (out, stdout) = (dir.0.join("out.glb"), dir.0.join("stdout"));
    let run_on = |name: &str, input: &Path| {
        let mut args = vec![Path::new(name), input];
        if name == "process" {
            args.extend([Path::new("-o"), &out, Path::new("-q")]);
        }
        run(&args, &stdout)
    };

    let mut failures = Vec::new();
    for name in ["process", "analyze"] {
        let (code, idle) = run_on(name, &tiny);
        assert_eq!(code, 0, "{name} of one primitive");
        let (code, peak) = run_on(name, &scene);
        assert_eq!(code, 0, "{name} of {PRIMITIVES} primitives");
        // The work was done: every primitive got tangents (and, for process, was written).
        if name == "process" {
            let written = std::fs::read(&out).unwrap();
            assert!(
                written.len() > body.len(),
                "{name}: output of {} bytes",
                written.len()
            );
            let count = written.windows(9).filter(|w| w == b"\"TANGENT\"").count();
            assert_eq!(count, PRIMITIVES, "{name}: TANGENT attributes written");
        } else {
            let report: serde_json::Value =
                serde_json::from_slice(&std::fs::read(&stdout).unwrap()).unwrap();
            assert_eq!(report["summary"]["generated"], PRIMITIVES, "{name}: report");
        }
        // A measure that reads nothing would pass anything: the peak holds the input at least.
        assert!(
            peak > idle + body.len() as u64,
            "{name}: peak {peak}, idle {idle}"
        );
        let ratio = (peak - idle) as f64 / body.len() as f64;
        eprintln!(
            "{name}: {PRIMITIVES} primitives, {:.1} MiB: peak {:.1} MiB, {:.1} MiB on one \
             primitive; {ratio:.1} times the body",
            mib(body.len() as u64),
            mib(peak),
            mib(idle),
        );
        if ratio > MAX_RATIO {
            failures.push(format!("{name}: {ratio:.1} times the body"));
        }
    }
    assert!(failures.is_empty(), "over {MAX_RATIO} times: {failures:?}");
}
