//! The physics stage (SPEC §3–4, §6; thesis Eqs. 4.2–4.4).
//!
//! # A decision ([`Physics::decide`])
//!
//! When a behaviour decides, each of its fish turns its action into the
//! per-step velocity change of Eq. 4.4, all of it computed once, from the state
//! at the decision:
//! * `Δv_f / k`: the action's speed change and turn (`kinematics::decide`),
//!   the target speed clamped to the fish's speed range (the lower bound is a
//!   floor: fish do not park);
//! * `(Δv_light + Δv_temp)·BL / k`: the vertical responses of Eqs. 4.2–4.3 at
//!   the fish's depth *at the decision* ([`vertical_response`]);
//! * the speed range itself, from the fish's [`crate::FishParams`].
//!
//! # A physics step ([`Physics::step`], `dt_sim`)
//!
//! 1. Every fish adds its two per-step changes to its velocity, clamps the
//!    speed to its range, faces its velocity and moves. A fish whose collider
//!    then crosses a wall, the bottom, the surface or an obstacle is respawned
//!    at once at a random valid pose with speed `v0` and glides, without
//!    action or vertical response, until its behaviour's next decision.
//! 2. Fish contacts (box colliders): each fish counts its partners, an
//!    aggressor notes catching its target, and each pair is pushed apart by
//!    half the penetration depth times `repulsion` each (the mild repulsion).
//! 3. The push is applied unless it would move a collider through a boundary.
//!
//! Each fish's update reads only the state of the previous stage, so the
//! stages run in parallel over fish with the same bits as serially.

use crate::cage::Cage;
use crate::collide::{Obb, overlap};
use crate::config::{PhysicsConfig, SiteConfig};
use crate::env::PAR_MIN_LEN;
use crate::forces::{light_at_depth, light_response, temperature_at_depth, temperature_response};
use crate::kinematics::{basis, decide, integrate_velocity};
use crate::rng::{Purpose, Stream};
use crate::state::{Motor, State};
use crate::traits::{BehaviourInfo, Traits};
use crate::world::{Chase, World};
use deepfoids_sensors::{Boundary, Obstacle, SpatialGrid};
use glam::Vec3;
use rayon::prelude::*;

/// Read-only view of what the physics stage needs besides the state.
pub(crate) struct Physics<'a> {
    pub info: &'a [BehaviourInfo],
    pub traits: &'a Traits,
    pub cage: &'a Cage,
    pub obstacles: &'a [Obstacle],
    pub site: &'a SiteConfig,
    pub config: &'a PhysicsConfig,
    pub seed: u64,
}

/// `(Δv_light, Δv_temp)` (BL/s, positive up) of a fish of behaviour `b` at
/// `depth` (m) under surface light `i0` (PAR): Beer–Lambert light and the
/// two-layer temperature (Eq. 4.1, SPEC §3) against the fish's light band and
/// light steepness (Eq. 4.2) and its species' temperature band and steepness
/// (Eq. 4.3).
pub(crate) fn vertical_response(
    b: &BehaviourInfo,
    light_pref: [f32; 2],
    light_steep: [f32; 2],
    site: &SiteConfig,
    i0: f32,
    depth: f32,
) -> (f32, f32) {
    (
        light_response(
            light_at_depth(i0, site.attenuation, depth),
            light_pref[0],
            light_pref[1],
            light_steep[0],
            light_steep[1],
        ),
        temperature_response(
            temperature_at_depth(site.surface_temperature, depth),
            b.temperature_pref[0],
            b.temperature_pref[1],
            b.temperature_steep[0],
            b.temperature_steep[1],
        ),
    )
}

/// Whether a collider crossed a boundary plane or overlaps an obstacle.
#[inline]
pub(crate) fn crosses(obb: &Obb, boundaries: &[Boundary], obstacles: &[Obstacle]) -> bool {
    boundaries.iter().any(|b| obb.clearance(&b.plane) < 0.0)
        || obstacles.iter().any(|o| obb.overlaps_obstacle(o))
}

