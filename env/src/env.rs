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
//!   pose with speed `v0`, and glides without action (and without light or
//!   temperature response) until its behaviour's next decision. The terminated transition earns `−300` plus the neighbour
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
//!
//! # Where things are
//!
//! The state lives in one place (`state`: the [`World`], each agent's motor and
//! what happened since its decision, the clock); per-fish traits in `traits`;
//! the stages are modules — `physics` (Eq. 4.4, crossings, contacts),
//! `sensing` (the grid sensor, the surroundings, the vector observation),
//! `reward` (the seven named terms and their Eq. 4.5 sum) and `chase`. This
//! file holds the step contract and the order in which [`Env::step`] runs them:
//!
//! 1. check the actions; each deciding behaviour starts its decision
//!    (`physics::decide`: motor, roll, and the responses to light and
//!    temperature at the depth then);
//! 2. the tick's physics steps (`physics::step`), the speed kept in each
//!    fish's range ([`FishParams`]) at every one;
//! 3. the decision pass over the behaviours deciding at the new tick: sense,
//!    reward, episode ends, newest frame and vector observation (in parallel);
//! 4. chases end and start; fish whose partner changed re-sense their newest frame.

use crate::cage::Cage;
use crate::chase;
use crate::config::MirrorRedraw;
use crate::physics::Physics;
use crate::reward::{Outcome, Rewards};
use crate::rng::{Purpose, Stream};
use crate::scene::Scene;
use crate::sensing::{Neighbour, Sensing, gather_neighbours};
use crate::state::State;
use crate::sun::SunPlace;
use crate::traits::{self, FishParams, Traits};
use crate::world::{Chase, World};
use deepfoids_sensors::{
    FRAME_BYTES, FRAME_LEN, Frame, FrameCell, GridFormat, GridSensor, GridsRef, Obstacle, STACK,
    STACK_BYTES, STACKED_LEN, SpatialGrid, mirror_columns, push_frame, reset_stack,
};
use glam::Vec3;
use rayon::prelude::*;

pub use crate::reward::{N_TERMS, TERM_NAMES, Terms};
pub use crate::traits::BehaviourInfo;

pub use crate::state::PAR_MIN_LEN;
/// Floats of an agent's vector observation.
pub const VECTOR_OBS: usize = 6;

/// Errors of [`Env::step`] and [`Env::set_fish_params`].
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
    #[error("fish parameters of fish {fish} (of {fish_count}): {message}")]
    FishParams {
        fish: usize,
        fish_count: usize,
        message: String,
    },
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
    /// Stacked grids `[n_agents, 18, 20, 34]` when the env hands out floats
    /// ([`GridFormat::Floats`], the default); empty otherwise.
    pub grids: Vec<f32>,
    /// The same stacks as bytes (`n_agents` × [`STACK_BYTES`],
    /// [`deepfoids_sensors::frames`]) when the env hands out
    /// [`GridFormat::Bytes`]; empty otherwise.
    pub frames: Vec<u8>,
    /// Vector observations `[n_agents, 6]`.
    pub vectors: Vec<f32>,
    /// Reward since the previous decision.
    pub rewards: Vec<f32>,
    /// The reward's terms, in the order of [`TERM_NAMES`].
    pub terms: Vec<[f32; N_TERMS]>,
    pub terminated: Vec<bool>,
    pub truncated: Vec<bool>,
    /// Boundary collisions since the previous decision: the collider crossed a
    /// wall, the bottom or the surface (terminated, or bounced back inside when
    /// the profile keeps the episode going).
    pub crossed: Vec<bool>,
    /// Neighbour collisions that began since the previous decision (partners
    /// not already touched during the previous decision).
    pub new_collisions: Vec<u16>,
}

