//! The training algorithm of a run, as `state.json` and the command line name it.

use serde::{Deserialize, Serialize};

/// The training algorithm of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Algorithm {
    Ppo,
    Sac,
}

impl Algorithm {
    /// Every algorithm, in the order the command line lists them.
    pub const ALL: [Algorithm; 2] = [Algorithm::Ppo, Algorithm::Sac];

    pub fn as_str(&self) -> &'static str {
        match self {
            Algorithm::Ppo => "ppo",
            Algorithm::Sac => "sac",
        }
    }
}

impl std::str::FromStr for Algorithm {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|a| a.as_str() == s)
            .ok_or_else(|| format!("unknown algorithm `{s}`; allowed: ppo, sac"))
    }
}

impl std::fmt::Display for Algorithm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}
