//! `deepfoids render`: a policy drives a scene, a camera of the field set-up
//! films it, and every frame is written with its labels (YOLO, COCO, masks,
//! per-frame JSON; see `deepfoids_render::dataset`). `deepfoids bench render`
//! times it. The rendering itself is `deepfoids_experiments::dataset`.

use crate::args::whole;
use crate::args::{PolicyArgs, SceneArgs};
use anyhow::{Result, bail};
use clap::Args;
use deepfoids_env::ConfigDirs;
use deepfoids_env::limits::{MAX_FPS, MAX_FRAMES, MAX_IMAGE_PX};
use deepfoids_experiments::bounds::{self, count_within, positive_at_most};
use deepfoids_experiments::dataset::{
    Clip, DatasetSpec, dir_bytes, render_dataset, size_classes, ticks,
};
use deepfoids_experiments::{PolicyOptions, load_scene};
use deepfoids_render::dataset::ImageFormat;
use deepfoids_render::setup::{place_camera, poses, species_meshes};
use deepfoids_render::{
    CameraKind, ClipParams, Dataset, FrameMeta, FrameWriter, RenderConfig, Renderer, Split,
};
use std::path::PathBuf;
use std::str::FromStr;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub policy_args: PolicyArgs,
    /// Frames to render
    #[arg(value_parser = whole::<usize>, long)]
    pub frames: usize,
    /// Frames per simulated second (rounded to whole decision ticks)
    #[arg(long, default_value_t = 5.0)]
    pub fps: f64,
    /// Camera: bottom-fisheye (235°, cage bottom looking up), side (pinhole 90°), side-fisheye (155°)
    #[arg(long, default_value = "bottom-fisheye", value_parser = CameraKind::from_str)]
    pub camera: CameraKind,
    /// Image width (pixels)
    #[arg(value_parser = whole::<u32>, long, default_value_t = 1280)]
    pub width: u32,
    /// Image height (pixels)
    #[arg(value_parser = whole::<u32>, long, default_value_t = 720)]
    pub height: u32,
    /// Draw time of day, date, chlorophyll, sediment, particles, fish count and camera jitter per clip
    #[arg(long)]
    pub randomize: bool,
    /// Frames per clip with --randomize (without it all frames form one clip)
    #[arg(value_parser = whole::<usize>, long, default_value_t = 50)]
    pub clip_frames: usize,
    /// Share of the clips held out for validation (whole clips, spread evenly: 0.2 = every 5th);
    /// named in data.yaml (train.txt, val.txt) and annotations_{train,val}.json
    #[arg(long, default_value_t = 0.2)]
    pub val_fraction: f64,
    /// With --randomize: keep a clip in which no fish is visible in any frame (by default its
    /// water is drawn again, up to --water-tries times, then the render stops with an error)
    #[arg(long)]
    pub allow_empty: bool,
    /// With --randomize: water draws per clip before an empty clip is an error
    #[arg(value_parser = whole::<u32>, long, default_value_t = 5)]
    pub water_tries: u32,
    /// Simulated seconds before a clip's first frame (the school settles)
    #[arg(long, default_value_t = 10.0)]
    pub warmup: f64,
    /// Least mean contrast (0–1 of the 8-bit range) for a visible fish to be labelled in YOLO
    /// and COCO; fainter fish (turbid water, dusk) stay in the frame JSON only. 0 labels every
    /// fish with a visible pixel
    #[arg(long, default_value_t = RenderConfig::default().min_contrast)]
    pub min_contrast: f32,
    /// Image format: jpg or png
    #[arg(long, default_value = "jpg", value_parser = ImageFormat::from_str)]
    pub format: ImageFormat,
    /// No progress bar
    #[arg(long)]
    pub quiet: bool,
    /// Output folder (continued if it holds a render with the same arguments)
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

