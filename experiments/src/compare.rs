//! `deepfoids compare`: runs side by side (the thesis' PPO-vs-SAC comparison,
//! §4.5.6, Table 4.5, Fig. 4.14, on any scene):
//!
//! * `learning_curves.png`: mean cumulative reward per episode against agent
//!   steps, one line per run (and behaviour), smoothed by TensorBoard's
//!   debiased exponential moving average, the raw values faint behind;
//! * `reward_terms.png`: the reward per decision and each of its seven terms,
//!   one panel each, the same way;
//! * `compare.md` and `compare.csv`: every run's final policy evaluated
//!   with sampled actions (or their means) in the same scene and seeds — mean reward and each term
//!   per decision, P, M, state shares, collisions per fish-hour, nearest-neighbour
//!   distance — with the training's wall-clock time and agent-steps/s.

use crate::evaluate::{PALETTE, evaluate};
use crate::plot::{FONT, draw_legend, legend_line, pe, save_png};
use crate::{bounds, load_scene, load_trained, lock_dir};
use anyhow::{Context, Result, bail};
use deepfoids_env::limits::MAX_SEEDS;
use deepfoids_env::metrics::{SchoolState, Summary};
use deepfoids_env::{ConfigDirs, Env, GridFormat, N_TERMS, TERM_NAMES};
use deepfoids_learn::checkpoint::{RunState, policy_dir};
use plotters::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What to compare and where (the options of `deepfoids compare`).
#[derive(Clone, Debug)]
pub struct CompareOptions {
    /// Run folders (two or more).
    pub runs: Vec<PathBuf>,
    /// Scene to evaluate every run in (`None`: the first run's).
    pub scene: Option<String>,
    /// Simulated seconds per evaluation.
    pub seconds: f64,
    /// Evaluation seeds `0..seeds`, the same for every run.
    pub seeds: u64,
    /// Weight of the exponential moving average of the curves, in [0, 1)
    /// (TensorBoard's smoothing).
    pub smoothing: f64,
    /// Output folder.
    pub out: PathBuf,
    /// Evaluate with the policies' means instead of sampled actions (SPEC §9).
    pub deterministic: bool,
}

/// Logged scalars: `(behaviour, tag)` → `(step, value)` in logging order.
type Scalars = BTreeMap<(String, String), Vec<(u64, f64)>>;

/// A run's name, state and logged scalars.
struct Run {
    label: String,
    dir: PathBuf,
    state: RunState,
    scalars: Scalars,
}

/// One run's evaluation, averaged over seeds.
#[derive(Default)]
struct Row {
    reward: f64,
    terms: [f64; N_TERMS],
    p: f64,
    p_sd: f64,
    m: f64,
    m_sd: f64,
    shares: [f64; 4],
    boundary: f64,
    neighbour: f64,
    nn_bl: f64,
    speed_bl: f64,
}

fn read_scalars(dir: &Path) -> Result<Scalars> {
    let path = dir.join("scalars.csv");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {} (is it a training run?)", path.display()))?;
    let mut out = Scalars::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.splitn(4, ',').collect();
        let parsed = match f.as_slice() {
            [b, step, tag, value] => step
                .parse::<u64>()
                .ok()
                .zip(value.parse::<f64>().ok())
                .map(|(s, v)| (b.to_string(), tag.to_string(), s, v)),
            _ => None,
        };
        match parsed {
            Some((b, tag, s, v)) => out.entry((b, tag)).or_default().push((s, v)),
            None => bail!(
                "{} line {}: expected `behaviour,step,tag,value`, got `{line}`",
                path.display(),
                i + 1
            ),
        }
    }
    Ok(out)
}

/// TensorBoard's smoothing: an exponential moving average with weight `w`,
/// debiased (divided by `1 − wᵏ`) so the first points are not pulled to 0.
pub fn ema(values: &[f64], w: f64) -> Vec<f64> {
    let mut last = 0.0;
    let mut out = Vec::with_capacity(values.len());
    for (k, v) in values.iter().enumerate() {
        last = last * w + (1.0 - w) * v;
        let debias = 1.0 - w.powi(k as i32 + 1);
        out.push(if debias > 0.0 { last / debias } else { *v });
    }
    out
}

