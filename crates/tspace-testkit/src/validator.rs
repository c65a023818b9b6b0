//! The Khronos glTF-Validator, for integration tests.
//!
//! The validator is an npm package (`gltf-validator`, exact version pinned in
//! `tools/gltf-validator/package.json`) run by `tools/gltf-validator/validate.mjs` under Node.js.
//! On first use in a test process, [`validate`] and [`validate_file`] run
//! `scripts/install-gltf-validator` (fast when already installed, safe when several test
//! processes run it at once). Where Node.js or the installed package is missing they print one
//! skip line and return `None`, so a test reads:
//!
//! ```ignore
//! let Some(report) = common::validator::validate("out.glb", &bytes) else { return };
//! assert_eq!(report.error_codes(), Vec::<&str>::new(), "{}", report.summary());
//! ```
//!
//! Set `TSPACE_REQUIRE_GLTF_VALIDATOR=1` to turn the skip into a panic (for a CI that must not
//! skip silently).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;

use serde_json::Value;

/// How serious a validator message is, as the validator grades it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Severity {
    Error,
    Warning,
    Info,
    Hint,
}

impl Severity {
    fn parse(s: &str) -> Severity {
        match s {
            "error" => Severity::Error,
            "warning" => Severity::Warning,
            "info" => Severity::Info,
            "hint" => Severity::Hint,
            other => panic!("gltf-validator: unknown severity {other:?}"),
        }
    }
}

/// One issue the validator reported.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ValidatorMessage {
    /// The validator's issue code, e.g. `ACCESSOR_TOTAL_OFFSET_ALIGNMENT`.
    pub code: String,
    pub severity: Severity,
    /// JSON pointer into the glTF JSON, e.g. `/accessors/0/count`; `None` for GLB-level issues.
    pub pointer: Option<String>,
    /// Byte offset for GLB-level issues.
    pub offset: Option<u64>,
    pub message: String,
}

/// The validator's report on one file.
#[derive(Clone, Debug)]
pub struct ValidatorReport {
    /// The name the file was validated under.
    pub file: String,
    pub validator_version: String,
    pub num_errors: u64,
    pub num_warnings: u64,
    pub num_infos: u64,
    pub num_hints: u64,
    /// Whether the validator stopped listing messages (it is run with no limit, so normally not).
    pub truncated: bool,
    pub messages: Vec<ValidatorMessage>,
}

impl ValidatorReport {
    /// The messages of one severity, in report order.
    pub fn messages_of(&self, severity: Severity) -> impl Iterator<Item = &ValidatorMessage> {
        self.messages.iter().filter(move |m| m.severity == severity)
    }

    /// The codes of the messages of one severity, in report order (repeats kept).
    pub fn codes(&self, severity: Severity) -> Vec<&str> {
        self.messages_of(severity)
            .map(|m| m.code.as_str())
            .collect()
    }

    /// The error codes, in report order (repeats kept).
    pub fn error_codes(&self) -> Vec<&str> {
        self.codes(Severity::Error)
    }

    /// The warning codes, in report order (repeats kept).
    pub fn warning_codes(&self) -> Vec<&str> {
        self.codes(Severity::Warning)
    }

    /// Whether some error has this code.
    pub fn has_error(&self, code: &str) -> bool {
        self.messages_of(Severity::Error).any(|m| m.code == code)
    }

    /// A few lines for assertion messages: counts, then every error and warning.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "{} (glTF-Validator {}): {} errors, {} warnings, {} infos, {} hints",
            self.file,
            self.validator_version,
            self.num_errors,
            self.num_warnings,
            self.num_infos,
            self.num_hints
        );
        for m in &self.messages {
            if m.severity <= Severity::Warning {
                let at = match (&m.pointer, m.offset) {
                    (Some(p), _) => p.clone(),
                    (None, Some(o)) => format!("byte {o}"),
                    (None, None) => String::new(),
                };
                s.push_str(&format!(
                    "\n  {:?} {} at {at}: {}",
                    m.severity, m.code, m.message
                ));
            }
        }
        s
    }
}

/// Validates in-memory glTF JSON or GLB bytes (format detected from the first byte). `name` is
/// only a label for the report and messages. The input has no directory, so external resources
/// (a `.bin` next to a `.gltf`) are refused and reported as `IO_ERROR`; `data:` URIs work.
///
/// `None` (after one skip line on stderr) when the validator is unavailable. Panics when the
/// validator cannot produce a report at all (e.g. the bytes are neither JSON nor GLB).
pub fn validate(name: &str, bytes: &[u8]) -> Option<ValidatorReport> {
    let tool = tool(name)?;
    let mut child = tool
        .command()
        .arg("-")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("gltf-validator: cannot start node for {name}: {e}"));
    let mut stdin = child.stdin.take().expect("piped stdin");
    let output = std::thread::scope(|s| {
        // Feed stdin from another thread so a large report cannot block on a full pipe.
        s.spawn(move || {
            // A write error here shows up as the validator's own failure below.
            let _ = stdin.write_all(bytes);
        });
        child.wait_with_output()
    })
    .unwrap_or_else(|e| panic!("gltf-validator: waiting for node on {name}: {e}"));
    Some(parse_output(name, &output))
}

