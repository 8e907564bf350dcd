//! What the claims are judged on: evaluations of the trained policies
//! (sampled actions unless `--deterministic`) (and of Boids) in their scenes, each cached as JSON beside the
//! runs, and the learning curves read back from each stage's `scalars.csv`.

use super::{Profile, Stage};
use crate::evaluate::{EvalMeta, RunArgs, evaluate, write_outputs};
use anyhow::{Context, Result};
use deepfoids_env::metrics::{Summary, tangential};
use deepfoids_env::world::Chase;
use deepfoids_env::{ConfigDirs, Env, GridFormat, Phase};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Environment seed of evaluation seed `e` of training seed `t`:
/// `ENV_SEED_BASE + 1000·e + t` (away from the training seeds' streams).
pub const ENV_SEED_BASE: u64 = 2_000_000;

/// Seconds between two points of the stored P/M series.
const SERIES_STEP: f64 = 0.5;

/// How the chases of one evaluation went (SPEC §6: a chase ends at contact,
/// when the target gets behind the aggressor, or after the timeout; a
/// boundary collision of either fish also ends it).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Chases {
    pub started: u64,
    pub contact: u64,
    pub lost_sight: u64,
    pub boundary: u64,
    pub timeout: u64,
}

impl Chases {
    pub fn ended(&self) -> u64 {
        self.contact + self.lost_sight + self.boundary + self.timeout
    }
}

/// Per behaviour: where its fish are and how they move about the cage.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Place {
    pub name: String,
    pub species: String,
    pub size_class: String,
    /// Mean body length (m).
    pub bl: f32,
    /// Mean horizontal distance from the cage's vertical axis (m).
    pub axis_distance: f32,
    /// Mean tangential alignment about the cage axis, signed, in [−1, 1]:
    /// +1 when every fish swims counter-clockwise around the axis (seen from
    /// above), 0 for no circulation around it.
    pub cage_rotation: f32,
    /// Depth quantiles (m): 10 %, 50 %, 90 %.
    pub depth_q: [f32; 3],
}

/// One evaluation of one policy in one scene.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Measurement {
    pub policy: String,
    pub scene: String,
    pub train_seed: u64,
    pub eval_seed: u64,
    /// Modification time (s since the epoch) of the policy's `final/state.json`;
    /// a cache with another stamp is stale.
    pub stamp: u64,
    pub summary: Summary,
    pub places: Vec<Place>,
    /// Whole school: mean distance from the cage axis (m) and that distance
    /// over the cage's inscribed radius.
    pub axis_distance: f32,
    pub axis_distance_rel: f32,
    /// |mean tangential alignment about the cage axis| of the whole school.
    pub cage_rotation: f32,
    pub cage_height: f32,
    pub cage_inradius: f32,
    pub chases: Chases,
    pub fish_hours: f64,
    /// `(t, P, M)` every [`SERIES_STEP`] s of the recording.
    pub pm: Vec<(f32, f32, f32)>,
}

/// A learning curve of one behaviour of one stage.
#[derive(Clone, Debug, Serialize)]
pub struct Curve {
    pub stage: String,
    pub train_seed: u64,
    pub behaviour: String,
    pub tag: String,
    pub points: Vec<(u64, f64)>,
}

/// Mean, standard deviation and count of a set of values.
#[derive(Clone, Copy, Debug, Default)]
pub struct Stat {
    pub mean: f64,
    pub sd: f64,
    pub n: usize,
}

impl Stat {
    pub fn of(values: impl IntoIterator<Item = f64>) -> Self {
        let v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return Self {
                mean: f64::NAN,
                sd: f64::NAN,
                n: 0,
            };
        }
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let var = if v.len() > 1 {
            v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len() - 1) as f64
        } else {
            0.0
        };
        Self {
            mean,
            sd: var.sqrt(),
            n: v.len(),
        }
    }

    /// `mean ± sd` with `d` decimals.
    pub fn fmt(&self, d: usize) -> String {
        if self.n == 0 {
            return "–".into();
        }
        format!("{:.d$} ± {:.d$}", self.mean, self.sd)
    }
}

