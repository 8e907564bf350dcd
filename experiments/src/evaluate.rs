//! Evaluating a school and writing what `eval` reports: `metrics.csv`,
//! `summary.json`, and the P/M, depth and trajectory plots.

use crate::plot::{FONT, caption_size, draw_legend, legend_line, pe, save_png};
use anyhow::{Context, Result};
use deepfoids_env::metrics::{Recorder, SchoolState, Summary};
use deepfoids_env::policy::{act_and_step, action_buffers};
use deepfoids_env::{Env, Policy};
use deepfoids_io::{AtomicFile, write_atomic};
use plotters::coord::types::RangedCoordf32 as RangedF32;
use plotters::prelude::*;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// Fish whose trajectories are drawn.
pub const TRACKED: usize = 5;
/// Seconds of trajectory drawn (the thesis' Fig. 4.10a).
pub const TRACK_SECONDS: f64 = 30.0;

/// The result of driving a scene with a policy.
pub struct Evaluation {
    pub recorder: Recorder,
    /// `(t, [(x, z)] per tracked fish)` at every tick.
    pub tracks: Vec<(f64, Vec<(f32, f32)>)>,
    pub tracked: Vec<usize>,
    pub seconds: f64,
    pub wall_seconds: f64,
}

/// Run `env` (fresh from `Env::new`) with `policy` for `warmup` simulated
/// seconds unrecorded, then for `seconds`, sampling every tick;
/// `observe(env, tick, ticks)` sees the env when recording starts (tick 0)
/// and after every recorded step (progress bars, replay recording).
pub fn evaluate(
    env: &mut Env,
    policy: &mut dyn Policy,
    warmup: f64,
    seconds: f64,
    mut observe: impl FnMut(&Env, u64, u64),
) -> Result<Evaluation> {
    let mut actions = action_buffers(env);
    for _ in 0..(warmup / env.tick_seconds()).round().max(0.0) as u64 {
        act_and_step(policy, env, &mut actions)?;
    }
    let t0 = env.output().time;
    let ticks = (seconds / env.tick_seconds()).round().max(1.0) as u64;
    let n = env.world().len();
    let tracked: Vec<usize> = (0..TRACKED.min(n))
        .map(|k| k * n / TRACKED.min(n))
        .collect();
    let mut recorder = Recorder::new(env);
    let mut tracks = Vec::with_capacity(ticks as usize + 1);
    let snapshot = |env: &Env| -> (f64, Vec<(f32, f32)>) {
        let f = &env.output().fish;
        (
            env.output().time,
            tracked
                .iter()
                .map(|&i| (f.position[i].x, f.position[i].z))
                .collect(),
        )
    };
    recorder.sample(env.output());
    tracks.push(snapshot(env));
    observe(env, 0, ticks);
    let start = Instant::now();
    for t in 0..ticks {
        let out = act_and_step(policy, env, &mut actions)?;
        recorder.count(out);
        recorder.sample(out);
        tracks.push(snapshot(env));
        observe(env, t + 1, ticks);
    }
    Ok(Evaluation {
        recorder,
        tracks,
        tracked,
        seconds: env.output().time - t0,
        wall_seconds: start.elapsed().as_secs_f64(),
    })
}

/// What `summary.json` holds besides the metrics.
#[derive(Serialize)]
pub struct EvalMeta<'a> {
    pub scene: &'a str,
    pub policy: &'a str,
    pub seed: u64,
    pub phase: &'a str,
    pub deterministic: bool,
    /// Simulated seconds run before recording.
    pub warmup: f64,
    pub seconds: f64,
    pub wall_seconds: f64,
    pub ticks_per_second: f64,
    /// How to run this evaluation again (`replay --from` does).
    pub rerun: RunArgs,
}

/// The command-line values that reproduce a run's school exactly (seeded
/// runs are deterministic): recorded in `summary.json` by `eval` and in
/// `simulate.json` by `simulate`, read back by `replay --from`. (Files
/// written when acting had a `--backend` hold a `backend` key too, ignored:
/// trained policies now act on the hand-written kernels.)
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunArgs {
    /// `--scene` as given (an id or a path).
    pub scene: String,
    pub phase: String,
    pub seed: u64,
    /// `--policy` as given (a baseline name, a run folder or a `.onnx` file).
    pub policy: String,
    pub checkpoint: Option<u64>,
    pub stochastic: bool,
    /// Simulated seconds run before recording (absent in files written
    /// before `--warmup` existed: 0).
    #[serde(default)]
    pub warmup: f64,
    /// Simulated seconds.
    pub seconds: f64,
    /// `--fish-count`: the scene's one group resized to this many fish (absent: the
    /// scene's own count).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fish: Option<usize>,
}

