//! `deepfoids simulate`: run a scene with a policy, write `trajectories.csv`
//! (one row per fish per decision of the fastest species) and `simulate.json`
//! (the options that made it, for `replay --from`), and print a summary.

use crate::args::{PolicyArgs, SceneArgs, rerun};
use anyhow::Result;
use clap::Args;
use deepfoids_env::reward::TERM_SYMBOLS;
use deepfoids_env::{ConfigDirs, Env, GridFormat};
use deepfoids_experiments::simulate::{Simulated, simulate_to_csv};
use deepfoids_experiments::{bounds, lock_dir, make_policy};
use deepfoids_io::write_atomic;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub policy_args: PolicyArgs,
    /// Simulated seconds
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Output folder [default: runs/simulate-<scene>[-n<fish>]-s<seed>]
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

pub fn run(dirs: &ConfigDirs, args: &SimulateArgs) -> Result<()> {
    let (policy_name, policy_args) = args.policy_args.resolve("random")?;
    bounds::seconds("--seconds", args.seconds)?;
    let sa = &args.scene;
    let scene = sa.load(dirs)?;
    let out_dir = args.out.clone().unwrap_or_else(|| {
        PathBuf::from(format!(
            "runs/simulate-{}-s{}",
            sa.label(&scene.id),
            sa.seed
        ))
    });
    bounds::out_dir("--out", &out_dir)?;
    let _lock = lock_dir(&out_dir)?;
    let mut env = Env::with_grid_format(scene, sa.seed, GridFormat::Bytes);
    let mut policy = make_policy(dirs, &policy_name, sa.seed, &env, &policy_args.options())?;
    let csv_path = out_dir.join("trajectories.csv");
    let Simulated {
        names,
        tallies,
        mean_speed_bl,
        mean_depth,
        wall,
    } = simulate_to_csv(&mut env, policy.as_mut(), args.seconds, &csv_path)?;
    // What `replay --from` needs to put the CSV back into its cage.
    let rerun = rerun(sa, &policy_name, &policy_args, 0.0, args.seconds);
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
        mean_speed_bl,
        mean_depth,
        env.cage().height,
        csv_path.display()
    );
    print!("{:<20} {:>10} {:>9}", "behaviour", "decisions", "reward");
    for n in TERM_SYMBOLS {
        print!(" {n:>10}");
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
            t.boundary_collisions as f64 / hours.max(1e-12),
            t.neighbour_collisions as f64 / hours.max(1e-12)
        );
    }
    Ok(())
}