/// Everything measured for the chosen claims.
pub struct Measured {
    pub measurements: Vec<Measurement>,
    pub curves: Vec<Curve>,
    /// Evaluation folders (`eval`'s CSV, JSON and PNGs) of the first
    /// evaluation of each (policy, scene).
    pub eval_dirs: Vec<((String, String), PathBuf)>,
}

impl Measured {
    pub fn of(&self, policy: &str, scene: &str) -> Vec<&Measurement> {
        self.measurements
            .iter()
            .filter(|m| m.policy == policy && m.scene == scene)
            .collect()
    }

    /// Mean ± sd of `f` over every training and evaluation seed.
    pub fn stat(&self, policy: &str, scene: &str, f: impl Fn(&Measurement) -> f64) -> Stat {
        Stat::of(self.of(policy, scene).into_iter().map(f))
    }

    /// A behaviour's value (by species or size class) over every seed.
    pub fn place_stat(
        &self,
        policy: &str,
        scene: &str,
        pick: impl Fn(&Place) -> bool,
        f: impl Fn(&Place) -> f64,
    ) -> Stat {
        Stat::of(self.of(policy, scene).into_iter().flat_map(|m| {
            m.places
                .iter()
                .filter(|p| pick(p))
                .map(&f)
                .collect::<Vec<_>>()
        }))
    }

    pub fn curves(&self, stage: &str, tag: &str) -> Vec<&Curve> {
        self.curves
            .iter()
            .filter(|c| c.stage == stage && c.tag == tag)
            .collect()
    }

    pub fn eval_dir(&self, policy: &str, scene: &str) -> Option<&Path> {
        self.eval_dirs
            .iter()
            .find(|((p, s), _)| p == policy && s == scene)
            .map(|(_, d)| d.as_path())
    }
}

/// The learning curve the claims judge.
pub const RPD_TAG: &str = "Environment/Reward per Decision";

/// Learning-curve tags read back for the report.
pub const CURVE_TAGS: [&str; 2] = [
    "Environment/Reward per Decision",
    "Environment/Cumulative Reward",
];

/// Evaluate every (policy, scene) of `wanted`, for every training and
/// evaluation seed, reusing cached measurements; read the learning curves of
/// `stages`.
pub fn measure_all(
    dirs: &ConfigDirs,
    profile: &Profile,
    wanted: &[(&str, &str)],
    stages: &[Stage],
    out: &Path,
) -> Result<Measured> {
    let mut measurements = Vec::new();
    let mut eval_dirs = Vec::new();
    for &(policy, scene) in wanted {
        let baseline = !policy.contains('-');
        // A baseline does not depend on the training seed: measured once.
        let train_seeds: Vec<u64> = if baseline {
            vec![profile.seeds[0]]
        } else {
            profile.seeds.clone()
        };
        for &ts in &train_seeds {
            for &es in &profile.eval_seeds {
                let (m, dir) = measure_one(dirs, profile, out, policy, scene, ts, es)?;
                if !eval_dirs
                    .iter()
                    .any(|(k, _)| k == &(policy.to_string(), scene.to_string()))
                {
                    eval_dirs.push(((policy.to_string(), scene.to_string()), dir));
                }
                measurements.push(m);
            }
        }
    }
    let mut curves = Vec::new();
    for &ts in &profile.seeds {
        for stage in stages {
            let path = out
                .join(format!("s{ts}"))
                .join(&stage.name)
                .join("scalars.csv");
            curves.extend(read_curves(&path, &stage.name, ts)?);
        }
    }
    Ok(Measured {
        measurements,
        curves,
        eval_dirs,
    })
}

/// Where a policy lives: a stage's run folder of training seed `ts`.
fn policy_dir(out: &Path, policy: &str, ts: u64) -> PathBuf {
    out.join(format!("s{ts}")).join(policy)
}

