//! Species files, `species/<name>.toml`: [`SpeciesConfig`] and its [`SizeClass`]es.

use super::check::{
    BL, LIGHT, SHARE, SPEED, TEMPERATURE, check, check_count, pair, positive_in, range,
};
use super::error::ConfigError;
use super::range::Range;
use crate::limits::{MAX_BODY_LENGTH_M, MAX_BODY_SCALE, MAX_DECISION_INTERVAL_S, MAX_SIZE_CLASSES};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// A size class of a species: its body scale and light preferences
/// (SPEC §2, Table 4.3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SizeClass {
    /// Body scale drawn per fish (× the species' body length). Default scenes: U[0.9, 1.1].
    pub body_scale: Range,
    /// Lower bound of the preferred light intensity `I_lpref` (PAR), drawn per fish.
    pub light_lpref: Range,
    /// Upper bound of the preferred light intensity `I_hpref` (PAR), drawn per fish;
    /// reset to the midpoint of this range if the draw falls below `I_lpref` (Foids rule).
    pub light_hpref: Range,
}

/// One species (SPEC §2, Tables 4.1 and 4.3). File: `species/<name>.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeciesConfig {
    /// Short id used by scenes and in behaviour names, e.g. `coho`.
    pub name: String,
    /// Human-readable name, e.g. `coho salmon`.
    pub display_name: String,
    /// Body length at body scale 1.0 (m). Table 4.3: 0.49 / 0.52 / 0.34.
    pub body_length: f32,
    /// Schooling speed range `[min, max]` (BL/s); the maximum is the speed clamp (SPEC §4).
    pub speed_bl: [f32; 2],
    /// Sensing range `d_sense` (BL). Table 4.1: 3 (coho, seabream), 2 (yellowtail).
    pub sense_range_bl: f32,
    /// Decision interval `dt_res` (s). SPEC §2: 0.2 coho, 0.1 the others.
    pub decision_interval: f32,
    /// Preferred temperature `[T_lpref, T_hpref]` (°C). Table 4.3.
    pub temperature_pref: [f32; 2],
    /// Box collider `[width, height, length]` (BL), centred on the body.
    /// Default `[0.12, 0.25, 1.0]`: a salmon-like body ~25 % deep and ~12 % wide.
    #[serde(default = "default_collider")]
    pub collider_bl: [f32; 3],
    /// Radius of the sphere a fish of this species appears as to the grid sensor (BL).
    /// Seen side-on a fish spans ±0.5 BL, head-on ±0.06 BL; default 0.25 BL.
    #[serde(default = "default_visual_radius")]
    pub visual_radius_bl: f32,
    /// Initial (and respawn) speed `v0` (BL/s). SPEC §2: 0.2.
    #[serde(default = "default_v0")]
    pub initial_speed_bl: f32,
    /// Maximum delta speed `Δv_max` of one decision (BL/s). SPEC §2: 4.1.
    #[serde(default = "default_dv_max")]
    pub max_delta_speed_bl: f32,
    /// Light steepness `[I_lsteep, I_hsteep]` (PAR). SPEC §2: [−20, 1000].
    #[serde(default = "default_light_steep")]
    pub light_steep: [f32; 2],
    /// Temperature steepness `[T_lsteep, T_hsteep]` (°C). SPEC §2: [−60, 80].
    #[serde(default = "default_temperature_steep")]
    pub temperature_steep: [f32; 2],
    /// Share of dominant fish, per behaviour (0–1). SPEC §2: 0.2.
    #[serde(default = "default_dominant_fraction")]
    pub dominant_fraction: f32,
    /// Body colour for rendering, linear RGB in [0, 1].
    #[serde(default = "default_colour")]
    pub colour: [f32; 3],
    /// Size classes by name (`regular`, `small`, `large`, …).
    pub size_classes: BTreeMap<String, SizeClass>,
}

fn default_collider() -> [f32; 3] {
    [0.12, 0.25, 1.0]
}
fn default_visual_radius() -> f32 {
    0.25
}
fn default_v0() -> f32 {
    0.2
}
fn default_dv_max() -> f32 {
    4.1
}
fn default_light_steep() -> [f32; 2] {
    [-20.0, 1000.0]
}
fn default_temperature_steep() -> [f32; 2] {
    [-60.0, 80.0]
}
fn default_dominant_fraction() -> f32 {
    0.2
}
fn default_colour() -> [f32; 3] {
    [0.55, 0.58, 0.62]
}