#[derive(Args, Debug)]
pub struct BenchRenderArgs {
    /// Scene id or path
    #[arg(long, default_value = "coho_default", value_name = "ID|PATH")]
    pub scene: String,
    /// Timed frames
    #[arg(value_parser = whole::<usize>, long, default_value_t = 10)]
    pub frames: usize,
    #[arg(value_parser = whole::<u32>, long, default_value_t = 1280)]
    pub width: u32,
    #[arg(value_parser = whole::<u32>, long, default_value_t = 720)]
    pub height: u32,
    #[arg(long, default_value = "bottom-fisheye", value_parser = CameraKind::from_str)]
    pub camera: CameraKind,
    /// Who acts (as for `render`)
    #[arg(long, default_value = "foids")]
    pub policy: String,
    #[arg(value_parser = whole::<u64>, long, default_value_t = 0)]
    pub seed: u64,
}

/// `--width` and `--height` within `[16, MAX_IMAGE_PX]`.
fn image_size(width: u32, height: u32) -> Result<()> {
    let px = [16, MAX_IMAGE_PX as u64];
    count_within("--width", width as u64, px, "px")?;
    count_within("--height", height as u64, px, "px")
}

pub fn run(dirs: &ConfigDirs, args: &RenderArgs) -> Result<()> {
    let (policy_name, policy_args) = args.policy_args.resolve("foids")?;
    let frames = [1, MAX_FRAMES as u64];
    count_within("--frames", args.frames as u64, frames, "frames")?;
    count_within("--clip-frames", args.clip_frames as u64, frames, "frames")?;
    image_size(args.width, args.height)?;
    positive_at_most("--fps", args.fps, MAX_FPS, "frames/s")?;
    bounds::warmup("--warmup", args.warmup)?;
    if !(0.0..=1.0).contains(&args.min_contrast) {
        bail!(
            "--min-contrast must be in [0, 1] (a share of the 8-bit range), got {}",
            args.min_contrast
        );
    }
    if !(0.0..=1.0).contains(&args.val_fraction) {
        bail!(
            "--val-fraction must be in [0, 1] (a share of the clips), got {}",
            args.val_fraction
        );
    }
    count_within("--water-tries", args.water_tries as u64, [1, 100], "draws")?;
    let spec = DatasetSpec {
        scene: args.scene.load(dirs)?,
        seed: args.scene.seed,
        policy: policy_name.clone(),
        policy_options: policy_args.options(),
        frames: args.frames,
        fps: args.fps,
        camera: args.camera,
        width: args.width,
        height: args.height,
        randomize: args.randomize,
        clip_frames: args.clip_frames,
        val_fraction: args.val_fraction,
        allow_empty: args.allow_empty,
        water_tries: args.water_tries,
        warmup: args.warmup,
        min_contrast: args.min_contrast,
        format: args.format,
        out: args.out.clone(),
    };
    let bar = progress(args.frames, args.quiet);
    let done = render_dataset(dirs, &spec, |n| bar.set_position(n as u64))?;
    bar.finish_and_clear();
    println!(
        "{}: {} frames ({} rendered now, {} kept), {} annotations, {:.1} MB in {}; {:.2} frames/s",
        spec.scene.id,
        args.frames,
        done.rendered,
        done.kept,
        done.annotations,
        done.bytes as f64 / 1e6,
        args.out.display(),
        done.rendered as f64 / done.seconds.max(1e-9)
    );
    Ok(())
}

fn progress(n: usize, quiet: bool) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(n as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "rendering [{bar:40}] {pos}/{len} frames, {per_sec}, eta {eta}",
        )
        .expect("a valid template")
        .progress_chars("=> "),
    );
    bar
}

