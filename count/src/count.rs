//! The counting pipeline of Fig. 4.5: pre-process → windows → detector →
//! one NMS → per-frame count → the maximum over frames (the thesis' MAX).

use crate::boxes::{Detection, cut_by_inner_edge, nms};
use crate::detector::Detector;
use crate::error::{CountError, Result};
use crate::frames::Frames;
use crate::preprocess::{InputCamera, PerspectiveView, median_blur};
use crate::windows::{crop, crop_planes, thesis_count, windows};
use deepfoids_io::write_atomic;
use image::RgbImage;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;

/// Everything `count` can be told; every field has its default.
#[derive(Clone, Debug, Serialize)]
pub struct CountConfig {
    /// What filmed the input; fisheye 235° (the thesis' Kodak 4KVR360).
    #[serde(skip)]
    pub camera: InputCamera,
    /// Field of view of the corrected perspective view (degrees); 120.
    pub view_fov_deg: f32,
    /// Side of the corrected view (pixels); 832 = 2 windows, so 3 × 3 windows.
    pub view_size: u32,
    /// Median-blur kernel (pixels, odd; 1 = off); 3.
    pub median: u32,
    /// Sliding window side (pixels); 416 (§4.4.2).
    pub window: u32,
    /// Window step (pixels); half the window, 208.
    pub step: u32,
    /// Least confidence of a detection; 0.5 (§4.4.2).
    pub conf: f32,
    /// IoU above which NMS suppresses the weaker box; 0.5.
    pub iou: f32,
    /// A box within this many pixels of an inner window edge counts as cut by it; 3.
    pub edge_margin: f32,
    /// The coarse pass: the view is also searched at half its size, and of
    /// what that finds the boxes whose longer side (in the view) is at least
    /// this many pixels join the NMS — fish close to the camera, longer than
    /// the detector's 135-px receptive field sees whole; 0: no coarse pass.
    pub coarse_min_px: f32,
}

impl Default for CountConfig {
    fn default() -> Self {
        Self {
            camera: InputCamera::Fisheye { fov_deg: 235.0 },
            view_fov_deg: 120.0,
            view_size: 832,
            median: 3,
            window: 416,
            step: 208,
            conf: 0.5,
            iou: 0.5,
            edge_margin: 3.0,
            coarse_min_px: 0.0,
        }
    }
}

impl CountConfig {
    /// This configuration with the view and confidence the user chose, and
    /// where they chose none (`None`) the detector's own from its metadata
    /// (the training's `view_fov_deg` and `view_size`, the `confidence` its val
    /// split chose), else the ones already here.
    pub fn with_detector_defaults(
        self,
        detector: &Detector,
        view_fov_deg: Option<f32>,
        view_size: Option<u32>,
        conf: Option<f32>,
    ) -> Self {
        Self {
            view_fov_deg: view_fov_deg
                .or_else(|| detector.meta("view_fov_deg"))
                .unwrap_or(self.view_fov_deg),
            view_size: view_size
                .or_else(|| detector.meta("view_size"))
                .unwrap_or(self.view_size),
            conf: conf
                .or_else(|| detector.meta("confidence"))
                .unwrap_or(self.conf),
            ..self
        }
    }

    /// This configuration with the coarse pass the user chose (`--coarse`),
    /// else the detector's own (`coarse_min_px` in its metadata, written by
    /// `train-detector --calibrate`), else the one already here.
    pub fn with_coarse_default(self, detector: &Detector, coarse: Option<f32>) -> Self {
        Self {
            coarse_min_px: coarse
                .or_else(|| detector.meta("coarse_min_px"))
                .unwrap_or(self.coarse_min_px),
            ..self
        }
    }

