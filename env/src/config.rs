//! The TOML configuration: species, sites, scenes and reward weights.
//!
//! The files live under a config root (`configs/` in the repository):
//! `species/<name>.toml`, `sites/<name>.toml`, `scenes/<id>.toml` and
//! `rewards/<phase>.toml`. A user adds a species, a site or a scene by adding a
//! file. Every struct rejects unknown keys, and every error names the file and
//! the field. Defaults live in code (`#[serde(default)]`), each documented with
//! its unit and source.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Everything that can go wrong while reading configuration. (An I/O error
/// is part of the message, not a `source`, so that a chain printed with
/// `{:#}` says the cause once.)
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read {path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("{path}: field `{field}`: {message}")]
    Invalid {
        path: PathBuf,
        field: String,
        message: String,
    },
    /// A value beyond its bound of [`crate::limits`].
    #[error("{path}: {field} = {value} is {} the limit of {limit}", if *above { "above" } else { "below" })]
    Limit {
        path: PathBuf,
        field: String,
        value: String,
        above: bool,
        limit: String,
    },
    #[error(
        "unknown {what} `{name}` (looked for {path}); {}",
        listing(path, available)
    )]
    Unknown {
        what: &'static str,
        name: String,
        path: PathBuf,
        available: Vec<String>,
    },
    /// A folder where a configuration file belongs (`species/x.toml/`).
    #[error("{path} is a folder, not a TOML file")]
    NotAFile { path: PathBuf },
    /// The configuration root (`--configs`) is missing or not a folder.
    #[error(
        "the configuration folder {root} {}; it should hold species/, sites/, scenes/, rewards/ and train/",
        if root.exists() { "is not a folder" } else { "does not exist" }
    )]
    NoRoot { root: PathBuf },
}

/// What an [`ConfigError::Unknown`] could have been: the names beside `path`,
/// or that its folder holds none.
fn listing(path: &Path, available: &[String]) -> String {
    if !available.is_empty() {
        return format!("available: {}", available.join(", "));
    }
    let dir = if path.extension().is_some() {
        path.parent().unwrap_or(path)
    } else {
        path
    };
    if dir.is_dir() {
        format!("{} holds none", dir.display())
    } else {
        format!("{} does not exist", dir.display())
    }
}

impl ConfigError {
    pub fn invalid(path: &Path, field: impl Into<String>, message: impl Into<String>) -> Self {
        ConfigError::Invalid {
            path: path.to_path_buf(),
            field: field.into(),
            message: message.into(),
        }
    }

    /// The message without the file it names.
    fn detail(&self) -> String {
        match self {
            ConfigError::Io { error, .. } => error.to_string(),
            ConfigError::Parse { message, .. } => message.clone(),
            ConfigError::Invalid { field, message, .. } => format!("field `{field}`: {message}"),
            ConfigError::Limit {
                field,
                value,
                above,
                limit,
                ..
            } => format!(
                "{field} = {value} is {} the limit of {limit}",
                if *above { "above" } else { "below" }
            ),
            ConfigError::Unknown { .. }
            | ConfigError::NotAFile { .. }
            | ConfigError::NoRoot { .. } => self.to_string(),
        }
    }
}

/// Values a scene file overrides in a species or site file, and where they are
/// written, so that an error they cause names the scene file.
#[derive(Clone, Copy, Debug)]
pub struct Overrides<'a> {
    /// The scene file that holds them.
    pub file: &'a Path,
    /// Their table in that file, e.g. `species_overrides.coho`.
    pub section: &'a str,
    pub table: &'a toml::Table,
}

