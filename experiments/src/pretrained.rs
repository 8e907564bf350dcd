//! The trained policies that ship with the repository, named on the command
//! line as `pretrained:<species>` (the species' default scene,
//! `policies/<species>/`) or `pretrained:<species>/<scene>` (transferred into
//! another scene, `policies/<species>/<scene>/`). Each is a run folder
//! holding `final/` — Burn weights, ONNX, `state.json` — its training log and
//! configuration, with a model card beside it (`policies/<species>.md`,
//! `policies/<species>/<scene>.md`).

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

/// Whether `dir` holds a finished policy (`final/state.json`).
fn is_policy(dir: &Path) -> bool {
    dir.join("final").join("state.json").is_file()
}

/// The subfolders of `dir` that hold a policy, by name, sorted.
fn policy_folders(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| is_policy(&e.path()))
        .filter_map(|e| e.file_name().to_str().map(str::to_string))
        .filter(|n| !n.starts_with('.'))
        .collect();
    v.sort();
    v
}

/// The shipped policies in `root` by name: each species (`coho`), then its
/// other scenes (`coho/density_dense`).
pub fn available(root: &Path) -> Vec<String> {
    let mut v = vec![];
    for species in policy_folders(root) {
        let nested = policy_folders(&root.join(&species));
        v.push(species.clone());
        v.extend(nested.into_iter().map(|scene| format!("{species}/{scene}")));
    }
    v
}

/// `pretrained:<species>` or `pretrained:<species>/<scene>` → its folder;
/// anything else is a path, unchanged.
pub fn resolve(s: &str) -> Result<PathBuf, String> {
    let Some(name) = s.strip_prefix(PREFIX) else {
        return Ok(PathBuf::from(s));
    };
    let root = root();
    let parts: Vec<&str> = name.split('/').collect();
    let well_formed = parts.len() <= 2
        && parts
            .iter()
            .all(|p| !p.is_empty() && !p.contains(['\\', '.']));
    let dir = parts.iter().fold(root.clone(), |d, p| d.join(p));
    if well_formed && is_policy(&dir) {
        return Ok(dir);
    }
    let have = available(&root);
    Err(format!(
        "no shipped policy `{name}` in {}; available: {}",
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
