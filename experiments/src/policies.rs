//! Who acts in a scene: a scripted baseline, random actions, a shipped policy
//! (`pretrained:<species>`), a trained run's folder (PPO or SAC, as its
//! `state.json` says) or an exported `.onnx` file.

use crate::pretrained;
use anyhow::{Result, bail};
use deepfoids_env::baselines::{Boids, BoidsConfig, Foids, FoidsConfig};
use deepfoids_env::{ConfigDirs, Env, Phase, Policy, RandomPolicy, Scene};
use deepfoids_learn::Algorithm;
use deepfoids_learn::checkpoint::{BehaviourState, RunState};
use deepfoids_learn::policy::{Actor, ActorPolicy};
use std::path::Path;

/// How a trained policy is loaded and run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PolicyOptions {
    /// With a run folder: load this checkpoint step instead of the final policy.
    pub checkpoint: Option<u64>,
    /// With a run folder: sample actions instead of acting with the clipped mean.
    pub stochastic: bool,
}

/// Load a scene with its reward weights; the error names the file and field.
/// An environment of it must fit into the machine's memory
/// (`deepfoids_env::memory`), checked before anything is allocated.
pub fn load_scene(dirs: &ConfigDirs, id: &str, phase: Phase) -> Result<Scene> {
    load_scene_with(dirs, id, phase, None)
}

/// [`load_scene`] with `fish` fish instead of the scene's own count when given
/// (`--fish-count`; [`Scene::with_fish`]: a scene of one group only).
pub fn load_scene_with(
    dirs: &ConfigDirs,
    id: &str,
    phase: Phase,
    fish: Option<usize>,
) -> Result<Scene> {
    let mut scene = Scene::load(dirs, id, phase)?;
    if let Some(n) = fish {
        scene = scene.with_fish(n)?;
    }
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
    opts: &PolicyOptions,
) -> Result<Box<dyn Policy>> {
    let resolved;
    let name = if name.starts_with(pretrained::PREFIX) {
        resolved = pretrained::resolve(name)
            .map_err(anyhow::Error::msg)?
            .display()
            .to_string();
        resolved.as_str()
    } else {
        name
    };
    let path = std::path::Path::new(name);
    match name {
        "random" => Ok(Box::new(RandomPolicy { seed })),
        "foids" | "foids_table1" => Ok(Box::new(Foids::new(
            FoidsConfig::load(&dirs.baseline(name)?)?,
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
            "unknown policy `{other}`; allowed: random, foids, foids_table1, boids, pretrained:<species> (a shipped policy), a run folder (runs/<id>) or a .onnx file"
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
