//! A resolved scene: the scene file with its site, species and reward weights
//! loaded, its groups merged into behaviours (species × size class), and all
//! values checked. This is what [`crate::Env::new`] takes, and what a run
//! folder stores as its resolved configuration.

use crate::cage::Cage;
use crate::config::{
    CageConfig, Clock, ConfigDirs, ConfigError, ObstacleConfig, Overrides, Phase, PhysicsConfig,
    Range, RewardWeights, SceneFile, SiteConfig, SpeciesConfig, parse_clock, read_toml,
};
use crate::limits;
use deepfoids_sensors::Obstacle;
use glam::Vec3;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// One behaviour: the fish of one species and size class, sharing a policy.
#[derive(Clone, Debug, Serialize)]
pub struct BehaviourSpec {
    /// `<species>_<size class>`, e.g. `coho_regular`.
    pub name: String,
    pub species: SpeciesConfig,
    pub size_class: String,
    /// Number of fish.
    pub count: usize,
    /// Body scales drawn per fish, one entry per group `(count, range)`.
    pub body_scales: Vec<(usize, Range)>,
    pub light_lpref: Range,
    pub light_hpref: Range,
}

impl BehaviourSpec {
    /// Physics steps per decision, `k = floor(dt_res / dt_sim)` (SPEC §3).
    pub fn steps_per_decision(&self, dt_sim: f32) -> usize {
        // A tiny epsilon keeps 0.1 / 0.02 = 4.9999… from flooring to 4.
        ((self.species.decision_interval / dt_sim) + 1e-4)
            .floor()
            .max(1.0) as usize
    }
}

/// The scene file's sizes, counts and durations within [`crate::limits`],
/// checked before anything else is loaded or allocated.
fn check_sizes(file: &SceneFile, path: &Path) -> Result<(), ConfigError> {
    let n_groups = file.groups.len() as u64;
    crate::config::check_count(path, "group", n_groups, limits::MAX_GROUPS as u64, "groups")?;
    let max = limits::MAX_FISH as u64;
    let mut total = 0u64;
    for (gi, g) in file.groups.iter().enumerate() {
        crate::config::check_count(
            path,
            &format!("group[{gi}].count"),
            g.count as u64,
            max,
            "fish",
        )?;
        total += g.count as u64;
    }
    if total > max {
        return Err(ConfigError::Limit {
            path: path.to_path_buf(),
            field: "the groups' counts".into(),
            value: format!("{total} fish in all"),
            above: true,
            limit: format!("{max} fish in a scene"),
        });
    }
    crate::config::cage_bounds(&file.cage, path)?;
    crate::config::obstacle_bounds(&file.obstacles, path)?;
    crate::config::physics_bounds(&file.physics, path)
}

/// A fully loaded scene.
#[derive(Clone, Debug, Serialize)]
pub struct Scene {
    /// Scene id (the file stem).
    pub id: String,
    /// The file it came from.
    pub source: PathBuf,
    pub description: String,
    pub site: SiteConfig,
    pub clock: Clock,
    pub cage_config: CageConfig,
    pub obstacles: Vec<ObstacleConfig>,
    pub behaviours: Vec<BehaviourSpec>,
    pub physics: PhysicsConfig,
    pub phase: Phase,
    /// The reward profile the weights come from (`rewards/<profile>/`).
    pub reward_profile: String,
    pub rewards: RewardWeights,
}

