//! Foids (Ishiwaka et al. 2021, §4, Algorithm 1, Table 1): the improved Boids
//! rules with distance terms, boundary avoidance with regular and front
//! factors, day/night scaling, the control cycle of Eq. 8 and the two swimming
//! modes. Parameters: `configs/baselines/foids.toml` (the tuned default) and
//! `configs/baselines/foids_table1.toml` (Table 1 as published).
//!
//! # Why the default is tuned
//!
//! Only the direction of the rules' sum `Δv_sum` matters once it exceeds the
//! speed range (the speed is clamped to [0.2, 1.9] BL/s, the turn to 20° per
//! decision), and with Table 1's weights separation (w_s = 30: up to
//! 30 · max (3 − d)·d = 67.5 BL/s) and alignment (w_a = 12: ≈ 14 BL/s at
//! schooling spacing) outweigh boundary avoidance (w_rb = w_fb = 1: at most
//! (4 − 0)·(1 + 1) = 8 BL/s at the net) by an order of magnitude. Near a net all
//! neighbours lie on the inner side, so separation points the fish into it:
//! Table 1 gives 2,000–2,800 boundary collisions per fish-hour in the density
//! scenes. Lifting the turn limit does not cure it (at 180° per decision,
//! 650–830, and the school falls apart into a swarm, P ≈ 0.05). The default
//! raises the two boundary weights to the separation's order — w_rb = 10,
//! w_fb = 15, everything else as Table 1 — which keeps every school inside
//! (≤ 5.3 per fish-hour in every single-species scene) at the price of a
//! denser school: r_pref = 4 BL spans most of these small cages, so the
//! regular factor, which points at the cage axis, also gathers the fish
//! (README, *Baselines*, has the table).
//!
//! All lengths are in the deciding fish's body lengths (BL) and velocities in
//! BL/s; the summed delta velocity `Δv_sum` (Eq. 8, without the light and
//! temperature terms the environment adds) gives the desired velocity
//! `v + Δv_sum`, turned into actions by [`super::steer`] within the action
//! limits, spread over the decision interval by the environment.

use super::{neighbour_grid, obstacle_deflection, steer};
use crate::config::{ConfigError, read_toml};
use crate::policy::{Policy, PolicyError};
use crate::rng::{Purpose, Stream};
use crate::{Env, FishParams, World};
use deepfoids_sensors::Boundary;
use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Foids parameters (Table 1 of the Foids paper). Lengths in BL.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FoidsConfig {
    /// Separation detection range `r_s` (BL). Table 1: 3.
    pub separation_range: f32,
    /// Alignment detection range `r_a` (BL). Table 1: 3.
    pub alignment_range: f32,
    /// Cohesion detection range `r_c` (BL). Table 1: 3.
    pub cohesion_range: f32,
    /// Separation weight `w_s` (BL). Table 1: 30.
    pub separation_weight: f32,
    /// Alignment weight `w_a` (BL). Table 1: 12.
    pub alignment_weight: f32,
    /// Cohesion weight `w_c` (BL). Table 1: 0.1.
    pub cohesion_weight: f32,
    /// Preferred distance to boundaries `r_pref` (BL). Table 1: 4.
    pub boundary_range: f32,
    /// Regular boundary avoidance weight `w_rb` (BL). Table 1: 1; default 10 (tuned, see the module docs).
    pub regular_boundary_weight: f32,
    /// Front boundary avoidance weight `w_fb` (BL). Table 1: 1; default 15 (tuned).
    pub front_boundary_weight: f32,
    /// Multiplier of vertical boundary avoidance `m`. Table 1: 2.5.
    pub vertical_multiplier: f32,
    /// Swimming speed at night (BL/s); by day the species' range. Table 1: [0, 0.4].
    pub night_speed: [f32; 2],
    /// Probability that a fish in the lower half of the cage starts hovering `H_start`. Table 1: 0.01.
    pub hover_start: f32,
    /// Probability per simulation step of switching mode `H_switch`. Table 1: 0.00005.
    pub hover_switch: f32,
    /// Elevation threshold for hover → rapid `θ_et` (degrees). Table 1: 23.
    pub elevation_threshold_deg: f32,
    /// Depression threshold for rapid → hover `θ_dt` (degrees). Table 1: 11.
    pub depression_threshold_deg: f32,
    /// Activeness of hovering fish `H_active` (scales speed, alignment and cohesion). Table 1: 0.17.
    pub hover_activeness: f32,
    /// Obstacle avoidance weight (BL/s); Foids has no obstacles, so the CS275 rule is used. Default 4.
    pub obstacle_weight: f32,
    /// Light steepness `[I_lsteep, I_hsteep]` (PAR) of Eq. 6, applied by the
    /// environment to Foids fish in place of DeepFoids' [−20, 1000]. Table 1: [−7, 409].
    pub light_steep: [f32; 2],
}

