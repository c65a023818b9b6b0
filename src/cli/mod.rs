//! The command line: `tspace serve`, `tspace process`, `tspace analyze`, `tspace healthcheck`,
//! `tspace completions`.
//!
//! Thin on purpose: argument parsing, file I/O and exit codes. Scenes are read, decided and
//! written by [`crate::scene::input::process`], the same entry point the HTTP server calls.

mod batch;
mod health;
pub mod huge_pages;
mod outcome;
mod paths;
mod picture;
mod progress;
mod stdio;
mod tally;
mod writeback;

pub use batch::write_atomically;

use crate::config::ServeArgs;
use crate::scene::options::Choices;
use crate::scene::options::{Compression, parse_angle};
use crate::scene::pictures::PictureFormat;
use crate::scene::{Normals, OutputFormat, SceneOptions, TangentType};
use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, CommandFactory, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;
use std::process::ExitCode;
use tspace_tangent::Method;

/// The exit codes, for `--help` (the README repeats them).
macro_rules! exit_codes {
    () => {
        "\
Exit codes:
  0  success
  1  internal failure (a bug in tspace; the file is named and nothing is left half-written)
  2  usage error (bad flags, -o with several inputs, an output that would replace an input)
  3  bad input: a file that is missing, unreadable, not a scene, malformed, unprocessable or
     over a limit
  4  I/O failure writing an output or the report
  5  --fail-on: a finding it names (an audit that disagrees with MikkTSpace, a warning or error)
With several files the worst outcome wins, in the order 1, 4, 3, 5, 0."
    };
}

const EXIT_CODES: &str = exit_codes!();

#[derive(Parser)]
#[command(
    name = "tspace",
    version,
    about = "Tangent frames for glTF, GLB and OBJ scenes",
    after_long_help = EXIT_CODES
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the HTTP service.
    Serve(ServeArgs),
    /// Add tangents to scene files and write them as GLB (or .gltf).
    #[command(after_long_help = PROCESS_HELP)]
    Process(ProcessArgs),
    /// Print the JSON report of scene files without writing anything.
    #[command(after_long_help = ANALYZE_HELP)]
    Analyze(AnalyzeArgs),
    /// Draw a scene's texture layout (UV space) as an SVG or a PNG, problems marked.
    #[command(name = "uv-layout", after_long_help = UV_LAYOUT_HELP)]
    UvLayout(UvLayoutArgs),
    /// GET /healthz on a running service; exit 0 when it answers 2xx, else 1 (for containers).
    Healthcheck(health::HealthArgs),
    /// Print a shell completion script on stdout.
    #[command(after_long_help = COMPLETIONS_HELP)]
    Completions(CompletionsArgs),
}

const PROCESS_HELP: &str = concat!(
    "\
Outputs:
  without -o or --out-dir   beside each input, as <stem>.tspace.glb (or .tspace.gltf)
  -o FILE                   exactly one input file, written to FILE (-o - : standard output)
  --out-dir DIR             DIR/<stem>.glb; files found in a directory input keep their
                            subfolder under DIR
Directories are searched recursively for .glb, .gltf and .obj files, in name order; hidden
files and folders, symbolic links to folders, and earlier outputs (*.tspace.glb, *.tspace.gltf)
are left out. Buffers, images and MTL files are read from the folder of the file that names
them, never from outside it. An output that would replace an input, or two inputs that would
write the same output, is a usage error and nothing is written.

`-` as the input reads one scene from standard input, its format told from its bytes; it needs
-o (a file, or - for standard output). A .gltf read this way has no folder: only its data: URIs
are read. With -o - nothing but the scene is written to standard output.

Failures are printed one a line, `tspace: <file>: <message> (<code>)`, then one summary line
(none with -q; -v adds a line per file, with its warnings and errors).

",
    exit_codes!()
);

const ANALYZE_HELP: &str = concat!(
    "\
One input file (or - for standard input) prints its report. Several files, or a directory
(searched as `process` searches one), print a JSON array of {input, report} and
{input, error: {code, message}}, the --report document of `process`.

",
    exit_codes!()
);

const UV_LAYOUT_HELP: &str = concat!(
    "\
Draws, in texture space, every primitive that gets tangents (with --mesh and --primitive, the
chosen ones; with --all, every triangle primitive with UVs): the UV set the tangents follow,
the 0-1 square and any tiles beyond it, triangles filled by what tspace found (mirrored,
zero UV area, degenerate), repaired tangents outlined, handedness flips dotted, and a legend
whose counts are the report's. Without -o the picture is written beside the input as
<stem>.uv.svg (or .uv.png with --format png).

",
    exit_codes!()
);

const COMPLETIONS_HELP: &str = "\
Install (or re-run after upgrading tspace):
  bash  tspace completions bash > ~/.local/share/bash-completion/completions/tspace
  zsh   tspace completions zsh > ~/.zfunc/_tspace   (with fpath+=(~/.zfunc) before compinit)
  fish  tspace completions fish > ~/.config/fish/completions/tspace.fish";

