//! `deepfoids count`: how many fish are in this cage video (thesis §4.4,
//! Fig. 4.5; the pipeline is `deepfoids_count`'s). `deepfoids bench count`
//! times it.

use crate::args::whole;
use anyhow::{Context, Result, bail};
use clap::Args;
use deepfoids_count::count::{Outputs, run as count_run};
use deepfoids_count::{CountConfig, Counter, Detector, InputCamera};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct CountArgs {
    /// A video (decoded by the system's ffmpeg) or a folder of PNG/JPEG frames
    #[arg(value_name = "INPUT")]
    pub input: PathBuf,
    #[command(flatten)]
    pub opts: CountOptions,
    /// Output folder: counts.csv (per frame), summary.json, annotated/ (with --annotate)
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Write every N-th processed frame with its boxes drawn to DIR/annotated (0: none)
    #[arg(value_parser = whole::<usize>, long, default_value_t = 0, value_name = "N")]
    pub annotate: usize,
    /// Process every N-th frame of the input
    #[arg(value_parser = whole::<usize>, long, default_value_t = 1, value_name = "N")]
    pub every: usize,
    /// Stop after this many processed frames
    #[arg(value_parser = whole::<usize>, long, value_name = "N")]
    pub max_frames: Option<usize>,
    /// No per-frame lines
    #[arg(long)]
    pub quiet: bool,
}

/// Options shared by `count` and `bench count`.
#[derive(Args, Debug, Clone)]
pub struct CountOptions {
    /// The camera that filmed the input: fisheye (corrected to a perspective view) or pinhole
    #[arg(long, default_value = "fisheye", value_parser = ["fisheye", "pinhole"])]
    pub camera: String,
    /// Field of view of the fisheye (degrees; the thesis' camera: 235)
    #[arg(long, default_value_t = 235.0, value_name = "DEG")]
    pub fov: f32,
    /// Detector: our ONNX (`deepfoids train-detector`) or a YOLOv8 ONNX export [default: the shipped detectors/fish.onnx]
    #[arg(long, value_name = "X.onnx")]
    pub detector: Option<PathBuf>,
    /// Least confidence of a detection [default: the detector's `confidence` metadata (chosen on its val split by `train-detector`), else 0.5]
    #[arg(long)]
    pub conf: Option<f32>,
    /// IoU above which the one NMS merges boxes
    #[arg(long, default_value_t = 0.5)]
    pub iou: f32,
    /// Field of view of the corrected perspective view (degrees) [default: the detector's, else 120]
    #[arg(long, value_name = "DEG")]
    pub view_fov: Option<f32>,
    /// Side of the corrected view (pixels) [default: the detector's, else 832]
    #[arg(value_parser = whole::<u32>, long, value_name = "PX")]
    pub view_size: Option<u32>,
    /// Median-blur kernel (odd pixels; 1: off)
    #[arg(value_parser = whole::<u32>, long, default_value_t = 3)]
    pub median: u32,
    /// Also search the view at half size and keep what that finds longer than PX pixels (fish
    /// close to the camera); 0: off [default: the detector's `coarse_min_px` metadata, else 0]
    #[arg(long, value_name = "PX")]
    pub coarse: Option<f32>,
}

/// `--detector`, else the shipped one.
fn detector_path(opts: &CountOptions) -> Result<PathBuf> {
    if let Some(p) = &opts.detector {
        return Ok(p.clone());
    }
    let p = deepfoids_experiments::pretrained::detector();
    if !p.is_file() {
        bail!(
            "no shipped detector at {}; pass --detector X.onnx (train one with `deepfoids train-detector`, or bring a YOLOv8 ONNX export)",
            p.display()
        );
    }
    Ok(p)
}

/// The counter of `opts`: the detector loaded, its training view and
/// confidence as the defaults.
pub fn counter(opts: &CountOptions) -> Result<Counter> {
    let path = detector_path(opts)?;
    let defaults = CountConfig::default();
    let detector = Detector::load(&path, defaults.window)?;
    let camera = match opts.camera.as_str() {
        "pinhole" => InputCamera::Pinhole,
        _ => InputCamera::Fisheye { fov_deg: opts.fov },
    };
    let config = CountConfig {
        camera,
        median: opts.median,
        iou: opts.iou,
        ..defaults
    }
    .with_detector_defaults(&detector, opts.view_fov, opts.view_size, opts.conf)
    .with_coarse_default(&detector, opts.coarse);
    Ok(Counter::new(config, detector)?)
}

