//! The multi-agent environment (SPEC §3–7).
//!
//! # The step contract
//!
//! Every fish is an agent; fish of one species and size class form a
//! *behaviour* and share a policy. [`Env::step`] advances the world by one
//! *tick* — the greatest common divisor of the behaviours' decision intervals
//! `k = floor(dt_res / dt_sim)` physics steps — and hands back a
//! [`StepOutput`] with one [`BehaviourBatch`] per behaviour, its agents in one
//! contiguous range of fish.
//!
//! * A behaviour *decides* every `k` physics steps. Its batch has
//!   `decided == true` on ticks where it decides; then it carries, per agent,
//!   the reward earned since its last decision (total and each of the seven
//!   terms), the `terminated` and `truncated` flags, and the observation for
//!   its next action. [`Env::step`] takes actions only for behaviours that
//!   decided at the previous tick ([`Env::awaiting`]); between decisions a fish
//!   keeps executing its last action (SPEC §3).
//! * **terminated** is a true end state: the fish's collider crossed a wall,
//!   the bottom, the surface or an obstacle (reward −300, SPEC §6). The fish
//!   respawns at once, at the physics step of the crossing, at a random valid
//!   pose with speed `v0`, and glides without action until its behaviour's next
//!   decision. The terminated transition earns `−300` plus the neighbour
//!   collisions counted before the crossing; the other terms are not evaluated
//!   for it, since its end state lies outside the cage. Do not bootstrap.
//! * **truncated** is an outside limit: the episode reached
//!   `max_episode_decisions`. Nothing happens to the fish; its episode counter
//!   restarts. Bootstrap from the observation in the same output, which is both
//!   the last observation of the old episode and the first of the new one.
//! * A respawned agent's first observation appears in the output of the
//!   decision at which it was terminated; its frame stack starts afresh (the
//!   two older frames are zeros). A fish is never both terminated and truncated.
//!
//! Observations per agent: the stacked grid `[18, 20, 34]` (C, H, W; three
//! frames oldest first, see `deepfoids_sensors`), and the vector
//! `[u_x, u_y, u_z, depth / H, aggressor, target]` (SPEC §5).
//!
//! # Determinism
//!
//! Every random draw comes from a stream keyed by `(seed, purpose, fish, …)`
//! ([`crate::rng`]), each fish's update reads only shared state of the previous
//! stage, and neighbour sums run in the grid's fixed order — so a seed gives
//! bit-identical runs whatever the number of threads. Below [`PAR_MIN_LEN`]
//! fish a stage runs as one task on one thread.
//!
//! # Allocation
//!
//! All buffers are allocated in [`Env::new`]; [`Env::step`] allocates nothing.

use crate::cage::Cage;
use crate::collide::{Obb, overlap};
use crate::config::{Range, RewardWeights};
use crate::forces::{light_at_depth, light_response, temperature_at_depth, temperature_response};
use crate::kinematics::{angle_deg, basis, decide, fast_acos_deg, integrate_velocity, pitch_deg};
use crate::rng::{Purpose, Stream};
use crate::scene::Scene;
use crate::sun::SunPlace;
use crate::world::{Chase, World};
use deepfoids_sensors::{
    Boundary, FRAME_LEN, Frame, GridSensor, Obstacle, STACK, STACKED_LEN, SeenKind, SpatialGrid,
    SphereBatch, push_frame, reset_stack,
};
use glam::Vec3;
use rayon::prelude::*;

/// Stages with fewer fish than this run as a single task.
pub const PAR_MIN_LEN: usize = 64;
/// Floats of an agent's vector observation.
pub const VECTOR_OBS: usize = 6;
/// Number of reward terms.
pub const N_TERMS: usize = 7;
/// Names of the reward terms, in the order of [`BehaviourBatch::terms`] (Eq. 4.5).
pub const TERM_NAMES: [&str; N_TERMS] = [
    "boundary_collision",
    "neighbour_collision",
    "boundary_distance",
    "neighbour_distance",
    "energy",
    "movement",
    "chase",
];
/// Distinct collision partners remembered per decision; beyond, each contact counts anew.
const MAX_HITS: usize = 12;

/// Errors of [`Env::step`].
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EnvError {
    #[error(
        "actions for behaviour {behaviour}: expected {expected} floats ({agents} agents × 3), got {got}"
    )]
    ActionShape {
        behaviour: String,
        agents: usize,
        expected: usize,
        got: usize,
    },
    #[error(
        "action {index} of behaviour {behaviour} (agent {agent}) is {value}; actions must be finite"
    )]
    NonFinite {
        behaviour: String,
        agent: usize,
        index: usize,
        value: f32,
    },
    #[error("expected actions for {expected} behaviours, got {got}")]
    BehaviourCount { expected: usize, got: usize },
}

/// Per-behaviour constants, in SI units where the spec gives BL.
#[derive(Clone, Debug)]
pub struct BehaviourInfo {
    pub name: String,
    pub species: String,
    pub size_class: String,
    /// The behaviour's fish are `first..first + count`.
    pub first: usize,
    pub count: usize,
    /// Physics steps per decision `k`.
    pub steps_per_decision: usize,
    /// Ticks per decision.
    pub period_ticks: u64,
    max_speed_bl: f32,
    max_delta_speed_bl: f32,
    v0_bl: f32,
    sense_bl: f32,
    visual_bl: f32,
    collider_bl: Vec3,
    temperature_pref: [f32; 2],
    temperature_steep: [f32; 2],
    light_steep: [f32; 2],
}

