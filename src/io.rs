//! Atomic file writing lives in `deepfoids_env::io`; re-exported for the commands.

pub use deepfoids_env::io::{AtomicFile, create_dir_atomic, write_atomic};
