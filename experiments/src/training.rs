//! Training a scene: one policy per behaviour, PPO or SAC, into a run folder
//! with its resolved configuration, then an evaluation of it with sampled actions.

use crate::evaluate::{EvalMeta, RunArgs as EvalRunArgs, evaluate, print_table, write_outputs};
use crate::policies::load_trained;
use anyhow::{Context, Result, bail};
use deepfoids_env::metrics::Summary;
use deepfoids_env::{ConfigDirs, Env, Policy, Scene};
use deepfoids_learn::driver::{check_run, open_sources};
use deepfoids_learn::{Algorithm, Backend, Budget, ProgressMode, RunArgs, TrainOutcome};
use deepfoids_ppo::Ppo;
use deepfoids_sac::Sac;
use std::path::{Path, PathBuf};

/// How a scene is trained (the options `train`, `pipeline` and `reproduce`
/// share).
#[derive(Clone, Debug)]
pub struct TrainOptions {
    /// Training algorithm.
    pub algo: Algorithm,
    /// Random seed (weights, exploration, environment).
    pub seed: u64,
    /// Folder of the runs.
    pub runs_dir: PathBuf,
    /// Compute backend of the training (acting runs on the hand-written kernels).
    pub backend: Backend,
    /// Simulated seconds of the evaluation after training (sampled actions) (0: none).
    pub eval_seconds: f64,
    /// No progress bar and no progress lines.
    pub quiet: bool,
    /// Budgets by species, `[pretraining, transfer]`, replacing the training
    /// config's (`reproduce`'s profiles).
    pub budgets: std::collections::BTreeMap<String, [u64; 2]>,
    /// Start a run whose budget makes no update (refused otherwise).
    pub allow_no_update: bool,
}

/// A finished training command.
pub struct Trained {
    pub run_dir: PathBuf,
    pub outcome: TrainOutcome,
    pub summary: Option<Summary>,
}

/// The training config of `opts.algo`, with `opts.budgets` in place of its own.
fn load_config(dirs: &ConfigDirs, opts: &TrainOptions) -> Result<Config> {
    let mut config = Config::load(dirs, opts.algo)?;
    for (species, b) in &opts.budgets {
        match &mut config {
            Config::Ppo(t) => t.config.budgets.insert(species.clone(), *b),
            Config::Sac(t) => t.config.budgets.insert(species.clone(), *b),
        };
    }
    Ok(config)
}

/// Either algorithm with its training config.
pub(crate) enum Config {
    Ppo(Ppo),
    Sac(Sac),
}

impl Config {
    /// `<configs>/train/<algo>.toml`, read and checked.
    pub(crate) fn load(dirs: &ConfigDirs, algo: Algorithm) -> Result<Self> {
        Ok(match algo {
            Algorithm::Ppo => Config::Ppo(Ppo::load(dirs)?),
            Algorithm::Sac => Config::Sac(Sac::load(dirs)?),
        })
    }

    /// When the updates of a behaviour of `agents` come.
    pub(crate) fn update_plan(&self, agents: usize) -> deepfoids_learn::plan::UpdatePlan {
        use deepfoids_learn::driver::Trainer;
        match self {
            Config::Ppo(t) => t.update_plan(agents),
            Config::Sac(t) => t.update_plan(agents),
        }
    }

    /// Train `run` with this algorithm.
    pub(crate) fn train(&self, run: RunArgs) -> deepfoids_learn::Result<TrainOutcome> {
        match self {
            Config::Ppo(t) => deepfoids_ppo::train(t, run),
            Config::Sac(t) => deepfoids_sac::train(t, run),
        }
    }
}

