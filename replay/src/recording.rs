//! A replay's recording: every fish at every frame, quantised the way the
//! viewer reads it, plus the P and M curves and what the scene looks like.
//!
//! # Quantisation (what a frame of one fish costs)
//!
//! | quantity | stored as | step |
//! |---|---|---|
//! | position | 3 × u16 from the cage's lower corner − [`MARGIN`] | 1 mm (coarser in cages wider than 65.5 m) |
//! | heading | yaw u16 over (−π, π], pitch i16 over [−π/2, π/2] | 0.088°, 0.044° |
//! | speed | u16 | 1 mm/s |
//! | flags | u8: respawned since the previous frame, chasing, chased | — |
//! | reward terms | 7 × IEEE half float (latest decision) | 3 significant digits |
//!
//! 13 bytes a fish-frame, 27 with the reward terms, before the gzip of
//! [`crate::encode`].
//!
//! Yaw is `atan2(d_x, d_z)` (0 = facing +z, π/2 = facing +x) and pitch
//! `asin(d_y)`, so a heading decodes as `(cos p · sin y, sin p, cos p · cos y)`.

use deepfoids_env::cage::Cage;
use deepfoids_env::metrics::{SchoolState, order_parameters};
use deepfoids_env::world::Chase;
use deepfoids_env::{Env, N_TERMS, TERM_NAMES};
use deepfoids_sensors::Obstacle;
use glam::Vec3;
use serde::Serialize;
use std::f32::consts::{FRAC_PI_2, PI};

/// Room around the cage's bounds that positions may take (m): fish are
/// recorded after a physics step, when their centre is inside the cage, but a
/// CSV from elsewhere may hold a fish a little outside.
pub const MARGIN: f32 = 0.5;
/// Flag bit: the fish respawned since the previous frame (do not interpolate).
pub const FLAG_RESPAWNED: u8 = 1;
/// Flag bit: the fish is chasing another (a dominant aggressor).
pub const FLAG_CHASING: u8 = 2;
/// Flag bit: the fish is being chased.
pub const FLAG_CHASED: u8 = 4;

/// Errors building a recording.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error("frames per second must be a positive number, got {0}")]
    Fps(f64),
    #[error("{path}: line {line}: {what}")]
    Csv {
        path: String,
        line: usize,
        what: String,
    },
    #[error("{path}: {what}")]
    Mismatch { path: String, what: String },
    #[error("a recording needs at least one fish")]
    NoFish,
}

/// What the viewer shows as the replay's title and provenance.
#[derive(Clone, Debug, Serialize)]
pub struct Info {
    pub title: String,
    pub scene: String,
    pub description: String,
    pub policy: String,
    pub seed: u64,
    pub phase: String,
    /// Where the trajectories come from, e.g. "simulated by deepfoids replay".
    pub source: String,
    /// Caveats shown under the title (e.g. what a CSV did not record).
    pub notes: Vec<String>,
}

/// The cage as the viewer draws it (metres, y up, surface at y = 0).
#[derive(Clone, Debug, Serialize)]
pub struct CageShape {
    /// e.g. `octagon edge 3 × 4.6 m`.
    pub describe: String,
    /// Horizontal outline `(x, z)` of the walls, counter-clockwise, not closed.
    pub outline: Vec<[f32; 2]>,
    /// Depth of the net bottom (m).
    pub height: f32,
}

/// An obstacle as the viewer draws it.
#[derive(Clone, Debug, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum ObstacleShape {
    Sphere {
        center: [f32; 3],
        radius: f32,
    },
    /// Vertical axis through `(x, z)`.
    Cylinder {
        x: f32,
        z: f32,
        radius: f32,
        y_min: f32,
        y_max: f32,
    },
}

/// A behaviour (species and size class) and its colour.
#[derive(Clone, Debug, Serialize)]
pub struct BehaviourMeta {
    pub name: String,
    pub species: String,
    pub size_class: String,
    pub first: usize,
    pub count: usize,
    /// `#rrggbb`.
    pub colour: String,
}

