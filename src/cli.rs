//! Argument parsing and dispatch.

use crate::commands;
use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use deepfoids_env::{ConfigDirs, Phase};
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(
    name = "deepfoids",
    version,
    about = "Multi-agent reinforcement-learning simulation of farmed fish schools (DeepFoids in Rust)",
    long_about = None
)]
pub struct Cli {
    /// Folder of the TOML configuration [default: ./configs, else $DEEPFOIDS_CONFIGS, else the repository's]
    #[arg(long, global = true, value_name = "DIR")]
    pub configs: Option<PathBuf>,
    /// Reward profile: a folder of `rewards/` in the configuration with the pretrain and transfer weights and SPEC §4/§6.1/§6.2 switches (`thesis`, `legacy`, …) [default: thesis]
    #[arg(long, global = true, value_name = "NAME")]
    pub reward_profile: Option<String>,
    /// Worker threads, 1 to 1024 (0 is refused) [default: one per core]
    #[arg(long, global = true, value_name = "N", value_parser = parse_threads)]
    pub threads: Option<usize>,
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// List the scenes with species, fish count, cage and density
    Scenes,
    /// Run a scene with a policy and write trajectories.csv
    Simulate(SimulateArgs),
    /// Draw what one fish sees: its stacked grid-sensor frames as a PNG
    SensorView(SensorViewArgs),
    /// Judge a school: P, M, state shares, collisions, depth — CSV, JSON and plots
    Eval(EvalArgs),
    /// Train one policy per behaviour of a scene (PPO or SAC)
    Train(TrainCmd),
    /// Pretrain a species in its default scene, then transfer-learn into each of its scenes
    Pipeline(PipelineArgs),
    /// Reproduce the thesis' claims (§4.5): train, evaluate, judge each claim, write a report
    Reproduce(commands::reproduce::ReproduceArgs),
    /// Export a trained policy to ONNX (Unity ML-Agents' interface)
    Export(ExportArgs),
    /// Compare runs (e.g. PPO against SAC): learning curves, reward terms, and a table of evaluations
    Compare(CompareArgs),
    /// Render a labelled image dataset (YOLO, COCO, masks) of a scene driven by a policy
    Render(commands::render::RenderArgs),
    /// Watch a school: one self-contained HTML replay (3D, scrub, follow a fish, P/M), and GIF clips
    Replay(commands::replay::ReplayArgs),
    /// Benchmarks
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
}

/// Options shared by every command that simulates.
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// Scene id (see `deepfoids scenes`) or path to a scene TOML file
    #[arg(long, value_name = "ID|PATH")]
    pub scene: String,
    /// Random seed: fish traits, placement, respawns, chases and random actions
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Reward weights of this phase
    #[arg(long, default_value = "pretrain", value_parser = parse_phase)]
    pub phase: Phase,
}

pub(crate) fn parse_phase(s: &str) -> Result<Phase, String> {
    s.parse()
}

/// `--threads`: 1 to `MAX_THREADS`. 0 is refused rather than read as "all
/// cores" (rayon's meaning) or "one" (what it silently meant before): leaving
/// the option out already means one thread per core.
fn parse_threads(s: &str) -> Result<usize, String> {
    let max = deepfoids_env::limits::MAX_THREADS;
    match s.parse::<usize>() {
        Ok(0) => Err("0 threads cannot run anything; give 1 or more, or leave --threads out for one thread per core".into()),
        Ok(n) if n <= max => Ok(n),
        Ok(n) => Err(format!("{n} is above the limit of {max} threads")),
        Err(_) => Err(format!("`{s}` is not a thread count (1 to {max})")),
    }
}

#[derive(Args, Debug)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Who acts: `random`, `foids`, `foids_table1` (Table 1 as published), `boids`, a shipped policy (`pretrained:<species>`), a run folder (`runs/<id>`) or an exported `.onnx` file
    #[arg(long, default_value = "random")]
    pub policy: String,
    #[command(flatten)]
    pub policy_args: PolicyArgs,
    /// Simulated seconds
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Output folder [default: runs/simulate-<scene>-s<seed>]
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// How a trained policy is loaded and run.
#[derive(Args, Debug, Clone)]
pub struct PolicyArgs {
    /// With a run folder: load this checkpoint step instead of the final policy
    #[arg(long, value_name = "STEP")]
    pub checkpoint: Option<u64>,
    /// With a run folder: sample actions instead of acting with the clipped mean
    #[arg(long)]
    pub stochastic: bool,
}

fn parse_backend(s: &str) -> Result<deepfoids_learn::Backend, String> {
    s.parse()
}