/// Write `metrics.csv`, `summary.json`, `pm.png`, `depth.png` and `trajectories.png` to `dir`.
pub fn write_outputs(
    dir: &Path,
    env: &Env,
    eval: &Evaluation,
    meta: &EvalMeta<'_>,
) -> Result<Summary> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let summary = eval.recorder.summary(eval.seconds);
    write_csv(&dir.join("metrics.csv"), eval)?;
    #[derive(Serialize)]
    struct File<'a> {
        #[serde(flatten)]
        meta: &'a EvalMeta<'a>,
        summary: &'a Summary,
    }
    let json = serde_json::to_string_pretty(&File {
        meta,
        summary: &summary,
    })?;
    write_atomic(dir.join("summary.json"), json.as_bytes())?;
    let title = format!("{} · {} · seed {}", meta.scene, meta.policy, meta.seed);
    plot_pm(&dir.join("pm.png"), eval, &summary, &title)?;
    plot_depth(&dir.join("depth.png"), &summary, env.cage().height, &title)?;
    plot_tracks(&dir.join("trajectories.png"), env, eval, &title)?;
    Ok(summary)
}

fn write_csv(path: &Path, eval: &Evaluation) -> Result<()> {
    let mut f = AtomicFile::create(path)?;
    let names = eval.recorder.behaviour_names();
    write!(f, "t,P,M,state")?;
    for n in names {
        write!(f, ",P_{n},M_{n}")?;
    }
    writeln!(
        f,
        ",nn_mean_bl,nn_p05_bl,nn_alignment,speed_bl,depth_m,boundary_collisions,neighbour_collisions,reward"
    )?;
    for s in &eval.recorder.samples {
        write!(f, "{:.3},{:.5},{:.5},{}", s.t, s.p, s.m, s.state.as_str())?;
        for (p, m) in &s.per_behaviour {
            write!(f, ",{p:.5},{m:.5}")?;
        }
        writeln!(
            f,
            ",{:.4},{:.4},{:.4},{:.4},{:.4},{},{},{}",
            s.nn_mean_bl,
            s.nn_p05_bl,
            s.nn_alignment,
            s.speed_bl,
            s.depth,
            s.boundary_collisions,
            s.neighbour_collisions,
            if s.reward.is_finite() {
                format!("{:.4}", s.reward)
            } else {
                String::new()
            }
        )?;
    }
    f.commit()?;
    Ok(())
}

