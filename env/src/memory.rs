//! How much memory a job will need, and whether this machine has it — asked
//! *before* anything large is allocated, so that a scene too large for the
//! machine fails with one line instead of the kernel's OOM killer.
//!
//! * [`env_bytes`] estimates what [`crate::Env::new`] allocates for a scene
//!   (an upper bound; `env/tests/memory.rs` measures it against the allocator).
//!   Nearly all of it is the observation buffer: every fish's stacked grid,
//!   `18 × 20 × 34` floats = 48,960 bytes.
//! * [`available`] says how much the machine can give: `MemAvailable` of
//!   `/proc/meminfo` on Linux, lowered to the room left under a cgroup
//!   memory limit (containers); elsewhere `sysctl hw.memsize` (physical
//!   memory) where it exists; else unknown. `DEEPFOIDS_MEMORY_AVAILABLE`
//!   (bytes, or with a `K`, `M`, `G`, `T` suffix for powers of 1024)
//!   replaces the measured figure.
//! * [`check`] refuses a request above [`MAX_SHARE`] of that (trainers call it
//!   for their buffers too); [`check_env`] does it for one environment. When
//!   the available memory is unknown, nothing is refused: the bounds of
//!   [`crate::limits`] still hold.

use crate::scene::Scene;
use deepfoids_sensors::STACKED_LEN;
use std::path::Path;

/// The environment variable that replaces the measured available memory.
pub const OVERRIDE_VAR: &str = "DEEPFOIDS_MEMORY_AVAILABLE";

/// Share of the available memory one request may take: the rest is left to
/// the operating system, the page cache and whatever else runs.
pub const MAX_SHARE: f64 = 0.8;

/// Bytes per fish of [`crate::Env`] besides its observation stack, rounded up
/// from the sizes of its per-fish arrays: the batch's vector, reward, terms and
/// flags (60), the copied fish state (35), the world (65), motor, episode
/// accumulator, collider axes and extents, decision results and scratch (260),
/// both spatial grids' entries (48) and what sensing gathers of each
/// neighbour (20); 488 in all, but measured ≈ 590
/// with the growth of per-fish vectors at 30,000 fish (`field_dense`).
pub const FISH_STATE_BYTES: u64 = 640;

/// Bytes of one fish's stacked grid observation.
pub const OBSERVATION_BYTES: u64 = (STACKED_LEN * std::mem::size_of::<f32>()) as u64;

/// Fixed costs of an environment: the sensor's tables, per-thread frames,
/// behaviour records (a generous 1 MiB).
const FIXED_BYTES: u64 = 1 << 20;

/// Grid cells per axis at most (as `deepfoids_sensors::SpatialGrid` clamps them).
const MAX_CELLS_PER_AXIS: f32 = 256.0;

/// An upper bound of the bytes [`crate::Env::new`] allocates for `scene`.
pub fn env_bytes(scene: &Scene) -> u64 {
    let n = scene.fish_count() as u64;
    // The cells of the two neighbour grids: the smallest possible cell gives
    // the most cells, so take each behaviour's smallest body.
    let (lo, hi) = scene.cage().bounds;
    let min_bl = |b: &crate::scene::BehaviourSpec| {
        b.species.body_length
            * b.body_scales
                .iter()
                .map(|(_, r)| r.bounds().0)
                .fold(f32::INFINITY, f32::min)
    };
    let sense = scene
        .behaviours
        .iter()
        .map(|b| b.species.sense_range_bl * min_bl(b))
        .fold(0.1, f32::max);
    let contact = scene
        .behaviours
        .iter()
        .map(|b| glam::Vec3::from(b.species.collider_bl).length() * min_bl(b))
        .fold(0.05, f32::max);
    let cells = |cell: f32| -> u64 {
        let extent = (hi - lo).max(glam::Vec3::splat(cell));
        let axis = |e: f32| (e / cell).ceil().clamp(1.0, MAX_CELLS_PER_AXIS) as u64;
        axis(extent.x) * axis(extent.y) * axis(extent.z) + 1
    };
    let grid_bytes = 4 * (cells(sense / 2.0) + cells(contact));
    n * (OBSERVATION_BYTES + FISH_STATE_BYTES) + grid_bytes + FIXED_BYTES
}

/// The most [`env_bytes`] can be for a scene within [`crate::limits`]:
/// [`crate::limits::MAX_FISH`] fish and two grids of 256³ cells (≈ 10 GB).
pub fn max_env_bytes() -> u64 {
    let cells = (MAX_CELLS_PER_AXIS as u64).pow(3) + 1;
    crate::limits::MAX_FISH as u64 * (OBSERVATION_BYTES + FISH_STATE_BYTES)
        + 2 * 4 * cells
        + FIXED_BYTES
}

/// What the machine can give, and where the figure comes from.
#[derive(Clone, Debug, PartialEq)]
pub struct Available {
    pub bytes: u64,
    /// E.g. `MemAvailable in /proc/meminfo`.
    pub source: String,
}

