//! The thesis' claims (§4.5) and the numeric criterion each is judged by.
//!
//! The criteria were written down, in this file, before the `full` run they
//! judge (commit history shows it); they are not tuned after the fact. Every
//! value is a mean over training seeds × evaluation seeds, each evaluation a
//! run of the final policy acting with sampled actions (`--deterministic`:
//! the mean action): `warmup` s unrecorded, then `seconds` s recorded (the
//! profile's).
//!
//! Terms: *cage rotation* is |mean over fish of the tangential component of the
//! horizontal heading about the cage's vertical axis| (1: every fish swims
//! around the axis in one sense; 0: no circulation about it) — what "circle
//! around the cage" measures whatever the school's own shape; *axis distance*
//! is a fish's horizontal distance from the cage axis, relative to the cage's
//! inscribed half-width when marked "rel.".

use super::measure::{Measured, Measurement, Stat};
use anyhow::{Result, bail};
use deepfoids_env::metrics::SchoolState;

/// One claim of the thesis, how it is measured, and its verdict function.
pub struct Claim {
    pub id: &'static str,
    pub thesis: &'static str,
    pub criterion: &'static str,
    /// Training stages it needs (`Stage::all` names).
    pub stages: &'static [&'static str],
    /// Evaluations it needs: (policy: a stage or a baseline, scene).
    pub evals: &'static [(&'static str, &'static str)],
    pub judge: fn(&Measured) -> Verdict,
}

/// A claim's outcome: holds or not (None: could not be measured), a one-line
/// summary, and the measured values (name, value) for the report.
pub struct Verdict {
    pub holds: Option<bool>,
    pub summary: String,
    pub values: Vec<(String, String)>,
}

impl Verdict {
    pub fn verdict(&self) -> &'static str {
        match self.holds {
            Some(true) => "holds",
            Some(false) => "does not hold",
            None => "not measured",
        }
    }
}

/// Share of the evaluation in `state`.
fn share(m: &Measurement, state: SchoolState) -> f64 {
    m.summary
        .state_share
        .iter()
        .find(|(s, _)| *s == state)
        .map_or(0.0, |(_, x)| *x as f64)
}

const DEFAULTS: [(&str, &str); 3] = [
    ("coho", "coho_default"),
    ("yellowtail", "yellowtail_default"),
    ("seabream", "seabream_default"),
];

/// The transferred default policies, and their evaluations in their scenes.
const DEFAULT_STAGES: [&str; 3] = [
    "transfer-coho_default",
    "transfer-yellowtail_default",
    "transfer-seabream_default",
];
const DEFAULT_EVALS: [(&str, &str); 3] = [
    ("transfer-coho_default", "coho_default"),
    ("transfer-yellowtail_default", "yellowtail_default"),
    ("transfer-seabream_default", "seabream_default"),
];

/// Pretraining and transfer learning of the default scenes.
const LEARN_STAGES: [&str; 6] = [
    "pretrain-coho",
    "pretrain-yellowtail",
    "pretrain-seabream",
    "transfer-coho_default",
    "transfer-yellowtail_default",
    "transfer-seabream_default",
];

