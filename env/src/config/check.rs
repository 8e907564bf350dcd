//! The bounds helpers of every config kind: a value must be finite and lie
//! within its limit of [`crate::limits`], and the error names the file, the
//! field, the value and the limit in plain numbers.

use super::error::ConfigError;
use super::range::Range;
use crate::limits::*;
use std::path::Path;

/// A number as a person reads it: `1e30` rather than thirty-one digits.
pub fn number<T: Into<f64> + std::fmt::Display + std::fmt::LowerExp + Copy>(v: T) -> String {
    let a = v.into().abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e7).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// `value` must be finite and lie in `[lo, hi]` (in `unit`, which may be empty).
pub fn check(
    path: &Path,
    field: &str,
    value: f32,
    [lo, hi]: [f32; 2],
    unit: &str,
) -> Result<(), ConfigError> {
    if !value.is_finite() {
        return Err(ConfigError::invalid(
            path,
            field,
            format!("must be a finite number, got {value}"),
        ));
    }
    let limit = |b: f32| {
        format!(
            "{}{}{unit}",
            number(b),
            if unit.is_empty() { "" } else { " " }
        )
    };
    if value > hi || value < lo {
        return Err(ConfigError::Limit {
            path: path.to_path_buf(),
            field: field.to_string(),
            value: number(value),
            above: value > hi,
            limit: limit(if value > hi { hi } else { lo }),
        });
    }
    Ok(())
}

/// `value` of `field` must be positive and finite.
pub fn positive_in(path: &Path, field: &str, value: f32) -> Result<(), ConfigError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(ConfigError::invalid(
            path,
            field,
            format!("must be a positive number, got {value}"),
        ))
    }
}

/// A count must be at most `hi` (in `unit`).
pub fn check_count(
    path: &Path,
    field: &str,
    value: u64,
    hi: u64,
    unit: &str,
) -> Result<(), ConfigError> {
    if value > hi {
        return Err(ConfigError::Limit {
            path: path.to_path_buf(),
            field: field.to_string(),
            value: value.to_string(),
            above: true,
            limit: format!("{hi} {unit}"),
        });
    }
    Ok(())
}

pub(super) fn range(
    path: &Path,
    field: &str,
    r: &Range,
    bounds: [f32; 2],
    unit: &str,
) -> Result<(), ConfigError> {
    let (a, b) = r.bounds();
    check(path, field, a, bounds, unit)?;
    check(path, field, b, bounds, unit)
}

pub(super) fn pair(
    path: &Path,
    field: &str,
    v: [f32; 2],
    bounds: [f32; 2],
    unit: &str,
) -> Result<(), ConfigError> {
    for (i, x) in v.iter().enumerate() {
        check(path, &format!("{field}[{i}]"), *x, bounds, unit)?;
    }
    Ok(())
}

pub(super) const BL: [f32; 2] = [0.0, MAX_RANGE_BL];
pub(super) const SPEED: [f32; 2] = [0.0, MAX_SPEED_BL];
pub(super) const WEIGHT: [f32; 2] = [0.0, MAX_WEIGHT];
pub(super) const SHARE: [f32; 2] = [0.0, 1.0];
pub(super) const LIGHT: [f32; 2] = [-(MAX_LIGHT_PAR), MAX_LIGHT_PAR];
pub(super) const TEMPERATURE: [f32; 2] = [TEMPERATURE_C[0], TEMPERATURE_C[1]];

/// Kinds of baseline parameter, for their bounds.
pub(crate) enum Param {
    /// A distance in body lengths.
    Bl(f32),
    /// A speed in BL/s.
    Speed(f32),
    /// A weight or multiplier.
    Weight(f32),
    /// A probability or share.
    Share(f32),
    /// An angle in degrees.
    Degrees(f32),
}

/// The bounds of a baseline's parameter file.
pub(crate) fn params(path: &Path, fields: &[(&str, Param)]) -> Result<(), ConfigError> {
    for (field, p) in fields {
        match *p {
            Param::Bl(v) => check(path, field, v, BL, "BL")?,
            Param::Speed(v) => check(path, field, v, SPEED, "BL/s")?,
            Param::Weight(v) => check(path, field, v, WEIGHT, "")?,
            Param::Share(v) => check(path, field, v, SHARE, "")?,
            Param::Degrees(v) => check(path, field, v, [0.0, 90.0], "°")?,
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_read_as_people_write_them() {
        assert_eq!(number(1e30), "1e30");
        assert_eq!(number(100000000.0), "1e8");
        assert_eq!(number(200000.0), "200000");
        assert_eq!(number(0.02), "0.02");
        assert_eq!(number(-3.5), "-3.5");
        assert_eq!(number(0.0), "0");
    }

    #[test]
    fn a_value_above_its_bound_names_file_field_value_and_bound() {
        let p = Path::new("configs/scenes/x.toml");
        let e = check(p, "cage.edge", 1e30, [0.0, 1000.0], "m").unwrap_err();
        assert_eq!(
            e.to_string(),
            "configs/scenes/x.toml: cage.edge = 1e30 is above the limit of 1000 m"
        );
        let e = check(p, "w", -1.0, [0.0, 10.0], "").unwrap_err();
        assert_eq!(
            e.to_string(),
            "configs/scenes/x.toml: w = -1 is below the limit of 0"
        );
        let e = check(p, "w", f32::NAN, [0.0, 10.0], "").unwrap_err();
        assert!(e.to_string().contains("finite"), "{e}");
        assert!(check(p, "w", 10.0, [0.0, 10.0], "").is_ok());
        let e = check_count(p, "group[0].count", 100_000_000, 200_000, "fish").unwrap_err();
        assert_eq!(
            e.to_string(),
            "configs/scenes/x.toml: group[0].count = 100000000 is above the limit of 200000 fish"
        );
    }
}
