//! `deepfoids pipeline`: the two-step scheme of thesis §4.5.2 — pretrain a
//! species in its default scene with the pretraining weights and budget, then
//! transfer-learn from that policy into every scene of the species (the default
//! included) with the transfer weights, evaluate each, and tabulate. With
//! `--species all`: pretrain every species, then transfer into every scene,
//! mixed ones (`three_species`) included, each behaviour from its species'
//! pretrained policy (`--init-from` with several runs).
//!
//! Stages live in `<runs>/<pipeline>/pretrain` (`pretrain-<species>` with
//! `all`) and `…/transfer-<scene>`; a stage with a final policy is reused and
//! one with checkpoints is resumed, so an interrupted pipeline continues where
//! it stopped.

use crate::load_scene;
use crate::training::{TrainOptions, curve_ends, evaluate_run, train_scene};
use anyhow::{Context, Result, bail};
use deepfoids_env::config::ConfigError;
use deepfoids_env::metrics::Summary;
use deepfoids_env::{ConfigDirs, Phase, Scene};
use deepfoids_io::write_atomic;
use deepfoids_learn::Budget;
use std::path::Path;

/// What the pipeline trains (the options of `deepfoids pipeline`).
#[derive(Clone, Debug)]
pub struct PipelineOptions {
    /// Species to train: its default scene, then every scene with only this
    /// species; `all`: every species, then every scene (mixed ones included).
    pub species: String,
    /// Pretraining budget per behaviour (agent decisions; `None`: the thesis').
    pub pretrain_steps: Option<u64>,
    /// Transfer budget per behaviour and scene (`None`: the thesis').
    pub transfer_steps: Option<u64>,
    /// Only these target scenes (empty: all of the species, or all).
    pub scenes: Vec<String>,
    /// Run name (`None`: `pipeline-<algo>-<species>-s<seed>`).
    pub run_id: Option<String>,
    pub opts: TrainOptions,
}

struct Row {
    scene: String,
    phase: &'static str,
    steps: u64,
    train_reward: Option<f64>,
    summary: Summary,
}

pub fn run(dirs: &ConfigDirs, args: &PipelineOptions) -> Result<()> {
    let all = args.species == "all";
    let (species, mut targets) = species_and_targets(dirs, args)?;
    // The default scenes first, as the thesis does.
    let defaults: Vec<String> = species.iter().map(|s| format!("{s}_default")).collect();
    targets.sort_by_key(|id| (!defaults.contains(id), id.clone()));
    let opts = &args.opts;
    let id = args.run_id.clone().unwrap_or_else(|| {
        format!(
            "pipeline-{}-{}-s{}",
            opts.algo.as_str(),
            args.species,
            opts.seed
        )
    });
    for (flag, steps) in [
        ("--pretrain-steps", args.pretrain_steps),
        ("--transfer-steps", args.transfer_steps),
    ] {
        if let Some(s) = steps {
            crate::bounds::train_steps(flag, s)?;
        }
    }
    // Every stage's budget and memory before the first trains (issue 25): a
    // transfer stage that cannot update is refused now, not hours from now.
    // Its sources do not exist yet; the stage checks them when it starts.
    for (ids, phase, steps) in [
        (&defaults, Phase::Pretrain, args.pretrain_steps),
        (&targets, Phase::Transfer, args.transfer_steps),
    ] {
        for scene_id in ids {
            let scene = load_scene(dirs, scene_id, phase)?;
            crate::training::check_start(dirs, &scene, steps.map(Budget::Steps), &[], opts)
                .with_context(|| format!("pipeline stage {scene_id} ({})", phase.as_str()))?;
        }
    }
    let root = opts.runs_dir.join(&id);
    // One process per pipeline folder for the life of this one (issue 13
    // item 2); each stage's run folder is locked as well while it trains.
    let _lock = crate::lock_dir(&root)?;
    std::fs::create_dir_all(&root)?;
    eprintln!(
        "pipeline {id}: pretrain in {}, then transfer into {}",
        defaults.join(", "),
        targets.join(", ")
    );

    let mut rows = Vec::new();
    let mut pretrained: Vec<(String, std::path::PathBuf)> = Vec::new();
    for s in &species {
        let stage_name = if all {
            format!("pretrain-{s}")
        } else {
            "pretrain".to_string()
        };
        let dir = root.join(&stage_name);
        let scene = load_scene(dirs, &format!("{s}_default"), Phase::Pretrain)?;
        rows.push(stage(
            dirs,
            scene,
            &dir,
            &format!("{id}/{stage_name}"),
            args.pretrain_steps,
            &[],
            args,
        )?);
        pretrained.push((s.clone(), dir));
    }
    for target in &targets {
        let scene = load_scene(dirs, target, Phase::Transfer)?;
        // Each species of the scene from its own pretrained policy.
        let init: Vec<std::path::PathBuf> = scene
            .species_names()
            .iter()
            .map(|sp| {
                pretrained
                    .iter()
                    .find(|(p, _)| p == sp)
                    .map(|(_, d)| d.clone())
                    .ok_or_else(|| {
                        anyhow::anyhow!(
                            "scene {target} holds {sp}, which this pipeline does not pretrain"
                        )
                    })
            })
            .collect::<Result<_>>()?;
        let dir = root.join(format!("transfer-{target}"));
        rows.push(stage(
            dirs,
            scene,
            &dir,
            &format!("{id}/transfer-{target}"),
            args.transfer_steps,
            &init,
            args,
        )?);
    }

    let (md, csv) = tables(&rows);
    write_atomic(root.join("summary.md"), md.as_bytes())?;
    write_atomic(root.join("summary.csv"), csv.as_bytes())?;
    println!("\n{md}");
    println!("wrote {}/summary.md and summary.csv", root.display());
    Ok(())
}