impl Default for FoidsConfig {
    fn default() -> Self {
        Self {
            separation_range: 3.0,
            alignment_range: 3.0,
            cohesion_range: 3.0,
            separation_weight: 30.0,
            alignment_weight: 12.0,
            cohesion_weight: 0.1,
            boundary_range: 4.0,
            regular_boundary_weight: 10.0,
            front_boundary_weight: 15.0,
            vertical_multiplier: 2.5,
            night_speed: [0.0, 0.4],
            hover_start: 0.01,
            hover_switch: 0.00005,
            elevation_threshold_deg: 23.0,
            depression_threshold_deg: 11.0,
            hover_activeness: 0.17,
            obstacle_weight: 4.0,
            light_steep: [-7.0, 409.0],
        }
    }
}

impl FoidsConfig {
    /// Read `path`; every value within [`crate::limits`].
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        use crate::config::Param::{Bl, Degrees, Share, Speed, Weight};
        let c: Self = read_toml(path)?;
        crate::config::params(
            path,
            &[
                ("separation_range", Bl(c.separation_range)),
                ("alignment_range", Bl(c.alignment_range)),
                ("cohesion_range", Bl(c.cohesion_range)),
                ("separation_weight", Weight(c.separation_weight)),
                ("alignment_weight", Weight(c.alignment_weight)),
                ("cohesion_weight", Weight(c.cohesion_weight)),
                ("boundary_range", Bl(c.boundary_range)),
                ("regular_boundary_weight", Weight(c.regular_boundary_weight)),
                ("front_boundary_weight", Weight(c.front_boundary_weight)),
                ("vertical_multiplier", Weight(c.vertical_multiplier)),
                ("night_speed[0]", Speed(c.night_speed[0])),
                ("night_speed[1]", Speed(c.night_speed[1])),
                ("hover_start", Share(c.hover_start)),
                ("hover_switch", Share(c.hover_switch)),
                (
                    "elevation_threshold_deg",
                    Degrees(c.elevation_threshold_deg),
                ),
                (
                    "depression_threshold_deg",
                    Degrees(c.depression_threshold_deg),
                ),
                ("hover_activeness", Share(c.hover_activeness)),
                ("obstacle_weight", Weight(c.obstacle_weight)),
            ],
        )?;
        if c.night_speed[0] > c.night_speed[1] {
            return Err(ConfigError::invalid(
                path,
                "night_speed",
                "must be [low, high] with low ≤ high",
            ));
        }
        Ok(c)
    }

    /// Table 1 of the Foids paper as published (boundary weights 1 and 1).
    pub fn table1() -> Self {
        Self {
            regular_boundary_weight: 1.0,
            front_boundary_weight: 1.0,
            ..Self::default()
        }
    }
}

/// The sums of Eqs. 1–3 over every neighbour of one fish within the rules'
/// ranges (lengths in BL, velocities in BL/s): the published rules average over
/// all neighbours in range, so they are accumulated one neighbour at a time in
/// a single pass (no list, no cap).
#[derive(Clone, Copy, Debug, Default)]
pub struct Neighbourhood {
    separation: Vec3,
    n_s: u32,
    alignment: Vec3,
    n_a: u32,
    cohesion: Vec3,
    n_c: u32,
}

