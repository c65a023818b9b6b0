//! `tspace process` and `tspace analyze`: read files, call the scene layer, write outputs and
//! reports, and turn every outcome into lines on stderr and an exit code.

use super::outcome::{Failure, FailureCode, Outcome, failure_line, guarded, write_report_json};
use super::paths::{self, Destination, Found, Input, io_message};
use super::progress::Progress;
use super::stdio::{self, is_dash, output_name};
use super::tally::{self, Tally};
use super::writeback;
use super::{AnalyzeArgs, Exit, ProcessArgs, RunArgs, usage_error};
use crate::scene::error::{ProblemCode, SceneError};
use crate::scene::folder::Folder;
use crate::scene::input::{self, InputKind};
use crate::scene::options::Debug;
use crate::scene::report::Report;
use crate::scene::{OutputFormat, Processed, SceneOptions};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The largest file read: a main file, or a buffer, image or MTL file it names.
const MAX_FILE_BYTES: u64 = 1 << 30;

pub(super) fn read_and_process(path: &Path, options: &SceneOptions) -> Result<Processed, Failure> {
    if is_dash(path) {
        return stdio::process_stdin(MAX_FILE_BYTES, options);
    }
    let (processed, _) = process_file(read_input(path)?, options)?;
    Ok(processed)
}

/// Processes a scene file; returns with what it made the file's bytes, where they are still
/// held (a glTF's output in pieces refers to them). An OBJ's are let go once read (see
/// [`input::read_obj`]): nothing made from the text refers to it, and the mapping's pages
/// leave the process before the conversion's arrive.
fn process_file(
    file: SceneFile,
    options: &SceneOptions,
) -> Result<(Processed, Option<FileBytes>), Failure> {
    let SceneFile {
        bytes,
        kind,
        folder,
    } = file;
    if kind == InputKind::Obj {
        let read = input::read_obj(&bytes, options)?;
        drop(bytes);
        return Ok((input::process_read_obj(read, &folder, options)?, None));
    }
    let processed = input::process(kind, &bytes, &folder, options)?;
    Ok((processed, Some(bytes)))
}

/// A scene file's bytes, what they are, and the folder its other files are read from.
struct SceneFile {
    bytes: FileBytes,
    kind: InputKind,
    folder: Folder,
}

fn read_input(path: &Path) -> Result<SceneFile, Failure> {
    let unreadable = |e: std::io::Error| {
        Failure::bad_input(
            FailureCode::UnreadableInput,
            format!("cannot read it: {}", io_message(&e)),
        )
    };
    let metadata = std::fs::metadata(path).map_err(unreadable)?;
    if !metadata.is_file() {
        return Err(Failure::bad_input(
            FailureCode::UnreadableInput,
            "not a file (name the scene file itself)",
        ));
    }
    if metadata.len() > MAX_FILE_BYTES {
        return Err(Failure::bad_input(
            ProblemCode::TooLarge,
            format!(
                "the file has {} bytes, over the {MAX_FILE_BYTES} byte limit",
                metadata.len()
            ),
        ));
    }
    let bytes = read_file(path, metadata.len()).map_err(unreadable)?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let kind = InputKind::from_file_name(&name)
        .or_else(|| InputKind::sniff(&bytes))
        .ok_or_else(|| {
            Failure::bad_input(FailureCode::UnknownFormat, "not a GLB, glTF or OBJ file")
        })?;
    let folder = Folder::of_file(path, MAX_FILE_BYTES);
    Ok(SceneFile {
        bytes,
        kind,
        folder,
    })
}

/// Files this large are mapped rather than read. It was 16 MiB until a megabyte-sized scene
/// was measured too: DamagedHelmet (3.8 MB), `tspace process` in twenty runs of each build
/// three times over, 12.5–13.5 ms read against 11.4–12.2 ms mapped, 1,850 page faults against
/// 955.
const MAP_FROM_BYTES: u64 = 1 << 20;

/// A file's bytes: read into memory, or for a large file mapped from the page cache.
enum FileBytes {
    Read(Vec<u8>),
    Mapped(memmap2::Mmap),
}

