//! What several test suites share and no library should carry: an allocator
//! that counts, a test's temporary folder, and a folder copy. A
//! dev-dependency only.
//!
//! A test binary installs the allocator once:
//!
//! ```ignore
//! #[global_allocator]
//! static GLOBAL: deepfoids_testkit::Counting = deepfoids_testkit::Counting;
//! ```

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The system allocator, counting allocations, and bytes in use (now and at
/// the peak) both for the whole process and per thread.
pub struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static THREAD_LIVE: Cell<i64> = const { Cell::new(0) };
    static THREAD_PEAK: Cell<i64> = const { Cell::new(0) };
}

fn grew(bytes: usize) {
    let live = LIVE.fetch_add(bytes, Ordering::SeqCst) + bytes;
    PEAK.fetch_max(live, Ordering::SeqCst);
    thread_grew(bytes as i64);
}

fn shrank(bytes: usize) {
    LIVE.fetch_sub(bytes, Ordering::SeqCst);
    thread_grew(-(bytes as i64));
}

fn thread_grew(bytes: i64) {
    // `try_with`: the thread's counters may already be gone while it exits.
    let _ = THREAD_LIVE.try_with(|l| {
        l.set(l.get() + bytes);
        let _ = THREAD_PEAK.try_with(|p| p.set(p.get().max(l.get())));
    });
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        grew(layout.size());
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        shrank(layout.size());
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        if new_size >= layout.size() {
            grew(new_size - layout.size());
        } else {
            shrank(layout.size() - new_size);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocations (and reallocations) so far, in the whole process.
pub fn allocations() -> usize {
    ALLOCATIONS.load(Ordering::SeqCst)
}

/// Most bytes in use at once in the process while `f` runs, above what was
/// in use before (other threads' allocations count too).
pub fn peak_during<T>(f: impl FnOnce() -> T) -> (T, u64) {
    let before = LIVE.load(Ordering::SeqCst);
    PEAK.store(before, Ordering::SeqCst);
    let out = f();
    (
        out,
        PEAK.load(Ordering::SeqCst).saturating_sub(before) as u64,
    )
}

/// Most bytes in use at once on this thread while `f` runs, above the start
/// (what other threads allocate does not count).
pub fn thread_peak_during<T>(f: impl FnOnce() -> T) -> (T, i64) {
    let start = THREAD_LIVE.with(Cell::get);
    THREAD_PEAK.with(|p| p.set(start));
    let out = f();
    (out, THREAD_PEAK.with(Cell::get) - start)
}

/// Copy folder `from` into `to`, sub-folders included.
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let dest = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_dir(&p, &dest);
        } else {
            std::fs::copy(&p, dest).unwrap();
        }
    }
}

/// `deepfoids-<suite>-<name>-<pid>` in the temporary folder, removed if an
/// earlier run left it (not created), and removed again when the returned
/// guard drops — unless the test is failing, so its files can be read.
pub fn temp_path(suite: &str, name: &str) -> TempDir {
    let d = std::env::temp_dir().join(format!("deepfoids-{suite}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    TempDir(d)
}

/// A test's folder in the temporary folder ([`temp_path`]); a `Path` to use.
#[derive(Debug)]
pub struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}
