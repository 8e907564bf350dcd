//! How a school is judged, whoever drives it (SPEC §9; thesis Appendix A.3).
//!
//! * Order parameters over the N fish of a school at one instant, with `x_c`
//!   the school centre, `r_i = x_i − x_c` and `d_i` the unit heading (Eq. A.3):
//!   `P = |Σ d_i| / N` (polarisation), `M = |Σ (r_i × d_i)/|r_i|| / N` (milling).
//! * School state by the thresholds of Tunstrøm et al. (2013): swarm
//!   `P < 0.35 ∧ M < 0.35`; milling `P < 0.35 ∧ M > 0.65`; polarised
//!   `P > 0.65 ∧ M < 0.35`; otherwise transitional.
//! * Nearest-neighbour distance in body lengths (of the fish measuring it),
//!   collisions per fish-hour, speed in BL/s, depth distribution per behaviour,
//!   cumulative reward per term.
//! * Turning about the vertical ([`Turning`]): each fish's mean rate in deg/s,
//!   positive clockwise seen from above (from +x towards +z, y up), and the
//!   share of fish turning clockwise. A lone fish of a lateralised policy circles one
//!   way; so does every fish of a school that shares the policy (issue 21).
//! * Own circling about the cage's vertical axis ([`Circling`]; not in the
//!   sources): the mean over fish of |each fish's time-mean [`tangential`]
//!   heading|. 1: every fish circles the axis, each in a sense of its own or
//!   all in one; → 0: fish wander. M and P cannot tell fish that circle the
//!   cage singly in mixed senses from a swarm; this can (issue 21, session 58).

use crate::env::{N_TERMS, StepOutput, TERM_NAMES};
use deepfoids_sensors::SpatialGrid;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};

/// Polarisation `P` and milling `M` (Eq. A.3) of the fish `idx` (all if `None`).
pub fn order_parameters(position: &[Vec3], heading: &[Vec3], idx: Option<&[usize]>) -> (f32, f32) {
    let all: Vec<usize>;
    let idx = match idx {
        Some(i) => i,
        None => {
            all = (0..position.len()).collect();
            &all
        }
    };
    let n = idx.len();
    if n == 0 {
        return (0.0, 0.0);
    }
    let centre = idx.iter().map(|&i| position[i]).sum::<Vec3>() / n as f32;
    let mut sum_d = Vec3::ZERO;
    let mut sum_m = Vec3::ZERO;
    for &i in idx {
        let d = heading[i].normalize_or_zero();
        sum_d += d;
        let r = position[i] - centre;
        let len = r.length();
        if len > 1e-9 {
            sum_m += r.cross(d) / len;
        }
    }
    (sum_d.length() / n as f32, sum_m.length() / n as f32)
}

/// The collective state of a school (Tunstrøm et al. 2013).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SchoolState {
    Swarm,
    Milling,
    Polarised,
    Transitional,
}

impl SchoolState {
    /// Lower threshold of "high" and upper threshold of "low".
    pub const LOW: f32 = 0.35;
    pub const HIGH: f32 = 0.65;
    pub const ALL: [SchoolState; 4] = [
        SchoolState::Swarm,
        SchoolState::Milling,
        SchoolState::Polarised,
        SchoolState::Transitional,
    ];

    pub fn classify(p: f32, m: f32) -> Self {
        if p < Self::LOW && m < Self::LOW {
            SchoolState::Swarm
        } else if p < Self::LOW && m > Self::HIGH {
            SchoolState::Milling
        } else if p > Self::HIGH && m < Self::LOW {
            SchoolState::Polarised
        } else {
            SchoolState::Transitional
        }
    }

    pub fn as_str(&self) -> &'static str {
        match self {
            SchoolState::Swarm => "swarm",
            SchoolState::Milling => "milling",
            SchoolState::Polarised => "polarised",
            SchoolState::Transitional => "transitional",
        }
    }

    fn index(&self) -> usize {
        *self as usize
    }
}

/// Nearest-neighbour distance of every fish in its own body lengths
/// (`f32::INFINITY` for a fish alone) into `out`, and that neighbour's index
/// (`u32::MAX` for a fish alone) into `index`, using `grid` (rebuilt here).
pub fn nearest_neighbours(
    position: &[Vec3],
    bl: &[f32],
    grid: &mut SpatialGrid,
    out: &mut Vec<f32>,
    index: &mut Vec<u32>,
) {
    grid.rebuild(position, &[]);
    out.clear();
    index.clear();
    for (i, &p) in position.iter().enumerate() {
        // Grow the search until something is found (cells are a few BL wide).
        let mut radius = grid.cell_size();
        let (mut best, mut who) = (f32::INFINITY, u32::MAX);
        for _ in 0..6 {
            grid.for_each_candidate(p, radius, |j, q| {
                let d2 = q.truncate().distance_squared(p);
                if j != i && d2 < best {
                    (best, who) = (d2, j as u32);
                }
            });
            if best <= radius * radius {
                break;
            }
            radius *= 2.0;
        }
        out.push(best.sqrt() / bl[i]);
        index.push(who);
    }
}