/// The value parser of an option whose values the scene layer names ([`Choices`]): `--help`
/// lists its names with their help, a name outside them gets clap's usual "invalid value"
/// error, and the value itself comes from the type's one `FromStr`, the parser the query
/// string uses too. (A clap `ValueEnum` would need a mirror enum here, since `Method` lives in
/// the tangent core, and a second list of names to keep in step.)
fn choice<T: Choices>() -> impl TypedValueParser<Value = T>
where
    T::Err: std::error::Error + Send + Sync + 'static,
{
    let listed = T::choices()
        .into_iter()
        .map(|c| PossibleValue::new(c.name).help(c.help).aliases(c.aliases));
    PossibleValuesParser::new(listed).try_map(|name| name.parse::<T>())
}

/// What to do with each scene; shared by `process` and `analyze`.
#[derive(Clone, Debug, Args)]
struct SceneArgs {
    /// How tangents are computed.
    #[arg(long, value_parser = choice::<Method>(), default_value = "mikktspace")]
    method: Method,
    /// Recompute tangents that primitives already have (otherwise they are audited).
    #[arg(long)]
    overwrite: bool,
    /// Give tangents to every triangle primitive, normal map or not.
    #[arg(long)]
    all: bool,
    /// The TANGENT's component type.
    #[arg(long, value_parser = choice::<TangentType>(), default_value = "auto")]
    tangents: TangentType,
    /// How the written geometry is stored (EXT_meshopt_compression or not).
    #[arg(long, value_parser = choice::<Compression>(), default_value = "auto")]
    compress: Compression,
    /// Normals for OBJ faces without vn (glTF primitives without NORMAL are always flat, as
    /// the glTF specification requires).
    #[arg(long, value_parser = choice::<Normals>(), default_value = "auto")]
    normals: Normals,
    /// The crease angle in degrees (0 to 180) where OBJ normals are smoothed by angle: edges
    /// sharper than it stay hard.
    #[arg(long, value_name = "DEGREES", value_parser = parse_angle, default_value = "60")]
    normals_angle: f32,
}

impl SceneArgs {
    /// The scene layer's options for these arguments.
    fn scene_options(&self, format: OutputFormat, write: bool) -> SceneOptions {
        SceneOptions {
            method: self.method,
            overwrite: self.overwrite,
            all: self.all,
            format,
            write,
            tangents: self.tangents,
            compress: self.compress,
            normals: self.normals,
            normals_angle: self.normals_angle,
            // A large document's freed tree would otherwise stay beside the output's JSON.
            release_freed_memory: Some(crate::memory::give_back_freed_memory),
            ..SceneOptions::default()
        }
    }
}

/// A finding that `--fail-on` turns into exit 5.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum FailOn {
    /// Kept tangents that disagree with MikkTSpace (the report's summary.audits_disagreeing).
    Audit,
    /// Any finding of warning or error severity in a report (summary.findings).
    Warnings,
}

/// How a run reports itself and what fails it; shared by `process` and `analyze`.
#[derive(Clone, Debug, Args)]
struct RunArgs {
    /// Exit 5 when any file has this finding (a comma list, or repeat the flag).
    #[arg(long, value_name = "FINDING", value_enum, value_delimiter = ',')]
    fail_on: Vec<FailOn>,
    /// No progress bar and no summary line; failures are still printed, one line each.
    #[arg(short, long, conflicts_with = "verbose")]
    quiet: bool,
    /// A line per file with its counts, and each of its findings of warning or error severity.
    #[arg(short, long)]
    verbose: bool,
}

#[derive(Debug, Args)]
struct ProcessArgs {
    /// Scene files (.glb, .gltf, .obj) or directories to search for them; - reads standard
    /// input. `tspace process IN OUT` (two paths, the second a .glb or .gltf name that does not
    /// exist yet, or -) writes OUT.
    #[arg(value_name = "IN", required = true)]
    inputs: Vec<PathBuf>,
    /// The output file (only with exactly one input file); - writes standard output.
    #[arg(
        short = 'o',
        long = "output",
        value_name = "OUT",
        conflicts_with = "out_dir"
    )]
    output: Option<PathBuf>,
    /// Write outputs into this directory instead of beside the inputs.
    #[arg(long, value_name = "DIR")]
    out_dir: Option<PathBuf>,
    /// Write the JSON report here (- for standard output): one report for one input file, else
    /// an array of {input, output, report} or {input, error: {code, message}}.
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
    #[command(flatten)]
    scene: SceneArgs,
    /// Output format [default: glb, or gltf when -o names a .gltf file].
    #[arg(long, value_parser = choice::<OutputFormat>())]
    format: Option<OutputFormat>,
    /// Write a scene for looking, not shipping: each computed primitive painted by what tspace
    /// found in its triangles (COLOR_0 and an unlit material). Outputs are named
    /// <stem>.debug.glb.
    #[arg(long)]
    debug_colors: bool,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(Debug, Args)]
