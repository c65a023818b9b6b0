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

pub(crate) fn process(args: ProcessArgs) -> Exit {
    if args.output.is_some() && args.inputs.len() != 1 {
        return usage_error(
            "process",
            format!(
                "-o/--output takes exactly one input, and {} were given; use --out-dir DIR for several",
                args.inputs.len()
            ),
        );
    }
    let found = paths::collect(&args.inputs, args.out_dir.as_deref());
    let named_directory = args.inputs.iter().any(|p| p.is_dir());
    if let (Some(_), true) = (&args.output, named_directory) {
        return usage_error(
            "process",
            "-o/--output takes one input file, not a directory; use --out-dir DIR",
        );
    }
    let format: OutputFormat = match (args.format, &args.output) {
        (Some(format), _) => format,
        (None, Some(out))
            if out
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("gltf")) =>
        {
            OutputFormat::GltfEmbedded
        }
        _ => OutputFormat::Glb,
    };
    let destination = match (&args.output, &args.out_dir) {
        (Some(file), _) => Destination::File(file.clone()),
        (None, Some(dir)) => Destination::Dir(dir.clone()),
        (None, None) => Destination::Beside,
    };
    let plan: Vec<Plan> = found
        .iter()
        .map(|f| match f {
            Found::File(input) => Plan::Run(input, paths::output_path(input, &destination, format)),
            Found::Unreadable { path, message } => Plan::Fail(path, message),
        })
        .collect();
    let (files, planned): (Vec<&Input>, Vec<PathBuf>) = plan
        .iter()
        .filter_map(|p| match p {
            Plan::Run(input, output) => Some((*input, output.clone())),
            Plan::Fail(..) => None,
        })
        .unzip();
    if let Err(message) = paths::check(&files, &planned, args.report.as_deref()) {
        return usage_error("process", message);
    }

    let options = args.scene.scene_options(format, true);
    let bar = progress_bar(files.len());
    let outcomes: Vec<Outcome> = plan
        .par_iter()
        .map(|p| match p {
            Plan::Run(input, output) => {
                bar.set_message(input.path.display().to_string());
                let result = guarded(|| process_one(input, output, &options));
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
        })
        .collect();
    bar.finish_and_clear();

    let mut exit = Exit::Ok;
    let (mut ok, mut failed, mut generated, mut vertices_added) = (0u64, 0u64, 0u64, 0u64);
    for outcome in &outcomes {
        match &outcome.result {
            Ok(report) => {
                ok += 1;
                generated += report.summary.generated;
                vertices_added += report.summary.vertices_added;
            }
            Err(failure) => {
                failed += 1;
                exit = exit.worst(failure.exit);
                eprintln!("{}", failure_line(&outcome.input, failure));
            }
        }
    }
    if let Some(path) = &args.report {
        let single = args.inputs.len() == 1 && !named_directory;
        let written = report_text(&outcomes, single)
            .map_err(std::io::Error::other)
            .and_then(|text| write_atomically(path, format!("{text}\n").as_bytes()));
        if let Err(e) = written {
            eprintln!(
                "tspace: {}: cannot write the report: {} ({})",
                path.display(),
                io_message(&e),
                FailureCode::WriteFailed
            );
            exit = exit.worst(Exit::Write);
        }
    }
    eprintln!(
        "tspace: {} ok, {} failed; {} generated, {} added",
        plural(ok, "file", "files"),
        failed,
        plural(generated, "primitive", "primitives"),
        plural(vertices_added, "vertex", "vertices"),
    );
    exit
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