impl Neighbourhood {
    /// Add neighbour `(p, v)` of the fish at `me`, with the ranges `[r_s, r_a, r_c]`.
    #[inline]
    pub fn add(&mut self, me: Vec3, p: Vec3, v: Vec3, ranges: [f32; 3]) {
        let d = me - p;
        let len = d.length();
        if len < ranges[0] {
            self.separation += (ranges[0] - len) * d;
            self.n_s += 1;
        }
        if len < ranges[1] {
            self.alignment += (ranges[1] - len) * v;
            self.n_a += 1;
        }
        if len < ranges[2] {
            self.cohesion += p;
            self.n_c += 1;
        }
    }

    /// The sums over `others` (`(position, velocity)` pairs).
    pub fn of(me: Vec3, others: &[(Vec3, Vec3)], ranges: [f32; 3]) -> Self {
        let mut n = Self::default();
        for &(p, v) in others {
            n.add(me, p, v, ranges);
        }
        n
    }

    /// Separation (Eq. 1): `w_s · mean_j (r_s − |d_ij|) d_ij` over the `N_s`
    /// neighbours with `|d_ij| < r_s`, `d_ij` pointing from neighbour `j` to the fish.
    pub fn separation(&self, weight: f32) -> Vec3 {
        mean_or_zero(self.separation, self.n_s) * weight
    }

    /// Alignment (Eq. 2): `w_a · (mean_j (r_a − |d_ij|) v_j − v_i)` over the
    /// `N_a` neighbours within `r_a`.
    pub fn alignment(&self, v: Vec3, weight: f32) -> Vec3 {
        if self.n_a == 0 {
            Vec3::ZERO
        } else {
            weight * (self.alignment / self.n_a as f32 - v)
        }
    }

    /// Cohesion (Eq. 3): `w_c · (mean_j p_j − p_i)` over the `N_c` neighbours within `r_c`.
    pub fn cohesion(&self, me: Vec3, weight: f32) -> Vec3 {
        if self.n_c == 0 {
            Vec3::ZERO
        } else {
            weight * (self.cohesion / self.n_c as f32 - me)
        }
    }
}

fn mean_or_zero(sum: Vec3, n: u32) -> Vec3 {
    if n == 0 { Vec3::ZERO } else { sum / n as f32 }
}

/// Boundary avoidance (Eq. 4), distances in BL. Walls: `max(r_pref − r, 0) ·
/// (w_rb d_ca + w_fb cos θ_fb n)`; bottom and surface: `m (w_rb + w_fb cos θ_fb)
/// max(r_pref − r, 0)` up or down. `d_ca` points horizontally to the cage axis,
/// `n` is the inward normal, and `cos θ_fb = heading · (−n)` counts only when
/// the boundary is ahead (`cos θ_fb > 0`). `scale` multiplies the weights (night).
pub fn boundary(
    p: Vec3,
    heading: Vec3,
    bl: f32,
    boundaries: &[Boundary],
    cfg: &FoidsConfig,
    scale: f32,
) -> Vec3 {
    let mut dv = Vec3::ZERO;
    let to_axis = Vec3::new(-p.x, 0.0, -p.z)
        .try_normalize()
        .unwrap_or(Vec3::ZERO);
    let r_pref = cfg.boundary_range;
    for b in boundaries {
        let r = b.plane.distance(p) / bl;
        let excess = (r_pref - r).max(0.0);
        if excess == 0.0 {
            continue;
        }
        let n = b.plane.normal;
        let front = heading.dot(-n).max(0.0);
        let (w_rb, w_fb) = (
            cfg.regular_boundary_weight * scale,
            cfg.front_boundary_weight * scale,
        );
        dv += if n.y.abs() > 0.5 {
            // Bottom (n up) or surface (n down).
            cfg.vertical_multiplier * (w_rb + w_fb * front) * excess * n
        } else {
            excess * (w_rb * to_axis + w_fb * front * n)
        };
    }
    dv
}

/// A fish's swimming mode switch at this decision (Algorithm 1, §4.6).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
enum Switch {
    #[default]
    None,
    /// Rapid → hovering: `v`, the speed range and the alignment and cohesion
    /// weights are multiplied by `H_active`.
    ToHover,
    /// Hovering → rapid: the same divided by `H_active`.
    ToRapid,
}