impl Physics<'_> {
    /// `(Δv_light, Δv_temp)` of fish `i` where it is now (BL/s, positive up).
    pub fn vertical_response(&self, w: &World, i0: f32, i: usize) -> (f32, f32) {
        vertical_response(
            &self.info[w.behaviour[i] as usize],
            w.light_pref[i],
            self.traits.params[i].light_steep,
            self.site,
            i0,
            -w.position[i].y,
        )
    }

    /// Start a decision of behaviour `b` with `actions` (`count × 3`, checked):
    /// each fish's [`Motor`] for the next `k` steps, its roll, and the start of
    /// what its next reward looks back on.
    pub fn decide(&self, state: &mut State, b: usize, actions: &[f32]) {
        let info = &self.info[b];
        let r = info.range();
        let (max_turn, roll_max) = (
            self.config.max_turn_deg.to_radians(),
            self.config.roll_clamp_deg.to_radians(),
        );
        let k = info.steps_per_decision;
        let i0 = state.surface_light;
        let (site, params) = (self.site, &self.traits.params[r.clone()]);
        let w = &mut state.world;
        let (heading, bl, position, light_pref) = (
            &w.heading[r.clone()],
            &w.bl[r.clone()],
            &w.position[r.clone()],
            &w.light_pref[r.clone()],
        );
        (
            actions.par_chunks(3),
            w.roll[r.clone()].par_iter_mut(),
            w.speed[r.clone()].par_iter_mut(),
            state.motor[r.clone()].par_iter_mut(),
            state.since[r.clone()].par_iter_mut(),
        )
            .into_par_iter()
            .with_min_len(PAR_MIN_LEN)
            .enumerate()
            .for_each(|(a, (act, roll, speed, motor, since))| {
                let p = params[a];
                let d = decide(
                    [act[0], act[1], act[2]],
                    heading[a],
                    *roll,
                    *speed,
                    bl[a],
                    info.max_delta_speed_bl,
                    p.speed_bl,
                    max_turn,
                    roll_max,
                    k,
                );
                let (dv_light, dv_temp) =
                    vertical_response(info, light_pref[a], p.light_steep, site, i0, -position[a].y);
                // A range set anew (a model switching to its night or hovering
                // speeds) applies from the decision on: the speed the action
                // changed is clamped into it, and the decision leads from there
                // to the action's target.
                let clamped = speed.clamp(p.speed_bl[0] * bl[a], p.speed_bl[1] * bl[a]);
                let dv_step = if clamped == *speed {
                    d.dv_step
                } else {
                    *speed = clamped;
                    (d.target - clamped * heading[a]) / k as f32
                };
                *motor = Motor {
                    dv_step,
                    vertical_step: (dv_light + dv_temp) * bl[a] / k as f32,
                    speed_range: [p.speed_bl[0] * bl[a], p.speed_bl[1] * bl[a]],
                };
                *roll = d.roll;
                since.start_decision(heading[a]);
            });
    }

    /// A random valid pose for fish `i` from stream `s`: position uniform in the
    /// cage with the collider at least `spawn_margin_bl` from every boundary and
    /// obstacle, yaw uniform, pitch within ±`spawn_pitch_deg`.
    pub fn spawn_pose(&self, w: &World, i: usize, s: &mut Stream) -> (Vec3, Vec3) {
        spawn_pose(
            self.cage,
            self.obstacles,
            self.traits.half[i],
            self.config.spawn_margin_bl * w.bl[i],
            self.config.spawn_pitch_deg.to_radians(),
            s,
        )
    }

    /// One physics step (see the module docs).
    pub fn step(&self, state: &mut State, contact_grid: &mut SpatialGrid, correction: &mut [Vec3]) {
        let dt = self.config.dt_sim;
        // 1. Velocity (Eq. 4.4), position, heading; respawn on crossing.
        {
            let w = &mut state.world;
            let (traits, cage, obstacles, seed) =
                (self.traits, self.cage, self.obstacles, self.seed);
            let (info, behaviour, bl) = (self.info, &w.behaviour, &w.bl);
            let (margin_bl, max_pitch) = (
                self.config.spawn_margin_bl,
                self.config.spawn_pitch_deg.to_radians(),
            );
            (
                w.position.par_iter_mut(),
                w.heading.par_iter_mut(),
                w.roll.par_iter_mut(),
                w.speed.par_iter_mut(),
                state.motor.par_iter_mut(),
                state.since.par_iter_mut(),
                state.axes.par_iter_mut(),
            )
                .into_par_iter()
                .with_min_len(PAR_MIN_LEN)
                .enumerate()
                .for_each(|(i, (p, f, roll, s, motor, since, axes))| {
                    let (nf, ns) = integrate_velocity(
                        *f,
                        *s,
                        motor.dv_step,
                        motor.vertical_step,
                        motor.speed_range,
                    );
                    let obb = Obb {
                        center: *p + nf * ns * dt,
                        axes: basis(nf, *roll),
                        half: traits.half[i],
                    };
                    if crosses(&obb, &cage.boundaries, obstacles) {
                        let mut st =
                            Stream::new(seed, Purpose::Spawn, i as u64, since.spawns as u64);
                        since.spawns += 1;
                        let (sp, sf) = spawn_pose(
                            cage,
                            obstacles,
                            traits.half[i],
                            margin_bl * bl[i],
                            max_pitch,
                            &mut st,
                        );
                        *p = sp;
                        *f = sf;
                        *roll = 0.0;
                        *s = info[behaviour[i] as usize].v0_bl * bl[i];
                        motor.dv_step = Vec3::ZERO;
                        motor.vertical_step = 0.0;
                        since.crossed = true;
                        *axes = basis(sf, 0.0);
                    } else {
                        *p = obb.center;
                        *f = nf;
                        *s = ns;
                        *axes = obb.axes;
                    }
                });
        }
        // 2. Contacts between fish: count partners, note catches, and push apart.
        contact_grid.rebuild(&state.world.position, &self.traits.bound);
        {
            let w = &state.world;
            let (grid, axes, repulsion) = (&*contact_grid, &state.axes, self.config.repulsion);
            let (half, bound, max_bound) =
                (&self.traits.half, &self.traits.bound, self.traits.max_bound);
            (state.since.par_iter_mut(), correction.par_iter_mut())
                .into_par_iter()
                .with_min_len(PAR_MIN_LEN)
                .enumerate()
                .for_each(|(i, (since, corr))| {
                    let me = Obb {
                        center: w.position[i],
                        axes: axes[i],
                        half: half[i],
                    };
                    let r = bound[i];
                    let target = match w.chase[i] {
                        Chase::Aggressor { target, .. } => Some(target as usize),
                        _ => None,
                    };
                    let mut push = Vec3::ZERO;
                    grid.for_each_candidate(me.center, r + max_bound, |j, q| {
                        let reach = r + q.w;
                        if me.center.distance_squared(q.truncate()) >= reach * reach || j == i {
                            return;
                        }
                        let other = Obb {
                            center: q.truncate(),
                            axes: axes[j],
                            half: half[j],
                        };
                        if let Some((axis, depth)) = overlap(&me, &other) {
                            since.add_hit(j as u32);
                            if target == Some(j) {
                                since.caught = true;
                            }
                            // Each fish of the pair moves half the corrected depth away.
                            push -= axis * (0.5 * repulsion * depth);
                        }
                    });
                    *corr = push;
                });
        }
        // 3. Apply the repulsion unless it would push a collider through a boundary.
        {
            let (cage, obstacles, axes, half) =
                (self.cage, self.obstacles, &state.axes, &self.traits.half);
            (state.world.position.par_iter_mut(), correction.par_iter())
                .into_par_iter()
                .with_min_len(PAR_MIN_LEN)
                .enumerate()
                .for_each(|(i, (p, corr))| {
                    if *corr == Vec3::ZERO {
                        return;
                    }
                    let obb = Obb {
                        center: *p + *corr,
                        axes: axes[i],
                        half: half[i],
                    };
                    if !crosses(&obb, &cage.boundaries, obstacles) {
                        *p = obb.center;
                    }
                });
        }
        state.physics_steps += 1;
        state.world.time = state.physics_steps as f64 * dt as f64;
    }
}

