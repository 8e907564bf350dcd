//! An exclusive lock on a folder for the life of a process, so that two
//! processes never write one run or output folder at once.
//!
//! ```no_run
//! # fn main() -> Result<(), deepfoids_io::LockError> {
//! use deepfoids_io::DirLock;
//! let lock = DirLock::acquire(std::path::Path::new("runs/my-run"))?;
//! if let Some(dead) = lock.stale() {
//!     eprintln!("warning: took over the stale lock of {dead}");
//! }
//! // … create, resume or replace runs/my-run; nobody else can until `lock` drops.
//! # Ok(()) }
//! ```
//!
//! # How it works
//!
//! * **Where.** The lock is a file *beside* the folder, `<parent>/.<name>.lock`,
//!   so a folder can be locked before it exists, and removed and made again
//!   (`--force`) while locked. The parent is canonicalised first: every
//!   spelling of one folder (`runs/x`, `./runs/../runs/x`, a symlink to it)
//!   locks the same file.
//! * **Holding.** The holder keeps the file open with an exclusive `flock`
//!   (`File::try_lock`; `LockFileEx` on Windows) for as long as the [`DirLock`]
//!   lives. The kernel drops a `flock` when its process ends, however it ends —
//!   so a killed holder never blocks anyone. Taking the lock is one atomic
//!   system call: two processes cannot both get it.
//! * **Who.** The file holds the holder's record ([`Holder`]: PID, host, start
//!   time, command line) for the messages: a refused process says who holds
//!   the folder.
//! * **Stale locks.** A record in a file that nobody holds was left by a
//!   holder that ended without releasing it (killed, power cut). It is taken
//!   over, and [`DirLock::stale`] returns the dead holder so that the caller
//!   can say so.
//! * **Releasing** (drop): the file is unlinked, then closed (which drops the
//!   `flock`). A process that opened the file just before the unlink may then
//!   lock the unlinked file; so after locking, the acquirer checks that the
//!   path still names the file it locked, and starts again if not.
//!
//! File systems without locks (some FUSE mounts) give [`LockError::Io`]
//! rather than a lock that does not exclude.

use serde::{Deserialize, Serialize};
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

/// Who holds (or held) a lock: the record in its file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Holder {
    pub pid: u32,
    pub host: String,
    /// When it took the lock (seconds since the Unix epoch).
    pub started: u64,
    /// Its command line.
    pub command: String,
}

impl Holder {
    /// This process, now.
    fn me() -> Self {
        let mut args = std::env::args();
        let program = args
            .next()
            .map(|p| {
                Path::new(&p)
                    .file_name()
                    .map_or(p.clone(), |n| n.to_string_lossy().into_owned())
            })
            .unwrap_or_default();
        let mut command = std::iter::once(program)
            .chain(args)
            .collect::<Vec<_>>()
            .join(" ");
        if command.chars().count() > 300 {
            command = command.chars().take(299).chain(['…']).collect();
        }
        Self {
            pid: std::process::id(),
            host: host_name(),
            started: unix_now(),
            command,
        }
    }

    /// Whether its process still runs: `None` when that cannot be known
    /// (another host, or no `/proc`).
    pub fn alive(&self) -> Option<bool> {
        let proc = Path::new("/proc");
        (self.host == host_name() && proc.is_dir())
            .then(|| proc.join(self.pid.to_string()).exists())
    }
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ago = unix_now().saturating_sub(self.started);
        let ago = match ago {
            0..120 => format!("{ago} s"),
            120..7200 => format!("{} min", ago / 60),
            _ => format!("{} h", ago / 3600),
        };
        write!(
            f,
            "PID {} on host {} (`{}`, started {ago} ago)",
            self.pid, self.host, self.command
        )
    }
}

/// Why a folder could not be locked.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    #[error(
        "{dir} is in use by {}; wait for it to finish or stop it (lock file {path})",
        holder.as_ref().map_or("another process".to_string(), Holder::to_string)
    )]
    Held {
        dir: PathBuf,
        path: PathBuf,
        /// `None` while the holder has not written its record yet.
        holder: Option<Holder>,
    },
    /// The message leads with the folder the user gave; the lock file is a
    /// detail at the end. The I/O error is part of the message, not a
    /// `source`: a chain says it once.
    #[error("{dir} cannot be locked for writing: {error} (while trying to {what} {path})")]
    Io {
        dir: PathBuf,
        path: PathBuf,
        what: &'static str,
        error: std::io::Error,
    },
}

/// An exclusive lock on a folder, held until dropped (see the module docs).
#[derive(Debug)]
pub struct DirLock {
    dir: PathBuf,
    path: PathBuf,
    /// Open for as long as the lock is held; closing it releases the `flock`.
    file: File,
    stale: Option<Holder>,
}

