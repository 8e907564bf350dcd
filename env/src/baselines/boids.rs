//! Boids (Reynolds 1987) as the thesis compares it (§4.5.5): separation,
//! alignment and cohesion, plus boundary avoidance, plus the obstacle avoidance
//! of the CS275 report (§4.4). The forces are combined as CS275 §4.8 does:
//! added in order of increasing priority — schooling, boundaries, obstacles —
//! with the velocity clamped to the maximum speed after each addition, so the
//! last (most important) force can override the others. Parameters:
//! `configs/baselines/boids.toml`. Lengths in BL, velocities in BL/s.
//!
//! Boids itself knows no light, temperature or decision interval; here the
//! environment applies all three to every fish, so the comparison isolates
//! the decision rules.

use super::{neighbour_grid, obstacle_deflection, steer};
use crate::config::{ConfigError, read_toml};
use crate::policy::{Policy, PolicyError};
use crate::{Env, World};
use deepfoids_sensors::Boundary;
use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Boids parameters. Lengths in BL, weights in BL/s per unit of their rule.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BoidsConfig {
    /// Neighbours within this distance are seen (BL). Default 3 (as DeepFoids' `d_sense`).
    pub perception: f32,
    /// Separation acts on neighbours closer than this (BL). Default 1.5.
    pub separation_distance: f32,
    /// Separation weight `A` of CS275 Eq. 1 (BL/s). Default 3.
    pub separation_weight: f32,
    /// Alignment weight `A` of CS275 Eq. 2 (BL/s). Default 1.
    pub alignment_weight: f32,
    /// Cohesion weight `A` of CS275 Eq. 3 (1/s). Default 0.1.
    pub cohesion_weight: f32,
    /// Boundaries closer than this push back (BL). Default 2.
    pub boundary_distance: f32,
    /// Boundary push at contact (BL/s), falling linearly to 0 at `boundary_distance`.
    /// Default 6: with 3, fast seabream (2.7 BL/s) still hit the net 16–42 times per
    /// fish-hour in their 3 m cubes (README, *Baselines*).
    pub boundary_weight: f32,
    /// Obstacle deflection weight (BL/s). Default 3.
    pub obstacle_weight: f32,
    /// Cruising speed the fish return to (BL/s). Default 1.
    pub cruise_speed: f32,
}

impl Default for BoidsConfig {
    fn default() -> Self {
        Self {
            perception: 3.0,
            separation_distance: 1.5,
            separation_weight: 3.0,
            alignment_weight: 1.0,
            cohesion_weight: 0.1,
            boundary_distance: 2.0,
            boundary_weight: 6.0,
            obstacle_weight: 3.0,
            cruise_speed: 1.0,
        }
    }
}

impl BoidsConfig {
    /// Read `path`; every value within [`crate::limits`].
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        use crate::config::Param::{Bl, Speed, Weight};
        let c: Self = read_toml(path)?;
        crate::config::params(
            path,
            &[
                ("perception", Bl(c.perception)),
                ("separation_distance", Bl(c.separation_distance)),
                ("separation_weight", Weight(c.separation_weight)),
                ("alignment_weight", Weight(c.alignment_weight)),
                ("cohesion_weight", Weight(c.cohesion_weight)),
                ("boundary_distance", Bl(c.boundary_distance)),
                ("boundary_weight", Weight(c.boundary_weight)),
                ("obstacle_weight", Weight(c.obstacle_weight)),
                ("cruise_speed", Speed(c.cruise_speed)),
            ],
        )?;
        Ok(c)
    }
}

/// The sums of the three Reynolds rules over every neighbour within
/// `perception` (BL units), accumulated one neighbour at a time (no list, no cap).
#[derive(Clone, Copy, Debug, Default)]
pub struct Flock {
    away: Vec3,
    n_close: u32,
    heading: Vec3,
    centre: Vec3,
    n: u32,
}

impl Flock {
    /// Add a neighbour at `p` with heading `h`, seen from `me`.
    #[inline]
    pub fn add(&mut self, me: Vec3, p: Vec3, h: Vec3, separation_distance: f32) {
        let d = me - p;
        if d.length() < separation_distance {
            self.away += d.normalize_or_zero();
            self.n_close += 1;
        }
        self.heading += h.normalize_or_zero();
        self.centre += p;
        self.n += 1;
    }

    /// The sums over `others` (`(position, heading)` pairs).
    pub fn of(me: Vec3, others: &[(Vec3, Vec3)], cfg: &BoidsConfig) -> Self {
        let mut f = Self::default();
        for &(p, h) in others {
            f.add(me, p, h, cfg.separation_distance);
        }
        f
    }

    /// CS275 Eqs. 1–3: separation is the mean unit vector away from neighbours
    /// closer than `separation_distance`, alignment the mean unit heading of the
    /// neighbours, cohesion the offset to their mean position; each times its weight.
    pub fn steering(&self, me: Vec3, cfg: &BoidsConfig) -> Vec3 {
        let mut dv = Vec3::ZERO;
        if self.n_close > 0 {
            dv += cfg.separation_weight * self.away / self.n_close as f32;
        }
        if self.n > 0 {
            let n = self.n as f32;
            dv += cfg.alignment_weight * self.heading / n
                + cfg.cohesion_weight * (self.centre / n - me);
        }
        dv
    }
}