impl Overrides<'_> {
    /// Whether the overrides set `field` (`a.b.c`, `a[1]`) or a table above it.
    fn hold(&self, field: &str) -> bool {
        let mut table = self.table;
        for key in field.split('.') {
            let key = key.split('[').next().unwrap_or(key);
            match table.get(key) {
                Some(toml::Value::Table(t)) => table = t,
                Some(_) => return true,
                None => return false,
            }
        }
        true
    }

    /// Point an error of the file at `base` (merged with these overrides) at the
    /// scene file when an override caused it: the field it names is overridden,
    /// or `base` alone passes. `loads(key)` says whether `base` with only the
    /// override `key` (`None`: none) loads; the first key that breaks it is named.
    fn blame(
        &self,
        e: ConfigError,
        base: &Path,
        loads: impl Fn(Option<&str>) -> bool,
    ) -> ConfigError {
        let in_scene = |field: &str| format!("{}.{field}", self.section);
        match e {
            ConfigError::Invalid { field, message, .. } if self.hold(&field) => {
                ConfigError::Invalid {
                    path: self.file.to_path_buf(),
                    field: in_scene(&field),
                    message,
                }
            }
            ConfigError::Limit {
                field,
                value,
                above,
                limit,
                ..
            } if self.hold(&field) => ConfigError::Limit {
                path: self.file.to_path_buf(),
                field: in_scene(&field),
                value,
                above,
                limit,
            },
            e @ (ConfigError::Io { .. }
            | ConfigError::Unknown { .. }
            | ConfigError::NotAFile { .. }
            | ConfigError::NoRoot { .. }) => e,
            e if loads(None) => ConfigError::Invalid {
                path: self.file.to_path_buf(),
                field: match self.table.keys().find(|k| !loads(Some(k))) {
                    Some(key) => in_scene(key),
                    None => self.section.to_string(),
                },
                message: format!("{} (applied to {})", e.detail(), base.display()),
            },
            e => e,
        }
    }
}

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
    fn check(&self, path: &Path, field: &str, min: Option<f32>) -> Result<(), ConfigError> {
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
    fn validate(&self, path: &Path) -> Result<(), ConfigError> {
        let positive = |v: f32, field: &str| {
            if v > 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err(ConfigError::invalid(
                    path,
                    field,
                    format!("must be a positive number, got {v}"),
                ))
            }
        };
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
        if !(0.0..=1.0).contains(&self.dominant_fraction) {
            return Err(ConfigError::invalid(
                path,
                "dominant_fraction",
                "must lie in [0, 1]",
            ));
        }
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
        crate::limits::species(self, path)
    }
}

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
    fn validate(&self, path: &Path) -> Result<(), ConfigError> {
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
        crate::limits::site(self, path)
    }
}

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

/// The training phase, which picks the reward weights (thesis §4.5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    #[default]
    Pretrain,
    Transfer,
}

impl Phase {
    pub fn as_str(&self) -> &'static str {
        match self {
            Phase::Pretrain => "pretrain",
            Phase::Transfer => "transfer",
        }
    }
}

impl std::str::FromStr for Phase {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "pretrain" => Ok(Phase::Pretrain),
            "transfer" => Ok(Phase::Transfer),
            _ => Err(format!("unknown phase `{s}`; allowed: pretrain, transfer")),
        }
    }
}

/// When the action acts (SPEC §4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ActionTiming {
    /// The original Unity agent's reading: at every physics step the speed
    /// changes by `a0 · Δv_max · BL · dt_sim` (`Δv_max` in BL/s per second) and
    /// the heading turns by `a1, a2 · turn_step_deg` (SPEC §4; the default).
    #[default]
    PerStep,
    /// The earlier reading: the whole change of one decision (`a0 · Δv_max`
    /// BL/s, `θ_max` = `physics.max_turn_deg` per decision) spread over its k steps.
    PerDecision,
}

/// When `r_M`, `r_BD`, `r_E` and `r_NC` accrue (SPEC §6.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum RewardTiming {
    /// `r_M`, `r_BD` and `r_E` at every physics step, `r_NC` once when a
    /// contact starts, `r_ND` and `r_C` once per decision (SPEC §6.1; the default).
    #[default]
    PerStep,
    /// Every term once per decision from the state at the decision; `r_NC`
    /// per distinct partner touched during the decision (the earlier reading).
    PerDecision,
}

/// When the action acts and the rewards accrue (SPEC §4, §6.1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Timing {
    /// SPEC §4: `per_step` (default) or `per_decision`.
    pub actions: ActionTiming,
    /// SPEC §6.1: `per_step` (default) or `per_decision`.
    pub rewards: RewardTiming,
    /// Heading change per physics step at a full action, `θ_step` (degrees),
    /// with `actions = "per_step"`. SPEC §4: 1 (the original's Euler angle per step).
    pub turn_step_deg: f32,
}