fn stamp(dir: &Path) -> u64 {
    std::fs::metadata(dir.join("final").join("state.json"))
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_secs())
}

pub fn measure_one(
    dirs: &ConfigDirs,
    profile: &Profile,
    out: &Path,
    policy: &str,
    scene_id: &str,
    ts: u64,
    es: u64,
) -> Result<(Measurement, PathBuf)> {
    let baseline = !policy.contains('-');
    let (cache_dir, policy_path, phase) = if baseline {
        (out.join("measure"), None, Phase::Transfer)
    } else {
        let stage = Stage::find(policy);
        let d = policy_dir(out, policy, ts);
        (d.join("measure"), Some(d), stage.phase)
    };
    // Sampled evaluations (the default) are cached apart from deterministic ones.
    let mode = if profile.deterministic {
        ""
    } else {
        "-sampled"
    };
    let key = format!("{policy}@{scene_id}-e{es}{mode}");
    let cache = cache_dir.join(format!("{key}.json"));
    let eval_dir = cache_dir.join(&key);
    let want_stamp = policy_path.as_deref().map_or(0, stamp);
    if let Some(m) = std::fs::read_to_string(&cache)
        .ok()
        .and_then(|t| serde_json::from_str::<Measurement>(&t).ok())
        .filter(|m| {
            m.stamp == want_stamp
                && (m.summary.seconds - profile.seconds).abs() < 1.0
                && m.train_seed == ts
        })
    {
        return Ok((m, eval_dir));
    }
    let scene = crate::load_scene(dirs, scene_id, phase)?;
    let env_seed = ENV_SEED_BASE + 1000 * es + ts;
    let mut env = Env::with_grid_format(scene, env_seed, GridFormat::Bytes);
    let mut pol: Box<dyn deepfoids_env::Policy> = match &policy_path {
        Some(d) => Box::new(crate::load_trained(
            d,
            None,
            &env,
            profile.deterministic,
            env_seed,
        )?),
        None => crate::make_policy(
            dirs,
            policy,
            env_seed,
            &env,
            &crate::PolicyOptions {
                checkpoint: None,
                stochastic: !profile.deterministic,
            },
        )?,
    };
    eprintln!("measuring {policy} in {scene_id} (training seed {ts}, evaluation seed {es})");
    let mut acc = Acc::new(&env);
    let eval = evaluate(
        &mut env,
        pol.as_mut(),
        profile.warmup,
        profile.seconds,
        |env, tick, _| acc.observe(env, tick),
    )
    .with_context(|| format!("evaluating {policy} in {scene_id}"))?;
    let name = pol.name();
    let meta = EvalMeta {
        scene: scene_id,
        policy: &name,
        seed: env_seed,
        phase: phase.as_str(),
        deterministic: profile.deterministic,
        warmup: profile.warmup,
        seconds: eval.seconds,
        wall_seconds: eval.wall_seconds,
        ticks_per_second: eval.recorder.samples.len() as f64 / eval.wall_seconds.max(1e-9),
        rerun: RunArgs {
            scene: scene_id.to_string(),
            phase: phase.as_str().to_string(),
            seed: env_seed,
            policy: policy_path
                .as_ref()
                .map_or(policy.to_string(), |d| d.display().to_string()),
            checkpoint: None,
            stochastic: !profile.deterministic,
            warmup: profile.warmup,
            seconds: profile.seconds,
            fish: None,
        },
    };
    let summary = write_outputs(&eval_dir, &env, &eval, &meta)?;
    let m = acc.finish(
        &env,
        summary,
        policy,
        scene_id,
        ts,
        es,
        want_stamp,
        &eval.recorder.samples,
    );
    deepfoids_io::write_atomic(&cache, serde_json::to_string_pretty(&m)?.as_bytes())?;
    Ok((m, eval_dir))
}

