//! What the `deepfoids` commands do, as a library that a Python or Ray driver
//! can call without the command line: the benchmarks ([`bench`]), load scenes and policies
//! ([`policies`]), evaluate a school ([`evaluate`]), train a scene
//! ([`training`]), runs side by side ([`compare`]), the two-step scheme
//! ([`pipeline`]), labelled datasets for detectors ([`dataset`]), replay pages ([`replays`]) and the reproduction of thesis §4.5 ([`reproduce`]: stages,
//! claims, measurement, figures, shipping).
//!
//! Errors are `anyhow` chains: the library crates below (`deepfoids-env`,
//! `-learn`, `-ppo`, `-sac`, `-onnx`, `-io`) give typed errors that name the
//! file or value; this crate adds which run, stage or claim it was.

pub mod bench;
pub mod bounds;
pub mod compare;
pub mod dataset;
pub mod evaluate;
pub mod pipeline;
pub mod plot;
pub mod policies;
pub mod pretrained;
pub mod process;
pub mod replays;
pub mod reproduce;
pub mod sensor_view;
pub mod simulate;
pub mod training;

pub use policies::{PolicyOptions, load_actor, load_scene, load_trained, make_policy};

use deepfoids_io::DirLock;

/// Lock output folder `dir` until the returned guard drops, so that no other
/// process writes it meanwhile; a lock left by a process that died is taken
/// over with a note on stderr.
pub fn lock_dir(dir: &std::path::Path) -> anyhow::Result<DirLock> {
    let lock = DirLock::acquire(dir)?;
    if let Some(dead) = lock.stale() {
        eprintln!(
            "note: {} was locked by {dead}, which ended without releasing it; taking the lock over",
            dir.display()
        );
    }
    Ok(lock)
}