/// Behaviour colours: Okabe and Ito's colour-blind-safe set, the bright ones
/// first (they are drawn on dark water).
pub const COLOURS: [[u8; 3]; 10] = [
    [86, 180, 233],
    [230, 159, 0],
    [0, 158, 115],
    [240, 228, 66],
    [204, 121, 167],
    [213, 94, 0],
    [200, 200, 200],
    [0, 114, 178],
    [188, 189, 34],
    [23, 190, 207],
];

/// Colour of behaviour `b`.
pub fn colour(b: usize) -> [u8; 3] {
    COLOURS[b % COLOURS.len()]
}

/// Positions are `origin + q · step` per axis; headings are whole steps of
/// yaw and pitch.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Quant {
    pub origin: [f32; 3],
    pub step: f32,
    /// Yaw steps per full turn.
    pub yaw_steps: u16,
    /// Pitch steps per quarter turn (straight up).
    pub pitch_steps: i16,
}

/// Finest position step (m): finer only costs file size.
pub const POSITION_STEP: f32 = 0.001;
/// Yaw steps per turn: 0.088°.
pub const YAW_STEPS: u16 = 4096;
/// Pitch steps per quarter turn: 0.044°.
pub const PITCH_STEPS: i16 = 2047;

impl Quant {
    /// Steps covering `bounds` widened by [`MARGIN`] on every side: 1 mm, or
    /// coarser if the cage is wider than 65.5 m.
    pub fn for_bounds(lo: Vec3, hi: Vec3) -> Self {
        let origin = lo - Vec3::splat(MARGIN);
        let extent = (hi - lo + Vec3::splat(2.0 * MARGIN)).max_element();
        Self {
            origin: origin.into(),
            step: (extent / u16::MAX as f32).max(POSITION_STEP),
            yaw_steps: YAW_STEPS,
            pitch_steps: PITCH_STEPS,
        }
    }

    pub fn encode(&self, p: Vec3) -> [u16; 3] {
        let o = Vec3::from(self.origin);
        let q = ((p - o) / self.step).round();
        let c = |x: f32| x.clamp(0.0, u16::MAX as f32) as u16;
        [c(q.x), c(q.y), c(q.z)]
    }

    pub fn decode(&self, q: [u16; 3]) -> Vec3 {
        Vec3::from(self.origin) + Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32) * self.step
    }

    /// Yaw and pitch steps of a unit heading (see the module doc).
    pub fn encode_heading(&self, d: Vec3) -> (u16, i16) {
        let turn = self.yaw_steps as f32;
        let yaw = d.x.atan2(d.z);
        let pitch = d.y.clamp(-1.0, 1.0).asin();
        let y = (((yaw + PI) / (2.0 * PI)) * turn).round() as i64;
        let p = (pitch / FRAC_PI_2 * self.pitch_steps as f32).round() as i64;
        let pmax = self.pitch_steps as i64;
        (
            y.rem_euclid(self.yaw_steps as i64) as u16,
            p.clamp(-pmax, pmax) as i16,
        )
    }

    /// The unit heading of a yaw and pitch in steps.
    pub fn decode_heading(&self, yaw: u16, pitch: i16) -> Vec3 {
        let y = yaw as f32 / self.yaw_steps as f32 * 2.0 * PI - PI;
        let p = pitch as f32 / self.pitch_steps as f32 * FRAC_PI_2;
        Vec3::new(p.cos() * y.sin(), p.sin(), p.cos() * y.cos())
    }
}

/// P and M over time (every tick of the run, or every row of a CSV).
#[derive(Clone, Debug, Default)]
pub struct Curves {
    pub t: Vec<f32>,
    pub p: Vec<f32>,
    pub m: Vec<f32>,
    /// [`SchoolState`] as 0 swarm, 1 polarised, 2 milling, 3 transitional.
    pub state: Vec<u8>,
}

impl Curves {
    pub fn push(&mut self, t: f64, p: f32, m: f32) {
        self.t.push(t as f32);
        self.p.push(p);
        self.m.push(m);
        self.state.push(state_code(SchoolState::classify(p, m)));
    }
}

