//! `deepfoids sensor-view`: what one fish sees — its three stacked grid-sensor
//! frames (oldest left), proximity as brightness and object type as colour.

use crate::args::SceneArgs;
use crate::args::whole;
use anyhow::{Result, bail};
use clap::Args;
use deepfoids_env::limits::MAX_TICKS;
use deepfoids_env::policy::action_buffers;
use deepfoids_env::{Chase, ConfigDirs, Env, Policy, RandomPolicy};
use deepfoids_experiments::bounds;
use deepfoids_experiments::sensor_view::draw;
use deepfoids_sensors::STACKED_LEN;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct SensorViewArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Index of the fish to look through (0-based)
    #[arg(value_parser = whole::<usize>, long, default_value_t = 0)]
    pub fish: usize,
    /// Ticks to simulate (random actions) before looking
    #[arg(value_parser = whole::<u64>, long, default_value_t = 10)]
    pub step: u64,
    /// Output PNG
    #[arg(long, default_value = "view.png", value_name = "PNG")]
    pub out: PathBuf,
}

pub fn run(dirs: &ConfigDirs, args: &SensorViewArgs) -> Result<()> {
    bounds::count_within("--step", args.step, [0, MAX_TICKS], "ticks")?;
    let sa = &args.scene;
    let scene = sa.load(dirs)?;
    let mut env = Env::new(scene, sa.seed);
    let n = env.world().len();
    if args.fish >= n {
        bail!(
            "--fish {} is out of range: scene {} has {n} fish (0..{})",
            args.fish,
            env.scene().id,
            n - 1
        );
    }
    let mut policy = RandomPolicy { seed: sa.seed };
    let mut actions = action_buffers(&env);
    // Step until the fish's behaviour has decided at or after the requested tick.
    let b = env.world().behaviour[args.fish] as usize;
    while env.output().tick < args.step || !env.output().behaviours[b].decided {
        policy
            .act(&env, &mut actions)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        env.step(&actions)?;
    }
    let out = env.output();
    let batch = &out.behaviours[b];
    let a = args.fish - batch.first;
    let stack = &batch.grids[a * STACKED_LEN..(a + 1) * STACKED_LEN];
    let v = &batch.vectors[a * 6..(a + 1) * 6];
    let w = env.world();
    let role = match w.chase[args.fish] {
        Chase::None => "none".to_string(),
        Chase::Aggressor { target, .. } => format!("chasing fish {target}"),
        Chase::Target { aggressor } => format!("chased by fish {aggressor}"),
    };
    let title = format!(
        "{} · fish {} ({}{}) · tick {} · t = {:.2} s",
        env.scene().id,
        args.fish,
        batch.name,
        if w.dominant[args.fish] {
            ", dominant"
        } else {
            ""
        },
        out.tick,
        out.time
    );
    let subtitle = format!(
        "depth {:.2} m · speed {:.2} BL/s · u = ({:+.2}, {:+.2}, {:+.2}) · depth/H {:.2} · chase: {} · sensing range {:.2} m",
        -w.position[args.fish].y,
        w.speed[args.fish] / w.bl[args.fish],
        v[0],
        v[1],
        v[2],
        v[3],
        role,
        sensing_range(&env, args.fish),
    );
    draw(&args.out, stack, &title, &subtitle)?;
    println!("wrote {}", args.out.display());
    Ok(())
}

fn sensing_range(env: &Env, i: usize) -> f32 {
    let w = env.world();
    let b = &env.scene().behaviours[w.behaviour[i] as usize];
    b.species.sense_range_bl * w.bl[i]
}
