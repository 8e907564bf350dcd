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
use crate::config::{ActionTiming, PhysicsConfig, RewardTiming, RewardWeights, SiteConfig};
use crate::forces::{light_at_depth, light_response, temperature_at_depth, temperature_response};
use crate::kinematics::{angle_deg, basis, decide, integrate_velocity, pitch_deg, turn};
use crate::reward;
use crate::rng::{Purpose, Stream};
use crate::sensing::boundary_closeness;
use crate::state::{MAX_HITS, Motor, PAR_MIN_LEN, State};
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
    /// The reward profile's timing, contacts and episode rule (SPEC §4, §6.1, §6.2).
    pub rewards: &'a RewardWeights,
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
        let stepwise = self.rewards.timing.actions == ActionTiming::PerStep;
        let (turn_step, dt) = (
            self.rewards.timing.turn_step_deg.to_radians(),
            self.config.dt_sim,
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
                let (dv_light, dv_temp) =
                    vertical_response(info, light_pref[a], p.light_steep, site, i0, -position[a].y);
                // A range set anew (a model switching to its night or hovering
                // speeds) applies from the decision on: the speed is clamped into it.
                let range = [p.speed_bl[0] * bl[a], p.speed_bl[1] * bl[a]];
                let clamped = speed.clamp(range[0], range[1]);
                let [a0, a1, mut a2] = [act[0], act[1], act[2]].map(|x| x.clamp(-1.0, 1.0));
                // A mirrored fish (`mirrored_share`) turns the other way.
                if self.traits.is_mirrored(r.start + a) {
                    a2 = -a2;
                }
                let dv_step = if stepwise {
                    Vec3::ZERO
                } else {
                    let d = decide(
                        [a0, a1, a2],
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
                    *roll = d.roll;
                    // The decision leads from the clamped speed to the action's target.
                    if clamped == *speed {
                        d.dv_step
                    } else {
                        (d.target - clamped * heading[a]) / k as f32
                    }
                };
                *speed = clamped;
                *motor = Motor {
                    dv_step,
                    vertical_step: (dv_light + dv_temp) * bl[a] / k as f32,
                    speed_range: range,
                    stepwise,
                    // SPEC §4: Δv_max is an acceleration (BL/s per second).
                    accel_step: a0 * info.max_delta_speed_bl * bl[a] * dt,
                    yaw_step: a2 * turn_step,
                    pitch_step: a1 * turn_step,
                    kick: motor.kick,
                };
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

    /// One physics step (see the module docs): move, then contacts, then
    /// the repulsion they ask for.
    pub fn step(&self, state: &mut State, contact_grid: &mut SpatialGrid, correction: &mut [Vec3]) {
        self.move_fish(state);
        self.contacts(state, contact_grid, correction);
        self.repel(state, correction);
        state.physics_steps += 1;
        state.world.time = state.physics_steps as f64 * self.config.dt_sim as f64;
    }

    /// Step part 1. Velocity (Eq. 4.4), position, heading; respawn or bounce
    /// on crossing; the terms that accrue at every step (SPEC §6.1).
    fn move_fish(&self, state: &mut State) {
        let dt = self.config.dt_sim;
        let rw = self.rewards;
        let (per_step_rewards, ends_episode) = (
            rw.timing.rewards == RewardTiming::PerStep,
            rw.extensions.boundary_ends_episode,
        );
        let w = &mut state.world;
        let (traits, cage, obstacles, seed) = (self.traits, self.cage, self.obstacles, self.seed);
        let (info, behaviour, bl) = (self.info, &w.behaviour, &w.bl);
        let (margin_bl, max_pitch, roll_max) = (
            self.config.spawn_margin_bl,
            self.config.spawn_pitch_deg.to_radians(),
            self.config.roll_clamp_deg.to_radians(),
        );
        let (pitch_threshold, speed_threshold) = (
            self.config.pitch_threshold_deg,
            self.config.speed_threshold_bl,
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
                let (f0, s0) = (*f, *s);
                // SPEC §4: per-step actions turn by θ_step and change the
                // speed by Δv_max·BL·dt_sim at this step; per-decision ones
                // add their decision's Δv_f / k.
                let (dv, new_roll) = if motor.stepwise {
                    let (tf, troll) = turn(f0, *roll, motor.yaw_step, motor.pitch_step, roll_max);
                    let ts =
                        (s0 + motor.accel_step).clamp(motor.speed_range[0], motor.speed_range[1]);
                    (ts * tf - s0 * f0, troll)
                } else {
                    (motor.dv_step, *roll)
                };
                let (nf, ns) = integrate_velocity(
                    f0,
                    s0,
                    dv + motor.kick,
                    motor.vertical_step,
                    motor.speed_range,
                );
                motor.kick = Vec3::ZERO;
                let obb = Obb {
                    center: *p + nf * ns * dt,
                    axes: basis(nf, new_roll),
                    half: traits.half[i],
                };
                if !crosses(&obb, &cage.boundaries, obstacles) {
                    *p = obb.center;
                    *f = nf;
                    *s = ns;
                    *roll = new_roll;
                    *axes = obb.axes;
                } else if ends_episode {
                    let mut st = Stream::new(seed, Purpose::Spawn, i as u64, since.spawns as u64);
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
                    motor.stepwise = false;
                    since.crossed = true;
                    since.n_touching = 0;
                    *axes = basis(sf, 0.0);
                    return;
                } else {
                    let (bp, bf, br) = bounce(*p, f0, *roll, &obb, cage, obstacles);
                    *p = bp;
                    *f = bf;
                    *s = ns;
                    *roll = br;
                    *axes = basis(bf, br);
                    since.crossed = true;
                }
                if per_step_rewards {
                    let b = bl[i];
                    let acc = &mut since.accrued;
                    acc.movement += reward::movement(
                        rw,
                        pitch_deg(*f),
                        *s / b,
                        pitch_threshold,
                        speed_threshold,
                    );
                    acc.boundary_distance += reward::boundary_distance(
                        rw,
                        boundary_closeness(*p, traits.sense[i], &cage.boundaries, obstacles),
                    );
                    acc.energy +=
                        reward::energy(rw, angle_deg(f0, *f), (*s * *f - s0 * f0).length() / b);
                }
            });
    }

    /// Step part 2. Contacts between fish: count partners, note catches, push apart,
    /// and kick the pairs whose contact starts (SPEC §6.1).
    fn contacts(&self, state: &mut State, contact_grid: &mut SpatialGrid, correction: &mut [Vec3]) {
        let rw = self.rewards;
        contact_grid.rebuild(&state.world.position, &self.traits.bound);
        {
            let w = &state.world;
            let (grid, axes, repulsion) = (&*contact_grid, &state.axes, self.config.repulsion);
            let (half, bound, max_bound) =
                (&self.traits.half, &self.traits.bound, self.traits.max_bound);
            let contacts = rw.contacts;
            (
                state.since.par_iter_mut(),
                state.motor.par_iter_mut(),
                correction.par_iter_mut(),
            )
                .into_par_iter()
                .with_min_len(PAR_MIN_LEN)
                .enumerate()
                .for_each(|(i, (since, motor, corr))| {
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
                    let mut kick = Vec3::ZERO;
                    let mut now = [0u32; MAX_HITS];
                    let mut n_now = 0usize;
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
                            if since.was_touching(j as u32) {
                                kick -= axis * contacts.push;
                            } else {
                                since.accrued.contact_starts += 1;
                                kick -= axis * contacts.kick;
                            }
                            if n_now < MAX_HITS {
                                now[n_now] = j as u32;
                                n_now += 1;
                            }
                        }
                    });
                    since.touching = now;
                    since.n_touching = n_now as u8;
                    motor.kick += kick;
                    *corr = push;
                });
        }
    }

    /// Step part 3. Apply the repulsion unless it would push a collider through a boundary.
    fn repel(&self, state: &mut State, correction: &[Vec3]) {
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
}

