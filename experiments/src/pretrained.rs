//! The trained policies that ship with the repository (`policies/<species>/`,
//! each a run folder holding `final/` — Burn weights, ONNX, `state.json` — its
//! training log and configuration, with a model card `policies/<species>.md`),
//! named on the command line as `pretrained:<species>`.

use std::path::{Path, PathBuf};

/// Prefix naming a shipped policy.
pub const PREFIX: &str = "pretrained:";

/// Where the shipped policies are: `$DEEPFOIDS_POLICIES`, else `./policies`
/// when it exists, else the repository's (the parent of this crate's folder).
pub fn root() -> PathBuf {
    shipped("DEEPFOIDS_POLICIES", "policies")
}

/// Where the shipped detector is: `$DEEPFOIDS_DETECTORS/fish.onnx`, else
/// `./detectors/fish.onnx` when that folder exists, else the repository's.
pub fn detector() -> PathBuf {
    shipped("DEEPFOIDS_DETECTORS", "detectors").join("fish.onnx")
}

/// A shipped folder: `$var`, else `./folder` when it exists, else the
/// repository's.
fn shipped(var: &str, folder: &str) -> PathBuf {
    if let Ok(d) = std::env::var(var) {
        return d.into();
    }
    let local = PathBuf::from(folder);
    if local.is_dir() {
        return local;
    }
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap_or(Path::new("."))
        .join(folder)
}

/// Species with a shipped policy in `root`.
pub fn available(root: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(root)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().join("final").join("state.json").is_file())
        .filter_map(|e| e.file_name().to_str().map(str::to_string))
        .collect();
    v.sort();
    v
}

/// `pretrained:<species>` → its folder; anything else is a path, unchanged.
pub fn resolve(s: &str) -> Result<PathBuf, String> {
    let Some(species) = s.strip_prefix(PREFIX) else {
        return Ok(PathBuf::from(s));
    };
    let root = root();
    let dir = root.join(species);
    if !species.is_empty()
        && !species.contains(['/', '\\', '.'])
        && dir.join("final").join("state.json").is_file()
    {
        return Ok(dir);
    }
    let have = available(&root);
    Err(format!(
        "no shipped policy `{species}` in {}; available: {}",
        root.display(),
        if have.is_empty() {
            "none".to_string()
        } else {
            have.iter()
                .map(|s| format!("{PREFIX}{s}"))
                .collect::<Vec<_>>()
                .join(", ")
        }
    ))
}

/// clap's parser of run-folder arguments (`--init-from`, `compare`'s runs).
pub fn parse_run(s: &str) -> Result<PathBuf, String> {
    resolve(s)
}
