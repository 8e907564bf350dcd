//! `deepfoids eval`: drive a scene with a policy and judge the school.

use crate::args::{PolicyArgs, SceneArgs, rerun};
use anyhow::Result;
use clap::Args;
use deepfoids_env::limits::MAX_FPS;
use deepfoids_env::{ConfigDirs, Env, GridFormat};
use deepfoids_experiments::evaluate::{EvalMeta, print_table, write_outputs};
use deepfoids_experiments::replays::evaluate_recorded;
use deepfoids_experiments::{bounds, lock_dir, make_policy};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct EvalArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub policy_args: PolicyArgs,
    /// Simulated seconds recorded
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Simulated seconds run before recording (the school settles from its random start)
    #[arg(long, default_value_t = 0.0)]
    pub warmup: f64,
    /// Output folder [default: runs/eval-<scene>[-n<fish>]-<policy>-s<seed>]
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Also write replay.html (see `deepfoids replay`) next to the plots
    #[arg(long)]
    pub replay: bool,
    /// Frames per simulated second stored in replay.html (the viewer interpolates between them)
    #[arg(long, default_value_t = 5.0, value_name = "FPS")]
    pub replay_fps: f64,
}

pub fn run(dirs: &ConfigDirs, args: &EvalArgs) -> Result<()> {
    let (policy_name, policy_args) = args.policy_args.resolve("foids")?;
    bounds::seconds("--seconds", args.seconds)?;
    bounds::warmup("--warmup", args.warmup)?;
    bounds::positive_at_most("--replay-fps", args.replay_fps, MAX_FPS, "frames/s")?;
    let sa = &args.scene;
    let scene = sa.load(dirs)?;
    let mut env = Env::with_grid_format(scene, sa.seed, GridFormat::Bytes);
    let mut policy = make_policy(dirs, &policy_name, sa.seed, &env, &policy_args.options())?;
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from(format!(
            "runs/eval-{}-{}-s{}",
            sa.label(&env.scene().id),
            policy.name(),
            sa.seed
        ))
    });
    bounds::out_dir("--out", &out)?;
    let _lock = lock_dir(&out)?;
    let info = if args.replay {
        deepfoids_experiments::replays::check_recording(&env, args.seconds, args.replay_fps)?;
        Some(deepfoids_experiments::replays::info(
            &env,
            &policy.name(),
            "simulated by deepfoids eval",
            vec![],
        ))
    } else {
        None
    };
    let (eval, recording) = evaluate_recorded(
        &mut env,
        policy.as_mut(),
        args.warmup,
        args.seconds,
        info,
        args.replay_fps,
    )?;
    let scene_id = env.scene().id.clone();
    let name = policy.name();
    let meta = EvalMeta {
        scene: &scene_id,
        policy: &name,
        seed: sa.seed,
        phase: sa.phase.as_str(),
        deterministic: policy_args.deterministic,
        warmup: args.warmup,
        seconds: eval.seconds,
        wall_seconds: eval.wall_seconds,
        ticks_per_second: eval.recorder.samples.len() as f64 / eval.wall_seconds.max(1e-9),
        rerun: rerun(sa, &policy_name, &policy_args, args.warmup, args.seconds),
    };
    let summary = write_outputs(&out, &env, &eval, &meta)?;
    print_table(&meta, &summary);
    println!(
        "wrote {}/{{metrics.csv, summary.json, pm.png, depth.png, trajectories.png}}",
        out.display()
    );
    if let Some(rec) = recording {
        let path = out.join("replay.html");
        let size = deepfoids_experiments::replays::write_page(&path, &rec)?;
        println!(
            "{}",
            deepfoids_experiments::replays::describe(&path, &rec, &size)
        );
        deepfoids_experiments::replays::warn_if_large(&size);
    }
    Ok(())
}
