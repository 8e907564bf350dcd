//! The TOML configuration: species, sites, scenes and reward weights.
//!
//! The files live under a config root (`configs/` in the repository):
//! `species/<name>.toml`, `sites/<name>.toml`, `scenes/<id>.toml` and
//! `rewards/<profile>/<phase>.toml`. A user adds a species, a site or a scene by
//! adding a file. Every struct rejects unknown keys, and every error names the
//! file and the field. Defaults live in code (`#[serde(default)]`), each
//! documented with its unit and source.
//!
//! One module per file kind, each type with its own checks:
//!
//! | file | type | module |
//! |---|---|---|
//! | `species/<name>.toml` | [`SpeciesConfig`] with its [`SizeClass`]es | `species` |
//! | `sites/<name>.toml` | [`SiteConfig`] | `site` |
//! | `scenes/<id>.toml` | [`SceneFile`]: cage, obstacles, groups, physics; its [`Clock`] | `scene` |
//! | `rewards/<profile>/<phase>.toml` | [`RewardWeights`] with timing, contacts and extensions | `rewards` |
//!
//! `range` holds [`Range`], the fixed-or-drawn value they share; `read` reads a
//! file, applies a scene's [`Overrides`] and says serde's errors plainly;
//! `error` holds [`ConfigError`]; `check` the bounds helpers every kind's
//! checks use, with the limits of [`crate::limits`]. This file holds
//! [`ConfigDirs`], the root folder that finds and loads each kind.

mod check;
mod error;
mod range;
mod read;
mod rewards;
mod scene;
mod site;
mod species;

pub use check::number;
pub(crate) use check::{Param, check_count, params, positive_in};
pub use error::ConfigError;
pub use range::Range;
pub use read::{Overrides, read_toml};
pub use rewards::{
    ActionTiming, Contacts, Extensions, HeadingOf, MirrorRedraw, NeighbourForm, NeighbourWeight,
    PersonalSpaceOf, Phase, RewardTiming, RewardWeights, Timing,
};
pub use scene::{
    CageConfig, Clock, GroupConfig, ObstacleConfig, PhysicsConfig, SceneFile, parse_clock,
};
pub(crate) use scene::{cage_bounds, obstacle_bounds, physics_bounds, steps_per_decision};
pub use site::SiteConfig;
pub use species::{SizeClass, SpeciesConfig};

use read::load_with;
use std::path::{Path, PathBuf};

/// The root folder of the TOML configuration.
#[derive(Clone, Debug)]
pub struct ConfigDirs {
    pub root: PathBuf,
    /// The reward profile: a folder `rewards/<profile>/` with `pretrain.toml`
    /// and `transfer.toml` (SPEC §6.2). Default [`DEFAULT_REWARD_PROFILE`].
    pub reward_profile: String,
}

/// The reward profile used unless `--reward-profile` names another
/// (docs/reward-profiles.md): the profile that held the most claims in a
/// `quick` reproduction (docs/reproduction/NOTES.md, session 34), with which
/// the shipped policies are trained.
pub const DEFAULT_REWARD_PROFILE: &str = "mean_then_budget_space20";

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
    /// The other phase's file is read and checked as well (a profile is
    /// refused whole), and both must agree on what the policy sees.
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
        let load = |phase: Phase| -> Result<(PathBuf, RewardWeights), ConfigError> {
            let path = self.named(
                "reward weights",
                &format!("rewards/{profile}"),
                phase.as_str(),
            )?;
            let weights: RewardWeights = read_toml(&path)?;
            weights.check_bounds(&path)?;
            Ok((path, weights))
        };
        let (path, weights) = load(phase)?;
        // The other phase's file is checked too: a broken transfer file is
        // refused before a pretraining of hours, not after it.
        let (other_path, o) = load(match phase {
            Phase::Pretrain => Phase::Transfer,
            Phase::Transfer => Phase::Pretrain,
        })?;
        // What the policy sees must not change between the phases: a
        // transfer starts from the pretrained weights.
        if o.extensions.heading_of != weights.extensions.heading_of {
            return Err(ConfigError::Invalid {
                path,
                field: "extensions.heading_of".into(),
                message: format!(
                    "{} here but {} in {}: what the policy sees must be the same in \
                     both phases of a profile",
                    weights.extensions.heading_of.as_str(),
                    o.extensions.heading_of.as_str(),
                    other_path.display()
                ),
            });
        }
        Ok(weights)
    }
}
