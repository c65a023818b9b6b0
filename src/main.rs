//! The `tspace` binary: `serve`, `process`, `analyze` and `healthcheck` (see `src/cli/`).

fn main() -> std::process::ExitCode {
    tspace::cli::main()
}
