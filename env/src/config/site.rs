//! Site files, `sites/<name>.toml`: [`SiteConfig`].

use super::check::check;
use super::error::ConfigError;
use crate::limits::{MAX_ATTENUATION, MAX_LIGHT_PAR, SURFACE_TEMPERATURE_C};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A fish-farm site (SPEC §2). File: `sites/<name>.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteConfig {
    /// Short id, e.g. `onmaehama`.
    pub name: String,
    /// Human-readable name.
    pub display_name: String,
    /// Latitude (degrees, north positive).
    pub latitude_deg: f32,
    /// Longitude (degrees, east positive).
    pub longitude_deg: f32,
    /// Offset of local clock time from UTC (hours); Japan: 9.
    pub utc_offset_hours: f32,
    /// Light at the surface at solar noon, `I0` maximum (PAR). Onmaehama 519.69, Nishiki 15.13.
    pub surface_light_max: f32,
    /// Light attenuation coefficient `a` of Eq. 4.1 (1/m). Onmaehama 1.5, Nishiki 0.26.
    pub attenuation: f32,
    /// Water temperature at the surface `T_surf` (°C).
    pub surface_temperature: f32,
    /// Where each value comes from.
    #[serde(default)]
    pub notes: String,
}

impl SiteConfig {
    pub(super) fn validate(&self, path: &Path) -> Result<(), ConfigError> {
        if !(-90.0..=90.0).contains(&self.latitude_deg) {
            return Err(ConfigError::invalid(
                path,
                "latitude_deg",
                "must lie in [-90, 90]",
            ));
        }
        if !(-180.0..=180.0).contains(&self.longitude_deg) {
            return Err(ConfigError::invalid(
                path,
                "longitude_deg",
                "must lie in [-180, 180]",
            ));
        }
        if !(-14.0..=14.0).contains(&self.utc_offset_hours) {
            return Err(ConfigError::invalid(
                path,
                "utc_offset_hours",
                "must lie in [-14, 14]",
            ));
        }
        if self.surface_light_max.is_nan() || self.surface_light_max < 0.0 {
            return Err(ConfigError::invalid(
                path,
                "surface_light_max",
                "must be ≥ 0",
            ));
        }
        if self.attenuation.is_nan() || self.attenuation < 0.0 {
            return Err(ConfigError::invalid(path, "attenuation", "must be ≥ 0"));
        }
        bounds(self, path)
    }
}

/// The bounds of a site file (after a scene's overrides).
fn bounds(s: &SiteConfig, path: &Path) -> Result<(), ConfigError> {
    check(
        path,
        "surface_light_max",
        s.surface_light_max,
        [0.0, MAX_LIGHT_PAR],
        "PAR",
    )?;
    check(
        path,
        "attenuation",
        s.attenuation,
        [0.0, MAX_ATTENUATION],
        "1/m",
    )?;
    check(
        path,
        "surface_temperature",
        s.surface_temperature,
        [SURFACE_TEMPERATURE_C[0], SURFACE_TEMPERATURE_C[1]],
        "°C",
    )
}
