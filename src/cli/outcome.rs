//! Outcomes: why a file failed, panics caught and turned into failures, the failure line on
//! stderr, and the `--report` document.

use super::Exit;
use crate::scene::error::{ProblemCode, SceneError};
use crate::scene::report::Report;
use serde::Serialize;
use std::fmt;
use std::io::Write;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

/// A failure's code: one of the [`ProblemCode`]s the service shares, or one of the few only a
/// command line has, for files it reads and writes itself (the service never names a file).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FailureCode {
    Problem(ProblemCode),
    /// Missing, not a file, or unreadable.
    UnreadableInput,
    /// Neither its name nor its bytes say GLB, glTF or OBJ.
    UnknownFormat,
    /// An output or the report could not be written.
    WriteFailed,
}

impl FailureCode {
    /// What `(code)` and the `--report` document's `code` say.
    pub(crate) fn slug(self) -> &'static str {
        match self {
            FailureCode::Problem(code) => code.code(),
            FailureCode::UnreadableInput => "unreadable-input",
            FailureCode::UnknownFormat => "unknown-format",
            FailureCode::WriteFailed => "write-failed",
        }
    }
}

impl From<ProblemCode> for FailureCode {
    fn from(code: ProblemCode) -> Self {
        FailureCode::Problem(code)
    }
}

impl fmt::Display for FailureCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.slug())
    }
}

/// Why one file failed.
#[derive(Debug)]
pub(crate) struct Failure {
    pub exit: Exit,
    pub code: FailureCode,
    pub message: String,
}

impl Failure {
    pub(crate) fn bad_input(code: impl Into<FailureCode>, message: impl Into<String>) -> Self {
        Failure {
            exit: Exit::BadInput,
            code: code.into(),
            message: message.into(),
        }
    }
}

impl From<SceneError> for Failure {
    fn from(e: SceneError) -> Self {
        Failure::bad_input(e.code, e.message)
    }
}

/// What happened to one input.
pub(crate) struct Outcome {
    pub input: PathBuf,
    pub output: Option<PathBuf>,
    pub result: Result<Report, Failure>,
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".to_owned())
}

/// Runs `f`, turning a panic into an internal failure.
pub(crate) fn guarded<T>(f: impl FnOnce() -> Result<T, Failure>) -> Result<T, Failure> {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|payload| {
        Err(Failure {
            exit: Exit::Internal,
            code: ProblemCode::Internal.into(),
            message: format!(
                "internal error: {}; this is a bug in tspace, please report it (RUST_BACKTRACE=1 shows where)",
                panic_message(&*payload)
            ),
        })
    })
}

/// Runs a whole command with panics kept from the terminal: each is reported as one line by
/// whoever catches it. With `RUST_BACKTRACE` set, Rust's own panic message is printed as well.
pub(crate) fn guarded_command(f: impl FnOnce() -> Exit) -> Exit {
    if std::env::var_os("RUST_BACKTRACE").is_none() {
        std::panic::set_hook(Box::new(|_| {}));
    }
    match guarded(|| Ok(f())) {
        Ok(exit) => exit,
        Err(failure) => {
            eprintln!("tspace: {}", failure.message);
            failure.exit
        }
    }
}

pub(crate) fn failure_line(path: &Path, failure: &Failure) -> String {
    format!(
        "tspace: {}: {} ({})",
        super::stdio::input_name(path),
        failure.message,
        failure.code
    )
}

#[derive(Serialize)]
struct ErrorJson<'a> {
    code: &'a str,
    message: &'a str,
}

/// One element of the `--report` array.
#[derive(Serialize)]
struct EntryJson<'a> {
    input: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    output: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    report: Option<&'a Report>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<ErrorJson<'a>>,
}

impl<'a> EntryJson<'a> {
    fn of(outcome: &'a Outcome) -> Self {
        let lossy = |p: &Path| p.to_string_lossy().into_owned();
        let (report, error) = match &outcome.result {
            Ok(report) => (Some(report), None),
            Err(f) => (
                None,
                Some(ErrorJson {
                    code: f.code.slug(),
                    message: &f.message,
                }),
            ),
        };
        // A failed entry names its output only when writing it was what failed.
        let output = match &outcome.result {
            Ok(_)
            | Err(Failure {
                exit: Exit::Write, ..
            }) => outcome.output.as_deref().map(lossy),
            Err(_) => None,
        };
        EntryJson {
            input: lossy(&outcome.input),
            output,
            report,
            error,
        }
    }
}

/// Writes the `--report` document and a newline to `out`: the report itself for one named input
/// file that succeeded, that file's entry when it failed, else an array of entries. Serialized
/// as it is written: a scene of many primitives has a report twice its own size as text, which
/// is never held whole.
pub(crate) fn write_report_json(
    outcomes: &[Outcome],
    single: bool,
    out: impl std::io::Write,
) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::with_capacity(1 << 16, out);
    match outcomes {
        [one] if single => match &one.result {
            Ok(report) => serde_json::to_writer_pretty(&mut out, report),
            Err(_) => serde_json::to_writer_pretty(&mut out, &EntryJson::of(one)),
        },
        _ => serde_json::to_writer_pretty(
            &mut out,
            &outcomes.iter().map(EntryJson::of).collect::<Vec<_>>(),
        ),
    }?;
    out.write_all(b"\n")?;
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_an_internal_failure() {
        let result: Result<(), Failure> = guarded(|| panic!("boom {}", 7));
        let failure = result.unwrap_err();
        assert_eq!(failure.exit, Exit::Internal);
        assert_eq!(failure.code.slug(), "internal");
        assert!(failure.message.contains("boom 7"), "{}", failure.message);
    }
}
