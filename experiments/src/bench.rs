//! The `deepfoids bench` measurements: the environment with random actions
//! ([`env`]), training end to end ([`train`]) and a trained policy's
//! inference through the kernels, Burn and tract ([`policy`]). Each prints
//! its rates and where the time went.

use crate::process::{cpu_seconds, resident_set_bytes};
use crate::training::Config;
use crate::{bounds, load_actor, load_scene};
use anyhow::Result;
use deepfoids_env::policy::action_buffers;
use deepfoids_env::{ConfigDirs, Env, GridFormat, GridsRef, Phase, Policy, RandomPolicy};
use deepfoids_learn::plan::UpdatePlan;
use deepfoids_learn::{Algorithm, Backend, ProgressMode, RunArgs};
use std::path::Path;
use std::time::Instant;

/// `bench env`: agent-decisions per second with random actions in `scene`,
/// sensor included (its grids handed out in `format`), `warmup` simulated
/// seconds excluded; and where the time goes.
pub fn env(
    dirs: &ConfigDirs,
    scene: &str,
    seconds: f64,
    warmup: f64,
    seed: u64,
    format: GridFormat,
) -> Result<()> {
    let scene = load_scene(dirs, scene, Phase::Pretrain)?;
    let mut env = Env::with_grid_format(scene, seed, format);
    let mut policy = RandomPolicy { seed };
    let mut actions = action_buffers(&env);
    let warm = (warmup / env.tick_seconds()).round() as u64;
    let ticks = (seconds / env.tick_seconds()).round().max(1.0) as u64;
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
        "{}: {} fish, grids as {}, {} threads, {:.1} simulated s in {:.2} s wall",
        env.scene().id,
        env.world().len(),
        match format {
            GridFormat::Bytes => "bytes",
            GridFormat::Floats => "floats",
        },
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

/// What `bench train` trains.
#[derive(Clone, Debug)]
pub struct TrainBench {
    /// Scene id or path.
    pub scene: String,
    /// Agent decisions per behaviour (default: [`BENCH_UPDATES`] updates of
    /// every behaviour, and at least 30,000).
    pub steps: Option<u64>,
    pub algo: Algorithm,
    pub backend: Backend,
    /// PPO's rollout scheme in place of `ppo.toml`'s.
    pub rollout: Option<deepfoids_ppo::Rollout>,
    pub seed: u64,
}

/// `deepfoids bench train`: PPO or SAC end to end (collection and updates)
/// for a number of agent steps per behaviour, nothing saved; prints
/// agent-steps/s, the split, the updates' own split and the buffers' size.
pub fn train(dirs: &ConfigDirs, args: &TrainBench) -> Result<()> {
    let scene = load_scene(dirs, &args.scene, Phase::Pretrain)?;
    let tmp = std::env::temp_dir().join(format!("deepfoids-bench-train-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let id = scene.id.clone();
    let fish = scene.fish_count();
    let mut trainer = Config::load(dirs, args.algo)?;
    if let (Config::Ppo(ppo), Some(r)) = (&mut trainer, args.rollout) {
        ppo.config.rollout = r;
    }
    // Every behaviour's update plan: the default budget plans one update more
    // than BENCH_UPDATES, as episode ends can delay PPO's joins by up to a
    // time horizon (one update's worth at most), so each makes at least 3.
    let plans: Vec<(String, UpdatePlan)> = scene
        .behaviours
        .iter()
        .map(|b| (b.name.clone(), trainer.update_plan(b.count)))
        .collect();
    let steps = args.steps.unwrap_or_else(|| {
        plans
            .iter()
            .map(|(_, p)| p.budget_for(BENCH_UPDATES + 1))
            .fold(30_000, u64::max)
    });
    bounds::train_steps("--steps", steps)?;
    let expected: u64 = plans.iter().map(|(_, p)| p.updates(steps)).sum();
    for (name, p) in &plans {
        if p.updates(steps) == 0 {
            eprintln!(
                "warning: {steps} agent steps make no update of {name} (its first comes after {}): the rate below is collection only, not training; drop --steps for a budget with {BENCH_UPDATES} updates",
                p.first
            );
        }
    }
    let run = RunArgs {
        scene,
        run_dir: tmp.clone(),
        run_id: "bench".into(),
        seed: args.seed,
        steps: Some(steps.into()),
        resume: false,
        init_from: vec![],
        backend: args.backend,
        progress: ProgressMode::Quiet,
        progress_sink: None,
        save: false,
        config_toml: None,
    };
    let rss_before = resident_set_bytes();
    let cpu_before = cpu_seconds();
    let out = trainer.train(run);
    let cpu = cpu_seconds().zip(cpu_before).map(|(a, b)| a - b);
    let rss_after = resident_set_bytes();
    let _ = std::fs::remove_dir_all(&tmp);
    let out = out?;
    let t = &out.timing;
    let secs = |d: std::time::Duration| d.as_secs_f64();
    let wall = out.wall_seconds.max(1e-9);
    println!(
        "{id}: {fish} fish, {}, {} backend, {} threads: {} agent steps in {:.1} s{}",
        args.algo.as_str(),
        args.backend.as_str(),
        rayon::current_num_threads(),
        out.steps_this_run,
        out.wall_seconds,
        cpu.map_or(String::new(), |c| format!(" ({c:.1} CPU-s)"))
    );
    println!(
        "{:.0} agent-steps/s{}",
        out.steps_this_run as f64 / wall,
        cpu.map_or(String::new(), |c| format!(
            " ({:.0} per CPU-second)",
            out.steps_this_run as f64 / c.max(1e-9)
        ))
    );
    println!(
        "split: environment {:.1} s ({:.0} %), inference {:.1} s ({:.0} %), updates {:.1} s ({:.0} %), other {:.0} %",
        secs(t.env),
        100.0 * secs(t.env) / wall,
        secs(t.inference),
        100.0 * secs(t.inference) / wall,
        secs(t.update),
        100.0 * secs(t.update) / wall,
        100.0 * (wall - secs(t.env) - secs(t.inference) - secs(t.update)) / wall
    );
    println!(
        "updates: {} ({expected} planned without episode ends; a benchmark without updates measures collection only)",
        out.updates
    );
    if out.updates > 0 {
        let parts: Vec<String> = t
            .parts
            .iter()
            .map(|(k, v)| format!("{k} {:.0} %", 100.0 * secs(*v) / secs(t.update).max(1e-9)))
            .collect();
        println!(
            "each update {:.3} s; within them: {}",
            secs(t.update) / out.updates as f64,
            parts.join(", ")
        );
    }
    let mb = |b: u64| b as f64 / 1e6;
    let b = out.buffer;
    println!(
        "experience buffer: {:.1} MB allocated, {:.1} MB written, {:.1} MB at the largest, {} transitions held at the end{}",
        mb(b.allocated),
        mb(b.resident),
        mb(b.peak),
        b.transitions,
        match args.algo {
            Algorithm::Sac => format!(
                " ({} bytes each)",
                deepfoids_sac::replay::BYTES_PER_TRANSITION
            ),
            Algorithm::Ppo => format!(
                " (≈ {} bytes each)",
                deepfoids_learn::frames::FRAME_BYTES + deepfoids_ppo::rollout::STEP_BYTES
            ),
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

/// Updates of every behaviour in `bench train`'s default budget.
pub const BENCH_UPDATES: u64 = 3;

/// `deepfoids bench policy`: deterministic actions for `agents` sensor-like
/// observations per call of a run's first behaviour: the fused kernels on the
/// sensor's bytes (what acting uses) and on the same grids as floats, Burn's
/// own layers, and the run's ONNX export in tract; the largest difference
/// between them.
pub fn policy(run: &Path, agents: usize, reps: usize) -> Result<()> {
    use deepfoids_learn::checkpoint::{RunState, policy_dir};
    let dir = policy_dir(run, None)?;
    let state = RunState::load(&dir)?;
    state.check_layout(&dir)?;
    let b = state
        .behaviours
        .first()
        .ok_or_else(|| anyhow::anyhow!("the run has no behaviours"))?;
    let actor = load_actor(&dir, &state, b)?;
    let onnx_path =
        std::env::temp_dir().join(format!("deepfoids-bench-{}.onnx", std::process::id()));
    let meta = deepfoids_learn::onnx::Metadata {
        species: b.species.clone(),
        behaviour: b.name.clone(),
        ..Default::default()
    };
    std::fs::write(&onnx_path, actor.onnx(&meta))?;
    let tract = deepfoids_onnx::OnnxPolicy::load(&onnx_path, false)?;
    let _ = std::fs::remove_file(&onnx_path);
    let n = agents;
    let mut s = deepfoids_env::rng::Stream::new(1, deepfoids_env::rng::Purpose::Policy, 0, 0);
    // Grids as the sensor makes them: a cell of a frame sees something or
    // nothing; if something, a proximity in (0, 1] and one of the five type
    // channels. 63 % of the cells seeing something gives the 21 % non-zero
    // inputs measured in `coho_default` (the sparser scenes act faster).
    use deepfoids_sensors::{CELLS, CHANNELS, FRAME_LEN, STACKED_LEN};
    let mut grids = vec![0.0f32; n * STACKED_LEN];
    for frame in grids.chunks_exact_mut(FRAME_LEN) {
        for c in 0..CELLS {
            if s.uniform() < 0.63 {
                frame[c] = 1.0 - s.uniform().min(0.999);
                let kind = 1 + ((s.uniform() * (CHANNELS - 1) as f32) as usize).min(CHANNELS - 2);
                frame[kind * CELLS + c] = 1.0;
            }
        }
    }
    // The sensor hands out bytes; the floats are those bytes rebuilt, so
    // every path sees the same observation.
    let frames = deepfoids_learn::frames::CompactGrids::from_dense(&grids);
    let grids = frames.to_dense();
    let bytes = GridsRef::Compact(&frames.bytes);
    let nonzero = grids.iter().filter(|&&v| v != 0.0).count() as f64 / grids.len() as f64;
    let vectors: Vec<f32> = (0..n * 6).map(|_| s.range(-1.0, 1.0)).collect();
    let fused = actor.deterministic(bytes, &vectors);
    let fused_floats = actor.deterministic(GridsRef::Dense(&grids), &vectors);
    let reference = actor.deterministic_reference(&grids, &vectors);
    let onnx = tract.run(&grids, &vectors, n)?;
    let diff = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f32, f32::max)
    };
    // Interleaved repetitions, the fastest of each kept (the machine is shared).
    let (mut t_fused, mut t_floats, mut t_burn, mut t_tract) =
        (f64::MAX, f64::MAX, f64::MAX, f64::MAX);
    let time = |f: &mut dyn FnMut()| {
        let t = Instant::now();
        f();
        t.elapsed().as_secs_f64()
    };
    for _ in 0..reps {
        t_fused = t_fused.min(time(&mut || {
            actor.deterministic(bytes, &vectors);
        }));
        t_floats = t_floats.min(time(&mut || {
            actor.deterministic(GridsRef::Dense(&grids), &vectors);
        }));
        t_burn = t_burn.min(time(&mut || {
            actor.deterministic_reference(&grids, &vectors);
        }));
        t_tract = t_tract.min(time(&mut || {
            tract.run(&grids, &vectors, n).expect("tract runs");
        }));
    }
    let rate = |t: f64| n as f64 / t;
    println!(
        "{n} agents per call ({:.0} % of the grid inputs non-zero), {} threads, fastest of {} interleaved calls: kernels on the sensor's bytes {:.1} ms ({:.0} samples/s), on floats {:.1} ms ({:.0}/s), Burn layers {:.1} ms ({:.0}/s), tract {:.1} ms ({:.0}/s); bytes {:.2}× floats, {:.1}× Burn, {:.1}× tract; max |Δaction| bytes–floats {:.1e}, kernels–Burn {:.1e}, kernels–tract {:.1e}",
        100.0 * nonzero,
        rayon::current_num_threads(),
        reps,
        t_fused * 1e3,
        rate(t_fused),
        t_floats * 1e3,
        rate(t_floats),
        t_burn * 1e3,
        rate(t_burn),
        t_tract * 1e3,
        rate(t_tract),
        t_floats / t_fused,
        t_burn / t_fused,
        t_tract / t_fused,
        diff(&fused, &fused_floats),
        diff(&fused, &reference),
        diff(&fused, &onnx)
    );
    Ok(())
}