/// A random valid pose: position uniform in the cage with the collider at least
/// `margin` from every boundary and obstacle, yaw uniform, pitch within ±`max_pitch`.
fn spawn_pose(
    cage: &Cage,
    obstacles: &[Obstacle],
    half: Vec3,
    margin: f32,
    max_pitch: f32,
    s: &mut Stream,
) -> (Vec3, Vec3) {
    let (lo, hi) = cage.bounds;
    let mut fallback = None;
    for _ in 0..1000 {
        let p = Vec3::new(
            s.range(lo.x, hi.x),
            s.range(lo.y, hi.y),
            s.range(lo.z, hi.z),
        );
        let yaw = s.range(0.0, std::f32::consts::TAU);
        let pitch = s.range(-max_pitch, max_pitch);
        let f = Vec3::new(
            pitch.cos() * yaw.sin(),
            pitch.sin(),
            pitch.cos() * yaw.cos(),
        );
        let obb = Obb {
            center: p,
            axes: basis(f, 0.0),
            half,
        };
        let clear = cage
            .boundaries
            .iter()
            .all(|b| obb.clearance(&b.plane) >= margin)
            && obstacles
                .iter()
                .all(|o| o.distance(p) >= obb.radius() + margin);
        if clear {
            return (p, f);
        }
        if fallback.is_none() && !crosses(&obb, &cage.boundaries, obstacles) {
            fallback = Some((p, f));
        }
    }
    // Validation guarantees room; this only triggers in pathological obstacle layouts.
    fallback.unwrap_or((Vec3::new(0.0, -cage.height / 2.0, 0.0), Vec3::Z))
}
