//! `deepfoids replay`: watch a school. Writes one self-contained HTML file
//! (the viewer of `deepfoids_replay`, three.js embedded) and, on request, a GIF
//! of the top and side views.
//!
//! Where the school comes from:
//! - `--scene S --policy P`: simulated now, as `eval` would (same loop, same P/M).
//! - `--from <simulate folder>`: its `trajectories.csv`, in the cage and with
//!   the fish of the scene and seed in its `simulate.json` (or `--scene`/`--seed`).
//!   The CSV holds no chases or reward terms; the viewer says so.
//! - `--from <eval folder>`: eval keeps no per-fish trajectories, so the run is
//!   simulated again from the scene, policy and seed in its `summary.json`
//!   (seeded runs are deterministic), and every tick's P and M must equal its
//!   `metrics.csv` — a changed policy or code is an error, not a different film.

use crate::args::whole;
use crate::args::{PolicyArgs, SceneArgs, from_rerun, parse_phase, rerun};
use anyhow::{Context, Result, bail};
use clap::Args;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use deepfoids_env::limits::MAX_FPS;
use deepfoids_env::memory;
use deepfoids_env::{ConfigDirs, Env, GridFormat, Phase};
use deepfoids_experiments::evaluate::{Evaluation, RunArgs};
use deepfoids_experiments::replays::{
    MIN_CSV_ROW, PAGE_BYTES_PER_FISH_FRAME, bytes, check_pm, check_recording, describe,
    evaluate_recorded, info, read_json, read_pm, warn_if_large, write_page,
};
use deepfoids_experiments::{bounds, make_policy};
use deepfoids_replay::{GifView, check_gif, write_gif};
use deepfoids_replay::{Recording, from_trajectories};
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct ReplayArgs {
    /// Scene id (see `deepfoids scenes`) or path to a scene TOML file; with --from, only for a
    /// simulate folder without simulate.json
    #[arg(long, value_name = "ID|PATH")]
    pub scene: Option<String>,
    /// Random seed (with --from: only for a simulate folder without simulate.json)
    #[arg(value_parser = whole::<u64>, long)]
    pub seed: Option<u64>,
    /// Reward weights of this phase (the reward terms shown)
    #[arg(long, default_value = "pretrain", value_parser = parse_phase)]
    pub phase: Phase,
    /// Swim this many fish instead of the scene's count (a scene of one group only;
    /// with --from: only for a simulate folder without simulate.json)
    #[arg(long, value_name = "N", value_parser = whole::<usize>)]
    pub fish_count: Option<usize>,
    #[command(flatten)]
    pub policy_args: PolicyArgs,
    /// Simulated seconds
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Replay a saved run: a `simulate` output folder (its trajectories.csv) or an `eval` output
    /// folder (simulated again from its summary.json and checked against its metrics.csv)
    #[arg(long, value_name = "DIR", conflicts_with_all = ["seconds", "policy"])]
    pub from: Option<PathBuf>,
    /// Frames per simulated second stored (rounded to whole ticks; the viewer interpolates)
    #[arg(long, default_value_t = 5.0)]
    pub fps: f64,
    /// Output HTML file
    #[arg(long, default_value = "replay.html", value_name = "HTML")]
    pub out: PathBuf,
    /// Also write an animated GIF (top and side views) for papers, slides and issues
    #[arg(long, value_name = "GIF")]
    pub gif: Option<PathBuf>,
    /// Views in the GIF: top, side, or both side by side
    #[arg(long, default_value = "both", value_parser = gif_view())]
    pub gif_view: GifView,
    /// Width of each GIF view in pixels (the cage fills it)
    #[arg(value_parser = whole::<u32>, long, default_value_t = 360, value_name = "PX")]
    pub gif_size: u32,
    /// GIF playback speed relative to real time
    #[arg(long, default_value_t = 1.0, value_name = "X")]
    pub gif_speed: f64,
}

/// `--gif-view`: top, side or both, listed in `--help` and in the error.
fn gif_view() -> impl TypedValueParser<Value = GifView> {
    PossibleValuesParser::new(GifView::ALL.map(|(name, _)| name)).try_map(|s| s.parse::<GifView>())
}

pub fn run(dirs: &ConfigDirs, args: &ReplayArgs) -> Result<()> {
    let (policy_name, policy_args) = args.policy_args.resolve("foids")?;
    bounds::positive_at_most("--fps", args.fps, MAX_FPS, "frames/s")?;
    bounds::out_file("--out", &args.out)?;
    if let Some(gif) = &args.gif {
        bounds::out_file("--gif", gif)?;
        check_gif(args.gif_size, args.gif_speed)?;
    }
    let rec = match &args.from {
        Some(dir) => from_folder(dirs, dir, args)?,
        None => {
            let Some(scene) = &args.scene else {
                bail!(
                    "give --scene (and --policy) to simulate a school, or --from <simulate or eval folder> to replay one"
                );
            };
            bounds::seconds("--seconds", args.seconds)?;
            let sa = SceneArgs {
                scene: scene.clone(),
                seed: args.seed.unwrap_or(0),
                phase: args.phase,
                fish_count: args.fish_count,
            };
            let run = rerun(&sa, &policy_name, &policy_args, 0.0, args.seconds);
            simulate(dirs, &run, args.fps, "simulated by deepfoids replay")?.0
        }
    };
    let size = write_page(&args.out, &rec)?;
    println!("{}", describe(&args.out, &rec, &size));
    warn_if_large(&size);
    if let Some(gif) = &args.gif {
        let size = write_gif(gif, &rec, args.gif_view, args.gif_size, args.gif_speed)?;
        println!(
            "wrote {}: {} frames, {}",
            gif.display(),
            rec.frames(),
            bytes(size)
        );
    }
    Ok(())
}

