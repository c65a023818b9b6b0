//! Every `curl` example in `README.md` and `docs/*.md` must work against the real binary.
//!
//! The test starts `tspace serve` on a free loopback port, takes every ```sh fenced block of
//! those files, joins backslash continuations, and runs each line that starts with `curl` (or
//! pipes into it) with `sh -c`, `http://localhost:8080` replaced by the server's address. Each
//! must exit 0, and every HTTP answer it got must be neither a server error (5xx) nor a route
//! that does not exist (404, 405): the error examples in the docs are meant to get 4xx answers,
//! but never those.
//!
//! The examples name fixtures by paths relative to the repository's root (`fixtures/…`) and write
//! their outputs to relative file names (`-o Box.tspace.glb`). So that running them leaves the
//! work tree untouched, they run in a fresh folder under Cargo's target directory holding a copy
//! of `fixtures/` (a copy, not a symbolic link, so that no example can write into the real one).
//! A missing fixture is then missing from the copy too, and curl fails on it.
//!
//! Self-contained: std only, no test kit.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The base URL the documentation uses.
const DOCS_BASE: &str = "http://localhost:8080";

/// Prepended to every example: a `curl` function that runs the real curl without the user's
/// `.curlrc` (`-q`, which must come first), with a time limit, and reports the status of every
/// answer on stderr, after whatever the example itself writes (`%{stderr}` needs curl 7.63).
const CURL_WRAPPER: &str = "curl() { command curl -q --max-time 120 \
     --write-out '%{stderr}\\ndocs-example-status %{http_code}\\n' \"$@\"; }";

const STATUS_PREFIX: &str = "docs-example-status ";

/// Kills the server when the test ends, however it ends.
struct Server {
    child: Child,
    base: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A folder removed when the test ends.
struct TempDir(PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn tool_runs(program: &str, args: &[&str]) -> bool {
    Command::new(program)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

fn free_port() -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind an ephemeral port");
    listener.local_addr().expect("local address").port()
}

/// Whether `GET /healthz` answers 200 `ok`.
fn healthy(port: u16) -> bool {
    let Ok(mut stream) =
        TcpStream::connect_timeout(&([127, 0, 0, 1], port).into(), Duration::from_millis(500))
    else {
        return false;
    };
    let _ = stream.set_read_timeout(Some(Duration::from_secs(2)));
    let request = "GET /healthz HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n";
    if stream.write_all(request.as_bytes()).is_err() {
        return false;
    }
    let mut answer = String::new();
    let _ = stream.read_to_string(&mut answer);
    answer.starts_with("HTTP/1.1 200") && answer.trim_end().ends_with("ok")
}

/// Starts `tspace serve` on a free port and waits until it answers. The port is free when
/// chosen but could be taken before the server binds it; then the server exits and another
/// port is tried.
fn start_server(workdir: &Path) -> Server {
    for _ in 0..5 {
        let port = free_port();
        let child = Command::new(env!("CARGO_BIN_EXE_tspace"))
            .args(["serve", "--addr", &format!("127.0.0.1:{port}")])
            .env("TSPACE_LOG", "warn")
            .current_dir(workdir)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start the tspace binary");
        let mut server = Server {
            child,
            base: format!("http://127.0.0.1:{port}"),
        };
        let deadline = Instant::now() + Duration::from_secs(60);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = server.child.try_wait() {
                break;
            }
            if healthy(port) {
                return server;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        eprintln!("docs_examples: the server on port {port} did not come up; trying another port");
    }
    panic!("tspace serve did not answer /healthz on any of five ports");
}

/// The contents of every fenced block tagged `sh`. Other fenced blocks are skipped whole, so
/// that a fence line inside them is never taken for the start of an `sh` block.
fn sh_blocks(markdown: &str) -> Vec<String> {
    enum State {
        Text,
        Sh(String),
        Other,
    }
    let mut blocks = Vec::new();
    let mut state = State::Text;
    for line in markdown.lines() {
        let fence = line.trim_start().strip_prefix("```");
        state = match (state, fence) {
            (State::Text, Some(tag)) if tag.trim() == "sh" => State::Sh(String::new()),
            (State::Text, Some(_)) => State::Other,
            (State::Text, None) => State::Text,
            (State::Sh(block), Some(_)) => {
                blocks.push(block);
                State::Text
            }
            (State::Sh(mut block), None) => {
                block.push_str(line);
                block.push('\n');
                State::Sh(block)
            }
            (State::Other, Some(_)) => State::Text,
            (State::Other, None) => State::Other,
        };
    }
    assert!(matches!(state, State::Text), "a fenced block is not closed");
    blocks
}

/// The `curl` command lines of a block, backslash continuations joined.
fn curl_lines(block: &str) -> Vec<String> {
    let mut lines = Vec::new();
    let mut pending = String::new();
    for line in block.lines() {
        match line.trim_end().strip_suffix('\\') {
            Some(head) => {
                pending.push_str(head);
                pending.push(' ');
            }
            None => {
                pending.push_str(line);
                let command = std::mem::take(&mut pending);
                let command = command.trim();
                if runs_curl(command) {
                    lines.push(command.to_owned());
                }
            }
        }
    }
    if !pending.trim().is_empty() {
        let command = pending.trim();
        if runs_curl(command) {
            lines.push(command.to_owned());
        }
    }
    lines
}

/// A line that is a curl command, or pipes into one (`gzip -c … | curl … --data-binary @-`).
fn runs_curl(command: &str) -> bool {
    let last = command.rsplit(" | ").next().unwrap_or(command).trim_start();
    last == "curl" || last.starts_with("curl ")
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("create a folder for the fixtures");
    for entry in std::fs::read_dir(from).expect("read fixtures") {
        let entry = entry.expect("fixture entry");
        let target = to.join(entry.file_name());
        if entry.file_type().expect("file type").is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).expect("copy a fixture");
        }
    }
}

#[test]
fn every_curl_example_in_the_docs_runs() {
    if !tool_runs("curl", &["--version"]) || !tool_runs("sh", &["-c", "true"]) {
        println!("docs_examples: curl or sh not found, skipping the documentation's examples");
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));