/// The mean over the fish of `cos` of the angle between a fish's heading and
/// its nearest neighbour's (`index`, from [`nearest_neighbours`]; fish alone
/// left out, NaN when every fish is): 1 when neighbours swim side by side,
/// as in a polarised school or a mill, ≈ 0 for independent headings. Not in
/// the sources: P and M judge the whole school, this a fish's neighbourhood.
pub fn neighbour_alignment(heading: &[Vec3], index: &[u32]) -> f32 {
    let (mut sum, mut n) = (0.0f32, 0usize);
    for (i, &j) in index.iter().enumerate() {
        if j != u32::MAX {
            sum += heading[i].dot(heading[j as usize]);
            n += 1;
        }
    }
    if n == 0 { f32::NAN } else { sum / n as f32 }
}

/// The `q`-quantile (0–1) of `values` by linear interpolation (sorts a copy).
pub fn quantile(values: &[f32], q: f32) -> f32 {
    let mut v: Vec<f32> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f32::NAN;
    }
    v.sort_by(f32::total_cmp);
    let pos = q.clamp(0.0, 1.0) * (v.len() - 1) as f32;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    v[lo] + (v[hi] - v[lo]) * (pos - lo as f32)
}

/// Each fish's turning about the vertical, summed from one sample to the
/// next: how far its heading's bearing (the angle of its horizontal part,
/// from +x towards +z) moved, wrapped to (−180°, 180°], and over what time.
/// An interval does not count where the fish respawned since the last sample
/// ([`Turning::restart`]) or where either heading is within 5.7° of vertical
/// (horizontal part below 0.1), whose bearing means nothing. (The recorder
/// learns of a respawn at the fish's next decision: where a behaviour decides
/// less often than every tick, the jump itself may count once, as a turn of
/// at most 180°.)
#[derive(Clone, Debug, Default)]
pub struct Turning {
    /// Bearing at the last sample (rad); NaN where the next interval must not count.
    last: Vec<f64>,
    last_t: f64,
    /// Turned (rad) and time (s) summed over the intervals that count.
    turned: Vec<f64>,
    time: Vec<f64>,
}

impl Turning {
    /// Horizontal part of a unit heading below which its bearing is not used.
    pub const MIN_HORIZONTAL: f32 = 0.1;

    pub fn new(fish: usize) -> Self {
        Self {
            last: vec![f64::NAN; fish],
            last_t: f64::NAN,
            turned: vec![0.0; fish],
            time: vec![0.0; fish],
        }
    }

    /// Fish `i` was put somewhere else (a respawn): its next interval does not count.
    pub fn restart(&mut self, i: usize) {
        self.last[i] = f64::NAN;
    }

    /// Every fish's unit heading at simulated time `t` (s).
    pub fn sample(&mut self, t: f64, heading: &[Vec3]) {
        let dt = t - self.last_t;
        for (i, h) in heading.iter().enumerate() {
            let bearing = if h.x.hypot(h.z) >= Self::MIN_HORIZONTAL {
                f64::from(h.z).atan2(f64::from(h.x))
            } else {
                f64::NAN
            };
            let d = bearing - self.last[i];
            if d.is_finite() && dt > 0.0 {
                self.turned[i] += (d + PI).rem_euclid(TAU) - PI;
                self.time[i] += dt;
            }
            self.last[i] = bearing;
        }
        self.last_t = t;
    }

    /// Each fish's mean turning rate (deg/s, + clockwise seen from above);
    /// NaN for a fish with no interval that counted.
    pub fn rates(&self) -> Vec<f32> {
        self.turned
            .iter()
            .zip(&self.time)
            .map(|(a, t)| {
                if *t > 0.0 {
                    (a.to_degrees() / t) as f32
                } else {
                    f32::NAN
                }
            })
            .collect()
    }

    /// The mean of the finite `rates` and the share of them above 0 (NaN, NaN
    /// if none is finite).
    pub fn stats(rates: &[f32]) -> (f32, f32) {
        let v: Vec<f32> = rates.iter().copied().filter(|r| r.is_finite()).collect();
        if v.is_empty() {
            return (f32::NAN, f32::NAN);
        }
        let n = v.len() as f32;
        (
            v.iter().sum::<f32>() / n,
            v.iter().filter(|r| **r > 0.0).count() as f32 / n,
        )
    }
}

/// The tangential part of a fish's horizontal heading about the vertical axis
/// through `centre` (its x, z): the vertical component of r̂ × ĥ, with `r` the
/// fish's horizontal offset from the axis and `ĥ` its horizontal heading, both
/// normalised. +1 swimming counter-clockwise around the axis seen from above
/// (y up; from +z towards +x), −1 clockwise, 0 straight towards or away
/// from it. `None` on the axis or for a vertical heading.
pub fn tangential(centre: (f32, f32), position: Vec3, heading: Vec3) -> Option<f32> {
    let (rx, rz) = (position.x - centre.0, position.z - centre.1);
    let r = rx.hypot(rz);
    let h = heading.x.hypot(heading.z);
    (r > 1e-6 && h > 1e-6).then(|| (rz * heading.x - rx * heading.z) / (r * h))
}