/// Simulate `run` as `eval` does, recording `fps` frames per second.
fn simulate(
    dirs: &ConfigDirs,
    run: &RunArgs,
    fps: f64,
    source: &str,
) -> Result<(Recording, Evaluation)> {
    let (sa, opts) = from_rerun(run)?;
    let scene = sa.load(dirs)?;
    let mut env = Env::with_grid_format(scene, sa.seed, GridFormat::Bytes);
    check_recording(&env, run.seconds, fps)?;
    let mut policy = make_policy(dirs, &run.policy, sa.seed, &env, &opts.options())?;
    let info = info(&env, &policy.name(), source, vec![]);
    let (eval, rec) = evaluate_recorded(
        &mut env,
        policy.as_mut(),
        run.warmup,
        run.seconds,
        Some(info),
        fps,
    )?;
    let rec = rec.context("the evaluation recorded nothing")?;
    Ok((rec, eval))
}

fn from_folder(dirs: &ConfigDirs, dir: &Path, args: &ReplayArgs) -> Result<Recording> {
    if !dir.is_dir() {
        bail!("--from {}: no such folder", dir.display());
    }
    let csv = dir.join("trajectories.csv");
    let summary = dir.join("summary.json");
    if csv.is_file() {
        from_simulate(dirs, dir, &csv, args)
    } else if summary.is_file() {
        from_eval(dirs, dir, &summary, args.fps)
    } else {
        bail!(
            "--from {}: neither trajectories.csv (written by simulate) nor summary.json (written by eval) is there",
            dir.display()
        )
    }
}

fn from_simulate(
    dirs: &ConfigDirs,
    dir: &Path,
    csv: &Path,
    args: &ReplayArgs,
) -> Result<Recording> {
    let meta_path = dir.join("simulate.json");
    let (sa, policy) = if meta_path.is_file() {
        let run: RunArgs = read_json(&meta_path)?;
        if args.scene.is_some() || args.seed.is_some() || args.fish_count.is_some() {
            bail!(
                "--scene, --seed and --fish-count come from {} here; drop them",
                meta_path.display()
            );
        }
        (from_rerun(&run)?.0, run.policy)
    } else {
        let Some(scene) = &args.scene else {
            bail!(
                "{} is missing (simulate writes it since replay exists): give --scene and --seed of the run that wrote {}",
                meta_path.display(),
                csv.display()
            );
        };
        let sa = SceneArgs {
            scene: scene.clone(),
            seed: args.seed.unwrap_or(0),
            phase: args.phase,
            fish_count: args.fish_count,
        };
        (sa, "unknown policy".to_string())
    };
    let scene = sa.load(dirs)?;
    let env = Env::new(scene, sa.seed);
    let csv_bytes = std::fs::metadata(csv)
        .with_context(|| format!("cannot read {}", csv.display()))?
        .len();
    deepfoids_env::memory::check(
        &format!("replaying {} ({})", csv.display(), memory::human(csv_bytes)),
        csv_bytes + csv_bytes / MIN_CSV_ROW * PAGE_BYTES_PER_FISH_FRAME,
        "replay a shorter simulation",
    )?;
    let text =
        std::fs::read_to_string(csv).with_context(|| format!("cannot read {}", csv.display()))?;
    let source = format!("replayed from {}", csv.display());
    let notes = vec!["simulate's CSV holds no chases or reward terms".to_string()];
    let info = info(&env, &policy, &source, notes);
    Ok(from_trajectories(
        &csv.display().to_string(),
        &text,
        &env,
        info,
        args.fps,
    )?)
}

fn from_eval(dirs: &ConfigDirs, dir: &Path, summary: &Path, fps: f64) -> Result<Recording> {
    #[derive(serde::Deserialize)]
    struct Summary {
        rerun: Option<RunArgs>,
    }
    let s: Summary = read_json(summary)?;
    let Some(run) = s.rerun else {
        bail!(
            "{} does not record how to run the evaluation again (written before replay existed): replay it with --scene, --seed and --policy",
            summary.display()
        );
    };
    let metrics = dir.join("metrics.csv");
    let saved = read_pm(&metrics)?;
    let source = format!(
        "simulated again from {} (P and M match its metrics.csv)",
        summary.display()
    );
    let (rec, eval) = simulate(dirs, &run, fps, &source)
        .with_context(|| format!("re-running the evaluation in {}", dir.display()))?;
    check_pm(&metrics, &saved, &eval)?;
    Ok(rec)
}
