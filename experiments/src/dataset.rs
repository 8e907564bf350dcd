//! Rendering a labelled dataset (`deepfoids render`): a policy drives a
//! scene, a camera of the field set-up films it, and every frame is written
//! with its labels (YOLO, COCO, masks, per-frame JSON; see
//! `deepfoids_render::dataset`).
//!
//! Clips: frames come in clips of `clip_frames` consecutive frames, each a
//! fresh environment (seed derived from the seed and the clip index) warmed
//! up for `warmup` simulated seconds. With `randomize` each clip draws its
//! date, time of day, water, fish count and camera jitter; without it there
//! is one clip in the scene's own conditions.
//!
//! Continuing: a frame is finished when its JSON exists (written last). A
//! rerun with the same request skips finished frames; a partly finished clip
//! is re-simulated from its start (the simulation is deterministic for a
//! seed), and only its missing frames are rendered.

use crate::{PolicyOptions, lock_dir, make_policy};
use anyhow::{Context, Result, bail};
use deepfoids_env::policy::{act_and_step, action_buffers};
use deepfoids_env::{ConfigDirs, Env, GridFormat, Policy, Scene};
use deepfoids_render::dataset::ImageFormat;
use deepfoids_render::setup::{TailPhases, place_camera, poses, species_meshes};
use deepfoids_render::{
    CameraKind, ClipParams, Dataset, FishPose, FrameMeta, FrameWriter, RandomRanges, RenderConfig,
    Renderer, Split,
};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to render, every value checked by the caller (the command line's
/// bounds, `crate::bounds`).
#[derive(Clone, Debug)]
pub struct DatasetSpec {
    pub scene: Scene,
    pub seed: u64,
    /// Who acts, as [`make_policy`] names it.
    pub policy: String,
    pub policy_options: PolicyOptions,
    pub frames: usize,
    /// Frames per simulated second.
    pub fps: f64,
    pub camera: CameraKind,
    pub width: u32,
    pub height: u32,
    pub randomize: bool,
    /// Frames per clip (with `randomize`; otherwise all frames are one clip).
    pub clip_frames: usize,
    pub val_fraction: f64,
    pub allow_empty: bool,
    pub water_tries: u32,
    /// Simulated seconds before a clip's first frame.
    pub warmup: f64,
    pub min_contrast: f32,
    pub format: ImageFormat,
    pub out: PathBuf,
}

/// What [`render_dataset`] did.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Frames rendered by this call, and those a previous one had finished.
    pub rendered: usize,
    pub kept: usize,
    pub annotations: usize,
    /// Bytes of the output folder.
    pub bytes: u64,
    pub seconds: f64,
}

/// A clip's environment with its policy, action buffers and tail phases.
pub struct Clip {
    pub env: Env,
    pub policy: Box<dyn Policy>,
    actions: Vec<Vec<f32>>,
    pub phases: TailPhases,
}

impl Clip {
    pub fn new(
        dirs: &ConfigDirs,
        scene: Scene,
        seed: u64,
        policy: &str,
        options: &PolicyOptions,
    ) -> Result<Self> {
        let env = Env::with_grid_format(scene, seed, GridFormat::Bytes);
        let policy = make_policy(dirs, policy, seed, &env, options)?;
        let actions = action_buffers(&env);
        let phases = TailPhases::new(env.world().len(), seed);
        Ok(Self {
            env,
            policy,
            actions,
            phases,
        })
    }

    pub fn step(&mut self, ticks: u64) -> Result<()> {
        let dt = self.env.tick_seconds() as f32;
        for _ in 0..ticks {
            act_and_step(self.policy.as_mut(), &mut self.env, &mut self.actions)?;
            self.phases.advance(self.env.world(), dt);
        }
        Ok(())
    }
}

/// Decision ticks in `seconds` of simulated time.
pub fn ticks(seconds: f64, env: &Env) -> u64 {
    (seconds / env.tick_seconds()).round().max(0.0) as u64
}

/// Size class of each behaviour, by behaviour index.
pub fn size_classes(scene: &Scene) -> Vec<String> {
    scene
        .behaviours
        .iter()
        .map(|b| b.size_class.clone())
        .collect()
}