    /// Check every value; the error names it and what is allowed.
    pub fn validate(&self) -> Result<()> {
        let bad = |what, allowed, value: String| {
            Err(CountError::Value {
                what,
                allowed,
                value,
            })
        };
        if let InputCamera::Fisheye { fov_deg } = self.camera
            && !(fov_deg > 0.0 && fov_deg <= 360.0)
        {
            return bad("--fov", "in (0, 360] degrees", fov_deg.to_string());
        }
        if !(self.view_fov_deg > 1.0 && self.view_fov_deg < 179.0) {
            return bad(
                "--view-fov",
                "in (1, 179) degrees",
                self.view_fov_deg.to_string(),
            );
        }
        if !(0.0..=1.0).contains(&self.conf) {
            return bad("--conf", "in [0, 1]", self.conf.to_string());
        }
        if !(0.0..=1.0).contains(&self.iou) {
            return bad("--iou", "in [0, 1]", self.iou.to_string());
        }
        if !(self.coarse_min_px >= 0.0 && self.coarse_min_px.is_finite()) {
            return bad(
                "--coarse",
                "0 (off) or a length in pixels",
                self.coarse_min_px.to_string(),
            );
        }
        if (self.median.is_multiple_of(2) && self.median > 0) || self.median > 15 {
            return bad("--median", "odd, 1 to 15", self.median.to_string());
        }
        if !(16..=4096).contains(&self.window) || self.step == 0 || self.step > self.window {
            return bad(
                "--window/--step",
                "16 to 4096 pixels, 0 < step ≤ window",
                format!("{}/{}", self.window, self.step),
            );
        }
        if !(16..=8192).contains(&self.view_size) {
            return bad(
                "--view-size",
                "16 to 8192 pixels",
                self.view_size.to_string(),
            );
        }
        Ok(())
    }
}

/// One frame's result.
pub struct FrameResult {
    /// The image the detector saw (denoised, corrected).
    pub view: RgbImage,
    pub detections: Vec<Detection>,
    /// Windows run (and the thesis' R for the same image).
    pub windows: usize,
    pub thesis_windows: usize,
}

/// Counting with one detector.
pub struct Counter {
    pub config: CountConfig,
    pub detector: Detector,
    view: Option<PerspectiveView>,
}

impl Counter {
    pub fn new(config: CountConfig, detector: Detector) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config,
            detector,
            view: None,
        })
    }

    /// Pre-processing alone: denoise, then correct a fisheye.
    pub fn preprocess(&mut self, frame: &RgbImage) -> RgbImage {
        let c = &self.config;
        let clean = median_blur(frame, c.median);
        match c.camera {
            InputCamera::Pinhole => clean,
            InputCamera::Fisheye { fov_deg } => {
                let (w, h) = frame.dimensions();
                if self.view.as_ref().is_none_or(|v| v.source != (w, h)) {
                    self.view = Some(PerspectiveView::new(
                        w,
                        h,
                        fov_deg,
                        c.view_fov_deg,
                        c.view_size,
                    ));
                }
                self.view.as_ref().expect("made above").apply(&clean)
            }
        }
    }

    /// Detections on an already pre-processed image (its pixels).
    pub fn detect(&self, view: &RgbImage) -> Result<(Vec<Detection>, usize)> {
        let (mut found, mut n) = self.detect_at_scale(view)?;
        if self.config.coarse_min_px > 0.0 {
            let (w, h) = view.dimensions();
            let half = image::imageops::resize(
                view,
                (w / 2).max(1),
                (h / 2).max(1),
                image::imageops::FilterType::Triangle,
            );
            let (coarse, m) = self.detect_at_scale(&half)?;
            let scale = (
                w as f32 / half.width() as f32,
                h as f32 / half.height() as f32,
            );
            found.extend(coarse_boxes(coarse, scale, self.config.coarse_min_px));
            n += m;
        }
        Ok((nms(found, self.config.iou), n))
    }

    /// The detections of every window of `view` (each window's own NMS is
    /// the caller's), and how many windows.
    fn detect_at_scale(&self, view: &RgbImage) -> Result<(Vec<Detection>, usize)> {
        let c = &self.config;
        let (w, h) = view.dimensions();
        let wins = windows(w, h, c.window, c.step);
        // Our detector's local contrast, once for the whole view.
        let planes = self.detector.view_contrast(view, c.window);
        let per_window: Vec<Vec<Detection>> = wins
            .par_iter()
            .map(|&win| {
                let dets = match &planes {
                    Some(p) => self
                        .detector
                        .detect_input(crop_planes(p, (w, h), win, c.window), c.conf)?,
                    None => self.detector.detect(&crop(view, win, c.window), c.conf)?,
                };
                Ok(dets
                    .into_iter()
                    .map(|d| d.scaled_shifted(1.0, win.x as f32, win.y as f32))
                    .filter(|d| !cut_by_inner_edge(d, win, c.window, c.step, (w, h), c.edge_margin))
                    .map(|d| Detection {
                        x0: d.x0.max(0.0),
                        y0: d.y0.max(0.0),
                        x1: d.x1.min(w as f32),
                        y1: d.y1.min(h as f32),
                        ..d
                    })
                    .collect())
            })
            .collect::<Result<_>>()?;
        Ok((per_window.concat(), wins.len()))
    }

    /// One frame through the whole pipeline.
    pub fn frame(&mut self, frame: &RgbImage) -> Result<FrameResult> {
        let view = self.preprocess(frame);
        let (detections, n) = self.detect(&view)?;
        let (w, h) = view.dimensions();
        Ok(FrameResult {
            thesis_windows: thesis_count(w, h, self.config.window, self.config.step),
            view,
            detections,
            windows: n,
        })
    }
}