impl BehaviourInfo {
    /// Fish indices of this behaviour.
    pub fn range(&self) -> std::ops::Range<usize> {
        self.first..self.first + self.count
    }
}

/// The observations and rewards of one behaviour at one tick.
#[derive(Clone, Debug)]
pub struct BehaviourBatch {
    pub name: String,
    pub species: String,
    pub size_class: String,
    /// Agent `a` of this batch is fish `first + a` of the world.
    pub first: usize,
    pub n_agents: usize,
    /// Whether the behaviour decided at this tick (the rest is fresh only then).
    pub decided: bool,
    /// Stacked grids `[n_agents, 18, 20, 34]`.
    pub grids: Vec<f32>,
    /// Vector observations `[n_agents, 6]`.
    pub vectors: Vec<f32>,
    /// Reward since the previous decision.
    pub rewards: Vec<f32>,
    /// The reward's terms, in the order of [`TERM_NAMES`].
    pub terms: Vec<[f32; N_TERMS]>,
    pub terminated: Vec<bool>,
    pub truncated: Vec<bool>,
    /// Neighbour collisions that began since the previous decision (partners
    /// not already touched during the previous decision).
    pub new_collisions: Vec<u16>,
}

/// State of every fish, copied at each tick for logging.
#[derive(Clone, Debug, Default)]
pub struct FishState {
    pub position: Vec<Vec3>,
    /// Unit heading.
    pub heading: Vec<Vec3>,
    /// Speed (m/s).
    pub speed: Vec<f32>,
    /// Body length (m).
    pub bl: Vec<f32>,
    pub behaviour: Vec<u16>,
    pub dominant: Vec<bool>,
}

/// Wall-clock time spent in each stage since the env was built (for benchmarks).
#[derive(Clone, Copy, Debug, Default)]
pub struct StageTimes {
    /// Eq. 4.4 integration, boundary crossings, contacts and repulsion.
    pub physics: std::time::Duration,
    /// The decision pass: neighbour search, grid sensor, rewards, episodes.
    pub sensing: std::time::Duration,
    /// Chase bookkeeping and re-sensing after partner changes.
    pub chases: std::time::Duration,
}

/// What [`Env::step`] and [`Env::reset`] return.
#[derive(Clone, Debug, Default)]
pub struct StepOutput {
    /// Ticks since reset.
    pub tick: u64,
    /// Simulated seconds since reset.
    pub time: f64,
    pub behaviours: Vec<BehaviourBatch>,
    pub fish: FishState,
}

/// Motor state of a fish between decisions.
#[derive(Clone, Copy, Debug, Default)]
struct Motor {
    /// `Δv_f / k`, added at each physics step (m/s).
    dv_step: Vec3,
}

/// What happened to a fish since its last decision.
#[derive(Clone, Copy, Debug)]
struct Acc {
    crossed: bool,
    caught: bool,
    n_hits: u8,
    hits: [u32; MAX_HITS],
    n_prev: u8,
    prev: [u32; MAX_HITS],
    start_heading: Vec3,
    start_speed: f32,
    /// Respawns so far (keys the spawn stream); never reset.
    spawns: u32,
    /// Decisions in the current episode.
    episode_len: u32,
}

impl Default for Acc {
    fn default() -> Self {
        Self {
            crossed: false,
            caught: false,
            n_hits: 0,
            hits: [0; MAX_HITS],
            n_prev: 0,
            prev: [0; MAX_HITS],
            start_heading: Vec3::Z,
            start_speed: 0.0,
            spawns: 0,
            episode_len: 0,
        }
    }
}

impl Acc {
    fn add_hit(&mut self, j: u32) {
        if self.hits[..(self.n_hits as usize).min(MAX_HITS)].contains(&j) {
            return;
        }
        if (self.n_hits as usize) < MAX_HITS {
            self.hits[self.n_hits as usize] = j;
        }
        self.n_hits = self.n_hits.saturating_add(1);
    }

    fn new_collisions(&self) -> u16 {
        let listed = (self.n_hits as usize).min(MAX_HITS);
        let prev = &self.prev[..(self.n_prev as usize).min(MAX_HITS)];
        let fresh = self.hits[..listed]
            .iter()
            .filter(|j| !prev.contains(j))
            .count();
        (fresh + (self.n_hits as usize - listed)) as u16
    }
}

/// What a decision pass found for one fish (before the chase update).
#[derive(Clone, Copy, Debug, Default)]
struct Decided {
    reward: f32,
    terms: [f32; N_TERMS],
    terminated: bool,
    truncated: bool,
    new_collisions: u16,
    nearest_subordinate: Option<u32>,
}

/// What the sensor pass found around one fish.
#[derive(Clone, Copy, Debug, Default)]
struct Surroundings {
    /// `Σ (d_sense − d_i)/d_sense` over boundaries and obstacles within range.
    boundary_sum: f32,
    /// `Σ (90 − Δθ_j)/90` over neighbours within range.
    alignment_sum: f32,
    nearest_front: Option<u32>,
    nearest_subordinate: Option<u32>,
}

/// Why observations are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    /// After a reset: fresh stacks, zero rewards, every behaviour.
    Reset,
    /// At a tick: the deciding behaviours' rewards, episodes, chases and observations.
    Decision,
    /// Recompute the newest frame and vector in place; nothing else changes.
    Refresh,
}