/// `deepfoids bench render`: frames per second of rendering with every label
/// written (image, mask, YOLO, frame JSON) as `render` runs it (each frame
/// rendering while the one before is written), the same frames one stage
/// after the other for the split, and with the simulation included. The
/// background is made before the timing (a clip makes it once).
pub fn bench(dirs: &ConfigDirs, args: &BenchRenderArgs) -> Result<()> {
    count_within(
        "--frames",
        args.frames as u64,
        [1, MAX_FRAMES as u64],
        "frames",
    )?;
    image_size(args.width, args.height)?;
    let scene = load_scene(dirs, &args.scene, deepfoids_env::Phase::Pretrain)?;
    let clip = ClipParams::from_scene(&scene, 0, args.seed, args.camera);
    let sampled = PolicyOptions {
        checkpoint: None,
        stochastic: true,
    };
    let mut sim = Clip::new(dirs, scene.clone(), clip.seed, &args.policy, &sampled)?;
    sim.step(ticks(10.0, &sim.env))?;
    let renderer = Renderer::new(
        RenderConfig::default(),
        species_meshes(&scene),
        Renderer::faces_of(&scene.cage()),
    );
    let camera = place_camera(&scene.cage(), &clip.camera, args.width, args.height);
    let tmp = std::env::temp_dir().join(format!("deepfoids-bench-render-{}", std::process::id()));
    let dataset = Dataset::new(
        &tmp,
        ImageFormat::Jpg,
        scene.species_names(),
        size_classes(&scene),
    );
    let behaviour_of = sim.env.world().behaviour.clone();
    let per_frame = ticks(0.2, &sim.env).max(1);
    // The clip's poses and conditions first, as `render` does.
    let t = Instant::now();
    let mut frames = Vec::with_capacity(args.frames);
    for i in 0..args.frames {
        sim.step(per_frame)?;
        let hours = sim.env.clock_hours();
        let cond = clip.conditions(&scene, hours, true);
        let meta = FrameMeta {
            clip: 0,
            time: sim.env.output().time,
            clock_hours: hours,
            sun_elevation_deg: cond.light.sun_elevation_deg,
            camera,
            split: Split::Train,
            water_attempt: 0,
        };
        frames.push((i, poses(sim.env.world(), &sim.phases), cond, meta));
    }
    let t_sim = t.elapsed().as_secs_f64();
    renderer.background(&camera, &frames[0].2);
    // One stage after the other.
    let (mut t_render, mut t_write, mut visible) = (0.0, 0.0, 0usize);
    for (i, fish, cond, meta) in &frames {
        let t = Instant::now();
        let frame = renderer.render(fish, &camera, cond);
        t_render += t.elapsed().as_secs_f64();
        visible += frame.visible_count();
        let t = Instant::now();
        dataset.write_frame(*i, &frame, &behaviour_of, meta)?;
        t_write += t.elapsed().as_secs_f64();
    }
    // As `render` runs them: frame i renders while frame i − 1 is written.
    let t = Instant::now();
    let mut writer = FrameWriter::new(&dataset, &behaviour_of);
    for (i, fish, cond, meta) in &frames {
        writer.next(*i, meta.clone(), || renderer.render(fish, &camera, cond))?;
    }
    writer.finish()?;
    let t_overlap = t.elapsed().as_secs_f64();
    let bytes = dir_bytes(&tmp);
    let _ = std::fs::remove_dir_all(&tmp);
    let n = args.frames as f64;
    println!(
        "{}: {} fish, {}×{} {}, {} threads, policy {}: {:.1} visible fish per frame",
        scene.id,
        sim.env.world().len(),
        args.width,
        args.height,
        args.camera.as_str(),
        rayon::current_num_threads(),
        sim.policy.name(),
        visible as f64 / n
    );
    println!(
        "{:.2} frames/s rendered with all labels written, as `render` runs them (a frame renders while the one before is written)",
        n / t_overlap,
    );
    println!(
        "{:.2} frames/s one stage after the other: render + labels {:.0} ms, encode + write {:.0} ms per frame",
        n / (t_render + t_write),
        1e3 * t_render / n,
        1e3 * t_write / n
    );
    println!(
        "{:.2} frames/s including the simulation ({:.0} ms per frame at 5 fps); {:.2} MB per 1,000 frames",
        n / (t_sim + t_overlap),
        1e3 * t_sim / n,
        bytes as f64 / n * 1000.0 / 1e6
    );
    Ok(())
}
