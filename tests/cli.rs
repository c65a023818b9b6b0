//! The `tspace` binary's `process`, `analyze` and `healthcheck` commands, run as a user would,
//! on copies of the fixtures in temporary folders.

use serde_json::Value;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
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
    }
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
