//! Upper bounds on every size, count and duration that a configuration file or
//! a command line can ask for.
//!
//! A typo must not take the machine down: `count = 100000000` once asked the
//! allocator for 4.9 TB and `edge = 1e30` simulated a cage of 10³⁰ m. Every
//! value is checked against a bound *before* anything is allocated, and the
//! error names the file, the field, the value and the bound:
//! `configs/scenes/x.toml: group[0].count = 100000000 is above the limit of 200000 fish`.
//! The bounds are machine-independent sanity limits, generous enough for any
//! real farm; whether a scene within them fits into *this* machine's memory is
//! the separate check of [`crate::memory`].
//!
//! | value | bound | why |
//! |---|---|---|
//! | fish in a scene (per group and in total) | 200,000 | the largest licensed salmon pens hold 200,000 fish (Norway's per-cage cap); ≈ 10 GB of observations |
//! | groups, obstacles per scene | 256 each | every fish tests every obstacle at every step |
//! | size classes per species | 64 | |
//! | cage width, length, height, edge; obstacle radius | 1,000 m | the largest sea cages are ~110 m across and ~70 m deep; `f32` positions keep 0.1 mm resolution up to 1 km |
//! | physics steps per decision `dt_res / dt_sim` | 1,000 | the thesis uses 5–10; beyond, one decision is a CPU-minute |
//! | decision interval | 10 s | the thesis uses 0.1–0.2 s |
//! | episode length | 1,000,000 decisions | ≥ 27 simulated hours; the thesis uses 2,000 |
//! | chase timeout | 3,600 s | the thesis uses 3 s |
//! | body length | 10 m | farmed fish are < 3 m (bluefin tuna) |
//! | body scale | 10 × | the thesis uses 0.5–1.5 |
//! | speeds (BL/s) | 50 BL/s | burst speeds of fish reach ~20 BL/s |
//! | sensing range, colliders, visual radius, baseline ranges (BL) | 100 BL | the thesis senses 2–3 BL |
//! | light (PAR) | 5,000 | full sunlight is ~2,000–2,500 µmol m⁻² s⁻¹ |
//! | light attenuation | 100 1/m | turbid coastal water: ~5 1/m |
//! | temperatures | −100 … 100 °C (water at the surface −5 … 50 °C) | liquid sea water |
//! | reward and baseline weights | 0 … 10,000 | the thesis' largest is 300 |
//! | a configuration file | 1 MiB | ours are < 2 kB; the whole file is read into memory |
//! | simulated seconds of one command (`--seconds`, `--warmup`) | 86,400 s | one simulated day, a full light cycle |
//! | evaluation seeds (`compare --seeds`) | 1,000 | |
//! | worker threads (`--threads`) | 1 … 1,024 | 0 is refused: leave the option out for one thread per core |
//! | frames (`render --frames`, `--clip-frames`) | 1,000,000 | frame files are numbered with six digits |
//! | image side (`render --width`, `--height`) | 8,192 px | 8K; a frame's buffers grow with the pixel count |
//! | frames per second (`--fps`, `--replay-fps`) | 1,000 | more than one frame per physics step is impossible anyway |
//! | ticks before `sensor-view` looks (`--step`) | 1,000,000 | |

use crate::config::{
    CageConfig, ConfigError, ObstacleConfig, PhysicsConfig, Range, RewardWeights, SiteConfig,
    SpeciesConfig,
};
use std::path::Path;

/// Largest `neighbour_cap` of a reward file: the sensing pass keeps that
/// many nearest neighbours on the stack (`crate::sensing`).
pub const MAX_NEIGHBOUR_CAP: usize = 32;

