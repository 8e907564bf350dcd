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
//! file, applies a scene's overrides and says serde's errors plainly. This file
//! holds what every kind shares: [`ConfigError`], [`Overrides`] and
//! [`ConfigDirs`], the root folder that finds and loads each kind.

mod range;
mod read;
mod rewards;
mod scene;
mod site;
mod species;

pub use range::Range;
pub use read::read_toml;
pub use rewards::{
    ActionTiming, Contacts, Extensions, NeighbourForm, Phase, RewardTiming, RewardWeights, Timing,
};
pub use scene::{
    CageConfig, Clock, GroupConfig, ObstacleConfig, PhysicsConfig, SceneFile, parse_clock,
};
pub use site::SiteConfig;
pub use species::{SizeClass, SpeciesConfig};

use read::load_with;
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
    /// `field = value` of `path` must lie in `[lo, hi]` (NaN does not).
    pub fn check_within(
        path: &Path,
        field: &str,
        value: f32,
        lo: f32,
        hi: f32,
    ) -> Result<(), Self> {
        if (lo..=hi).contains(&value) {
            return Ok(());
        }
        Err(Self::invalid(
            path,
            field,
            format!("must lie in [{lo}, {hi}]"),
        ))
    }

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
