//! `deepfoids pipeline`: the two-step scheme of thesis §4.5.2 for one species —
//! pretrain in its default scene with the pretraining weights and budget, then
//! transfer-learn from that policy into every scene of the species (the default
//! included) with the transfer weights, evaluate each, and tabulate.
//!
//! Stages live in `<runs>/<pipeline>/pretrain` and `…/transfer-<scene>`; a stage
//! with a final policy is reused and one with checkpoints is resumed, so an
//! interrupted pipeline continues where it stopped.

use super::load_scene;
use super::train::{algo_name, curve_ends, evaluate_run, train_scene};
use crate::cli::PipelineArgs;
use crate::io::write_atomic;
use anyhow::{Result, bail};
use deepfoids_env::metrics::Summary;
use deepfoids_env::{ConfigDirs, Phase, Scene};
use std::path::Path;

struct Row {
    scene: String,
    phase: &'static str,
    steps: u64,
    train_reward: Option<f64>,
    summary: Summary,
}

pub fn run(dirs: &ConfigDirs, args: &PipelineArgs) -> Result<()> {
    let species = args.species.as_str();
    let known = dirs.list("species");
    if !known.iter().any(|s| s == species) {
        bail!(
            "unknown species `{species}`; available: {}",
            known.join(", ")
        );
    }
    let default = format!("{species}_default");
    let pretrain_scene = load_scene(dirs, &default, Phase::Pretrain)?;
    let only_this = |s: &Scene| s.species_names() == [species.to_string()];
    let mut targets: Vec<String> = if args.scenes.is_empty() {
        dirs.list("scenes")
            .into_iter()
            .filter(|id| {
                Scene::load(dirs, id, Phase::Transfer)
                    .map(|s| only_this(&s))
                    .unwrap_or(false)
            })
            .collect()
    } else {
        for id in &args.scenes {
            let s = load_scene(dirs, id, Phase::Transfer)?;
            if !only_this(&s) {
                bail!(
                    "scene {id} holds {}, not only {species}",
                    s.species_names().join(", ")
                );
            }
        }
        args.scenes.clone()
    };
    // The default scene first, as the thesis does.
    targets.sort_by_key(|id| (id != &default, id.clone()));
    let opts = &args.opts;
    let id = args
        .run_id
        .clone()
        .unwrap_or_else(|| format!("pipeline-{}-{species}-s{}", algo_name(opts.algo), opts.seed));
    let root = opts.runs_dir.join(&id);
    std::fs::create_dir_all(&root)?;
    eprintln!(
        "pipeline {id}: pretrain in {default}, then transfer into {}",
        targets.join(", ")
    );

    let mut rows = Vec::new();
    let pretrain_dir = root.join("pretrain");
    rows.push(stage(
        dirs,
        pretrain_scene,
        &pretrain_dir,
        &format!("{id}/pretrain"),
        args.pretrain_steps,
        None,
        args,
    )?);
    for target in &targets {
        let scene = load_scene(dirs, target, Phase::Transfer)?;
        let dir = root.join(format!("transfer-{target}"));
        rows.push(stage(
            dirs,
            scene,
            &dir,
            &format!("{id}/transfer-{target}"),
            args.transfer_steps,
            Some(&pretrain_dir),
            args,
        )?);
    }

    let mut md = String::from(
        "| scene | phase | agent steps | train reward/decision (end) | eval reward/decision | P | M | state | boundary coll./fish-h | neighbour coll./fish-h |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut csv = String::from(
        "scene,phase,agent_steps,train_reward_end,eval_reward,p,m,state,boundary_per_fish_hour,neighbour_per_fish_hour\n",
    );
    for r in &rows {
        let s = &r.summary;
        let train = r
            .train_reward
            .map_or("–".to_string(), |x| format!("{x:.3}"));
        md.push_str(&format!(
            "| {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {} | {:.1} | {:.1} |\n",
            r.scene,
            r.phase,
            r.steps,
            train,
            s.reward_per_decision,
            s.p_mean,
            s.m_mean,
            s.dominant_state.as_str(),
            s.boundary_collisions_per_fish_hour,
            s.neighbour_collisions_per_fish_hour
        ));
        csv.push_str(&format!(
            "{},{},{},{},{:.5},{:.5},{:.5},{},{:.3},{:.3}\n",
            r.scene,
            r.phase,
            r.steps,
            r.train_reward.map_or(String::new(), |x| format!("{x:.5}")),
            s.reward_per_decision,
            s.p_mean,
            s.m_mean,
            s.dominant_state.as_str(),
            s.boundary_collisions_per_fish_hour,
            s.neighbour_collisions_per_fish_hour
        ));
    }
    write_atomic(root.join("summary.md"), md.as_bytes())?;
    write_atomic(root.join("summary.csv"), csv.as_bytes())?;
    println!("\n{md}");
    println!("wrote {}/summary.md and summary.csv", root.display());
    Ok(())
}

/// One stage: reuse a finished run, resume an interrupted one, or train afresh.
fn stage(
    dirs: &ConfigDirs,
    scene: Scene,
    dir: &Path,
    run_id: &str,
    steps: Option<u64>,
    init_from: Option<&Path>,
    args: &PipelineArgs,
) -> Result<Row> {
    let phase = scene.phase;
    let scene_id = scene.id.clone();
    let finished = dir.join("final").join("state.json").is_file();
    let (summary, train_reward, agent_steps) = if finished {
        eprintln!("{run_id}: finished before, reusing it");
        let state = deepfoids_ppo::checkpoint::RunState::load(&dir.join("final"))?;
        let summary = match read_summary(&dir.join("eval").join("summary.json")) {
            Some(s) => s,
            None => evaluate_run(scene, dir, &args.opts)?,
        };
        (summary, None, state.agent_steps)
    } else {
        let resume = !deepfoids_ppo::checkpoint::checkpoints(dir).is_empty();
        let mut opts = args.opts.clone();
        if opts.eval_seconds <= 0.0 {
            opts.eval_seconds = 60.0;
        }
        let t = train_scene(
            dirs,
            scene,
            dir,
            run_id,
            steps,
            init_from.map(Path::to_path_buf),
            resume,
            &opts,
        )?;
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