pub const CLAIMS: &[Claim] = &[
    Claim {
        id: "learn",
        thesis: "Reward rises in pretraining and transfer learning for all three species (Fig. 4.7).",
        criterion: "For each of the six stages (pretraining and transfer of coho, yellowtail, seabream in their default scenes), the mean reward per decision over the last 10 % of the logged learning curve exceeds the mean over its first 10 %, for every training seed.",
        stages: &LEARN_STAGES,
        evals: &[],
        judge: judge_learn,
    },
    Claim {
        id: "transfer",
        thesis: "Two-step training (pretrain, then transfer) beats training from scratch at equal steps (§4.5.2).",
        criterion: "In density_dense, the transferred policy (coho pretraining + transfer budget) has a higher evaluation reward per decision AND no more boundary collisions per fish-hour than a policy trained from scratch there with the transfer weights for the same total budget.",
        stages: &["transfer-density_dense", "scratch-density_dense"],
        evals: &[
            ("transfer-density_dense", "density_dense"),
            ("scratch-density_dense", "density_dense"),
        ],
        judge: judge_transfer,
    },
    Claim {
        id: "circle",
        thesis: "Trained schools in the default scenes form circling patterns (§4.5.3).",
        criterion: "For each species' transferred default policy in its default scene, cage rotation ≥ 0.5 (M and state shares reported beside it).",
        stages: &DEFAULT_STAGES,
        evals: &DEFAULT_EVALS,
        judge: judge_circle,
    },
    Claim {
        id: "seabream-cage",
        thesis: "10 seabream circle slowly around the centre of the 3 m cube, and swim fast and away from the centre in the 5 m cube (Fig. 4.9a).",
        criterion: "3 m cube: cage rotation ≥ 0.5; 5 m cube: mean speed ≥ 1.25 × the 3 m cube's AND rel. axis distance greater than the 3 m cube's.",
        stages: &["transfer-seabream_default", "transfer-seabream_cube5"],
        evals: &[
            ("transfer-seabream_default", "seabream_default"),
            ("transfer-seabream_cube5", "seabream_cube5"),
        ],
        judge: judge_seabream_cage,
    },
    Claim {
        id: "seabream-50",
        thesis: "50 seabream form a more compact school than 10 and circle the whole 3 m cage (Fig. 4.9b).",
        criterion: "seabream_50 against seabream_default (10 fish), both 3 m cubes: nearest-neighbour distance (BL) smaller, cage rotation ≥ 0.5, and rel. axis distance (the circle's radius) at least the 10 fish's.",
        stages: &["transfer-seabream_50", "transfer-seabream_default"],
        evals: &[
            ("transfer-seabream_50", "seabream_50"),
            ("transfer-seabream_default", "seabream_default"),
        ],
        judge: judge_seabream_50,
    },
    Claim {
        id: "layers",
        thesis: "Coho of mixed sizes form vertical layers by body size, larger fish deeper (Fig. 4.9c; Hvas et al. 2021).",
        criterion: "coho_mixed: median depths ordered small < regular < large AND median(large) − median(small) ≥ 0.5 m (about one regular body length).",
        stages: &["transfer-coho_mixed"],
        evals: &[("transfer-coho_mixed", "coho_mixed")],
        judge: judge_layers,
    },
    Claim {
        id: "species",
        thesis: "Coho, yellowtail and seabream in one cage swim distinctly (Fig. 4.9d).",
        criterion: "three_species: every pair of species differs in at least one of: mean depth by ≥ 0.5 m, mean speed (BL/s) by a factor ≥ 1.25, P by ≥ 0.2, M by ≥ 0.2.",
        stages: &["transfer-three_species"],
        evals: &[("transfer-three_species", "three_species")],
        judge: judge_species,
    },
    Claim {
        id: "density",
        thesis: "The school swarms at 0.59 fish/m³ and mills at 14.7 fish/m³ (Fig. 4.10).",
        criterion: "density_sparse: swarm share ≥ 50 %; density_dense: milling share ≥ 50 %; and M(dense) − M(sparse) ≥ 0.3.",
        stages: &["transfer-density_sparse", "transfer-density_dense"],
        evals: &[
            ("transfer-density_sparse", "density_sparse"),
            ("transfer-density_dense", "density_dense"),
        ],
        judge: judge_density,
    },
    Claim {
        id: "chase",
        thesis: "Dominant fish chase subordinates until contact or until the target is out of sight (Fig. 4.13).",
        criterion: "Pooled over the three default scenes: chases start (> 0 per fish-hour) and ≥ 50 % of the ended chases end by contact or loss of sight (not by the timeout or a boundary collision).",
        stages: &DEFAULT_STAGES,
        evals: &DEFAULT_EVALS,
        judge: judge_chase,
    },
    Claim {
        id: "ppo-sac",
        thesis: "On coho, SAC's reward is higher early, PPO's final reward is higher and more stable (Fig. 4.14).",
        criterion: "(a) over the first 20 % of the pretraining budget SAC's mean reward per decision > PPO's; (b) after transfer, PPO's evaluation reward per decision in coho_default > SAC's; (c) the standard deviation of the reward per decision over the last 20 % of the transfer curve is smaller for PPO.",
        stages: &[
            "pretrain-coho",
            "transfer-coho_default",
            "sac-pretrain-coho",
            "sac-transfer-coho_default",
        ],
        evals: &[
            ("transfer-coho_default", "coho_default"),
            ("sac-transfer-coho_default", "coho_default"),
        ],
        judge: judge_ppo_sac,
    },
    Claim {
        id: "boids",
        thesis: "Boids with boundary avoidance misses what DeepFoids reproduces of caged fish (§4.5.5).",
        criterion: "DeepFoids meets the `density` criterion (swarm when sparse, mill when dense) and Boids (configs/baselines/boids.toml) does not; speed, collisions and NN distance side by side.",
        stages: &["transfer-density_sparse", "transfer-density_dense"],
        evals: &[
            ("transfer-density_sparse", "density_sparse"),
            ("transfer-density_dense", "density_dense"),
            ("boids", "density_sparse"),
            ("boids", "density_dense"),
        ],
        judge: judge_boids,
    },
];

