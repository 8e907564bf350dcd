//! What the integration tests of the binary share: running it from the
//! repository root, its output as one text, and fresh temporary folders
//! (`deepfoids_testkit`'s). Each test file uses a part of it.
#![allow(dead_code)]

#[allow(unused_imports)]
pub use deepfoids_testkit::{TempDir, temp_path};
use std::process::{Command, Output};

/// The `deepfoids` binary with `args`, run in the repository root.
pub fn command(args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_deepfoids"));
    c.args(args).current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

/// Run the binary with `args` to its end.
pub fn deepfoids(args: &[&str]) -> Output {
    command(args).output().expect("the binary runs")
}

/// The binary with the words of `line` (split at white space: an argument
/// holding a space, such as a path under a folder with one, goes through
/// [`command`]), run in the repository root.
pub fn command_line(line: &str) -> Command {
    let words: Vec<&str> = line.split_whitespace().collect();
    command(&words)
}

/// Run the binary with the words of `line` to its end (see [`command_line`]).
pub fn cli(line: &str) -> Output {
    command_line(line).output().expect("the binary runs")
}

/// [`cli`], which must succeed (its output shown if not).
#[track_caller]
pub fn cli_ok(line: &str) -> Output {
    let o = cli(line);
    succeeds(&o);
    o
}

/// A finished run of the binary that must have succeeded; its output.
#[track_caller]
pub fn succeeds(o: &Output) -> String {
    let t = text(o);
    assert!(o.status.success(), "{t}");
    t
}

/// [`cli`], which must fail with `said` in its output; the output.
#[track_caller]
pub fn cli_fails(line: &str, said: &str) -> String {
    fails(&cli(line), said)
}

/// A finished run of the binary that must have failed with `said` in its
/// output; the output.
#[track_caller]
pub fn fails(o: &Output, said: &str) -> String {
    let t = text(o);
    assert!(!o.status.success(), "succeeded where it must fail: {t}");
    assert!(t.contains(said), "failed without saying `{said}`: {t}");
    t
}

/// Standard output, then standard error.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The JSON file `path`, parsed.
pub fn json(path: &std::path::Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}