/// The share of time in each state, e.g. `swarm 6 %, milling 74 %, …`.
pub fn state_shares(s: &Summary) -> String {
    s.state_share
        .iter()
        .map(|(st, x)| format!("{} {:.0} %", st.as_str(), 100.0 * x))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Print the short table `eval` shows.
pub fn print_table(meta: &EvalMeta<'_>, s: &Summary) {
    println!(
        "{} · policy {} · seed {} · {:.0} simulated s{} in {:.1} s wall ({:.0} ticks/s)",
        meta.scene,
        meta.policy,
        meta.seed,
        meta.seconds,
        if meta.warmup > 0.0 {
            format!(" after {:.0} s warm-up", meta.warmup)
        } else {
            String::new()
        },
        meta.wall_seconds,
        meta.ticks_per_second
    );
    println!(
        "P {:.3} ± {:.3}   M {:.3} ± {:.3}   state: {} ({})",
        s.p_mean,
        s.p_std,
        s.m_mean,
        s.m_std,
        s.dominant_state.as_str(),
        state_shares(s)
    );
    println!(
        "nearest neighbour {} · speed {:.2} BL/s · collisions per fish-hour: boundary {:.1}, neighbour {:.1} · reward/decision {:.3}",
        if s.fish == 1 {
            "none (a lone fish)".to_string()
        } else {
            format!(
                "{:.2} BL (5th pct {:.2}; heading agreement with it {:.2})",
                s.nn_mean_bl, s.nn_p05_bl, s.nn_alignment
            )
        },
        s.mean_speed_bl,
        s.boundary_collisions_per_fish_hour,
        s.neighbour_collisions_per_fish_hour,
        s.reward_per_decision
    );
    println!(
        "turning {:+.1}°/s (+ clockwise seen from above) · {:.0} % of fish turn clockwise · own circling {:.2} (1: each fish circles the cage axis; 0: they wander)",
        s.turning.turn_rate_deg_s,
        100.0 * s.turning.clockwise_share,
        s.turning.own_circling
    );
    if s.behaviours.len() > 1 {
        for b in &s.behaviours {
            println!(
                "  {:<20} P {:.3} M {:.3} depth {:.2} m speed {:.2} BL/s turning {:+.1}°/s reward/decision {:.3}",
                b.name,
                b.p_mean,
                b.m_mean,
                b.mean_depth,
                b.mean_speed_bl,
                b.turning.turn_rate_deg_s,
                b.reward_per_decision
            );
        }
    }
}

/// Line colours (matplotlib's tab10).
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// P and M over time with the state thresholds (Tunstrøm et al. 2013).
fn plot_pm(path: &Path, eval: &Evaluation, s: &Summary, title: &str) -> Result<()> {
    let samples = &eval.recorder.samples;
    let t_max = samples.last().map_or(1.0, |x| x.t).max(1e-3) as f32;
    save_png(path, 1200, 520, |root| {
        root.fill(&WHITE).map_err(pe)?;
        let caption = format!(
            "{title} — mean P {:.2}, mean M {:.2}, mostly {} ({:.0} %)",
            s.p_mean,
            s.m_mean,
            s.dominant_state.as_str(),
            100.0
                * s.state_share
                    .iter()
                    .find(|x| x.0 == s.dominant_state)
                    .map_or(0.0, |x| x.1)
        );
        let mut chart = eval_chart(
            root,
            (&caption, 20.0),
            (0f32..t_max, 0f32..1.02f32),
            ("time (s)", "order parameter"),
            false,
        )?;
        for (level, label) in [
            (SchoolState::LOW, "0.35: below = low"),
            (SchoolState::HIGH, "0.65: above = high"),
        ] {
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(0.0, level), (t_max, level)],
                    8,
                    5,
                    BLACK.mix(0.5).stroke_width(1),
                ))
                .map_err(pe)?
                .label(label)
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.5)));
        }
        for (k, label) in ["P (polarisation)", "M (milling)"].into_iter().enumerate() {
            let colour = PALETTE[k];
            chart
                .draw_series(LineSeries::new(
                    samples
                        .iter()
                        .map(|x| (x.t as f32, if k == 0 { x.p } else { x.m })),
                    colour.stroke_width(2),
                ))
                .map_err(pe)?
                .label(label)
                .legend(legend_line(colour));
        }
        draw_legend(&mut chart, SeriesLabelPosition::MiddleRight, 14)?;
        Ok(())
    })
}

/// Depth distribution per behaviour (share of samples per depth bin; depth down).
fn plot_depth(path: &Path, s: &Summary, height: f32, title: &str) -> Result<()> {
    let max_share = s
        .behaviours
        .iter()
        .flat_map(|b| b.depth_share.iter().copied())
        .fold(0.05f32, f32::max)
        * 1.1;
    save_png(path, 800, 700, |root| {
        root.fill(&WHITE).map_err(pe)?;
        let caption = format!("{title} — depth distribution");
        let mut chart = eval_chart(
            root,
            (&caption, 18.0),
            (0f32..max_share, height..0f32),
            ("share of fish-time", "depth (m)"),
            true,
        )?;
        for (k, b) in s.behaviours.iter().enumerate() {
            let colour = PALETTE[k % PALETTE.len()];
            // A step outline: each bin drawn from its top edge to its bottom edge.
            let mut pts = vec![];
            for (i, share) in b.depth_share.iter().enumerate() {
                pts.push((*share, b.depth_edges[i]));
                pts.push((*share, b.depth_edges[i + 1]));
            }
            chart
                .draw_series(LineSeries::new(pts, colour.stroke_width(2)))
                .map_err(pe)?
                .label(format!("{} (mean {:.2} m)", b.name, b.mean_depth))
                .legend(legend_line(colour));
        }
        draw_legend(&mut chart, SeriesLabelPosition::LowerRight, 14)?;
        Ok(())
    })
}

