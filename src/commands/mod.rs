//! One module per command.

pub mod bench;
pub mod compare;
pub mod eval;
pub mod export;
pub mod pipeline;
pub mod render;
pub mod replay;
pub mod scenes;
pub mod sensor_view;
pub mod simulate;
pub mod train;

use crate::cli::PolicyArgs;
use anyhow::{Result, bail};
use deepfoids_env::baselines::{Boids, BoidsConfig, Foids, FoidsConfig};
use deepfoids_env::{ConfigDirs, Env, Phase, Policy, RandomPolicy, Scene};
use deepfoids_learn::Algorithm;
use deepfoids_learn::checkpoint::{BehaviourState, RunState};
use deepfoids_learn::policy::{Actor, ActorPolicy};
use std::path::Path;

/// Load a scene with its reward weights; the error names the file and field.
/// An environment of it must fit into the machine's memory
/// (`deepfoids_env::memory`), checked before anything is allocated.
pub fn load_scene(dirs: &ConfigDirs, id: &str, phase: Phase) -> Result<Scene> {
    let scene = Scene::load(dirs, id, phase)?;
    deepfoids_env::memory::check_env(&scene)?;
    Ok(scene)
}

/// The policy named on the command line: a scripted baseline (parameters from
/// `configs/baselines/<name>.toml`), random actions, or a trained run's folder.
pub fn make_policy(
    dirs: &ConfigDirs,
    name: &str,
    seed: u64,
    env: &Env,
    opts: &PolicyArgs,
) -> Result<Box<dyn Policy>> {
    let path = std::path::Path::new(name);
    match name {
        "random" => Ok(Box::new(RandomPolicy { seed })),
        "foids" => Ok(Box::new(Foids::new(
            FoidsConfig::load(&dirs.baseline("foids")?)?,
            seed,
        ))),
        "boids" => Ok(Box::new(Boids::new(BoidsConfig::load(
            &dirs.baseline("boids")?,
        )?))),
        _ if path.is_file() && path.extension().is_some_and(|e| e == "onnx") => {
            let p = deepfoids_onnx::OnnxPolicy::load(path, opts.stochastic)?;
            deepfoids_onnx::check_species(&p, env)?;
            Ok(Box::new(p))
        }
        _ if path.is_dir() => Ok(Box::new(load_trained(
            path,
            opts.checkpoint,
            env,
            !opts.stochastic,
            seed,
        )?)),
        other if path.extension().is_some_and(|e| e == "onnx") || other.contains('/') => bail!(
            "policy `{other}` does not exist (a run folder or a .onnx file was expected there)"
        ),
        other => bail!(
            "unknown policy `{other}`; allowed: random, foids, boids, a run folder (runs/<id>) or a .onnx file"
        ),
    }
}

/// Behaviour `source` of a policy folder as an actor, PPO or SAC as its
/// `state.json` says.
pub fn load_actor(
    dir: &Path,
    state: &RunState,
    source: &BehaviourState,
) -> deepfoids_learn::Result<Box<dyn Actor>> {
    match state.algo {
        Algorithm::Ppo => deepfoids_ppo::load_actor(dir, state, source),
        Algorithm::Sac => deepfoids_sac::load_actor(dir, state, source),
    }
}

/// The policy of a run folder (its `final/`, or checkpoint `step`), PPO or SAC
/// as its `state.json` says; it acts on the hand-written kernels.
pub fn load_trained(
    run: &Path,
    step: Option<u64>,
    env: &Env,
    deterministic: bool,
    seed: u64,
) -> Result<ActorPolicy> {
    Ok(ActorPolicy::load(
        run,
        step,
        env,
        deterministic,
        seed,
        &load_actor,
    )?)
}

/// Agent decisions of the built-in main job (a few minutes on 2 cores).
pub const QUICKSTART_STEPS: u64 = 150_000;

/// `deepfoids` without a command: train PPO on the seabream default scene with a
/// short budget into `runs/quickstart-ppo-seabream_default` (replacing an earlier
/// one), evaluate it, and print P, M and the learning curve's start and end.
pub fn default_job(dirs: &ConfigDirs) -> Result<()> {
    eprintln!(
        "no command given: the quickstart — PPO on seabream_default for {QUICKSTART_STEPS} agent steps (see --help for the commands)"
    );
    let args = crate::cli::TrainCmd {
        scene: "seabream_default".into(),
        phase: Phase::Pretrain,
        init_from: vec![],
        steps: Some(QUICKSTART_STEPS),
        run_id: Some("quickstart-ppo-seabream_default".into()),
        resume: false,
        force: true,
        opts: crate::cli::TrainOptions {
            algo: crate::cli::Algo::Ppo,
            seed: 0,
            runs_dir: "runs".into(),
            backend: deepfoids_learn::Backend::Flex,
            eval_seconds: 60.0,
            quiet: false,
        },
    };
    let t = train::run(dirs, &args)?;
    if let Some(s) = &t.summary {
        println!(
            "quickstart done: P {:.3}, M {:.3} ({}); run folder {}",
            s.p_mean,
            s.m_mean,
            s.dominant_state.as_str(),
            t.run_dir.display()
        );
    }
    Ok(())
}
