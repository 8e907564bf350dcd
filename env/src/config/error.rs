//! [`ConfigError`]: everything that can go wrong while reading configuration.

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
    pub(super) fn detail(&self) -> String {
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
