//! `deepfoids train-detector`: our fish detector trained from scratch on
//! `render` folders (`deepfoids_count::train`), exported to ONNX.

use crate::args::whole;
use anyhow::{Result, bail};
use clap::Args;
use deepfoids_count::train::{TrainConfig, load_data, score_detector, train};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct TrainDetectorArgs {
    /// `deepfoids render` output folders (split by clip: their val clips are held out)
    #[arg(long, value_name = "DIR", num_args = 1.., required = true)]
    pub data: Vec<PathBuf>,
    /// Output folder: detector.onnx, model.bpk (Burn), report.json, checkpoint/
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Optimiser steps
    #[arg(value_parser = whole::<usize>, long, default_value_t = TrainConfig::default().steps)]
    pub steps: usize,
    /// Stop after this many minutes even if steps remain (0: no limit)
    #[arg(long, default_value_t = 0.0)]
    pub minutes: f64,
    /// Crops per step
    #[arg(value_parser = whole::<usize>, long, default_value_t = TrainConfig::default().batch)]
    pub batch: usize,
    /// Side of the training crops (pixels, a multiple of 8)
    #[arg(value_parser = whole::<u32>, long, default_value_t = TrainConfig::default().crop)]
    pub crop: u32,
    /// Adam's first learning rate (decayed linearly to a tenth)
    #[arg(long, default_value_t = TrainConfig::default().lr)]
    pub lr: f64,
    /// Channels of the first layer (the network's width)
    #[arg(value_parser = whole::<usize>, long, default_value_t = TrainConfig::default().base)]
    pub base: usize,
    /// Output stride of the heatmap: 8, or 4 for schools whose fish lie closer than 8 px in the view
    #[arg(value_parser = whole::<usize>, long, default_value_t = TrainConfig::default().stride)]
    pub stride: usize,
    /// One more dilated layer: a receptive field of 263 px instead of 135, for fish close to the camera
    #[arg(long)]
    pub wide: bool,
    #[arg(value_parser = whole::<u64>, long, default_value_t = 0)]
    pub seed: u64,
    /// Share of the crops cut from the views shrunk to half, as `--coarse` searches them at count
    /// time: teaches the fish close to the lens at the size the coarse pass shows them (0 to 1)
    #[arg(long, default_value_t = TrainConfig::default().half_share)]
    pub half_share: f32,
    /// Field of view of the perspective view fisheye frames are corrected to (degrees), as `count`'s
    #[arg(long, default_value_t = 120.0)]
    pub view_fov: f32,
    /// Side of that view (pixels), as `count`'s
    #[arg(value_parser = whole::<u32>, long, default_value_t = 832)]
    pub view_size: u32,
    /// IoU above which the one NMS merges boxes when the val split is scored, as `count`'s
    #[arg(long, default_value_t = 0.5)]
    pub iou: f32,
    /// With --eval: `count`'s coarse pass (pixels; 0: off) [default: the detector's
    /// `coarse_min_px`, else off]; --calibrate writes it into the detector
    #[arg(long, value_name = "PX", requires = "eval")]
    pub coarse: Option<f32>,
    /// Use at most this many training frames (0: all)
    #[arg(value_parser = whole::<usize>, long, default_value_t = 0)]
    pub max_frames: usize,
    /// Ignore the fish too faint for the renderer to label (neither fish nor water) instead of training them as water
    #[arg(long)]
    pub ignore_faint: bool,
    /// Write OUT/checkpoint (weights, Adam's state, the crop sampler's) every this many steps and
    /// whenever the run stops early (0: only then)
    #[arg(long, default_value_t = TrainConfig::default().checkpoint_every)]
    pub checkpoint_every: usize,
    /// Continue the run of OUT/checkpoint (same settings and data; --minutes may differ): a
    /// killed or --minutes-limited run ends as one run would have
    #[arg(long, conflicts_with = "eval")]
    pub resume: bool,
    /// No progress lines
    #[arg(long)]
    pub quiet: bool,
    /// Do not train: score this detector on the val split of --data (mAP50, count error per clip)
    #[arg(long, value_name = "X.onnx")]
    pub eval: Option<PathBuf>,
    /// With --eval: let these val frames choose the confidence (not the detector's) and write
    /// OUT/detector.onnx, the detector with that confidence as `count`'s default
    #[arg(long, requires = "eval")]
    pub calibrate: bool,
}

pub fn run(args: &TrainDetectorArgs) -> Result<()> {
    if args.steps == 0 || args.batch == 0 {
        bail!("--steps and --batch must be at least 1");
    }
    let mut cfg = TrainConfig {
        steps: args.steps,
        minutes: args.minutes,
        batch: args.batch,
        crop: args.crop,
        lr: args.lr,
        base: args.base,
        stride: args.stride,
        wide: args.wide,
        seed: args.seed,
        half_share: args.half_share,
        max_frames: args.max_frames,
        faint_as_water: !args.ignore_faint,
        checkpoint_every: args.checkpoint_every,
        resume: args.resume,
        ..TrainConfig::default()
    };
    cfg.count.view_fov_deg = args.view_fov;
    cfg.count.view_size = args.view_size;
    cfg.count.iou = args.iou;
    cfg.count.validate()?;
    cfg.check()?;
    let _lock = deepfoids_experiments::lock_dir(&args.out)?;
    let t = Instant::now();
    let data = load_data(&args.data, &cfg.count, cfg.max_frames)?;
    println!(
        "data: {} train frames ({} fish), {} val frames ({} fish) from {} folders, loaded in {:.1} s",
        data.train.len(),
        data.train.iter().map(|s| s.boxes.len()).sum::<usize>(),
        data.val.len(),
        data.val.iter().map(|s| s.boxes.len()).sum::<usize>(),
        args.data.len(),
        t.elapsed().as_secs_f64()
    );
    if let Some(onnx) = &args.eval {
        print!(
            "{}",
            score_detector(
                onnx,
                &data.val,
                &cfg.count,
                &args.out,
                args.calibrate,
                args.coarse
            )?
        );
        return Ok(());
    }
    let quiet = args.quiet;
    let r = train(&data, &cfg, &args.out, |line| {
        if !quiet {
            println!("{line}");
        }
    })?;
    println!(
        "{} steps in {:.0} s; {} parameters, ONNX {:.2} MB; mAP50 {}; written to {}",
        r.steps,
        r.seconds,
        r.parameters,
        r.onnx_bytes as f64 / 1e6,
        r.map50
            .map_or("not measured (no val frames)".into(), |m| format!("{m:.3}")),
        args.out.join("detector.onnx").display()
    );
    Ok(())
}