/// The claims `--only` names (all when empty); unknown ids are refused.
pub fn select(only: &[String]) -> Result<Vec<&'static Claim>> {
    if only.is_empty() {
        return Ok(CLAIMS.iter().collect());
    }
    let mut v = Vec::new();
    for id in only {
        match CLAIMS.iter().find(|c| c.id == id) {
            Some(c) => v.push(c),
            None => bail!(
                "unknown claim `{id}`; allowed: {}",
                CLAIMS.iter().map(|c| c.id).collect::<Vec<_>>().join(", ")
            ),
        }
    }
    Ok(v)
}

fn missing(what: &str) -> Verdict {
    Verdict {
        holds: None,
        summary: format!("no measurement of {what}"),
        values: vec![],
    }
}

/// Mean of the points of a curve whose step lies in `[from, to)` of its
/// last step (fractions; `to = 1` includes the last point); when none does,
/// the point nearest that window.
fn window(points: &[(u64, f64)], from: f64, to: f64) -> Stat {
    let Some(last) = points.last().map(|p| p.0 as f64) else {
        return Stat::of([]);
    };
    let inside: Vec<f64> = points
        .iter()
        .filter(|p| {
            let x = p.0 as f64 / last.max(1.0);
            x >= from && (x < to || (to >= 1.0 && x <= 1.0))
        })
        .map(|p| p.1)
        .collect();
    if !inside.is_empty() {
        return Stat::of(inside);
    }
    let mid = 0.5 * (from + to) * last;
    let near = points
        .iter()
        .min_by(|a, b| {
            (a.0 as f64 - mid)
                .abs()
                .total_cmp(&(b.0 as f64 - mid).abs())
        })
        .map(|p| p.1);
    Stat::of(near)
}

/// Mean of the first (`head`) or last `frac` of a curve's points, at least one.
fn ends(points: &[(u64, f64)], frac: f64, head: bool) -> Stat {
    let k = ((points.len() as f64 * frac).round() as usize).clamp(1, points.len().max(1));
    let pick = if head {
        &points[..k.min(points.len())]
    } else {
        &points[points.len().saturating_sub(k)..]
    };
    Stat::of(pick.iter().map(|p| p.1))
}

use super::measure::RPD_TAG as RPD;

fn judge_learn(m: &Measured) -> Verdict {
    let mut values = Vec::new();
    let mut holds = true;
    let mut any = false;
    for stage in LEARN_STAGES {
        for c in m.curves(stage, RPD) {
            any = true;
            let a = ends(&c.points, 0.1, true);
            let b = ends(&c.points, 0.1, false);
            let up = b.mean > a.mean;
            holds &= up;
            values.push((
                format!("{stage} (seed {})", c.train_seed),
                format!(
                    "{:.2} → {:.2}{}",
                    a.mean,
                    b.mean,
                    if up { "" } else { " (falls)" }
                ),
            ));
        }
    }
    if !any {
        return missing("learning curves");
    }
    Verdict {
        holds: Some(holds),
        summary: format!(
            "reward per decision rises in {} of {} stages",
            values.iter().filter(|v| !v.1.contains("falls")).count(),
            values.len()
        ),
        values,
    }
}