impl Default for Timing {
    fn default() -> Self {
        Self {
            actions: ActionTiming::PerStep,
            rewards: RewardTiming::PerStep,
            turn_step_deg: 1.0,
        }
    }
}

/// Fish–fish contacts (SPEC §6.1): the repulsive velocity kicks of the
/// original agent. Both in m/s, not BL-scaled, as the Unity agent sets them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Contacts {
    /// Velocity kick away from the partner on the step a contact starts (m/s).
    /// The Unity agent: 0.03 for 1,000 coho, 0.05 for 300. Default 0.03.
    pub kick: f32,
    /// Velocity push away from the partner at every step while they overlap (m/s).
    /// The Unity agent: 0.0003. Default 0.0003.
    pub push: f32,
}

impl Default for Contacts {
    fn default() -> Self {
        Self {
            kick: 0.03,
            push: 0.0003,
        }
    }
}

/// How `r_ND` counts neighbours (SPEC §6, §6.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum NeighbourForm {
    /// `Σ_j (90 − Δθ_j)/90`, the thesis' sum (default).
    #[default]
    Sum,
    /// The same sum divided by the number of neighbours counted (§6.2: normalised).
    Mean,
}

/// The extensions of SPEC §6.2 the thesis cites but never formalises; all off by default.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Extensions {
    /// `r_ND` as the thesis' `sum` (default) or the `mean` over the neighbours counted.
    pub neighbour_form: NeighbourForm,
    /// Personal space (Føre et al. 2009: ≥ 0.66 BL) in BL: a neighbour nearer
    /// than this does not count for `r_ND`. 0 (default): off.
    pub personal_space_bl: f32,
    /// Penalty per neighbour inside the personal space, per decision, added to
    /// `r_ND` (> 0 means a cost). 0 (default): none.
    pub personal_space_penalty: f32,
    /// Assortment (Krause et al. 1996): `r_ND` counts only neighbours of the
    /// fish's own species. Default false.
    pub conspecific_only: bool,
    /// Assortment by size: each neighbour's `r_ND` term is weighted by
    /// `min(BL_i, BL_j) / max(BL_i, BL_j)`. Default false.
    pub size_weighted: bool,
    /// Whether a net, bottom or surface collision ends the agent's episode
    /// (SPEC §6, default true). With false the fish pays `r_BC`, bounces back
    /// inside (the velocity reflected off the plane, the collider moved back
    /// inside) and its episode goes on (SPEC §6.2).
    pub boundary_ends_episode: bool,
}

impl Default for Extensions {
    fn default() -> Self {
        Self {
            neighbour_form: NeighbourForm::Sum,
            personal_space_bl: 0.0,
            personal_space_penalty: 0.0,
            conspecific_only: false,
            size_weighted: false,
            boundary_ends_episode: true,
        }
    }
}

/// Reward weights of one phase of a reward profile (SPEC §6, Table 4.1), with
/// the profile's timing (§4, §6.1), contacts (§6.1) and extensions (§6.2).
/// File: `rewards/<profile>/<phase>.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RewardWeights {
    /// Penalty of a boundary collision, `−r_BC` (> 0). SPEC §6: 300.
    pub boundary_collision: f32,
    /// Neighbour collision weight `w_NC`. Pretrain 0.5, transfer 4.
    pub w_nc: f32,
    /// Boundary avoidance weight `w_BD`. 2.
    pub w_bd: f32,
    /// Neighbour interaction weight `w_ND`. 1.5.
    pub w_nd: f32,
    /// `r_ND` sums over at most this many nearest neighbours within `d_sense`
    /// (0: every one, as SPEC §6 writes it). A topological cap keeps the
    /// reward's scale independent of density (issue 14; README deviations).
    #[serde(default)]
    pub neighbour_cap: u32,
    /// Rotation penalty weight `w_r` (per degree). Pretrain 0.001, transfer 0.5.
    pub w_r: f32,
    /// Speed-change penalty weight `w_s` (per BL/s). Pretrain 5, transfer 10.
    pub w_s: f32,
    /// Penalty for a pitch at or beyond `θrt` (> 0). SPEC §6: 10.
    pub pitch_penalty: f32,
    /// Bonus for level swimming at or above `v_st`. SPEC §6: 2.
    pub movement_bonus: f32,
    /// Chase reward weight of the aggressor `w_agg` (per BL/s). 8.
    pub w_agg: f32,
    /// Escape weight of the target `w_tar` (per BL/s). 1.
    pub w_tar: f32,
    /// One-off reward of an aggressor hitting its target. SPEC §6: 100.
    pub catch_bonus: f32,
    /// When actions act and terms accrue (SPEC §4, §6.1).
    #[serde(default)]
    pub timing: Timing,
    /// Contact kicks (SPEC §6.1).
    #[serde(default)]
    pub contacts: Contacts,
    /// SPEC §6.2's extensions (all off by default).
    #[serde(default)]
    pub extensions: Extensions,
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