/// Each fish's circling about the cage's vertical axis: the time mean of its
/// [`tangential`] heading over the samples where it has one. A fish that
/// circles the axis one way all along scores ±1; one that wanders, passing
/// the axis on either side, → 0 as the window grows. A respawned fish goes on
/// adding to its mean. Not in the sources (issue 21, session 58).
#[derive(Clone, Debug)]
pub struct Circling {
    centre: (f32, f32),
    sum: Vec<f64>,
    n: Vec<u32>,
}

impl Circling {
    /// `fish` fish about the vertical axis through `centre` (x, z).
    pub fn new(centre: (f32, f32), fish: usize) -> Self {
        Self {
            centre,
            sum: vec![0.0; fish],
            n: vec![0; fish],
        }
    }

    /// Every fish's position and unit heading now.
    pub fn sample(&mut self, position: &[Vec3], heading: &[Vec3]) {
        for (i, (p, h)) in position.iter().zip(heading).enumerate() {
            if let Some(c) = tangential(self.centre, *p, *h) {
                self.sum[i] += f64::from(c);
                self.n[i] += 1;
            }
        }
    }

    /// The mean over the fish of `range` of |their time-mean tangential
    /// heading|, in [0, 1]; NaN if none of them has a sample.
    pub fn own(&self, range: std::ops::Range<usize>) -> f32 {
        let (sum, fish) = range
            .filter(|&i| self.n[i] > 0)
            .fold((0.0f64, 0u32), |(s, k), i| {
                (s + (self.sum[i] / f64::from(self.n[i])).abs(), k + 1)
            });
        if fish == 0 {
            f32::NAN
        } else {
            (sum / f64::from(fish)) as f32
        }
    }
}

/// One sample of the school, taken at a tick.
#[derive(Clone, Debug, Serialize)]
pub struct Sample {
    /// Simulated time (s).
    pub t: f64,
    pub p: f32,
    pub m: f32,
    pub state: SchoolState,
    /// P and M per behaviour, in behaviour order.
    pub per_behaviour: Vec<(f32, f32)>,
    /// Mean and 5th percentile of the nearest-neighbour distance (BL).
    pub nn_mean_bl: f32,
    pub nn_p05_bl: f32,
    /// [`neighbour_alignment`] now.
    pub nn_alignment: f32,
    /// Mean speed (BL/s) and depth (m).
    pub speed_bl: f32,
    pub depth: f32,
    /// Boundary and neighbour collisions since the previous sample.
    pub boundary_collisions: u64,
    pub neighbour_collisions: u64,
    /// Mean reward per agent-decision of the decisions ending at this tick (NaN if none).
    pub reward: f32,
}

/// Per-behaviour totals over a run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BehaviourSummary {
    pub name: String,
    pub fish: usize,
    pub decisions: u64,
    pub p_mean: f32,
    pub m_mean: f32,
    /// Mean reward per agent-decision and each term's mean (in [`TERM_NAMES`] order).
    pub reward_per_decision: f64,
    pub terms_per_decision: Vec<(String, f64)>,
    /// Reward per agent-decision summed… per fish over the run (cumulative reward).
    pub cumulative_reward_per_fish: f64,
    pub boundary_collisions_per_fish_hour: f64,
    pub neighbour_collisions_per_fish_hour: f64,
    pub mean_speed_bl: f32,
    /// Depth histogram: `depth_edges` (m) has one more entry than `depth_share`.
    pub depth_edges: Vec<f32>,
    pub depth_share: Vec<f32>,
    pub mean_depth: f32,
    /// How this behaviour's fish turn.
    #[serde(flatten)]
    pub turning: TurningSummary,
}

/// How fish turn about the vertical, in a summary's JSON beside its other
/// fields. Each is absent (NaN) in files written before it was measured.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TurningSummary {
    /// The mean of the fish's turning rates (deg/s, + clockwise seen from
    /// above; [`Turning`]).
    #[serde(default = "nan", deserialize_with = "f32_or_nan")]
    pub turn_rate_deg_s: f32,
    /// The share of fish turning clockwise.
    #[serde(default = "nan", deserialize_with = "f32_or_nan")]
    pub clockwise_share: f32,
    /// [`Circling::own`] over the fish.
    #[serde(default = "nan", deserialize_with = "f32_or_nan")]
    pub own_circling: f32,
}

fn nan() -> f32 {
    f32::NAN
}

/// A value that may be NaN, as `serde_json` writes NaN (`null`), read back
/// as NaN (a lone fish has no nearest neighbour).
fn f32_or_nan<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    Ok(Option::<f32>::deserialize(d)?.unwrap_or(f32::NAN))
}