/// The coarse pass's detections (found on the view at half size) in the
/// view's pixels (`scale`: view over half size, per axis), keeping those
/// whose longer side is at least `min_px` there.
pub fn coarse_boxes(
    coarse: Vec<Detection>,
    (sx, sy): (f32, f32),
    min_px: f32,
) -> impl Iterator<Item = Detection> {
    coarse
        .into_iter()
        .map(move |d| Detection {
            x0: d.x0 * sx,
            y0: d.y0 * sy,
            x1: d.x1 * sx,
            y1: d.y1 * sy,
            ..d
        })
        .filter(move |d| (d.x1 - d.x0).max(d.y1 - d.y0) >= min_px)
}

/// The counts of a video and the estimates made from them.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub frames: usize,
    /// The thesis' MAX: the largest per-frame count.
    pub estimate: usize,
    pub median: f64,
    /// 90th percentile (nearest rank).
    pub p90: usize,
    pub mean: f64,
    pub counts: Vec<usize>,
}

impl Summary {
    pub fn of(counts: Vec<usize>) -> Self {
        let mut s = counts.clone();
        s.sort_unstable();
        let n = s.len();
        let median = match n {
            0 => 0.0,
            _ if n % 2 == 1 => s[n / 2] as f64,
            _ => (s[n / 2 - 1] + s[n / 2]) as f64 / 2.0,
        };
        // Nearest rank: the ⌈0.9·n⌉-th smallest.
        let p90 = if n == 0 {
            0
        } else {
            s[((0.9 * n as f64).ceil() as usize).clamp(1, n) - 1]
        };
        Self {
            frames: n,
            estimate: s.last().copied().unwrap_or(0),
            median,
            p90,
            mean: if n == 0 {
                0.0
            } else {
                s.iter().sum::<usize>() as f64 / n as f64
            },
            counts,
        }
    }

    /// The summary's last line.
    pub fn line(&self) -> String {
        format!(
            "estimate: {} fish (max over {} frames)",
            self.estimate, self.frames
        )
    }
}

/// Draw each detection's box (2 px, yellow) on `img`.
pub fn draw_boxes(img: &mut RgbImage, dets: &[Detection]) {
    let (w, h) = img.dimensions();
    let colour = image::Rgb([255, 220, 0]);
    for d in dets {
        let x0 = (d.x0.max(0.0) as u32).min(w - 1);
        let y0 = (d.y0.max(0.0) as u32).min(h - 1);
        let x1 = (d.x1.max(0.0) as u32).min(w - 1);
        let y1 = (d.y1.max(0.0) as u32).min(h - 1);
        for t in 0..2 {
            for x in x0..=x1 {
                img.put_pixel(x, (y0 + t).min(h - 1), colour);
                img.put_pixel(x, y1.saturating_sub(t), colour);
            }
            for y in y0..=y1 {
                img.put_pixel((x0 + t).min(w - 1), y, colour);
                img.put_pixel(x1.saturating_sub(t), y, colour);
            }
        }
    }
}

/// Encode an RGB image as PNG bytes.
pub fn png_bytes(img: &RgbImage) -> Vec<u8> {
    let mut buf = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut buf), image::ImageFormat::Png)
        .expect("PNG encoding of an in-memory image");
    buf
}