/// The species to pretrain and the scenes to transfer into: every scene
/// (`all`), or those holding only this species.
fn species_and_targets(
    dirs: &ConfigDirs,
    args: &PipelineOptions,
) -> Result<(Vec<String>, Vec<String>)> {
    dirs.check_root()?;
    let known = dirs.list("species");
    let all = args.species == "all";
    let species: Vec<String> = if all {
        known.clone()
    } else if known.iter().any(|s| s == &args.species) {
        vec![args.species.clone()]
    } else {
        // Say why when a name is there but not as a file (a folder `x.toml/`).
        if let Err(e @ ConfigError::NotAFile { .. }) = dirs.species(&args.species, None) {
            return Err(e.into());
        }
        bail!(
            "unknown species `{}`; available: {}, or all",
            args.species,
            known.join(", ")
        );
    };
    // Target scenes: every scene (all), or those holding only this species.
    let fits = |s: &Scene| all || s.species_names() == species;
    let targets: Vec<String> = if args.scenes.is_empty() {
        dirs.list("scenes")
            .into_iter()
            .filter(|id| {
                Scene::load(dirs, id, Phase::Transfer)
                    .map(|s| fits(&s))
                    .unwrap_or(false)
            })
            .collect()
    } else {
        for id in &args.scenes {
            let s = load_scene(dirs, id, Phase::Transfer)?;
            if !fits(&s) {
                bail!(
                    "scene {id} holds {}, not only {}",
                    s.species_names().join(", "),
                    args.species
                );
            }
        }
        args.scenes.clone()
    };
    Ok((species, targets))
}

/// `summary.md` and `summary.csv`: one row per stage.
fn tables(rows: &[Row]) -> (String, String) {
    let mut md = String::from(
        "| scene | phase | agent steps | train reward/decision (end) | eval reward/decision | P | M | state | boundary coll./fish-h | neighbour coll./fish-h |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut csv = String::from(
        "scene,phase,agent_steps,train_reward_end,eval_reward,p,m,state,boundary_per_fish_hour,neighbour_per_fish_hour\n",
    );
    for r in rows {
        let s = &r.summary;
        let train = |f: fn(f64) -> String, none: &str| r.train_reward.map_or(none.into(), f);
        // The cells of both tables: the Markdown one rounds for reading.
        let cells = |train: String, d: usize, c: usize| {
            [
                r.scene.clone(),
                r.phase.to_string(),
                r.steps.to_string(),
                train,
                format!("{:.d$}", s.reward_per_decision),
                format!("{:.d$}", s.p_mean),
                format!("{:.d$}", s.m_mean),
                s.dominant_state.as_str().to_string(),
                format!("{:.c$}", s.boundary_collisions_per_fish_hour),
                format!("{:.c$}", s.neighbour_collisions_per_fish_hour),
            ]
        };
        let md_row = cells(train(|x| format!("{x:.3}"), "–"), 3, 1);
        let csv_row = cells(train(|x| format!("{x:.5}"), ""), 5, 3);
        md.push_str(&format!("| {} |\n", md_row.join(" | ")));
        csv.push_str(&format!("{}\n", csv_row.join(",")));
    }
    (md, csv)
}

/// One stage: reuse a finished run, resume an interrupted one, or train afresh.
fn stage(
    dirs: &ConfigDirs,
    scene: Scene,
    dir: &Path,
    run_id: &str,
    steps: Option<u64>,
    init_from: &[std::path::PathBuf],
    args: &PipelineOptions,
) -> Result<Row> {
    let phase = scene.phase;
    let scene_id = scene.id.clone();
    let _lock = crate::lock_dir(dir)?;
    let finished = dir.join("final").join("state.json").is_file();
    let (summary, train_reward, agent_steps) = if finished {
        eprintln!("{run_id}: finished before, reusing it");
        let state = deepfoids_learn::checkpoint::RunState::load(&dir.join("final"))?;
        let summary = match read_summary(&dir.join("eval").join("summary.json")) {
            Some(s) => s,
            None => evaluate_run(scene, dir, &args.opts)?,
        };
        (summary, None, state.agent_steps)
    } else {
        let resume = !deepfoids_learn::checkpoint::checkpoints(dir).is_empty();
        if !resume && dir.exists() {
            // Stopped before its first checkpoint: start it again from nothing
            // (its logs would otherwise hold a second copy of the early steps).
            std::fs::remove_dir_all(dir)
                .with_context(|| format!("cannot remove {}", dir.display()))?;
        }
        let mut opts = args.opts.clone();
        if opts.eval_seconds <= 0.0 {
            opts.eval_seconds = 60.0;
        }
        let budget = steps.map(Budget::Steps);
        let t = train_scene(dirs, scene, dir, run_id, budget, init_from, resume, &opts)?;
        let end = curve_ends(&t.outcome.curve, 3).map(|x| x.1);
        (t.summary.expect("evaluated"), end, t.outcome.agent_steps)
    };
    Ok(Row {
        scene: scene_id,
        phase: phase.as_str(),
        steps: agent_steps,
        train_reward,
        summary,
    })
}

fn read_summary(path: &Path) -> Option<Summary> {
    #[derive(serde::Deserialize)]
    struct File {
        summary: Summary,
    }
    let text = std::fs::read_to_string(path).ok()?;
    serde_json::from_str::<File>(&text).ok().map(|f| f.summary)
}
