//! What the process itself uses, for the benchmarks (Linux `/proc`; `None`
//! elsewhere).

/// The process's resident set size (Linux `/proc/self/status`, `VmRSS`).
pub fn resident_set_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// CPU seconds used by the process so far, user + system (Linux
/// `/proc/self/stat`, in clock ticks of 1/100 s): on a shared machine a
/// steadier measure of work than wall-clock time.
pub fn cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = &s[s.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let (utime, stime): (f64, f64) = (f.get(11)?.parse().ok()?, f.get(12)?.parse().ok()?);
    Some((utime + stime) / 100.0)
}