/// Boundary avoidance: `w_b · (r_b − r)/r_b` along each inward normal within `r_b` (BL).
pub fn boundary(p: Vec3, bl: f32, boundaries: &[Boundary], cfg: &BoidsConfig) -> Vec3 {
    boundaries
        .iter()
        .map(|b| {
            let r = b.plane.distance(p) / bl;
            let excess = ((cfg.boundary_distance - r) / cfg.boundary_distance).max(0.0);
            cfg.boundary_weight * excess * b.plane.normal
        })
        .sum()
}

/// Clamp a velocity's magnitude to `max`.
fn clamp_speed(v: Vec3, max: f32) -> Vec3 {
    let s = v.length();
    if s > max { v * (max / s) } else { v }
}

/// The Boids school.
#[derive(Clone, Debug)]
pub struct Boids {
    pub config: BoidsConfig,
}

impl Boids {
    pub fn new(config: BoidsConfig) -> Self {
        Self { config }
    }
}

impl Policy for Boids {
    fn name(&self) -> String {
        "boids".into()
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
        let cfg = &self.config;
        let max_bl = w.bl.iter().copied().fold(0.0, f32::max);
        let grid = neighbour_grid(env, cfg.perception * max_bl);
        let phys = &env.scene().physics;
        for (b, info) in env.behaviours().iter().enumerate() {
            if !env.awaiting(b) {
                continue;
            }
            let species = &env.scene().behaviours[b].species;
            let speed_range = species.speed_bl;
            let range = info.range();
            let out = &mut actions[b];
            out.resize(info.count * 3, 0.0);
            out.par_chunks_mut(3)
                .enumerate()
                .with_min_len(64)
                .for_each(|(a, act)| {
                    let i = range.start + a;
                    let bl = w.bl[i];
                    let me = w.position[i] / bl;
                    let mut flock = Flock::default();
                    let reach = cfg.perception * bl;
                    grid.for_each_candidate(w.position[i], reach, |j, q| {
                        if j != i && q.truncate().distance_squared(w.position[i]) < reach * reach {
                            flock.add(me, q.truncate() / bl, w.heading[j], cfg.separation_distance);
                        }
                    });
                    // Start from the current velocity nudged towards the cruising speed.
                    let v = w.velocity(i) / bl;
                    let cruise = w.heading[i] * cfg.cruise_speed;
                    let max = speed_range[1];
                    let mut desired =
                        clamp_speed(v + 0.5 * (cruise - v) + flock.steering(me, cfg), max);
                    desired = clamp_speed(
                        desired + boundary(w.position[i], bl, &env.cage().boundaries, cfg),
                        max,
                    );
                    for o in env.obstacles() {
                        let push = obstacle_deflection(
                            w.position[i],
                            w.heading[i],
                            0.5 * bl,
                            o,
                            cfg.boundary_distance * bl,
                        );
                        desired = clamp_speed(desired + cfg.obstacle_weight * push, max);
                    }
                    let action = steer(
                        w.heading[i],
                        w.roll[i],
                        w.speed[i],
                        bl,
                        desired * bl,
                        speed_range,
                        species.max_delta_speed_bl,
                        phys.max_turn_deg.to_radians(),
                    );
                    act.copy_from_slice(&action);
                });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two fish 0.5 BL apart: separation (3 · (−1, 0, 0)) + alignment (1 · heading of the
    /// other, (0, 0, 1)) + cohesion (0.1 · (0.5, 0, 0)) = (−2.95, 0, 1).
    #[test]
    fn schooling_two_fish() {
        let cfg = BoidsConfig::default();
        let dv = Flock::of(Vec3::ZERO, &[(Vec3::new(0.5, 0.0, 0.0), Vec3::Z)], &cfg)
            .steering(Vec3::ZERO, &cfg);
        assert!((dv - Vec3::new(-2.95, 0.0, 1.0)).length() < 1e-6, "{dv}");
    }

    /// Three fish: neighbours at (0.5, 0, 0) heading +z and at (0, 0, 2) heading +x (beyond
    /// the separation distance): separation 3 · (−1, 0, 0); alignment 1 · ((0,0,1) + (1,0,0))/2;
    /// cohesion 0.1 · ((0.5, 0, 2)/2 − 0) = (0.025, 0, 0.1) → (−2.475, 0, 0.6).
    #[test]
    fn schooling_three_fish() {
        let others = [
            (Vec3::new(0.5, 0.0, 0.0), Vec3::Z),
            (Vec3::new(0.0, 0.0, 2.0), Vec3::X),
        ];
        let cfg = BoidsConfig::default();
        let dv = Flock::of(Vec3::ZERO, &others, &cfg).steering(Vec3::ZERO, &cfg);
        assert!((dv - Vec3::new(-2.475, 0.0, 0.6)).length() < 1e-6, "{dv}");
    }

    /// A fish 0.5 BL from the floor (BL 1): 6 · (2 − 0.5)/2 = 4.5 up.
    #[test]
    fn boundary_push() {
        let cage = crate::cage::Cage::new(crate::config::CageConfig::Cube { edge: 8.0 });
        let dv = boundary(
            Vec3::new(0.0, -7.5, 0.0),
            1.0,
            &cage.boundaries,
            &BoidsConfig::default(),
        );
        assert!((dv - Vec3::new(0.0, 4.5, 0.0)).length() < 1e-6, "{dv}");
    }
}
