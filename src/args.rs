//! Options that several commands share, and the parsers of option values.
//! Each command's own options live beside it in `commands/`.

use clap::Args;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use deepfoids_env::{ConfigDirs, Phase, Scene};
use deepfoids_experiments::PolicyOptions;
use deepfoids_experiments::evaluate::RunArgs;
use deepfoids_experiments::policies::load_scene_with;
use deepfoids_experiments::training::TrainOptions;
use deepfoids_learn::{Algorithm, Backend};
use std::fmt::Display;
use std::num::{IntErrorKind, ParseIntError};
use std::path::PathBuf;
use std::str::FromStr;

/// Options shared by every command that simulates.
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// Scene id (see `deepfoids scenes`) or path to a scene TOML file
    #[arg(long, value_name = "ID|PATH")]
    pub scene: String,
    /// Random seed: fish traits, placement, respawns, chases and random actions
    #[arg(value_parser = whole::<u64>, long, default_value_t = 0)]
    pub seed: u64,
    /// Reward weights of this phase
    #[arg(long, default_value = "pretrain", value_parser = parse_phase)]
    pub phase: Phase,
    /// Swim this many fish instead of the scene's count (a scene of one group
    /// only): `--fish-count 1` shows a lone fish's habits, other counts another density
    #[arg(long, value_name = "N", value_parser = whole::<usize>)]
    pub fish_count: Option<usize>,
}

impl SceneArgs {
    /// The scene with the reward weights of `--phase`, resized by `--fish-count`.
    pub fn load(&self, dirs: &ConfigDirs) -> anyhow::Result<Scene> {
        load_scene_with(dirs, &self.scene, self.phase, self.fish_count)
    }

    /// The scene's part of a default output folder's name: its id, then
    /// `-n<N>` when `--fish-count` resized it.
    pub fn label(&self, id: &str) -> String {
        match self.fish_count {
            Some(n) => format!("{id}-n{n}"),
            None => id.to_string(),
        }
    }
}

/// Who acts, and how a trained policy is loaded and run.
#[derive(Args, Debug, Clone)]
pub struct PolicyArgs {
    /// Who acts: `foids`, `foids_table1` (Table 1 as published), `boids`, `random`, a shipped
    /// policy (`pretrained:<species>`, `pretrained:<species>/<scene>`), a run folder
    /// (`runs/<id>`) or an exported `.onnx` file [default: `foids`; `simulate`: `random`]
    #[arg(long, value_name = "POLICY")]
    pub policy: Option<String>,
    /// With a run folder: load this checkpoint step instead of the final policy
    #[arg(value_parser = whole::<u64>, long, value_name = "STEP")]
    pub checkpoint: Option<u64>,
    /// Act with the policy's mean (clipped) instead of sampling from it; sampled
    /// actions are the default, as Unity ML-Agents 1.x inference (the thesis') did
    #[arg(long)]
    pub deterministic: bool,
    /// Sample actions (the default; kept so that older scripts still run)
    #[arg(long, hide = true, conflicts_with = "deterministic")]
    pub stochastic: bool,
    /// With a run folder that has no final policy yet (still training, or
    /// stopped): load its newest checkpoint; the outputs record its step
    #[arg(long, conflicts_with = "checkpoint")]
    pub latest: bool,
}

impl PolicyArgs {
    /// The policy that acts (`--policy`, else the command's `default`) and
    /// these options with `--latest` replaced by the step of its newest
    /// checkpoint, so that everything recorded names the exact checkpoint.
    pub fn resolve(&self, default: &str) -> anyhow::Result<(String, PolicyArgs)> {
        let policy = self.policy.clone().unwrap_or_else(|| default.to_string());
        let mut args = self.clone();
        if args.latest {
            let run = std::path::Path::new(&policy);
            if !run.is_dir() {
                anyhow::bail!("--latest needs a run folder as --policy, not `{policy}`");
            }
            args.checkpoint = Some(deepfoids_learn::checkpoint::latest_checkpoint(run)?);
            args.latest = false;
        }
        Ok((policy, args))
    }

    pub fn options(&self) -> PolicyOptions {
        PolicyOptions {
            checkpoint: self.checkpoint,
            stochastic: !self.deterministic,
        }
    }
}

