//! The `tspace` binary's `process`, `analyze` and `healthcheck` commands, run as a user would,
//! on copies of the fixtures in temporary folders.

use serde_json::Value;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use tspace::scene::gltf::glb;
#[allow(unused_imports)]
use tspace_testkit::validator;

/// A temporary folder, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("tspace-cli-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn path(&self) -> &Path {
        &self.0
    }

    /// Copies `fixtures/<name>` (a flat folder) to `<self>/<to>`.
    fn copy_fixture(&self, name: &str, to: &str) -> PathBuf {
        let from = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fixtures")
            .join(name);
        let dest = self.0.join(to);
        std::fs::create_dir_all(&dest).unwrap();
        for entry in std::fs::read_dir(&from).unwrap() {
            let entry = entry.unwrap();
            std::fs::copy(entry.path(), dest.join(entry.file_name())).unwrap();
        }
        dest
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn tspace(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tspace"))
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap()
}

/// Runs `tspace` with `input` piped to its standard input.
fn tspace_with_stdin(dir: &Path, args: &[&str], input: Vec<u8>) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tspace"))
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_BACKTRACE")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    // Written from a thread, so that a child writing its output before reading all of its input
    // cannot deadlock the test; a child that stops reading early closes the pipe, which is fine.
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(&input);
    });
    let output = child.wait_with_output().unwrap();
    writer.join().unwrap();
    output
}

fn fixture_bytes(path: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fixtures")
            .join(path),
    )
    .unwrap()
}

/// The names in a folder, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn code(output: &Output) -> i32 {
    output.status.code().expect("exited, not killed")
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

fn read_json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// Parses the file as GLB and returns its JSON chunk.
fn glb_json(path: &Path) -> Value {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let parsed = glb::parse(&bytes).unwrap_or_else(|e| panic!("{}: {e:?}", path.display()));
    serde_json::from_slice(parsed.json).unwrap()
}

fn assert_valid(path: &Path) {
    let Some(report) = validator::validate_file(path) else {
        return;
    };
    let errors: Vec<_> = report
        .messages_of(validator::Severity::Error)
        .map(|m| format!("{} {:?} {}", m.code, m.pointer, m.message))
        .collect();
    assert!(errors.is_empty(), "{}: {errors:#?}", path.display());
}

fn has_tangents(gltf: &Value) -> bool {
    gltf["meshes"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|m| m["primitives"].as_array().unwrap())
        .all(|p| p["attributes"].get("TANGENT").is_some())
}

#[test]
fn process_writes_glb_beside_each_input_and_an_array_report() {
    let t = TempDir::new("beside");
    t.copy_fixture("Avocado", "Avocado");
    t.copy_fixture("Box", "Box");
    t.copy_fixture("negative_indices", "negative_indices");
    let out = tspace(
        t.path(),
        &[
            "process",
            "Avocado/Avocado.gltf",
            "Box/Box.glb",
            "negative_indices/negative_indices.obj",
            "--report",
            "report.json",
        ],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let err = stderr(&out);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("3 files ok, 0 failed; 1 primitive generated, 0 vertices added"),
        "{err}"
    );
    assert!(out.stdout.is_empty());

    for output in [
        "Avocado/Avocado.tspace.glb",
        "Box/Box.tspace.glb",
        "negative_indices/negative_indices.tspace.glb",
    ] {
        glb_json(&t.path().join(output));
    }
    let obj = t
        .path()
        .join("negative_indices/negative_indices.tspace.glb");
    assert!(has_tangents(&glb_json(&obj)));
    assert_valid(&obj);

    let report = read_json(&t.path().join("report.json"));
    let entries = report.as_array().unwrap();
    assert_eq!(entries.len(), 3);
    assert_eq!(entries[0]["input"], "Avocado/Avocado.gltf");
    assert_eq!(entries[0]["output"], "Avocado/Avocado.tspace.glb");
    // Avocado already has tangents: they are audited, not replaced.
    assert_eq!(entries[0]["report"]["primitives"][0]["action"], "audited");
    assert_eq!(entries[1]["report"]["input_format"], "glb");
    let obj_report = &entries[2]["report"];
    assert_eq!(obj_report["input_format"], "obj");
    assert_eq!(obj_report["output_format"], "glb");
    assert_eq!(obj_report["summary"]["generated"], 1);
    assert_eq!(obj_report["primitives"][0]["action"], "generated");
}