#[derive(Args, Debug)]
pub struct EvalArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Who acts: `foids`, `foids_table1` (Table 1 as published), `boids`, `random`, a shipped policy (`pretrained:<species>`), a run folder (`runs/<id>`) or an exported `.onnx` file
    #[arg(long, default_value = "foids")]
    pub policy: String,
    #[command(flatten)]
    pub policy_args: PolicyArgs,
    /// Simulated seconds recorded
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Simulated seconds run before recording (the school settles from its random start)
    #[arg(long, default_value_t = 0.0)]
    pub warmup: f64,
    /// Output folder [default: runs/eval-<scene>-<policy>-s<seed>]
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Also write replay.html (see `deepfoids replay`) next to the plots
    #[arg(long)]
    pub replay: bool,
    /// Frames per simulated second stored in replay.html (the viewer interpolates between them)
    #[arg(long, default_value_t = 5.0, value_name = "FPS")]
    pub replay_fps: f64,
}

/// The training algorithm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Algo {
    Ppo,
    Sac,
}

#[derive(Args, Debug, Clone)]
pub struct TrainOptions {
    /// Training algorithm
    #[arg(long, value_enum, default_value = "ppo")]
    pub algo: Algo,
    /// Random seed (weights, exploration, environment)
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Folder of the runs
    #[arg(long, default_value = "runs", value_name = "DIR")]
    pub runs_dir: PathBuf,
    /// Compute backend of the training (acting runs on the hand-written kernels)
    #[arg(long, default_value = "flex", value_parser = parse_backend)]
    pub backend: deepfoids_learn::Backend,
    /// Simulated seconds of the deterministic evaluation after training (0: none)
    #[arg(long, default_value_t = 30.0)]
    pub eval_seconds: f64,
    /// No progress bar and no progress lines
    #[arg(long)]
    pub quiet: bool,
    /// Budgets by species, `[pretraining, transfer]`, replacing the training
    /// config's (`reproduce`'s profiles); not a command-line option.
    #[arg(skip)]
    pub budgets: std::collections::BTreeMap<String, [u64; 2]>,
}

#[derive(Args, Debug, Clone)]
pub struct TrainCmd {
    /// Scene id or path
    #[arg(long, value_name = "ID|PATH")]
    pub scene: String,
    /// Reward weights and budget of this phase
    #[arg(long, default_value = "pretrain", value_parser = parse_phase)]
    pub phase: Phase,
    /// Start from the weights of these runs (transfer learning; comma-separated
    /// or repeated, e.g. one per species): each behaviour takes the weights of
    /// a behaviour of the same name, else of the same species; steps start at 0;
    /// `pretrained:<species>` names a shipped policy
    #[arg(long, value_name = "RUN", value_delimiter = ',', value_parser = crate::pretrained::parse_run)]
    pub init_from: Vec<PathBuf>,
    /// Agent decisions to train, per behaviour (each counts its own, as ML-Agents'
    /// max_steps) [default: the thesis' budget for its species and phase]
    #[arg(long)]
    pub steps: Option<u64>,
    /// Run name [default: <algo>-<scene>-<phase>-s<seed>]
    #[arg(long)]
    pub run_id: Option<String>,
    /// Continue the run from its last checkpoint
    #[arg(long)]
    pub resume: bool,
    /// Replace an existing run folder
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    pub opts: TrainOptions,
}

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Run folder
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,
    /// Export this checkpoint step instead of the final policy
    #[arg(long, value_name = "STEP")]
    pub checkpoint: Option<u64>,
    /// Behaviour to export (required when the run has several)
    #[arg(long, value_name = "NAME")]
    pub behaviour: Option<String>,
    /// Output file
    #[arg(long, default_value = "policy.onnx", value_name = "FILE")]
    pub out: PathBuf,
}

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Run folders (two or more); `pretrained:<species>` names a shipped policy
    #[arg(value_name = "RUN", required = true, num_args = 2.., value_parser = crate::pretrained::parse_run)]
    pub runs: Vec<PathBuf>,
    /// Scene to evaluate every run in [default: the first run's]
    #[arg(long, value_name = "ID|PATH")]
    pub scene: Option<String>,
    /// Simulated seconds per evaluation
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Evaluation seeds 0..N, the same for every run
    #[arg(long, default_value_t = 3, value_name = "N")]
    pub seeds: u64,
    /// Weight of the exponential moving average of the curves (TensorBoard's smoothing)
    #[arg(long, default_value_t = 0.6, value_name = "W")]
    pub smoothing: f64,
    /// Output folder
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

