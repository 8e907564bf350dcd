//! `deepfoids bench env`: agent-decisions per second with random actions,
//! sensor included, warm-up excluded; and where the time goes.

use super::load_scene;
use crate::cli::{Algo, BenchEnvArgs, BenchPolicyArgs, BenchTrainArgs};
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
    let tmp = std::env::temp_dir().join(format!("deepfoids-bench-train-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let id = scene.id.clone();
    let fish = scene.fish_count();
    let rss_before = resident_set_bytes();
    let out = match args.algo {
        Algo::Ppo => deepfoids_ppo::train(deepfoids_ppo::TrainArgs {
            scene,
            config: deepfoids_ppo::PpoConfig::load(dirs)?,
            run_dir: tmp.clone(),
            run_id: "bench".into(),
            seed: args.seed,
            steps: Some(args.steps),
            resume: false,
            init_from: None,
            backend: args.backend,
            progress: false,
            save: false,
        }),
        Algo::Sac => deepfoids_sac::train(deepfoids_sac::SacTrainArgs {
            scene,
            config: deepfoids_sac::SacConfig::load(dirs)?,
            run_dir: tmp.clone(),
            run_id: "bench".into(),
            seed: args.seed,
            steps: Some(args.steps),
            resume: false,
            init_from: None,
            backend: args.backend,
            progress: false,
            save: false,
        }),
    };
    let rss_after = resident_set_bytes();
    let _ = std::fs::remove_dir_all(&tmp);
    let out = out?;
    let t = out.timing;
    let secs = |d: std::time::Duration| d.as_secs_f64();
    println!(
        "{id}: {fish} fish, {}, {} backend, {} threads: {} agent steps in {:.1} s",
        super::train::algo_name(args.algo),
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
    let mb = |b: u64| b as f64 / 1e6;
    let b = out.buffer;
    println!(
        "experience buffer: {:.1} MB allocated, {:.1} MB resident, {} transitions{}",
        mb(b.allocated),
        mb(b.resident),
        b.transitions,
        match args.algo {
            Algo::Sac => format!(
                " of the replay ({} bytes each)",
                deepfoids_sac::replay::BYTES_PER_TRANSITION
            ),
            Algo::Ppo => String::new(),
        }
    );
    if let (Some(a), Some(z)) = (rss_before, rss_after) {
        println!(
            "process resident set: {:.1} MB before training, {:.1} MB after",
            mb(a),
            mb(z)
        );
    }
    Ok(())
}

/// The process's resident set size (Linux `/proc/self/status`, `VmRSS`).
fn resident_set_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// `deepfoids bench policy`: deterministic actions for `agents` observations per
/// call, Burn (flex, GEMM convolutions) against the run's ONNX export in tract;
/// also the largest difference between the two.
pub fn policy(args: &BenchPolicyArgs) -> Result<()> {
    use burn::prelude::*;
    use deepfoids_ppo::checkpoint::{RunState, policy_dir};
    use deepfoids_ppo::model::{ActorCriticConfig, BodyConfig};
    let dir = policy_dir(&args.run, None)?;
    let state = RunState::load(&dir)?;
    let b = state
        .behaviours
        .first()
        .ok_or_else(|| anyhow::anyhow!("the run has no behaviours"))?;
    let dev = Device::flex();
    let cfg = ActorCriticConfig::new().with_body(
        BodyConfig::new()
            .with_hidden(state.hidden)
            .with_layers(state.layers),
    );
    let model =
        deepfoids_ppo::train::load_weights(&dir, &state, &b.name, &b.species, cfg.init(&dev))?;
    let onnx_path =
        std::env::temp_dir().join(format!("deepfoids-bench-{}.onnx", std::process::id()));
    let meta = deepfoids_onnx::Metadata {
        species: b.species.clone(),
        behaviour: b.name.clone(),
        ..Default::default()
    };
    std::fs::write(&onnx_path, deepfoids_onnx::export_actor(&model, &meta))?;
    let tract = deepfoids_onnx::OnnxPolicy::load(&onnx_path, false)?;
    let _ = std::fs::remove_file(&onnx_path);
    let n = args.agents;
    let mut s = deepfoids_env::rng::Stream::new(1, deepfoids_env::rng::Purpose::Policy, 0, 0);
    let grids: Vec<f32> = (0..n * deepfoids_sensors::STACKED_LEN)
        .map(|_| if s.uniform() < 0.3 { s.uniform() } else { 0.0 })
        .collect();
    let vectors: Vec<f32> = (0..n * 6).map(|_| s.range(-1.0, 1.0)).collect();
    let burn_run = || -> Vec<f32> {
        let g = Tensor::<4>::from_data(TensorData::new(grids.clone(), [n, 18, 20, 34]), &dev);
        let v = Tensor::<2>::from_data(TensorData::new(vectors.clone(), [n, 6]), &dev);
        model
            .actor(g, v)
            .0
            .clamp(-1.0, 1.0)
            .into_data()
            .try_into_vec::<f32>()
            .expect("f32")
    };
    let (a, b2) = (burn_run(), tract.run(&grids, &vectors, n)?);
    let diff = a
        .iter()
        .zip(&b2)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    let time = |f: &mut dyn FnMut()| {
        let t = Instant::now();
        for _ in 0..args.reps {
            f();
        }
        t.elapsed().as_secs_f64() / args.reps as f64
    };
    let t_burn = time(&mut || {
        burn_run();
    });
    let t_tract = time(&mut || {
        tract.run(&grids, &vectors, n).expect("tract runs");
    });
    println!(
        "{n} agents per call, {} threads: Burn (flex) {:.1} ms, tract {:.1} ms per call; tract/Burn time ratio {:.2}; max |Δaction| {diff:.2e}",
        rayon::current_num_threads(),
        t_burn * 1e3,
        t_tract * 1e3,
        t_tract / t_burn
    );
    Ok(())
}