impl std::ops::Deref for FileBytes {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        match self {
            FileBytes::Read(bytes) => bytes,
            FileBytes::Mapped(map) => map,
        }
    }
}

/// Reads `path` (of `length` bytes when it was looked at). A large file is mapped: reading it
/// would copy every byte into fresh memory first, and on a 56 MB GLB the copy and its page
/// faults took a tenth of the whole run, while most of the BIN chunk is only copied on into
/// the output. The map is private and read-only; another program that truncated the file while
/// tspace reads it would make it fail (as it would ripgrep, which maps files the same way), so
/// small files, where mapping saves little beside its own system calls, are read as before.
fn read_file(path: &Path, length: u64) -> std::io::Result<FileBytes> {
    if length < MAP_FROM_BYTES {
        return std::fs::read(path).map(FileBytes::Read);
    }
    let file = std::fs::File::open(path)?;
    // SAFETY: the map is read-only and private; its contents change only if another process
    // writes the file meanwhile, which gives wrong bytes (caught as a malformed scene) or, for a
    // truncation, a bus error: the risk every memory-mapping reader takes, named above.
    let map = unsafe { memmap2::Mmap::map(&file) }?;
    Ok(FileBytes::Mapped(map))
}

/// Writes to `path` through a temporary file beside it, so that a failure never leaves a partial
/// output under the final name (the commands' way of writing every file; benches measure it).
///
/// A path that is there and is neither a file nor a folder (`/dev/null`, `/dev/stdout`, a named
/// pipe, a shell's `>(…)`) is written as it is: renaming a file over it would replace the device
/// or pipe, and as root `--report /dev/null` replaced the machine's `/dev/null` with a file.
///
/// The previous file's cached pages are dropped first (see `writeback::drop_cached_pages`).
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    write_atomically_from(path, (), |(), out| write(out))
}

