//! The `citymesh` binary: parses the command line and hands over to the library.

use citymesh::cli::Cli;
use clap::Parser;

// mimalloc keeps freed pages for the next request instead of handing a scene's buffers back to
// the kernel and faulting them in again (a fifth of generation time with glibc's allocator).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Runs the command; an error is printed as one message with its causes (`error: ...: ...`),
/// never a backtrace, and the exit status is 1.
fn main() -> std::process::ExitCode {
    match citymesh::commands::run(Cli::parse().command.unwrap_or_default()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
