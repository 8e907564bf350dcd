//! Simulating a scene into `trajectories.csv` (`deepfoids simulate`): one row
//! per fish per decision of the fastest species, with running sums per
//! behaviour.

use anyhow::{Context, Result};
use deepfoids_env::policy::{act_and_step, action_buffers};
use deepfoids_env::{Env, N_TERMS, Policy, StepOutput};
use deepfoids_io::AtomicFile;
use deepfoids_replay::trajectories::{HEADER, write_rows};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// Running sums per behaviour.
#[derive(Clone, Debug, Default)]
pub struct Tally {
    pub decisions: u64,
    pub reward: f64,
    pub terms: [f64; N_TERMS],
    /// Decisions whose fish crossed a wall since the previous one (whether or
    /// not the profile ends the episode there).
    pub boundary_collisions: u64,
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
            self.boundary_collisions += batch.crossed[a] as u64;
            self.neighbour_collisions += batch.new_collisions[a] as u64;
        }
    }
}

/// What [`simulate_to_csv`] measured.
#[derive(Clone, Debug)]
pub struct Simulated {
    /// Behaviour names, in the order of `tallies`.
    pub names: Vec<String>,
    pub tallies: Vec<Tally>,
    /// Over the rows written: mean speed (BL/s) and depth (m).
    pub mean_speed_bl: f64,
    pub mean_depth: f64,
    /// Wall-clock seconds of the simulation.
    pub wall: f64,
}

/// Run `env` with `policy` for `seconds` of simulated time, writing the
/// trajectories to `csv_path` (atomically: the file appears complete or not
/// at all).
pub fn simulate_to_csv(
    env: &mut Env,
    policy: &mut dyn Policy,
    seconds: f64,
    csv_path: &Path,
) -> Result<Simulated> {
    let mut actions = action_buffers(env);
    let ticks = (seconds / env.tick_seconds()).round().max(1.0) as u64;
    let fastest = env
        .behaviours()
        .iter()
        .map(|b| b.steps_per_decision)
        .min()
        .unwrap_or(1);
    let names: Vec<String> = env.behaviours().iter().map(|b| b.name.clone()).collect();
    let tick_steps = env.tick_steps() as u64;

    let mut csv = AtomicFile::create(csv_path)?;
    writeln!(csv, "{HEADER}")?;
    write_rows(&mut csv, env.output(), &names)?;

    let mut tallies = vec![Tally::default(); names.len()];
    let (mut speed_bl, mut depth, mut samples) = (0.0f64, 0.0f64, 0u64);
    let start = Instant::now();
    for _ in 0..ticks {
        let out = act_and_step(policy, env, &mut actions)?;
        for (b, t) in tallies.iter_mut().enumerate() {
            t.add(out, b);
        }
        let steps = out.tick * tick_steps;
        if steps.is_multiple_of(fastest as u64) {
            write_rows(&mut csv, out, &names)?;
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
    Ok(Simulated {
        names,
        tallies,
        mean_speed_bl: speed_bl / samples.max(1) as f64,
        mean_depth: depth / samples.max(1) as f64,
        wall,
    })
}