impl DirLock {
    /// Lock folder `dir` (which need not exist; its parent is created), or
    /// fail with [`LockError::Held`] naming the live holder.
    pub fn acquire(dir: &Path) -> Result<Self, LockError> {
        let path = lock_path(dir)?;
        let err = |what, error| LockError::Io {
            dir: dir.to_path_buf(),
            path: path.clone(),
            what,
            error,
        };
        // Each retry means a holder released the file between our open and
        // our lock; a few in a row would take a storm of processes.
        for _ in 0..64 {
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(|e| err("open", e))?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    return Err(LockError::Held {
                        dir: dir.to_path_buf(),
                        path: path.clone(),
                        holder: read_record(&mut file),
                    });
                }
                Err(TryLockError::Error(e)) => return Err(err("lock", e)),
            }
            if !names_file(&path, &file) {
                continue;
            }
            let stale = read_record(&mut file);
            let record = toml::to_string(&Holder::me())
                .map_err(|e| err("write", std::io::Error::other(e)))?;
            file.set_len(0)
                .and_then(|()| file.seek(SeekFrom::Start(0)))
                .and_then(|_| file.write_all(record.as_bytes()))
                .and_then(|()| file.flush())
                .map_err(|e| err("write", e))?;
            return Ok(Self {
                dir: dir.to_path_buf(),
                path,
                file,
                stale,
            });
        }
        Err(err(
            "lock",
            std::io::Error::other("the lock file kept being replaced; try again"),
        ))
    }

    /// The holder whose stale lock was taken over, if any.
    pub fn stale(&self) -> Option<&Holder> {
        self.stale.as_ref()
    }

    /// The folder locked, as given.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        // Unlink before the file closes (and the flock goes): see the module docs.
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.unlock();
    }
}

/// `<canonical parent>/.<name>.lock` for folder `dir`; creates the parent.
pub fn lock_path(dir: &Path) -> Result<PathBuf, LockError> {
    let io = |what, path: &Path, error| LockError::Io {
        dir: dir.to_path_buf(),
        path: path.to_path_buf(),
        what,
        error,
    };
    let full = if dir.exists() {
        dir.canonicalize().map_err(|e| io("resolve", dir, e))?
    } else {
        let name = dir.file_name().ok_or_else(|| {
            io(
                "name",
                dir,
                std::io::Error::other("not a folder name (ends in `..`)"),
            )
        })?;
        let parent = match dir.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        std::fs::create_dir_all(parent).map_err(|e| io("create folder", parent, e))?;
        parent
            .canonicalize()
            .map_err(|e| io("resolve", parent, e))?
            .join(name)
    };
    let name = full.file_name().ok_or_else(|| {
        io(
            "name",
            dir,
            std::io::Error::other("the root folder cannot be locked"),
        )
    })?;
    Ok(full.with_file_name(format!(".{}.lock", name.to_string_lossy())))
}

/// The holder's record in `file`; `None` if it is empty.
fn read_record(file: &mut File) -> Option<Holder> {
    let mut text = String::new();
    file.seek(SeekFrom::Start(0)).ok()?;
    file.take(64 * 1024).read_to_string(&mut text).ok()?;
    if text.trim().is_empty() {
        return None;
    }
    Some(toml::from_str(&text).unwrap_or_else(|_| Holder {
        pid: 0,
        host: "unknown".into(),
        started: 0,
        command: "(an unreadable lock record)".into(),
    }))
}

/// Whether `path` still names the open `file` (same device and inode).
#[cfg(unix)]
fn names_file(path: &Path, file: &File) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(path), file.metadata()) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

/// Windows cannot unlink an open file, so the path always names it.
#[cfg(not(unix))]
fn names_file(path: &Path, _file: &File) -> bool {
    path.exists()
}

fn unix_now() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