/// Everything `eval` reports, for the whole school.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Summary {
    pub seconds: f64,
    pub samples: usize,
    pub fish: usize,
    pub p_mean: f32,
    pub p_std: f32,
    pub m_mean: f32,
    pub m_std: f32,
    /// Share of samples in each state.
    pub state_share: Vec<(SchoolState, f32)>,
    /// The state most often seen.
    pub dominant_state: SchoolState,
    #[serde(deserialize_with = "f32_or_nan")]
    pub nn_mean_bl: f32,
    #[serde(deserialize_with = "f32_or_nan")]
    pub nn_p05_bl: f32,
    /// The mean over the samples of [`neighbour_alignment`]. Absent (NaN) in
    /// files written before it was measured.
    #[serde(default = "nan", deserialize_with = "f32_or_nan")]
    pub nn_alignment: f32,
    pub boundary_collisions_per_fish_hour: f64,
    pub neighbour_collisions_per_fish_hour: f64,
    pub mean_speed_bl: f32,
    pub reward_per_decision: f64,
    /// How every fish turns.
    #[serde(flatten)]
    pub turning: TurningSummary,
    pub behaviours: Vec<BehaviourSummary>,
}

#[derive(Clone, Debug, Default)]
struct Acc {
    decisions: u64,
    reward: f64,
    terms: [f64; N_TERMS],
    boundary: u64,
    neighbour: u64,
    p: f64,
    m: f64,
    speed: f64,
    speed_n: u64,
    depth: Vec<u64>,
    depth_sum: f64,
}

/// Collects samples and totals from the outputs of a run.
pub struct Recorder {
    names: Vec<String>,
    counts: Vec<usize>,
    ranges: Vec<std::ops::Range<usize>>,
    cage_height: f32,
    depth_bins: usize,
    grid: SpatialGrid,
    nn: Vec<f32>,
    nn_index: Vec<u32>,
    acc: Vec<Acc>,
    pending_boundary: u64,
    pending_neighbour: u64,
    turning: Turning,
    circling: Circling,
    pub samples: Vec<Sample>,
}

impl Recorder {
    /// A recorder for `env`'s school.
    pub fn new(env: &crate::Env) -> Self {
        let (lo, hi) = env.cage().bounds;
        let max_bl = env.world().bl.iter().copied().fold(0.1, f32::max);
        let depth_bins = 20;
        Self {
            names: env.behaviours().iter().map(|b| b.name.clone()).collect(),
            counts: env.behaviours().iter().map(|b| b.count).collect(),
            ranges: env.behaviours().iter().map(|b| b.range()).collect(),
            cage_height: env.cage().height,
            depth_bins,
            grid: SpatialGrid::new(lo, hi, 2.0 * max_bl, env.world().len()),
            nn: Vec::with_capacity(env.world().len()),
            nn_index: Vec::with_capacity(env.world().len()),
            acc: vec![
                Acc {
                    depth: vec![0; depth_bins],
                    ..Acc::default()
                };
                env.behaviours().len()
            ],
            pending_boundary: 0,
            pending_neighbour: 0,
            turning: Turning::new(env.world().len()),
            circling: Circling::new(env.cage().axis(), env.world().len()),
            samples: Vec::new(),
        }
    }

    /// Count the rewards and collisions of an output (call for every output).
    pub fn count(&mut self, out: &StepOutput) {
        for (b, batch) in out.behaviours.iter().enumerate() {
            if !batch.decided {
                continue;
            }
            let a = &mut self.acc[b];
            a.decisions += batch.n_agents as u64;
            for i in 0..batch.n_agents {
                a.reward += batch.rewards[i] as f64;
                for (t, v) in batch.terms[i].iter().enumerate() {
                    a.terms[t] += *v as f64;
                }
                if batch.terminated[i] {
                    self.turning.restart(batch.first + i);
                }
                let bc = batch.crossed[i] as u64;
                a.boundary += bc;
                a.neighbour += batch.new_collisions[i] as u64;
                self.pending_boundary += bc;
                self.pending_neighbour += batch.new_collisions[i] as u64;
            }
        }
    }

