//! A behaviour's training budget (ML-Agents' `max_steps`, per behaviour):
//! agent decisions, all of its fish together — or decisions per fish, so that
//! scenes of 38 and of 587 fish can be trained equally long per fish
//! (docs/training.md, "a budget is shared among the fish").

/// How long a behaviour trains, when its species' budget is not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Budget {
    /// Agent decisions of the behaviour, its fish together (`--steps`).
    Steps(u64),
    /// Decisions of each fish (`--steps-per-fish`): a behaviour of `n` fish
    /// trains `n ×` this many agent decisions.
    PerFish(u64),
}

impl Budget {
    /// The agent decisions a behaviour of `fish` fish trains.
    pub fn steps(self, fish: usize) -> u64 {
        match self {
            Budget::Steps(s) => s,
            Budget::PerFish(d) => d.saturating_mul(fish as u64),
        }
    }

    /// The agent decisions a behaviour of `fish` fish trains under `budget`,
    /// or `species` (its species' budget for the phase) when none is given.
    pub fn resolve(budget: Option<Budget>, fish: usize, species: impl FnOnce() -> u64) -> u64 {
        budget.map_or_else(species, |b| b.steps(fish))
    }
}

impl From<u64> for Budget {
    fn from(steps: u64) -> Self {
        Budget::Steps(steps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_per_fish_budget_grows_with_the_school() {
        assert_eq!(Budget::PerFish(13_630).steps(587), 8_000_810);
        assert_eq!(Budget::PerFish(13_630).steps(38), 517_940);
        assert_eq!(Budget::Steps(1_000_000).steps(587), 1_000_000);
        assert_eq!(Budget::PerFish(u64::MAX).steps(2), u64::MAX);
        assert_eq!(Budget::resolve(Some(Budget::PerFish(3)), 10, || 7), 30);
        assert_eq!(Budget::resolve(None, 10, || 7), 7);
    }
}
