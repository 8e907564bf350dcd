//! What a clip is made of: the camera set-ups of thesis Appendix A.4, the
//! light and water of a date and time, the per-clip randomisation, and the
//! fish poses (with tail-beat phases) taken from the simulated world.

use crate::camera::Camera;
use crate::mesh::{FishMesh, FishStyle, tail_beat_hz};
use crate::optics::{Light, Water, WaterParams};
use crate::render::{Conditions, FishPose};
use deepfoids_env::cage::Cage;
use deepfoids_env::sun::{SunPlace, days_in_month};
use deepfoids_env::{Scene, World};
use glam::{Mat3, Vec3};
use serde::{Deserialize, Serialize};

/// Which camera of the field set-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CameraKind {
    /// Equidistant fisheye (235°, the Kodak 4KVR360's dome mode) at the centre
    /// of the cage bottom looking up (Fig. A.2c).
    BottomFisheye,
    /// Pinhole (90° horizontal) at the middle of a wall at a depth, facing the centre (Fig. A.2d).
    Side,
    /// The side camera with the 155° fisheye of the November footage (front mode).
    SideFisheye,
}

impl std::str::FromStr for CameraKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "bottom-fisheye" => Ok(Self::BottomFisheye),
            "side" => Ok(Self::Side),
            "side-fisheye" => Ok(Self::SideFisheye),
            other => Err(format!(
                "unknown camera `{other}`; allowed: bottom-fisheye, side, side-fisheye"
            )),
        }
    }
}

impl CameraKind {
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::BottomFisheye => "bottom-fisheye",
            Self::Side => "side",
            Self::SideFisheye => "side-fisheye",
        }
    }
}

/// Small random offsets of a camera's pose (zero without `--randomize`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Jitter {
    /// Position offset (m).
    pub offset: [f32; 3],
    /// Yaw, pitch, roll (degrees).
    pub yaw_deg: f32,
    pub pitch_deg: f32,
    pub roll_deg: f32,
}

/// Where and how a camera is placed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraPlacement {
    pub kind: CameraKind,
    /// Side cameras: which wall (index into the cage's walls).
    pub wall: usize,
    /// Side cameras: depth (m).
    pub depth: f32,
    pub jitter: Jitter,
}

/// Distance of the cameras from the net (m): fixed to the cage's pipes, just inside.
pub const CAMERA_INSET: f32 = 0.15;

/// Default depth of the side cameras (A.4.5): 2 m for red seabream, 3 m for
/// the others, kept 0.3 m inside the cage.
pub fn default_side_depth(species: &str, cage_height: f32) -> f32 {
    let d: f32 = if species == "seabream" { 2.0 } else { 3.0 };
    d.clamp(0.3, (cage_height - 0.3).max(0.3))
}

/// Number of net walls of a cage.
pub fn wall_count(cage: &Cage) -> usize {
    cage.boundaries.len() - 2
}

/// The camera of `placement` in `cage`.
pub fn place_camera(cage: &Cage, p: &CameraPlacement, width: u32, height: u32) -> Camera {
    let (pos, forward, up) = match p.kind {
        CameraKind::BottomFisheye => (
            Vec3::new(0.0, -cage.height + CAMERA_INSET, 0.0),
            Vec3::Y,
            -Vec3::Z,
        ),
        CameraKind::Side | CameraKind::SideFisheye => {
            let wall = &cage.boundaries[p.wall % wall_count(cage)].plane;
            let n = wall.normal;
            let on_wall = n * wall.offset + Vec3::new(0.0, -p.depth, 0.0);
            (on_wall + n * CAMERA_INSET, n, Vec3::Y)
        }
    };
    let j = &p.jitter;
    let rot = Mat3::from_axis_angle(Vec3::Y, j.yaw_deg.to_radians())
        * Mat3::from_axis_angle(forward.cross(up).normalize(), j.pitch_deg.to_radians());
    let forward = rot * forward;
    let up = Mat3::from_axis_angle(forward, j.roll_deg.to_radians()) * (rot * up);
    let mut pos = pos + Vec3::from(j.offset);
    // Jitter never pushes the camera through the net.
    for b in &cage.boundaries {
        let d = b.plane.distance(pos);
        if d < 0.05 {
            pos += b.plane.normal * (0.05 - d);
        }
    }
    match p.kind {
        CameraKind::BottomFisheye => Camera::fisheye(pos, forward, up, 235.0, width, height),
        CameraKind::Side => Camera::pinhole(pos, forward, up, 90.0, width, height),
        CameraKind::SideFisheye => Camera::fisheye(pos, forward, up, 155.0, width, height),
    }
}