/// The Foids school.
pub struct Foids {
    pub config: FoidsConfig,
    pub seed: u64,
    /// Hovering fish (per fish); decided at the first decision, then switched per Algorithm 1.
    hovering: Vec<bool>,
    /// The switch each fish made at its latest decision.
    switched: Vec<Switch>,
    /// Whether the latest decision was made at night (surface light 0).
    night: bool,
    started: bool,
}

impl Foids {
    pub fn new(config: FoidsConfig, seed: u64) -> Self {
        Self {
            config,
            seed,
            hovering: Vec::new(),
            switched: Vec::new(),
            night: false,
            started: false,
        }
    }

    /// Whether fish `i` is hovering now.
    pub fn is_hovering(&self, i: usize) -> bool {
        self.hovering.get(i).copied().unwrap_or(false)
    }

    /// The speed range of fish `i` (BL/s): the species' by day, `night_speed`
    /// at night, times `H_active` while hovering (§4.3, §4.6).
    pub fn speed_range(&self, env: &Env, i: usize) -> [f32; 2] {
        let base = if self.night {
            self.config.night_speed
        } else {
            env.species_params(i).speed_bl
        };
        let h = if self.is_hovering(i) {
            self.config.hover_activeness
        } else {
            1.0
        };
        [base[0] * h, base[1] * h]
    }

    /// Mode switches of the deciding fish of behaviour `b` (serial, seeded per
    /// fish and tick): a hovering fish may switch to rapid mode with
    /// probability `H_switch` per simulation step if it is in the upper half of
    /// the cage or its elevation exceeds `θ_et`; a rapid one to hovering if it
    /// is in the lower half or its depression exceeds `θ_dt`.
    fn switch_modes(&mut self, env: &Env, b: usize) {
        let (w, cfg, info) = (env.world(), &self.config, &env.behaviours()[b]);
        let height = env.cage().height;
        let tick = env.output().tick;
        let p_switch = 1.0 - (1.0 - cfg.hover_switch).powi(info.steps_per_decision as i32);
        for i in info.range() {
            let pitch = crate::kinematics::pitch_deg(w.heading[i]);
            let upper = -w.position[i].y < height / 2.0;
            let u = Stream::new(self.seed, Purpose::Policy, i as u64, tick).uniform();
            self.switched[i] = Switch::None;
            if self.hovering[i] {
                if (upper || pitch > cfg.elevation_threshold_deg) && u < p_switch {
                    self.hovering[i] = false;
                    self.switched[i] = Switch::ToRapid;
                }
            } else if (!upper || -pitch > cfg.depression_threshold_deg) && u < p_switch {
                self.hovering[i] = true;
                self.switched[i] = Switch::ToHover;
            }
        }
    }
}

impl Policy for Foids {
    fn name(&self) -> String {
        "foids".into()
    }

    /// It steers from the world, not from what a fish sees: nothing to mirror.
    fn mirrors(&self) -> bool {
        false
    }

    /// The model steers once per decision (SPEC §4's `per_decision` reading).
    fn action_timing(&self) -> Option<crate::config::ActionTiming> {
        Some(crate::config::ActionTiming::PerDecision)
    }

