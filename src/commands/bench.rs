//! `deepfoids bench env`: agent-decisions per second with random actions,
//! sensor included, warm-up excluded; and where the time goes.

use super::load_scene;
use crate::cli::{BenchEnvArgs, BenchTrainArgs};
use anyhow::Result;
use deepfoids_env::policy::action_buffers;
use deepfoids_env::{ConfigDirs, Env, Phase, Policy, RandomPolicy};
use std::time::Instant;

pub fn env(dirs: &ConfigDirs, args: &BenchEnvArgs) -> Result<()> {
    let scene = load_scene(dirs, &args.scene, Phase::Pretrain)?;
    let mut env = Env::new(scene, args.seed);
    let mut policy = RandomPolicy { seed: args.seed };
    let mut actions = action_buffers(&env);
    let warm = (args.warmup / env.tick_seconds()).round() as u64;
    let ticks = (args.seconds / env.tick_seconds()).round().max(1.0) as u64;
    let mut run = |env: &mut Env, n: u64| -> Result<(u64, f64)> {
        let mut decisions = 0u64;
        let mut policy_time = 0.0;
        for _ in 0..n {
            let t = Instant::now();
            policy
                .act(env, &mut actions)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            policy_time += t.elapsed().as_secs_f64();
            let out = env.step(&actions)?;
            decisions += out
                .behaviours
                .iter()
                .filter(|b| b.decided)
                .map(|b| b.n_agents as u64)
                .sum::<u64>();
        }
        Ok((decisions, policy_time))
    };
    run(&mut env, warm)?;
    let before = env.stage_times();
    let start = Instant::now();
    let (decisions, policy_time) = run(&mut env, ticks)?;
    let wall = start.elapsed().as_secs_f64();
    let after = env.stage_times();
    let physics = (after.physics - before.physics).as_secs_f64();
    let sensing = (after.sensing - before.sensing).as_secs_f64();
    let chases = (after.chases - before.chases).as_secs_f64();
    println!(
        "{}: {} fish, {} threads, {:.1} simulated s in {:.2} s wall",
        env.scene().id,
        env.world().len(),
        rayon::current_num_threads(),
        ticks as f64 * env.tick_seconds(),
        wall
    );
    println!("{:.0} agent-decisions/s", decisions as f64 / wall);
    println!(
        "time: sensing + rewards {:.1} %, physics {:.1} %, chases {:.1} %, random policy {:.1} %, other {:.1} %",
        100.0 * sensing / wall,
        100.0 * physics / wall,
        100.0 * chases / wall,
        100.0 * policy_time / wall,
        100.0 * (wall - sensing - physics - chases - policy_time) / wall
    );
    Ok(())
}

/// `deepfoids bench train`: PPO end to end (collection and updates) for a number
/// of agent steps, nothing saved; prints agent-steps/s and the split.
pub fn train(dirs: &ConfigDirs, args: &BenchTrainArgs) -> Result<()> {
    let scene = load_scene(dirs, &args.scene, Phase::Pretrain)?;
    let config = deepfoids_ppo::PpoConfig::load(dirs)?;
    let tmp = std::env::temp_dir().join(format!("deepfoids-bench-train-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let id = scene.id.clone();
    let fish = scene.fish_count();
    let out = deepfoids_ppo::train(deepfoids_ppo::TrainArgs {
        scene,
        config,
        run_dir: tmp.clone(),
        run_id: "bench".into(),
        seed: args.seed,
        steps: Some(args.steps),
        resume: false,
        init_from: None,
        backend: args.backend,
        progress: false,
        save: false,
    });
    let _ = std::fs::remove_dir_all(&tmp);
    let out = out?;
    let t = out.timing;
    let secs = |d: std::time::Duration| d.as_secs_f64();
    println!(
        "{id}: {fish} fish, {} backend, {} threads: {} agent steps in {:.1} s",
        args.backend.as_str(),
        rayon::current_num_threads(),
        out.steps_this_run,
        out.wall_seconds
    );
    println!(
        "{:.0} agent-steps/s",
        out.steps_this_run as f64 / out.wall_seconds.max(1e-9)
    );
    println!(
        "split: environment {:.1} s ({:.0} %), inference {:.1} s ({:.0} %), updates {:.1} s ({:.0} %)",
        secs(t.env),
        100.0 * secs(t.env) / out.wall_seconds,
        secs(t.inference),
        100.0 * secs(t.inference) / out.wall_seconds,
        secs(t.update),
        100.0 * secs(t.update) / out.wall_seconds
    );
    Ok(())
}
