//! Scene files, `scenes/<id>.toml`: [`SceneFile`] with its cage, obstacles,
//! groups and physics, and the [`Clock`] its date and time give
//! ([`parse_clock`]). [`crate::scene`] resolves a scene file into a scene.

use super::check::{BL, SPEED, check, check_count, number};
use super::error::ConfigError;
use super::range::Range;
use crate::limits::{
    MAX_CAGE_M, MAX_CHASE_TIMEOUT_S, MAX_EPISODE_DECISIONS, MAX_OBSTACLES, MAX_STEPS_PER_DECISION,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Cage geometry (SPEC §1). The surface is `y = 0`, the bottom `y = −height`.
/// Every dimension is positive and at most [`crate::limits::MAX_CAGE_M`] (1 km).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "shape", rename_all = "lowercase", deny_unknown_fields)]
pub enum CageConfig {
    /// A cube: x, z in [−edge/2, edge/2], height = edge (m).
    Cube { edge: f32 },
    /// A box: x in [−width/2, width/2], z in [−length/2, length/2], y in [−height, 0] (m).
    Box {
        width: f32,
        length: f32,
        height: f32,
    },
    /// A regular octagonal prism with edge `edge` (m), apothem edge / (2 tan 22.5°).
    Octagon { edge: f32, height: f32 },
}

/// An obstacle listed in a scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum ObstacleConfig {
    /// A sphere with `center = [x, y, z]` and `radius` (m).
    Sphere { center: [f32; 3], radius: f32 },
    /// A vertical cylinder through `center = [x, z]`, `radius`, spanning `y = [min, max]` (m).
    Cylinder {
        center: [f32; 2],
        radius: f32,
        y: [f32; 2],
    },
}

/// A group of fish in a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroupConfig {
    /// Species id (a file `species/<species>.toml`).
    pub species: String,
    /// Size class of that species; default `regular`.
    #[serde(default = "default_size_class")]
    pub size_class: String,
    /// Number of fish, 1 to [`crate::limits::MAX_FISH`] (200,000; also in total).
    pub count: usize,
    /// Body scale override; default: the size class' `body_scale`.
    #[serde(default)]
    pub body_scale: Option<Range>,
}

fn default_size_class() -> String {
    "regular".into()
}

/// World parameters shared by all fish of a scene; all have defaults.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PhysicsConfig {
    /// Fixed simulation step `dt_sim` (s). SPEC §1: 0.02.
    pub dt_sim: f32,
    /// Largest pitch or yaw change of one decision `θ_max` (degrees). SPEC §4: 20.
    pub max_turn_deg: f32,
    /// Roll clamp `θzt` (degrees). Table 4.1: 10.
    pub roll_clamp_deg: f32,
    /// Pitch threshold `θrt` of the movement reward (degrees). Table 4.1: 53.
    pub pitch_threshold_deg: f32,
    /// Speed threshold `v_st` of the movement reward (BL/s). Table 4.1: 0.3.
    pub speed_threshold_bl: f32,
    /// Maximum episode length (decisions); reaching it truncates the episode. SPEC §7: 2000.
    pub max_episode_decisions: u32,
    /// Probability per decision that a free dominant fish starts a chase, `p_a`. Table 4.1: 0.005.
    pub chase_probability: f32,
    /// A chase ends after this long (s). SPEC §6: e.g. 3.
    pub chase_timeout: f32,
    /// Share of the penetration depth removed per step by the mild repulsion (0–1); 0.5.
    pub repulsion: f32,
    /// Minimum clearance of a (re)spawned fish's collider from every boundary (BL); 0.5.
    pub spawn_margin_bl: f32,
    /// Largest pitch of a (re)spawned fish (degrees); 20.
    pub spawn_pitch_deg: f32,
}