/// A SplitMix64 stream for the renderer's draws, keyed by `(seed, clip)`.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64, clip: u64) -> Self {
        let mut r = Rng(seed ^ 0x005E_ED0F_F15E_u64.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        r.0 = r
            .next_u64()
            .wrapping_add(clip.wrapping_mul(0xD6E8_FEB8_6659_FD93));
        r
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next_u64() >> 40) as f32 / (1u64 << 24) as f32)
    }
}

/// Ranges of `--randomize`, each drawn uniformly per clip.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RandomRanges {
    /// Local time of day (hours): 5:30–19:00 covers dawn, noon and dusk,
    /// narrowed on each date to the hours when the sun is at least
    /// `min_sun_elevation_deg` high (a dataset of black night frames teaches a
    /// detector nothing; dusk stays in).
    pub hours: [f32; 2],
    /// Lowest solar elevation of a drawn time (degrees); 2.
    pub min_sun_elevation_deg: f32,
    /// Chlorophyll (mg/m³): 0–9, the range of the thesis' Fig. 4.17a.
    pub chlorophyll: [f32; 2],
    /// Sediment (g/m³): 0–5, Fig. 4.17b.
    pub sediment: [f32; 2],
    /// Kopelevich small and large particles (ppm): 0–4 each (the range).
    pub small_particles: [f32; 2],
    pub large_particles: [f32; 2],
    /// Skew of the water draws: chlorophyll, sediment and particles are
    /// `lo + (hi − lo)·u^skew` with `u` uniform; 4. Uniform draws (skew 1)
    /// over these ranges give a median extinction of 5.2 /m at 550 nm, under
    /// a metre of sight, so most frames would show empty murk; with 4 the
    /// median is 1.7 /m (10–90 %: 0.4–4.7 /m; coastal cages see 0.5–3 /m) and
    /// the murky end of every range is still drawn.
    pub water_skew: f32,
    /// Beam extinction at 550 nm (1/m) a drawn water must have, else it is
    /// drawn again: 0.13–3.0, i.e. half the clearest and twice the murkiest
    /// site attenuation of the thesis' Table 4.3 (Nishiki 0.26 /m, Onmaehama
    /// 1.5 /m). Without it the skewed draws reach 4–7 /m, where no fish is
    /// visible beyond a metre (issue 22: a whole fisheye clip with 0 labels).
    pub extinction_550: [f32; 2],
    /// Draws of the water before giving up on [`RandomRanges::extinction_550`]; 1000.
    pub water_tries: u32,
    /// Share of the scene's fish that are simulated (per group, at least 1 fish).
    pub fish_fraction: [f32; 2],
    /// Camera position jitter (± m per axis) and angle jitter (± degrees).
    pub jitter_m: f32,
    pub jitter_deg: f32,
}

impl Default for RandomRanges {
    fn default() -> Self {
        Self {
            hours: [5.5, 19.0],
            min_sun_elevation_deg: 2.0,
            chlorophyll: [0.0, 9.0],
            sediment: [0.0, 5.0],
            small_particles: [0.0, 4.0],
            large_particles: [0.0, 4.0],
            water_skew: 4.0,
            extinction_550: [0.13, 3.0],
            water_tries: 1000,
            fish_fraction: [0.2, 1.0],
            jitter_m: 0.1,
            jitter_deg: 5.0,
        }
    }
}

/// The scene's site as the sun model takes it.
pub fn site_place(scene: &Scene) -> SunPlace {
    let site = &scene.site;
    SunPlace {
        latitude_deg: site.latitude_deg as f64,
        longitude_deg: site.longitude_deg as f64,
        utc_offset_hours: site.utc_offset_hours as f64,
    }
}

/// The part of `r.hours` on a date when the sun stands at least
/// `r.min_sun_elevation_deg` high at the scene's site, to the minute (the
/// elevation rises and falls once a day, so it is one interval). The whole
/// range if the sun never gets that high (polar night).
fn daylight(scene: &Scene, year: i32, month: u32, day: u32, r: &RandomRanges) -> [f32; 2] {
    let place = site_place(scene);
    let [a, b] = r.hours;
    let minutes = ((b - a) * 60.0).round().max(0.0) as usize;
    let hour = |m: usize| a + m as f32 / 60.0;
    let up = |m: &usize| {
        place
            .position(year, month, day, hour(*m) as f64)
            .elevation_deg
            >= r.min_sun_elevation_deg as f64
    };
    match ((0..=minutes).find(up), (0..=minutes).rev().find(up)) {
        (Some(lo), Some(hi)) => [hour(lo), hour(hi)],
        _ => r.hours,
    }
}