fn judge_transfer(m: &Measured) -> Verdict {
    let (t, s) = ("transfer-density_dense", "scratch-density_dense");
    let rt = m.stat(t, "density_dense", |x| x.summary.reward_per_decision);
    let rs = m.stat(s, "density_dense", |x| x.summary.reward_per_decision);
    let bt = m.stat(t, "density_dense", |x| {
        x.summary.boundary_collisions_per_fish_hour
    });
    let bs = m.stat(s, "density_dense", |x| {
        x.summary.boundary_collisions_per_fish_hour
    });
    if rt.n == 0 || rs.n == 0 {
        return missing("both policies in density_dense");
    }
    let holds = rt.mean > rs.mean && bt.mean <= bs.mean;
    Verdict {
        holds: Some(holds),
        summary: format!(
            "reward/decision {} (two-step) vs {} (scratch); boundary coll./fish-h {} vs {}",
            rt.fmt(2),
            rs.fmt(2),
            bt.fmt(1),
            bs.fmt(1)
        ),
        values: vec![
            ("reward/decision, two-step".into(), rt.fmt(3)),
            ("reward/decision, scratch".into(), rs.fmt(3)),
            ("boundary coll./fish-h, two-step".into(), bt.fmt(1)),
            ("boundary coll./fish-h, scratch".into(), bs.fmt(1)),
        ],
    }
}

fn judge_circle(m: &Measured) -> Verdict {
    let mut values = Vec::new();
    let mut holds = true;
    let mut parts = Vec::new();
    for (sp, scene) in DEFAULTS {
        let p = format!("transfer-{scene}");
        let rot = m.stat(&p, scene, |x| x.cage_rotation as f64);
        if rot.n == 0 {
            return missing(scene);
        }
        let mm = m.stat(&p, scene, |x| x.summary.m_mean as f64);
        let mill = m.stat(&p, scene, |x| share(x, SchoolState::Milling));
        let pol = m.stat(&p, scene, |x| share(x, SchoolState::Polarised));
        let swarm = m.stat(&p, scene, |x| share(x, SchoolState::Swarm));
        holds &= rot.mean >= 0.5;
        parts.push(format!("{sp} {:.2}", rot.mean));
        values.push((format!("{sp}: cage rotation"), rot.fmt(2)));
        values.push((format!("{sp}: M"), mm.fmt(2)));
        values.push((
            format!("{sp}: swarm / milling / polarised share"),
            format!(
                "{:.0} % / {:.0} % / {:.0} %",
                100.0 * swarm.mean,
                100.0 * mill.mean,
                100.0 * pol.mean
            ),
        ));
    }
    Verdict {
        holds: Some(holds),
        summary: format!("cage rotation {}", parts.join(", ")),
        values,
    }
}

fn speed_of(x: &Measurement) -> f64 {
    x.summary.mean_speed_bl as f64
}

fn rel_of(x: &Measurement) -> f64 {
    x.axis_distance_rel as f64
}

fn rot_of(x: &Measurement) -> f64 {
    x.cage_rotation as f64
}

fn m_of(x: &Measurement) -> f64 {
    x.summary.m_mean as f64
}

/// `label` → `a / b`: one measure of two evaluations side by side.
fn both(
    m: &Measured,
    (pa, sa): (&str, &str),
    (pb, sb): (&str, &str),
    label: &str,
    f: fn(&Measurement) -> f64,
) -> (String, String) {
    (
        label.into(),
        format!(
            "{} / {}",
            m.stat(pa, sa, f).fmt(2),
            m.stat(pb, sb, f).fmt(2)
        ),
    )
}

fn judge_seabream_cage(m: &Measured) -> Verdict {
    let (a, b) = (
        ("transfer-seabream_default", "seabream_default"),
        ("transfer-seabream_cube5", "seabream_cube5"),
    );
    let speed = |(p, s): (&str, &str)| m.stat(p, s, speed_of);
    let rel = |(p, s): (&str, &str)| m.stat(p, s, rel_of);
    let rot = |(p, s): (&str, &str)| m.stat(p, s, rot_of);
    let (s3, s5) = (speed(a), speed(b));
    if s3.n == 0 || s5.n == 0 {
        return missing("both seabream cages");
    }
    let holds = rot(a).mean >= 0.5 && s5.mean >= 1.25 * s3.mean && rel(b).mean > rel(a).mean;
    Verdict {
        holds: Some(holds),
        summary: format!(
            "speed {} → {} BL/s; rel. axis distance {} → {}; cage rotation (3 m) {}",
            s3.fmt(2),
            s5.fmt(2),
            rel(a).fmt(2),
            rel(b).fmt(2),
            rot(a).fmt(2)
        ),
        values: vec![
            both(m, a, b, "speed BL/s, 3 m / 5 m", speed_of),
            both(m, a, b, "axis distance m, 3 m / 5 m", |x| {
                x.axis_distance as f64
            }),
            both(m, a, b, "rel. axis distance, 3 m / 5 m", rel_of),
            both(m, a, b, "cage rotation, 3 m / 5 m", rot_of),
            both(m, a, b, "M, 3 m / 5 m", m_of),
        ],
    }
}