/// Total size of the files under `dir` (bytes).
pub fn dir_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .map(|rd| {
            rd.flatten()
                .map(|e| match e.metadata() {
                    Ok(m) if m.is_dir() => dir_bytes(&e.path()),
                    Ok(m) => m.len(),
                    Err(_) => 0,
                })
                .sum()
        })
        .unwrap_or(0)
}

/// Render `spec` into `spec.out` (locked meanwhile), continuing a render of
/// the same request; `progress(frames done)` is told as frames finish.
pub fn render_dataset(
    dirs: &ConfigDirs,
    spec: &DatasetSpec,
    mut progress: impl FnMut(usize),
) -> Result<Rendered> {
    let scene = &spec.scene;
    let seed = spec.seed;
    let clip_frames = if spec.randomize {
        spec.clip_frames
    } else {
        spec.frames
    };
    let ranges = RandomRanges::default();
    let n_clips = spec.frames.div_ceil(clip_frames);
    let clips: Vec<ClipParams> = (0..n_clips)
        .map(|c| {
            if spec.randomize {
                ClipParams::random(scene, c, seed, spec.camera, &ranges)
                    .map_err(|e| anyhow::anyhow!("clip {c}: {e}"))
            } else {
                Ok(ClipParams::from_scene(scene, c, seed, spec.camera))
            }
        })
        .collect::<Result<_>>()?;
    // The policy must drive the scene before the folder is touched: a
    // mismatch (another species, a missing file) leaves nothing behind.
    Clip::new(
        dirs,
        scene.clone(),
        seed,
        &spec.policy,
        &spec.policy_options,
    )?;
    let _lock = lock_dir(&spec.out)?;
    let dataset = Dataset::new(
        &spec.out,
        spec.format,
        scene.species_names(),
        size_classes(scene),
    );
    let config = RenderConfig {
        min_contrast: spec.min_contrast,
        ..RenderConfig::default()
    };
    let request = json!({
        "min_contrast": spec.min_contrast,
        "scene": scene.id, "policy": spec.policy, "frames": spec.frames, "fps": spec.fps,
        "camera": spec.camera.as_str(), "width": spec.width, "height": spec.height,
        "randomize": spec.randomize, "clip_frames": clip_frames, "warmup": spec.warmup,
        "seed": seed, "format": spec.format.ext(), "phase": scene.phase.as_str(),
        "val_fraction": spec.val_fraction, "allow_empty": spec.allow_empty, "water_tries": spec.water_tries,
        "stochastic": spec.policy_options.stochastic, "checkpoint": spec.policy_options.checkpoint,
    });
    let optics: Vec<_> = clips
        .iter()
        .map(|c| {
            let w = c.conditions(scene, c.hours, true).water;
            json!({"clip": c.clip, "ac": w.ac.to_array(), "extinction_c": w.c.to_array(),
                   "diffuse_k": w.k.to_array(), "absorption": w.a.to_array()})
        })
        .collect();
    let params = json!({
        "scene": scene, "render": config, "randomize_ranges": ranges, "clips": clips,
        "optics": optics, "classes": scene.species_names(),
    });
    dataset
        .write_or_check_scene(&params, &request)
        .with_context(|| format!("preparing {}", spec.out.display()))?;
    let renderer = Renderer::new(
        config,
        species_meshes(scene),
        Renderer::faces_of(&scene.cage()),
    );

    let done_before = (0..spec.frames).filter(|&i| dataset.frame_done(i)).count();
    progress(done_before);
    let start = Instant::now();
    let job = Job {
        dirs,
        spec,
        dataset: &dataset,
        renderer: &renderer,
        ranges: &ranges,
        clip_frames,
        n_clips,
    };
    let mut rendered = 0usize;
    for clip in &clips {
        let before = done_before + rendered;
        rendered += job.render_clip(clip, &mut |n| progress(before + n))?;
    }
    let annotations = dataset.finish(spec.frames)?;
    Ok(Rendered {
        rendered,
        kept: done_before,
        annotations,
        bytes: dir_bytes(&spec.out),
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// One render's fixed parts, shared by its clips.
struct Job<'a> {
    dirs: &'a ConfigDirs,
    spec: &'a DatasetSpec,
    dataset: &'a Dataset,
    renderer: &'a Renderer,
    ranges: &'a RandomRanges,
    clip_frames: usize,
    n_clips: usize,
}

impl Job<'_> {
    /// Render `clip`'s missing frames: simulate the whole clip first (poses
    /// are small), then render it, drawing its water again while no fish is
    /// visible (with `randomize`, up to `water_tries` draws). Returns the
    /// frames rendered; `progress(n)` after each of the first pass.
    fn render_clip(&self, clip: &ClipParams, progress: &mut dyn FnMut(usize)) -> Result<usize> {
        let first = clip.clip * self.clip_frames;
        let range = first..(first + self.clip_frames).min(self.spec.frames);
        if range.clone().all(|i| self.dataset.frame_done(i)) {
            return Ok(0);
        }
        let split = Split::of_clip(clip.clip, self.n_clips, self.spec.val_fraction);
        let cs = clip.apply(&self.spec.scene);
        let mut sim = Clip::new(
            self.dirs,
            cs.clone(),
            clip.seed,
            &self.spec.policy,
            &self.spec.policy_options,
        )?;
        let per_frame = ticks(1.0 / self.spec.fps, &sim.env).max(1);
        sim.step(ticks(self.spec.warmup, &sim.env))?;
        let camera = place_camera(&cs.cage(), &clip.camera, self.spec.width, self.spec.height);
        let behaviour_of = sim.env.world().behaviour.clone();
        // The whole clip is simulated first (poses are small); the water does
        // not move the fish, so a redrawn water only renders again.
        let mut steps: Vec<(f64, f64, Vec<FishPose>)> = Vec::with_capacity(range.len());
        for k in 0..range.len() {
            if k > 0 {
                sim.step(per_frame)?;
            }
            steps.push((
                sim.env.clock_hours(),
                sim.env.output().time,
                poses(sim.env.world(), &sim.phases),
            ));
        }
        // A partly finished clip continues with the water its frames were drawn with.
        let mut attempt = range
            .clone()
            .find(|&i| self.dataset.frame_done(i))
            .and_then(|i| self.dataset.frame_meta(i).ok())
            .map_or(0, |m| m.1);
        let mut first_pass = true;
        let mut rendered = 0usize;
        loop {
            let water = if attempt == 0 {
                clip.clone()
            } else {
                clip.redraw_water(self.spec.seed, attempt, self.ranges)
                    .map_err(|e| anyhow::anyhow!("clip {}: {e}", clip.clip))?
            };
            let mut visible = 0usize;
            let mut writer = FrameWriter::new(self.dataset, &behaviour_of);
            for (i, (hours, time, fish)) in range.clone().zip(&steps) {
                if self.dataset.frame_done(i)
                    && let Ok((v, a)) = self.dataset.frame_meta(i)
                    && a == attempt
                {
                    visible += v;
                    continue;
                }
                let cond = water.conditions(&cs, *hours, true);
                let meta = FrameMeta {
                    clip: clip.clip,
                    time: *time,
                    clock_hours: *hours,
                    sun_elevation_deg: cond.light.sun_elevation_deg,
                    camera,
                    split,
                    water_attempt: attempt,
                };
                // Frame i renders while frame i − 1 is written.
                visible += writer
                    .next(i, meta, || self.renderer.render(fish, &camera, &cond))
                    .with_context(|| format!("writing a frame of clip {}", clip.clip))?;
                if first_pass {
                    rendered += 1;
                    progress(rendered);
                }
            }
            writer
                .finish()
                .with_context(|| format!("writing the last frame of clip {}", clip.clip))?;
            if visible > 0 || !self.spec.randomize || self.spec.allow_empty {
                break;
            }
            first_pass = false;
            attempt += 1;
            if attempt >= self.spec.water_tries {
                let w = deepfoids_render::Water::new(water.water, true);
                bail!(
                    "clip {} of {}: no fish visible in any of its frames with {} water draws (last: extinction {:.2} /m at 550 nm, {:02}:{:02} local time, sun {:.0}° high); pass --allow-empty to keep empty clips, or more --water-tries",
                    clip.clip,
                    self.spec.scene.id,
                    self.spec.water_tries,
                    w.c.y,
                    clip.hours as u32,
                    (clip.hours.fract() * 60.0) as u32,
                    deepfoids_env::sun::SunPlace::position(
                        &deepfoids_render::setup::site_place(&cs),
                        clip.year,
                        clip.month,
                        clip.day,
                        clip.hours
                    )
                    .elevation_deg
                );
            }
        }
        Ok(rendered)
    }
}