    let mut files = vec![root.join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("read docs/")
        .map(|e| e.expect("docs entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);

    let mut examples: Vec<(String, String)> = Vec::new();
    for file in &files {
        let name = file
            .strip_prefix(root)
            .unwrap_or(file)
            .display()
            .to_string();
        let text = std::fs::read_to_string(file).expect("read a documentation file");
        for block in sh_blocks(&text) {
            for command in curl_lines(&block) {
                examples.push((name.clone(), command));
            }
        }
    }
    for must in ["README.md", "docs/http-api.md"] {
        assert!(
            examples.iter().any(|(file, _)| file == must),
            "{must} has no curl example in an ```sh block"
        );
    }
    let mut failures = Vec::new();
    for (file, command) in &examples {
        if !command.contains(DOCS_BASE) {
            failures.push(format!(
                "{file}: `{command}`: does not use {DOCS_BASE}, so it cannot be pointed at the test server"
            ));
        }
    }

    let workdir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("docs_examples-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&workdir);
    std::fs::create_dir_all(&workdir).expect("create the examples' folder");
    let _workdir_guard = TempDir(workdir.clone());
    copy_dir(&root.join("fixtures"), &workdir.join("fixtures"));

    let server = start_server(&workdir);
    for (file, command) in &examples {
        let runnable = command.replace(DOCS_BASE, &server.base);
        let script = format!("{CURL_WRAPPER}\n{runnable}\n");
        let output = Command::new("sh")
            .arg("-c")
            .arg(&script)
            .current_dir(&workdir)
            .stdin(Stdio::null())
            .output()
            .expect("run sh");
        let stderr = String::from_utf8_lossy(&output.stderr);
        let statuses: Vec<&str> = stderr
            .lines()
            .filter_map(|l| l.strip_prefix(STATUS_PREFIX))
            .map(str::trim)
            .collect();
        let mut problems = Vec::new();
        if !output.status.success() {
            problems.push(format!("exited with {}", output.status));
        }
        if statuses.is_empty() {
            problems.push("no HTTP answer".to_owned());
        }
        for status in &statuses {
            let code: u16 = status.parse().unwrap_or(0);
            if !(100..500).contains(&code) || code == 404 || code == 405 {
                problems.push(format!("HTTP status {status}"));
            }
        }
        println!("{file}: {} -> {}", command, statuses.join(", "));
        if !problems.is_empty() {
            let shown: String = String::from_utf8_lossy(&output.stdout)
                .chars()
                .take(2000)
                .collect();
            failures.push(format!(
                "{file}: `{command}`: {}\n  stdout: {}\n  stderr: {}",
                problems.join("; "),
                shown.trim(),
                stderr.trim()
            ));
        }
    }
    drop(server);

    assert!(
        failures.is_empty(),
        "{} of {} documentation examples failed:\n{}",
        failures.len(),
        examples.len(),
        failures.join("\n")
    );
}