fn load_run(path: &Path) -> Result<Run> {
    let dir = policy_dir(path, None)?;
    let state = RunState::load(&dir)?;
    let label = format!(
        "{} ({})",
        path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into_owned()
        ),
        state.algo
    );
    Ok(Run {
        label,
        dir: path.to_path_buf(),
        scalars: read_scalars(path)?,
        state,
    })
}

pub fn run(dirs: &ConfigDirs, args: &CompareOptions) -> Result<()> {
    if args.runs.len() < 2 {
        bail!(
            "compare needs at least two run folders, got {}",
            args.runs.len()
        );
    }
    bounds::seconds("--seconds", args.seconds)?;
    bounds::count_within("--seeds", args.seeds, [1, MAX_SEEDS], "seeds")?;
    if !(0.0..1.0).contains(&args.smoothing) {
        bail!("--smoothing must lie in [0, 1), got {}", args.smoothing);
    }
    let runs = args
        .runs
        .iter()
        .map(|p| load_run(p))
        .collect::<Result<Vec<_>>>()?;
    let scene_id = args
        .scene
        .clone()
        .unwrap_or_else(|| runs[0].state.scene.clone());
    let scene = load_scene(dirs, &scene_id, runs[0].state.phase)?;
    // Every run must be able to drive the scene before any is evaluated: a
    // mismatch (another species, a missing behaviour) is refused at once, not
    // after minutes of evaluating the runs before it, and writes nothing.
    let probe = Env::with_grid_format(scene.clone(), 0, GridFormat::Bytes);
    for r in &runs {
        load_trained(&r.dir, None, &probe, args.deterministic, 0)
            .with_context(|| format!("{} cannot drive scene {}", r.label, scene.id))?;
    }
    drop(probe);
    let _lock = lock_dir(&args.out)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;

    plot_curves(
        &args.out.join("learning_curves.png"),
        &runs,
        &[(
            "Environment/Cumulative Reward",
            "mean cumulative reward per episode",
        )],
        args.smoothing,
        (1200, 600),
        &format!("Learning curves (EMA {:.2})", args.smoothing),
    )?;
    let mut panels: Vec<(String, String)> = vec![(
        "Environment/Reward per Decision".into(),
        "reward per decision".into(),
    )];
    for t in TERM_NAMES {
        panels.push((format!("Reward/{t}"), t.replace('_', " ")));
    }
    let panels_ref: Vec<(&str, &str)> = panels
        .iter()
        .map(|(a, b)| (a.as_str(), b.as_str()))
        .collect();
    plot_curves(
        &args.out.join("reward_terms.png"),
        &runs,
        &panels_ref,
        args.smoothing,
        (1600, 1300),
        "Reward per decision and its terms",
    )?;

    let mut rows = Vec::new();
    for r in &runs {
        eprintln!(
            "evaluating {} on {} for {} s × {} seeds",
            r.label, scene.id, args.seconds, args.seeds
        );
        let mut summaries = Vec::new();
        for seed in 0..args.seeds {
            let mut env = Env::with_grid_format(scene.clone(), seed, GridFormat::Bytes);
            let mut policy = load_trained(&r.dir, None, &env, args.deterministic, seed)?;
            let eval = evaluate(&mut env, &mut policy, 0.0, args.seconds, |_, _, _| {})?;
            summaries.push(eval.recorder.summary(eval.seconds));
        }
        rows.push(average(&summaries));
    }
    let (md, csv) = table(&runs, &rows, &scene.id, args);
    deepfoids_io::write_atomic(args.out.join("compare.md"), md.as_bytes())?;
    deepfoids_io::write_atomic(args.out.join("compare.csv"), csv.as_bytes())?;
    println!("{md}");
    println!(
        "wrote {}/compare.md, compare.csv, learning_curves.png, reward_terms.png",
        args.out.display()
    );
    Ok(())
}

fn mean_sd(xs: &[f64]) -> (f64, f64) {
    let n = xs.len().max(1) as f64;
    let m = xs.iter().sum::<f64>() / n;
    let var = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n;
    (m, var.sqrt())
}