impl Default for PhysicsConfig {
    fn default() -> Self {
        Self {
            dt_sim: 0.02,
            max_turn_deg: 20.0,
            roll_clamp_deg: 10.0,
            pitch_threshold_deg: 53.0,
            speed_threshold_bl: 0.3,
            max_episode_decisions: 2000,
            chase_probability: 0.005,
            chase_timeout: 3.0,
            repulsion: 0.5,
            spawn_margin_bl: 0.5,
            spawn_pitch_deg: 20.0,
        }
    }
}

/// Clock of a scene: date, local time of day, and whether it advances.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Clock {
    pub year: i32,
    pub month: u32,
    pub day: u32,
    /// Local clock time at the start (hours, 0–24).
    pub start_hours: f32,
    /// Whether the time of day advances with simulated time.
    pub runs: bool,
}

/// A scene file. File: `scenes/<id>.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// One line describing the scene.
    #[serde(default)]
    pub description: String,
    /// Site id (a file `sites/<site>.toml`).
    pub site: String,
    /// Date `YYYY-MM-DD`.
    pub date: String,
    /// Local time of day `HH:MM`.
    pub time: String,
    /// Whether the clock runs with simulated time (default false: light stays as at `time`).
    #[serde(default)]
    pub clock_runs: bool,
    pub cage: CageConfig,
    #[serde(default, rename = "obstacle")]
    pub obstacles: Vec<ObstacleConfig>,
    #[serde(rename = "group")]
    pub groups: Vec<GroupConfig>,
    /// Per-species overrides of any species value, e.g. `[species_overrides.coho] sense_range_bl = 2.5`.
    #[serde(default)]
    pub species_overrides: BTreeMap<String, toml::Table>,
    /// Overrides of any site value, e.g. `[site_overrides] surface_temperature = 9.0`.
    #[serde(default)]
    pub site_overrides: toml::Table,
    #[serde(default)]
    pub physics: PhysicsConfig,
}

/// Parse `YYYY-MM-DD` and `HH:MM` into a clock.
pub fn parse_clock(path: &Path, date: &str, time: &str, runs: bool) -> Result<Clock, ConfigError> {
    let bad_date =
        || ConfigError::invalid(path, "date", format!("`{date}` is not a date YYYY-MM-DD"));
    let parts: Vec<&str> = date.split('-').collect();
    if parts.len() != 3 {
        return Err(bad_date());
    }
    let year: i32 = parts[0].parse().map_err(|_| bad_date())?;
    let month: u32 = parts[1].parse().map_err(|_| bad_date())?;
    let day: u32 = parts[2].parse().map_err(|_| bad_date())?;
    if !(1..=12).contains(&month) || day == 0 || day > crate::sun::days_in_month(year, month) {
        return Err(bad_date());
    }
    let bad_time = || {
        ConfigError::invalid(
            path,
            "time",
            format!("`{time}` is not a time HH:MM (00:00–23:59)"),
        )
    };
    let (h, m) = time.split_once(':').ok_or_else(bad_time)?;
    let h: u32 = h.parse().map_err(|_| bad_time())?;
    let m: u32 = m.parse().map_err(|_| bad_time())?;
    if h > 23 || m > 59 {
        return Err(bad_time());
    }
    Ok(Clock {
        year,
        month,
        day,
        start_hours: h as f32 + m as f32 / 60.0,
        runs,
    })
}

/// The bounds of a scene's cage.
pub(crate) fn cage_bounds(c: &CageConfig, path: &Path) -> Result<(), ConfigError> {
    let m = [0.0, MAX_CAGE_M];
    match *c {
        CageConfig::Cube { edge } => check(path, "cage.edge", edge, m, "m"),
        CageConfig::Box {
            width,
            length,
            height,
        } => {
            check(path, "cage.width", width, m, "m")?;
            check(path, "cage.length", length, m, "m")?;
            check(path, "cage.height", height, m, "m")
        }
        CageConfig::Octagon { edge, height } => {
            check(path, "cage.edge", edge, m, "m")?;
            check(path, "cage.height", height, m, "m")
        }
    }
}

