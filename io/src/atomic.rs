//! Files are written atomically: to a temporary file next to the target, then
//! renamed over it, so an interrupted run never leaves a half-written output.

use std::fs::File;
use std::io::{BufWriter, Error, Write};
use std::path::{Path, PathBuf};

fn with_path(e: Error, what: &str, path: &Path) -> Error {
    Error::new(e.kind(), format!("cannot {what} {}: {e}", path.display()))
}

/// A file being written; it appears at its path only on [`AtomicFile::commit`].
pub struct AtomicFile {
    tmp: PathBuf,
    path: PathBuf,
    writer: Option<BufWriter<File>>,
}

impl AtomicFile {
    pub fn create(path: impl AsRef<Path>) -> std::io::Result<Self> {
        let path = path.as_ref().to_path_buf();
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| with_path(e, "create folder", dir))?;
        }
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = path.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
        let file = File::create(&tmp).map_err(|e| with_path(e, "create", &tmp))?;
        Ok(Self {
            tmp,
            path,
            writer: Some(BufWriter::new(file)),
        })
    }

    /// Flush, sync and rename into place. On an error (say, the path is a
    /// folder) the temporary file is removed: nothing is left behind.
    pub fn commit(mut self) -> std::io::Result<()> {
        let writer = self.writer.take().expect("an AtomicFile is committed once");
        let done = writer
            .into_inner()
            .map_err(|e| with_path(e.into_error(), "write", &self.tmp))
            .and_then(|file| file.sync_all().map_err(|e| with_path(e, "sync", &self.tmp)))
            .and_then(|()| {
                std::fs::rename(&self.tmp, &self.path)
                    .map_err(|e| with_path(e, "rename into place", &self.path))
            });
        if done.is_err() {
            let _ = std::fs::remove_file(&self.tmp);
        }
        done
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.writer.as_mut().expect("not committed").write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.writer.as_mut().expect("not committed").flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        // Not committed (an error or a panic): remove the temporary file.
        if self.writer.is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Write `bytes` to `path` atomically.
pub fn write_atomic(path: impl AsRef<Path>, bytes: &[u8]) -> std::io::Result<()> {
    let mut f = AtomicFile::create(path)?;
    f.write_all(bytes)?;
    f.commit()
}

/// Make a folder appear atomically: `fill` writes into a temporary sibling,
/// which is then renamed to `dir` (replacing nothing: `dir` must not exist).
pub fn create_dir_atomic(
    dir: &Path,
    fill: impl FnOnce(&Path) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).map_err(|e| with_path(e, "create folder", &tmp))?;
    match fill(&tmp) {
        Ok(()) => std::fs::rename(&tmp, dir).map_err(|e| with_path(e, "rename into place", dir)),
        Err(e) => {
            let _ = std::fs::remove_dir_all(&tmp);
            Err(e)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uncommitted_files_leave_nothing() {
        let dir = std::env::temp_dir().join(format!("deepfoids-io-{}", std::process::id()));
        let path = dir.join("a.txt");
        {
            let mut f = AtomicFile::create(&path).unwrap();
            f.write_all(b"half").unwrap();
        }
        assert!(!path.exists());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        write_atomic(&path, b"whole").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"whole");
        create_dir_atomic(&dir.join("ck"), |d| std::fs::write(d.join("x"), b"1")).unwrap();
        assert!(dir.join("ck/x").exists());
        assert!(create_dir_atomic(&dir.join("bad"), |_| Err(Error::other("no"))).is_err());
        assert!(!dir.join("bad").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Regression (issue 25): `replay --out` an existing folder left its
    /// `.NAME.PID.tmp` beside it, since a failed rename skipped the cleanup.
    #[test]
    fn a_failed_rename_leaves_no_temporary_file() {
        let dir = std::env::temp_dir().join(format!("deepfoids-io-rename-{}", std::process::id()));
        let target = dir.join("replay.html");
        std::fs::create_dir_all(&target).unwrap();
        let e = write_atomic(&target, b"page").unwrap_err();
        assert!(e.to_string().contains("replay.html"), "{e}");
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, ["replay.html"], "only the folder remains");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