/// Fish in one scene, per group and in total.
pub const MAX_FISH: usize = 200_000;
/// `[[group]]` tables in one scene.
pub const MAX_GROUPS: usize = 256;
/// `[[obstacle]]` tables in one scene.
pub const MAX_OBSTACLES: usize = 256;
/// Size classes of one species.
pub const MAX_SIZE_CLASSES: usize = 64;
/// Any cage dimension or obstacle radius (m).
pub const MAX_CAGE_M: f32 = 1_000.0;
/// Physics steps per decision, `floor(dt_res / dt_sim)`.
pub const MAX_STEPS_PER_DECISION: f32 = 1_000.0;
/// Decision interval `dt_res` (s).
pub const MAX_DECISION_INTERVAL_S: f32 = 10.0;
/// Episode length (decisions).
pub const MAX_EPISODE_DECISIONS: u32 = 1_000_000;
/// Chase timeout (s).
pub const MAX_CHASE_TIMEOUT_S: f32 = 3_600.0;
/// Body length at body scale 1 (m).
pub const MAX_BODY_LENGTH_M: f32 = 10.0;
/// Body scale (× the species' body length).
pub const MAX_BODY_SCALE: f32 = 10.0;
/// Any speed or speed change (BL/s).
pub const MAX_SPEED_BL: f32 = 50.0;
/// Any distance given in body lengths: sensing range, collider, visual radius,
/// spawn margin, baseline ranges (BL).
pub const MAX_RANGE_BL: f32 = 100.0;
/// Any light intensity (PAR).
pub const MAX_LIGHT_PAR: f32 = 5_000.0;
/// Light attenuation coefficient `a` of Eq. 4.1 (1/m).
pub const MAX_ATTENUATION: f32 = 100.0;
/// Any temperature preference or steepness (°C), as `[min, max]`.
pub const TEMPERATURE_C: [f32; 2] = [-100.0, 100.0];
/// Water temperature at the surface (°C), as `[min, max]`.
pub const SURFACE_TEMPERATURE_C: [f32; 2] = [-5.0, 50.0];
/// Any reward or baseline weight.
pub const MAX_WEIGHT: f32 = 10_000.0;
/// Size of a configuration file (bytes).
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;
/// Simulated seconds of one command (`--seconds`, `--warmup`): one day.
pub const MAX_SECONDS: f64 = 86_400.0;
/// Evaluation seeds (`compare --seeds`).
pub const MAX_SEEDS: u64 = 1_000;
/// Worker threads (`--threads`).
pub const MAX_THREADS: usize = 1_024;
/// Frames of one render (`--frames`, `--clip-frames`): file names have six digits.
pub const MAX_FRAMES: usize = 1_000_000;
/// Width or height of a rendered image (px).
pub const MAX_IMAGE_PX: u32 = 8_192;
/// Frames per simulated second (`--fps`, `--replay-fps`).
pub const MAX_FPS: f64 = 1_000.0;
/// Ticks simulated before `sensor-view` looks (`--step`).
pub const MAX_TICKS: u64 = 1_000_000;

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

fn range(
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

fn pair(
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

const BL: [f32; 2] = [0.0, MAX_RANGE_BL];
const SPEED: [f32; 2] = [0.0, MAX_SPEED_BL];
const WEIGHT: [f32; 2] = [0.0, MAX_WEIGHT];
const SHARE: [f32; 2] = [0.0, 1.0];
const LIGHT: [f32; 2] = [-(MAX_LIGHT_PAR), MAX_LIGHT_PAR];
const TEMPERATURE: [f32; 2] = [TEMPERATURE_C[0], TEMPERATURE_C[1]];

/// The bounds of a species file (after a scene's overrides).
pub(crate) fn species(s: &SpeciesConfig, path: &Path) -> Result<(), ConfigError> {
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

/// The bounds of a site file (after a scene's overrides).
pub(crate) fn site(s: &SiteConfig, path: &Path) -> Result<(), ConfigError> {
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

/// The bounds of a scene's cage.
pub(crate) fn cage(c: &CageConfig, path: &Path) -> Result<(), ConfigError> {
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
pub(crate) fn obstacles(obstacles: &[ObstacleConfig], path: &Path) -> Result<(), ConfigError> {
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
pub(crate) fn physics(p: &PhysicsConfig, path: &Path) -> Result<(), ConfigError> {
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

/// The bounds of a reward-weights file.
pub(crate) fn rewards(r: &RewardWeights, path: &Path) -> Result<(), ConfigError> {
    let fields = [
        ("boundary_collision", r.boundary_collision),
        ("w_nc", r.w_nc),
        ("w_bd", r.w_bd),
        ("w_nd", r.w_nd),
        ("w_r", r.w_r),
        ("w_s", r.w_s),
        ("pitch_penalty", r.pitch_penalty),
        ("movement_bonus", r.movement_bonus),
        ("w_agg", r.w_agg),
        ("w_tar", r.w_tar),
        ("catch_bonus", r.catch_bonus),
        (
            "extensions.personal_space_penalty",
            r.extensions.personal_space_penalty,
        ),
    ];
    for (field, v) in fields {
        check(path, field, v, WEIGHT, "")?;
    }
    let cap = MAX_NEIGHBOUR_CAP;
    check_count(
        path,
        "neighbour_cap",
        r.neighbour_cap as u64,
        cap as u64,
        "neighbours (0: every neighbour)",
    )?;
    check(
        path,
        "timing.turn_step_deg",
        r.timing.turn_step_deg,
        [0.0, 90.0],
        "°",
    )?;
    check(path, "contacts.kick", r.contacts.kick, SPEED, "m/s")?;
    check(path, "contacts.push", r.contacts.push, SPEED, "m/s")?;
    check(
        path,
        "extensions.personal_space_bl",
        r.extensions.personal_space_bl,
        BL,
        "BL",
    )
}

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