/// The viewer's code of a school state.
pub fn state_code(s: SchoolState) -> u8 {
    match s {
        SchoolState::Swarm => 0,
        SchoolState::Polarised => 1,
        SchoolState::Milling => 2,
        SchoolState::Transitional => 3,
    }
}

/// One fish at one frame, in SI units (what [`Recording::push_frame`] takes).
#[derive(Clone, Copy, Debug)]
pub struct FishSample {
    pub position: Vec3,
    pub heading: Vec3,
    /// m/s.
    pub speed: f32,
    pub flags: u8,
}

/// Every fish at every frame.
#[derive(Clone, Debug)]
pub struct Recording {
    pub info: Info,
    pub cage: CageShape,
    pub obstacles: Vec<ObstacleShape>,
    pub behaviours: Vec<BehaviourMeta>,
    pub fish: usize,
    /// Body length (m) per fish.
    pub bl: Vec<f32>,
    pub behaviour: Vec<u16>,
    pub dominant: Vec<bool>,
    pub quant: Quant,
    /// Time of each frame (s).
    pub times: Vec<f32>,
    /// `[frame][fish][axis]`.
    pub position: Vec<u16>,
    /// `[frame][fish]`.
    pub yaw: Vec<u16>,
    pub pitch: Vec<i16>,
    /// mm/s.
    pub speed: Vec<u16>,
    pub flags: Vec<u8>,
    /// `[frame][fish][term]` half-float bits of the reward terms of each fish's
    /// latest decision; empty when the source did not record them.
    pub terms: Vec<u16>,
    /// Whether chases were recorded (flags bits 1–2 and the pairs).
    pub has_chases: bool,
    /// Chases per frame, and `(aggressor, target)` pairs of all frames in order.
    pub chase_count: Vec<u32>,
    pub chase_pairs: Vec<[u32; 2]>,
    pub curves: Curves,
}

impl Recording {
    /// An empty recording of `env`'s scene and school (traits, cage, obstacles).
    pub fn new(env: &Env, info: Info) -> Result<Self, ReplayError> {
        let w = env.world();
        if w.is_empty() {
            return Err(ReplayError::NoFish);
        }
        let cage = env.cage();
        let (lo, hi) = cage.bounds;
        Ok(Self {
            info,
            cage: cage_shape(cage),
            obstacles: env.obstacles().iter().map(obstacle_shape).collect(),
            behaviours: env
                .behaviours()
                .iter()
                .enumerate()
                .map(|(b, x)| {
                    let [r, g, bl] = colour(b);
                    BehaviourMeta {
                        name: x.name.clone(),
                        species: x.species.clone(),
                        size_class: x.size_class.clone(),
                        first: x.first,
                        count: x.count,
                        colour: format!("#{r:02x}{g:02x}{bl:02x}"),
                    }
                })
                .collect(),
            fish: w.len(),
            bl: w.bl.clone(),
            behaviour: w.behaviour.clone(),
            dominant: w.dominant.clone(),
            quant: Quant::for_bounds(lo, hi),
            times: vec![],
            position: vec![],
            yaw: vec![],
            pitch: vec![],
            speed: vec![],
            flags: vec![],
            terms: vec![],
            has_chases: false,
            chase_count: vec![],
            chase_pairs: vec![],
            curves: Curves::default(),
        })
    }

    pub fn frames(&self) -> usize {
        self.times.len()
    }