/// This machine's name.
pub fn host_name() -> String {
    ["/proc/sys/kernel/hostname", "/etc/hostname"]
        .iter()
        .find_map(|p| std::fs::read_to_string(p).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok())
        .or_else(|| std::env::var("COMPUTERNAME").ok())
        .unwrap_or_else(|| "unknown".into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("deepfoids-lock-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_second_lock_is_refused_while_the_first_lives() {
        let root = temp("second");
        let dir = root.join("run");
        let first = DirLock::acquire(&dir).unwrap();
        assert!(first.stale().is_none());
        assert_eq!(first.path(), root.canonicalize().unwrap().join(".run.lock"));
        assert!(!dir.exists(), "locking does not create the folder");
        let e = DirLock::acquire(&dir).unwrap_err();
        match &e {
            LockError::Held { holder, .. } => {
                let h = holder.as_ref().expect("the record is written");
                assert_eq!(h.pid, std::process::id());
                assert_eq!(h.host, host_name());
                assert_eq!(h.alive(), Some(true));
            }
            other => panic!("{other}"),
        }
        let msg = e.to_string();
        assert!(
            msg.contains("run is in use by PID")
                && msg.contains(&format!("PID {} on host", std::process::id()))
                && msg.contains("wait for it to finish or stop it"),
            "{msg}"
        );
        // The folder can be made, removed and made again under the lock (--force).
        std::fs::create_dir_all(dir.join("a")).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        std::fs::create_dir_all(&dir).unwrap();
        assert!(DirLock::acquire(&dir).is_err());
        drop(first);
        assert!(!first_path(&dir).exists(), "released locks leave no file");
        let again = DirLock::acquire(&dir).unwrap();
        assert!(again.stale().is_none(), "a released lock is not stale");
    }

    fn first_path(dir: &Path) -> PathBuf {
        lock_path(dir).unwrap()
    }

    #[test]
    fn every_spelling_of_a_folder_locks_the_same_file() {
        let root = temp("spelling");
        let dir = root.join("runs").join("x");
        std::fs::create_dir_all(&dir).unwrap();
        let _lock = DirLock::acquire(&dir).unwrap();
        let dotted = root
            .join("runs")
            .join("..")
            .join("runs")
            .join(".")
            .join("x");
        assert!(DirLock::acquire(&dotted).is_err());
        #[cfg(unix)]
        {
            let link = root.join("link");
            std::os::unix::fs::symlink(&dir, &link).unwrap();
            assert!(DirLock::acquire(&link).is_err());
        }
        // Other folders are free.
        assert!(DirLock::acquire(&root.join("runs").join("y")).is_ok());
    }

    #[test]
    fn a_stale_lock_is_taken_over_and_reported() {
        let root = temp("stale");
        let dir = root.join("run");
        let dead = Holder {
            pid: 999_999_999,
            host: host_name(),
            started: unix_now() - 3600,
            command: "deepfoids render --out run".into(),
        };
        std::fs::write(lock_path(&dir).unwrap(), toml::to_string(&dead).unwrap()).unwrap();
        assert_eq!(dead.alive(), Some(false));
        let lock = DirLock::acquire(&dir).unwrap();
        assert_eq!(lock.stale(), Some(&dead));
        assert!(
            dead.to_string().contains("PID 999999999 on host")
                && dead.to_string().contains("started 60 min ago"),
            "{dead}"
        );
        // The record is now ours.
        let record: Holder =
            toml::from_str(&std::fs::read_to_string(lock.path()).unwrap()).unwrap();
        assert_eq!(record.pid, std::process::id());
        // Garbage in a lock file is a stale lock too.
        drop(lock);
        std::fs::write(lock_path(&dir).unwrap(), "not toml [").unwrap();
        let lock = DirLock::acquire(&dir).unwrap();
        assert_eq!(lock.stale().map(|h| h.pid), Some(0));
    }

    /// Threads (each its own open file, as processes are) take and release
    /// one lock thousands of times: never two inside at once, and the
    /// release-while-opening race does not let two in.
    #[test]
    fn only_one_holder_at_a_time_under_contention() {
        let root = temp("race");
        let dir = root.join("run");
        let inside = AtomicUsize::new(0);
        let entries = AtomicUsize::new(0);
        std::thread::scope(|s| {
            for _ in 0..6 {
                s.spawn(|| {
                    for _ in 0..300 {
                        match DirLock::acquire(&dir) {
                            Ok(lock) => {
                                assert_eq!(inside.fetch_add(1, Ordering::SeqCst), 0);
                                entries.fetch_add(1, Ordering::SeqCst);
                                std::thread::yield_now();
                                inside.fetch_sub(1, Ordering::SeqCst);
                                assert!(lock.stale().is_none(), "no lock was abandoned");
                            }
                            Err(LockError::Held { .. }) => std::thread::yield_now(),
                            Err(e) => panic!("{e}"),
                        }
                    }
                });
            }
        });
        assert!(entries.load(Ordering::SeqCst) > 100);
        assert!(!lock_path(&dir).unwrap().exists());
    }

    #[test]
    fn the_root_cannot_be_locked() {
        assert!(matches!(
            DirLock::acquire(Path::new("/")),
            Err(LockError::Io { .. })
        ));
    }

    /// Issue 25: a lock that cannot be taken is reported for the folder the
    /// user gave, not for `.NAME.lock`; the lock file is a detail at the end.
    #[test]
    fn a_failed_lock_names_the_folder_first() {
        let dir = temp("names-folder");
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("file");
        std::fs::write(&file, "x").unwrap();
        let out = file.join("run");
        let e = DirLock::acquire(&out).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("{} cannot be locked for writing: ", out.display())),
            "{e}"
        );
        assert_eq!(e.matches("os error").count(), 1, "the cause once: {e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