impl BehaviourBatch {
    /// The stacked grids in whichever format the env hands out.
    pub fn observations(&self) -> GridsRef<'_> {
        if self.frames.is_empty() {
            GridsRef::Dense(&self.grids)
        } else {
            GridsRef::Compact(&self.frames)
        }
    }

    /// Hold the stacks held in the other format in `format` (bytes to floats
    /// rebuild the proximities within 1/510).
    fn convert(&mut self, format: GridFormat) {
        match format {
            GridFormat::Bytes => {
                self.frames = GridsRef::Dense(&self.grids).to_bytes().into_owned();
                self.grids = Vec::new();
            }
            GridFormat::Floats => {
                self.grids = GridsRef::Compact(&self.frames).to_dense().into_owned();
                self.frames = Vec::new();
            }
        }
    }

    /// The newest frame of agent `a`'s stack, written from `frame`.
    fn write_newest(&mut self, a: usize, frame: &Frame) {
        if self.frames.is_empty() {
            frame.write(&mut self.grids[a * STACKED_LEN + (STACK - 1) * FRAME_LEN..][..FRAME_LEN]);
        } else {
            frame.write_bytes(
                &mut self.frames[a * STACK_BYTES + (STACK - 1) * FRAME_BYTES..][..FRAME_BYTES],
            );
        }
    }
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
    /// Decisions (Eq. 4.4 set-up), integration, boundary crossings, contacts and repulsion.
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

/// Buffers the stages write into, reused at every tick.
struct Scratch {
    /// Neighbours for sensing (cells of half the largest sensing range).
    sense_grid: SpatialGrid,
    /// What sensing reads of each fish, in `sense_grid`'s entry order.
    neighbours: Vec<Neighbour>,
    /// Neighbours for contacts (cells of the largest collider).
    contact_grid: SpatialGrid,
    /// Repulsion of each fish at the current physics step (m).
    correction: Vec<Vec3>,
    /// What the latest decision brought each fish.
    outcome: Vec<Outcome>,
    /// Fish whose chase partner changed at this tick.
    changed: Vec<u32>,
    /// Which behaviours decide at this tick.
    deciding: Vec<bool>,
    /// Fish whose handedness was drawn anew and changed at this decision
    /// (`mirror_redraw = "decision"`): their older stacked frames are mirrored.
    flipped: Vec<bool>,
}

/// What the world is made of, fixed while it runs (only the fish parameters
/// may be set): the scene, the behaviours, each fish's traits, the cage, the
/// sun and the sensor.
struct Model {
    scene: Scene,
    seed: u64,
    info: Vec<BehaviourInfo>,
    traits: Traits,
    cage: Cage,
    obstacles: Vec<Obstacle>,
    sun: SunPlace,
    sensor: GridSensor,
}

impl Model {
    /// The physics stage's view.
    fn physics(&self) -> Physics<'_> {
        Physics {
            info: &self.info,
            traits: &self.traits,
            cage: &self.cage,
            obstacles: &self.obstacles,
            site: &self.scene.site,
            config: &self.scene.physics,
            rewards: &self.scene.rewards,
            seed: self.seed,
        }
    }

    /// The sensing stage's view of `world` with neighbours in `grid`.
    fn sensing<'a>(
        &'a self,
        world: &'a World,
        grid: &'a SpatialGrid,
        neighbours: &'a [Neighbour],
    ) -> Sensing<'a> {
        Sensing {
            world,
            traits: &self.traits,
            boundaries: &self.cage.boundaries,
            obstacles: &self.obstacles,
            sensor: &self.sensor,
            grid,
            neighbours,
            cage_height: self.cage.height,
            neighbour_cap: self.scene.rewards.neighbour_cap as usize,
            extensions: self.scene.rewards.extensions,
        }
    }
}

/// The DeepFoids environment.
pub struct Env {
    model: Model,
    state: State,
    scratch: Scratch,
    /// Physics steps per tick: the gcd of the behaviours' `k`.
    tick_steps: usize,
    times: StageTimes,
    output: StepOutput,
    grid_format: GridFormat,
}

impl Env {
    /// Build the world of `scene` with per-fish traits drawn from `seed`, and
    /// reset it; the grids are handed out as floats.
    pub fn new(scene: Scene, seed: u64) -> Self {
        Self::with_grid_format(scene, seed, GridFormat::Floats)
    }