/// The root folder of the TOML configuration.
#[derive(Clone, Debug)]
pub struct ConfigDirs {
    pub root: PathBuf,
    /// The reward profile: a folder `rewards/<profile>/` with `pretrain.toml`
    /// and `transfer.toml` (SPEC §6.2). Default [`DEFAULT_REWARD_PROFILE`].
    pub reward_profile: String,
}

/// The reward profile used unless `--reward-profile` names another (README,
/// "Reward profiles": chosen by the variant table of docs/reproduction/NOTES.md).
pub const DEFAULT_REWARD_PROFILE: &str = "thesis";

impl ConfigDirs {
    pub fn new(root: impl Into<PathBuf>) -> Self {
        Self {
            root: root.into(),
            reward_profile: DEFAULT_REWARD_PROFILE.to_string(),
        }
    }

    /// The same folder with reward profile `profile` (checked when rewards are read).
    pub fn with_reward_profile(mut self, profile: impl Into<String>) -> Self {
        self.reward_profile = profile.into();
        self
    }

    /// The reward profiles: the sub-folders of `rewards/`, sorted.
    pub fn reward_profiles(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(self.root.join("rewards"))
            .map(|rd| {
                rd.filter_map(|e| e.ok())
                    .filter(|e| e.path().is_dir())
                    .filter_map(|e| e.file_name().to_str().map(str::to_string))
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        names
    }

    /// `configs/` of the current directory if it exists, else the repository's own.
    pub fn discover() -> Self {
        if let Ok(dir) = std::env::var("DEEPFOIDS_CONFIGS") {
            return Self::new(dir);
        }
        let local = PathBuf::from("configs");
        if local.join("scenes").is_dir() {
            return Self::new(local);
        }
        Self::new(Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs"))
    }

    fn named(&self, kind: &'static str, sub: &str, name: &str) -> Result<PathBuf, ConfigError> {
        let path = self.root.join(sub).join(format!("{name}.toml"));
        if path.is_file() {
            Ok(path)
        } else if path.is_dir() {
            Err(ConfigError::NotAFile { path })
        } else {
            self.check_root()?;
            Err(ConfigError::Unknown {
                what: kind,
                name: name.to_string(),
                path,
                available: self.list(sub),
            })
        }
    }

    /// The root is a folder: otherwise every name would be "unknown" with an
    /// empty list of the available ones.
    pub fn check_root(&self) -> Result<(), ConfigError> {
        if self.root.is_dir() {
            Ok(())
        } else {
            Err(ConfigError::NoRoot {
                root: self.root.clone(),
            })
        }
    }

    /// The ids of the files in a sub-folder, sorted.
    pub fn list(&self, sub: &str) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(self.root.join(sub))
            .map(|rd| {
                rd.filter_map(|e| e.ok())
                    .filter_map(|e| {
                        let p = e.path();
                        (p.extension()? == "toml" && p.is_file())
                            .then(|| p.file_stem()?.to_str().map(str::to_string))?
                    })
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        names
    }

    /// Path of a baseline's parameter file, `baselines/<name>.toml`.
    pub fn baseline(&self, name: &str) -> Result<PathBuf, ConfigError> {
        self.named("baseline", "baselines", name)
    }

    /// Path of a scene: an existing file path as given, else `scenes/<id>.toml`.
    pub fn scene_path(&self, id_or_path: &str) -> Result<PathBuf, ConfigError> {
        let p = Path::new(id_or_path);
        if id_or_path.ends_with(".toml") || id_or_path.contains('/') {
            if p.is_file() {
                return Ok(p.to_path_buf());
            }
            if p.is_dir() {
                return Err(ConfigError::NotAFile {
                    path: p.to_path_buf(),
                });
            }
            return Err(ConfigError::Io {
                path: p.to_path_buf(),
                error: std::io::Error::new(std::io::ErrorKind::NotFound, "no such scene file"),
            });
        }
        self.named("scene", "scenes", id_or_path)
    }

    /// Species `name`, with a scene's overrides applied.
    pub fn species(
        &self,
        name: &str,
        overrides: Option<Overrides>,
    ) -> Result<SpeciesConfig, ConfigError> {
        let path = self.named("species", "species", name)?;
        load_with(&path, overrides, |s: &SpeciesConfig, path| {
            if s.name != name {
                return Err(ConfigError::invalid(
                    path,
                    "name",
                    format!("must match the file name `{name}`"),
                ));
            }
            s.validate(path)
        })
    }

    /// Site `name`, with a scene's overrides applied.
    pub fn site(
        &self,
        name: &str,
        overrides: Option<Overrides>,
    ) -> Result<SiteConfig, ConfigError> {
        let path = self.named("site", "sites", name)?;
        load_with(&path, overrides, SiteConfig::validate)
    }

    /// The weights of `phase` in the reward profile, `rewards/<profile>/<phase>.toml`.
    pub fn rewards(&self, phase: Phase) -> Result<RewardWeights, ConfigError> {
        let profile = &self.reward_profile;
        self.check_root()?;
        if profile.is_empty() || profile.contains(['/', '\\']) || profile.starts_with('.') {
            return Err(ConfigError::Unknown {
                what: "reward profile",
                name: profile.clone(),
                path: self.root.join("rewards"),
                available: self.reward_profiles(),
            });
        }
        let dir = self.root.join("rewards").join(profile);
        if !dir.is_dir() {
            return Err(ConfigError::Unknown {
                what: "reward profile",
                name: profile.clone(),
                path: dir,
                available: self.reward_profiles(),
            });
        }
        let path = self.named(
            "reward weights",
            &format!("rewards/{profile}"),
            phase.as_str(),
        )?;
        let weights: RewardWeights = read_toml(&path)?;
        crate::limits::rewards(&weights, &path)?;
        Ok(weights)
    }
}

/// Read and deserialize a TOML file of at most [`crate::limits::MAX_CONFIG_BYTES`];
/// errors name the file, line and field.
pub fn read_toml<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, ConfigError> {
    let io = |error| ConfigError::Io {
        path: path.to_path_buf(),
        error,
    };
    let max = crate::limits::MAX_CONFIG_BYTES;
    let mut bytes = Vec::new();
    // `take` rather than the file's length: a FIFO or /dev/zero has none.
    std::fs::File::open(path)
        .and_then(|f| f.take(max + 1).read_to_end(&mut bytes))
        .map_err(io)?;
    if bytes.len() as u64 > max {
        return Err(ConfigError::Parse {
            path: path.to_path_buf(),
            message: format!(
                "the file is larger than {max} bytes, the limit of a configuration file"
            ),
        });
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text ({e})"),
        ))
    })?;
    toml::from_str(&text).map_err(|e| ConfigError::Parse {
        path: path.to_path_buf(),
        message: match e.span() {
            Some(span) => {
                let before = &text[..text.floor_char_boundary(span.start)];
                let line = before.matches('\n').count() + 1;
                let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
                let field =
                    field_at(&text, span.start).map_or(String::new(), |f| format!(", field `{f}`"));
                format!(
                    "line {line}, column {column}{field}: {}",
                    plain(e.message())
                )
            }
            None => plain(e.message()),
        },
    })
}

/// The dotted name of the `key = value` on the line holding byte `at` of a
/// TOML `text`, under its last table header: `group[1].count`. `None` when
/// that line holds no `key =` (a value continued from an earlier line).
fn field_at(text: &str, at: usize) -> Option<String> {
    let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let line = text[start..].lines().next()?;
    let key = line.split_once('=')?.0.trim();
    let bare = |k: &str| {
        !k.is_empty()
            && k.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
    };
    if !bare(key) {
        return None;
    }
    let headers = text[..start]
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with('['));
    let table = match headers.clone().next_back() {
        None => return Some(key.to_string()),
        Some(h) => h.split('#').next().unwrap_or(h).trim(),
    };
    Some(
        match table.strip_prefix("[[").and_then(|t| t.strip_suffix("]]")) {
            Some(name) => {
                let index = headers
                    .filter(|h| h.starts_with(&format!("[[{name}]]")))
                    .count()
                    - 1;
                format!("{}[{index}].{key}", name.trim())
            }
            None => format!("{}.{key}", table.trim_matches(['[', ']']).trim()),
        },
    )
}