    /// Append a frame: `fish` (one per fish), the chase pairs and the reward
    /// terms if the source has them.
    pub fn push_frame(
        &mut self,
        t: f64,
        fish: impl ExactSizeIterator<Item = FishSample>,
        chases: Option<&[[u32; 2]]>,
        terms: Option<&[[f32; N_TERMS]]>,
    ) {
        debug_assert_eq!(fish.len(), self.fish);
        self.times.push(t as f32);
        for s in fish {
            self.position.extend(self.quant.encode(s.position));
            let (y, p) = self.quant.encode_heading(s.heading);
            self.yaw.push(y);
            self.pitch.push(p);
            self.speed
                .push((s.speed * 1000.0).round().clamp(0.0, u16::MAX as f32) as u16);
            self.flags.push(s.flags);
        }
        if let Some(c) = chases {
            self.has_chases = true;
            self.chase_count.push(c.len() as u32);
            self.chase_pairs.extend_from_slice(c);
        } else {
            self.chase_count.push(0);
        }
        if let Some(terms) = terms {
            debug_assert_eq!(terms.len(), self.fish);
            for t in terms {
                self.terms
                    .extend(t.iter().map(|&x| half::f16::from_f32(x).to_bits()));
            }
        }
    }

    /// Position of fish `i` at frame `f` (m), as the viewer decodes it.
    pub fn position_at(&self, f: usize, i: usize) -> Vec3 {
        let k = 3 * (f * self.fish + i);
        self.quant
            .decode([self.position[k], self.position[k + 1], self.position[k + 2]])
    }

    /// Unit heading of fish `i` at frame `f`, as the viewer decodes it.
    pub fn heading_at(&self, f: usize, i: usize) -> Vec3 {
        let k = f * self.fish + i;
        self.quant.decode_heading(self.yaw[k], self.pitch[k])
    }

    /// Speed (m/s) of fish `i` at frame `f`.
    pub fn speed_at(&self, f: usize, i: usize) -> f32 {
        self.speed[f * self.fish + i] as f32 / 1000.0
    }

    pub fn flags_at(&self, f: usize, i: usize) -> u8 {
        self.flags[f * self.fish + i]
    }

    /// The reward terms of fish `i` at frame `f`, if recorded.
    pub fn terms_at(&self, f: usize, i: usize) -> Option<[f32; N_TERMS]> {
        if self.terms.is_empty() {
            return None;
        }
        let k = (f * self.fish + i) * N_TERMS;
        let mut out = [0.0; N_TERMS];
        for (o, &b) in out.iter_mut().zip(&self.terms[k..k + N_TERMS]) {
            *o = half::f16::from_bits(b).to_f32();
        }
        Some(out)
    }

    /// The `(aggressor, target)` pairs of frame `f`.
    pub fn chases_at(&self, f: usize) -> &[[u32; 2]] {
        let start: usize = self.chase_count[..f].iter().map(|&c| c as usize).sum();
        &self.chase_pairs[start..start + self.chase_count[f] as usize]
    }

    /// Names of the reward terms (as in `metrics.csv` and TensorBoard).
    pub fn term_names(&self) -> Vec<&'static str> {
        TERM_NAMES.to_vec()
    }
}

fn cage_shape(cage: &Cage) -> CageShape {
    let mut outline: Vec<[f32; 2]> = cage.outline().into_iter().map(|(x, z)| [x, z]).collect();
    outline.pop(); // `Cage::outline` repeats the first vertex.
    CageShape {
        describe: cage.describe(),
        outline,
        height: cage.height,
    }
}

fn obstacle_shape(o: &Obstacle) -> ObstacleShape {
    match *o {
        Obstacle::Sphere { center, radius } => ObstacleShape::Sphere {
            center: center.into(),
            radius,
        },
        Obstacle::Cylinder {
            x,
            z,
            radius,
            y_min,
            y_max,
        } => ObstacleShape::Cylinder {
            x,
            z,
            radius,
            y_min,
            y_max,
        },
    }
}

/// Frames per second → ticks between frames: `round(1 / (fps · tick))`, at least 1.
pub fn stride(fps: f64, tick_seconds: f64) -> Result<u64, ReplayError> {
    if !(fps > 0.0 && fps.is_finite()) {
        return Err(ReplayError::Fps(fps));
    }
    Ok(((1.0 / (fps * tick_seconds)).round() as u64).max(1))
}

/// Records a replay from an [`Env`] as it runs: call [`EnvRecorder::observe`]
/// after every `Env::step`. A frame is taken every [`stride`] ticks; between
/// frames it remembers each fish's latest reward terms and whether it respawned.
pub struct EnvRecorder {
    rec: Recording,
    stride: u64,
    terms: Vec<[f32; N_TERMS]>,
    respawned: Vec<bool>,
    chases: Vec<[u32; 2]>,
}

