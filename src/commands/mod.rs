//! One module per command.

pub mod bench;
pub mod compare;
pub mod count;
pub mod eval;
pub mod export;
pub mod image_stats;
pub mod pipeline;
pub mod render;
pub mod replay;
pub mod reproduce;
pub mod scenes;
pub mod sensor_view;
pub mod simulate;
pub mod train;
pub mod train_detector;

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
    let resolved;
    let name = if name.starts_with(crate::pretrained::PREFIX) {
        resolved = crate::pretrained::resolve(name)
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

/// What the built-in main job (`deepfoids` without a command) trains. Chosen by
/// experiment so that, in its own deterministic evaluation, the school swims
/// (mean speed ≥ 0.3 BL/s, the thesis' `v_st`) and stays in the cage (≤ 10
/// boundary collisions per fish-hour) within about 5 minutes on 2 cores; the
/// experiments are in README's "Quickstart". Everything else is the thesis'
/// (Table 4.4's PPO, the pretraining weights of Table 4.1).
pub struct Quickstart {
    /// Scene id.
    pub scene: &'static str,
    pub phase: Phase,
    /// Agent decisions to train.
    pub steps: u64,
    /// Training seed (the evaluation uses its own, derived from it).
    pub seed: u64,
    /// Simulated seconds of the evaluation after training.
    pub eval_seconds: f64,
}

pub const QUICKSTART: Quickstart = Quickstart {
    scene: "seabream_default",
    phase: Phase::Pretrain,
    steps: 600_000,
    seed: 0,
    eval_seconds: 60.0,
};

/// `deepfoids` without a command: train PPO as [`QUICKSTART`] says into
/// `runs/quickstart-ppo-<scene>` (replacing an earlier one), evaluate it, and
/// print what a biologist looks at first: P, M, the school's state, speed,
/// collisions, and where the plots are.
pub fn default_job(dirs: &ConfigDirs) -> Result<()> {
    let q = &QUICKSTART;
    eprintln!(
        "no command given: the quickstart — PPO on {} ({} phase) for {} agent steps, then a {:.0} s evaluation (see --help for the commands)",
        q.scene,
        q.phase.as_str(),
        q.steps,
        q.eval_seconds
    );
    let start = std::time::Instant::now();
    let args = crate::cli::TrainCmd {
        scene: q.scene.into(),
        phase: q.phase,
        init_from: vec![],
        steps: Some(q.steps),
        run_id: Some(format!("quickstart-ppo-{}", q.scene)),
        resume: false,
        force: true,
        opts: crate::cli::TrainOptions {
            algo: crate::cli::Algo::Ppo,
            seed: q.seed,
            runs_dir: "runs".into(),
            backend: deepfoids_learn::Backend::Flex,
            eval_seconds: q.eval_seconds,
            quiet: false,
            budgets: Default::default(),
        },
    };
    let t = train::run(dirs, &args)?;
    let s = t
        .summary
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("the quickstart's evaluation did not run"))?;
    let eval = t.run_dir.join("eval");
    println!(
        "quickstart done in {:.0} s: P {:.2}, M {:.2}, state {} ({}); speed {:.2} BL/s; collisions per fish-hour: boundary {:.1}, neighbour {:.1}",
        start.elapsed().as_secs_f64(),
        s.p_mean,
        s.m_mean,
        s.dominant_state.as_str(),
        crate::report::state_shares(s),
        s.mean_speed_bl,
        s.boundary_collisions_per_fish_hour,
        s.neighbour_collisions_per_fish_hour
    );
    println!(
        "plots: {} and {}; run folder {}",
        eval.join("pm.png").display(),
        eval.join("trajectories.png").display(),
        t.run_dir.display()
    );
    Ok(())
}