#[test]
fn one_input_with_o_gets_the_report_object_itself() {
    let t = TempDir::new("single");
    t.copy_fixture("negative_indices", "in");
    let out = tspace(
        t.path(),
        &[
            "process",
            "in/negative_indices.obj",
            "-o",
            "sub/out.glb",
            "--report",
            "r.json",
            "--method",
            "fast",
        ],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(has_tangents(&glb_json(&t.path().join("sub/out.glb"))));
    let report = read_json(&t.path().join("r.json"));
    assert_eq!(report["method"], "fast");
    assert_eq!(report["summary"]["generated"], 1);
    assert!(!t.path().join("in/negative_indices.tspace.glb").exists());
}

/// `--report` and `-o` naming a pipe (or a device such as `/dev/null`) write into it and leave
/// it in place: a file renamed over it would replace it (as root, `/dev/null` itself).
#[cfg(unix)]
#[test]
fn a_pipe_named_as_output_is_written_not_replaced() {
    use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
    let t = TempDir::new("pipe");
    t.copy_fixture("negative_indices", "in");
    let pipes = ["report.pipe", "scene.pipe"].map(|name| t.path().join(name));
    let readers = pipes.each_ref().map(|pipe| {
        let name = std::ffi::CString::new(pipe.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid C string; mkfifo only creates the named pipe.
        assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0, "mkfifo");
        // Opened for reading first, without waiting for a writer: tspace's open for writing
        // then returns at once, and a regression (a file renamed over the pipe) fails below
        // instead of hanging.
        let reader = std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(pipe)
            .unwrap();
        let pipe = pipe.clone();
        std::thread::spawn(move || drain(reader, &pipe))
    });
    let out = tspace(
        t.path(),
        &[
            "process",
            "in/negative_indices.obj",
            "-o",
            "scene.pipe",
            "--report",
            "report.pipe",
        ],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let [report, scene] = readers.map(|reader| reader.join().unwrap());
    for pipe in &pipes {
        let kind = std::fs::symlink_metadata(pipe).unwrap().file_type();
        assert!(kind.is_fifo(), "{} was replaced", pipe.display());
    }
    let report: Value = serde_json::from_slice(&report).expect("the report came through the pipe");
    assert_eq!(report["summary"]["generated"], 1);
    let scene = glb::parse(&scene).expect("a GLB came through the pipe");
    assert!(has_tangents(&serde_json::from_slice(scene.json).unwrap()));
}

/// Everything written into a pipe opened without blocking, until its writer closes it (or, where
/// nothing ever opens it for writing, for at most ten seconds).
#[cfg(unix)]
fn drain(mut reader: std::fs::File, pipe: &Path) -> Vec<u8> {
    let started = std::time::Instant::now();
    let (mut bytes, mut chunk, mut opened) = (Vec::new(), [0u8; 65536], false);
    while started.elapsed() < std::time::Duration::from_secs(10) {
        match reader.read(&mut chunk) {
            Ok(0)
                if opened
                    || !std::fs::symlink_metadata(pipe)
                        .is_ok_and(|m| std::os::unix::fs::FileTypeExt::is_fifo(&m.file_type())) =>
            {
                break;
            }
            Ok(0) => std::thread::sleep(std::time::Duration::from_millis(5)),
            Ok(n) => {
                opened = true;
                bytes.extend_from_slice(&chunk[..n]);
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                opened = true;
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
            Err(e) => panic!("reading {}: {e}", pipe.display()),
        }
    }
    bytes
}

#[test]
fn format_gltf_writes_embedded_json() {
    let t = TempDir::new("gltf");
    t.copy_fixture("negative_indices", "in");
    let out = tspace(
        t.path(),
        &["process", "in/negative_indices.obj", "--format", "gltf"],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let written = t.path().join("in/negative_indices.tspace.gltf");
    let gltf: Value = read_json(&written);
    assert!(has_tangents(&gltf));
    assert!(
        gltf["buffers"][0]["uri"]
            .as_str()
            .unwrap()
            .starts_with("data:")
    );
    assert_valid(&written);
}

#[test]
fn overwrite_regenerates_avocado() {
    let t = TempDir::new("overwrite");
    t.copy_fixture("Avocado", "Avocado");
    let out = tspace(
        t.path(),
        &[
            "process",
            "Avocado/Avocado.gltf",
            "--overwrite",
            "--report",
            "r.json",
        ],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let report = read_json(&t.path().join("r.json"));
    assert_eq!(report["overwrite"], true);
    assert_eq!(report["summary"]["generated"], 1);
    assert_eq!(report["primitives"][0]["action"], "overwritten");
    assert!(has_tangents(&glb_json(
        &t.path().join("Avocado/Avocado.tspace.glb")
    )));
}

#[test]
fn an_obj_without_uvs_is_converted_and_skipped_unless_axis() {
    let t = TempDir::new("axis");
    t.copy_fixture("concave_polygon", "c");
    // Like a glTF primitive without UVs: converted, skipped with the reason, exit 0.
    let out = tspace(
        t.path(),
        &[
            "process",
            "c/concave_polygon.obj",
            "--all",
            "--report",
            "r.json",
        ],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let written = t.path().join("c/concave_polygon.tspace.glb");
    assert!(!has_tangents(&glb_json(&written)));
    assert_valid(&written);
    let report = read_json(&t.path().join("r.json"));
    assert_eq!(report["primitives"][0]["action"], "skipped");
    assert_eq!(report["primitives"][0]["reason"], "no_texcoords");
    assert!(
        report["primitives"][0]["message"]
            .as_str()
            .unwrap()
            .contains("axis method"),
        "{report}"
    );

    // Its material has no normal map, so with the axis method it is converted and skipped…
    let out = tspace(
        t.path(),
        &["process", "c/concave_polygon.obj", "--method", "axis"],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let written = t.path().join("c/concave_polygon.tspace.glb");
    assert!(!has_tangents(&glb_json(&written)));
    assert_valid(&written);

    // …and with --all it gets tangents.
    let out = tspace(
        t.path(),
        &[
            "process",
            "c/concave_polygon.obj",
            "--method",
            "axis",
            "--all",
            "--report",
            "r.json",
        ],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(has_tangents(&glb_json(&written)));
    assert_valid(&written);
    let report = read_json(&t.path().join("r.json"));
    assert_eq!(report["method"], "axis");
    assert_eq!(report["primitives"][0]["action"], "generated");
}

#[test]
fn a_directory_is_searched_and_mirrored_under_out_dir() {
    let t = TempDir::new("directory");
    t.copy_fixture("Box", "in/Box");
    t.copy_fixture("Avocado", "in/deeper/Avocado");
    t.copy_fixture("negative_indices", "in/negative_indices");
    t.copy_fixture("concave_polygon", "in/concave_polygon");
    t.copy_fixture("Box", "in/.hidden");
    // An earlier output beside its input is not read again.
    std::fs::copy(
        t.path().join("in/Box/Box.glb"),
        t.path().join("in/Box/Box.tspace.glb"),
    )
    .unwrap();
    let out = tspace(
        t.path(),
        &["process", "in", "--out-dir", "out", "--report", "r.json"],
    );
    // Every file is written, the OBJ without UVs too (converted, its primitive skipped).
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let err = stderr(&out);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("4 files ok, 0 failed"), "{err}");
    for output in [
        "out/Box/Box.glb",
        "out/deeper/Avocado/Avocado.glb",
        "out/negative_indices/negative_indices.glb",
        "out/concave_polygon/concave_polygon.glb",
    ] {
        glb_json(&t.path().join(output));
    }
    assert!(!t.path().join("out/.hidden").exists());

    let report = read_json(&t.path().join("r.json"));
    let entries = report.as_array().unwrap();
    let inputs: Vec<&str> = entries
        .iter()
        .map(|e| e["input"].as_str().unwrap())
        .collect();
    assert_eq!(
        inputs,
        [
            "in/Box/Box.glb",
            "in/concave_polygon/concave_polygon.obj",
            "in/deeper/Avocado/Avocado.gltf",
            "in/negative_indices/negative_indices.obj"
        ]
    );
    // The untextured OBJ converts, its primitive skipped (no normal map, and no UVs).
    assert_eq!(entries[1]["report"]["summary"]["skipped"], 1);
    assert!(entries[1].get("output").is_some());
    assert_eq!(entries[3]["report"]["summary"]["generated"], 1);

    // Running again over a folder that holds the output folder does not read the outputs.
    let again = tspace(t.path(), &["process", ".", "--out-dir", "out"]);
    assert!(
        stderr(&again).contains("4 files ok, 0 failed"),
        "{}",
        stderr(&again)
    );
}

#[test]
fn analyze_prints_the_report_and_writes_nothing() {
    let t = TempDir::new("analyze");
    t.copy_fixture("negative_indices", "n");
    let out = tspace(t.path(), &["analyze", "n/negative_indices.obj", "--all"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(out.stderr.is_empty(), "{}", stderr(&out));
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["all"], true);
    assert_eq!(report["summary"]["generated"], 1);
    assert!(report.get("output_format").is_none());
    let files: Vec<_> = std::fs::read_dir(t.path().join("n")).unwrap().collect();
    assert_eq!(files.len(), 1);
}

#[test]
fn o_with_two_inputs_is_a_usage_error() {
    let t = TempDir::new("usage");
    t.copy_fixture("Box", "Box");
    t.copy_fixture("negative_indices", "n");
    let out = tspace(
        t.path(),
        &[
            "process",
            "Box/Box.glb",
            "n/negative_indices.obj",
            "-o",
            "x.glb",
        ],
    );
    assert_eq!(code(&out), 2);
    assert!(stderr(&out).contains("--out-dir"), "{}", stderr(&out));
    assert!(!t.path().join("x.glb").exists());

    let out = tspace(t.path(), &["process", "Box", "-o", "x.glb"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    let out = tspace(t.path(), &["process", "Box/Box.glb", "--method", "nope"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    let out = tspace(t.path(), &["process"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
}

#[test]
fn process_in_out_writes_out_or_refuses_when_out_exists() {
    // glTF-Transform's form: the second path, not there yet, is the output.
    let t = TempDir::new("in-out");
    t.copy_fixture("Box", "Box");
    let out = tspace(t.path(), &["process", "Box/Box.glb", "out.gltf"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(t.path().join("out.gltf").is_file());
    assert!(!t.path().join("Box/Box.tspace.glb").exists());
    let written = std::fs::read(t.path().join("out.gltf")).unwrap();
    assert!(written.starts_with(b"{"), "a .gltf name gives .gltf output");

    // Run again: out.gltf exists now, so it might be an input or a stale output. Refused, with
    // the two ways to say what is meant, and nothing written.
    let before = std::fs::read(t.path().join("out.gltf")).unwrap();
    let again = tspace(t.path(), &["process", "Box/Box.glb", "out.gltf"]);
    assert_eq!(code(&again), 2, "{}", stderr(&again));
    let message = stderr(&again);
    assert!(
        message.contains("-o out.gltf") && message.contains("--out-dir"),
        "{message}"
    );
    assert_eq!(std::fs::read(t.path().join("out.gltf")).unwrap(), before);
    assert!(!t.path().join("out.tspace.glb").exists());
    assert!(!t.path().join("Box/Box.tspace.glb").exists());

    // Said either way, it runs.
    let with_o = tspace(t.path(), &["process", "Box/Box.glb", "-o", "out.gltf"]);
    assert_eq!(code(&with_o), 0, "{}", stderr(&with_o));
    let both = tspace(
        t.path(),
        &["process", "Box/Box.glb", "out.gltf", "--out-dir", "both"],
    );
    assert_eq!(code(&both), 0, "{}", stderr(&both));
    assert!(t.path().join("both").is_dir());
}

#[test]
fn an_output_never_replaces_an_input() {
    let t = TempDir::new("replace");
    t.copy_fixture("Box", "Box");
    let before = std::fs::read(t.path().join("Box/Box.glb")).unwrap();
    let out = tspace(t.path(), &["process", "Box/Box.glb", "--out-dir", "Box"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert!(
        stderr(&out).contains("would replace the input"),
        "{}",
        stderr(&out)
    );
    let out = tspace(
        t.path(),
        &["process", "Box/Box.glb", "-o", "./Box/../Box/Box.glb"],
    );
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert_eq!(std::fs::read(t.path().join("Box/Box.glb")).unwrap(), before);
}

#[test]
fn a_missing_input_exits_3_with_one_line() {
    let t = TempDir::new("missing");
    let out = tspace(t.path(), &["analyze", "absent.glb"]);
    assert_eq!(code(&out), 3);
    assert_eq!(
        stderr(&out),
        "tspace: absent.glb: cannot read it: No such file or directory (unreadable-input)\n"
    );
    assert!(out.stdout.is_empty());

    let out = tspace(t.path(), &["process", "absent.glb"]);
    assert_eq!(code(&out), 3);
    let err = stderr(&out);
    let failures: Vec<_> = err
        .lines()
        .filter(|l| l.starts_with("tspace: absent.glb: "))
        .collect();
    assert_eq!(failures.len(), 1, "{err}");
    assert_eq!(err.lines().count(), 2, "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn a_file_that_is_not_a_scene_exits_3() {
    let t = TempDir::new("garbage");
    std::fs::write(t.path().join("broken.glb"), b"glTF\x02\0\0\0\xff\xff").unwrap();
    std::fs::write(t.path().join("image.png"), b"\x89PNG\r\n\x1a\n\0\0\0\0").unwrap();
    for file in ["broken.glb", "image.png"] {
        let out = tspace(t.path(), &["process", file, "--report", "r.json"]);
        assert_eq!(code(&out), 3, "{}", stderr(&out));
        let report = read_json(&t.path().join("r.json"));
        assert_eq!(report["input"], file);
        assert!(report["error"]["code"].is_string(), "{report}");
    }
}

#[test]
fn write_failures_exit_4_and_win_over_bad_input() {
    let t = TempDir::new("write");
    t.copy_fixture("Box", "Box");
    std::fs::write(t.path().join("blocker"), b"a file, not a folder").unwrap();
    let out = tspace(
        t.path(),
        &[
            "process",
            "Box/Box.glb",
            "absent.obj",
            "--out-dir",
            "blocker",
        ],
    );
    assert_eq!(code(&out), 4, "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.contains("tspace: Box/Box.glb: cannot write blocker/Box.glb"),
        "{err}"
    );
    assert!(err.contains("(write-failed)"), "{err}");
    assert!(err.contains("tspace: absent.obj: "), "{err}");

    let out = tspace(
        t.path(),
        &["process", "Box/Box.glb", "--report", "blocker/r.json"],
    );
    assert_eq!(code(&out), 4, "{}", stderr(&out));
    assert!(
        stderr(&out).contains("cannot write the report"),
        "{}",
        stderr(&out)
    );
    // The scene itself was written.
    glb_json(&t.path().join("Box/Box.tspace.glb"));
}

#[test]
fn help_documents_the_exit_codes() {
    let t = TempDir::new("help");
    for args in [
        &["--help"][..],
        &["process", "--help"],
        &["analyze", "--help"],
    ] {
        let out = tspace(t.path(), args);
        assert_eq!(code(&out), 0);
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains("Exit codes:"), "{text}");
        assert!(text.contains("4  I/O failure"), "{text}");
        assert!(text.contains("5  --fail-on"), "{text}");
        assert!(text.contains("1, 4, 3, 5, 0"), "{text}");
    }
}

#[test]
fn dash_reads_stdin_and_writes_stdout() {
    let t = TempDir::new("stdio");
    let before = listing(t.path());
    let out = tspace_with_stdin(
        t.path(),
        &["process", "-", "-o", "-", "--all"],
        fixture_bytes("BoxTextured_embedded/BoxTextured.gltf"),
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    // stdout holds the scene and nothing else; the summary is on stderr.
    let parsed = glb::parse(&out.stdout).expect("stdout is one GLB");
    let gltf: Value = serde_json::from_slice(parsed.json).unwrap();
    assert!(has_tangents(&gltf));
    let err = stderr(&out);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("1 file ok, 0 failed; 1 primitive generated"),
        "{err}"
    );
    assert_eq!(listing(t.path()), before, "nothing written beside");

    // The format comes from the bytes (a .gltf with data: URIs above): an OBJ, written as .gltf.
    let out = tspace_with_stdin(
        t.path(),
        &["process", "-", "-o", "-", "--format", "gltf", "--all"],
        fixture_bytes("negative_indices/negative_indices.obj"),
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let gltf: Value = serde_json::from_slice(&out.stdout).expect("stdout is .gltf JSON");
    assert!(has_tangents(&gltf));
    let out = tspace_with_stdin(
        t.path(),
        &["analyze", "-"],
        fixture_bytes("BoxTextured_embedded/BoxTextured.gltf"),
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["input_format"], "gltf");

    // glTF-Transform's IN OUT form takes - on either side; a file is written atomically.
    let out = tspace_with_stdin(
        t.path(),
        &["process", "-", "from-stdin.glb", "--all"],
        fixture_bytes("BoxTextured_embedded/BoxTextured.gltf"),
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(has_tangents(&glb_json(&t.path().join("from-stdin.glb"))));
    let out = tspace(t.path(), &["process", "from-stdin.glb", "-", "-q"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(glb::parse(&out.stdout).is_ok());
    assert!(out.stderr.is_empty(), "{}", stderr(&out));
    // The report can take standard output instead, the summary staying on stderr.
    let out = tspace(
        t.path(),
        &[
            "process",
            "from-stdin.glb",
            "-o",
            "again.glb",
            "--report",
            "-",
        ],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let report: Value = serde_json::from_slice(&out.stdout).expect("stdout is the report");
    assert_eq!(report["input_format"], "glb");
    assert_eq!(stderr(&out).lines().count(), 1, "{}", stderr(&out));
    assert!(t.path().join("again.glb").is_file());
}

#[test]
fn a_gltf_from_stdin_never_opens_its_uris() {
    // Avocado.bin is right there in the working folder, and still not read.
    let t = TempDir::new("stdin-uris");
    let dir = t.copy_fixture("Avocado", "Avocado");
    let out = tspace_with_stdin(
        &dir,
        &["analyze", "-"],
        fixture_bytes("Avocado/Avocado.gltf"),
    );
    assert_eq!(code(&out), 3, "{}", stderr(&out));
    let err = stderr(&out);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("tspace: standard input: "), "{err}");
    assert!(err.contains("Avocado.bin"), "{err}");
    assert!(err.contains("only data: URIs"), "{err}");
    assert!(err.trim_end().ends_with("(missing-resource)"), "{err}");
    assert!(out.stdout.is_empty());

    let out = tspace_with_stdin(&dir, &["analyze", "-"], b"\x89PNG\r\n\x1a\n\0\0".to_vec());
    assert_eq!(code(&out), 3, "{}", stderr(&out));
    assert!(
        stderr(&out).contains("(unknown-format)"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn dash_where_it_cannot_work_is_one_usage_line() {
    let t = TempDir::new("stdio-usage");
    t.copy_fixture("Box", "Box");
    t.copy_fixture("Avocado", "Avocado");
    for args in [
        &["process", "-"][..],
        &["process", "-", "Box/Box.glb", "-o", "x.glb"],
        &["process", "-", "-", "-o", "-"],
        &["process", "Box/Box.glb", "Avocado/Avocado.gltf", "-o", "-"],
        &["process", "Box", "-o", "-"],
        &["analyze", "-", "Box/Box.glb"],
        &["process", "-", "-o", "-", "--report", "-"],
    ] {
        let out = tspace_with_stdin(t.path(), args, fixture_bytes("Box/Box.glb"));
        assert_eq!(code(&out), 2, "{args:?}: {}", stderr(&out));
        let err = stderr(&out);
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(out.stdout.is_empty(), "{args:?}");
    }
    assert_eq!(listing(t.path()), ["Avocado", "Box"]);
}

#[test]
fn analyze_several_inputs_prints_an_array() {
    let t = TempDir::new("analyze-many");
    t.copy_fixture("Box", "Box");
    t.copy_fixture("Avocado", "models/Avocado");
    t.copy_fixture("negative_indices", "models/negative_indices");
    let out = tspace(
        t.path(),
        &["analyze", "Box/Box.glb", "models", "absent.glb"],
    );
    assert_eq!(code(&out), 3, "{}", stderr(&out));
    let err = stderr(&out);
    assert_eq!(
        err,
        "tspace: absent.glb: cannot read it: No such file or directory (unreadable-input)\n"
    );
    let entries: Value = serde_json::from_slice(&out.stdout).unwrap();
    let entries = entries.as_array().unwrap();
    let inputs: Vec<&str> = entries
        .iter()
        .map(|e| e["input"].as_str().unwrap())
        .collect();
    assert_eq!(
        inputs,
        [
            "Box/Box.glb",
            "models/Avocado/Avocado.gltf",
            "models/negative_indices/negative_indices.obj",
            "absent.glb"
        ]
    );
    assert_eq!(entries[1]["report"]["summary"]["audited"], 1);
    assert_eq!(entries[2]["report"]["input_format"], "obj");
    assert_eq!(entries[3]["error"]["code"], "unreadable-input");
    assert!(entries.iter().all(|e| e.get("output").is_none()));
    // Analysis writes nothing.
    assert_eq!(
        listing(&t.path().join("models/Avocado")),
        ["Avocado.bin", "Avocado.gltf"]
    );

    // One directory is an array too, even of one file.
    let out = tspace(t.path(), &["analyze", "Box"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let entries: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(entries.as_array().unwrap().len(), 1);
}

#[test]
fn fail_on_exits_5_after_writing_everything_and_failures_win() {
    let t = TempDir::new("fail-on");
    t.copy_fixture("Avocado", "Avocado");
    t.copy_fixture("spider", "spider");
    t.copy_fixture("Box", "Box");
    t.copy_fixture("NormalTangentMirrorTest", "Mirror");

    // Avocado's kept tangents disagree with MikkTSpace.
    let out = tspace(
        t.path(),
        &["analyze", "Avocado/Avocado.gltf", "--fail-on", "audit"],
    );
    assert_eq!(code(&out), 5, "{}", stderr(&out));
    assert_eq!(
        stderr(&out),
        "tspace: --fail-on audit: 1 audit disagrees with MikkTSpace\n"
    );
    assert!(serde_json::from_slice::<Value>(&out.stdout).is_ok());
    let out = tspace(t.path(), &["analyze", "Avocado/Avocado.gltf"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    // This one's kept tangents agree, and with its images beside it (the fixture leaves them
    // out; analyze checks only that they are there) its findings are only of info severity.
    let mirror = "Mirror/NormalTangentMirrorTest.gltf";
    let out = tspace(t.path(), &["analyze", mirror, "--fail-on", "warnings"]);
    assert_eq!(code(&out), 5, "{}", stderr(&out));
    for image in ["OcclusionRoughnessMetallic", "Normal", "BaseColor"] {
        let path = t
            .path()
            .join(format!("Mirror/NormalTangentMirrorTest_{image}.png"));
        std::fs::write(path, b"\x89PNG\r\n\x1a\n").unwrap();
    }
    let out = tspace(
        t.path(),
        &["analyze", mirror, "--fail-on", "audit,warnings"],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["summary"]["audited"], 1);
    assert_eq!(report["summary"]["findings"]["info"], 1);

    // The spider OBJ has an error (normals dropped) and a warning: warnings counts both. Its
    // output is still written.
    let out = tspace(
        t.path(),
        &[
            "process",
            "spider/spider.obj",
            "Box/Box.glb",
            "--out-dir",
            "out",
            "--fail-on",
            "warnings",
        ],
    );
    assert_eq!(code(&out), 5, "{}", stderr(&out));
    assert!(
        stderr(&out).ends_with("tspace: --fail-on warnings: 1 error, 1 warning\n"),
        "{}",
        stderr(&out)
    );
    glb_json(&t.path().join("out/spider.glb"));

    // A comma list, or the flag repeated, names both.
    for flags in [
        &["--fail-on", "audit,warnings"][..],
        &["--fail-on", "warnings", "--fail-on", "audit"],
    ] {
        let mut args = vec!["analyze", "Avocado/Avocado.gltf", "spider/spider.obj"];
        args.extend_from_slice(flags);
        let out = tspace(t.path(), &args);
        assert_eq!(code(&out), 5, "{}", stderr(&out));
        assert!(
            stderr(&out).contains(
                "--fail-on audit,warnings: 1 audit disagrees with MikkTSpace, 1 error, 5 warnings"
            ),
            "{}",
            stderr(&out)
        );
    }

    // A file that fails is worse than a finding: exit 3.
    let out = tspace(
        t.path(),
        &[
            "analyze",
            "Avocado/Avocado.gltf",
            "absent.glb",
            "--fail-on",
            "audit",
        ],
    );
    assert_eq!(code(&out), 3, "{}", stderr(&out));
    let out = tspace(
        t.path(),
        &["analyze", "Box/Box.glb", "--fail-on", "nothing"],
    );
    assert_eq!(code(&out), 2, "{}", stderr(&out));
}

#[test]
fn the_summary_counts_audits_and_warnings() {
    let t = TempDir::new("summary");
    t.copy_fixture("Avocado", "Avocado");
    t.copy_fixture("spider", "spider");
    let out = tspace(t.path(), &["process", "Avocado", "spider"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    // Avocado: its audit, and its three images, not in the fixture (four warnings); the spider:
    // its normals dropped (an error) and its textures not supplied (a warning).
    assert_eq!(
        stderr(&out),
        "tspace: 2 files ok, 0 failed; 0 primitives generated, 0 vertices added; \
         1 audit disagrees with MikkTSpace, 1 error, 5 warnings\n"
    );
}

#[test]
fn quiet_keeps_only_failures_and_verbose_adds_each_file() {
    let t = TempDir::new("quiet");
    t.copy_fixture("Box", "Box");
    t.copy_fixture("spider", "spider");
    let out = tspace(
        t.path(),
        &["process", "Box/Box.glb", "-q", "--out-dir", "q"],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(out.stderr.is_empty(), "{}", stderr(&out));
    assert!(t.path().join("q/Box.glb").is_file());

    let out = tspace(
        t.path(),
        &[
            "process",
            "Box/Box.glb",
            "absent.obj",
            "--quiet",
            "--out-dir",
            "q",
        ],
    );
    assert_eq!(code(&out), 3);
    assert_eq!(
        stderr(&out),
        "tspace: absent.obj: cannot read it: No such file or directory (unreadable-input)\n"
    );

    let out = tspace(
        t.path(),
        &[
            "process",
            "spider/spider.obj",
            "Box/Box.glb",
            "-v",
            "--out-dir",
            "v",
        ],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let err = stderr(&out);
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 5, "{err}");
    assert_eq!(
        lines[0],
        "tspace: spider/spider.obj: 0 primitives generated, 0 audited, 4 skipped, 0 vertices added; 1 error, 1 warning"
    );
    assert!(
        lines[1].starts_with("tspace: spider/spider.obj: error: 52 triangles")
            && lines[1].ends_with("(invalid_normals_dropped)"),
        "{err}"
    );
    assert!(
        lines[2].starts_with("tspace: spider/spider.obj: warning: texture files")
            && lines[2].ends_with("(textures_not_supplied)"),
        "{err}"
    );
    assert!(
        lines[3].starts_with("tspace: Box/Box.glb: 0 primitives generated"),
        "{err}"
    );
    assert!(
        lines[4].starts_with("tspace: 2 files ok, 0 failed"),
        "{err}"
    );

    let out = tspace(t.path(), &["process", "Box/Box.glb", "-q", "-v"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
}

#[test]
fn completions_are_printed_for_each_shell() {
    let t = TempDir::new("completions");
    for (shell, marker) in [
        ("bash", "complete -F _tspace"),
        ("zsh", "#compdef tspace"),
        ("fish", "complete -c tspace"),
    ] {
        let out = tspace(t.path(), &["completions", shell]);
        assert_eq!(code(&out), 0, "{shell}: {}", stderr(&out));
        let script = String::from_utf8(out.stdout).unwrap();
        assert!(script.contains(marker), "{shell}: {script}");
        assert!(script.contains("fail-on"), "{shell}");
        assert!(out.stderr.is_empty());
    }
    let out = tspace(t.path(), &["completions", "cmd.exe"]);
    assert_eq!(code(&out), 2);
}

/// Runs `tspace ARGS` on a pseudo-terminal 80 columns wide (stdin, stdout and stderr), under
/// `script` (util-linux), returning what the terminal showed; `None`, with one line, where
/// `script` is missing.
fn tspace_on_a_terminal(dir: &Path, args: &str) -> Option<(i32, String)> {
    let script_runs = Command::new("script")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !script_runs {
        println!("cli: script (util-linux) not found, skipping a terminal test");
        return None;
    }
    // `timeout`: a binary that waits on the terminal fails the test instead of hanging it.
    let shell = format!(
        "stty cols 80 rows 24; exec timeout 60 '{}' {args} < /dev/tty",
        env!("CARGO_BIN_EXE_tspace")
    );
    let out = Command::new("script")
        .args(["-qec", &shell, "/dev/null"])
        .current_dir(dir)
        .env_remove("RUST_BACKTRACE")
        .stdin(Stdio::null())
        .output()
        .unwrap();
    Some((
        code(&out),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    ))
}

#[test]
fn the_progress_bar_fits_80_columns_and_keeps_the_file_name() {
    let t = TempDir::new("progress");
    t.copy_fixture(
        "Avocado",
        "a-rather-long-folder-name/another-long-folder/Avocado",
    );
    let Some((exit, terminal)) =
        tspace_on_a_terminal(t.path(), "process a-rather-long-folder-name --out-dir out")
    else {
        return;
    };
    assert_eq!(exit, 0, "{terminal}");
    let frames: Vec<&str> = terminal
        .split('\r')
        .map(|frame| frame.trim_start_matches("\x1b[2K").trim_end())
        .filter(|frame| frame.contains(" files "))
        .collect();
    assert!(!frames.is_empty(), "no progress bar drawn: {terminal:?}");
    for frame in frames {
        assert!(frame.chars().count() < 80, "{frame:?}");
        assert!(
            frame.ends_with("a-rather-long…folder/Avocado/Avocado.gltf"),
            "{frame:?}"
        );
    }
    assert!(terminal.contains("tspace: 1 file ok"), "{terminal:?}");
}

#[test]
fn dash_from_a_terminal_is_refused_rather_than_waited_on() {
    let t = TempDir::new("stdin-tty");
    let Some((exit, terminal)) = tspace_on_a_terminal(t.path(), "analyze -") else {
        return;
    };
    assert_eq!(exit, 2, "{terminal}");
    assert_eq!(terminal.trim_end().lines().count(), 1, "{terminal:?}");
    assert!(
        terminal.contains("standard input, which is a terminal"),
        "{terminal:?}"
    );
}

/// Answers one connection with `status`, returning the request it read.
fn serve_once(status: &'static str) -> (u16, std::thread::JoinHandle<String>) {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let handle = std::thread::spawn(move || {
        let (mut stream, _) = listener.accept().unwrap();
        let mut request = Vec::new();
        let mut buf = [0u8; 1024];
        while !request.ends_with(b"\r\n\r\n") {
            let n = stream.read(&mut buf).unwrap();
            if n == 0 {
                break;
            }
            request.extend_from_slice(&buf[..n]);
        }
        write!(
            stream,
            "HTTP/1.1 {status}\r\ncontent-length: 2\r\nconnection: close\r\n\r\nok"
        )
        .unwrap();
        String::from_utf8_lossy(&request).into_owned()
    });
    (port, handle)
}

#[test]
fn healthcheck_gets_healthz() {
    let t = TempDir::new("health");
    let (port, server) = serve_once("200 OK");
    let out = Command::new(env!("CARGO_BIN_EXE_tspace"))
        .arg("healthcheck")
        .env("TSPACE_ADDR", format!("0.0.0.0:{port}"))
        .current_dir(t.path())
        .output()
        .unwrap();
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let request = server.join().unwrap();
    assert!(
        request.starts_with("GET /healthz HTTP/1.1\r\n"),
        "{request}"
    );

    let (port, server) = serve_once("503 Service Unavailable");
    let url = format!("http://127.0.0.1:{port}/readyz");
    let out = tspace(t.path(), &["healthcheck", "--url", &url]);
    assert_eq!(code(&out), 1);
    assert!(stderr(&out).contains("503"), "{}", stderr(&out));
    assert!(server.join().unwrap().starts_with("GET /readyz "));

    // Nothing listens on a port just released.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let url = format!("http://127.0.0.1:{port}/healthz");
    let out = tspace(t.path(), &["healthcheck", "--url", &url, "--timeout", "2"]);
    assert_eq!(code(&out), 1);
    assert_eq!(stderr(&out).lines().count(), 1, "{}", stderr(&out));
}

/// `--normals` and `--normals-angle` reach an OBJ's conversion: the report says which normals
/// were made, the written vertices follow, and a bad angle is a usage error.
#[test]
fn normals_flag_chooses_an_objs_generated_normals() {
    let t = TempDir::new("normals");
    // An open 8-sided prism without vt, vn or s: its sides meet at 45°.
    let mut prism = String::new();
    for i in 0..8 {
        let a = f64::from(i) * std::f64::consts::FRAC_PI_4;
        prism += &format!("v {} {} 0\nv {} {} 1\n", a.cos(), a.sin(), a.cos(), a.sin());
    }
    for i in 0..8 {
        let j = (i + 1) % 8;
        prism += &format!(
            "f {} {} {} {}\n",
            2 * i + 1,
            2 * j + 1,
            2 * j + 2,
            2 * i + 2
        );
    }
    std::fs::write(t.path().join("prism.obj"), prism).unwrap();
    for (flags, expected, vertices) in [
        (&[][..], "smooth, with edges sharper than 60° kept hard", 16),
        (
            &["--normals", "flat"][..],
            "flat (faceted), as normals=flat asks",
            32,
        ),
        (
            &["--normals", "smooth", "--normals-angle", "30"][..],
            "smooth, with edges sharper than 30° kept hard",
            32,
        ),
    ] {
        let mut args = vec![
            "process",
            "prism.obj",
            "-o",
            "out.glb",
            "--report",
            "r.json",
        ];
        args.extend_from_slice(flags);
        let out = tspace(t.path(), &args);
        assert_eq!(code(&out), 0, "{flags:?}: {}", stderr(&out));
        let report = read_json(&t.path().join("r.json"));
        let warning = report["warnings"][0].as_str().unwrap_or("");
        assert!(
            warning.starts_with("normals generated for 16 triangles without vn: ")
                && warning.contains(expected),
            "{flags:?}: {warning}"
        );
        let output = t.path().join("out.glb");
        assert_valid(&output);
        let gltf = glb_json(&output);
        let attributes = &gltf["meshes"][0]["primitives"][0]["attributes"];
        let normal = attributes["NORMAL"].as_u64().expect("NORMAL") as usize;
        assert_eq!(gltf["accessors"][normal]["count"], vertices, "{flags:?}");
    }

    let out = tspace(
        t.path(),
        &["analyze", "prism.obj", "--normals-angle", "200"],
    );
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert!(stderr(&out).contains("from 0 to 180"), "{}", stderr(&out));
}

#[test]
fn uv_layout_writes_an_svg_beside_the_input_or_a_png_where_told() {
    let dir = TempDir::new("uv-layout");
    let scene = dir.copy_fixture("NormalTangentMirrorTest", "mirror");
    let input = scene.join("NormalTangentMirrorTest.gltf");
    let input = input.to_str().unwrap();
    let out = tspace(dir.path(), &["uv-layout", input]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let svg = std::fs::read_to_string(scene.join("NormalTangentMirrorTest.uv.svg")).unwrap();
    assert!(svg.contains("mirrored UVs: "), "{svg}");
    assert!(stderr(&out).contains("NormalTangentMirrorTest.uv.svg"));

    let png = dir.path().join("layout.png");
    let out = tspace(
        dir.path(),
        &["uv-layout", input, "-o", png.to_str().unwrap(), "-q"],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(stderr(&out).is_empty(), "{}", stderr(&out));
    assert!(
        std::fs::read(&png)
            .unwrap()
            .starts_with(b"\x89PNG\r\n\x1a\n")
    );

    // Standard output, the format named.
    let out = tspace(
        dir.path(),
        &["uv-layout", input, "-o", "-", "--format", "svg"],
    );
    assert_eq!(code(&out), 0);
    assert!(out.stdout.starts_with(b"<svg "));

    // Usage errors: one line, exit 2.
    let out = tspace(
        dir.path(),
        &["uv-layout", input, "-o", "x.png", "--format", "svg"],
    );
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert_eq!(stderr(&out).lines().count(), 1, "{}", stderr(&out));
    let out = tspace(dir.path(), &["uv-layout", input, "--primitive", "0"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));

    // Nothing to draw where asked: exit 3 and one line naming what there is.
    let out = tspace(dir.path(), &["uv-layout", input, "--mesh", "9", "-o", "-"]);
    assert_eq!(code(&out), 3, "{}", stderr(&out));
    let line = stderr(&out);
    assert_eq!(line.lines().count(), 1, "{line}");
    assert!(line.contains("(nothing-to-draw)"), "{line}");
    assert!(line.contains("meshes[0].primitives[0]"), "{line}");
}

#[test]
fn debug_colors_write_a_debug_named_scene_that_says_what_it_is() {
    let dir = TempDir::new("debug-colors");
    let scene = dir.copy_fixture("NormalTangentMirrorTest", "mirror");
    let input = scene.join("NormalTangentMirrorTest.gltf");
    let out = tspace(
        dir.path(),
        &[
            "process",
            input.to_str().unwrap(),
            "--debug-colors",
            "--report",
            "report.json",
            "-v",
        ],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    // Named so that nobody ships it, and not taken for an input by a later run.
    let output = scene.join("NormalTangentMirrorTest.debug.glb");
    let gltf = glb_json(&output);
    assert!(gltf["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"].is_u64());
    assert!(!scene.join("NormalTangentMirrorTest.tspace.glb").exists());
    let report = read_json(&dir.path().join("report.json"));
    assert!(report["debug_colors"]["classes"].is_array());
    assert!(
        stderr(&out).contains("not for shipping"),
        "{}",
        stderr(&out)
    );
    let out = tspace(dir.path(), &["analyze", scene.to_str().unwrap(), "-q"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let reports: Value = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
    let inputs = serde_json::to_string(&reports).unwrap();
    assert!(!inputs.contains(".debug.glb"), "{inputs}");
}
