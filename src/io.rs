//! Atomic file writing and the folder lock live in `deepfoids_io`;
//! re-exported for the commands.

pub use deepfoids_io::{AtomicFile, DirLock, create_dir_atomic, write_atomic};

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