/// serde's message with its Rust type names said as the numbers they allow:
/// "expected usize" becomes "expected a whole number ≥ 0".
fn plain(message: &str) -> String {
    let mut m = message.to_string();
    for (rust, allowed) in [
        ("usize", "a whole number ≥ 0"),
        ("u64", "a whole number ≥ 0"),
        ("u32", "a whole number from 0 to 4294967295"),
        ("u16", "a whole number from 0 to 65535"),
        ("u8", "a whole number from 0 to 255"),
        ("f32", "a number"),
        ("f64", "a number"),
    ] {
        m = m.replace(&format!("expected {rust}"), &format!("expected {allowed}"));
    }
    m
}

fn from_table<T: serde::de::DeserializeOwned>(
    path: &Path,
    table: toml::Table,
) -> Result<T, ConfigError> {
    toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| ConfigError::Parse {
            path: path.to_path_buf(),
            message: plain(e.message()),
        })
}

/// Read the file at `path`, apply `overrides`, deserialize and `validate`;
/// an error the overrides cause names the scene file that holds them.
fn load_with<T: serde::de::DeserializeOwned>(
    path: &Path,
    overrides: Option<Overrides>,
    validate: impl Fn(&T, &Path) -> Result<(), ConfigError>,
) -> Result<T, ConfigError> {
    let base: toml::Table = read_toml(path)?;
    let load = |table: toml::Table| {
        let value: T = from_table(path, table)?;
        validate(&value, path).map(|()| value)
    };
    match overrides.filter(|o| !o.table.is_empty()) {
        None => load(base),
        Some(o) => {
            let mut merged = base.clone();
            merge(&mut merged, o.table);
            load(merged).map_err(|e| {
                // Does `base` load with no override (`None`) or only override `key`?
                let loads = |key: Option<&str>| {
                    let mut table = base.clone();
                    if let Some(k) = key {
                        let one: toml::Table = o
                            .table
                            .iter()
                            .filter(|(name, _)| *name == k)
                            .map(|(name, v)| (name.clone(), v.clone()))
                            .collect();
                        merge(&mut table, &one);
                    }
                    load(table).is_ok()
                };
                o.blame(e, path, loads)
            })
        }
    }
}

/// Overlay `over` onto `base`, recursing into tables.
fn merge(base: &mut toml::Table, over: &toml::Table) {
    for (k, v) in over {
        match (base.get_mut(k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            _ => {
                base.insert(k.clone(), v.clone());
            }
        }
    }
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

    #[test]
    fn merge_overrides_nested_values() {
        let mut base: toml::Table = toml::from_str("a = 1\n[t]\nx = 1\ny = 2").unwrap();
        let over: toml::Table = toml::from_str("[t]\ny = 3").unwrap();
        merge(&mut base, &over);
        assert_eq!(base["a"].as_integer(), Some(1));
        assert_eq!(base["t"]["x"].as_integer(), Some(1));
        assert_eq!(base["t"]["y"].as_integer(), Some(3));
    }
}