/// Read-only view of everything a sensing or reward pass needs.
struct Ctx<'a> {
    world: &'a World,
    info: &'a [BehaviourInfo],
    acc: &'a [Acc],
    boundaries: &'a [Boundary],
    obstacles: &'a [Obstacle],
    sensor: &'a GridSensor,
    grid: &'a SpatialGrid,
    rewards: &'a RewardWeights,
    cage_height: f32,
    pitch_threshold: f32,
    speed_threshold_bl: f32,
    max_episode: u32,
}

/// The DeepFoids environment.
pub struct Env {
    scene: Scene,
    seed: u64,
    info: Vec<BehaviourInfo>,
    cage: Cage,
    obstacles: Vec<Obstacle>,
    sun: SunPlace,
    sensor: GridSensor,
    sense_grid: SpatialGrid,
    contact_grid: SpatialGrid,
    tick_steps: usize,
    world: World,
    motor: Vec<Motor>,
    acc: Vec<Acc>,
    correction: Vec<Vec3>,
    /// Each fish's collider axes after the latest physics step.
    axes: Vec<glam::Mat3>,
    /// Each fish's collider half extents (m) and bounding radius (m); fixed.
    half: Vec<Vec3>,
    bound: Vec<f32>,
    /// The largest bounding radius (m).
    max_bound: f32,
    /// Each fish's visual radius for the grid sensor (m); fixed.
    visual: Vec<f32>,
    decided: Vec<Decided>,
    changed: Vec<u32>,
    deciding: Vec<bool>,
    surface_light: f32,
    times: StageTimes,
    physics_steps: u64,
    tick: u64,
    output: StepOutput,
}

impl Env {
    /// Build the world of `scene` with per-fish traits drawn from `seed`, and reset it.
    pub fn new(scene: Scene, seed: u64) -> Self {
        let dt = scene.physics.dt_sim;
        let species_names = scene.species_names();
        let mut info = Vec::new();
        let mut world = World::default();
        let mut first = 0;
        for (b, spec) in scene.behaviours.iter().enumerate() {
            let sp = &spec.species;
            let k = spec.steps_per_decision(dt);
            info.push(BehaviourInfo {
                name: spec.name.clone(),
                species: sp.name.clone(),
                size_class: spec.size_class.clone(),
                first,
                count: spec.count,
                steps_per_decision: k,
                period_ticks: 0,
                max_speed_bl: sp.speed_bl[1],
                max_delta_speed_bl: sp.max_delta_speed_bl,
                v0_bl: sp.initial_speed_bl,
                sense_bl: sp.sense_range_bl,
                visual_bl: sp.visual_radius_bl,
                collider_bl: Vec3::from(sp.collider_bl),
                temperature_pref: sp.temperature_pref,
                temperature_steep: sp.temperature_steep,
                light_steep: sp.light_steep,
            });
            let species_idx = species_names
                .iter()
                .position(|s| *s == sp.name)
                .unwrap_or(0) as u16;
            // Per-fish traits: body scale per group, light preferences with the Foids reset rule.
            let mut group_scales = spec
                .body_scales
                .iter()
                .flat_map(|(n, r)| std::iter::repeat_n(*r, *n));
            for i in first..first + spec.count {
                let mut s = Stream::new(seed, Purpose::Traits, i as u64, 0);
                let scale: Range = group_scales.next().unwrap_or(Range::Fixed(1.0));
                let bl = sp.body_length * scale.at(s.uniform());
                let lpref = spec.light_lpref.at(s.uniform());
                let mut hpref = spec.light_hpref.at(s.uniform());
                if hpref < lpref {
                    hpref = spec.light_hpref.midpoint();
                }
                world.behaviour.push(b as u16);
                world.species.push(species_idx);
                world.bl.push(bl);
                world.light_pref.push([lpref, hpref]);
            }
            // Dominance: exactly round(fraction · n) fish of the behaviour, by a partial shuffle.
            let n_dom = (sp.dominant_fraction * spec.count as f32).round() as usize;
            let mut idx: Vec<usize> = (first..first + spec.count).collect();
            let mut s = Stream::new(seed, Purpose::Dominance, b as u64, 0);
            for j in 0..n_dom {
                let pick = j + s.below(idx.len() - j);
                idx.swap(j, pick);
            }
            world.dominant.resize(first + spec.count, false);
            for &i in &idx[..n_dom] {
                world.dominant[i] = true;
            }
            first += spec.count;
        }
        let n = first;
        let tick_steps = info.iter().map(|b| b.steps_per_decision).fold(0, gcd);
        for b in &mut info {
            b.period_ticks = (b.steps_per_decision / tick_steps) as u64;
        }
        world.position = vec![Vec3::ZERO; n];
        world.heading = vec![Vec3::Z; n];
        world.roll = vec![0.0; n];
        world.speed = vec![0.0; n];
        world.chase = vec![Chase::None; n];

        let cage = scene.cage();
        let obstacles = scene.obstacles();
        let max_sense = (0..n)
            .map(|i| info[world.behaviour[i] as usize].sense_bl * world.bl[i])
            .fold(0.1, f32::max);
        let half: Vec<Vec3> = (0..n)
            .map(|i| info[world.behaviour[i] as usize].collider_bl * 0.5 * world.bl[i])
            .collect();
        let max_contact = half.iter().map(|h| h.length() * 2.0).fold(0.05, f32::max);
        let visual: Vec<f32> = (0..n)
            .map(|i| info[world.behaviour[i] as usize].visual_bl * world.bl[i])
            .collect();
        let (lo, hi) = cage.bounds;
        let output = StepOutput {
            tick: 0,
            time: 0.0,
            behaviours: info
                .iter()
                .map(|b| BehaviourBatch {
                    name: b.name.clone(),
                    species: b.species.clone(),
                    size_class: b.size_class.clone(),
                    first: b.first,
                    n_agents: b.count,
                    decided: true,
                    grids: vec![0.0; b.count * STACKED_LEN],
                    vectors: vec![0.0; b.count * VECTOR_OBS],
                    rewards: vec![0.0; b.count],
                    terms: vec![[0.0; N_TERMS]; b.count],
                    terminated: vec![false; b.count],
                    truncated: vec![false; b.count],
                    new_collisions: vec![0; b.count],
                })
                .collect(),
            fish: FishState {
                position: vec![Vec3::ZERO; n],
                heading: vec![Vec3::Z; n],
                speed: vec![0.0; n],
                bl: world.bl.clone(),
                behaviour: world.behaviour.clone(),
                dominant: world.dominant.clone(),
            },
        };
        let sun = SunPlace {
            latitude_deg: scene.site.latitude_deg as f64,
            longitude_deg: scene.site.longitude_deg as f64,
            utc_offset_hours: scene.site.utc_offset_hours as f64,
        };
        let mut env = Env {
            seed,
            info,
            // Half-range cells visit ~40 % fewer candidates than full-range ones.
            sense_grid: SpatialGrid::new(lo, hi, max_sense / 2.0, n),
            contact_grid: SpatialGrid::new(lo, hi, max_contact, n),
            max_bound: max_contact / 2.0,
            cage,
            obstacles,
            sun,
            sensor: GridSensor::new(),
            tick_steps,
            world,
            motor: vec![Motor::default(); n],
            acc: vec![Acc::default(); n],
            correction: vec![Vec3::ZERO; n],
            axes: vec![glam::Mat3::IDENTITY; n],
            bound: half.iter().map(|h| h.length()).collect(),
            visual,
            half,
            decided: vec![Decided::default(); n],
            changed: Vec::with_capacity(2 * n + 2),
            deciding: vec![true; scene.behaviours.len()],
            surface_light: 0.0,
            times: StageTimes::default(),
            physics_steps: 0,
            tick: 0,
            output,
            scene,
        };
        env.reset();
        env
    }