fn judge_seabream_50(m: &Measured) -> Verdict {
    let (a, b) = (
        ("transfer-seabream_default", "seabream_default"),
        ("transfer-seabream_50", "seabream_50"),
    );
    let nn = |(p, s): (&str, &str)| m.stat(p, s, |x| x.summary.nn_mean_bl as f64);
    let rel = |(p, s): (&str, &str)| m.stat(p, s, rel_of);
    let rot = |(p, s): (&str, &str)| m.stat(p, s, rot_of);
    let (n10, n50) = (nn(a), nn(b));
    if n10.n == 0 || n50.n == 0 {
        return missing("seabream_50 and seabream_default");
    }
    let holds = n50.mean < n10.mean && rot(b).mean >= 0.5 && rel(b).mean >= rel(a).mean;
    Verdict {
        holds: Some(holds),
        summary: format!(
            "NN {} → {} BL; cage rotation (50) {}; rel. radius {} → {}",
            n10.fmt(2),
            n50.fmt(2),
            rot(b).fmt(2),
            rel(a).fmt(2),
            rel(b).fmt(2)
        ),
        values: vec![
            both(m, a, b, "NN distance BL, 10 / 50 fish", |x| {
                x.summary.nn_mean_bl as f64
            }),
            both(m, a, b, "cage rotation, 10 / 50", rot_of),
            both(
                m,
                a,
                b,
                "rel. axis distance (circle radius), 10 / 50",
                rel_of,
            ),
            both(m, a, b, "M, 10 / 50", m_of),
        ],
    }
}

fn judge_layers(m: &Measured) -> Verdict {
    let (p, s) = ("transfer-coho_mixed", "coho_mixed");
    let med = |class: &str| m.place_stat(p, s, |x| x.size_class == class, |x| x.depth_q[1] as f64);
    let (sm, re, la) = (med("small"), med("regular"), med("large"));
    if sm.n == 0 || re.n == 0 || la.n == 0 {
        return missing("coho_mixed's three size classes");
    }
    let sep = la.mean - sm.mean;
    let holds = sm.mean < re.mean && re.mean < la.mean && sep >= 0.5;
    let q = |class: &str, k: usize| {
        m.place_stat(p, s, |x| x.size_class == class, |x| x.depth_q[k] as f64)
    };
    let mut values = vec![];
    for class in ["small", "regular", "large"] {
        values.push((
            format!("{class}: depth 10 % / 50 % / 90 % (m)"),
            format!(
                "{:.2} / {:.2} / {:.2}",
                q(class, 0).mean,
                q(class, 1).mean,
                q(class, 2).mean
            ),
        ));
    }
    values.push((
        "median(large) − median(small)".into(),
        format!("{sep:.2} m"),
    ));
    Verdict {
        holds: Some(holds),
        summary: format!(
            "median depth small {} / regular {} / large {} m",
            sm.fmt(2),
            re.fmt(2),
            la.fmt(2)
        ),
        values,
    }
}

fn judge_species(m: &Measured) -> Verdict {
    let (p, s) = ("transfer-three_species", "three_species");
    let sp = ["coho", "yellowtail", "seabream"];
    let ms = m.of(p, s);
    if ms.is_empty() {
        return missing("three_species");
    }
    // Per species: depth (mean of the median), speed, P, M.
    let stat = |name: &str, f: &dyn Fn(&Measurement, usize) -> f64| {
        Stat::of(ms.iter().filter_map(|x| {
            let b = x.places.iter().position(|pl| pl.species == name)?;
            Some(f(x, b))
        }))
    };
    let depth = |n: &str| stat(n, &|x, b| x.summary.behaviours[b].mean_depth as f64);
    let speed = |n: &str| stat(n, &|x, b| x.summary.behaviours[b].mean_speed_bl as f64);
    let pp = |n: &str| stat(n, &|x, b| x.summary.behaviours[b].p_mean as f64);
    let mm = |n: &str| stat(n, &|x, b| x.summary.behaviours[b].m_mean as f64);
    let mut values = Vec::new();
    for n in sp {
        values.push((
            format!("{n}: depth m / speed BL/s / P / M"),
            format!(
                "{} / {} / {} / {}",
                depth(n).fmt(2),
                speed(n).fmt(2),
                pp(n).fmt(2),
                mm(n).fmt(2)
            ),
        ));
    }
    let mut holds = true;
    let mut pairs = Vec::new();
    for i in 0..3 {
        for j in i + 1..3 {
            let (a, b) = (sp[i], sp[j]);
            let (sa, sb) = (speed(a).mean, speed(b).mean);
            let ratio = sa.max(sb) / sa.min(sb).max(1e-9);
            let distinct = (depth(a).mean - depth(b).mean).abs() >= 0.5
                || ratio >= 1.25
                || (pp(a).mean - pp(b).mean).abs() >= 0.2
                || (mm(a).mean - mm(b).mean).abs() >= 0.2;
            holds &= distinct;
            pairs.push(format!(
                "{a}/{b} {}",
                if distinct { "distinct" } else { "alike" }
            ));
        }
    }
    Verdict {
        holds: Some(holds),
        summary: pairs.join(", "),
        values,
    }
}