    /// Take a sample of the school's state now.
    pub fn sample(&mut self, out: &StepOutput) {
        let f = &out.fish;
        self.turning.sample(out.time, &f.heading);
        self.circling.sample(&f.position, &f.heading);
        let (p, m) = order_parameters(&f.position, &f.heading, None);
        let per_behaviour: Vec<(f32, f32)> = self
            .ranges
            .iter()
            .map(|r| {
                let idx: Vec<usize> = r.clone().collect();
                order_parameters(&f.position, &f.heading, Some(&idx))
            })
            .collect();
        nearest_neighbours(
            &f.position,
            &f.bl,
            &mut self.grid,
            &mut self.nn,
            &mut self.nn_index,
        );
        let finite: Vec<f32> = self.nn.iter().copied().filter(|x| x.is_finite()).collect();
        let nn_mean = if finite.is_empty() {
            f32::NAN
        } else {
            finite.iter().sum::<f32>() / finite.len() as f32
        };
        let n = f.position.len().max(1) as f32;
        let speed = f.speed.iter().zip(&f.bl).map(|(s, b)| s / b).sum::<f32>() / n;
        let depth = f.position.iter().map(|p| -p.y).sum::<f32>() / n;
        for (b, r) in self.ranges.iter().enumerate() {
            let a = &mut self.acc[b];
            a.p += per_behaviour[b].0 as f64;
            a.m += per_behaviour[b].1 as f64;
            for i in r.clone() {
                a.speed += (f.speed[i] / f.bl[i]) as f64;
                a.speed_n += 1;
                let d = -f.position[i].y;
                a.depth_sum += d as f64;
                let bin = ((d / self.cage_height) * self.depth_bins as f32)
                    .clamp(0.0, self.depth_bins as f32 - 1.0) as usize;
                a.depth[bin] += 1;
            }
        }
        let (mut r_sum, mut r_n) = (0.0f64, 0u64);
        for batch in out.behaviours.iter().filter(|b| b.decided) {
            r_sum += batch.rewards.iter().map(|&r| r as f64).sum::<f64>();
            r_n += batch.n_agents as u64;
        }
        self.samples.push(Sample {
            t: out.time,
            p,
            m,
            state: SchoolState::classify(p, m),
            per_behaviour,
            nn_mean_bl: nn_mean,
            nn_p05_bl: quantile(&finite, 0.05),
            nn_alignment: neighbour_alignment(&f.heading, &self.nn_index),
            speed_bl: speed,
            depth,
            boundary_collisions: std::mem::take(&mut self.pending_boundary),
            neighbour_collisions: std::mem::take(&mut self.pending_neighbour),
            reward: if r_n > 0 {
                (r_sum / r_n as f64) as f32
            } else {
                f32::NAN
            },
        });
    }

    /// How the fish in `range` turned, from every fish's turning `rates`.
    fn turning_summary(&self, rates: &[f32], range: std::ops::Range<usize>) -> TurningSummary {
        let (turn_rate_deg_s, clockwise_share) = Turning::stats(&rates[range.clone()]);
        TurningSummary {
            turn_rate_deg_s,
            clockwise_share,
            own_circling: self.circling.own(range),
        }
    }

    /// Totals over the run; `seconds` is the simulated time covered.
    pub fn summary(&self, seconds: f64) -> Summary {
        let s = &self.samples;
        let n = s.len().max(1) as f32;
        let mean = |f: &dyn Fn(&Sample) -> f32| s.iter().map(f).sum::<f32>() / n;
        let std = |f: &dyn Fn(&Sample) -> f32, mu: f32| {
            (s.iter().map(|x| (f(x) - mu).powi(2)).sum::<f32>() / n).sqrt()
        };
        let (p_mean, m_mean) = (mean(&|x| x.p), mean(&|x| x.m));
        let mut states = [0usize; 4];
        for x in s {
            states[x.state.index()] += 1;
        }
        let state_share: Vec<(SchoolState, f32)> = SchoolState::ALL
            .iter()
            .map(|st| (*st, states[st.index()] as f32 / n))
            .collect();
        let dominant_state = state_share
            .iter()
            .fold(state_share[0], |a, b| if b.1 > a.1 { *b } else { a })
            .0;
        let fish: usize = self.counts.iter().sum();
        let fish_hours = fish as f64 * seconds / 3600.0;
        let finite_mean = |f: &dyn Fn(&Sample) -> f32| {
            let v: Vec<f32> = s.iter().map(f).filter(|x| x.is_finite()).collect();
            if v.is_empty() {
                f32::NAN
            } else {
                v.iter().sum::<f32>() / v.len() as f32
            }
        };
        let rates = self.turning.rates();
        let behaviours: Vec<BehaviourSummary> = self
            .acc
            .iter()
            .enumerate()
            .map(|(b, a)| {
                let dec = a.decisions.max(1) as f64;
                let hours = self.counts[b] as f64 * seconds / 3600.0;
                let total: u64 = a.depth.iter().sum();
                BehaviourSummary {
                    name: self.names[b].clone(),
                    fish: self.counts[b],
                    decisions: a.decisions,
                    p_mean: (a.p / n as f64) as f32,
                    m_mean: (a.m / n as f64) as f32,
                    reward_per_decision: a.reward / dec,
                    terms_per_decision: TERM_NAMES
                        .iter()
                        .zip(a.terms)
                        .map(|(t, v)| (t.to_string(), v / dec))
                        .collect(),
                    cumulative_reward_per_fish: a.reward / self.counts[b].max(1) as f64,
                    boundary_collisions_per_fish_hour: a.boundary as f64 / hours.max(1e-12),
                    neighbour_collisions_per_fish_hour: a.neighbour as f64 / hours.max(1e-12),
                    mean_speed_bl: (a.speed / a.speed_n.max(1) as f64) as f32,
                    depth_edges: (0..=self.depth_bins)
                        .map(|k| self.cage_height * k as f32 / self.depth_bins as f32)
                        .collect(),
                    depth_share: a
                        .depth
                        .iter()
                        .map(|&c| c as f32 / total.max(1) as f32)
                        .collect(),
                    mean_depth: (a.depth_sum / a.speed_n.max(1) as f64) as f32,
                    turning: self.turning_summary(&rates, self.ranges[b].clone()),
                }
            })
            .collect();
        let decisions: u64 = self.acc.iter().map(|a| a.decisions).sum();
        Summary {
            seconds,
            samples: s.len(),
            fish,
            p_mean,
            p_std: std(&|x| x.p, p_mean),
            m_mean,
            m_std: std(&|x| x.m, m_mean),
            state_share,
            dominant_state,
            nn_mean_bl: finite_mean(&|x| x.nn_mean_bl),
            nn_p05_bl: finite_mean(&|x| x.nn_p05_bl),
            nn_alignment: finite_mean(&|x| x.nn_alignment),
            boundary_collisions_per_fish_hour: self.acc.iter().map(|a| a.boundary).sum::<u64>()
                as f64
                / fish_hours.max(1e-12),
            neighbour_collisions_per_fish_hour: self.acc.iter().map(|a| a.neighbour).sum::<u64>()
                as f64
                / fish_hours.max(1e-12),
            mean_speed_bl: mean(&|x| x.speed_bl),
            reward_per_decision: self.acc.iter().map(|a| a.reward).sum::<f64>()
                / decisions.max(1) as f64,
            turning: self.turning_summary(&rates, 0..fish),
            behaviours,
        }
    }

