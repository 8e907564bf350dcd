//! The `deepfoids` command line: a thin layer over the library crates.

use std::process::ExitCode;

fn main() -> ExitCode {
    match deepfoids::cli::run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