/// The bounds of a scene's obstacles (their centres must lie in the cage, checked elsewhere).
pub(crate) fn obstacle_bounds(
    obstacles: &[ObstacleConfig],
    path: &Path,
) -> Result<(), ConfigError> {
    check_count(
        path,
        "obstacle",
        obstacles.len() as u64,
        MAX_OBSTACLES as u64,
        "obstacles",
    )?;
    let m = [-(MAX_CAGE_M), MAX_CAGE_M];
    for (i, o) in obstacles.iter().enumerate() {
        let (radius, coords): (f32, Vec<f32>) = match *o {
            ObstacleConfig::Sphere { center, radius } => (radius, center.to_vec()),
            ObstacleConfig::Cylinder { center, radius, y } => {
                (radius, vec![center[0], center[1], y[0], y[1]])
            }
        };
        check(path, &format!("obstacle[{i}].radius"), radius, m, "m")?;
        for c in coords {
            check(path, &format!("obstacle[{i}]"), c, m, "m")?;
        }
    }
    Ok(())
}

/// The bounds of a scene's `[physics]` that do not depend on the species.
pub(crate) fn physics_bounds(p: &PhysicsConfig, path: &Path) -> Result<(), ConfigError> {
    check(
        path,
        "physics.max_turn_deg",
        p.max_turn_deg,
        [0.0, 180.0],
        "°",
    )?;
    check(
        path,
        "physics.pitch_threshold_deg",
        p.pitch_threshold_deg,
        [0.0, 90.0],
        "°",
    )?;
    check(
        path,
        "physics.speed_threshold_bl",
        p.speed_threshold_bl,
        SPEED,
        "BL/s",
    )?;
    check_count(
        path,
        "physics.max_episode_decisions",
        p.max_episode_decisions as u64,
        MAX_EPISODE_DECISIONS as u64,
        "decisions",
    )?;
    check(
        path,
        "physics.chase_timeout",
        p.chase_timeout,
        [0.0, MAX_CHASE_TIMEOUT_S],
        "s",
    )?;
    check(path, "physics.spawn_margin_bl", p.spawn_margin_bl, BL, "BL")
}

/// At most [`MAX_STEPS_PER_DECISION`] physics steps per decision of any species.
pub(crate) fn steps_per_decision(
    dt_sim: f32,
    decision_interval: f32,
    species: &str,
    path: &Path,
) -> Result<(), ConfigError> {
    let k = decision_interval / dt_sim;
    if k > MAX_STEPS_PER_DECISION {
        return Err(ConfigError::Limit {
            path: path.to_path_buf(),
            field: "physics.dt_sim".into(),
            value: format!(
                "{} s (giving {} physics steps per decision of {species})",
                number(dt_sim),
                number(k.floor())
            ),
            above: true,
            limit: format!("{MAX_STEPS_PER_DECISION} steps"),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_cage_key_is_rejected() {
        #[derive(Deserialize, Debug)]
        #[allow(dead_code)]
        struct T {
            cage: CageConfig,
        }
        let err =
            toml::from_str::<T>("[cage]\nshape = \"cube\"\nedge = 3\nheight = 2").unwrap_err();
        assert!(err.to_string().contains("height"), "{err}");
        let err = toml::from_str::<T>("[cage]\nshape = \"sphere\"\nedge = 3").unwrap_err();
        assert!(err.to_string().contains("octagon"), "{err}");
    }

    #[test]
    fn clock_parses_and_rejects() {
        let p = Path::new("x.toml");
        let c = parse_clock(p, "2021-03-15", "11:30", false).unwrap();
        assert_eq!((c.year, c.month, c.day), (2021, 3, 15));
        assert!((c.start_hours - 11.5).abs() < 1e-6);
        assert!(parse_clock(p, "2021-02-30", "11:00", false).is_err());
        assert!(parse_clock(p, "2021-03-15", "25:00", false).is_err());
    }
}
