//! The report of a reproduction: `REPORT.md` with every claim's criterion,
//! measured values and verdict beside the thesis' figure it reproduces; CSVs
//! of the verdicts, stages, measurements and learning curves; and the figures.

use super::claims::{Claim, Verdict};
use super::measure::{Measured, RPD_TAG};
use super::{Profile, ReproduceOptions, StageRecord};
use crate::plot::{FONT, draw_legend, legend_line, pe, save_png};
use anyhow::{Context, Result};
use deepfoids_io::write_atomic;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;

const BLUE: RGBColor = RGBColor(31, 119, 180);
const RED: RGBColor = RGBColor(214, 39, 40);
const GREEN: RGBColor = RGBColor(44, 160, 44);
const ORANGE: RGBColor = RGBColor(255, 127, 14);
const COLOURS: [RGBColor; 4] = [BLUE, RED, GREEN, ORANGE];

/// A line of a panel: label, colour, dashed, points.
struct Line {
    label: String,
    colour: RGBColor,
    dashed: bool,
    points: Vec<(f64, f64)>,
}

/// One chart in `area` (empty lines are skipped; an empty panel says so).
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    lines: &[Line],
    y_range: Option<(f64, f64)>,
    legend: SeriesLabelPosition,
) -> Result<()> {
    let pts = lines.iter().flat_map(|l| l.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        if x.is_finite() && y.is_finite() {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if x0 > x1 {
        area.titled(&format!("{title}: no data"), (FONT, 18))
            .map_err(pe)?;
        return Ok(());
    }
    if let Some((a, b)) = y_range {
        (y0, y1) = (a, b);
    }
    if x1 - x0 < 1e-9 {
        x1 = x0 + 1.0;
    }
    if y1 - y0 < 1e-9 {
        y1 = y0 + 1.0;
    }
    let pad = 0.05 * (y1 - y0);
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
        .map_err(pe)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&|x| si(*x))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(pe)?;
    for l in lines.iter().filter(|l| !l.points.is_empty()) {
        let style = l.colour.stroke_width(2);
        let series = if l.dashed {
            chart
                .draw_series(DashedLineSeries::new(l.points.clone(), 8, 5, style))
                .map_err(pe)?
        } else {
            chart
                .draw_series(LineSeries::new(l.points.clone(), style))
                .map_err(pe)?
        };
        let c = l.colour;
        series.label(l.label.clone()).legend(legend_line(c));
    }
    draw_legend(&mut chart, legend, 13)?;
    Ok(())
}

/// `1.5M`, `250k` for large numbers; one decimal otherwise.
fn si(x: f64) -> String {
    if x.abs() >= 1e6 {
        format!("{:.1}M", x / 1e6)
    } else if x.abs() >= 1e4 {
        format!("{:.0}k", x / 1e3)
    } else {
        format!("{x:.1}")
    }
}

/// Exponential moving average (the smoothing of Fig. 4.7), weight `a` on the past.
fn smooth(points: &[(u64, f64)], a: f64) -> Vec<(f64, f64)> {
    let mut s = None;
    points
        .iter()
        .map(|&(x, y)| {
            let v = match s {
                None => y,
                Some(p) => a * p + (1.0 - a) * y,
            };
            s = Some(v);
            (x as f64, v)
        })
        .collect()
}

/// The reward-per-decision curve of every behaviour of `stage` (first seed).
fn stage_lines(
    m: &Measured,
    stage: &str,
    label: &str,
    colour: RGBColor,
    dashed: bool,
) -> Vec<Line> {
    let curves = m.curves(stage, RPD_TAG);
    let seed0 = curves.first().map(|c| c.train_seed);
    curves
        .into_iter()
        .filter(|c| Some(c.train_seed) == seed0)
        .enumerate()
        .map(|(k, c)| Line {
            label: if k == 0 {
                label.to_string()
            } else {
                format!("{label} ({})", c.behaviour)
            },
            colour: if k == 0 { colour } else { COLOURS[k % 4] },
            dashed,
            points: smooth(&c.points, 0.6),
        })
        .collect()
}

/// What the report is written from.
pub struct Report<'a> {
    pub profile: &'a Profile,
    pub args: &'a ReproduceOptions,
    pub claims: &'a [&'a Claim],
    pub verdicts: &'a [Verdict],
    pub records: &'a [(u64, StageRecord)],
    pub measured: &'a Measured,
    /// The reward profile the stages were trained and evaluated with.
    pub reward_profile: &'a str,
    /// Wall seconds of this invocation.
    pub total_seconds: f64,
}