/// Sums collected at every recorded tick.
struct Acc {
    centre: (f32, f32),
    ranges: Vec<std::ops::Range<usize>>,
    axis: Vec<f64>,
    rot: Vec<f64>,
    n: Vec<u64>,
    depths: Vec<Vec<f32>>,
    school_rot: f64,
    ticks: u64,
    prev: Vec<Chase>,
    since: Vec<f64>,
    chases: Chases,
    timeout: f64,
    chase_term: usize,
}

impl Acc {
    fn new(env: &Env) -> Self {
        let ranges: Vec<_> = env.behaviours().iter().map(|b| b.range()).collect();
        let nb = ranges.len();
        let chase_term = deepfoids_env::TERM_NAMES
            .iter()
            .position(|t| *t == "chase")
            .expect("a chase term");
        Self {
            centre: env.cage().axis(),
            ranges,
            axis: vec![0.0; nb],
            rot: vec![0.0; nb],
            n: vec![0; nb],
            depths: vec![Vec::new(); nb],
            school_rot: 0.0,
            ticks: 0,
            prev: Vec::new(),
            since: Vec::new(),
            chases: Chases::default(),
            timeout: env.scene().physics.chase_timeout as f64,
            chase_term,
        }
    }

    fn observe(&mut self, env: &Env, tick: u64) {
        let w = env.world();
        let mut school = 0.0f64;
        for b in 0..self.ranges.len() {
            let mut rot = 0.0f64;
            for i in self.ranges[b].clone() {
                let p = w.position[i];
                let (rx, rz) = (p.x - self.centre.0, p.z - self.centre.1);
                let r = rx.hypot(rz);
                self.axis[b] += r as f64;
                if let Some(c) = tangential(self.centre, p, w.heading[i]) {
                    rot += c as f64;
                }
                if tick.is_multiple_of(5) {
                    self.depths[b].push(-p.y);
                }
            }
            let cnt = self.ranges[b].len().max(1) as f64;
            self.rot[b] += (rot / cnt).abs();
            school += rot;
            self.n[b] += self.ranges[b].len() as u64;
        }
        self.school_rot += (school / w.len().max(1) as f64).abs();
        self.ticks += 1;
        // Chases: starts, and how each one ended.
        if tick == 0 {
            self.prev = w.chase.clone();
            self.since = vec![0.0; w.len()];
            return;
        }
        let out = env.output();
        for i in 0..w.len() {
            let (was, now) = (self.prev[i], w.chase[i]);
            if let (Chase::None, Chase::Aggressor { .. }) = (was, now) {
                self.chases.started += 1;
            }
            if let Chase::Aggressor { target, since } = was {
                let ended = !matches!(now, Chase::Aggressor { target: t2, since: s2 } if t2 == target && s2 == since);
                if ended {
                    let t = target as usize;
                    let term = |k: usize| -> Option<(f32, bool)> {
                        let b = out
                            .behaviours
                            .iter()
                            .find(|b| b.first <= k && k < b.first + b.n_agents)?;
                        let a = k - b.first;
                        b.decided
                            .then(|| (b.terms[a][self.chase_term], b.terminated[a]))
                    };
                    let bonus = 0.5 * env.scene().rewards.catch_bonus;
                    let (r, term_i) = term(i).unwrap_or((0.0, false));
                    let term_t = term(t).map(|x| x.1).unwrap_or(false);
                    if r >= bonus {
                        self.chases.contact += 1;
                    } else if term_i || term_t {
                        self.chases.boundary += 1;
                    } else if out.time - since >= self.timeout - 0.05 {
                        self.chases.timeout += 1;
                    } else {
                        // The target got behind the aggressor (at the decision;
                        // it may be in front again by the tick's end).
                        self.chases.lost_sight += 1;
                    }
                }
            }
        }
        self.prev.clone_from(&w.chase);
    }