/// Everything one clip draws (or takes from the scene without `--randomize`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClipParams {
    pub clip: usize,
    /// Environment seed of the clip (fish traits, spawns, policy noise).
    pub seed: u64,
    pub year: i32,
    pub month: u32,
    pub day: u32,
    /// Local clock time at the clip's start (hours).
    pub hours: f64,
    pub water: WaterParams,
    /// How many times the water was drawn again because no fish was visible
    /// in the whole clip (`render` without `--allow-empty`); 0 at first.
    #[serde(default)]
    pub water_attempt: u32,
    /// Share of the scene's fish simulated.
    pub fish_fraction: f32,
    pub camera: CameraPlacement,
}

impl ClipParams {
    /// The scene's own conditions: its date and time, default water, all fish,
    /// the camera without jitter (side cameras on the first wall).
    pub fn from_scene(scene: &Scene, clip: usize, seed: u64, kind: CameraKind) -> Self {
        let c = scene.clock;
        let cage = scene.cage();
        let species = scene.behaviours[0].species.name.as_str();
        Self {
            clip,
            seed: clip_seed(seed, clip),
            year: c.year,
            month: c.month,
            day: c.day,
            hours: c.start_hours as f64,
            water: WaterParams::default(),
            water_attempt: 0,
            fish_fraction: 1.0,
            camera: CameraPlacement {
                kind,
                wall: 0,
                depth: default_side_depth(species, cage.height),
                jitter: Jitter::default(),
            },
        }
    }

    /// Draw a clip's date, time, water, fish count and camera jitter. The
    /// error says why no water fits [`RandomRanges::extinction_550`].
    pub fn random(
        scene: &Scene,
        clip: usize,
        seed: u64,
        kind: CameraKind,
        r: &RandomRanges,
    ) -> Result<Self, String> {
        let mut p = Self::from_scene(scene, clip, seed, kind);
        let mut g = Rng::new(seed, clip as u64);
        let u = |g: &mut Rng, [a, b]: [f32; 2]| g.range(a, b);
        let year = p.year;
        let doy = (g.next_u64() % 365) as u32 + 1;
        let (mut month, mut left) = (1, doy);
        while left > days_in_month(year, month) {
            left -= days_in_month(year, month);
            month += 1;
        }
        p.month = month;
        p.day = left;
        let [h0, h1] = daylight(scene, year, month, left, r);
        p.hours = g.range(h0, h1) as f64;
        p.water = draw_water(&mut g, r)?;
        p.fish_fraction = u(&mut g, r.fish_fraction);
        let cage = scene.cage();
        // Wall and depth only place side cameras.
        if kind != CameraKind::BottomFisheye {
            p.camera.wall = (g.next_u64() % wall_count(&cage) as u64) as usize;
            p.camera.depth = g.range(0.5, (cage.height - 0.5).max(0.6));
        }
        let (m, d) = (r.jitter_m, r.jitter_deg);
        p.camera.jitter = Jitter {
            offset: [g.range(-m, m), g.range(-m, m), g.range(-m, m)],
            yaw_deg: g.range(-d, d),
            pitch_deg: g.range(-d, d),
            roll_deg: g.range(-d, d),
        };
        Ok(p)
    }

    /// The clip with its water drawn anew for the `attempt`-th time (its own
    /// random stream, so attempt `k` is the same whatever came before).
    pub fn redraw_water(&self, seed: u64, attempt: u32, r: &RandomRanges) -> Result<Self, String> {
        let mut g = Rng::new(
            seed ^ (attempt as u64).wrapping_mul(0xA076_1D64_78BD_642F),
            self.clip as u64 ^ 0x57A7_E000,
        );
        let mut p = self.clone();
        p.water = draw_water(&mut g, r)?;
        p.water_attempt = attempt;
        Ok(p)
    }