/// The options of a training (`train`, `pipeline`).
#[derive(Args, Debug, Clone)]
pub struct TrainOptionArgs {
    /// Training algorithm
    #[arg(long, default_value = "ppo", value_parser = algorithm())]
    pub algo: Algorithm,
    /// Random seed (weights, exploration, environment)
    #[arg(value_parser = whole::<u64>, long, default_value_t = 0)]
    pub seed: u64,
    /// Folder of the runs
    #[arg(long, default_value = "runs", value_name = "DIR")]
    pub runs_dir: PathBuf,
    /// Compute backend of the training (acting runs on the hand-written kernels)
    #[arg(long, default_value = "flex", value_parser = parse_backend)]
    pub backend: Backend,
    /// Simulated seconds of the evaluation after training, with sampled actions (0: none)
    #[arg(long, default_value_t = 30.0)]
    pub eval_seconds: f64,
    /// No progress bar and no progress lines
    #[arg(long)]
    pub quiet: bool,
    /// Start even if the budget is too small for a single update (a run that
    /// would learn nothing is refused otherwise)
    #[arg(long)]
    pub allow_no_update: bool,
}

impl TrainOptionArgs {
    pub fn options(&self) -> TrainOptions {
        TrainOptions {
            algo: self.algo,
            seed: self.seed,
            runs_dir: self.runs_dir.clone(),
            backend: self.backend,
            eval_seconds: self.eval_seconds,
            quiet: self.quiet,
            budgets: Default::default(),
            allow_no_update: self.allow_no_update,
        }
    }
}

/// The values that run a simulation again (`summary.json`, `simulate.json`).
pub fn rerun(
    scene: &SceneArgs,
    policy: &str,
    opts: &PolicyArgs,
    warmup: f64,
    seconds: f64,
) -> RunArgs {
    RunArgs {
        scene: scene.scene.clone(),
        phase: scene.phase.as_str().to_string(),
        seed: scene.seed,
        policy: policy.to_string(),
        checkpoint: opts.checkpoint,
        stochastic: !opts.deterministic,
        warmup,
        seconds,
        fish: scene.fish_count,
    }
}

/// Back to the options, for loading the scene and policy again.
pub fn from_rerun(run: &RunArgs) -> anyhow::Result<(SceneArgs, PolicyArgs)> {
    Ok((
        SceneArgs {
            scene: run.scene.clone(),
            seed: run.seed,
            phase: run
                .phase
                .parse()
                .map_err(|e| anyhow::anyhow!("phase `{}`: {e}", run.phase))?,
            fish_count: run.fish,
        },
        PolicyArgs {
            policy: Some(run.policy.clone()),
            checkpoint: run.checkpoint,
            deterministic: !run.stochastic,
            stochastic: false,
            latest: false,
        },
    ))
}

/// A whole-number option value. A negative one (the command line lets it
/// through as a value, see `cli::negative_numbers`) is refused with the
/// range — "must be ≥ 0, got -5" — rather than clap's "unexpected argument"
/// or "invalid digit found in string".
pub fn whole<T>(s: &str) -> Result<T, String>
where
    T: FromStr<Err = ParseIntError> + Bounded,
{
    s.trim().parse::<T>().map_err(|e| match e.kind() {
        _ if s.trim().parse::<f64>().is_ok_and(|v| v < 0.0) => {
            format!("must be ≥ 0, got {s}")
        }
        IntErrorKind::PosOverflow => format!("must be at most {}, got {s}", T::MAX),
        _ => format!("must be a whole number from 0 to {}, got `{s}`", T::MAX),
    })
}

/// The largest value of an unsigned integer type, for [`whole`]'s messages.
pub trait Bounded: Display {
    const MAX: Self;
}

impl Bounded for u32 {
    const MAX: Self = u32::MAX;
}
impl Bounded for u64 {
    const MAX: Self = u64::MAX;
}
impl Bounded for usize {
    const MAX: Self = usize::MAX;
}

pub fn parse_phase(s: &str) -> Result<Phase, String> {
    s.parse()
}

pub fn parse_backend(s: &str) -> Result<Backend, String> {
    s.parse()
}

/// `--algo`: `ppo` or `sac`, listed in `--help` and in the error.
pub fn algorithm() -> impl TypedValueParser<Value = Algorithm> {
    PossibleValuesParser::new(Algorithm::ALL.map(|a| a.as_str()))
        .try_map(|s| s.parse::<Algorithm>())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_numbers_say_their_range() {
        assert_eq!(whole::<u64>("7"), Ok(7));
        assert_eq!(whole::<u64>("-5"), Err("must be ≥ 0, got -5".into()));
        assert_eq!(whole::<u32>("-0.5"), Err("must be ≥ 0, got -0.5".into()));
        assert_eq!(
            whole::<u32>("5000000000"),
            Err("must be at most 4294967295, got 5000000000".into())
        );
        assert_eq!(
            whole::<u32>("1.5"),
            Err("must be a whole number from 0 to 4294967295, got `1.5`".into())
        );
    }
}