/// Means over seeds (P and M also their spread over seeds); reward terms per
/// decision weighted by each behaviour's decisions.
fn average(s: &[Summary]) -> Row {
    let n = s.len().max(1) as f64;
    let mut row = Row::default();
    let (p, p_sd) = mean_sd(&s.iter().map(|x| x.p_mean as f64).collect::<Vec<_>>());
    let (m, m_sd) = mean_sd(&s.iter().map(|x| x.m_mean as f64).collect::<Vec<_>>());
    (row.p, row.p_sd, row.m, row.m_sd) = (p, p_sd, m, m_sd);
    for x in s {
        row.reward += x.reward_per_decision / n;
        row.boundary += x.boundary_collisions_per_fish_hour / n;
        row.neighbour += x.neighbour_collisions_per_fish_hour / n;
        row.nn_bl += x.nn_mean_bl as f64 / n;
        row.speed_bl += x.mean_speed_bl as f64 / n;
        for (k, state) in SchoolState::ALL.iter().enumerate() {
            row.shares[k] += x
                .state_share
                .iter()
                .find(|(st, _)| st == state)
                .map_or(0.0, |(_, v)| *v as f64)
                / n;
        }
        let decisions: u64 = x.behaviours.iter().map(|b| b.decisions).sum();
        for b in &x.behaviours {
            let w = b.decisions as f64 / decisions.max(1) as f64;
            for (t, (_, v)) in b.terms_per_decision.iter().enumerate().take(N_TERMS) {
                row.terms[t] += w * v / n;
            }
        }
    }
    row
}

fn table(runs: &[Run], rows: &[Row], scene: &str, args: &CompareOptions) -> (String, String) {
    let mut md = format!(
        "Deterministic evaluation on `{scene}`: {} simulated s × {} seed(s) (0..{}) per run.\n\n",
        args.seconds,
        args.seeds,
        args.seeds - 1
    );
    let states: Vec<&str> = SchoolState::ALL.iter().map(|s| s.as_str()).collect();
    let mut head = vec![
        "run".to_string(),
        "algo".into(),
        "trained on".into(),
        "agent steps".into(),
        "train time (s)".into(),
        "agent-steps/s".into(),
        "reward/decision".into(),
    ];
    head.extend(TERM_NAMES.iter().map(|t| t.to_string()));
    head.extend(["P".into(), "M".into()]);
    head.extend(states.iter().map(|s| format!("{s} %")));
    head.extend([
        "boundary coll./fish-h".into(),
        "neighbour coll./fish-h".into(),
        "nearest neighbour (BL)".into(),
        "speed (BL/s)".into(),
    ]);
    let _ = writeln!(md, "| {} |", head.join(" | "));
    let _ = writeln!(md, "|{}|", vec!["---"; head.len()].join("|"));
    let mut csv = head
        .iter()
        .map(|h| h.replace(',', ";"))
        .collect::<Vec<_>>()
        .join(",")
        + "\n";
    for (r, row) in runs.iter().zip(rows) {
        let st = &r.state;
        let rate = st.agent_steps as f64 / st.wall_seconds.max(1e-9);
        // The run's columns, with `t` decimals for its time and rate and `v` for its reward.
        let run_cells = |name: String, t: usize, v: usize| {
            vec![
                name,
                st.algo.to_string(),
                format!("{} ({})", st.scene, st.phase.as_str()),
                st.agent_steps.to_string(),
                format!("{:.t$}", st.wall_seconds),
                format!("{rate:.t$}"),
                format!("{:.v$}", row.reward),
            ]
        };
        let mut md_cells = run_cells(r.label.clone(), 0, 3);
        let mut csv_cells = run_cells(r.dir.display().to_string(), 1, 5);
        for t in row.terms {
            md_cells.push(format!("{t:.3}"));
            csv_cells.push(format!("{t:.5}"));
        }
        md_cells.push(format!("{:.3} ± {:.3}", row.p, row.p_sd));
        md_cells.push(format!("{:.3} ± {:.3}", row.m, row.m_sd));
        csv_cells.push(format!("{:.4}", row.p));
        csv_cells.push(format!("{:.4}", row.m));
        for s in row.shares {
            md_cells.push(format!("{:.0}", 100.0 * s));
            csv_cells.push(format!("{:.2}", 100.0 * s));
        }
        for (v, d) in [
            (row.boundary, 1),
            (row.neighbour, 1),
            (row.nn_bl, 2),
            (row.speed_bl, 2),
        ] {
            md_cells.push(format!("{v:.d$}"));
            csv_cells.push(format!("{v:.4}"));
        }
        let _ = writeln!(md, "| {} |", md_cells.join(" | "));
        let _ = writeln!(
            csv,
            "{}",
            csv_cells
                .iter()
                .map(|c| c.replace(',', ";"))
                .collect::<Vec<_>>()
                .join(",")
        );
    }
    md.push_str(if args.deterministic {
        "\nEvaluated with the policies' means (deterministic). "
    } else {
        "\nEvaluated with sampled actions (as Unity ML-Agents 1.x inference). "
    });
    md.push_str("P and M: mean ± spread over seeds. Rewards are per agent decision, with the weights of the first run's phase.\n");
    (md, csv)
}