/// Top-down (x–z) trajectories of the tracked fish over the last 30 s, with the
/// cage outline; a dot marks each fish's latest position. Drawn as seen from
/// above (x right, z down the page, as the replay clip's top view: SPEC's frame
/// is right-handed with y up), so a fish turning clockwise there turns
/// clockwise in `turn_rate_deg_s`'s sense. (Plots drawn before session 54 had
/// z up the page: the view from below, a mirror image.)
fn plot_tracks(path: &Path, env: &Env, eval: &Evaluation, title: &str) -> Result<()> {
    let outline = env.cage().outline();
    let (lo, hi) = env.cage().bounds;
    let half = (hi.x - lo.x).max(hi.z - lo.z) / 2.0 * 1.08;
    let t_end = eval.tracks.last().map_or(0.0, |x| x.0);
    let recent: Vec<&(f64, Vec<(f32, f32)>)> = eval
        .tracks
        .iter()
        .filter(|x| x.0 >= t_end - TRACK_SECONDS)
        .collect();
    // The farthest any fish swims in one tick, with margin (for spotting respawns).
    let max_step = env
        .scene()
        .behaviours
        .iter()
        .map(|b| b.species.speed_bl[1] * b.species.body_length * 1.6)
        .fold(0.0, f32::max)
        * env.tick_seconds() as f32
        * 3.0;
    save_png(path, 760, 800, |root| {
        root.fill(&WHITE).map_err(pe)?;
        let caption = format!(
            "{title} — top view, last {:.0} s (breaks = respawns)",
            TRACK_SECONDS.min(t_end)
        );
        let mut chart = eval_chart(
            root,
            (&caption, 17.0),
            (-half..half, half..-half),
            ("x (m)", "z (m), seen from above"),
            false,
        )?;
        chart
            .draw_series(LineSeries::new(outline.clone(), BLACK.stroke_width(2)))
            .map_err(pe)?;
        for (k, &fish) in eval.tracked.iter().enumerate() {
            let colour = PALETTE[k % PALETTE.len()];
            // Break the path where the fish respawned (a jump no swimming fish makes in one tick).
            let mut segments: Vec<Vec<(f32, f32)>> = vec![vec![]];
            for x in &recent {
                let p = x.1[k];
                if let Some(&q) = segments.last().and_then(|s| s.last())
                    && ((p.0 - q.0).powi(2) + (p.1 - q.1).powi(2)).sqrt() > max_step
                {
                    segments.push(vec![]);
                }
                segments.last_mut().expect("one segment at least").push(p);
            }
            for (si, seg) in segments.into_iter().enumerate() {
                let series = chart
                    .draw_series(LineSeries::new(seg, colour.stroke_width(2)))
                    .map_err(pe)?;
                if si == 0 {
                    series
                        .label(format!("fish {fish}"))
                        .legend(legend_line(colour));
                }
            }
            if let Some(last) = recent.last() {
                chart
                    .draw_series(std::iter::once(Circle::new(last.1[k], 5, colour.filled())))
                    .map_err(pe)?;
            }
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 13)?;
        Ok(())
    })
}

/// A chart as `eval`'s plots draw it: the caption fitted to the width
/// ([`caption_size`] from `caption.1` pt), 12-px margins, both axes
/// described in 14/15-pt type; `light_grid` keeps plotters' light grid lines.
fn eval_chart<'a, 'b>(
    root: &'a DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>,
    caption: (&str, f64),
    (x, y): (std::ops::Range<f32>, std::ops::Range<f32>),
    (x_desc, y_desc): (&str, &str),
    light_grid: bool,
) -> Result<ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedF32, RangedF32>>> {
    let mut chart = ChartBuilder::on(root)
        .caption(caption.0, (FONT, caption_size(root, caption.0, caption.1)))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(55)
        .build_cartesian_2d(x, y)
        .map_err(pe)?;
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(x_desc)
        .y_desc(y_desc)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15));
    if !light_grid {
        mesh.light_line_style(WHITE.mix(0.0));
    }
    mesh.draw().map_err(pe)?;
    Ok(chart)
}