    #[allow(clippy::too_many_arguments)]
    fn finish(
        mut self,
        env: &Env,
        summary: Summary,
        policy: &str,
        scene: &str,
        ts: u64,
        es: u64,
        stamp: u64,
        samples: &[deepfoids_env::metrics::Sample],
    ) -> Measurement {
        let (lo, hi) = env.cage().bounds;
        let inradius = 0.5 * (hi.x - lo.x).min(hi.z - lo.z);
        let ticks = self.ticks.max(1) as f64;
        let w = env.world();
        let places: Vec<Place> = env
            .behaviours()
            .iter()
            .enumerate()
            .map(|(b, info)| {
                let d = &mut self.depths[b];
                d.sort_by(|a, b| a.total_cmp(b));
                let q = |f: f32| {
                    if d.is_empty() {
                        f32::NAN
                    } else {
                        d[((d.len() - 1) as f32 * f).round() as usize]
                    }
                };
                let r = info.range();
                let bl = r.clone().map(|i| w.bl[i]).sum::<f32>() / r.len().max(1) as f32;
                Place {
                    name: info.name.clone(),
                    species: info.species.clone(),
                    size_class: info.size_class.clone(),
                    bl,
                    axis_distance: (self.axis[b] / self.n[b].max(1) as f64) as f32,
                    cage_rotation: (self.rot[b] / ticks) as f32,
                    depth_q: [q(0.1), q(0.5), q(0.9)],
                }
            })
            .collect();
        let all_n: u64 = self.n.iter().sum();
        let axis = (self.axis.iter().sum::<f64>() / all_n.max(1) as f64) as f32;
        let mut pm = Vec::new();
        let mut next = f64::NEG_INFINITY;
        let t0 = samples.first().map_or(0.0, |s| s.t);
        for s in samples {
            if s.t >= next {
                pm.push(((s.t - t0) as f32, s.p, s.m));
                next = s.t + SERIES_STEP - 1e-6;
            }
        }
        let fish_hours = summary.fish as f64 * summary.seconds / 3600.0;
        Measurement {
            policy: policy.into(),
            scene: scene.into(),
            train_seed: ts,
            eval_seed: es,
            stamp,
            summary,
            places,
            axis_distance: axis,
            axis_distance_rel: axis / inradius,
            cage_rotation: (self.school_rot / ticks) as f32,
            cage_height: env.cage().height,
            cage_inradius: inradius,
            chases: self.chases,
            fish_hours,
            pm,
        }
    }
}

/// The curves of `CURVE_TAGS` in a stage's `scalars.csv` (none if missing).
pub fn read_curves(path: &Path, stage: &str, ts: u64) -> Result<Vec<Curve>> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(Vec::new());
    };
    let mut curves: Vec<Curve> = Vec::new();
    for line in text.lines().skip(1) {
        let mut f = line.splitn(4, ',');
        let (Some(beh), Some(step), Some(tag), Some(value)) =
            (f.next(), f.next(), f.next(), f.next())
        else {
            continue;
        };
        if !CURVE_TAGS.contains(&tag) {
            continue;
        }
        let (Ok(step), Ok(value)) = (step.parse::<u64>(), value.parse::<f64>()) else {
            continue;
        };
        match curves
            .iter_mut()
            .find(|c| c.behaviour == beh && c.tag == tag)
        {
            Some(c) => c.points.push((step, value)),
            None => curves.push(Curve {
                stage: stage.into(),
                train_seed: ts,
                behaviour: beh.into(),
                tag: tag.into(),
                points: vec![(step, value)],
            }),
        }
    }
    for c in &mut curves {
        // Stable: of several values logged at one step, the last is kept.
        c.points.sort_by_key(|p| p.0);
        let mut kept: Vec<(u64, f64)> = Vec::with_capacity(c.points.len());
        for &p in &c.points {
            match kept.last_mut() {
                Some(last) if last.0 == p.0 => *last = p,
                _ => kept.push(p),
            }
        }
        c.points = kept;
    }
    Ok(curves)
}