    /// [`Env::new`] handing out the grids in `format` (bytes: 12× less memory,
    /// and what the fused kernels act on directly).
    pub fn with_grid_format(scene: Scene, seed: u64, format: GridFormat) -> Self {
        let (mut info, world, traits) = traits::draw(&scene, seed);
        let n = world.len();
        let tick_steps = info.iter().map(|b| b.steps_per_decision).fold(0, gcd);
        for b in &mut info {
            b.period_ticks = (b.steps_per_decision / tick_steps) as u64;
        }
        let cage = scene.cage();
        let obstacles = scene.obstacles();
        let max_sense = traits.sense.iter().copied().fold(0.1, f32::max);
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
                    grids: match format {
                        GridFormat::Floats => vec![0.0; b.count * STACKED_LEN],
                        GridFormat::Bytes => Vec::new(),
                    },
                    frames: match format {
                        GridFormat::Floats => Vec::new(),
                        GridFormat::Bytes => vec![0; b.count * STACK_BYTES],
                    },
                    vectors: vec![0.0; b.count * VECTOR_OBS],
                    rewards: vec![0.0; b.count],
                    terms: vec![[0.0; N_TERMS]; b.count],
                    terminated: vec![false; b.count],
                    truncated: vec![false; b.count],
                    crossed: vec![false; b.count],
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
        let scratch = Scratch {
            // Half-range cells visit ~40 % fewer candidates than full-range ones.
            sense_grid: SpatialGrid::new(lo, hi, max_sense / 2.0, n),
            neighbours: vec![Neighbour::default(); n],
            contact_grid: SpatialGrid::new(lo, hi, 2.0 * traits.max_bound, n),
            correction: vec![Vec3::ZERO; n],
            outcome: vec![Outcome::default(); n],
            changed: Vec::with_capacity(2 * n + 2),
            deciding: vec![true; info.len()],
            flipped: vec![false; n],
        };
        let mut env = Env {
            model: Model {
                scene,
                seed,
                info,
                traits,
                cage,
                obstacles,
                sun,
                sensor: GridSensor::new(),
            },
            state: State::new(world),
            scratch,
            tick_steps,
            times: StageTimes::default(),
            output,
            grid_format: format,
        };
        env.reset();
        env
    }