/// Everything a run needs before its folder is made (issue 25): the
/// training config loads and its sizes are within bounds; every behaviour's
/// budget makes an update (unless `opts.allow_no_update`); the environment
/// and the learners fit into the machine's memory; and the runs of
/// `init_from` hold policies of this algorithm and architecture with a
/// source for every behaviour of `scene`. A wrong start thus leaves nothing
/// behind, and `--force` removes nothing, when it is refused. Returns the
/// notes for the user ([`check_run`]); [`train_scene`] prints them.
pub fn check_start(
    dirs: &ConfigDirs,
    scene: &Scene,
    steps: Option<Budget>,
    init_from: &[PathBuf],
    opts: &TrainOptions,
) -> Result<Vec<String>> {
    let check = match load_config(dirs, opts)? {
        Config::Ppo(t) => {
            let check = check_run(&t, scene, steps, opts.allow_no_update)?;
            open_sources(&t, init_from, scene)?;
            check
        }
        Config::Sac(t) => {
            let check = check_run(&t, scene, steps, opts.allow_no_update)?;
            open_sources(&t, init_from, scene)?;
            check
        }
    };
    Ok(check.notes)
}

/// Refuse to overwrite a run by accident (ML-Agents' behaviour). The caller
/// holds the folder's lock, so `--force` never removes a run in use.
pub fn prepare_run_dir(run_dir: &Path, resume: bool, force: bool) -> Result<()> {
    if resume {
        if !run_dir.is_dir() {
            bail!("--resume: there is no run folder {}", run_dir.display());
        }
    } else if run_dir.exists() {
        if force {
            std::fs::remove_dir_all(run_dir)
                .with_context(|| format!("cannot remove {}", run_dir.display()))?;
        } else {
            bail!(
                "the run folder {} exists; use --resume to continue it, --force to replace it, or another --run-id",
                run_dir.display()
            );
        }
    }
    Ok(())
}

/// Train `scene` into `run_dir`, write the resolved configuration, and evaluate the result.
#[allow(clippy::too_many_arguments)]
pub fn train_scene(
    dirs: &ConfigDirs,
    scene: Scene,
    run_dir: &Path,
    run_id: &str,
    steps: Option<Budget>,
    init_from: &[PathBuf],
    resume: bool,
    opts: &TrainOptions,
) -> Result<Trained> {
    let config = load_config(dirs, opts)?;
    // Each behaviour's own budget (ML-Agents' max_steps is per behaviour).
    let mut budgets = toml::Table::new();
    for b in &scene.behaviours {
        let species = &b.species.name;
        let budget = Budget::resolve(steps, b.count, || match &config {
            Config::Ppo(c) => c.config.budget(species, scene.phase),
            Config::Sac(c) => c.config.budget(species, scene.phase),
        });
        budgets.insert(b.name.clone(), (budget as i64).into());
    }
    let config_toml = if resume {
        None
    } else {
        for note in check_start(dirs, &scene, steps, init_from, opts)? {
            eprintln!("{note}");
        }
        let mut resolved = toml::Table::new();
        let mut run = toml::Table::new();
        run.insert("run_id".into(), run_id.into());
        run.insert("algo".into(), opts.algo.as_str().into());
        run.insert("scene".into(), scene.id.clone().into());
        run.insert("phase".into(), scene.phase.as_str().into());
        run.insert("seed".into(), (opts.seed as i64).into());
        run.insert("steps".into(), budgets.clone().into());
        run.insert("backend".into(), opts.backend.as_str().into());
        run.insert(
            "instruction_set".into(),
            deepfoids_learn::kernels::instruction_set().into(),
        );
        if !init_from.is_empty() {
            let runs: Vec<toml::Value> = init_from
                .iter()
                .map(|i| i.display().to_string().into())
                .collect();
            run.insert("init_from".into(), runs.into());
        }
        resolved.insert("run".into(), run.into());
        match &config {
            Config::Ppo(c) => resolved.insert("ppo".into(), toml::Value::try_from(&c.config)?),
            Config::Sac(c) => resolved.insert("sac".into(), toml::Value::try_from(&c.config)?),
        };
        resolved.insert("scene".into(), toml::Value::try_from(&scene)?);
        Some(toml::to_string_pretty(&resolved)?)
    };
    eprintln!(
        "training {} on {} ({} phase) into {}",
        opts.algo.as_str(),
        scene.id,
        scene.phase.as_str(),
        run_dir.display()
    );
    let args = RunArgs {
        scene: scene.clone(),
        run_dir: run_dir.to_path_buf(),
        run_id: run_id.to_string(),
        seed: opts.seed,
        steps,
        resume,
        init_from: init_from.to_vec(),
        backend: opts.backend,
        progress: if opts.quiet {
            ProgressMode::Quiet
        } else {
            ProgressMode::Auto
        },
        progress_sink: None,
        save: true,
        config_toml,
    };
    let outcome = config.train(args)?;
    print_training(&outcome);
    let summary = if opts.eval_seconds > 0.0 {
        Some(evaluate_run(scene, run_dir, opts)?)
    } else {
        None
    };
    Ok(Trained {
        run_dir: run_dir.to_path_buf(),
        outcome,
        summary,
    })
}

