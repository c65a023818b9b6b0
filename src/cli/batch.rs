//! `tspace process` and `tspace analyze`: read files, call the scene layer, write outputs and
//! reports, and turn every outcome into lines on stderr and an exit code.

use super::outcome::{Failure, FailureCode, Outcome, failure_line, guarded, report_text};
use super::paths::{self, Destination, Found, Input, io_message};
use super::{AnalyzeArgs, Exit, ProcessArgs, usage_error};
use crate::scene::error::ProblemCode;
use crate::scene::folder::Folder;
use crate::scene::input::{self, InputKind};
use crate::scene::report::Report;
use crate::scene::{OutputFormat, Processed, SceneOptions};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

/// The largest file read: a main file, or a buffer, image or MTL file it names.
const MAX_FILE_BYTES: u64 = 1 << 30;

fn read_and_process(path: &Path, options: &SceneOptions) -> Result<Processed, Failure> {
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
    let bytes = std::fs::read(path).map_err(unreadable)?;
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
    Ok(input::process(kind, &bytes, &folder, options)?)
}

/// Writes `bytes` to `path` through a temporary file beside it, so that a failure never leaves
/// a partial output under the final name.
fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(format!(".tspace-tmp-{}", std::process::id()));
    let temporary = path.with_file_name(name);
    let result = std::fs::write(&temporary, bytes).and_then(|()| std::fs::rename(&temporary, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result
}

fn process_one(input: &Input, output: &Path, options: &SceneOptions) -> Result<Report, Failure> {
    let processed = read_and_process(&input.path, options)?;
    let bytes = processed.bytes.unwrap_or_default();
    write_atomically(output, &bytes).map_err(|e| Failure {
        exit: Exit::Write,
        code: FailureCode::WriteFailed,
        message: format!("cannot write {}: {}", output.display(), io_message(&e)),
    })?;
    Ok(processed.report)
}

fn progress_bar(files: usize) -> ProgressBar {
    if files == 0 || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(files as u64);
    if let Ok(style) =
        ProgressStyle::with_template("{bar:30} {pos}/{len} files  {elapsed}  {wide_msg}")
    {
        bar.set_style(style);
    }
    bar
}

/// One input's part of a run: a file to process into an output, or a failure found already.
enum Plan<'a> {
    Run(&'a Input, PathBuf),
    Fail(&'a Path, &'a str),
}

fn plural(n: u64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// `tspace process IN OUT`, the form glTF-Transform's users type: two paths, neither `-o` nor
/// `--out-dir`, the first a file and the second a `.glb` or `.gltf` name. When the second does not
/// exist it can only be meant as the output, and becomes `-o`. When it does exist the line is
/// ambiguous (two inputs, or the output of an earlier run): refused, naming the two ways to say
/// it, rather than guessed; guessing "input" would leave a stale output behind and report
/// success, guessing "output" could overwrite an input.
fn take_in_out_form(args: &mut ProcessArgs) -> Result<(), String> {
    let [first, second] = args.inputs.as_slice() else {
        return Ok(());
    };
    let scene_name = second
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"));
    if args.output.is_some() || args.out_dir.is_some() || !first.is_file() || !scene_name {
        return Ok(());
    }
    if second.exists() {
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

/// `-o` names one output file, so it takes exactly one input, and that a file.
fn check_single_output(args: &ProcessArgs, named_directory: bool) -> Result<(), String> {
    if args.output.is_none() {
        return Ok(());
    }
    if args.inputs.len() != 1 {
        return Err(format!(
            "-o/--output takes exactly one input, and {} were given; use --out-dir DIR for several",
            args.inputs.len()
        ));
    }
    if named_directory {
        return Err(
            "-o/--output takes one input file, not a directory; use --out-dir DIR".to_owned(),
        );
    }
    Ok(())
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

fn plan_runs<'a>(
    found: &'a [Found],
    destination: &Destination,
    format: OutputFormat,
) -> Vec<Plan<'a>> {
    found
        .iter()
        .map(|f| match f {
            Found::File(input) => Plan::Run(input, paths::output_path(input, destination, format)),
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
            Plan::Run(input, output) => Some((*input, output.clone())),
            Plan::Fail(..) => None,
        })
        .unzip();
    paths::check(&files, &planned, report)
}

fn run_one(plan: &Plan, options: &SceneOptions, bar: &ProgressBar) -> Outcome {
    match plan {
        Plan::Run(input, output) => {
            bar.set_message(input.path.display().to_string());
            let result = guarded(|| process_one(input, output, options));
            bar.inc(1);
            Outcome {
                input: input.path.clone(),
                output: Some(output.clone()),
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

/// Runs the files in parallel; outcomes stay in input order.
fn run_all(plan: &[Plan], options: &SceneOptions) -> Vec<Outcome> {
    let files = plan.iter().filter(|p| matches!(p, Plan::Run(..))).count();
    let bar = progress_bar(files);
    let outcomes = plan.par_iter().map(|p| run_one(p, options, &bar)).collect();
    bar.finish_and_clear();
    outcomes
}

/// How a run went: the worst exit code and the counts of the closing line.
struct Summary {
    exit: Exit,
    ok: u64,
    failed: u64,
    generated: u64,
    vertices_added: u64,
}

/// Prints one line per failure, after the parallel run so that lines come in input order.
fn print_failures(outcomes: &[Outcome]) -> Summary {
    let mut summary = Summary {
        exit: Exit::Ok,
        ok: 0,
        failed: 0,
        generated: 0,
        vertices_added: 0,
    };
    for outcome in outcomes {
        match &outcome.result {
            Ok(report) => {
                summary.ok += 1;
                summary.generated += report.summary.generated;
                summary.vertices_added += report.summary.vertices_added;
            }
            Err(failure) => {
                summary.failed += 1;
                summary.exit = summary.exit.worst(failure.exit);
                eprintln!("{}", failure_line(&outcome.input, failure));
            }
        }
    }
    summary
}

/// Writes the `--report` document. Failing to is [`Exit::Write`] but undoes nothing: the
/// outputs are written already.
fn write_report(path: &Path, outcomes: &[Outcome], single: bool) -> Exit {
    let written = report_text(outcomes, single)
        .map_err(std::io::Error::other)
        .and_then(|text| write_atomically(path, format!("{text}\n").as_bytes()));
    match written {
        Ok(()) => Exit::Ok,
        Err(e) => {
            eprintln!(
                "tspace: {}: cannot write the report: {} ({})",
                path.display(),
                io_message(&e),
                FailureCode::WriteFailed
            );
            Exit::Write
        }
    }
}

fn print_summary(summary: &Summary) {
    eprintln!(
        "tspace: {} ok, {} failed; {} generated, {} added",
        plural(summary.ok, "file", "files"),
        summary.failed,
        plural(summary.generated, "primitive", "primitives"),
        plural(summary.vertices_added, "vertex", "vertices"),
    );
}

pub(crate) fn process(mut args: ProcessArgs) -> Exit {
    if let Err(message) = take_in_out_form(&mut args) {
        return usage_error("process", message);
    }
    let named_directory = args.inputs.iter().any(|p| p.is_dir());
    if let Err(message) = check_single_output(&args, named_directory) {
        return usage_error("process", message);
    }
    let format = output_format(&args);
    let found = paths::collect(&args.inputs, args.out_dir.as_deref());
    let plan = plan_runs(&found, &destination(&args), format);
    if let Err(message) = check_outputs(&plan, args.report.as_deref()) {
        return usage_error("process", message);
    }

    let outcomes = run_all(&plan, &args.scene.scene_options(format, true));
    let mut summary = print_failures(&outcomes);
    if let Some(path) = &args.report {
        // One input file gets its report alone; several, or a folder, get an array of them.
        let single = args.inputs.len() == 1 && !named_directory;
        summary.exit = summary.exit.worst(write_report(path, &outcomes, single));
    }
    print_summary(&summary);
    summary.exit
}

pub(crate) fn analyze(args: AnalyzeArgs) -> Exit {
    let options = args.scene.scene_options(OutputFormat::Glb, false);
    match guarded(|| read_and_process(&args.input, &options)) {
        Ok(processed) => {
            let mut stdout = std::io::stdout().lock();
            match writeln!(stdout, "{}", processed.report.to_json_pretty())
                .and_then(|()| stdout.flush())
            {
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
        Err(failure) => {
            eprintln!("{}", failure_line(&args.input, &failure));
            failure.exit
        }
    }
}