impl Scene {
    /// Load scene `id_or_path` with the reward weights of `phase`.
    pub fn load(dirs: &ConfigDirs, id_or_path: &str, phase: Phase) -> Result<Self, ConfigError> {
        let path = dirs.scene_path(id_or_path)?;
        let file: SceneFile = read_toml(&path)?;
        let id = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("scene")
            .to_string();
        check_sizes(&file, &path)?;
        let site = dirs.site(
            &file.site,
            Some(Overrides {
                file: &path,
                section: "site_overrides",
                table: &file.site_overrides,
            }),
        )?;
        let clock = parse_clock(&path, &file.date, &file.time, file.clock_runs)?;
        let rewards = dirs.rewards(phase)?;

        if file.groups.is_empty() {
            return Err(ConfigError::invalid(
                &path,
                "group",
                "a scene needs at least one [[group]] of fish",
            ));
        }
        if let Some(unknown) = file
            .species_overrides
            .keys()
            .find(|k| !file.groups.iter().any(|g| &g.species == *k))
        {
            return Err(ConfigError::invalid(
                &path,
                format!("species_overrides.{unknown}"),
                "names a species that no group uses",
            ));
        }
        let mut behaviours: Vec<BehaviourSpec> = Vec::new();
        for (gi, g) in file.groups.iter().enumerate() {
            if g.count == 0 {
                return Err(ConfigError::invalid(
                    &path,
                    format!("group[{gi}].count"),
                    "must be at least 1",
                ));
            }
            let section = format!("species_overrides.{}", g.species);
            let species = dirs.species(
                &g.species,
                file.species_overrides
                    .get(&g.species)
                    .map(|table| Overrides {
                        file: &path,
                        section: &section,
                        table,
                    }),
            )?;
            let class = species.size_classes.get(&g.size_class).ok_or_else(|| {
                ConfigError::invalid(
                    &path,
                    format!("group[{gi}].size_class"),
                    format!(
                        "`{}` is not a size class of {}; allowed: {}",
                        g.size_class,
                        g.species,
                        species
                            .size_classes
                            .keys()
                            .cloned()
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )
            })?;
            let scale = g.body_scale.unwrap_or(class.body_scale);
            let (lo, hi) = scale.bounds();
            if !(lo > 0.0 && lo <= hi && hi.is_finite()) {
                return Err(ConfigError::invalid(
                    &path,
                    format!("group[{gi}].body_scale"),
                    "must be positive and ordered",
                ));
            }
            let name = format!("{}_{}", g.species, g.size_class);
            match behaviours.iter_mut().find(|b| b.name == name) {
                Some(b) => {
                    b.count += g.count;
                    b.body_scales.push((g.count, scale));
                }
                None => behaviours.push(BehaviourSpec {
                    name,
                    size_class: g.size_class.clone(),
                    count: g.count,
                    body_scales: vec![(g.count, scale)],
                    light_lpref: class.light_lpref,
                    light_hpref: class.light_hpref,
                    species,
                }),
            }
        }
        let scene = Scene {
            id,
            source: path.clone(),
            description: file.description,
            site,
            clock,
            cage_config: file.cage,
            obstacles: file.obstacles,
            behaviours,
            physics: file.physics,
            phase,
            reward_profile: dirs.reward_profile.clone(),
            rewards,
        };
        scene.validate(&path)?;
        Ok(scene)
    }

    /// This scene with `fish` fish instead of its own count (`--fish-count`): a lone
    /// fish, or the same cage at another density. Only a scene of one group of
    /// fish can be resized, since how many of each group there should be is
    /// not for a single number to say; the count must be 1 to
    /// [`limits::MAX_FISH`]. The error names the scene file.
    pub fn with_fish(mut self, fish: usize) -> Result<Self, ConfigError> {
        let groups: usize = self.behaviours.iter().map(|b| b.body_scales.len()).sum();
        if groups != 1 {
            return Err(ConfigError::invalid(
                &self.source,
                "group",
                format!(
                    "--fish-count resizes a scene of one [[group]] of fish; this one has {groups} groups \
                     ({}), so write a scene file with the counts you want",
                    self.behaviours
                        .iter()
                        .map(|b| format!("{} {}", b.count, b.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        if fish == 0 || fish > limits::MAX_FISH {
            return Err(ConfigError::invalid(
                &self.source,
                "group[0].count",
                format!("--fish-count must be 1 to {}, got {fish}", limits::MAX_FISH),
            ));
        }
        let b = &mut self.behaviours[0];
        b.count = fish;
        b.body_scales[0].0 = fish;
        Ok(self)
    }

    fn validate(&self, path: &Path) -> Result<(), ConfigError> {
        let p = &self.physics;
        let positive = |v: f32, field: &str| crate::config::positive_in(path, field, v);
        match self.cage_config {
            CageConfig::Cube { edge } => positive(edge, "cage.edge")?,
            CageConfig::Box {
                width,
                length,
                height,
            } => {
                positive(width, "cage.width")?;
                positive(length, "cage.length")?;
                positive(height, "cage.height")?;
            }
            CageConfig::Octagon { edge, height } => {
                positive(edge, "cage.edge")?;
                positive(height, "cage.height")?;
            }
        }
        positive(p.dt_sim, "physics.dt_sim")?;
        positive(p.max_turn_deg, "physics.max_turn_deg")?;
        positive(p.chase_timeout, "physics.chase_timeout")?;
        ConfigError::check_within(path, "physics.roll_clamp_deg", p.roll_clamp_deg, 0.0, 90.0)?;
        ConfigError::check_within(path, "physics.repulsion", p.repulsion, 0.0, 1.0)?;
        ConfigError::check_within(
            path,
            "physics.chase_probability",
            p.chase_probability,
            0.0,
            1.0,
        )?;
        if p.max_episode_decisions == 0 {
            return Err(ConfigError::invalid(
                path,
                "physics.max_episode_decisions",
                "must be at least 1",
            ));
        }
        // (`spawn_margin_bl` is bounded to [0, 100] by `limits::physics`.)
        if !(0.0..90.0).contains(&p.spawn_pitch_deg) {
            return Err(ConfigError::invalid(
                path,
                "physics.spawn_pitch_deg",
                format!("must lie in [0, 90) degrees, got {}", p.spawn_pitch_deg),
            ));
        }
        for b in &self.behaviours {
            crate::config::steps_per_decision(
                p.dt_sim,
                b.species.decision_interval,
                &b.species.name,
                path,
            )?;
            if b.species.decision_interval < p.dt_sim {
                return Err(ConfigError::invalid(
                    path,
                    "physics.dt_sim",
                    format!(
                        "{} s is longer than the decision interval of {} ({} s)",
                        p.dt_sim, b.species.name, b.species.decision_interval
                    ),
                ));
            }
        }
        // Every fish must fit inside the cage with its spawn margin.
        let cage = Cage::new(self.cage_config);
        let room = cage.inner_radius();
        for b in &self.behaviours {
            let max_bl = b.species.body_length
                * b.body_scales
                    .iter()
                    .map(|(_, r)| r.bounds().1)
                    .fold(0.0, f32::max);
            let need = (Vec3::from(b.species.collider_bl) * 0.5 * max_bl).length()
                + p.spawn_margin_bl * max_bl;
            if need >= room {
                return Err(ConfigError::invalid(
                    path,
                    "cage",
                    format!(
                        "too small for {} (a fish needs {need:.2} m of clearance, the cage offers {room:.2} m)",
                        b.name
                    ),
                ));
            }
        }
        for (i, o) in self.obstacles().iter().enumerate() {
            let centre = match *o {
                Obstacle::Sphere { center, radius } => {
                    positive(radius, &format!("obstacle[{i}].radius"))?;
                    center
                }
                Obstacle::Cylinder {
                    x,
                    z,
                    radius,
                    y_min,
                    y_max,
                } => {
                    positive(radius, &format!("obstacle[{i}].radius"))?;
                    if y_min >= y_max {
                        return Err(ConfigError::invalid(
                            path,
                            format!("obstacle[{i}].y"),
                            "must be [min, max] with min < max",
                        ));
                    }
                    Vec3::new(x, (y_min + y_max) / 2.0, z)
                }
            };
            if cage.clearance(centre) <= 0.0 {
                return Err(ConfigError::invalid(
                    path,
                    format!("obstacle[{i}]"),
                    "its centre must lie inside the cage",
                ));
            }
        }
        Ok(())
    }

    /// The cage geometry.
    pub fn cage(&self) -> Cage {
        Cage::new(self.cage_config)
    }

    /// The obstacles as geometry.
    pub fn obstacles(&self) -> Vec<Obstacle> {
        self.obstacles
            .iter()
            .map(|o| match *o {
                ObstacleConfig::Sphere { center, radius } => Obstacle::Sphere {
                    center: Vec3::from(center),
                    radius,
                },
                ObstacleConfig::Cylinder { center, radius, y } => Obstacle::Cylinder {
                    x: center[0],
                    z: center[1],
                    radius,
                    y_min: y[0],
                    y_max: y[1],
                },
            })
            .collect()
    }

    /// Total number of fish.
    pub fn fish_count(&self) -> usize {
        self.behaviours.iter().map(|b| b.count).sum()
    }

    /// Stocking density (fish/m³).
    pub fn density(&self) -> f32 {
        self.fish_count() as f32 / self.cage().volume()
    }

    /// Species names, in order of first appearance.
    pub fn species_names(&self) -> Vec<String> {
        let mut v: Vec<String> = Vec::new();
        for b in &self.behaviours {
            if !v.contains(&b.species.name) {
                v.push(b.species.name.clone());
            }
        }
        v
    }

    /// The resolved scene as TOML (for run folders).
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self)
            .unwrap_or_else(|e| format!("# could not serialise the scene: {e}\n"))
    }
}