/// As [`write_atomically`], for a `write` that reads only `held` (an output's pieces and the
/// input they refer to), which is let go once the output is written, while the rename runs
/// (see `writeback::write_then`).
pub fn write_atomically_from<T: Send>(
    path: &Path,
    held: T,
    write: impl FnOnce(&T, &mut dyn std::io::Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        let mut special = std::fs::OpenOptions::new().write(true).open(path)?;
        return write(&held, &mut special);
    }
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    // The file replaced is never an input: `paths::check` refuses an output named as an input,
    // and another name for an input's file gives it a second link, which the drop leaves alone.
    writeback::drop_cached_pages(path);
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(format!(".tspace-tmp-{}", std::process::id()));
    let temporary = path.with_file_name(name);
    let result = std::fs::File::create(&temporary).and_then(|file| {
        writeback::write_then(file, held, write, || std::fs::rename(&temporary, path))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result
}

/// Writes one output: to standard output for `-`, else to its file.
pub(super) fn write_output(output: &Path, bytes: &[u8]) -> Result<(), Failure> {
    write_with(output, |out| out.write_all(bytes))
}

/// Writes one output with `write`: to standard output for `-`, else to its file.
fn write_with(
    output: &Path,
    write: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> Result<(), Failure> {
    write_from(output, (), |(), out| write(out))
}

/// Writes one output with `write`, which reads only `held`: to standard output for `-`, else to
/// its file, letting `held` go while the file is renamed into place (see
/// [`write_atomically_from`]).
fn write_from<T: Send>(
    output: &Path,
    held: T,
    write: impl FnOnce(&T, &mut dyn std::io::Write) -> std::io::Result<()>,
) -> Result<(), Failure> {
    let written = if is_dash(output) {
        stdio::with_stdout(|out| write(&held, out))
    } else {
        write_atomically_from(output, held, write)
    };
    written.map_err(|e| Failure {
        exit: Exit::Write,
        code: FailureCode::WriteFailed,
        message: format!("cannot write {}: {}", output_name(output), io_message(&e)),
    })
}

/// Reads one input and, for `process`, writes its output.
fn process_one(
    input: &Input,
    output: Option<&Path>,
    options: &SceneOptions,
) -> Result<Report, Failure> {
    let (Some(output), false) = (output, is_dash(&input.path)) else {
        let processed = read_and_process(&input.path, options)?;
        if let Some(output) = output {
            write_output(output, processed.bytes.as_deref().unwrap_or_default())?;
        }
        return Ok(processed.report);
    };
    // A file input is held until its output is written, so the output is written in pieces
    // that refer to it (see SceneOptions::in_pieces) and never assembled in memory.
    let file = read_input(&input.path)?;
    let options = SceneOptions {
        in_pieces: true,
        ..options.clone()
    };
    let (mut processed, held) = process_file(file, &options)?;
    match (processed.pieces.take(), held) {
        (Some(pieces), Some(bytes)) => {
            write_from(output, (pieces, bytes), |(pieces, bytes), out| {
                pieces.write_to(bytes, out)
            })?
        }
        // An OBJ's: they hold the GLB it was converted to.
        (Some(pieces), None) if pieces.hold_their_input() => {
            write_from(output, pieces, |pieces, out| pieces.write_to(&[], out))?
        }
        (Some(_), None) => {
            return Err(SceneError::new(
                ProblemCode::Internal,
                "the written scene refers to an input that was let go",
            )
            .into());
        }
        (None, _) => write_output(output, processed.bytes.as_deref().unwrap_or_default())?,
    }
    Ok(processed.report)
}

/// One input's part of a run: a file to read (and, for `process`, the output to write), or a
/// failure found already.
enum Plan<'a> {
    Run(&'a Input, Option<PathBuf>),
    Fail(&'a Path, &'a str),
}

/// `tspace process IN OUT`, the form glTF-Transform's users type: two paths, neither `-o` nor
/// `--out-dir`, the first a file (or `-`) and the second a `.glb` or `.gltf` name (or `-`). When
/// the second does not exist it can only be meant as the output, and becomes `-o`; so does `-`,
/// since standard input cannot be a second input. When the second exists the line is ambiguous
/// (two inputs, or the output of an earlier run): refused, naming the two ways to say it, rather
/// than guessed; guessing "input" would leave a stale output behind and report success,
/// guessing "output" could overwrite an input.
fn take_in_out_form(args: &mut ProcessArgs) -> Result<(), String> {
    let [first, second] = args.inputs.as_slice() else {
        return Ok(());
    };
    let scene_name = second
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"));
    let first_is_input = is_dash(first) || first.is_file();
    if args.output.is_some()
        || args.out_dir.is_some()
        || !first_is_input
        || !(scene_name || is_dash(second))
    {
        return Ok(());
    }
    if second.exists() && !is_dash(second) {
        return Err(format!(
            "{} exists, so it is not clear whether it is a second input or the output; to write the output there, say -o {}; to process both files, add --out-dir DIR",
            second.display(),
            second.display()
        ));
    }
    args.output = Some(second.clone());
    args.inputs.truncate(1);
    Ok(())
}

/// `-o` names one output file (or standard output), so it takes exactly one input, and that a
/// file.
fn check_single_output(args: &ProcessArgs, named_directory: bool) -> Result<(), String> {
    let Some(output) = &args.output else {
        return Ok(());
    };
    let flag = if is_dash(output) {
        "-o - (standard output)"
    } else {
        "-o/--output"
    };
    if args.inputs.len() != 1 {
        return Err(format!(
            "{flag} takes exactly one input, and {} were given; use --out-dir DIR for several",
            args.inputs.len()
        ));
    }
    if named_directory {
        return Err(format!(
            "{flag} takes one input file, not a directory; use --out-dir DIR"
        ));
    }
    Ok(())
}

/// Whether an input names a directory (whose files then get an array report).
fn names_directory(inputs: &[PathBuf]) -> bool {
    inputs.iter().any(|p| !is_dash(p) && p.is_dir())
}

/// Standard output carries one thing: the scene or the report.
fn check_one_stdout(args: &ProcessArgs) -> Result<(), String> {
    let to_stdout = |p: &Option<PathBuf>| p.as_deref().is_some_and(is_dash);
    if to_stdout(&args.output) && to_stdout(&args.report) {
        return Err(
            "-o - and --report - would both write standard output; write one of them to a file"
                .to_owned(),
        );
    }
    Ok(())
}

/// The checks of a `process` line that need no file read: its form, `-`, and `-o`.
fn check_process_line(args: &mut ProcessArgs) -> Result<(), String> {
    take_in_out_form(args)?;
    stdio::check_dash_input(&args.inputs, args.output.is_none())?;
    check_one_stdout(args)?;
    check_single_output(args, names_directory(&args.inputs))
}

/// `--format` when given, else what `-o`'s extension says, else GLB.
fn output_format(args: &ProcessArgs) -> OutputFormat {
    match (args.format, &args.output) {
        (Some(format), _) => format,
        (None, Some(out))
            if out
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("gltf")) =>
        {
            OutputFormat::GltfEmbedded
        }
        _ => OutputFormat::Glb,
    }
}

fn destination(args: &ProcessArgs) -> Destination {
    match (&args.output, &args.out_dir) {
        (Some(file), _) => Destination::File(file.clone()),
        (None, Some(dir)) => Destination::Dir(dir.clone()),
        (None, None) => Destination::Beside,
    }
}

/// Each input's part of the run; `destination` is where outputs go (and whether they are debug
/// outputs), `None` for `analyze`.
fn plan_runs<'a>(
    found: &'a [Found],
    destination: Option<(&Destination, bool)>,
    format: OutputFormat,
) -> Vec<Plan<'a>> {
    found
        .iter()
        .map(|f| match f {
            Found::File(input) => Plan::Run(
                input,
                destination.map(|(d, debug)| paths::output_path(input, d, format, debug)),
            ),
            Found::Unreadable { path, message } => Plan::Fail(path, message),
        })
        .collect()
}