/// Figures, each as `(claim id, file name)` in `dir`.
type Figures = Vec<(&'static str, String)>;

/// Write the report into `dir`: the figures of the chosen claims, the CSVs,
/// then `REPORT.md`.
pub fn write_report(dir: &Path, r: &Report<'_>) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let has = |id: &str| r.claims.iter().any(|c| c.id == id);
    let m = r.measured;
    let mut figures: Figures = Vec::new();
    if has("learn") {
        figures.push(("learn", learning_figure(dir, m)?));
    }
    if has("transfer") {
        figures.push(("transfer", transfer_figure(dir, m)?));
    }
    if has("ppo-sac") {
        figures.push(("ppo-sac", ppo_sac_figure(dir, m)?));
    }
    if has("density") {
        figures.push(("density", density_figure(dir, m)?));
    }
    depth_figures(dir, m, &has, &mut figures)?;
    trajectory_figures(dir, m, &has, &mut figures)?;
    write_atomic(dir.join("claims.csv"), claims_csv(r)?.as_bytes())?;
    write_atomic(dir.join("stages.csv"), stages_csv(r.records)?.as_bytes())?;
    write_atomic(
        dir.join("measurements.csv"),
        measurements_csv(m)?.as_bytes(),
    )?;
    write_atomic(dir.join("curves.csv"), curves_csv(m)?.as_bytes())?;
    let mut md = String::new();
    report_header(&mut md, r)?;
    report_claims(&mut md, r, &figures)?;
    report_stages(&mut md, r.records)?;
    write_atomic(dir.join("REPORT.md"), md.as_bytes())?;
    Ok(())
}

/// Fig. 4.7: the learning curves of pretraining and transfer, per species.
fn learning_figure(dir: &Path, m: &Measured) -> Result<String> {
    save_png(&dir.join("learning.png"), 1500, 800, |root| {
        root.fill(&WHITE).map_err(pe)?;
        let cells = root.split_evenly((2, 3));
        for (k, sp) in ["coho", "yellowtail", "seabream"].iter().enumerate() {
            for (row, (stage, what)) in [
                (format!("pretrain-{sp}"), "pretraining"),
                (format!("transfer-{sp}_default"), "transfer learning"),
            ]
            .iter()
            .enumerate()
            {
                panel(
                    &cells[row * 3 + k],
                    &format!("{sp}: {what}"),
                    "agent steps",
                    "reward per decision",
                    &stage_lines(m, stage, "PPO", BLUE, false),
                    None,
                    SeriesLabelPosition::LowerRight,
                )?;
            }
        }
        Ok(())
    })?;
    Ok("learning.png".into())
}

/// §4.5.2: two-step training against training from scratch in density_dense.
fn transfer_figure(dir: &Path, m: &Measured) -> Result<String> {
    save_png(&dir.join("transfer.png"), 1000, 520, |root| {
        root.fill(&WHITE).map_err(pe)?;
        let mut lines = stage_lines(
            m,
            "transfer-density_dense",
            "two-step (after pretraining)",
            BLUE,
            false,
        );
        lines.extend(stage_lines(
            m,
            "scratch-density_dense",
            "from scratch",
            RED,
            true,
        ));
        panel(
            root,
            "density_dense: two-step against scratch",
            "agent steps in density_dense",
            "reward per decision",
            &lines,
            None,
            SeriesLabelPosition::LowerRight,
        )
    })?;
    Ok("transfer.png".into())
}

/// Fig. 4.14: PPO against SAC on coho, pretraining and transfer.
fn ppo_sac_figure(dir: &Path, m: &Measured) -> Result<String> {
    save_png(&dir.join("ppo_sac.png"), 1400, 520, |root| {
        root.fill(&WHITE).map_err(pe)?;
        let cells = root.split_evenly((1, 2));
        for (k, (p, s, what)) in [
            ("pretrain-coho", "sac-pretrain-coho", "pretraining"),
            (
                "transfer-coho_default",
                "sac-transfer-coho_default",
                "transfer learning",
            ),
        ]
        .iter()
        .enumerate()
        {
            let mut lines = stage_lines(m, p, "PPO", BLUE, false);
            lines.extend(stage_lines(m, s, "SAC", RED, true));
            panel(
                &cells[k],
                &format!("coho {what}: PPO against SAC"),
                "agent steps",
                "reward per decision",
                &lines,
                None,
                SeriesLabelPosition::LowerRight,
            )?;
        }
        Ok(())
    })?;
    Ok("ppo_sac.png".into())
}

/// Fig. 4.10: P and M over time in the dense and the sparse cage.
fn density_figure(dir: &Path, m: &Measured) -> Result<String> {
    let series = |p: &str, s: &str, k: usize| -> Vec<(f64, f64)> {
        m.of(p, s)
            .first()
            .map(|x| {
                x.pm.iter()
                    .map(|q| (q.0 as f64, [q.1, q.2][k] as f64))
                    .collect()
            })
            .unwrap_or_default()
    };
    save_png(&dir.join("density_pm.png"), 1400, 480, |root| {
        root.fill(&WHITE).map_err(pe)?;
        let cells = root.split_evenly((1, 2));
        for (k, name) in ["P (polarisation)", "M (milling)"].iter().enumerate() {
            let lines = vec![
                Line {
                    label: "dense (14.7 fish/m³)".into(),
                    colour: BLUE,
                    dashed: false,
                    points: series("transfer-density_dense", "density_dense", k),
                },
                Line {
                    label: "sparse (0.59 fish/m³)".into(),
                    colour: RED,
                    dashed: true,
                    points: series("transfer-density_sparse", "density_sparse", k),
                },
            ];
            // M stays low where P is high: the key goes where the lines are not.
            let key = if k == 0 {
                SeriesLabelPosition::MiddleRight
            } else {
                SeriesLabelPosition::UpperRight
            };
            panel(
                &cells[k],
                name,
                "time (s)",
                name,
                &lines,
                Some((0.0, 1.0)),
                key,
            )?;
        }
        Ok(())
    })?;
    Ok("density_pm.png".into())
}

/// Depth histograms per size class (layers) and per species.
fn depth_figures(
    dir: &Path,
    m: &Measured,
    has: &dyn Fn(&str) -> bool,
    figures: &mut Figures,
) -> Result<()> {
    for (id, policy, scene, file) in [
        (
            "layers",
            "transfer-coho_mixed",
            "coho_mixed",
            "depth_sizes.png",
        ),
        (
            "species",
            "transfer-three_species",
            "three_species",
            "depth_species.png",
        ),
    ] {
        if !has(id) {
            continue;
        }
        let ms = m.of(policy, scene);
        let Some(first) = ms.first() else { continue };
        save_png(&dir.join(file), 900, 600, |root| {
            root.fill(&WHITE).map_err(pe)?;
            let lines: Vec<Line> = first
                .summary
                .behaviours
                .iter()
                .enumerate()
                .map(|(b, beh)| {
                    let n = beh.depth_share.len();
                    let points = (0..n)
                        .map(|k| {
                            let share = ms
                                .iter()
                                .map(|x| x.summary.behaviours[b].depth_share[k] as f64)
                                .sum::<f64>()
                                / ms.len() as f64;
                            let mid = 0.5 * (beh.depth_edges[k] + beh.depth_edges[k + 1]) as f64;
                            (100.0 * share, -mid)
                        })
                        .collect();
                    Line {
                        label: beh.name.clone(),
                        colour: COLOURS[b % 4],
                        dashed: false,
                        points,
                    }
                })
                .collect();
            panel(
                root,
                &format!("{scene}: depth distribution per behaviour"),
                "share of fish-time (%)",
                "− depth below the surface (m)",
                &lines,
                None,
                SeriesLabelPosition::LowerRight,
            )
        })?;
        figures.push((id, file.into()));
    }
    Ok(())
}

/// Trajectory plots (top view, the evaluation of the first seeds), copied
/// from the evaluations.
fn trajectory_figures(
    dir: &Path,
    m: &Measured,
    has: &dyn Fn(&str) -> bool,
    figures: &mut Figures,
) -> Result<()> {
    let traj: &[(&str, &str, &str)] = &[
        ("density", "transfer-density_sparse", "density_sparse"),
        ("density", "transfer-density_dense", "density_dense"),
        (
            "seabream-cage",
            "transfer-seabream_default",
            "seabream_default",
        ),
        ("seabream-cage", "transfer-seabream_cube5", "seabream_cube5"),
        ("seabream-50", "transfer-seabream_50", "seabream_50"),
        ("circle", "transfer-coho_default", "coho_default"),
        (
            "circle",
            "transfer-yellowtail_default",
            "yellowtail_default",
        ),
        ("boids", "boids", "density_sparse"),
        ("boids", "boids", "density_dense"),
        ("layers", "transfer-coho_mixed", "coho_mixed"),
        ("species", "transfer-three_species", "three_species"),
        ("ppo-sac", "sac-transfer-coho_default", "coho_default"),
    ];
    for &(id, policy, scene) in traj {
        if !has(id) {
            continue;
        }
        if let Some(src) = m.eval_dir(policy, scene) {
            let name = format!("trajectories-{policy}-{scene}.png");
            if !figures.iter().any(|f| f.1 == name) {
                let bytes = std::fs::read(src.join("trajectories.png")).with_context(|| {
                    format!("cannot read {}", src.join("trajectories.png").display())
                })?;
                write_atomic(dir.join(&name), &bytes)?;
            }
            figures.push((id, name));
        }
    }

    Ok(())
}

/// `claims.csv`: one row per claim with its verdict.
fn claims_csv(r: &Report<'_>) -> Result<String> {
    let mut claims_csv = String::from("claim,verdict,summary\n");
    for (c, v) in r.claims.iter().zip(r.verdicts) {
        writeln!(
            claims_csv,
            "{},{},\"{}\"",
            c.id,
            v.verdict(),
            v.summary.replace('"', "'")
        )?;
    }
    Ok(claims_csv)
}

/// `stages.csv`: one row per training stage and seed.
fn stages_csv(records: &[(u64, StageRecord)]) -> Result<String> {
    let mut stages_csv = String::from(
        "train_seed,stage,scene,algo,phase,budget_per_behaviour,agent_steps,wall_seconds,agent_steps_per_second\n",
    );
    for (seed, r) in records {
        let budget = r
            .budgets
            .iter()
            .map(|b| format!("{}={}", b.0, b.1))
            .collect::<Vec<_>>()
            .join(" ");
        writeln!(
            stages_csv,
            "{seed},{},{},{},{},{budget},{},{:.0},{:.0}",
            r.stage,
            r.scene,
            r.algo,
            r.phase,
            r.agent_steps,
            r.wall_seconds,
            r.agent_steps as f64 / r.wall_seconds.max(1e-9)
        )?;
    }
    Ok(stages_csv)
}

/// `measurements.csv`: one row per evaluation.
fn measurements_csv(m: &Measured) -> Result<String> {
    let mut meas = String::from(
        "policy,scene,train_seed,eval_seed,p,m,swarm,milling,polarised,transitional,nn_bl,speed_bl_s,boundary_per_fish_h,neighbour_per_fish_h,reward_per_decision,axis_distance_m,axis_distance_rel,cage_rotation,chases_started,chase_contact,chase_lost_sight,chase_boundary,chase_timeout,fish_hours\n",
    );
    for x in &m.measurements {
        let s = &x.summary;
        let sh = |name: &str| {
            s.state_share
                .iter()
                .find(|q| q.0.as_str() == name)
                .map_or(0.0, |q| q.1)
        };
        writeln!(
            meas,
            "{},{},{},{},{:.4},{:.4},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.1},{:.1},{:.4},{:.3},{:.3},{:.3},{},{},{},{},{},{:.3}",
            x.policy,
            x.scene,
            x.train_seed,
            x.eval_seed,
            s.p_mean,
            s.m_mean,
            sh("swarm"),
            sh("milling"),
            sh("polarised"),
            sh("transitional"),
            s.nn_mean_bl,
            s.mean_speed_bl,
            s.boundary_collisions_per_fish_hour,
            s.neighbour_collisions_per_fish_hour,
            s.reward_per_decision,
            x.axis_distance,
            x.axis_distance_rel,
            x.cage_rotation,
            x.chases.started,
            x.chases.contact,
            x.chases.lost_sight,
            x.chases.boundary,
            x.chases.timeout,
            x.fish_hours
        )?;
    }
    Ok(meas)
}

/// `curves.csv`: the learning curves.
fn curves_csv(m: &Measured) -> Result<String> {
    let mut curves = String::from("stage,train_seed,behaviour,tag,step,value\n");
    for c in &m.curves {
        for (s, v) in &c.points {
            writeln!(
                curves,
                "{},{},{},{},{s},{v:.4}",
                c.stage, c.train_seed, c.behaviour, c.tag
            )?;
        }
    }

    Ok(curves)
}

/// REPORT.md's title, profile and command.
fn report_header(md: &mut String, r: &Report<'_>) -> Result<()> {
    let (profile, args) = (r.profile, r.args);
    writeln!(md, "# Reproducing DeepFoids (thesis §4.5)\n")?;
    let commit = git_commit();
    writeln!(
        md,
        "Profile **{:?}**{}, reward profile `{}`; training seeds {:?}; evaluation seeds {:?} per trained policy ({}, {:.0} s warm-up then {:.0} s recorded). Built from commit `{commit}`. Total time of this invocation: {:.0} s (stages reused from earlier invocations count in the stage table, not here).\n",
        profile.name,
        if args.budget_scale < 1.0 {
            format!(" with every budget × {}", args.budget_scale)
        } else {
            String::new()
        },
        r.reward_profile,
        profile.seeds,
        profile.eval_seeds,
        if profile.deterministic {
            "deterministic policy: the mean action"
        } else {
            "sampled actions, as Unity ML-Agents 1.x inference"
        },
        profile.warmup,
        profile.seconds,
        r.total_seconds
    )?;
    writeln!(
        md,
        "Command: `{}`. Each criterion below was written into `experiments/src/reproduce/claims.rs` before the runs; values are mean ± standard deviation over training × evaluation seeds.\n",
        command_line(profile, r.reward_profile, &args.out, &args.only)
    )?;
    Ok(())
}

/// The `reproduce` invocation that trains and judges what a report shows:
/// the reward profile and `--deterministic` only when they are not the defaults.
fn command_line(profile: &Profile, reward_profile: &str, out: &Path, only: &[String]) -> String {
    let mut c = format!("deepfoids reproduce --profile {}", profile.name.as_str());
    if reward_profile != deepfoids_env::config::DEFAULT_REWARD_PROFILE {
        c += &format!(" --reward-profile {reward_profile}");
    }
    if profile.deterministic {
        c += " --deterministic";
    }
    c += &format!(" --out {}", out.display());
    if !only.is_empty() {
        c += &format!(" --only {}", only.join(","));
    }
    c
}

/// REPORT.md's verdict table, then each claim with its values and figures.
fn report_claims(md: &mut String, r: &Report<'_>, figures: &Figures) -> Result<()> {
    writeln!(
        md,
        "## Verdicts\n\n| claim | thesis | criterion | measured | verdict |\n|---|---|---|---|---|"
    )?;
    for (c, v) in r.claims.iter().zip(r.verdicts) {
        writeln!(
            md,
            "| {} | {} | {} | {} | **{}** |",
            c.id,
            c.thesis,
            c.criterion,
            v.summary,
            v.verdict()
        )?;
    }
    for (c, v) in r.claims.iter().zip(r.verdicts) {
        writeln!(
            md,
            "\n## {}: {}\n\nCriterion: {}\n\nVerdict: **{}**.\n",
            c.id,
            c.thesis,
            c.criterion,
            v.verdict()
        )?;
        if !v.values.is_empty() {
            writeln!(md, "| measure | value |\n|---|---|")?;
            for (k, val) in &v.values {
                writeln!(md, "| {k} | {val} |")?;
            }
            writeln!(md)?;
        }
        for (_, f) in figures.iter().filter(|f| f.0 == c.id) {
            writeln!(md, "![{f}]({f})\n")?;
        }
    }
    Ok(())
}

/// REPORT.md's table of stages and the total training time.
fn report_stages(md: &mut String, records: &[(u64, StageRecord)]) -> Result<()> {
    writeln!(
        md,
        "\n## Stages\n\n| seed | stage | scene | algo | phase | budget per behaviour | agent steps | wall time | agent-steps/s |\n|---|---|---|---|---|---|---|---|---|"
    )?;
    let mut total = 0.0;
    for (seed, r) in records {
        total += if r.wall_seconds.is_finite() {
            r.wall_seconds
        } else {
            0.0
        };
        writeln!(
            md,
            "| {seed} | {} | {} | {} | {} | {} | {} | {:.0} s | {:.0} |",
            r.stage,
            r.scene,
            r.algo,
            r.phase,
            r.budgets
                .iter()
                .map(|b| format!("{} {}", b.0, b.1))
                .collect::<Vec<_>>()
                .join(", "),
            r.agent_steps,
            r.wall_seconds,
            r.agent_steps as f64 / r.wall_seconds.max(1e-9)
        )?;
    }
    writeln!(
        md,
        "\nTraining wall time, all stages: {:.0} s ({:.1} h) on this machine. Files: `claims.csv`, `stages.csv`, `measurements.csv` (one row per evaluation), `curves.csv` (learning curves).",
        total,
        total / 3600.0
    )?;
    Ok(())
}

/// The checkout's commit (`git rev-parse --short HEAD`), with `-dirty` when
/// it has changes; `unknown` outside a git checkout.
pub fn git_commit() -> String {
    let run = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    match run(&["rev-parse", "--short", "HEAD"]) {
        Some(c) => match run(&["status", "--porcelain", "--untracked-files=no"]) {
            Some(s) if !s.is_empty() => format!("{c}-dirty"),
            _ => c,
        },
        None => "unknown".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reproduce::ProfileName;

    /// A report names the flags that change what it measured, and only those.
    #[test]
    fn the_command_line_names_profile_mode_and_claims() {
        let out = Path::new("runs/r");
        let mut full = Profile::new(ProfileName::Full);
        let default = deepfoids_env::config::DEFAULT_REWARD_PROFILE;
        assert_eq!(
            command_line(&full, default, out, &[]),
            "deepfoids reproduce --profile full --out runs/r"
        );
        full.deterministic = true;
        let only = ["layers".to_string(), "species".to_string()];
        assert_eq!(
            command_line(&full, "assort_then_budget_pairspace20", out, &only),
            "deepfoids reproduce --profile full --reward-profile assort_then_budget_pairspace20 --deterministic --out runs/r --only layers,species"
        );
    }
}
