//! Bounds of command-line values (`deepfoids_env::limits` gives them and says
//! why): a typo in `--seconds` or `--width` is refused with the bound in the
//! message instead of running for a week or exhausting memory.

use anyhow::{Result, bail};
use deepfoids_env::config::number;
use std::path::Path;

/// `value` of option `flag` must be positive, finite and at most `max` (in `unit`).
pub fn positive_at_most(flag: &str, value: f64, max: f64, unit: &str) -> Result<()> {
    if !(value > 0.0 && value.is_finite()) {
        bail!(
            "{flag} must be above 0 and at most {} {unit}, got {value}",
            number(max)
        );
    }
    at_most(flag, value, max, unit)
}

/// `value` of option `flag` must be at most `max` (in `unit`).
pub fn at_most(flag: &str, value: f64, max: f64, unit: &str) -> Result<()> {
    if value > max {
        bail!(
            "{flag} {} is above the limit of {} {unit}",
            number(value),
            number(max)
        );
    }
    Ok(())
}

/// `value` of option `flag` must lie in `[min, max]` (in `unit`).
pub fn count_within(flag: &str, value: u64, [min, max]: [u64; 2], unit: &str) -> Result<()> {
    if value < min {
        bail!("{flag} {value} is below the minimum of {min}");
    }
    if value > max {
        bail!("{flag} {value} is above the limit of {max} {unit}");
    }
    Ok(())
}

/// A simulated duration of one command: `(0, MAX_SECONDS]`.
pub fn seconds(flag: &str, value: f64) -> Result<()> {
    positive_at_most(
        flag,
        value,
        deepfoids_env::limits::MAX_SECONDS,
        "s (one simulated day)",
    )
}

/// Simulated seconds run before recording: `[0, MAX_SECONDS]`.
pub fn warmup(flag: &str, value: f64) -> Result<()> {
    if !(value >= 0.0 && value.is_finite()) {
        bail!(
            "{flag} must be ≥ 0 and at most {} s, got {value}",
            number(deepfoids_env::limits::MAX_SECONDS)
        );
    }
    at_most(
        flag,
        value,
        deepfoids_env::limits::MAX_SECONDS,
        "s (one simulated day)",
    )
}

/// A training budget (agent decisions per behaviour): at least one; `0`
/// would write an untrained policy as if it were trained.
pub fn train_steps(flag: &str, value: u64) -> Result<()> {
    if value == 0 {
        bail!(
            "{flag} 0 would train nothing; give at least 1 agent decision per behaviour (or leave {flag} out for the thesis' budget)"
        );
    }
    Ok(())
}

/// Output file `path` of option `flag` can be written: it is not a folder,
/// and the first of its parents that exists is a folder. Checked before a
/// command simulates, so that a wrong path costs nothing.
pub fn out_file(flag: &str, path: &Path) -> Result<()> {
    if path.is_dir() {
        bail!(
            "{flag} {} is a folder; give the path of a file to write",
            path.display()
        );
    }
    parent_is_folder(flag, path)
}

/// Output folder `path` of option `flag` is a folder or can be made one.
pub fn out_dir(flag: &str, path: &Path) -> Result<()> {
    if path.exists() && !path.is_dir() {
        bail!(
            "{flag} {} is a file; give a folder (it is created if missing)",
            path.display()
        );
    }
    parent_is_folder(flag, path)
}

fn parent_is_folder(flag: &str, path: &Path) -> Result<()> {
    if let Some(up) = path.ancestors().skip(1).find(|p| p.exists())
        && !up.is_dir()
    {
        bail!(
            "{flag} {}: {} is a file, not a folder",
            path.display(),
            up.display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_option_value_and_bound() {
        let e = seconds("--seconds", 1e9).unwrap_err().to_string();
        assert_eq!(
            e,
            "--seconds 1e9 is above the limit of 86400 s (one simulated day)"
        );
        let e = warmup("--warmup", -1.0).unwrap_err().to_string();
        assert_eq!(e, "--warmup must be ≥ 0 and at most 86400 s, got -1");
        assert!(warmup("--warmup", 0.0).is_ok());
        let e = warmup("--warmup", 1e6).unwrap_err().to_string();
        assert_eq!(
            e,
            "--warmup 1000000 is above the limit of 86400 s (one simulated day)"
        );
        let e = seconds("--seconds", f64::NAN).unwrap_err().to_string();
        assert_eq!(
            e,
            "--seconds must be above 0 and at most 86400 s (one simulated day), got NaN"
        );
        let e = seconds("--seconds", -1.0).unwrap_err().to_string();
        assert_eq!(
            e,
            "--seconds must be above 0 and at most 86400 s (one simulated day), got -1"
        );
        assert!(seconds("--seconds", 86_400.0).is_ok());
        let e = count_within("--seeds", 0, [1, 1000], "seeds")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "--seeds 0 is below the minimum of 1");
        let e = count_within("--width", 100_000, [16, 8192], "px")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "--width 100000 is above the limit of 8192 px");
    }
}