pub fn run(args: &CountArgs) -> Result<()> {
    if args.every == 0 {
        bail!("--every must be at least 1");
    }
    let mut counter = counter(&args.opts)?;
    let c = &counter.config;
    println!(
        "detector {}: confidence {}, view {}° on {} px{}",
        counter.detector.path.display(),
        c.conf,
        c.view_fov_deg,
        c.view_size,
        if c.coarse_min_px > 0.0 {
            format!(
                ", coarse pass for fish of {} px and longer",
                c.coarse_min_px
            )
        } else {
            String::new()
        }
    );
    let _lock = match &args.out {
        Some(d) => Some(deepfoids_experiments::lock_dir(d)?),
        None => None,
    };
    let out = Outputs {
        dir: args.out.clone(),
        annotate_every: args.annotate,
        frame_step: args.every,
        max_frames: args.max_frames,
    };
    let start = Instant::now();
    let quiet = args.quiet;
    let s = count_run(&mut counter, &args.input, &out, |i, name, n| {
        if !quiet {
            println!("frame {i} ({name}): {n} fish");
        }
    })
    .with_context(|| format!("counting {}", args.input.display()))?;
    let wall = start.elapsed().as_secs_f64();
    println!(
        "{} frames in {:.1} s ({:.2} frames/s); per frame: median {}, 90th percentile {}, mean {:.1}",
        s.frames,
        wall,
        s.frames as f64 / wall.max(1e-9),
        s.median,
        s.p90,
        s.mean
    );
    if let Some(d) = &args.out {
        println!("counts in {}", d.join("counts.csv").display());
    }
    println!("{}", s.line());
    Ok(())
}

#[derive(Args, Debug)]
pub struct BenchCountArgs {
    /// A video or folder of frames (1280 × 720 fisheye frames for the target)
    #[arg(value_name = "INPUT")]
    pub input: PathBuf,
    #[command(flatten)]
    pub opts: CountOptions,
    /// Frames to time (after one untimed warm-up frame)
    #[arg(value_parser = whole::<usize>, long, default_value_t = 10)]
    pub frames: usize,
}

/// What `bench count` sums over the timed frames of one pipeline.
#[derive(Default)]
struct Timing {
    /// Seconds pre-processing (denoising, fisheye correction, local contrast).
    preprocess: f64,
    /// Seconds detecting, windows and NMS included.
    detect: f64,
    /// Fish counted, over all frames.
    fish: usize,
    /// Windows per frame.
    windows: usize,
}

impl Timing {
    fn frames_per_second(&self, frames: usize) -> f64 {
        frames as f64 / (self.preprocess + self.detect)
    }

    fn fish_per_frame(&self, frames: usize) -> f64 {
        self.fish as f64 / frames as f64
    }
}

/// `deepfoids bench count`: frames per second of the whole pipeline, and
/// its split. With our detector, also the graph as exported (its own local
/// contrast pooled per window) on the same frames, interleaved, and the ratio.
pub fn bench(args: &BenchCountArgs) -> Result<()> {
    let mut counter = counter(&args.opts)?;
    let mut frames = deepfoids_count::frames::Frames::open(&args.input)?;
    let mut imgs = Vec::new();
    while imgs.len() < args.frames + 1 {
        match frames.next_frame()? {
            Some((_, img)) => imgs.push(img),
            None => break,
        }
    }
    if imgs.len() < 2 {
        bail!("{} holds fewer than 2 frames", args.input.display());
    }
    let mut exported = match counter.detector.cuts_local_contrast {
        Some(_) => {
            let d = &counter.detector;
            let whole = Detector::load_as_exported(&d.path, d.input)?;
            Some(Counter::new(counter.config.clone(), whole)?)
        }
        None => None,
    };
    let time = |counter: &mut Counter, img, t: &mut Timing| -> Result<()> {
        let start = Instant::now();
        let view = counter.preprocess(img);
        t.preprocess += start.elapsed().as_secs_f64();
        let start = Instant::now();
        let (d, w) = counter.detect(&view)?;
        t.detect += start.elapsed().as_secs_f64();
        t.fish += d.len();
        t.windows = w;
        Ok(())
    };
    let (mut ours, mut theirs) = (Timing::default(), Timing::default());
    counter.frame(&imgs[0])?;
    if let Some(e) = exported.as_mut() {
        e.frame(&imgs[0])?;
    }
    for img in &imgs[1..] {
        time(&mut counter, img, &mut ours)?;
        if let Some(e) = exported.as_mut() {
            time(e, img, &mut theirs)?;
        }
    }
    let n = imgs.len() - 1;
    let (w, h) = imgs[0].dimensions();
    println!(
        "{w}×{h} {}, {} threads, {} windows per frame, detector {}: {:.1} fish per frame",
        args.opts.camera,
        rayon::current_num_threads(),
        ours.windows,
        counter.detector.path.display(),
        ours.fish_per_frame(n)
    );
    let line = |what: &str, t: &Timing| {
        println!(
            "{what}{:.2} frames/s (pre-processing {:.0} ms, detection + NMS {:.0} ms per frame)",
            t.frames_per_second(n),
            1e3 * t.preprocess / n as f64,
            1e3 * t.detect / n as f64
        )
    };
    line("", &ours);
    if exported.is_some() {
        line(
            "the graph as exported (local contrast per window): ",
            &theirs,
        );
        println!(
            "ratio {:.2}× ({:.1} fish per frame as exported)",
            ours.frames_per_second(n) / theirs.frames_per_second(n),
            theirs.fish_per_frame(n)
        );
    }
    Ok(())
}