impl EnvRecorder {
    /// Start recording `env` (fresh from `Env::new`, at tick 0) at `fps` frames per second.
    pub fn new(env: &Env, info: Info, fps: f64) -> Result<Self, ReplayError> {
        let stride = stride(fps, env.tick_seconds())?;
        let n = env.world().len();
        let mut me = Self {
            rec: Recording::new(env, info)?,
            stride,
            terms: vec![[0.0; N_TERMS]; n],
            respawned: vec![false; n],
            chases: vec![],
        };
        me.take_frame(env);
        Ok(me)
    }

    /// Seconds between frames.
    pub fn frame_seconds(&self, env: &Env) -> f64 {
        self.stride as f64 * env.tick_seconds()
    }

    /// Note the tick `env` just stepped; take a frame if one is due.
    pub fn observe(&mut self, env: &Env) {
        let out = env.output();
        for batch in out.behaviours.iter().filter(|b| b.decided) {
            for a in 0..batch.n_agents {
                let i = batch.first + a;
                self.terms[i] = batch.terms[a];
                self.respawned[i] |= batch.terminated[a];
            }
        }
        if out.tick.is_multiple_of(self.stride) {
            self.take_frame(env);
        }
    }

    fn take_frame(&mut self, env: &Env) {
        let out = env.output();
        let w = env.world();
        self.chases.clear();
        let mut role = vec![0u8; w.len()];
        for (i, c) in w.chase.iter().enumerate() {
            match *c {
                Chase::Aggressor { target, .. } => {
                    self.chases.push([i as u32, target]);
                    role[i] |= FLAG_CHASING;
                }
                Chase::Target { .. } => role[i] |= FLAG_CHASED,
                Chase::None => {}
            }
        }
        let f = &out.fish;
        let respawned = &self.respawned;
        let fish = (0..f.position.len()).map(|i| FishSample {
            position: f.position[i],
            heading: f.heading[i],
            speed: f.speed[i],
            flags: role[i] | if respawned[i] { FLAG_RESPAWNED } else { 0 },
        });
        self.rec
            .push_frame(out.time, fish, Some(&self.chases), Some(&self.terms));
        self.respawned.iter_mut().for_each(|r| *r = false);
    }

    /// The recording, with the P and M curves of every tick (`(t, P, M)`, e.g.
    /// from `metrics::Recorder::samples`).
    pub fn finish(mut self, curves: impl IntoIterator<Item = (f64, f32, f32)>) -> Recording {
        for (t, p, m) in curves {
            self.rec.curves.push(t, p, m);
        }
        self.rec
    }
}