/// Validates a `.gltf` or `.glb` file on disk; external resources (a sidecar `.bin`, images) are
/// read from the file's directory. `None` (after one skip line on stderr) when the validator is
/// unavailable. Panics when the file cannot be read or the validator cannot produce a report.
pub fn validate_file(path: &Path) -> Option<ValidatorReport> {
    let name = path.display().to_string();
    let tool = tool(&name)?;
    let output = tool
        .command()
        .arg(path)
        .stdin(Stdio::null())
        .output()
        .unwrap_or_else(|e| panic!("gltf-validator: cannot start node for {name}: {e}"));
    let mut report = parse_output(&name, &output);
    report.file = name;
    Some(report)
}

/// Where the validator runs from, once found installed.
struct Tool {
    node: PathBuf,
    script: PathBuf,
}

impl Tool {
    fn command(&self) -> Command {
        let mut c = Command::new(&self.node);
        c.arg(&self.script);
        c
    }
}

/// The installed validator, or `None` after printing the skip line for `what`.
fn tool(what: &str) -> Option<&'static Tool> {
    static TOOL: OnceLock<Result<Tool, String>> = OnceLock::new();
    match TOOL.get_or_init(find_or_install) {
        Ok(tool) => Some(tool),
        Err(why) => {
            if std::env::var_os("TSPACE_REQUIRE_GLTF_VALIDATOR").is_some_and(|v| v != "0") {
                panic!("gltf-validator: {why} (TSPACE_REQUIRE_GLTF_VALIDATOR is set)");
            }
            eprintln!("gltf-validator: {why}; skipping validation of {what}");
            None
        }
    }
}

fn find_or_install() -> Result<Tool, String> {
    let root = crate::fixtures::workspace_root();
    let node = PathBuf::from("node");
    match Command::new(&node).arg("--version").output() {
        Ok(o) if o.status.success() => {}
        Ok(o) => return Err(format!("`node --version` failed ({})", o.status)),
        Err(e) => return Err(format!("node not found ({e})")),
    }
    let install = root.join("scripts/install-gltf-validator");
    let said = match Command::new("bash")
        .arg(&install)
        .stdin(Stdio::null())
        .output()
    {
        Ok(o) if o.status.success() => String::from_utf8_lossy(&o.stdout).trim().to_string(),
        Ok(o) => {
            return Err(format!(
                "{} failed ({}): {}{}",
                install.display(),
                o.status,
                String::from_utf8_lossy(&o.stdout).trim(),
                String::from_utf8_lossy(&o.stderr).trim()
            ));
        }
        Err(e) => return Err(format!("cannot run {} ({e})", install.display())),
    };
    let dir = root.join("tools/gltf-validator");
    if !dir
        .join("node_modules/gltf-validator/package.json")
        .is_file()
    {
        return Err(format!(
            "not installed in tools/gltf-validator/node_modules (install script: {said:?})"
        ));
    }
    Ok(Tool {
        node,
        script: dir.join("validate.mjs"),
    })
}

/// Reads validate.mjs's single JSON line for one input.
fn parse_output(name: &str, output: &std::process::Output) -> ValidatorReport {
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let line = stdout.lines().next().unwrap_or_else(|| {
        panic!(
            "gltf-validator printed nothing for {name} ({}): {stderr}",
            output.status
        )
    });
    let v: Value = serde_json::from_str(line)
        .unwrap_or_else(|e| panic!("gltf-validator: bad JSON for {name} ({e}): {line}"));
    if let Some(err) = v.get("error") {
        panic!("gltf-validator could not validate {name}: {err}");
    }
    assert!(
        output.status.success(),
        "gltf-validator exited with {} on {name}: {stderr}",
        output.status
    );
    let str_field = |v: &Value, k: &str| -> String {
        v[k].as_str()
            .unwrap_or_else(|| panic!("gltf-validator: no string {k:?} in {line}"))
            .to_string()
    };
    let count = |k: &str| -> u64 {
        v[k].as_u64()
            .unwrap_or_else(|| panic!("gltf-validator: no count {k:?} in {line}"))
    };
    let messages = v["messages"]
        .as_array()
        .unwrap_or_else(|| panic!("gltf-validator: no messages in {line}"))
        .iter()
        .map(|m| ValidatorMessage {
            code: str_field(m, "code"),
            severity: Severity::parse(&str_field(m, "severity")),
            pointer: m["pointer"].as_str().map(str::to_string),
            offset: m["offset"].as_u64(),
            message: str_field(m, "message"),
        })
        .collect();
    ValidatorReport {
        file: name.to_string(),
        validator_version: str_field(&v, "validatorVersion"),
        num_errors: count("numErrors"),
        num_warnings: count("numWarnings"),
        num_infos: count("numInfos"),
        num_hints: count("numHints"),
        truncated: v["truncated"].as_bool().unwrap_or(false),
        messages,
    }
}