/// The mean of the first and of the last `k` points of a curve.
pub fn curve_ends(curve: &[(u64, f64)], k: usize) -> Option<(f64, f64)> {
    if curve.is_empty() {
        return None;
    }
    let k = k.min(curve.len().div_ceil(2)).max(1);
    let mean = |s: &[(u64, f64)]| s.iter().map(|x| x.1).sum::<f64>() / s.len() as f64;
    Some((mean(&curve[..k]), mean(&curve[curve.len() - k..])))
}

fn print_training(o: &TrainOutcome) {
    let t = &o.timing;
    let total = (t.env + t.inference + t.update).as_secs_f64().max(1e-9);
    println!(
        "trained {} agent steps in {:.0} s ({:.0} agent-steps/s): environment {:.0} %, inference {:.0} %, updates {:.0} %",
        o.steps_this_run,
        o.wall_seconds,
        o.steps_this_run as f64 / o.wall_seconds.max(1e-9),
        100.0 * t.env.as_secs_f64() / total,
        100.0 * t.inference.as_secs_f64() / total,
        100.0 * t.update.as_secs_f64() / total
    );
    if let Some((a, b)) = curve_ends(&o.curve, 3) {
        println!(
            "learning curve (mean reward per decision): start {a:.3} → end {b:.3} over {} log points",
            o.curve.len()
        );
    }
    if let Some((a, b)) = curve_ends(&o.episode_curve, 3) {
        println!("cumulative reward per episode: start {a:.1} → end {b:.1}");
    }
    if let Some(f) = &o.final_dir {
        println!(
            "final policy: {} (weights, state.json, <behaviour>.onnx)",
            f.display()
        );
    }
}

/// Evaluate a run's final policy with sampled actions (SPEC §9; the
/// environment's seed also seeds the sampling); writes `<run>/eval/`.
pub fn evaluate_run(scene: Scene, run_dir: &Path, opts: &TrainOptions) -> Result<Summary> {
    let env_seed = opts.seed.wrapping_add(1_000_003);
    let rerun = EvalRunArgs {
        scene: scene.source.display().to_string(),
        phase: scene.phase.as_str().to_string(),
        seed: env_seed,
        policy: run_dir.display().to_string(),
        checkpoint: None,
        stochastic: true,
        warmup: 0.0,
        seconds: opts.eval_seconds,
        fish: None,
    };
    let mut env = Env::new(scene, env_seed);
    let mut policy = load_trained(run_dir, None, &env, false, env_seed)?;
    let eval = evaluate(&mut env, &mut policy, 0.0, opts.eval_seconds, |_, _, _| {})?;
    let scene_id = env.scene().id.clone();
    let name = policy.name();
    let meta = EvalMeta {
        scene: &scene_id,
        policy: &name,
        seed: opts.seed,
        phase: env.scene().phase.as_str(),
        deterministic: false,
        warmup: 0.0,
        seconds: eval.seconds,
        wall_seconds: eval.wall_seconds,
        ticks_per_second: eval.recorder.samples.len() as f64 / eval.wall_seconds.max(1e-9),
        rerun,
    };
    let summary = write_outputs(&run_dir.join("eval"), &env, &eval, &meta)?;
    print_table(&meta, &summary);
    Ok(summary)
}