/// Refuses, before anything is written, a plan whose outputs or report would replace an input,
/// or that writes two outputs to one path.
fn check_outputs(plan: &[Plan], report: Option<&Path>) -> Result<(), String> {
    let (files, planned): (Vec<&Input>, Vec<PathBuf>) = plan
        .iter()
        .filter_map(|p| match p {
            Plan::Run(input, Some(output)) => Some((*input, output.clone())),
            Plan::Run(_, None) | Plan::Fail(..) => None,
        })
        .unzip();
    paths::check(&files, &planned, report)
}

fn run_one(plan: &Plan, options: &SceneOptions, progress: &Progress) -> Outcome {
    match plan {
        Plan::Run(input, output) => {
            progress.start(&input.path);
            let result = guarded(|| process_one(input, output.as_deref(), options));
            progress.done();
            Outcome {
                input: input.path.clone(),
                output: output.clone(),
                result,
            }
        }
        Plan::Fail(path, message) => Outcome {
            input: path.to_path_buf(),
            output: None,
            result: Err(Failure::bad_input(FailureCode::UnreadableInput, *message)),
        },
    }
}

/// Runs the files in parallel; outcomes stay in input order. One file runs on this thread: the
/// scene layer spreads its own work over the threads, and a file that cannot be read then
/// fails without starting them.
fn run_all(plan: &[Plan], options: &SceneOptions, run: &RunArgs) -> Vec<Outcome> {
    let files = plan.iter().filter(|p| matches!(p, Plan::Run(..))).count();
    let progress = Progress::new(files, !run.quiet);
    let outcomes = if plan.len() <= 1 {
        plan.iter()
            .map(|p| run_one(p, options, &progress))
            .collect()
    } else {
        plan.par_iter()
            .map(|p| run_one(p, options, &progress))
            .collect()
    };
    progress.finish();
    outcomes
}

/// One line per failure and, with `--verbose`, the lines of each file that succeeded; after the
/// parallel run, so that lines come in input order.
fn print_outcomes(outcomes: &[Outcome], verbose: bool) {
    for outcome in outcomes {
        match &outcome.result {
            Ok(report) if verbose => {
                for line in tally::file_lines(&outcome.input, report) {
                    eprintln!("{line}");
                }
            }
            Ok(_) => {}
            Err(failure) => eprintln!("{}", failure_line(&outcome.input, failure)),
        }
    }
}