/// One panel per `(tag, title)`, every run's (and behaviour's) curve in it.
fn plot_curves(
    path: &Path,
    runs: &[Run],
    panels: &[(&str, &str)],
    smoothing: f64,
    size: (u32, u32),
    caption: &str,
) -> Result<()> {
    let cols = if panels.len() == 1 { 1 } else { 2 };
    let rows = panels.len().div_ceil(cols);
    save_png(path, size.0, size.1, |root| {
        root.fill(&WHITE).map_err(pe)?;
        let root = root.titled(caption, (FONT, 22)).map_err(pe)?;
        let areas = root.split_evenly((rows, cols));
        for ((tag, title), area) in panels.iter().zip(areas) {
            // Series: (label, colour index, raw points, smoothed points).
            let mut series = Vec::new();
            for (k, r) in runs.iter().enumerate() {
                let behaviours: Vec<&String> = r
                    .scalars
                    .keys()
                    .filter(|(_, t)| t == tag)
                    .map(|(b, _)| b)
                    .collect();
                for b in &behaviours {
                    let pts = &r.scalars[&((*b).clone(), tag.to_string())];
                    let vals: Vec<f64> = pts.iter().map(|p| p.1).collect();
                    let smooth = ema(&vals, smoothing);
                    let label = if behaviours.len() > 1 {
                        format!("{} · {b}", r.label)
                    } else {
                        r.label.clone()
                    };
                    series.push((label, k, pts.clone(), smooth));
                }
            }
            let (mut x_max, mut y_lo, mut y_hi) = (1.0f64, f64::INFINITY, f64::NEG_INFINITY);
            for (_, _, pts, smooth) in &series {
                for (p, s) in pts.iter().zip(smooth) {
                    x_max = x_max.max(p.0 as f64);
                    y_lo = y_lo.min(p.1).min(*s);
                    y_hi = y_hi.max(p.1).max(*s);
                }
            }
            if !y_lo.is_finite() {
                (y_lo, y_hi) = (0.0, 1.0);
            }
            let pad = ((y_hi - y_lo) * 0.05).max(1e-3);
            let mut chart = ChartBuilder::on(&area)
                .caption(*title, (FONT, 17))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(0f64..x_max, (y_lo - pad)..(y_hi + pad))
                .map_err(pe)?;
            chart
                .configure_mesh()
                .x_desc("agent steps")
                .label_style((FONT, 13))
                .axis_desc_style((FONT, 14))
                .x_label_formatter(&|x| format!("{:.0}k", x / 1000.0))
                .draw()
                .map_err(pe)?;
            for (label, k, pts, smooth) in &series {
                let colour = PALETTE[k % PALETTE.len()];
                chart
                    .draw_series(LineSeries::new(
                        pts.iter().map(|p| (p.0 as f64, p.1)),
                        colour.mix(0.25).stroke_width(1),
                    ))
                    .map_err(pe)?;
                chart
                    .draw_series(LineSeries::new(
                        pts.iter().zip(smooth).map(|(p, s)| (p.0 as f64, *s)),
                        colour.stroke_width(2),
                    ))
                    .map_err(pe)?
                    .label(label.clone())
                    .legend(legend_line(colour));
            }
            draw_legend(&mut chart, SeriesLabelPosition::LowerRight, 13)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// w = 0.5 on (2, 4, 8): raw EMA 1, 2.5, 5.25; debiased by 0.5, 0.75, 0.875 →
    /// 2, 3.333…, 6.
    #[test]
    fn ema_is_debiased() {
        let s = ema(&[2.0, 4.0, 8.0], 0.5);
        let want = [2.0, 10.0 / 3.0, 6.0];
        for (a, b) in s.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{s:?}");
        }
        assert_eq!(ema(&[3.0, 5.0], 0.0), vec![3.0, 5.0]);
    }
}