/// The `density` criterion for one policy pair (DeepFoids' or a baseline's).
fn density_of(m: &Measured, sparse: &str, dense: &str) -> Option<(bool, Vec<(String, String)>)> {
    let sw = m.stat(sparse, "density_sparse", |x| share(x, SchoolState::Swarm));
    let mi = m.stat(dense, "density_dense", |x| share(x, SchoolState::Milling));
    let ms = m.stat(sparse, "density_sparse", |x| x.summary.m_mean as f64);
    let md = m.stat(dense, "density_dense", |x| x.summary.m_mean as f64);
    let ps = m.stat(sparse, "density_sparse", |x| x.summary.p_mean as f64);
    let pd = m.stat(dense, "density_dense", |x| x.summary.p_mean as f64);
    if sw.n == 0 || mi.n == 0 {
        return None;
    }
    let holds = sw.mean >= 0.5 && mi.mean >= 0.5 && md.mean - ms.mean >= 0.3;
    Some((
        holds,
        vec![
            (
                "swarm share, sparse".into(),
                format!("{:.0} %", 100.0 * sw.mean),
            ),
            (
                "milling share, dense".into(),
                format!("{:.0} %", 100.0 * mi.mean),
            ),
            (
                "P sparse / dense".into(),
                format!("{} / {}", ps.fmt(2), pd.fmt(2)),
            ),
            (
                "M sparse / dense".into(),
                format!("{} / {}", ms.fmt(2), md.fmt(2)),
            ),
        ],
    ))
}

fn judge_density(m: &Measured) -> Verdict {
    match density_of(m, "transfer-density_sparse", "transfer-density_dense") {
        None => missing("density_sparse and density_dense"),
        Some((holds, values)) => Verdict {
            holds: Some(holds),
            summary: values
                .iter()
                .map(|(k, v)| format!("{k} {v}"))
                .collect::<Vec<_>>()
                .join("; "),
            values,
        },
    }
}

fn judge_chase(m: &Measured) -> Verdict {
    let mut c = super::measure::Chases::default();
    let mut hours = 0.0;
    let mut values = Vec::new();
    for (sp, scene) in DEFAULTS {
        let p = format!("transfer-{scene}");
        let mut one = super::measure::Chases::default();
        let mut h = 0.0;
        for x in m.of(&p, scene) {
            one.started += x.chases.started;
            one.contact += x.chases.contact;
            one.lost_sight += x.chases.lost_sight;
            one.boundary += x.chases.boundary;
            one.timeout += x.chases.timeout;
            h += x.fish_hours;
        }
        values.push((
            format!("{sp}: chases/fish-h; ended by contact / lost sight / boundary / timeout"),
            format!(
                "{:.1}; {} / {} / {} / {}",
                one.started as f64 / h.max(1e-9),
                one.contact,
                one.lost_sight,
                one.boundary,
                one.timeout
            ),
        ));
        c.started += one.started;
        c.contact += one.contact;
        c.lost_sight += one.lost_sight;
        c.boundary += one.boundary;
        c.timeout += one.timeout;
        hours += h;
    }
    if hours == 0.0 {
        return missing("the default scenes");
    }
    let ended = c.ended();
    let good = if ended > 0 {
        (c.contact + c.lost_sight) as f64 / ended as f64
    } else {
        0.0
    };
    let rate = c.started as f64 / hours;
    let holds = rate > 0.0 && ended > 0 && good >= 0.5;
    Verdict {
        holds: Some(holds),
        summary: format!(
            "{rate:.1} chases per fish-hour; {:.0} % of {ended} ended by contact or loss of sight",
            100.0 * good
        ),
        values,
    }
}