/// Writes the `--report` document, to standard output for `-`. Failing to is [`Exit::Write`]
/// but undoes nothing: the outputs are written already.
fn write_report(path: &Path, outcomes: &[Outcome], single: bool) -> Exit {
    let written = if is_dash(path) {
        write_report_json(outcomes, single, std::io::stdout().lock())
    } else {
        write_atomically(path, |file| write_report_json(outcomes, single, file))
    };
    match written {
        Ok(()) => Exit::Ok,
        Err(e) => {
            eprintln!(
                "tspace: {}: cannot write the report: {} ({})",
                output_name(path),
                io_message(&e),
                FailureCode::WriteFailed
            );
            Exit::Write
        }
    }
}

/// Exit 5 when `--fail-on` names a finding the run had, with the line that says so; failures
/// still win (see [`Exit::worst`]).
fn apply_fail_on(tally: &Tally, run: &RunArgs) -> Exit {
    match tally.fail_on_line(&run.fail_on) {
        Some(line) => {
            eprintln!("{line}");
            Exit::Findings
        }
        None => Exit::Ok,
    }
}

pub(crate) fn process(mut args: ProcessArgs) -> Exit {
    if let Err(message) = check_process_line(&mut args) {
        return usage_error("process", message);
    }
    let format = output_format(&args);
    let found = paths::collect(&args.inputs, args.out_dir.as_deref());
    let debug = args.debug_colors;
    let plan = plan_runs(&found, Some((&destination(&args), debug)), format);
    if let Err(message) = check_outputs(&plan, args.report.as_deref()) {
        return usage_error("process", message);
    }

    let options = SceneOptions {
        debug: if debug { Debug::Colors } else { Debug::None },
        ..args.scene.scene_options(format, true)
    };
    let outcomes = run_all(&plan, &options, &args.run);
    print_outcomes(&outcomes, args.run.verbose);
    let tally = Tally::of(&outcomes);
    let mut exit = tally.exit;
    if let Some(path) = &args.report {
        // One input file gets its report alone; several, or a folder, get an array of them.
        let single = args.inputs.len() == 1 && !names_directory(&args.inputs);
        exit = exit.worst(write_report(path, &outcomes, single));
    }
    if !args.run.quiet {
        eprintln!("{}", tally.summary_line());
    }
    exit.worst(apply_fail_on(&tally, &args.run))
}

/// `analyze`'s stdout: one named file's report alone, as before several inputs were taken (so
/// scripts reading it keep working), nothing when that file failed (its line is on stderr);
/// else the array `process --report` writes.
fn print_analysis(outcomes: &[Outcome], single: bool) -> Exit {
    if let [one] = outcomes
        && single
        && one.result.is_err()
    {
        return Exit::Ok;
    }
    match write_report_json(outcomes, single, std::io::stdout().lock()) {
        Ok(()) => Exit::Ok,
        Err(e) => {
            eprintln!(
                "tspace: cannot write the report: {} ({})",
                io_message(&e),
                FailureCode::WriteFailed
            );
            Exit::Write
        }
    }
}

pub(crate) fn analyze(args: AnalyzeArgs) -> Exit {
    if let Err(message) = stdio::check_dash_input(&args.inputs, false) {
        return usage_error("analyze", message);
    }
    let found = paths::collect(&args.inputs, None);
    let plan = plan_runs(&found, None, OutputFormat::Glb);
    let options = args.scene.scene_options(OutputFormat::Glb, false);

    let outcomes = run_all(&plan, &options, &args.run);
    print_outcomes(&outcomes, args.run.verbose);
    let tally = Tally::of(&outcomes);
    let single = args.inputs.len() == 1 && !names_directory(&args.inputs);
    let mut exit = tally.exit;
    exit = exit.worst(print_analysis(&outcomes, single));
    exit.worst(apply_fail_on(&tally, &args.run))
}
