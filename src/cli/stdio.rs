//! `-`: a scene read from standard input, an output written to standard output.
//!
//! A scene from stdin is treated like an HTTP upload with no other parts: its format comes from
//! its bytes and a `.gltf`'s URIs are never opened (it has no folder; only `data:` URIs are
//! read), so piping a file can never make tspace read files the pipe did not name.

use super::outcome::{Failure, FailureCode};
use super::paths::io_message;
use crate::scene::Processed;
use crate::scene::error::ProblemCode;
use crate::scene::gltf::load::NoResources;
use crate::scene::input::{self, InputKind};
use crate::scene::options::SceneOptions;
use std::borrow::Cow;
use std::io::{IsTerminal, Read, Write};
use std::path::{Path, PathBuf};

/// The name that means standard input as an input and standard output as `-o`.
const DASH: &str = "-";

pub(crate) fn is_dash(path: &Path) -> bool {
    path.as_os_str() == DASH
}

/// How an input is named in messages.
pub(crate) fn input_name(path: &Path) -> Cow<'_, str> {
    if is_dash(path) {
        Cow::Borrowed("standard input")
    } else {
        path.to_string_lossy()
    }
}

/// How an output is named in messages.
pub(crate) fn output_name(path: &Path) -> Cow<'_, str> {
    if is_dash(path) {
        Cow::Borrowed("standard output")
    } else {
        path.to_string_lossy()
    }
}

/// Refuses a command line whose `-` cannot work: with other inputs (standard input is one
/// scene), without `-o` for `process` (there is no folder to write beside), or from a terminal
/// (it would wait for bytes nobody types).
pub(crate) fn check_dash_input(inputs: &[PathBuf], needs_output: bool) -> Result<(), String> {
    if !inputs.iter().any(|p| is_dash(p)) {
        return Ok(());
    }
    if inputs.len() > 1 {
        return Err(
            "- (standard input) is one scene and cannot be combined with other inputs".to_owned(),
        );
    }
    if needs_output {
        return Err(
            "- (standard input) needs -o: -o - writes standard output, -o FILE a file".to_owned(),
        );
    }
    if std::io::stdin().is_terminal() {
        return Err(
            "- reads a scene from standard input, which is a terminal; pipe one in (< model.glb)"
                .to_owned(),
        );
    }
    Ok(())
}

/// Reads standard input whole, refusing more than `max_bytes`.
fn read_stdin(max_bytes: u64) -> Result<Vec<u8>, Failure> {
    let mut bytes = Vec::new();
    std::io::stdin()
        .lock()
        .take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| {
            Failure::bad_input(
                FailureCode::UnreadableInput,
                format!("cannot read it: {}", io_message(&e)),
            )
        })?;
    if bytes.len() as u64 > max_bytes {
        return Err(Failure::bad_input(
            ProblemCode::TooLarge,
            format!("over the {max_bytes} byte limit"),
        ));
    }
    Ok(bytes)
}

/// Reads one scene from standard input and processes it, its format told from its bytes.
pub(crate) fn process_stdin(max_bytes: u64, options: &SceneOptions) -> Result<Processed, Failure> {
    let bytes = read_stdin(max_bytes)?;
    let kind = InputKind::sniff(&bytes).ok_or_else(|| {
        Failure::bad_input(FailureCode::UnknownFormat, "not a GLB, glTF or OBJ scene")
    })?;
    let processed = match kind {
        // The text goes once read, before the conversion needs as much memory again.
        InputKind::Obj => input::read_obj(&bytes, options).and_then(|read| {
            drop(bytes);
            input::process_read_obj(read, &NoResources, options)
        }),
        kind => input::process(kind, &bytes, &NoResources, options),
    };
    processed.map_err(|e| explain_missing_resource(e.into()))
}

/// A missing buffer or MTL file from standard input: say why nothing beside it was looked for.
fn explain_missing_resource(mut failure: Failure) -> Failure {
    if failure.code == FailureCode::Problem(ProblemCode::MissingResource) {
        failure.message.push_str(
            "; standard input has no folder to read it from (only data: URIs are read): name the file instead, or pipe a GLB",
        );
    }
    failure
}

/// Writes `bytes` to standard output and flushes it.
pub(crate) fn write_stdout(bytes: &[u8]) -> std::io::Result<()> {
    with_stdout(|out| out.write_all(bytes))
}

/// Writes to standard output with `write`, then flushes it.
pub(crate) fn with_stdout(
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let mut stdout = std::io::stdout().lock();
    write(&mut stdout)?;
    stdout.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dash_is_refused_where_it_cannot_work() {
        let dash = PathBuf::from("-");
        let other = PathBuf::from("a.glb");
        assert!(check_dash_input(std::slice::from_ref(&other), true).is_ok());
        let mixed = check_dash_input(&[dash.clone(), other], false).unwrap_err();
        assert!(mixed.contains("other inputs"), "{mixed}");
        let without_o = check_dash_input(&[dash], true).unwrap_err();
        assert!(without_o.contains("-o -"), "{without_o}");
    }

    #[test]
    fn a_missing_buffer_says_why() {
        let failure = explain_missing_resource(Failure::bad_input(
            ProblemCode::MissingResource,
            "buffers[0].uri: missing",
        ));
        assert!(failure.message.contains("no folder"), "{}", failure.message);
        let other = explain_missing_resource(Failure::bad_input(ProblemCode::MalformedGltf, "x"));
        assert_eq!(other.message, "x");
    }

    #[test]
    fn dash_is_named_for_what_it_is() {
        assert_eq!(input_name(Path::new("-")), "standard input");
        assert_eq!(output_name(Path::new("-")), "standard output");
        assert_eq!(input_name(Path::new("./-x")), "./-x");
    }
}
