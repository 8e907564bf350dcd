//! `deepfoids simulate`: run a scene with a policy, write `trajectories.csv`
//! (one row per fish per decision of the fastest species) and `simulate.json`
//! (the options that made it, for `replay --from`), and print a summary.

use crate::args::{PolicyArgs, SceneArgs, rerun};
use anyhow::{Context, Result};
use clap::Args;
use deepfoids_env::policy::{act_and_step, action_buffers};
use deepfoids_env::{ConfigDirs, Env, N_TERMS, StepOutput, TERM_NAMES};
use deepfoids_experiments::{bounds, load_scene, lock_dir, make_policy};
use deepfoids_io::{AtomicFile, write_atomic};
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

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

/// Running sums per behaviour.
#[derive(Clone, Debug, Default)]
pub struct Tally {
    pub decisions: u64,
    pub reward: f64,
    pub terms: [f64; N_TERMS],
    pub terminated: u64,
    pub truncated: u64,
    pub neighbour_collisions: u64,
}

impl Tally {
    pub fn add(&mut self, out: &StepOutput, b: usize) {
        let batch = &out.behaviours[b];
        if !batch.decided {
            return;
        }
        self.decisions += batch.n_agents as u64;
        for a in 0..batch.n_agents {
            self.reward += batch.rewards[a] as f64;
            for (t, v) in batch.terms[a].iter().enumerate() {
                self.terms[t] += *v as f64;
            }
            self.terminated += batch.terminated[a] as u64;
            self.truncated += batch.truncated[a] as u64;
            self.neighbour_collisions += batch.new_collisions[a] as u64;
        }
    }
}

pub fn run(dirs: &ConfigDirs, args: &SimulateArgs) -> Result<()> {
    let mut policy_args = args.policy_args.clone();
    policy_args.resolve_latest(&args.policy)?;
    bounds::seconds("--seconds", args.seconds)?;
    let sa = &args.scene;
    let scene = load_scene(dirs, &sa.scene, sa.phase)?;
    let out_dir = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("runs/simulate-{}-s{}", scene.id, sa.seed)));
    bounds::out_dir("--out", &out_dir)?;
    let _lock = lock_dir(&out_dir)?;
    let mut env = Env::new(scene, sa.seed);
    let mut policy = make_policy(dirs, &args.policy, sa.seed, &env, &policy_args.options())?;
    let mut actions = action_buffers(&env);
    let ticks = (args.seconds / env.tick_seconds()).round().max(1.0) as u64;
    let fastest = env
        .behaviours()
        .iter()
        .map(|b| b.steps_per_decision)
        .min()
        .unwrap_or(1);
    let names: Vec<String> = env.behaviours().iter().map(|b| b.name.clone()).collect();
    let tick_steps = env.tick_steps() as u64;

    let csv_path = out_dir.join("trajectories.csv");
    let mut csv = AtomicFile::create(&csv_path)?;
    writeln!(csv, "t,fish,behaviour,x,y,z,dx,dy,dz,speed,bl")?;
    let write_rows = |csv: &mut AtomicFile, out: &StepOutput| -> std::io::Result<()> {
        let f = &out.fish;
        for i in 0..f.position.len() {
            let (p, d) = (f.position[i], f.heading[i]);
            writeln!(
                csv,
                "{:.3},{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
                out.time,
                i,
                names[f.behaviour[i] as usize],
                p.x,
                p.y,
                p.z,
                d.x,
                d.y,
                d.z,
                f.speed[i],
                f.bl[i]
            )?;
        }
        Ok(())
    };
    write_rows(&mut csv, env.output())?;

    let mut tallies = vec![Tally::default(); names.len()];
    let (mut speed_bl, mut depth, mut samples) = (0.0f64, 0.0f64, 0u64);
    let start = Instant::now();
    for _ in 0..ticks {
        let out = act_and_step(policy.as_mut(), &mut env, &mut actions)?;
        for (b, t) in tallies.iter_mut().enumerate() {
            t.add(out, b);
        }
        let steps = out.tick * tick_steps;
        if steps.is_multiple_of(fastest as u64) {
            write_rows(&mut csv, out)?;
            let f = &out.fish;
            for i in 0..f.position.len() {
                speed_bl += (f.speed[i] / f.bl[i]) as f64;
                depth += -f.position[i].y as f64;
            }
            samples += f.position.len() as u64;
        }
    }
    let wall = start.elapsed().as_secs_f64();
    csv.commit()
        .with_context(|| format!("writing {}", csv_path.display()))?;
    // What `replay --from` needs to put the CSV back into its cage.
    let rerun = rerun(sa, &args.policy, &policy_args, 0.0, args.seconds);
    write_atomic(
        out_dir.join("simulate.json"),
        serde_json::to_string_pretty(&rerun)?.as_bytes(),
    )?;

    let s = env.scene();
    let fish = env.world().len();
    let decisions: u64 = tallies.iter().map(|t| t.decisions).sum();
    println!(
        "{}: {} fish, {:.1} simulated s in {:.2} s wall ({:.0} agent-decisions/s), policy {}, seed {}",
        s.id,
        fish,
        env.output().time,
        wall,
        decisions as f64 / wall,
        policy.name(),
        sa.seed
    );
    println!(
        "mean speed {:.2} BL/s, mean depth {:.2} m of {:.2} m; wrote {}",
        speed_bl / samples.max(1) as f64,
        depth / samples.max(1) as f64,
        env.cage().height,
        csv_path.display()
    );
    print!("{:<20} {:>10} {:>9}", "behaviour", "decisions", "reward");
    for n in TERM_NAMES {
        print!(" {:>10}", short(n));
    }
    println!(" {:>10} {:>10}", "BC/fish·h", "NC/fish·h");
    for (name, t) in names.iter().zip(&tallies) {
        let per = |x: f64| x / t.decisions.max(1) as f64;
        print!("{:<20} {:>10} {:>9.3}", name, t.decisions, per(t.reward));
        for v in t.terms {
            print!(" {:>10.3}", per(v));
        }
        let count = env
            .behaviours()
            .iter()
            .find(|b| &b.name == name)
            .map_or(0, |b| b.count);
        let hours = count as f64 * env.output().time / 3600.0;
        println!(
            " {:>10.1} {:>10.1}",
            t.terminated as f64 / hours.max(1e-12),
            t.neighbour_collisions as f64 / hours.max(1e-12)
        );
    }
    Ok(())
}

/// Short column names for the reward terms.
pub fn short(term: &str) -> &'static str {
    match term {
        "boundary_collision" => "r_BC",
        "neighbour_collision" => "r_NC",
        "boundary_distance" => "r_BD",
        "neighbour_distance" => "r_ND",
        "energy" => "r_E",
        "movement" => "r_M",
        "chase" => "r_C",
        _ => "?",
    }
}