    /// Put every fish at a random valid pose (drawn from the seed) with speed
    /// `v0`, clear chases and episodes, and observe. Returns the initial output:
    /// every behaviour decided, rewards zero.
    pub fn reset(&mut self) -> &StepOutput {
        self.tick = 0;
        self.physics_steps = 0;
        self.world.time = 0.0;
        self.update_light();
        for i in 0..self.world.len() {
            let b = &self.info[self.world.behaviour[i] as usize];
            let bl = self.world.bl[i];
            let mut s = Stream::new(self.seed, Purpose::Spawn, i as u64, 0);
            let (p, f) = spawn_pose(
                &self.cage,
                &self.obstacles,
                b.collider_bl * 0.5 * bl,
                self.scene.physics.spawn_margin_bl * bl,
                self.scene.physics.spawn_pitch_deg.to_radians(),
                &mut s,
            );
            self.world.position[i] = p;
            self.world.heading[i] = f;
            self.world.roll[i] = 0.0;
            self.axes[i] = basis(f, 0.0);
            self.world.speed[i] = b.v0_bl * bl;
            self.world.chase[i] = Chase::None;
            self.motor[i] = Motor::default();
            self.acc[i] = Acc {
                spawns: 1,
                start_heading: f,
                start_speed: self.world.speed[i],
                ..Acc::default()
            };
        }
        self.observe(Mode::Reset);
        &self.output
    }

    /// The latest output.
    pub fn output(&self) -> &StepOutput {
        &self.output
    }