#[derive(Args, Debug)]
pub struct PipelineArgs {
    /// Species to train: its default scene, then every scene with only this
    /// species; `all`: every species, then every scene (mixed ones included)
    #[arg(long)]
    pub species: String,
    /// Pretraining budget per behaviour (agent decisions) [default: the thesis' budget]
    #[arg(long)]
    pub pretrain_steps: Option<u64>,
    /// Transfer budget per behaviour and scene [default: the thesis' budget]
    #[arg(long)]
    pub transfer_steps: Option<u64>,
    /// Only these target scenes (comma-separated) [default: all of the species, or all]
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Run name [default: pipeline-<algo>-<species>-s<seed>]
    #[arg(long)]
    pub run_id: Option<String>,
    #[command(flatten)]
    pub opts: TrainOptions,
}

#[derive(Args, Debug)]
pub struct SensorViewArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Index of the fish to look through (0-based)
    #[arg(long, default_value_t = 0)]
    pub fish: usize,
    /// Ticks to simulate (random actions) before looking
    #[arg(long, default_value_t = 10)]
    pub step: u64,
    /// Output PNG
    #[arg(long, default_value = "view.png", value_name = "PNG")]
    pub out: PathBuf,
}

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Environment speed: agent-decisions per second with random actions, sensor included
    Env(BenchEnvArgs),
    /// Training speed: agent-steps per second end to end, and its split
    Train(BenchTrainArgs),
    /// Inference speed of a trained policy: Burn against its ONNX export through tract
    Policy(BenchPolicyArgs),
    /// Dataset rendering speed: frames per second with all labels
    Render(commands::render::BenchRenderArgs),
}

#[derive(Args, Debug)]
pub struct BenchPolicyArgs {
    /// Run folder of the policy
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,
    /// Agents per forward pass
    #[arg(long, default_value_t = 1000)]
    pub agents: usize,
    /// Timed repetitions
    #[arg(long, default_value_t = 10)]
    pub reps: usize,
}

#[derive(Args, Debug)]
pub struct BenchTrainArgs {
    /// Scene id or path
    #[arg(long, default_value = "seabream_default", value_name = "ID|PATH")]
    pub scene: String,
    /// Agent decisions to train, per behaviour
    #[arg(long, default_value_t = 30_000)]
    pub steps: u64,
    /// Training algorithm
    #[arg(long, value_enum, default_value = "ppo")]
    pub algo: Algo,
    /// Compute backend
    #[arg(long, default_value = "flex", value_parser = parse_backend)]
    pub backend: deepfoids_learn::Backend,
    /// PPO's rollout: `ml-agents` or `synchronous` [default: configs/train/ppo.toml's]
    #[arg(long)]
    pub rollout: Option<String>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

#[derive(Args, Debug)]
pub struct BenchEnvArgs {
    /// Scene id or path
    #[arg(long, default_value = "coho_default", value_name = "ID|PATH")]
    pub scene: String,
    /// Simulated seconds to time (after the warm-up)
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Simulated seconds of warm-up, not timed
    #[arg(long, default_value_t = 2.0)]
    pub warmup: f64,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// Parse the command line and run the command.
pub fn run() -> Result<()> {
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("cannot set up the thread pool")?;
    }
    let mut dirs = cli
        .configs
        .clone()
        .map(ConfigDirs::new)
        .unwrap_or_else(ConfigDirs::discover);
    if let Some(profile) = &cli.reward_profile {
        dirs = dirs.with_reward_profile(profile);
    }
    match cli.command {
        None => commands::default_job(&dirs),
        Some(Command::Scenes) => commands::scenes::run(&dirs),
        Some(Command::Simulate(a)) => commands::simulate::run(&dirs, &a),
        Some(Command::SensorView(a)) => commands::sensor_view::run(&dirs, &a),
        Some(Command::Eval(a)) => commands::eval::run(&dirs, &a),
        Some(Command::Train(a)) => commands::train::run(&dirs, &a).map(|_| ()),
        Some(Command::Pipeline(a)) => commands::pipeline::run(&dirs, &a),
        Some(Command::Reproduce(a)) => commands::reproduce::run(&dirs, &a),
        Some(Command::Export(a)) => commands::export::run(&a),
        Some(Command::Compare(a)) => commands::compare::run(&dirs, &a),
        Some(Command::Bench {
            what: BenchCommand::Train(a),
        }) => commands::bench::train(&dirs, &a),
        Some(Command::Bench {
            what: BenchCommand::Env(a),
        }) => commands::bench::env(&dirs, &a),
        Some(Command::Bench {
            what: BenchCommand::Policy(a),
        }) => commands::bench::policy(&a),
        Some(Command::Render(a)) => commands::render::run(&dirs, &a),
        Some(Command::Replay(a)) => commands::replay::run(&dirs, &a),
        Some(Command::Bench {
            what: BenchCommand::Render(a),
        }) => commands::render::bench(&dirs, &a),
    }
}