    /// The scene as this clip simulates it: its date and start time, and the
    /// share of fish (each group keeps at least one).
    pub fn apply(&self, scene: &Scene) -> Scene {
        let mut s = scene.clone();
        s.clock.year = self.year;
        s.clock.month = self.month;
        s.clock.day = self.day;
        s.clock.start_hours = self.hours as f32;
        if self.fish_fraction < 1.0 {
            for b in &mut s.behaviours {
                for g in &mut b.body_scales {
                    g.0 = ((g.0 as f32 * self.fish_fraction).round() as usize).max(1);
                }
                b.count = b.body_scales.iter().map(|g| g.0).sum();
            }
        }
        s
    }

    /// Light and water at local time `hours`, the light as it was at the
    /// start of its [`LIGHT_STEP_SECONDS`] step of the clock, so the frames
    /// of a step share one background image (`Renderer::background`).
    pub fn conditions(&self, scene: &Scene, hours: f64, scattering: bool) -> Conditions {
        let place = site_place(scene);
        let (y, m, d) = (self.year, self.month, self.day);
        let step = LIGHT_STEP_SECONDS / 3600.0;
        Conditions {
            light: Light::new(place, y, m, d, (hours / step).floor() * step),
            noon: Light::new(place, y, m, d, place.solar_noon_hours(y, m, d)),
            water: Water::new(self.water, scattering),
        }
    }
}

/// How long the light is held (simulated seconds): the sun moves 0.04° in
/// that time, invisible in a frame, while a clip's frames within one step
/// share one background image instead of shading every pixel again.
pub const LIGHT_STEP_SECONDS: f64 = 10.0;

/// Chlorophyll, sediment and particles drawn as `lo + (hi − lo)·u^skew`,
/// again until the extinction at 550 nm lies in `r.extinction_550`.
fn draw_water(g: &mut Rng, r: &RandomRanges) -> Result<WaterParams, String> {
    let skewed = |g: &mut Rng, [a, b]: [f32; 2]| a + (b - a) * g.range(0.0, 1.0).powf(r.water_skew);
    let [lo, hi] = r.extinction_550;
    for _ in 0..r.water_tries.max(1) {
        let w = WaterParams {
            chlorophyll: skewed(g, r.chlorophyll),
            sediment: skewed(g, r.sediment),
            small_particles: skewed(g, r.small_particles),
            large_particles: skewed(g, r.large_particles),
        };
        let c = Water::new(w, true).c.y;
        if (lo..=hi).contains(&c) {
            return Ok(w);
        }
    }
    Err(format!(
        "no water of the random ranges has an extinction at 550 nm within [{lo}, {hi}] /m in {} draws; widen the ranges",
        r.water_tries
    ))
}

/// The environment seed of clip `clip`.
pub fn clip_seed(seed: u64, clip: usize) -> u64 {
    seed.wrapping_mul(1_000_003).wrapping_add(clip as u64)
}

/// One mesh per species of the scene, in the order of `Scene::species_names`.
pub fn species_meshes(scene: &Scene) -> Vec<FishMesh> {
    scene
        .species_names()
        .iter()
        .map(|name| {
            let sp = &scene
                .behaviours
                .iter()
                .find(|b| &b.species.name == name)
                .expect("every species has a behaviour")
                .species;
            FishMesh::standard(&FishStyle::for_species(name, sp.collider_bl, sp.colour))
        })
        .collect()
}

/// Tail-beat phases, advanced every simulation tick from each fish's speed.
#[derive(Clone, Debug, Default)]
pub struct TailPhases(pub Vec<f32>);

impl TailPhases {
    /// Random-looking but deterministic starting phases.
    pub fn new(n: usize, seed: u64) -> Self {
        let mut g = Rng::new(seed, u64::MAX);
        Self(
            (0..n)
                .map(|_| g.range(0.0, std::f32::consts::TAU))
                .collect(),
        )
    }

    /// Advance by `dt` seconds at the current speeds.
    pub fn advance(&mut self, world: &World, dt: f32) {
        for (i, p) in self.0.iter_mut().enumerate() {
            let f = tail_beat_hz(world.speed[i] / world.bl[i]);
            *p = (*p + std::f32::consts::TAU * f * dt) % std::f32::consts::TAU;
        }
    }
}

/// The fish of `world` as the renderer takes them.
pub fn poses(world: &World, phases: &TailPhases) -> Vec<FishPose> {
    (0..world.len())
        .map(|i| FishPose {
            position: world.position[i],
            heading: world.heading[i],
            roll: world.roll[i],
            bl: world.bl[i],
            speed: world.speed[i],
            species: world.species[i],
            tail_phase: phases.0.get(i).copied().unwrap_or(0.0),
        })
        .collect()
}