/// Everything that can go wrong in a memory check.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MemoryError {
    #[error(
        "{what} needs about {}, but this machine has {} available ({}) and one job may take at most {:.0} % of it: {hint}",
        human(*need), human(available.bytes), available.source, MAX_SHARE * 100.0
    )]
    TooLarge {
        what: String,
        need: u64,
        available: Available,
        hint: String,
    },
    #[error(
        "{OVERRIDE_VAR} = `{0}` is not a byte count (allowed: digits with an optional K, M, G or T suffix)"
    )]
    BadOverride(String),
}

/// Bytes for people: `48.96 kB`, `9.9 GB` (powers of 1000, as `ls -h --si`).
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    match bytes {
        0..1_000 => format!("{bytes} B"),
        1_000..1_000_000 => format!("{:.1} kB", b / 1e3),
        1_000_000..1_000_000_000 => format!("{:.1} MB", b / 1e6),
        _ => format!("{:.1} GB", b / 1e9),
    }
}

/// How much memory this process can have, if known.
pub fn available() -> Result<Option<Available>, MemoryError> {
    if let Ok(text) = std::env::var(OVERRIDE_VAR) {
        let bytes = parse_bytes(&text).ok_or(MemoryError::BadOverride(text))?;
        return Ok(Some(Available {
            bytes,
            source: format!("set by {OVERRIDE_VAR}"),
        }));
    }
    let read = |p: &str| std::fs::read_to_string(p).ok();
    if let Some(bytes) = read("/proc/meminfo").as_deref().and_then(mem_available) {
        let meminfo = Available {
            bytes,
            source: "MemAvailable in /proc/meminfo".into(),
        };
        return Ok(Some(match cgroup_room(read) {
            Some(room) if room.bytes < meminfo.bytes => room,
            _ => meminfo,
        }));
    }
    Ok(physical_memory())
}

/// Refuse `need` bytes for `what` if they are more than [`MAX_SHARE`] of the
/// available memory; `hint` says how to need less. Returns what was available.
pub fn check(what: &str, need: u64, hint: &str) -> Result<Option<Available>, MemoryError> {
    let available = available()?;
    if let Some(a) = &available
        && need as f64 > MAX_SHARE * a.bytes as f64
    {
        return Err(MemoryError::TooLarge {
            what: what.to_string(),
            need,
            available: a.clone(),
            hint: hint.to_string(),
        });
    }
    Ok(available)
}

/// [`check`] the memory an environment of `scene` needs ([`env_bytes`]); call
/// it before [`crate::Env::new`]. Returns the need in bytes.
pub fn check_env(scene: &Scene) -> Result<u64, MemoryError> {
    let need = env_bytes(scene);
    check(
        &format!(
            "the environment of scene {} ({} fish)",
            scene.id,
            scene.fish_count()
        ),
        need,
        &format!(
            "use fewer fish (each needs {}, mostly for its observations), or free memory",
            human(OBSERVATION_BYTES + FISH_STATE_BYTES)
        ),
    )?;
    Ok(need)
}

/// `4096`, `512M`, `16G` (powers of 1024).
fn parse_bytes(text: &str) -> Option<u64> {
    let t = text.trim();
    let (digits, shift) = match t.char_indices().last()? {
        (i, 'K' | 'k') => (&t[..i], 10),
        (i, 'M' | 'm') => (&t[..i], 20),
        (i, 'G' | 'g') => (&t[..i], 30),
        (i, 'T' | 't') => (&t[..i], 40),
        _ => (t, 0),
    };
    digits.trim().parse::<u64>().ok()?.checked_mul(1 << shift)
}

/// `MemAvailable` of `/proc/meminfo` text, in bytes.
fn mem_available(meminfo: &str) -> Option<u64> {
    meminfo.lines().find_map(|l| {
        let kb = l.strip_prefix("MemAvailable:")?.trim().strip_suffix("kB")?;
        kb.trim().parse::<u64>().ok()?.checked_mul(1024)
    })
}

