//! Atomic file writing lives in `deepfoids_env::io`; re-exported for the
//! commands, with the folder lock of `deepfoids_env::lock`.

pub use deepfoids_env::io::{AtomicFile, create_dir_atomic, write_atomic};
pub use deepfoids_env::lock::DirLock;

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