    /// Put every fish at a random valid pose (drawn from the seed) with speed
    /// `v0` and its species' [`FishParams`], clear chases and episodes, and
    /// observe. Returns the initial output: every behaviour decided, rewards zero.
    pub fn reset(&mut self) -> &StepOutput {
        self.state.tick = 0;
        self.state.physics_steps = 0;
        self.state.world.time = 0.0;
        self.update_light();
        let m = &mut self.model;
        for i in 0..self.state.world.len() {
            m.traits.params[i] = m.info[self.state.world.behaviour[i] as usize].params;
        }
        let (m, s) = (&self.model, &mut self.state);
        let physics = m.physics();
        for i in 0..s.world.len() {
            let b = &m.info[s.world.behaviour[i] as usize];
            let (p, f) = physics.spawn_pose(
                &s.world,
                i,
                &mut Stream::new(m.seed, Purpose::Spawn, i as u64, 0),
            );
            let w = &mut s.world;
            w.position[i] = p;
            w.heading[i] = f;
            w.roll[i] = 0.0;
            w.speed[i] = b.v0_bl * w.bl[i];
            w.chase[i] = Chase::None;
            s.axes[i] = crate::kinematics::basis(f, 0.0);
            let range = m.traits.params[i].speed_bl;
            s.motor[i] = crate::state::Motor {
                speed_range: [range[0] * w.bl[i], range[1] * w.bl[i]],
                ..Default::default()
            };
            s.since[i] = crate::state::Since {
                spawns: 1,
                start_heading: f,
                ..Default::default()
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
        &self.state.world
    }

    /// Mutable access to the school, for tests and scripted set-ups. Changes take
    /// effect from the next physics step; observations are refreshed at the next
    /// decision (or by [`Env::observe_now`]).
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.state.world
    }

    /// Recompute every behaviour's observation in place from the current state,
    /// without shifting the frame stacks or touching rewards (after editing the
    /// world with [`Env::world_mut`]).
    pub fn observe_now(&mut self) {
        self.observe(Mode::Refresh);
    }

    /// How the grids are handed out.
    pub fn grid_format(&self) -> GridFormat {
        self.grid_format
    }

    /// Hand the grids out in `format` from now on; the stacks held are
    /// converted (the newest frames are sensed again when going to floats, so
    /// only older frames carry the bytes' rounding, ≤ 1/510).
    pub fn set_grid_format(&mut self, format: GridFormat) {
        if format == self.grid_format {
            return;
        }
        self.grid_format = format;
        for batch in &mut self.output.behaviours {
            batch.convert(format);
        }
        if format == GridFormat::Floats {
            self.observe(Mode::Refresh);
        }
    }

    pub fn scene(&self) -> &Scene {
        &self.model.scene
    }

    pub fn seed(&self) -> u64 {
        self.model.seed
    }

    pub fn behaviours(&self) -> &[BehaviourInfo] {
        &self.model.info
    }

    pub fn cage(&self) -> &Cage {
        &self.model.cage
    }

    pub fn obstacles(&self) -> &[Obstacle] {
        &self.model.obstacles
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
        self.tick_steps as f64 * self.model.scene.physics.dt_sim as f64
    }

    /// Whether behaviour `b` decided at the current tick and so must be given
    /// actions at the next [`Env::step`].
    pub fn awaiting(&self, b: usize) -> bool {
        self.state
            .tick
            .is_multiple_of(self.model.info[b].period_ticks)
    }

    /// Light at the surface now, `I0(t)` (PAR).
    pub fn surface_light(&self) -> f32 {
        self.state.surface_light
    }

    /// Local clock time now (hours).
    pub fn clock_hours(&self) -> f64 {
        let c = &self.model.scene.clock;
        c.start_hours as f64
            + if c.runs {
                self.state.world.time / 3600.0
            } else {
                0.0
            }
    }

    /// The vertical responses `(Δv_light, Δv_temp)` of fish `i` where it is now
    /// (BL/s, positive up; Eqs. 4.2–4.3). A fish acts on them at its decisions.
    pub fn vertical_response(&self, i: usize) -> (f32, f32) {
        self.model
            .physics()
            .vertical_response(&self.state.world, self.state.surface_light, i)
    }

    /// The model parameters fish `i` decides with (see [`FishParams`]).
    pub fn fish_params(&self, i: usize) -> FishParams {
        self.model.traits.params[i]
    }

    /// Its species' defaults of [`FishParams`] for fish `i`.
    pub fn species_params(&self, i: usize) -> FishParams {
        self.model.info[self.state.world.behaviour[i] as usize].params
    }

    /// Set the model parameters of fish `i` for its next decisions (a
    /// rule-based model with its own published values does this through
    /// [`crate::policy::act_and_step`]); [`Env::reset`] restores the species'.
    pub fn set_fish_params(&mut self, i: usize, params: FishParams) -> Result<(), EnvError> {
        let n = self.model.traits.params.len();
        let bad = |message: String| EnvError::FishParams {
            fish: i,
            fish_count: n,
            message,
        };
        if i >= n {
            return Err(bad("no such fish".into()));
        }
        params.check().map_err(bad)?;
        self.model.traits.params[i] = params;
        Ok(())
    }

    /// Whether the mirrored fish (the profile's `mirrored_share`) see and
    /// steer mirrored from the next observation on; on unless a rule-based
    /// baseline drives ([`crate::Policy::mirrors`]). Which fish are mirrored
    /// is drawn from the seed when the env is built, and anew at each decision
    /// with `mirror_redraw = "decision"` (not while mirroring is off).
    pub fn set_mirroring(&mut self, on: bool) {
        self.model.traits.mirroring = on;
    }

    /// Whether fish `i` sees and steers as the policy's mirror image now
    /// (drawn from the profile's `mirrored_share`; see [`Env::set_mirroring`]).
    pub fn is_mirrored(&self, i: usize) -> bool {
        self.model.traits.is_mirrored(i)
    }

    /// How actions act from the next decision on (SPEC §4), overriding the
    /// reward profile's `timing.actions` (a rule-based policy fixes its own).
    pub fn set_action_timing(&mut self, timing: crate::config::ActionTiming) {
        self.model.scene.rewards.timing.actions = timing;
    }

    /// Advance one tick. `actions[b]` holds `n_agents × 3` floats for every
    /// behaviour `b` that is [`Env::awaiting`] (others are ignored and may be empty).
    pub fn step<A: AsRef<[f32]>>(&mut self, actions: &[A]) -> Result<&StepOutput, EnvError> {
        if actions.len() != self.model.info.len() {
            return Err(EnvError::BehaviourCount {
                expected: self.model.info.len(),
                got: actions.len(),
            });
        }
        for (b, info) in self.model.info.iter().enumerate() {
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
        let t0 = std::time::Instant::now();
        {
            let physics = self.model.physics();
            for (b, a) in actions.iter().enumerate() {
                if self
                    .state
                    .tick
                    .is_multiple_of(self.model.info[b].period_ticks)
                {
                    physics.decide(&mut self.state, b, a.as_ref());
                }
            }
            let scratch = &mut self.scratch;
            for _ in 0..self.tick_steps {
                physics.step(
                    &mut self.state,
                    &mut scratch.contact_grid,
                    &mut scratch.correction,
                );
            }
        }
        self.times.physics += t0.elapsed();
        self.state.tick += 1;
        self.observe(Mode::Decision);
        Ok(&self.output)
    }

    fn update_light(&mut self) {
        let c = self.model.scene.clock;
        self.state.surface_light = self.model.sun.surface_light(
            self.model.scene.site.surface_light_max as f64,
            c.year,
            c.month,
            c.day,
            self.clock_hours(),
        ) as f32;
    }

    /// Rewards, episodes, chases and observations of the behaviours deciding now.
    fn observe(&mut self, mode: Mode) {
        if mode == Mode::Decision && self.model.scene.clock.runs {
            self.update_light();
        }
        let scratch = &mut self.scratch;
        scratch
            .sense_grid
            .rebuild(&self.state.world.position, &self.model.traits.visual);
        gather_neighbours(
            &self.state.world,
            &scratch.sense_grid,
            &mut scratch.neighbours,
        );
        for (b, info) in self.model.info.iter().enumerate() {
            self.scratch.deciding[b] =
                mode != Mode::Decision || self.state.tick.is_multiple_of(info.period_ticks);
        }
        if mode == Mode::Decision {
            self.redraw_handedness();
        }
        let t0 = std::time::Instant::now();
        let phys = &self.model.scene.physics;
        let m = &self.model;
        let sensing = m.sensing(
            &self.state.world,
            &self.scratch.sense_grid,
            &self.scratch.neighbours,
        );
        let rewards = Rewards {
            world: &self.state.world,
            since: &self.state.since,
            motor: &self.state.motor,
            weights: &self.model.scene.rewards,
            pitch_threshold_deg: phys.pitch_threshold_deg,
            speed_threshold_bl: phys.speed_threshold_bl,
            max_episode: phys.max_episode_decisions,
        };
        // Pass A, parallel per fish: surroundings, reward, episode end, newest frame.
        let outcome = &mut self.scratch.outcome;
        for (b, batch) in self.output.behaviours.iter_mut().enumerate() {
            if !self.scratch.deciding[b] {
                batch.decided = false;
                continue;
            }
            if mode != Mode::Refresh {
                batch.decided = true;
            }
            let r = self.model.info[b].range();
            let pass = DecisionPass {
                mode,
                sensing: &sensing,
                rewards: &rewards,
                first: r.start,
                flipped: &self.scratch.flipped[r.clone()],
            };
            let outcome = &mut outcome[r];
            if batch.frames.is_empty() {
                pass.run(&mut batch.grids, &mut batch.vectors, outcome);
            } else {
                pass.run(&mut batch.frames, &mut batch.vectors, outcome);
            }
        }
        if mode != Mode::Refresh {
            self.publish_outcomes(mode);
        }
        let t1 = std::time::Instant::now();
        self.times.sensing += t1 - t0;
        if mode == Mode::Decision {
            self.update_chases();
        }
        self.times.chases += t1.elapsed();
        let (w, fish) = (&self.state.world, &mut self.output.fish);
        fish.position.copy_from_slice(&w.position);
        fish.heading.copy_from_slice(&w.heading);
        fish.speed.copy_from_slice(&w.speed);
        self.output.tick = self.state.tick;
        self.output.time = w.time;
    }

    /// With `mirror_redraw = "decision"`, each deciding fish is mirrored anew
    /// with probability `mirrored_share`, from `(seed, Handedness, fish, tick)`;
    /// [`Scratch::flipped`] marks the fish whose handedness changed.
    fn redraw_handedness(&mut self) {
        let x = &self.model.scene.rewards.extensions;
        let off = !self.model.traits.mirroring || x.mirrored_share <= 0.0;
        if off || x.mirror_redraw != MirrorRedraw::Decision {
            return;
        }
        let share = x.mirrored_share;
        let (traits, flipped) = (&mut self.model.traits, &mut self.scratch.flipped);
        for (b, info) in self.model.info.iter().enumerate() {
            if !self.scratch.deciding[b] {
                continue;
            }
            for i in info.range() {
                let mut s = Stream::new(
                    self.model.seed,
                    Purpose::Handedness,
                    i as u64,
                    self.state.tick,
                );
                let now = s.uniform() < share;
                flipped[i] = now != traits.mirrored[i];
                traits.mirrored[i] = now;
            }
        }
    }

    /// The deciding behaviours' rewards, reward terms and episode ends, from
    /// pass A's outcomes, into their batches; episode lengths move on.
    fn publish_outcomes(&mut self, mode: Mode) {
        for (b, info) in self.model.info.iter().enumerate() {
            if !self.scratch.deciding[b] {
                continue;
            }
            let batch = &mut self.output.behaviours[b];
            for (a, i) in info.range().enumerate() {
                let d = &self.scratch.outcome[i];
                let since = &mut self.state.since[i];
                let restart = mode == Mode::Reset || d.terminated || d.truncated;
                since.episode_len = if restart { 0 } else { since.episode_len + 1 };
                batch.terms[a] = d.terms.to_array();
                batch.rewards[a] = d.terms.total();
                batch.terminated[a] = d.terminated;
                batch.truncated[a] = d.truncated;
                batch.crossed[a] = d.crossed;
                batch.new_collisions[a] = d.new_collisions;
            }
        }
    }

    /// Chases end and start (SPEC §6, dominance); the fish whose partner changed see it
    /// at once: their newest frame and vector observation are redone.
    fn update_chases(&mut self) {
        let s = &mut self.state;
        chase::update(
            &mut s.world,
            &s.since,
            &self.scratch.outcome,
            &self.model.info,
            &self.scratch.deciding,
            &self.model.scene.physics,
            self.model.seed,
            s.tick,
            &mut self.scratch.changed,
        );
        // Fish whose chase partner changed see and know it at once: redo their newest frame.
        if !self.scratch.changed.is_empty() {
            gather_neighbours(
                &self.state.world,
                &self.scratch.sense_grid,
                &mut self.scratch.neighbours,
            );
        }
        let sensing = self.model.sensing(
            &self.state.world,
            &self.scratch.sense_grid,
            &self.scratch.neighbours,
        );
        for &i in &self.scratch.changed {
            let i = i as usize;
            let b = self.state.world.behaviour[i] as usize;
            let a = i - self.model.info[b].first;
            let batch = &mut self.output.behaviours[b];
            let mut frame = Frame::new(1.0);
            let seen = sensing.sense(i, &mut frame);
            batch.write_newest(a, &frame);
            sensing.vector_obs(
                i,
                &seen,
                &mut batch.vectors[a * VECTOR_OBS..(a + 1) * VECTOR_OBS],
            );
        }
    }
}

/// Pass A of a decision over one behaviour's agents, parallel per fish:
/// surroundings, reward, episode end, newest frame (floats or bytes) and
/// vector observation.
struct DecisionPass<'a> {
    mode: Mode,
    sensing: &'a Sensing<'a>,
    rewards: &'a Rewards<'a>,
    /// The behaviour's first fish.
    first: usize,
    /// The behaviour's fish whose handedness changed at this decision.
    flipped: &'a [bool],
}

impl DecisionPass<'_> {
    fn run<T: FrameCell>(&self, stacks: &mut [T], vectors: &mut [f32], outcome: &mut [Outcome]) {
        (
            stacks.par_chunks_mut(STACK * T::FRAME),
            vectors.par_chunks_mut(VECTOR_OBS),
            outcome.par_iter_mut(),
        )
            .into_par_iter()
            .with_min_len(PAR_MIN_LEN)
            .enumerate()
            .for_each(|(a, (stack, vector, out))| {
                let i = self.first + a;
                let mut frame = Frame::new(1.0);
                let seen = self.sensing.sense(i, &mut frame);
                let newest = match self.mode {
                    Mode::Reset => {
                        *out = Outcome::default();
                        reset_stack(stack)
                    }
                    Mode::Decision => {
                        *out = self.rewards.evaluate(i, &seen);
                        if out.terminated {
                            reset_stack(stack)
                        } else {
                            push_frame(stack);
                            let older = (STACK - 1) * T::FRAME;
                            if self.flipped[a] {
                                // Its older frames, seen with the other hand.
                                mirror_columns(&mut stack[..older]);
                            }
                            &mut stack[older..]
                        }
                    }
                    Mode::Refresh => &mut stack[(STACK - 1) * T::FRAME..],
                };
                out.nearest_subordinate = seen.nearest_subordinate;
                T::write(&frame, newest);
                self.sensing.vector_obs(i, &seen, vector);
            });
    }
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}
