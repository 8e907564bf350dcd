//! `deepfoids eval`: drive a scene with a policy and judge the school.

use super::{load_scene, make_policy};
use crate::cli::EvalArgs;
use crate::report::{EvalMeta, RunArgs, evaluate, print_table, write_outputs};
use anyhow::Result;
use deepfoids_env::limits::MAX_FPS;
use deepfoids_env::{ConfigDirs, Env};
use deepfoids_replay::EnvRecorder;
use std::path::PathBuf;

pub fn run(dirs: &ConfigDirs, args: &EvalArgs) -> Result<()> {
    crate::bounds::seconds("--seconds", args.seconds)?;
    crate::bounds::at_most("--replay-fps", args.replay_fps, MAX_FPS, "frames/s")?;
    let sa = &args.scene;
    let scene = load_scene(dirs, &sa.scene, sa.phase)?;
    let mut env = Env::new(scene, sa.seed);
    let mut policy = make_policy(dirs, &args.policy, sa.seed, &env, &args.policy_args)?;
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from(format!(
            "runs/eval-{}-{}-s{}",
            env.scene().id,
            policy.name(),
            sa.seed
        ))
    });
    let _lock = crate::io::lock_dir(&out)?;
    let mut recorder = if args.replay {
        super::replay::check_recording(&env, args.seconds, args.replay_fps)?;
        let info = super::replay::info(&env, &policy.name(), "simulated by deepfoids eval", vec![]);
        Some(EnvRecorder::new(&env, info, args.replay_fps)?)
    } else {
        None
    };
    let eval = evaluate(&mut env, policy.as_mut(), args.seconds, |env, _, _| {
        if let Some(r) = recorder.as_mut() {
            r.observe(env)
        }
    })?;
    let scene_id = env.scene().id.clone();
    let name = policy.name();
    let meta = EvalMeta {
        scene: &scene_id,
        policy: &name,
        seed: sa.seed,
        phase: sa.phase.as_str(),
        deterministic: !args.policy_args.stochastic,
        seconds: eval.seconds,
        wall_seconds: eval.wall_seconds,
        ticks_per_second: eval.recorder.samples.len() as f64 / eval.wall_seconds.max(1e-9),
        rerun: RunArgs::new(sa, &args.policy, &args.policy_args, args.seconds),
    };
    let summary = write_outputs(&out, &env, &eval, &meta)?;
    print_table(&meta, &summary);
    println!(
        "wrote {}/{{metrics.csv, summary.json, pm.png, depth.png, trajectories.png}}",
        out.display()
    );
    if let Some(r) = recorder {
        let rec = r.finish(super::replay::curves(&eval));
        let path = out.join("replay.html");
        let size = super::replay::write_page(&path, &rec)?;
        println!("{}", super::replay::describe(&path, &rec, &size));
        super::replay::warn_if_large(&size);
    }
    Ok(())
}