    fn act(&mut self, env: &Env, actions: &mut [Vec<f32>]) -> Result<(), PolicyError> {
        let w: &World = env.world();
        let n = w.len();
        if !self.started {
            let (cfg, height) = (&self.config, env.cage().height);
            self.hovering = (0..n)
                .map(|i| {
                    let lower = -w.position[i].y > height / 2.0;
                    lower
                        && Stream::new(self.seed, Purpose::Policy, i as u64, u64::MAX).uniform()
                            < cfg.hover_start
                })
                .collect();
            self.switched = vec![Switch::None; n];
            self.started = true;
        }
        self.night = env.surface_light() <= 0.0;
        let cfg = &self.config;
        let max_range = cfg
            .separation_range
            .max(cfg.alignment_range)
            .max(cfg.cohesion_range);
        let max_bl = w.bl.iter().copied().fold(0.0, f32::max);
        let grid = neighbour_grid(env, max_range * max_bl);
        let phys = &env.scene().physics;
        for (b, info) in env.behaviours().iter().enumerate() {
            if !env.awaiting(b) {
                continue;
            }
            self.switch_modes(env, b);
            let this = &*self;
            let cfg = &this.config;
            let species = &env.scene().behaviours[b].species;
            // Day/night: at night ranges and the alignment, cohesion and boundary
            // weights shrink by s = night max speed / day max speed (§4.3).
            let s = if this.night {
                cfg.night_speed[1] / species.speed_bl[1]
            } else {
                1.0
            };
            let ranges = [
                cfg.separation_range * s,
                cfg.alignment_range * s,
                cfg.cohesion_range * s,
            ];
            let reach = ranges[0].max(ranges[1]).max(ranges[2]);
            let range = info.range();
            let out = &mut actions[b];
            out.resize(info.count * 3, 0.0);
            out.par_chunks_mut(3)
                .enumerate()
                .with_min_len(64)
                .for_each(|(a, act)| {
                    let i = range.start + a;
                    let bl = w.bl[i];
                    let h = if this.hovering[i] {
                        cfg.hover_activeness
                    } else {
                        1.0
                    };
                    // A switch scales the current velocity itself (Algorithm 1).
                    let v = w.velocity(i) / bl
                        * match this.switched[i] {
                            Switch::ToHover => cfg.hover_activeness,
                            Switch::ToRapid => 1.0 / cfg.hover_activeness,
                            Switch::None => 1.0,
                        };
                    let me = w.position[i] / bl;
                    let mut near = Neighbourhood::default();
                    let reach_m = reach * bl;
                    grid.for_each_candidate(w.position[i], reach_m, |j, q| {
                        if j != i
                            && q.truncate().distance_squared(w.position[i]) < reach_m * reach_m
                        {
                            near.add(me, q.truncate() / bl, w.velocity(j) / bl, ranges);
                        }
                    });
                    let dv = near.separation(cfg.separation_weight)
                        + near.alignment(v, cfg.alignment_weight * s * h)
                        + near.cohesion(me, cfg.cohesion_weight * s * h)
                        + boundary(
                            w.position[i],
                            w.heading[i],
                            bl,
                            &env.cage().boundaries,
                            cfg,
                            s,
                        )
                        + env
                            .obstacles()
                            .iter()
                            .map(|o| {
                                obstacle_deflection(
                                    w.position[i],
                                    w.heading[i],
                                    0.5 * bl,
                                    o,
                                    cfg.boundary_range * bl,
                                ) * cfg.obstacle_weight
                            })
                            .sum::<Vec3>();
                    let action = steer(
                        w.heading[i],
                        w.roll[i],
                        w.speed[i],
                        bl,
                        (v + dv) * bl,
                        this.speed_range(env, i),
                        species.max_delta_speed_bl,
                        phys.max_turn_deg.to_radians(),
                    );
                    act.copy_from_slice(&action);
                });
        }
        Ok(())
    }

