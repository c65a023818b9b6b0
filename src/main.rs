//! The `tspace` binary: `serve`, `process` and `analyze` (see `cli.rs`).

fn main() -> std::process::ExitCode {
    tspace::cli::main()
}
