//! Upper bounds on every size, count and duration that a configuration file or
//! a command line can ask for.
//!
//! A typo must not take the machine down: `count = 100000000` once asked the
//! allocator for 4.9 TB and `edge = 1e30` simulated a cage of 10³⁰ m. Every
//! value is checked against a bound *before* anything is allocated, and the
//! error names the file, the field, the value and the bound:
//! `configs/scenes/x.toml: group[0].count = 100000000 is above the limit of 200000 fish`.
//! The bounds are machine-independent sanity limits, generous enough for any
//! real farm; whether a scene within them fits into *this* machine's memory is
//! the separate check of [`crate::memory`]. This module holds the bounds
//! only; each config type checks its own fields against them beside its
//! definition (`config::species`, `config::site`, `config::scene`,
//! `config::rewards`, with the shared helpers of `config::check`).
//!
//! | value | bound | why |
//! |---|---|---|
//! | fish in a scene (per group and in total) | 200,000 | the largest licensed salmon pens hold 200,000 fish (Norway's per-cage cap); ≈ 10 GB of observations |
//! | groups, obstacles per scene | 256 each | every fish tests every obstacle at every step |
//! | size classes per species | 64 | |
//! | cage width, length, height, edge; obstacle radius | 1,000 m | the largest sea cages are ~110 m across and ~70 m deep; `f32` positions keep 0.1 mm resolution up to 1 km |
//! | physics steps per decision `dt_res / dt_sim` | 1,000 | the thesis uses 5–10; beyond, one decision is a CPU-minute |
//! | decision interval | 10 s | the thesis uses 0.1–0.2 s |
//! | episode length | 1,000,000 decisions | ≥ 27 simulated hours; the thesis uses 2,000 |
//! | chase timeout | 3,600 s | the thesis uses 3 s |
//! | body length | 10 m | farmed fish are < 3 m (bluefin tuna) |
//! | body scale | 10 × | the thesis uses 0.5–1.5 |
//! | speeds (BL/s) | 50 BL/s | burst speeds of fish reach ~20 BL/s |
//! | sensing range, colliders, visual radius, baseline ranges (BL) | 100 BL | the thesis senses 2–3 BL |
//! | light (PAR) | 5,000 | full sunlight is ~2,000–2,500 µmol m⁻² s⁻¹ |
//! | light attenuation | 100 1/m | turbid coastal water: ~5 1/m |
//! | temperatures | −100 … 100 °C (water at the surface −5 … 50 °C) | liquid sea water |
//! | reward and baseline weights | 0 … 10,000 | the thesis' largest is 300 |
//! | a configuration file | 1 MiB | ours are < 2 kB; the whole file is read into memory |
//! | simulated seconds of one command (`--seconds`, `--warmup`) | 86,400 s | one simulated day, a full light cycle |
//! | evaluation seeds (`compare --seeds`) | 1,000 | |
//! | worker threads (`--threads`) | 1 … 1,024 | 0 is refused: leave the option out for one thread per core |
//! | frames (`render --frames`, `--clip-frames`) | 1,000,000 | frame files are numbered with six digits |
//! | image side (`render --width`, `--height`) | 8,192 px | 8K; a frame's buffers grow with the pixel count |
//! | frames per second (`--fps`, `--replay-fps`) | 1,000 | more than one frame per physics step is impossible anyway |
//! | ticks before `sensor-view` looks (`--step`) | 1,000,000 | |

/// Largest `neighbour_cap` of a reward file: the sensing pass keeps that
/// many nearest neighbours on the stack (`crate::sensing`).
pub const MAX_NEIGHBOUR_CAP: usize = 32;

/// Fish in one scene, per group and in total.
pub const MAX_FISH: usize = 200_000;
/// `[[group]]` tables in one scene.
pub const MAX_GROUPS: usize = 256;
/// `[[obstacle]]` tables in one scene.
pub const MAX_OBSTACLES: usize = 256;
/// Size classes of one species.
pub const MAX_SIZE_CLASSES: usize = 64;
/// Any cage dimension or obstacle radius (m).
pub const MAX_CAGE_M: f32 = 1_000.0;
/// Physics steps per decision, `floor(dt_res / dt_sim)`.
pub const MAX_STEPS_PER_DECISION: f32 = 1_000.0;
/// Decision interval `dt_res` (s).
pub const MAX_DECISION_INTERVAL_S: f32 = 10.0;
/// Episode length (decisions).
pub const MAX_EPISODE_DECISIONS: u32 = 1_000_000;
/// Chase timeout (s).
pub const MAX_CHASE_TIMEOUT_S: f32 = 3_600.0;
/// Body length at body scale 1 (m).
pub const MAX_BODY_LENGTH_M: f32 = 10.0;
/// Body scale (× the species' body length).
pub const MAX_BODY_SCALE: f32 = 10.0;
/// Any speed or speed change (BL/s).
pub const MAX_SPEED_BL: f32 = 50.0;
/// Any distance given in body lengths: sensing range, collider, visual radius,
/// spawn margin, baseline ranges (BL).
pub const MAX_RANGE_BL: f32 = 100.0;
/// Any light intensity (PAR).
pub const MAX_LIGHT_PAR: f32 = 5_000.0;
/// Light attenuation coefficient `a` of Eq. 4.1 (1/m).
pub const MAX_ATTENUATION: f32 = 100.0;
/// Any temperature preference or steepness (°C), as `[min, max]`.
pub const TEMPERATURE_C: [f32; 2] = [-100.0, 100.0];
/// Water temperature at the surface (°C), as `[min, max]`.
pub const SURFACE_TEMPERATURE_C: [f32; 2] = [-5.0, 50.0];
/// Any reward or baseline weight.
pub const MAX_WEIGHT: f32 = 10_000.0;
/// Size of a configuration file (bytes).
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;
/// Simulated seconds of one command (`--seconds`, `--warmup`): one day.
pub const MAX_SECONDS: f64 = 86_400.0;
/// Evaluation seeds (`compare --seeds`).
pub const MAX_SEEDS: u64 = 1_000;
/// Worker threads (`--threads`).
pub const MAX_THREADS: usize = 1_024;
/// Frames of one render (`--frames`, `--clip-frames`): file names have six digits.
pub const MAX_FRAMES: usize = 1_000_000;
/// Width or height of a rendered image (px).
pub const MAX_IMAGE_PX: u32 = 8_192;
/// Frames per simulated second (`--fps`, `--replay-fps`).
pub const MAX_FPS: f64 = 1_000.0;
/// Ticks simulated before `sensor-view` looks (`--step`).
pub const MAX_TICKS: u64 = 1_000_000;
