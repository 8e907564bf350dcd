//! The learning crates' errors: each says what was wrong, where, and what is allowed.

use crate::algorithm::Algorithm;
use std::path::PathBuf;

/// Everything training, loading or saving a policy can fail with.
#[derive(Debug, thiserror::Error)]
pub enum LearnError {
    /// A loss or parameter became NaN or infinite; the run stops and the last
    /// good checkpoint stays.
    #[error(
        "update {update} of {behaviour}: {what} is not finite; training stopped, the last good checkpoint is kept"
    )]
    NonFinite {
        update: u64,
        behaviour: String,
        what: String,
    },
    /// `--resume` asked for something the run folder cannot give.
    #[error("--resume: {run}: {reason}")]
    Resume { run: PathBuf, reason: String },
    /// A run asked to continue (`--resume`) or to be reused (`reproduce`)
    /// under another reward profile than the one it trained with.
    #[error(
        "{run} trained with reward profile {had}, not {want}: {what} it with --reward-profile {had}, or use another run folder"
    )]
    RewardProfile {
        run: PathBuf,
        had: String,
        want: String,
        what: &'static str,
    },
    /// A policy folder of another algorithm than the one asked for.
    #[error("{path} holds a {found} policy; {wanted} is needed here ({context})")]
    WrongAlgorithm {
        path: PathBuf,
        found: Algorithm,
        wanted: Algorithm,
        context: &'static str,
    },
    /// A policy trained with another network layout.
    #[error(
        "{path} holds networks of encoder layout {found}; this build reads layout {expected} ({why}): retrain the run"
    )]
    Layout {
        path: PathBuf,
        found: u32,
        expected: u32,
        why: &'static str,
    },
    /// A policy whose network size differs from the configuration's.
    #[error(
        "{path}: the network ({found_layers} × {found_hidden}) differs from {config} ({want_layers} × {want_hidden})"
    )]
    Architecture {
        path: PathBuf,
        found_layers: usize,
        found_hidden: usize,
        want_layers: usize,
        want_hidden: usize,
        config: String,
    },
    /// No source for a behaviour among the given runs.
    #[error(
        "no policy for behaviour {behaviour} (species {species}) in {searched}; they hold: {available}"
    )]
    MissingBehaviour {
        behaviour: String,
        species: String,
        searched: String,
        available: String,
    },
    /// A folder that should hold a run or a policy does not.
    #[error("{path}: {reason}")]
    NotARun { path: PathBuf, reason: String },
    /// A file of a run that cannot be read or written (the I/O error is
    /// part of the message, not a `source`: a chain says it once).
    #[error("{path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    /// A file that exists but does not hold what it should.
    #[error("{path}: {reason}")]
    Corrupt { path: PathBuf, reason: String },
    /// Burn could not load or save a module or an optimiser.
    #[error("cannot {action} {path}: {reason}")]
    Record {
        action: &'static str,
        path: PathBuf,
        reason: String,
    },
    /// A run that needs more memory than the machine can give.
    #[error("{config}: {error}")]
    Memory {
        config: String,
        error: deepfoids_env::memory::MemoryError,
    },
    /// A budget too small for a single update (`--allow-no-update` accepts it).
    #[error(
        "behaviour {behaviour} ({agents} agents): a budget of {budget} agent steps makes no update; the first comes after {first} agent steps at the earliest ({fields} in {config}); raise --steps to at least {first} (or --steps-per-fish to at least {first_per_fish}), lower those values, or pass --allow-no-update to run it anyway"
    )]
    NoUpdate {
        behaviour: String,
        agents: usize,
        budget: u64,
        first: u64,
        /// `first` shared among the behaviour's fish, rounded up.
        first_per_fish: u64,
        fields: String,
        config: String,
    },
    #[error(transparent)]
    Config(#[from] deepfoids_env::ConfigError),
    #[error("environment step: {0}")]
    Env(#[from] deepfoids_env::EnvError),
}

impl LearnError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> LearnError {
        let path = path.into();
        move |error| LearnError::Io { path, error }
    }
}

pub type Result<T, E = LearnError> = std::result::Result<T, E>;