/// P and M of one snapshot (all fish), as `metrics.csv` computes them.
pub fn school_order(position: &[Vec3], heading: &[Vec3]) -> (f32, f32) {
    order_parameters(position, heading, None)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use deepfoids_env::policy::action_buffers;
    use deepfoids_env::{ConfigDirs, Phase, Policy, RandomPolicy, Scene};

    /// `scene` in the `thesis` reward profile, whose net collisions end the
    /// episode: the recordings tested here hold respawns.
    pub(crate) fn env(scene: &str, seed: u64) -> Env {
        let dirs = ConfigDirs::discover().with_reward_profile("thesis");
        Env::new(Scene::load(&dirs, scene, Phase::Pretrain).unwrap(), seed)
    }

    fn info() -> Info {
        Info {
            title: "t".into(),
            scene: "s".into(),
            description: String::new(),
            policy: "random".into(),
            seed: 0,
            phase: "pretrain".into(),
            source: "test".into(),
            notes: vec![],
        }
    }

    /// Bounds (−1, −2, −1)…(1, 0, 1): origin (−1.5, −2.5, −1.5), 3 m across
    /// → 1 mm steps; (0, −1, 0.25) is (1500, 1500, 1750) steps.
    #[test]
    fn positions_in_millimetre_steps() {
        let q = Quant::for_bounds(Vec3::new(-1.0, -2.0, -1.0), Vec3::new(1.0, 0.0, 1.0));
        assert_eq!(q.origin, [-1.5, -2.5, -1.5]);
        assert_eq!(q.step, 0.001);
        assert_eq!(q.encode(Vec3::new(0.0, -1.0, 0.25)), [1500, 1500, 1750]);
        assert!(
            q.decode([1500, 1500, 1750])
                .distance(Vec3::new(0.0, -1.0, 0.25))
                < 1e-5
        );
        assert_eq!(q.encode(Vec3::new(-9.0, 0.0, 0.0))[0], 0, "clamped");
        // A 100 m cage: 101 m / 65,535 steps = 1.541 mm.
        let big = Quant::for_bounds(Vec3::new(-50.0, -10.0, -50.0), Vec3::new(50.0, 0.0, 50.0));
        assert!((big.step - 101.0 / 65535.0).abs() < 1e-9);
    }

    /// 4,096 yaw steps a turn from −π: facing +x (yaw π/2) is step 3,072,
    /// +z (0) step 2,048, −z (±π) step 0; straight up is pitch step 2,047.
    #[test]
    fn headings_in_steps() {
        let q = Quant::for_bounds(Vec3::splat(-1.0), Vec3::ZERO);
        assert_eq!(q.encode_heading(Vec3::X), (3072, 0));
        assert_eq!(q.encode_heading(Vec3::Z), (2048, 0));
        assert_eq!(q.encode_heading(-Vec3::Z), (0, 0));
        assert_eq!(q.encode_heading(Vec3::Y).1, 2047);
        assert_eq!(q.encode_heading(-Vec3::Y).1, -2047);
        assert!(q.decode_heading(3072, 0).distance(Vec3::X) < 1e-6);
        assert!(q.decode_heading(0, 0).distance(-Vec3::Z) < 1e-6);
        // Any heading comes back within half a yaw step plus half a pitch step.
        let limit = (PI / 4096.0 + FRAC_PI_2 / 2047.0 / 2.0) * 1.01;
        for k in 0..200 {
            let a = k as f32 * 0.7;
            let d = Vec3::new(
                a.sin() * (a * 0.3).cos(),
                (a * 0.3).sin(),
                a.cos() * (a * 0.3).cos(),
            );
            let (y, p) = q.encode_heading(d);
            let back = q.decode_heading(y, p);
            assert!(back.angle_between(d) <= limit, "{d} → {back}");
        }
    }

    /// Random actions in seabream_50 for 5 s (seed 3: fish hit the net and
    /// chase): at every frame the recording holds the env's fish to within
    /// its steps, the chases, the latest decision's reward terms, and a
    /// respawn flag for every fish terminated since the previous frame.
    #[test]
    fn env_recorder_holds_what_the_env_did() {
        let mut env = env("seabream_50", 3);
        let mut policy = RandomPolicy { seed: 3 };
        let mut actions = action_buffers(&env);
        let mut rec = EnvRecorder::new(&env, info(), 5.0).unwrap();
        assert_eq!(rec.stride, 2, "0.1 s ticks, 5 frames/s");
        let n = env.world().len();
        let mut terms = vec![[0.0f32; N_TERMS]; n];
        let mut respawned = vec![false; n];
        let (mut respawns, mut chases) = (0, 0);
        let mut expected = vec![];
        let snapshot = |env: &Env, terms: &[[f32; N_TERMS]], respawned: &[bool]| {
            let f = &env.output().fish;
            let pairs: Vec<[u32; 2]> = env
                .world()
                .chase
                .iter()
                .enumerate()
                .filter_map(|(i, c)| match c {
                    Chase::Aggressor { target, .. } => Some([i as u32, *target]),
                    _ => None,
                })
                .collect();
            (
                env.output().time,
                f.position.clone(),
                f.heading.clone(),
                f.speed.clone(),
                pairs,
                terms.to_vec(),
                respawned.to_vec(),
            )
        };
        expected.push(snapshot(&env, &terms, &respawned));
        for _ in 0..50 {
            policy.act(&env, &mut actions).unwrap();
            env.step(&actions).unwrap();
            rec.observe(&env);
            for b in env.output().behaviours.iter().filter(|b| b.decided) {
                for a in 0..b.n_agents {
                    terms[b.first + a] = b.terms[a];
                    respawned[b.first + a] |= b.terminated[a];
                    respawns += b.terminated[a] as usize;
                }
            }
            if env.output().tick.is_multiple_of(2) {
                let s = snapshot(&env, &terms, &respawned);
                chases += s.4.len();
                expected.push(s);
                respawned.iter_mut().for_each(|r| *r = false);
            }
        }
        assert!(
            respawns > 0 && chases > 0,
            "the test needs respawns ({respawns}) and chases ({chases})"
        );
        let r = rec.finish([(0.0, 0.5, 0.25)]);
        assert_eq!(r.frames(), 26);
        assert_eq!(
            r.curves.state,
            vec![state_code(SchoolState::classify(0.5, 0.25))]
        );
        for (f, (t, pos, head, speed, pairs, terms, resp)) in expected.iter().enumerate() {
            assert_eq!(r.times[f], *t as f32);
            assert_eq!(r.chases_at(f), &pairs[..], "frame {f}");
            for i in 0..n {
                assert!(
                    r.position_at(f, i).distance(pos[i]) <= 0.001 * 0.87,
                    "frame {f} fish {i}"
                );
                assert!(r.heading_at(f, i).angle_between(head[i]) < 0.002);
                assert!((r.speed_at(f, i) - speed[i]).abs() <= 0.0005);
                let got = r.terms_at(f, i).unwrap();
                for (g, e) in got.iter().zip(&terms[i]) {
                    assert!(
                        (g - e).abs() <= e.abs() * 1e-3 + 1e-4,
                        "frame {f} fish {i}: {g} vs {e}"
                    );
                }
                assert_eq!(
                    r.flags_at(f, i) & FLAG_RESPAWNED != 0,
                    resp[i],
                    "frame {f} fish {i}"
                );
                let in_chase = pairs.iter().any(|p| p[0] as usize == i);
                assert_eq!(r.flags_at(f, i) & FLAG_CHASING != 0, in_chase);
            }
        }
    }

    /// 1.0, −300 and 0.1 as half floats: 0x3C00, 0xDCB0, and 0.0999755859375.
    #[test]
    fn reward_terms_as_half_floats() {
        let e = env("seabream_default", 0);
        let mut r = Recording::new(&e, info()).unwrap();
        let fish = (0..r.fish).map(|_| FishSample {
            position: Vec3::new(0.0, -1.0, 0.0),
            heading: Vec3::Z,
            speed: 0.1,
            flags: 0,
        });
        let mut terms = vec![[0.0; N_TERMS]; r.fish];
        terms[2] = [1.0, -300.0, 0.1, 0.0, 0.0, 0.0, 0.0];
        r.push_frame(0.0, fish, None, Some(&terms));
        assert_eq!(
            &r.terms[2 * N_TERMS..2 * N_TERMS + 3],
            &[0x3C00, 0xDCB0, 0x2E66]
        );
        assert_eq!(
            r.terms_at(0, 2).unwrap()[2],
            half::f16::from_bits(0x2E66).to_f32()
        );
        assert!((r.terms_at(0, 2).unwrap()[2] - 0.099_975_586).abs() < 1e-9);
        assert!(!r.has_chases);
    }

    #[test]
    fn bad_frame_rates_are_refused() {
        assert!(matches!(stride(0.0, 0.1), Err(ReplayError::Fps(_))));
        assert!(matches!(stride(f64::NAN, 0.1), Err(ReplayError::Fps(_))));
        assert_eq!(stride(5.0, 0.2).unwrap(), 1);
        assert_eq!(stride(2.0, 0.1).unwrap(), 5);
        assert_eq!(stride(100.0, 0.1).unwrap(), 1, "never faster than a tick");
    }
}