/// Bounce off the net (SPEC §6.2, `boundary_ends_episode = false`). A fish at
/// `p` (heading `f_old`, roll `roll_old`: a valid pose) whose next collider
/// `moved` would cross a boundary stays at `p` with the new heading reflected
/// off every plane it would cross (`f − 2(f·n)n` where `f` points outwards),
/// its collider moved back inside along the normals by the depth it still
/// crosses, level (roll 0). If no plane was crossed (an obstacle) or that pose still crosses (a
/// corner), it turns back on itself in place: heading `−f_old`, roll
/// `−roll_old` — the same box turned 180° about its centre, so still valid.
/// Returns the position, heading and roll.
fn bounce(
    p: Vec3,
    f_old: Vec3,
    roll_old: f32,
    moved: &Obb,
    cage: &Cage,
    obstacles: &[Obstacle],
) -> (Vec3, Vec3, f32) {
    let turn_back = (p, -f_old, -roll_old);
    let mut reflected = moved.axes.z_axis;
    let mut any = false;
    for b in &cage.boundaries {
        if moved.clearance(&b.plane) < 0.0 {
            any = true;
            let along = reflected.dot(b.plane.normal);
            if along < 0.0 {
                reflected -= 2.0 * along * b.plane.normal;
            }
        }
    }
    let reflected = reflected.normalize_or_zero();
    if !any || reflected == Vec3::ZERO {
        return turn_back;
    }
    // Level after the bounce: roll 0 is always within the clamp.
    let roll = 0.0;
    let mut obb = Obb {
        center: p,
        axes: basis(reflected, roll),
        half: moved.half,
    };
    for _ in 0..2 {
        for b in &cage.boundaries {
            let c = obb.clearance(&b.plane);
            if c < 0.0 {
                obb.center += b.plane.normal * (1e-4 - c);
            }
        }
    }
    if crosses(&obb, &cage.boundaries, obstacles) {
        turn_back
    } else {
        (obb.center, reflected, roll)
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