    pub fn behaviour_names(&self) -> &[String] {
        &self.names
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::TAU;

    /// All fish aligned, on a grid symmetric about its centre: P = 1 and
    /// M = |(Σ r̂_i) × d| / N = 0 (the r̂_i cancel in pairs).
    #[test]
    fn aligned_fish_are_polarised() {
        let mut pos = vec![];
        for x in -2..=2 {
            for z in -2..=2 {
                for y in [-1.0f32, -2.0] {
                    pos.push(Vec3::new(x as f32 * 0.3, y, z as f32 * 0.4));
                }
            }
        }
        let head = vec![Vec3::new(1.0, 0.0, 1.0).normalize(); pos.len()];
        let (p, m) = order_parameters(&pos, &head, None);
        assert!((p - 1.0).abs() < 1e-6, "{p}");
        assert!(m < 1e-5, "{m}");
        assert_eq!(SchoolState::classify(p, m), SchoolState::Polarised);
    }

    /// A unit heading at bearing `deg` (from +x towards +z), pitched by `pitch` rad.
    fn bearing(deg: f32, pitch: f32) -> Vec3 {
        let (b, c) = (deg.to_radians(), pitch.cos());
        Vec3::new(c * b.cos(), pitch.sin(), c * b.sin())
    }

    /// Sampled every 0.2 s for 10 s: fish 0 turns 6° clockwise (from +x towards
    /// +z) per sample, 300° in all, across the ±180° seam: 30°/s; fish 1 turns
    /// 4° the other way per sample, pitched 30°: −20°/s; fish 2 points straight
    /// up: no bearing, no rate. Mean of the two rates 5°/s, one of two clockwise.
    #[test]
    fn turning_rates_are_the_bearing_turned_over_the_time() {
        let mut turning = Turning::new(3);
        for k in 0..=50 {
            let heading = [
                bearing(100.0 + 6.0 * k as f32, 0.0),
                bearing(-4.0 * k as f32, std::f32::consts::FRAC_PI_6),
                Vec3::Y,
            ];
            turning.sample(0.2 * k as f64, &heading);
        }
        let rates = turning.rates();
        assert!((rates[0] - 30.0).abs() < 1e-3, "{rates:?}");
        assert!((rates[1] + 20.0).abs() < 1e-3, "{rates:?}");
        assert!(rates[2].is_nan());
        let (mean, clockwise) = Turning::stats(&rates);
        assert!(
            (mean - 5.0).abs() < 1e-3 && clockwise == 0.5,
            "{mean} {clockwise}"
        );
    }

    /// A respawn's jump is not a turn: fish 0 turns 2° per 0.2 s, is moved to
    /// a bearing 150° away after the 5th sample, then turns on. The interval
    /// with the jump is left out: 9 intervals of 2° in 1.8 s, 10°/s.
    #[test]
    fn a_respawn_does_not_count_as_a_turn() {
        let mut turning = Turning::new(1);
        for k in 0..=10 {
            let jump = if k > 5 { 150.0 } else { 0.0 };
            if k == 6 {
                turning.restart(0);
            }
            turning.sample(0.2 * k as f64, &[bearing(2.0 * k as f32 + jump, 0.0)]);
        }
        let rate = turning.rates()[0];
        assert!((rate - 10.0).abs() < 1e-3, "{rate}");
        assert!(Turning::stats(&[f32::NAN]).0.is_nan());
    }

    /// About the axis through (1, 2): a fish at (3, ., 2) heading −z swims
    /// counter-clockwise seen from above (+1); heading +z, clockwise (−1);
    /// heading −x, straight at the axis (0); at 45° between −z and −x, 1/√2.
    /// On the axis, or heading straight up, there is none.
    #[test]
    fn tangential_headings_by_hand() {
        let c = (1.0, 2.0);
        let p = Vec3::new(3.0, -1.0, 2.0);
        let t = |h: Vec3| tangential(c, p, h).unwrap();
        assert!((t(Vec3::NEG_Z) - 1.0).abs() < 1e-6);
        assert!((t(Vec3::Z) + 1.0).abs() < 1e-6);
        assert!(t(Vec3::NEG_X).abs() < 1e-6);
        let diag = Vec3::new(-1.0, 0.0, -1.0).normalize();
        assert!((t(diag) - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-6);
        assert!(tangential(c, Vec3::new(1.0, -1.0, 2.0), Vec3::X).is_none());
        assert!(tangential(c, p, Vec3::Y).is_none());
    }

    /// Over 8 samples about the origin: fish 0 circles it counter-clockwise
    /// (+1 each time); fish 1 circles it the other way (−1); fish 2 crosses
    /// the cage heading +x at z = 1 from x = −3.5 to 3.5, whose tangential
    /// part is 1/√(x² + 1) at each x (it passes the axis on one side only):
    /// (2/√13.25 + 2/√7.25 + 2/√3.25 + 2/√1.25)/8 = 0.5238; fish 3 sits on
    /// the axis and never counts. Own circling (1 + 1 + 0.5238)/3 = 0.8413;
    /// over fish 0 and 1 alone 1, though they cancel in a mean about the axis.
    #[test]
    fn own_circling_by_hand() {
        let mut c = Circling::new((0.0, 0.0), 4);
        for k in 0..8 {
            let a = TAU * k as f32 / 8.0;
            let (ca, sa) = (a.cos(), a.sin());
            let x = -3.5 + k as f32;
            c.sample(
                &[
                    Vec3::new(2.0 * ca, -1.0, 2.0 * sa),
                    Vec3::new(3.0 * ca, -1.0, 3.0 * sa),
                    Vec3::new(x, -1.0, 1.0),
                    Vec3::new(0.0, -1.0, 0.0),
                ],
                &[
                    Vec3::new(sa, 0.0, -ca),
                    Vec3::new(-sa, 0.0, ca),
                    Vec3::X,
                    Vec3::X,
                ],
            );
        }
        let crossing: f64 = [13.25f64, 7.25, 3.25, 1.25]
            .iter()
            .map(|r2| 2.0 / r2.sqrt())
            .sum::<f64>()
            / 8.0;
        assert!((crossing - 0.5238).abs() < 1e-4, "{crossing}");
        let want = ((2.0 + crossing) / 3.0) as f32;
        assert!((want - 0.8413).abs() < 1e-4, "{want}");
        assert!((c.own(0..4) - want).abs() < 1e-5, "{} {want}", c.own(0..4));
        assert!((c.own(0..2) - 1.0).abs() < 1e-6);
        assert!(c.own(3..4).is_nan());
    }

    /// Fish on a ring heading tangentially: M = 1, P ≈ 0.
    #[test]
    fn a_ring_mills() {
        let n = 100;
        let pos: Vec<Vec3> = (0..n)
            .map(|i| {
                let a = TAU * i as f32 / n as f32;
                Vec3::new(2.0 * a.cos(), -1.5, 2.0 * a.sin())
            })
            .collect();
        let head: Vec<Vec3> = (0..n)
            .map(|i| {
                let a = TAU * i as f32 / n as f32;
                Vec3::new(-a.sin(), 0.0, a.cos())
            })
            .collect();
        let (p, m) = order_parameters(&pos, &head, None);
        assert!(p < 1e-5, "{p}");
        assert!((m - 1.0).abs() < 1e-5, "{m}");
        assert_eq!(SchoolState::classify(p, m), SchoolState::Milling);
    }

    /// Random headings at random positions, N = 1,000: P and M ≈ 1/√N ≈ 0.03;
    /// both below 0.1 (> 3 standard deviations of the expected value).
    #[test]
    fn random_headings_are_disordered() {
        let mut s = crate::rng::Stream::new(3, crate::rng::Purpose::Policy, 0, 0);
        let n = 1000;
        let pos: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(s.range(-2.0, 2.0), s.range(-4.0, 0.0), s.range(-2.0, 2.0)))
            .collect();
        let head: Vec<Vec3> = (0..n)
            .map(|_| {
                loop {
                    let v = Vec3::new(s.range(-1.0, 1.0), s.range(-1.0, 1.0), s.range(-1.0, 1.0));
                    if v.length() > 0.1 && v.length() < 1.0 {
                        break v.normalize();
                    }
                }
            })
            .collect();
        let (p, m) = order_parameters(&pos, &head, None);
        assert!(p < 0.1 && m < 0.1, "P {p}, M {m}");
        assert_eq!(SchoolState::classify(p, m), SchoolState::Swarm);
    }

    #[test]
    fn states_by_thresholds() {
        assert_eq!(SchoolState::classify(0.1, 0.2), SchoolState::Swarm);
        assert_eq!(SchoolState::classify(0.2, 0.8), SchoolState::Milling);
        assert_eq!(SchoolState::classify(0.9, 0.1), SchoolState::Polarised);
        assert_eq!(SchoolState::classify(0.5, 0.5), SchoolState::Transitional);
        assert_eq!(SchoolState::classify(0.2, 0.5), SchoolState::Transitional);
        assert_eq!(SchoolState::classify(0.8, 0.8), SchoolState::Transitional);
        // The boundaries are strict.
        assert_eq!(SchoolState::classify(0.35, 0.1), SchoolState::Transitional);
    }

    #[test]
    fn nearest_neighbours_in_body_lengths() {
        let pos = vec![
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(2.5, -1.0, 0.0),
        ];
        let bl = vec![0.5, 0.25, 0.5];
        let mut grid = SpatialGrid::new(
            Vec3::new(-3.0, -3.0, -3.0),
            Vec3::new(3.0, 0.0, 3.0),
            0.4,
            3,
        );
        let (mut out, mut index) = (vec![], vec![]);
        nearest_neighbours(&pos, &bl, &mut grid, &mut out, &mut index);
        assert_eq!(out, vec![1.0, 2.0, 4.0]);
        assert_eq!(index, vec![1, 0, 1]);
        assert!((quantile(&[1.0, 2.0, 3.0, 4.0, 5.0], 0.05) - 1.2).abs() < 1e-6);
    }

    /// A lone fish's summary (no nearest neighbour: NaN, which JSON writes
    /// as `null`) reads back, NaN where it was NaN; a file from before
    /// `nn_alignment` and the turning were measured reads as NaN too.
    #[test]
    fn a_lone_fish_summary_reads_back() {
        let s = Summary {
            seconds: 60.0,
            samples: 2,
            fish: 1,
            p_mean: 1.0,
            p_std: 0.0,
            m_mean: 0.5,
            m_std: 0.0,
            state_share: SchoolState::ALL.iter().map(|s| (*s, 0.25)).collect(),
            dominant_state: SchoolState::Swarm,
            nn_mean_bl: f32::NAN,
            nn_p05_bl: f32::NAN,
            nn_alignment: f32::NAN,
            boundary_collisions_per_fish_hour: 0.0,
            neighbour_collisions_per_fish_hour: 0.0,
            mean_speed_bl: 1.5,
            reward_per_decision: 1.0,
            turning: TurningSummary {
                turn_rate_deg_s: -29.7,
                clockwise_share: 0.0,
                own_circling: 0.25,
            },
            behaviours: vec![],
        };
        let json = serde_json::to_string(&s).unwrap();
        assert!(json.contains("\"nn_alignment\":null"), "{json}");
        let back: Summary = serde_json::from_str(&json).unwrap();
        assert!(back.nn_mean_bl.is_nan() && back.nn_p05_bl.is_nan() && back.nn_alignment.is_nan());
        assert_eq!(
            (back.turning.turn_rate_deg_s, back.turning.clockwise_share),
            (-29.7, 0.0)
        );
        let old = json
            .replace(",\"nn_alignment\":null", "")
            .replace(",\"turn_rate_deg_s\":-29.7", "")
            .replace(",\"own_circling\":0.25", "");
        let back: Summary = serde_json::from_str(&old).unwrap();
        assert!(back.nn_alignment.is_nan() && back.turning.turn_rate_deg_s.is_nan());
        assert!(back.turning.own_circling.is_nan());
        assert_eq!(back.turning.clockwise_share, 0.0);
    }

    /// Fish 0 and 1 are each other's nearest, 60° apart (cos 0.5); fish 2's
    /// nearest is fish 1, heading opposite (−1): (0.5 + 0.5 − 1)/3 = 0. A fish
    /// alone is left out; a school of one has no alignment.
    #[test]
    fn neighbour_alignment_by_hand() {
        let (c, s) = (0.5f32, 0.75f32.sqrt());
        let heading = [Vec3::X, Vec3::new(c, 0.0, s), Vec3::new(-c, 0.0, -s)];
        assert!(neighbour_alignment(&heading, &[1, 0, 1]).abs() < 1e-6);
        assert!((neighbour_alignment(&heading, &[1, 0, u32::MAX]) - 0.5).abs() < 1e-6);
        assert!(neighbour_alignment(&heading[..1], &[u32::MAX]).is_nan());
    }
}
