//! [`Range`]: a value fixed or drawn per fish, as species and scene files write it.

use super::error::ConfigError;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;

/// A value that is either fixed or drawn uniformly per fish.
///
/// In TOML a plain number (`0.5`) or a two-element array (`[0.9, 1.1]`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Range {
    Fixed(f32),
    Uniform([f32; 2]),
}

impl Range {
    /// Lower and upper bound.
    pub fn bounds(&self) -> (f32, f32) {
        match *self {
            Range::Fixed(v) => (v, v),
            Range::Uniform([a, b]) => (a, b),
        }
    }

    /// The value at `u ∈ [0, 1)` of the way from the lower to the upper bound.
    pub fn at(&self, u: f32) -> f32 {
        let (a, b) = self.bounds();
        a + (b - a) * u
    }

    /// The midpoint of the range.
    pub fn midpoint(&self) -> f32 {
        self.at(0.5)
    }

    /// Finite, ordered low to high, and at least `min` (`None`: any finite numbers).
    pub(super) fn check(
        &self,
        path: &Path,
        field: &str,
        min: Option<f32>,
    ) -> Result<(), ConfigError> {
        let (a, b) = self.bounds();
        let low = min.is_some_and(|m| a < m);
        if !(a.is_finite() && b.is_finite()) || a > b || low {
            let allowed = match min {
                Some(m) => format!("finite, ordered low to high and at least {m}"),
                None => "two finite numbers, ordered low to high".to_string(),
            };
            return Err(ConfigError::invalid(
                path,
                field,
                format!("range {self} must be {allowed}"),
            ));
        }
        Ok(())
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Range::Fixed(v) => write!(f, "{v}"),
            Range::Uniform([a, b]) => write!(f, "[{a}, {b}]"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_parses_number_or_pair() {
        #[derive(Deserialize)]
        struct T {
            a: Range,
            b: Range,
        }
        let t: T = toml::from_str("a = 0.5\nb = [0.9, 1.1]").unwrap();
        assert_eq!(t.a, Range::Fixed(0.5));
        assert_eq!(t.b, Range::Uniform([0.9, 1.1]));
        assert!((t.b.midpoint() - 1.0).abs() < 1e-6);
    }
}
