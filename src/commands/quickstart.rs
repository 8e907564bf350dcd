//! `deepfoids` without a command: the quickstart.

use super::train::TrainArgs;
use crate::args::TrainOptionArgs;
use anyhow::Result;
use deepfoids_env::{ConfigDirs, Phase};
use deepfoids_experiments::evaluate::state_shares;
use deepfoids_learn::{Algorithm, Backend};

/// What the built-in main job (`deepfoids` without a command) trains. Chosen by
/// experiment so that, in evaluations with sampled actions, the school swims
/// (mean speed ≥ 0.3 BL/s, the thesis' `v_st`) and stays in the cage (≤ 10
/// boundary collisions per fish-hour, averaged over evaluation seeds) within
/// 5 minutes on 2 cores; the experiments are in docs/quickstart.md. Everything else is the thesis'
/// (Table 4.4's PPO, the pretraining weights of Table 4.1, the `thesis` reward
/// profile: under the default profile the same run hits the net 168 times per
/// fish-hour).
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
    /// Reward profile, unless `--reward-profile` names another.
    pub reward_profile: &'static str,
}

pub const QUICKSTART: Quickstart = Quickstart {
    scene: "seabream_default",
    phase: Phase::Pretrain,
    steps: 1_000_000,
    seed: 0,
    eval_seconds: 60.0,
    reward_profile: "thesis",
};

/// `deepfoids` without a command: train PPO as [`QUICKSTART`] says into
/// `runs/quickstart-ppo-<scene>` (replacing an earlier one), evaluate it, and
/// print what a biologist looks at first: P, M, the school's state, speed,
/// collisions, and where the plots are.
pub fn default_job(dirs: &ConfigDirs) -> Result<()> {
    let q = &QUICKSTART;
    eprintln!(
        "no command given: the quickstart — PPO on {} ({} phase, reward profile {}) for {} agent steps, then a {:.0} s evaluation (see --help for the commands)",
        q.scene,
        q.phase.as_str(),
        dirs.reward_profile,
        q.steps,
        q.eval_seconds
    );
    let start = std::time::Instant::now();
    let args = TrainArgs {
        scene: q.scene.into(),
        phase: q.phase,
        init_from: vec![],
        steps: Some(q.steps),
        steps_per_fish: None,
        run_id: Some(format!("quickstart-ppo-{}", q.scene)),
        resume: false,
        force: true,
        opts: TrainOptionArgs {
            algo: Algorithm::Ppo,
            seed: q.seed,
            runs_dir: "runs".into(),
            backend: Backend::Flex,
            eval_seconds: q.eval_seconds,
            quiet: false,
            allow_no_update: false,
        },
    };
    let t = super::train::run(dirs, &args)?;
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
        state_shares(s),
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