/// What [`run`] writes besides the summary.
#[derive(Clone, Debug, Default)]
pub struct Outputs {
    /// Folder for `counts.csv`, `summary.json` and `annotated/`.
    pub dir: Option<std::path::PathBuf>,
    /// Write every `n`-th frame annotated (0: none).
    pub annotate_every: usize,
    /// Process every `n`-th frame (1: all).
    pub frame_step: usize,
    /// Stop after this many processed frames.
    pub max_frames: Option<usize>,
}

/// Count the fish of a video or folder of frames. `progress` sees each
/// frame's index, name and count.
pub fn run(
    counter: &mut Counter,
    input: &Path,
    out: &Outputs,
    mut progress: impl FnMut(usize, &str, usize),
) -> Result<Summary> {
    let mut frames = Frames::open(input)?;
    let mut csv = String::from("frame,source,count,windows\n");
    let mut counts = Vec::new();
    let mut index = 0usize;
    if let Some(d) = &out.dir {
        std::fs::create_dir_all(d).map_err(CountError::io(d))?;
        if out.annotate_every > 0 {
            let a = d.join("annotated");
            std::fs::create_dir_all(&a).map_err(CountError::io(&a))?;
        }
    }
    while let Some((name, img)) = frames.next_frame()? {
        let i = index;
        index += 1;
        if !i.is_multiple_of(out.frame_step.max(1)) {
            continue;
        }
        if out.max_frames.is_some_and(|m| counts.len() >= m) {
            break;
        }
        let r = counter.frame(&img)?;
        let n = r.detections.len();
        csv.push_str(&format!(
            "{i},{},{n},{}\n",
            name.replace(',', "_"),
            r.windows
        ));
        counts.push(n);
        progress(i, &name, n);
        if let Some(d) = &out.dir
            && out.annotate_every > 0
            && (counts.len() - 1) % out.annotate_every == 0
        {
            let mut v = r.view;
            draw_boxes(&mut v, &r.detections);
            let p = d.join("annotated").join(format!("frame_{i:06}.png"));
            write_atomic(&p, &png_bytes(&v)).map_err(CountError::io(&p))?;
        }
    }
    let summary = Summary::of(counts);
    if let Some(d) = &out.dir {
        let p = d.join("counts.csv");
        write_atomic(&p, csv.as_bytes()).map_err(CountError::io(&p))?;
        let v = serde_json::json!({
            "input": input.display().to_string(),
            "detector": counter.detector.path.display().to_string(),
            "config": counter.config,
            "camera": format!("{:?}", counter.config.camera),
            "summary": summary,
        });
        let p = d.join("summary.json");
        write_atomic(&p, serde_json::to_string_pretty(&v).unwrap().as_bytes())
            .map_err(CountError::io(&p))?;
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts 3, 7, 5, 9, 4: max 9, median 5, p90 = the ⌈4.5⌉ = 5th smallest = 9;
    /// four frames 1, 2, 3, 4: median 2.5, p90 the 4th = 4.
    #[test]
    fn summary_by_hand() {
        let s = Summary::of(vec![3, 7, 5, 9, 4]);
        assert_eq!((s.estimate, s.median, s.p90, s.mean), (9, 5.0, 9, 5.6));
        assert_eq!(s.line(), "estimate: 9 fish (max over 5 frames)");
        let s = Summary::of(vec![1, 2, 3, 4]);
        assert_eq!((s.median, s.p90), (2.5, 4));
    }

    /// Found at half size: a 10 × 20 box at (5, 5) and a 40 × 30 one at
    /// (100, 50). In an 832 × 832 view searched at 416 × 416 (scale 2) they
    /// are 20 × 40 at (10, 10) and 80 × 60 at (200, 100); with 64 px as the
    /// least longer side only the second stays, score kept.
    #[test]
    fn coarse_boxes_by_hand() {
        let found = vec![
            Detection::from_centre(10.0, 15.0, 10.0, 20.0, 0.9),
            Detection::from_centre(120.0, 65.0, 40.0, 30.0, 0.6),
        ];
        let kept: Vec<Detection> = coarse_boxes(found.clone(), (2.0, 2.0), 64.0).collect();
        assert_eq!(kept.len(), 1);
        let d = kept[0];
        assert_eq!(
            (d.x0, d.y0, d.x1, d.y1, d.score),
            (200.0, 100.0, 280.0, 160.0, 0.6)
        );
        assert_eq!(coarse_boxes(found, (2.0, 2.0), 40.0).count(), 2);
    }
}