struct AnalyzeArgs {
    /// Scene files (.glb, .gltf, .obj) or directories to search for them; - reads standard
    /// input.
    #[arg(value_name = "IN", required = true)]
    inputs: Vec<PathBuf>,
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(Debug, Args)]
struct UvLayoutArgs {
    /// The scene file (.glb, .gltf, .obj), or - for standard input.
    #[arg(value_name = "IN")]
    input: PathBuf,
    /// The picture file (.svg or .png), or - for standard output.
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    output: Option<PathBuf>,
    /// svg or png [default: the output's extension, else svg].
    #[arg(long, value_parser = parse_picture_format)]
    format: Option<PictureFormat>,
    /// Draw only this mesh: its index in meshes, or its name.
    #[arg(long, value_name = "MESH")]
    mesh: Option<String>,
    /// With --mesh: draw only this primitive of it (its index).
    #[arg(long, value_name = "INDEX", requires = "mesh")]
    primitive: Option<String>,
    #[command(flatten)]
    scene: SceneArgs,
    /// No line naming the file written.
    #[arg(short, long)]
    quiet: bool,
}

fn parse_picture_format(value: &str) -> Result<PictureFormat, String> {
    value.parse()
}

#[derive(Debug, Args)]
struct CompletionsArgs {
    /// The shell to complete for.
    #[arg(value_enum)]
    shell: clap_complete::Shell,
}

/// How a command ended, ranked so that the worst of several can be kept.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Exit {
    #[default]
    Ok,
    /// `--fail-on` found what it names; every file was still read and written.
    Findings,
    BadInput,
    Write,
    Usage,
    Internal,
}

impl Exit {
    fn code(self) -> u8 {
        match self {
            Exit::Ok => 0,
            Exit::Internal => 1,
            Exit::Usage => 2,
            Exit::BadInput => 3,
            Exit::Write => 4,
            Exit::Findings => 5,
        }
    }

    fn rank(self) -> u8 {
        match self {
            Exit::Ok => 0,
            Exit::Findings => 1,
            Exit::BadInput => 2,
            Exit::Write => 3,
            Exit::Usage => 4,
            Exit::Internal => 5,
        }
    }

    /// The worse of the two.
    pub(crate) fn worst(self, other: Exit) -> Exit {
        if other.rank() > self.rank() {
            other
        } else {
            self
        }
    }
}

impl From<Exit> for ExitCode {
    fn from(e: Exit) -> ExitCode {
        ExitCode::from(e.code())
    }
}

/// A usage error found after parsing: one line on stderr naming the command's help, exit 2.
fn usage_error(subcommand: &str, message: impl std::fmt::Display) -> Exit {
    eprintln!("tspace {subcommand}: {message} (see tspace {subcommand} --help)");
    Exit::Usage
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    if !matches!(cli.command, Command::Serve(_)) {
        huge_pages::enable();
    }
    match cli.command {
        Command::Serve(args) => match crate::server::run(args.into()) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("tspace: {e}");
                ExitCode::from(1)
            }
        },
        Command::Process(args) => outcome::guarded_command(|| batch::process(args)).into(),
        Command::Analyze(args) => outcome::guarded_command(|| batch::analyze(args)).into(),
        Command::UvLayout(args) => outcome::guarded_command(|| picture::uv_layout(args)).into(),
        Command::Healthcheck(args) => health::run(&args).into(),
        Command::Completions(args) => print_completions(args.shell).into(),
    }
}

/// Writes the completion script for `shell` to stdout.
fn print_completions(shell: clap_complete::Shell) -> Exit {
    let mut script = Vec::new();
    clap_complete::generate(shell, &mut Cli::command(), "tspace", &mut script);
    match stdio::write_stdout(&script) {
        Ok(()) => Exit::Ok,
        Err(e) => {
            eprintln!(
                "tspace: cannot write the completion script: {} ({})",
                paths::io_message(&e),
                outcome::FailureCode::WriteFailed
            );
            Exit::Write
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_command_line_is_well_formed() {
        Cli::command().debug_assert();
    }

    #[test]
    fn the_worst_exit_wins() {
        assert_eq!(Exit::Ok.worst(Exit::BadInput), Exit::BadInput);
        assert_eq!(Exit::Write.worst(Exit::BadInput), Exit::Write);
        assert_eq!(Exit::Write.worst(Exit::Internal), Exit::Internal);
        assert_eq!(Exit::Ok.worst(Exit::Ok), Exit::Ok);
        assert_eq!(Exit::Ok.worst(Exit::Findings), Exit::Findings);
        assert_eq!(Exit::Findings.worst(Exit::BadInput), Exit::BadInput);
        assert_eq!(Exit::Findings.worst(Exit::Ok), Exit::Findings);
    }
}