    /// Foids' own speed range (night, hovering) and Table 1's light steepness.
    fn fish_params(&self, env: &Env, fish: usize) -> Option<FishParams> {
        Some(FishParams {
            speed_bl: self.speed_range(env, fish),
            light_steep: self.config.light_steep,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    const R3: [f32; 3] = [3.0, 3.0, 3.0];

    /// Two fish 1 BL apart along x: d = (−1, 0, 0) from the neighbour to me;
    /// Δv_s = 30 · (3 − 1) · (−1, 0, 0) = (−60, 0, 0).
    #[test]
    fn separation_two_fish() {
        let n = Neighbourhood::of(Vec3::ZERO, &[(Vec3::X, Vec3::ZERO)], R3);
        assert!(close(n.separation(30.0), Vec3::new(-60.0, 0.0, 0.0)));
    }

    /// Three fish: neighbours at +x (1 BL) and +z (2 BL):
    /// mean of (2·(−1,0,0), 1·(0,0,−2)) = (−1, 0, −1); × 30 = (−30, 0, −30).
    /// A fish beyond r_s does not count.
    #[test]
    fn separation_three_fish() {
        let others = [
            (Vec3::X, Vec3::ZERO),
            (Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO),
            (Vec3::new(5.0, 0.0, 0.0), Vec3::ZERO),
        ];
        let dv = Neighbourhood::of(Vec3::ZERO, &others, R3).separation(30.0);
        assert!(close(dv, Vec3::new(-30.0, 0.0, -30.0)), "{dv}");
    }

    /// Alignment, three fish: me at 0 moving (1,0,0) BL/s; neighbours at 1 BL with
    /// v = (0,0,1) and at 2 BL with v = (0,0,2): weighted velocities 2·(0,0,1)
    /// and 1·(0,0,2); mean (0,0,2); Δv_a = 12 · ((0,0,2) − (1,0,0)) = (−12, 0, 24).
    #[test]
    fn alignment_three_fish() {
        let others = [
            (Vec3::X, Vec3::Z),
            (Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, 0.0, 2.0)),
        ];
        let dv = Neighbourhood::of(Vec3::ZERO, &others, R3).alignment(Vec3::X, 12.0);
        assert!(close(dv, Vec3::new(-12.0, 0.0, 24.0)), "{dv}");
    }

    /// Cohesion, three fish: neighbours at (2,0,0) and (0,0,2), mean (1,0,1);
    /// Δv_c = 0.1 · (1, 0, 1).
    #[test]
    fn cohesion_three_fish() {
        let others = [
            (Vec3::new(2.0, 0.0, 0.0), Vec3::ZERO),
            (Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO),
        ];
        let dv = Neighbourhood::of(Vec3::ZERO, &others, R3).cohesion(Vec3::ZERO, 0.1);
        assert!(close(dv, Vec3::new(0.1, 0.0, 0.1)), "{dv}");
    }

    /// Regression (issue 11, item 7): every neighbour within range counts — no
    /// cap, no grid order. 150 neighbours 1 BL to the fish's −x and 50 at 2 BL
    /// to its +x: mean separation (150·2·(1,0,0) + 50·1·(−2,0,0))/200 =
    /// (1, 0, 0); × 30 = (30, 0, 0). (A cap of 96 filled from one side first
    /// would see only one of the two groups.)
    #[test]
    fn all_neighbours_in_range_count() {
        let mut others = vec![(-Vec3::X, Vec3::ZERO); 150];
        others.extend(vec![(2.0 * Vec3::X, Vec3::ZERO); 50]);
        let dv = Neighbourhood::of(Vec3::ZERO, &others, R3).separation(30.0);
        assert!(close(dv, Vec3::new(30.0, 0.0, 0.0)), "{dv}");
    }

    /// Boundary, in a 5 m cube, a fish (BL 0.5) 1 m (2 BL) from the wall x = 2.5,
    /// 2.5 m (5 BL) from the other walls, bottom and surface, heading into the wall:
    /// (4 − 2)·(1·(−1,0,0) + 1·cos 0°·(−1,0,0)) = (−4, 0, 0); heading away, only the
    /// regular factor: (−2, 0, 0).
    #[test]
    fn boundary_wall_ahead() {
        let cage = crate::cage::Cage::new(crate::config::CageConfig::Cube { edge: 5.0 });
        let cfg = FoidsConfig::table1();
        let p = Vec3::new(1.5, -2.5, 0.0);
        let dv = boundary(p, Vec3::X, 0.5, &cage.boundaries, &cfg, 1.0);
        assert!(close(dv, Vec3::new(-4.0, 0.0, 0.0)), "{dv}");
        let dv = boundary(p, -Vec3::X, 0.5, &cage.boundaries, &cfg, 1.0);
        assert!(close(dv, Vec3::new(-2.0, 0.0, 0.0)), "{dv}");
        // In a 5 m cube, 0.5 m below the surface (1 BL), level: 2.5 · 1 · (4 − 1) · (0,−1,0)
        // = (0, −7.5, 0); bottom (9 BL) and walls (5 BL) are beyond r_pref.
        let cage = crate::cage::Cage::new(crate::config::CageConfig::Cube { edge: 5.0 });
        let dv = boundary(
            Vec3::new(0.0, -0.5, 0.0),
            Vec3::Z,
            0.5,
            &cage.boundaries,
            &cfg,
            1.0,
        );
        assert!(close(dv, Vec3::new(0.0, -7.5, 0.0)), "{dv}");
    }
}