    /// The school's state.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// Mutable access to the school, for tests and scripted set-ups. Changes take
    /// effect from the next physics step; observations are refreshed at the next
    /// decision (or by [`Env::observe_now`]).
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// Recompute every behaviour's observation in place from the current state,
    /// without shifting the frame stacks or touching rewards (after editing the
    /// world with [`Env::world_mut`]).
    pub fn observe_now(&mut self) {
        self.observe(Mode::Refresh);
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn seed(&self) -> u64 {
        self.seed
    }

    pub fn behaviours(&self) -> &[BehaviourInfo] {
        &self.info
    }

    pub fn cage(&self) -> &Cage {
        &self.cage
    }

    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Time spent per stage so far.
    pub fn stage_times(&self) -> StageTimes {
        self.times
    }

    /// Physics steps per tick.
    pub fn tick_steps(&self) -> usize {
        self.tick_steps
    }

    /// Simulated seconds per tick.
    pub fn tick_seconds(&self) -> f64 {
        self.tick_steps as f64 * self.scene.physics.dt_sim as f64
    }

    /// Whether behaviour `b` decided at the current tick and so must be given
    /// actions at the next [`Env::step`].
    pub fn awaiting(&self, b: usize) -> bool {
        self.tick.is_multiple_of(self.info[b].period_ticks)
    }

    /// Light at the surface now, `I0(t)` (PAR).
    pub fn surface_light(&self) -> f32 {
        self.surface_light
    }

    /// Local clock time now (hours).
    pub fn clock_hours(&self) -> f64 {
        let c = &self.scene.clock;
        c.start_hours as f64
            + if c.runs {
                self.world.time / 3600.0
            } else {
                0.0
            }
    }

    /// The vertical responses `(Δv_light, Δv_temp)` of fish `i` where it is now
    /// (BL/s, positive up; Eqs. 4.2–4.3).
    pub fn vertical_response(&self, i: usize) -> (f32, f32) {
        vertical_response(&self.world, &self.info, &self.scene, self.surface_light, i)
    }

    /// Advance one tick. `actions[b]` holds `n_agents × 3` floats for every
    /// behaviour `b` that is [`Env::awaiting`] (others are ignored and may be empty).
    pub fn step<A: AsRef<[f32]>>(&mut self, actions: &[A]) -> Result<&StepOutput, EnvError> {
        if actions.len() != self.info.len() {
            return Err(EnvError::BehaviourCount {
                expected: self.info.len(),
                got: actions.len(),
            });
        }
        for (b, info) in self.info.iter().enumerate() {
            if !self.awaiting(b) {
                continue;
            }
            let a = actions[b].as_ref();
            if a.len() != info.count * 3 {
                return Err(EnvError::ActionShape {
                    behaviour: info.name.clone(),
                    agents: info.count,
                    expected: info.count * 3,
                    got: a.len(),
                });
            }
            if let Some(index) = a.iter().position(|x| !x.is_finite()) {
                return Err(EnvError::NonFinite {
                    behaviour: info.name.clone(),
                    agent: index / 3,
                    index,
                    value: a[index],
                });
            }
        }
        for (b, a) in actions.iter().enumerate() {
            if self.awaiting(b) {
                self.apply_actions(b, a.as_ref());
            }
        }
        let t0 = std::time::Instant::now();
        for _ in 0..self.tick_steps {
            self.physics_step();
        }
        self.times.physics += t0.elapsed();
        self.tick += 1;
        self.observe(Mode::Decision);
        Ok(&self.output)
    }

    /// Start a decision for behaviour `b`: turn actions into per-step velocity changes.
    fn apply_actions(&mut self, b: usize, actions: &[f32]) {
        let info = &self.info[b];
        let r = info.range();
        let w = &mut self.world;
        let phys = &self.scene.physics;
        let (max_turn, roll_max) = (
            phys.max_turn_deg.to_radians(),
            phys.roll_clamp_deg.to_radians(),
        );
        let (heading, speed, bl) = (&w.heading[r.clone()], &w.speed[r.clone()], &w.bl[r.clone()]);
        (
            actions.par_chunks(3),
            w.roll[r.clone()].par_iter_mut(),
            self.motor[r.clone()].par_iter_mut(),
            self.acc[r.clone()].par_iter_mut(),
        )
            .into_par_iter()
            .with_min_len(PAR_MIN_LEN)
            .enumerate()
            .for_each(|(a, (act, roll, motor, acc))| {
                let d = decide(
                    [act[0], act[1], act[2]],
                    heading[a],
                    *roll,
                    speed[a],
                    bl[a],
                    info.max_delta_speed_bl,
                    info.max_speed_bl,
                    max_turn,
                    roll_max,
                    info.steps_per_decision,
                );
                motor.dv_step = d.dv_step;
                *roll = d.roll;
                acc.n_prev = acc.n_hits.min(MAX_HITS as u8);
                acc.prev = acc.hits;
                acc.n_hits = 0;
                acc.crossed = false;
                acc.caught = false;
                acc.start_heading = heading[a];
                acc.start_speed = speed[a];
            });
    }

    fn update_light(&mut self) {
        let c = self.scene.clock;
        self.surface_light = self.sun.surface_light(
            self.scene.site.surface_light_max as f64,
            c.year,
            c.month,
            c.day,
            self.clock_hours(),
        ) as f32;
    }

    /// One physics step: Eq. 4.4, boundary crossings and respawns, fish contacts and repulsion.
    fn physics_step(&mut self) {
        let dt = self.scene.physics.dt_sim;
        if self.scene.clock.runs {
            self.update_light();
        }
        // 1. Velocity (Eq. 4.4), position, heading; respawn on crossing.
        {
            let w = &mut self.world;
            let (info, scene, cage, obstacles, seed) = (
                &self.info,
                &self.scene,
                &self.cage,
                &self.obstacles,
                self.seed,
            );
            let (behaviour, bl, light_pref) = (&w.behaviour, &w.bl, &w.light_pref);
            let i0 = self.surface_light;
            let site = &scene.site;
            let phys = &scene.physics;
            (
                w.position.par_iter_mut(),
                w.heading.par_iter_mut(),
                w.roll.par_iter_mut(),
                w.speed.par_iter_mut(),
                self.motor.par_iter_mut(),
                self.acc.par_iter_mut(),
                self.axes.par_iter_mut(),
            )
                .into_par_iter()
                .with_min_len(PAR_MIN_LEN)
                .enumerate()
                .for_each(|(i, (p, f, roll, s, motor, acc, axes))| {
                    let b = &info[behaviour[i] as usize];
                    let bl = bl[i];
                    let depth = -p.y;
                    let dv_light = light_response(
                        light_at_depth(i0, site.attenuation, depth),
                        light_pref[i][0],
                        light_pref[i][1],
                        b.light_steep[0],
                        b.light_steep[1],
                    );
                    let dv_temp = temperature_response(
                        temperature_at_depth(site.surface_temperature, depth),
                        b.temperature_pref[0],
                        b.temperature_pref[1],
                        b.temperature_steep[0],
                        b.temperature_steep[1],
                    );
                    let vertical = (dv_light + dv_temp) * bl / b.steps_per_decision as f32;
                    let (nf, ns) =
                        integrate_velocity(*f, *s, motor.dv_step, vertical, b.max_speed_bl * bl);
                    let np = *p + nf * ns * dt;
                    let half = b.collider_bl * 0.5 * bl;
                    let obb = Obb {
                        center: np,
                        axes: basis(nf, *roll),
                        half,
                    };
                    if crosses(&obb, &cage.boundaries, obstacles) {
                        let mut st = Stream::new(seed, Purpose::Spawn, i as u64, acc.spawns as u64);
                        acc.spawns += 1;
                        let (sp, sf) = spawn_pose(
                            cage,
                            obstacles,
                            half,
                            phys.spawn_margin_bl * bl,
                            phys.spawn_pitch_deg.to_radians(),
                            &mut st,
                        );
                        *p = sp;
                        *f = sf;
                        *roll = 0.0;
                        *s = b.v0_bl * bl;
                        motor.dv_step = Vec3::ZERO;
                        acc.crossed = true;
                        *axes = basis(sf, 0.0);
                    } else {
                        *p = np;
                        *f = nf;
                        *s = ns;
                        *axes = obb.axes;
                    }
                });
        }
        // 2. Contacts between fish: count partners, note catches, and push apart.
        self.contact_grid.rebuild(&self.world.position, &self.bound);
        {
            let w = &self.world;
            let (grid, axes, repulsion) =
                (&self.contact_grid, &self.axes, self.scene.physics.repulsion);
            let (half, bound, max_bound) = (&self.half, &self.bound, self.max_bound);
            (self.acc.par_iter_mut(), self.correction.par_iter_mut())
                .into_par_iter()
                .with_min_len(PAR_MIN_LEN)
                .enumerate()
                .for_each(|(i, (acc, corr))| {
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
                            acc.add_hit(j as u32);
                            if target == Some(j) {
                                acc.caught = true;
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
            let w = &mut self.world;
            let (info, cage, obstacles, axes) =
                (&self.info, &self.cage, &self.obstacles, &self.axes);
            let (behaviour, bl) = (&w.behaviour, &w.bl);
            (w.position.par_iter_mut(), self.correction.par_iter())
                .into_par_iter()
                .with_min_len(PAR_MIN_LEN)
                .enumerate()
                .for_each(|(i, (p, corr))| {
                    if *corr == Vec3::ZERO {
                        return;
                    }
                    let b = &info[behaviour[i] as usize];
                    let obb = Obb {
                        center: *p + *corr,
                        axes: axes[i],
                        half: b.collider_bl * 0.5 * bl[i],
                    };
                    if !crosses(&obb, &cage.boundaries, obstacles) {
                        *p = obb.center;
                    }
                });
        }
        self.physics_steps += 1;
        self.world.time = self.physics_steps as f64 * dt as f64;
    }

    /// Rewards, episodes, chases and observations of the behaviours deciding now.
    fn observe(&mut self, mode: Mode) {
        if mode == Mode::Decision && self.scene.clock.runs {
            self.update_light();
        }
        self.sense_grid.rebuild(&self.world.position, &self.visual);
        for (b, info) in self.info.iter().enumerate() {
            self.deciding[b] =
                mode != Mode::Decision || self.tick.is_multiple_of(info.period_ticks);
        }
        let t0 = std::time::Instant::now();
        // The output buffers leave `self` while `ctx` reads it (moving a Vec allocates nothing).
        let mut output = std::mem::take(&mut self.output);
        let mut decided = std::mem::take(&mut self.decided);
        // Pass A, parallel per fish: surroundings, reward, episode end, newest frame.
        {
            let ctx = Ctx::new(self);
            for (b, batch) in output.behaviours.iter_mut().enumerate() {
                if !self.deciding[b] {
                    batch.decided = false;
                    continue;
                }
                if mode != Mode::Refresh {
                    batch.decided = true;
                }
                let r = self.info[b].range();
                (
                    batch.grids.par_chunks_mut(STACKED_LEN),
                    batch.vectors.par_chunks_mut(VECTOR_OBS),
                    decided[r.clone()].par_iter_mut(),
                )
                    .into_par_iter()
                    .with_min_len(PAR_MIN_LEN)
                    .enumerate()
                    .for_each(|(a, (stack, vector, out))| {
                        let i = r.start + a;
                        let mut frame = Frame::new(1.0);
                        let seen = ctx.sense(i, &mut frame);
                        let newest = match mode {
                            Mode::Reset => {
                                *out = Decided::default();
                                reset_stack(stack)
                            }
                            Mode::Decision => {
                                *out = ctx.reward(i, &seen);
                                if out.terminated {
                                    reset_stack(stack)
                                } else {
                                    push_frame(stack)
                                }
                            }
                            Mode::Refresh => &mut stack[(STACK - 1) * FRAME_LEN..],
                        };
                        out.nearest_subordinate = seen.nearest_subordinate;
                        frame.write(newest);
                        ctx.vector_obs(i, &seen, vector);
                    });
            }
        }
        self.decided = decided;
        if mode != Mode::Refresh {
            for (b, info) in self.info.iter().enumerate() {
                if !self.deciding[b] {
                    continue;
                }
                for i in info.range() {
                    let d = &self.decided[i];
                    let acc = &mut self.acc[i];
                    let restart = mode == Mode::Reset || d.terminated || d.truncated;
                    acc.episode_len = if restart { 0 } else { acc.episode_len + 1 };
                }
                let batch = &mut output.behaviours[b];
                for a in 0..batch.n_agents {
                    let d = &self.decided[info.first + a];
                    batch.rewards[a] = d.reward;
                    batch.terms[a] = d.terms;
                    batch.terminated[a] = d.terminated;
                    batch.truncated[a] = d.truncated;
                    batch.new_collisions[a] = d.new_collisions;
                }
            }
        }
        let t1 = std::time::Instant::now();
        self.times.sensing += t1 - t0;
        if mode == Mode::Decision {
            self.update_chases();
            // Fish whose chase partner changed see and know it at once: redo their newest frame.
            self.changed.sort_unstable();
            self.changed.dedup();
            let ctx = Ctx::new(self);
            for &i in &self.changed {
                let i = i as usize;
                let b = self.world.behaviour[i] as usize;
                let a = i - self.info[b].first;
                let batch = &mut output.behaviours[b];
                let mut frame = Frame::new(1.0);
                let seen = ctx.sense(i, &mut frame);
                frame.write(
                    &mut batch.grids
                        [a * STACKED_LEN + (STACK - 1) * FRAME_LEN..(a + 1) * STACKED_LEN],
                );
                ctx.vector_obs(
                    i,
                    &seen,
                    &mut batch.vectors[a * VECTOR_OBS..(a + 1) * VECTOR_OBS],
                );
            }
        }
        self.times.chases += t1.elapsed();
        let (w, fish) = (&self.world, &mut output.fish);
        fish.position.copy_from_slice(&w.position);
        fish.heading.copy_from_slice(&w.heading);
        fish.speed.copy_from_slice(&w.speed);
        output.tick = self.tick;
        output.time = self.world.time;
        self.output = output;
    }

    /// End finished chases and start new ones among the deciding fish.
    fn update_chases(&mut self) {
        self.changed.clear();
        let w = &mut self.world;
        let phys = &self.scene.physics;
        let now = w.time;
        for info in self
            .info
            .iter()
            .enumerate()
            .filter(|(b, _)| self.deciding[*b])
            .map(|(_, i)| i)
        {
            for i in info.range() {
                if let Chase::Aggressor { target, since } = w.chase[i] {
                    let t = target as usize;
                    let behind = (w.position[t] - w.position[i]).dot(w.heading[i]) < 0.0;
                    let over = self.acc[i].caught
                        || self.acc[i].crossed
                        || self.acc[t].crossed
                        || behind
                        // Half a step of slack: the clock sums f32 steps.
                        || now - since >= (phys.chase_timeout - 0.5 * phys.dt_sim) as f64;
                    if over {
                        w.chase[i] = Chase::None;
                        w.chase[t] = Chase::None;
                        self.changed.push(i as u32);
                        self.changed.push(target);
                    }
                }
            }
        }
        for info in self
            .info
            .iter()
            .enumerate()
            .filter(|(b, _)| self.deciding[*b])
            .map(|(_, i)| i)
        {
            for i in info.range() {
                if !w.dominant[i] || w.chase[i] != Chase::None || self.acc[i].crossed {
                    continue;
                }
                let u = Stream::new(self.seed, Purpose::Chase, i as u64, self.tick).uniform();
                if u >= phys.chase_probability {
                    continue;
                }
                if let Some(t) = self.decided[i].nearest_subordinate
                    && w.chase[t as usize] == Chase::None
                    && !self.acc[t as usize].crossed
                {
                    w.chase[i] = Chase::Aggressor {
                        target: t,
                        since: now,
                    };
                    w.chase[t as usize] = Chase::Target {
                        aggressor: i as u32,
                    };
                    self.changed.push(i as u32);
                    self.changed.push(t);
                }
            }
        }
    }
}

impl<'a> Ctx<'a> {
    fn new(env: &'a Env) -> Self {
        let phys = &env.scene.physics;
        Ctx {
            world: &env.world,
            info: &env.info,
            acc: &env.acc,
            boundaries: &env.cage.boundaries,
            obstacles: &env.obstacles,
            sensor: &env.sensor,
            grid: &env.sense_grid,
            rewards: &env.scene.rewards,
            cage_height: env.cage.height,
            pitch_threshold: phys.pitch_threshold_deg,
            speed_threshold_bl: phys.speed_threshold_bl,
            max_episode: phys.max_episode_decisions,
        }
    }

    /// Fill `frame` with what fish `i` sees and sum up its surroundings.
    fn sense(&self, i: usize, frame: &mut Frame) -> Surroundings {
        let w = self.world;
        let b = &self.info[w.behaviour[i] as usize];
        let range = b.sense_bl * w.bl[i];
        frame.clear(range);
        let (p, f) = (w.position[i], w.heading[i]);
        let rot = basis(f, w.roll[i]);
        let to_local = rot.transpose();
        let mut seen = Surroundings::default();
        for bd in self.boundaries {
            let d = bd.plane.distance(p);
            if d < range {
                seen.boundary_sum += (range - d.max(0.0)) / range;
                frame.add_plane(
                    self.sensor,
                    to_local * bd.plane.normal,
                    d.max(0.0),
                    SeenKind::from(bd.kind),
                );
            }
        }
        for o in self.obstacles {
            let d = o.distance(p);
            if d < range {
                seen.boundary_sum += (range - d.max(0.0)) / range;
                frame.add_obstacle(self.sensor, p, rot, o);
            }
        }
        let partner = w.chase[i].partner();
        let wants_target = w.dominant[i] && w.chase[i] == Chase::None;
        let (mut front_d, mut sub_d) = (f32::INFINITY, f32::INFINITY);
        let range2 = range * range;
        let mut spheres = SphereBatch::new();
        self.grid.for_each_candidate(p, range, |j, q| {
            let rel = q.truncate() - p;
            let d2 = rel.length_squared();
            if d2 >= range2 || j == i {
                return;
            }
            let d = d2.sqrt();
            seen.alignment_sum += (90.0 - fast_acos_deg(f.dot(w.heading[j]))) / 90.0;
            if rel.dot(f) > 0.0 && d < front_d {
                front_d = d;
                seen.nearest_front = Some(j as u32);
            }
            if wants_target
                && w.species[j] == w.species[i]
                && !w.dominant[j]
                && w.chase[j] == Chase::None
                && d < sub_d
            {
                sub_d = d;
                seen.nearest_subordinate = Some(j as u32);
            }
            let kind = if partner == Some(j) {
                SeenKind::ChasePartner
            } else {
                SeenKind::Fish
            };
            if spheres.push(to_local * rel, q.w, kind) {
                frame.add_spheres(self.sensor, &spheres);
                spheres.clear();
            }
        });
        frame.add_spheres(self.sensor, &spheres);
        seen
    }

    /// The seven reward terms of fish `i` for the decision just ended (SPEC §6).
    fn reward(&self, i: usize, seen: &Surroundings) -> Decided {
        let (w, rw, acc) = (self.world, self.rewards, &self.acc[i]);
        let bl = w.bl[i];
        let mut t = [0.0f32; N_TERMS];
        t[1] = -rw.w_nc * acc.n_hits as f32;
        let terminated = acc.crossed;
        if terminated {
            t[0] = -rw.boundary_collision;
        } else {
            t[2] = -rw.w_bd * seen.boundary_sum;
            t[3] = rw.w_nd * seen.alignment_sum;
            let turned = angle_deg(acc.start_heading, w.heading[i]);
            t[4] = -rw.w_r * turned - rw.w_s * (w.speed[i] - acc.start_speed).abs() / bl;
            let pitch = pitch_deg(w.heading[i]).abs();
            t[5] = if pitch >= self.pitch_threshold {
                -rw.pitch_penalty
            } else if w.speed[i] / bl >= self.speed_threshold_bl {
                rw.movement_bonus
            } else {
                0.0
            };
            t[6] = match w.chase[i] {
                Chase::Aggressor { target, .. } => {
                    if acc.caught {
                        rw.catch_bonus
                    } else {
                        let d = (w.position[target as usize] - w.position[i]).normalize_or_zero();
                        rw.w_agg * d.dot(w.velocity(i) / bl)
                    }
                }
                Chase::Target { aggressor } => {
                    let d = (w.position[aggressor as usize] - w.position[i]).normalize_or_zero();
                    -rw.w_tar * d.dot(w.velocity(i) / bl)
                }
                Chase::None => 0.0,
            };
        }
        let truncated = !terminated && acc.episode_len + 1 >= self.max_episode;
        Decided {
            reward: t.iter().sum(),
            terms: t,
            terminated,
            truncated,
            new_collisions: acc.new_collisions(),
            nearest_subordinate: None,
        }
    }

    /// `[u (3), depth / H, aggressor, target]`; the roles are written after the chase update.
    fn vector_obs(&self, i: usize, seen: &Surroundings, out: &mut [f32]) {
        let w = self.world;
        let u = match seen.nearest_front {
            Some(j) => {
                let to_local = basis(w.heading[i], w.roll[i]).transpose();
                Vec3::Z - to_local * w.heading[j as usize]
            }
            None => Vec3::ZERO,
        };
        out[0] = u.x;
        out[1] = u.y;
        out[2] = u.z;
        out[3] = -w.position[i].y / self.cage_height;
        out[4] = matches!(w.chase[i], Chase::Aggressor { .. }) as u8 as f32;
        out[5] = matches!(w.chase[i], Chase::Target { .. }) as u8 as f32;
    }
}

/// `(Δv_light, Δv_temp)` of fish `i` at its depth (BL/s, positive up).
fn vertical_response(
    w: &World,
    info: &[BehaviourInfo],
    scene: &Scene,
    i0: f32,
    i: usize,
) -> (f32, f32) {
    let b = &info[w.behaviour[i] as usize];
    let depth = -w.position[i].y;
    let light = light_at_depth(i0, scene.site.attenuation, depth);
    let temp = temperature_at_depth(scene.site.surface_temperature, depth);
    (
        light_response(
            light,
            w.light_pref[i][0],
            w.light_pref[i][1],
            b.light_steep[0],
            b.light_steep[1],
        ),
        temperature_response(
            temp,
            b.temperature_pref[0],
            b.temperature_pref[1],
            b.temperature_steep[0],
            b.temperature_steep[1],
        ),
    )
}

/// Whether a collider crossed a boundary plane or overlaps an obstacle.
#[inline]
fn crosses(obb: &Obb, boundaries: &[Boundary], obstacles: &[Obstacle]) -> bool {
    boundaries.iter().any(|b| obb.clearance(&b.plane) < 0.0)
        || obstacles.iter().any(|o| obb.overlaps_obstacle(o))
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

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}