impl SpeciesConfig {
    pub(super) fn validate(&self, path: &Path) -> Result<(), ConfigError> {
        let positive = |v: f32, field: &str| positive_in(path, field, v);
        positive(self.body_length, "body_length")?;
        positive(self.sense_range_bl, "sense_range_bl")?;
        positive(self.decision_interval, "decision_interval")?;
        positive(self.visual_radius_bl, "visual_radius_bl")?;
        positive(self.max_delta_speed_bl, "max_delta_speed_bl")?;
        for (i, c) in self.collider_bl.iter().enumerate() {
            positive(*c, &format!("collider_bl[{i}]"))?;
        }
        Range::Uniform(self.speed_bl).check(path, "speed_bl", Some(0.0))?;
        positive(self.speed_bl[1], "speed_bl[1]")?;
        Range::Uniform(self.temperature_pref).check(path, "temperature_pref", None)?;
        if !(self.initial_speed_bl >= 0.0 && self.initial_speed_bl <= self.speed_bl[1]) {
            return Err(ConfigError::invalid(
                path,
                "initial_speed_bl",
                format!("must lie in [0, speed_bl max = {}]", self.speed_bl[1]),
            ));
        }
        if self.light_steep[0] >= 0.0 || self.light_steep[1] <= 0.0 {
            return Err(ConfigError::invalid(
                path,
                "light_steep",
                "must be [negative, positive]",
            ));
        }
        if self.temperature_steep[0] >= self.temperature_pref[0]
            || self.temperature_steep[1] <= self.temperature_pref[1]
        {
            return Err(ConfigError::invalid(
                path,
                "temperature_steep",
                "must lie outside temperature_pref ([T_lsteep < T_lpref, T_hsteep > T_hpref])",
            ));
        }
        ConfigError::check_within(path, "dominant_fraction", self.dominant_fraction, 0.0, 1.0)?;
        if self.size_classes.is_empty() {
            return Err(ConfigError::invalid(
                path,
                "size_classes",
                "at least one size class is needed",
            ));
        }
        for (name, class) in &self.size_classes {
            class
                .body_scale
                .check(path, &format!("size_classes.{name}.body_scale"), Some(1e-3))?;
            class.light_lpref.check(
                path,
                &format!("size_classes.{name}.light_lpref"),
                Some(0.0),
            )?;
            class.light_hpref.check(
                path,
                &format!("size_classes.{name}.light_hpref"),
                Some(0.0),
            )?;
            if class.light_lpref.bounds().0 <= self.light_steep[0]
                || class.light_hpref.bounds().1 >= self.light_steep[1]
            {
                return Err(ConfigError::invalid(
                    path,
                    format!("size_classes.{name}"),
                    "light preferences must lie strictly between light_steep[0] and light_steep[1]",
                ));
            }
        }
        bounds(self, path)
    }
}

/// The bounds of a species file (after a scene's overrides).
fn bounds(s: &SpeciesConfig, path: &Path) -> Result<(), ConfigError> {
    check(
        path,
        "body_length",
        s.body_length,
        [0.0, MAX_BODY_LENGTH_M],
        "m",
    )?;
    pair(path, "speed_bl", s.speed_bl, SPEED, "BL/s")?;
    check(path, "sense_range_bl", s.sense_range_bl, BL, "BL")?;
    check(
        path,
        "decision_interval",
        s.decision_interval,
        [0.0, MAX_DECISION_INTERVAL_S],
        "s",
    )?;
    pair(
        path,
        "temperature_pref",
        s.temperature_pref,
        TEMPERATURE,
        "°C",
    )?;
    pair(
        path,
        "temperature_steep",
        s.temperature_steep,
        TEMPERATURE,
        "°C",
    )?;
    for (i, c) in s.collider_bl.iter().enumerate() {
        check(path, &format!("collider_bl[{i}]"), *c, BL, "BL")?;
    }
    check(path, "visual_radius_bl", s.visual_radius_bl, BL, "BL")?;
    check(path, "initial_speed_bl", s.initial_speed_bl, SPEED, "BL/s")?;
    check(
        path,
        "max_delta_speed_bl",
        s.max_delta_speed_bl,
        SPEED,
        "BL/s",
    )?;
    pair(path, "light_steep", s.light_steep, LIGHT, "PAR")?;
    check(path, "dominant_fraction", s.dominant_fraction, SHARE, "")?;
    for (i, c) in s.colour.iter().enumerate() {
        check(path, &format!("colour[{i}]"), *c, SHARE, "")?;
    }
    check_count(
        path,
        "size_classes",
        s.size_classes.len() as u64,
        MAX_SIZE_CLASSES as u64,
        "size classes",
    )?;
    for (name, c) in &s.size_classes {
        let field = |f: &str| format!("size_classes.{name}.{f}");
        range(
            path,
            &field("body_scale"),
            &c.body_scale,
            [0.0, MAX_BODY_SCALE],
            "×",
        )?;
        range(path, &field("light_lpref"), &c.light_lpref, LIGHT, "PAR")?;
        range(path, &field("light_hpref"), &c.light_hpref, LIGHT, "PAR")?;
    }
    Ok(())
}