/// The room left under this process' cgroup memory limit (v2 `memory.max`, or
/// v1 `memory.limit_in_bytes`): the limit less the usage that cannot be
/// reclaimed (usage less inactive page cache). `None` without a limit.
fn cgroup_room(read: impl Fn(&str) -> Option<String>) -> Option<Available> {
    let own = read("/proc/self/cgroup").unwrap_or_default();
    let path_of = |prefix: &str| {
        own.lines()
            .find_map(|l| l.strip_prefix(prefix).map(str::to_string))
    };
    let v2 = path_of("0::").unwrap_or_default();
    let v1 = own
        .lines()
        .find_map(|l| {
            let (_, rest) = l.split_once(':')?;
            rest.strip_prefix("memory:").map(str::to_string)
        })
        .unwrap_or_default();
    let mut tries = Vec::new();
    for dir in [format!("/sys/fs/cgroup{v2}"), "/sys/fs/cgroup".into()] {
        tries.push((dir, "memory.max", "memory.current", "inactive_file "));
    }
    for dir in [
        format!("/sys/fs/cgroup/memory{v1}"),
        "/sys/fs/cgroup/memory".into(),
    ] {
        tries.push((
            dir,
            "memory.limit_in_bytes",
            "memory.usage_in_bytes",
            "total_inactive_file ",
        ));
    }
    tries.into_iter().find_map(|(dir, limit, usage, inactive)| {
        let file = |name: &str| read(&Path::new(&dir).join(name).to_string_lossy());
        let room = room_under_limit(
            &file(limit)?,
            &file(usage)?,
            &file("memory.stat").unwrap_or_default(),
            inactive,
        )?;
        Some(Available {
            bytes: room,
            source: format!("the cgroup limit in {dir}/{limit}, less its usage"),
        })
    })
}

/// `limit − (usage − inactive page cache)`; `None` if there is no limit
/// (`max`, or v1's 2⁶³-ish "unlimited").
fn room_under_limit(limit: &str, usage: &str, stat: &str, inactive_key: &str) -> Option<u64> {
    let limit: u64 = limit.trim().parse().ok()?;
    if limit >= 1 << 60 {
        return None;
    }
    let usage: u64 = usage.trim().parse().ok()?;
    let inactive: u64 = stat
        .lines()
        .find_map(|l| l.strip_prefix(inactive_key)?.trim().parse().ok())
        .unwrap_or(0);
    Some(limit.saturating_sub(usage.saturating_sub(inactive)))
}

/// Physical memory where there is no `/proc/meminfo` (macOS, the BSDs).
fn physical_memory() -> Option<Available> {
    for key in ["hw.memsize", "hw.physmem64", "hw.physmem"] {
        let out = std::process::Command::new("sysctl")
            .args(["-n", key])
            .output()
            .ok()?;
        if let Ok(bytes) = String::from_utf8_lossy(&out.stdout).trim().parse::<u64>()
            && out.status.success()
        {
            return Some(Available {
                bytes,
                source: format!("physical memory, sysctl {key}"),
            });
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meminfo_and_cgroup_figures_are_read() {
        let meminfo = "MemTotal:       24684084 kB\nMemFree:         3008348 kB\nMemAvailable:   17435416 kB\n";
        assert_eq!(mem_available(meminfo), Some(17_435_416 * 1024));
        assert_eq!(mem_available("MemTotal: 1 kB\n"), None);
        // v2: 4 GiB limit, 3 GiB used of which 1 GiB inactive cache → 2 GiB room.
        let stat = "anon 100\ninactive_file 1073741824\nactive_file 5\n";
        assert_eq!(
            room_under_limit("4294967296\n", "3221225472\n", stat, "inactive_file "),
            Some(2 << 30)
        );
        assert_eq!(room_under_limit("max\n", "1", stat, "inactive_file "), None);
        assert_eq!(
            room_under_limit("9223372036854771712", "1", "", "total_inactive_file "),
            None
        );
        // Over the limit: no room, not an underflow.
        assert_eq!(
            room_under_limit("100", "300", "", "inactive_file "),
            Some(0)
        );
    }

    #[test]
    fn a_cgroup_limit_below_meminfo_is_found() {
        let files = |p: &str| -> Option<String> {
            match p {
                "/proc/self/cgroup" => Some("0::/job\n".into()),
                "/sys/fs/cgroup/job/memory.max" => Some("1073741824\n".into()),
                "/sys/fs/cgroup/job/memory.current" => Some("536870912\n".into()),
                "/sys/fs/cgroup/job/memory.stat" => Some("inactive_file 0\n".into()),
                _ => None,
            }
        };
        let room = cgroup_room(files).unwrap();
        assert_eq!(room.bytes, 512 << 20);
        assert!(
            room.source.contains("/sys/fs/cgroup/job/memory.max"),
            "{}",
            room.source
        );
        assert_eq!(cgroup_room(|_| None), None);
    }

    #[test]
    fn byte_counts_parse_with_binary_suffixes() {
        assert_eq!(parse_bytes("4096"), Some(4096));
        assert_eq!(parse_bytes("512M"), Some(512 << 20));
        assert_eq!(parse_bytes(" 16g "), Some(16 << 30));
        assert_eq!(parse_bytes("1T"), Some(1 << 40));
        assert_eq!(parse_bytes("lots"), None);
        assert_eq!(parse_bytes(""), None);
        assert_eq!(parse_bytes("99999999999999999999G"), None);
    }

    #[test]
    fn sizes_read_as_people_write_them() {
        assert_eq!(human(999), "999 B");
        assert_eq!(human(48_960), "49.0 kB");
        assert_eq!(human(9_892_000_000), "9.9 GB");
    }
}