fn judge_ppo_sac(m: &Measured) -> Verdict {
    let curve = |stage: &str| m.curves(stage, RPD).into_iter().next();
    let (Some(pp), Some(sp), Some(pt), Some(st)) = (
        curve("pretrain-coho"),
        curve("sac-pretrain-coho"),
        curve("transfer-coho_default"),
        curve("sac-transfer-coho_default"),
    ) else {
        return missing("PPO's and SAC's coho curves");
    };
    let early_p = window(&pp.points, 0.0, 0.2);
    let early_s = window(&sp.points, 0.0, 0.2);
    let late_p = window(&pt.points, 0.8, 1.0);
    let late_s = window(&st.points, 0.8, 1.0);
    let ep = m.stat("transfer-coho_default", "coho_default", |x| {
        x.summary.reward_per_decision
    });
    let es = m.stat("sac-transfer-coho_default", "coho_default", |x| {
        x.summary.reward_per_decision
    });
    if ep.n == 0 || es.n == 0 {
        return missing("PPO's and SAC's evaluations");
    }
    let (a, b, c) = (
        early_s.mean > early_p.mean,
        ep.mean > es.mean,
        late_p.sd < late_s.sd,
    );
    Verdict {
        holds: Some(a && b && c),
        summary: format!(
            "(a) early SAC {:.1} vs PPO {:.1} {}; (b) final eval PPO {} vs SAC {} {}; (c) late sd PPO {:.2} vs SAC {:.2} {}",
            early_s.mean,
            early_p.mean,
            if a { "✓" } else { "✗" },
            ep.fmt(1),
            es.fmt(1),
            if b { "✓" } else { "✗" },
            late_p.sd,
            late_s.sd,
            if c { "✓" } else { "✗" }
        ),
        values: vec![
            (
                "reward/decision, first 20 % of pretraining: PPO / SAC".into(),
                format!("{:.2} / {:.2}", early_p.mean, early_s.mean),
            ),
            (
                "evaluation reward/decision after transfer: PPO / SAC".into(),
                format!("{} / {}", ep.fmt(2), es.fmt(2)),
            ),
            (
                "sd of reward/decision, last 20 % of transfer: PPO / SAC".into(),
                format!("{:.3} / {:.3}", late_p.sd, late_s.sd),
            ),
        ],
    }
}

fn judge_boids(m: &Measured) -> Verdict {
    let (Some((deep, dv)), Some((boids, bv))) = (
        density_of(m, "transfer-density_sparse", "transfer-density_dense"),
        density_of(m, "boids", "boids"),
    ) else {
        return missing("DeepFoids and Boids in both density scenes");
    };
    let mut values: Vec<(String, String)> = dv
        .into_iter()
        .map(|(k, v)| (format!("DeepFoids: {k}"), v))
        .chain(bv.into_iter().map(|(k, v)| (format!("Boids: {k}"), v)))
        .collect();
    for (who, sparse, dense) in [
        (
            "DeepFoids",
            "transfer-density_sparse",
            "transfer-density_dense",
        ),
        ("Boids", "boids", "boids"),
    ] {
        for (p, s) in [(sparse, "density_sparse"), (dense, "density_dense")] {
            values.push((
                format!("{who} in {s}: speed BL/s / boundary, neighbour coll./fish-h / NN BL"),
                format!(
                    "{} / {}, {} / {}",
                    m.stat(p, s, |x| x.summary.mean_speed_bl as f64).fmt(2),
                    m.stat(p, s, |x| x.summary.boundary_collisions_per_fish_hour)
                        .fmt(1),
                    m.stat(p, s, |x| x.summary.neighbour_collisions_per_fish_hour)
                        .fmt(0),
                    m.stat(p, s, |x| x.summary.nn_mean_bl as f64).fmt(2)
                ),
            ));
        }
    }
    Verdict {
        holds: Some(deep && !boids),
        summary: format!(
            "density criterion: DeepFoids {}, Boids {}",
            if deep { "met" } else { "not met" },
            if boids { "met" } else { "not met" }
        ),
        values,
    }
}
