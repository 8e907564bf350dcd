//! What every command that writes a run or output folder needs, apart from the
//! simulation: files written atomically ([`atomic`]) and an exclusive lock on a
//! folder for the life of a process ([`lock`]).

pub mod atomic;
pub mod lock;

pub use atomic::{AtomicFile, create_dir_atomic, write_atomic};
pub use lock::{DirLock, Holder, LockError};
