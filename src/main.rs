//! The `deepfoids` command line: a thin layer over the library crates.

use std::process::ExitCode;

/// mimalloc instead of the system's allocator: the trainers and the
/// 30,000-fish cage allocate megabyte buffers every update or tick, which
/// glibc's malloc hands back to the kernel and gets again as fresh pages
/// (page faults and zeroing); mimalloc keeps them (docs/speed.md, session 45).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    #[cfg(unix)]
    // SAFETY: called first, before any thread or output exists; SIG_DFL is
    // the disposition every Unix tool starts with.
    unsafe {
        // Rust starts with SIGPIPE ignored, so a write to a closed pipe
        // (`deepfoids count … | head`) returns an error that `println!`
        // panics on; with the default the process ends quietly, as `cat`
        // and `grep` do.
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    match deepfoids::cli::run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
