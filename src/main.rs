//! The `tspace` binary: `serve`, `process`, `analyze` and `healthcheck` (see `src/cli/`).

/// The system allocator, with large blocks on huge pages for the one-shot commands (see
/// `tspace::cli::huge_pages`).
#[global_allocator]
static ALLOCATOR: tspace::cli::huge_pages::LargeOnHugePages =
    tspace::cli::huge_pages::LargeOnHugePages;

fn main() -> std::process::ExitCode {
    tspace::cli::main()
}
