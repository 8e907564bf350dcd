//! ONNX detectors run through tract, in two formats.
//!
//! * **Ours** (`deepfoids train-detector`, [`crate::model`]): input `image`
//!   `[1, 3, H, W]`, RGB in [0, 1]; outputs `heatmap` `[1, 1, H/s, W/s]`
//!   (a fish centre's probability per cell, after a sigmoid) and `boxes`
//!   `[1, 4, H/s, W/s]` = (offset x, offset y of the centre inside the cell in
//!   cells, ln(width/s), ln(height/s)); the stride `s` is in the metadata
//!   (`stride`, default 8). A detection is a cell whose heatmap is at least
//!   the confidence and at least each of its 8 neighbours (CenterNet's 3 × 3
//!   max-pool peak), at `((x + offset_x)·s, (y + offset_y)·s)`.
//! * **YOLOv8** (an Ultralytics export, `yolo export format=onnx`): input
//!   `[1, 3, S, S]` RGB in [0, 1], one output `[1, 4 + classes, anchors]`:
//!   per anchor `cx, cy, w, h` in input pixels, then one score per class
//!   (already sigmoided); the confidence is the largest class score. Ours are
//!   one-class; every class counts as a fish.
//!
//! A window is fed at the model's fixed input size if it has one (resized
//! bilinearly, boxes scaled back), else at its own size.
//!
//! Our graph begins with the input's local contrast (two 31-px average pools
//! per moment). [`Detector::load`] cuts it off and the caller feeds the
//! network [`local_contrast`] planes instead, computed once per view with
//! running sums ([`Detector::cuts_local_contrast`]); tract pooled every
//! overlapping window again, which cost 40 % of the frame rate.
//! [`Detector::load_as_exported`] keeps the graph whole (its parity test).

use crate::boxes::Detection;
use crate::error::{CountError, Result};
use crate::model::{NORM_EPS, NORM_KERNEL};
use crate::preprocess::local_contrast;
use deepfoids_onnx::runtime::{read_metadata, why_not_onnx};
use image::RgbImage;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use tract_onnx::prelude::*;

type Plan = Arc<TypedRunnableModel>;

/// Which output layout a detector has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DetectorFormat {
    /// Our heatmap + boxes network, with its output stride.
    Ours { stride: u32 },
    /// `[1, 4 + classes, anchors]`.
    YoloV8 { classes: usize },
}

/// A loaded detector.
pub struct Detector {
    plan: Plan,
    pub format: DetectorFormat,
    /// The input side the plan runs at.
    pub input: u32,
    pub path: PathBuf,
    pub metadata: HashMap<String, String>,
    /// `Some((k, ε))` when the graph's own local contrast was cut off at load:
    /// the network then takes [`local_contrast`] planes, not pixels.
    pub cuts_local_contrast: Option<(usize, f32)>,
}

/// The name of the last node of our graph's local contrast (`crate::export`).
const NORM_OUT: &str = "norm.out";

fn shape_text(s: &[Option<usize>]) -> String {
    let d: Vec<String> = s
        .iter()
        .map(|d| d.map_or("?".into(), |v| v.to_string()))
        .collect();
    format!("[{}]", d.join(", "))
}

impl Detector {
    /// The metadata entry `key` parsed as `T`, if it is there and parses.
    pub fn meta<T: std::str::FromStr>(&self, key: &str) -> Option<T> {
        self.metadata.get(key).and_then(|v| v.parse().ok())
    }

    /// Load `path`, running windows of `window` pixels (unless the model
    /// fixes its input). Ours loses its local contrast (see the module doc).
    pub fn load(path: &Path, window: u32) -> Result<Self> {
        Self::load_graph(path, window, true)
    }

    /// [`Detector::load`] with the graph exactly as exported.
    pub fn load_as_exported(path: &Path, window: u32) -> Result<Self> {
        Self::load_graph(path, window, false)
    }

    fn load_graph(path: &Path, window: u32, cut_norm: bool) -> Result<Self> {
        if !path.is_file() {
            return Err(CountError::Missing {
                path: path.to_path_buf(),
            });
        }
        let bytes = std::fs::read(path).map_err(CountError::io(path))?;
        let not_onnx = |e: &dyn std::fmt::Display| CountError::NotOnnx {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let mut model = tract_onnx::onnx()
            .model_for_read(&mut bytes.as_slice())
            .map_err(|e| CountError::NotOnnxFile {
                path: path.to_path_buf(),
                why: why_not_onnx(&bytes, &e, ""),
            })?;
        let metadata = read_metadata(&bytes);
        let ours = metadata.get("format").map(String::as_str) == Some(crate::export::FORMAT);
        let cuts_local_contrast = match model.node_id_by_name(NORM_OUT) {
            Ok(norm) if cut_norm && ours => {
                // The network's first layers read the input itself instead.
                let image = model.input_outlets().map_err(|e| not_onnx(&e))?[0];
                let readers = model.node(norm).outputs[0].successors.clone();
                for inlet in readers {
                    model.add_edge(image, inlet).map_err(|e| not_onnx(&e))?;
                }
                Some((NORM_KERNEL, NORM_EPS))
            }
            _ => None,
        };
        let fixed = model
            .input_fact(0)
            .map_err(|e| not_onnx(&e))?
            .shape
            .as_concrete_finite()
            .ok()
            .flatten();
        let input = match fixed.as_deref() {
            Some([1, 3, h, w]) if h == w => *h as u32,
            _ => window,
        };
        let n = input as usize;
        model
            .set_input_fact(
                0,
                InferenceFact::dt_shape(f32::datum_type(), tvec![1, 3, n, n]),
            )
            .map_err(|e| not_onnx(&e))?;
        let names: Vec<String> = model
            .output_outlets()
            .map_err(|e| not_onnx(&e))?
            .iter()
            .map(|o| {
                model
                    .outlet_label(*o)
                    .map_or_else(|| model.node(o.node).name.clone(), str::to_string)
            })
            .collect();
        let typed = model.into_typed().map_err(|e| CountError::Runtime {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let shapes: Vec<Vec<Option<usize>>> = (0..names.len())
            .map(|i| {
                typed
                    .output_fact(i)
                    .map(|f| {
                        f.shape
                            .iter()
                            .map(|d| d.to_i64().ok().map(|v| v as usize))
                            .collect()
                    })
                    .unwrap_or_default()
            })
            .collect();
        let outputs = names
            .iter()
            .zip(&shapes)
            .map(|(n, s)| format!("`{n}` {}", shape_text(s)))
            .collect::<Vec<_>>()
            .join(", ");
        let wrong = || CountError::WrongOutputs {
            path: path.to_path_buf(),
            outputs: outputs.clone(),
        };
        let pos = |n: &str| names.iter().position(|x| x == n);
        let format = match (pos("heatmap"), pos("boxes")) {
            (Some(0), Some(1)) => {
                let ok = |s: &[Option<usize>], c: usize| {
                    s.len() == 4 && s[0] == Some(1) && s[1] == Some(c)
                };
                if !(ok(&shapes[0], 1) && ok(&shapes[1], 4)) {
                    return Err(wrong());
                }
                let stride = metadata
                    .get("stride")
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(8);
                DetectorFormat::Ours { stride }
            }
            _ if names.len() == 1 => match shapes[0].as_slice() {
                [Some(1), Some(c), Some(_)] if *c > 4 => DetectorFormat::YoloV8 { classes: c - 4 },
                _ => return Err(wrong()),
            },
            _ => return Err(wrong()),
        };
        let plan = typed
            .into_optimized()
            .and_then(|m| m.into_runnable())
            .map_err(|e| CountError::Runtime {
                path: path.to_path_buf(),
                message: e.to_string(),
            })?;
        Ok(Self {
            plan,
            format,
            input,
            path: path.to_path_buf(),
            metadata,
            cuts_local_contrast,
        })
    }

    /// Detections in a window crop (crop pixels), confidence ≥ `conf`.
    pub fn detect(&self, crop: &RgbImage, conf: f32) -> Result<Vec<Detection>> {
        let (cw, ch) = crop.dimensions();
        let resized;
        let img = if cw != self.input || ch != self.input {
            resized = image::imageops::resize(
                crop,
                self.input,
                self.input,
                image::imageops::FilterType::Triangle,
            );
            &resized
        } else {
            crop
        };
        let dets = self.detect_input(self.input_of(img), conf)?;
        let k = cw as f32 / self.input as f32;
        Ok(dets.iter().map(|d| d.scaled_shifted(k, 0.0, 0.0)).collect())
    }

    /// The network's input for an image of the input's size: its pixels in
    /// [0, 1], or their local contrast where the graph's own was cut off.
    pub fn input_of(&self, img: &RgbImage) -> Vec<f32> {
        match self.cuts_local_contrast {
            Some((k, eps)) => local_contrast(img, k, eps),
            None => to_chw(img),
        }
    }

    /// The local contrast of a whole view, to cut `window`-pixel windows
    /// from ([`crate::windows::crop_planes`]) instead of computing it per
    /// window: `None` unless this detector's graph had its own local contrast
    /// cut off and the windows reach the network at their own size (a window
    /// resampled to the input needs the contrast of the resampled pixels).
    pub fn view_contrast(&self, view: &RgbImage, window: u32) -> Option<Vec<f32>> {
        self.cuts_local_contrast
            .filter(|_| self.input == window)
            .map(|(k, eps)| local_contrast(view, k, eps))
    }

    /// Detections (input pixels) from a `[3, input, input]` network input
    /// ([`Detector::input_of`], or a window of a view's local contrast).
    pub fn detect_input(&self, chw: Vec<f32>, conf: f32) -> Result<Vec<Detection>> {
        let n = self.input as usize;
        let input = Tensor::from_shape(&[1, 3, n, n], &chw).map_err(|e| self.runtime(e))?;
        let out = self
            .plan
            .run(tvec!(input.into()))
            .map_err(|e| self.runtime(e))?;
        let view = |k: usize| {
            out[k]
                .to_plain_array_view::<f32>()
                .map(|a| (a.shape().to_vec(), a.iter().copied().collect::<Vec<f32>>()))
                .map_err(|e| self.runtime(e))
        };
        Ok(match self.format {
            DetectorFormat::Ours { stride } => {
                let (s, heat) = view(0)?;
                let (_, boxes) = view(1)?;
                decode_ours(&heat, &boxes, s[2], s[3], stride as f32, conf)
            }
            DetectorFormat::YoloV8 { .. } => {
                let (s, o) = view(0)?;
                decode_yolov8(&o, s[1], s[2], conf)
            }
        })
    }

    /// The raw outputs (row-major) for a network input `[1, 3, input, input]`
    /// ([`Detector::input_of`]).
    pub fn run_raw(&self, chw: &[f32]) -> Result<Vec<Vec<f32>>> {
        let n = self.input as usize;
        let input = Tensor::from_shape(&[1, 3, n, n], chw).map_err(|e| self.runtime(e))?;
        let out = self
            .plan
            .run(tvec!(input.into()))
            .map_err(|e| self.runtime(e))?;
        out.iter()
            .map(|o| {
                o.to_plain_array_view::<f32>()
                    .map(|a| a.iter().copied().collect())
                    .map_err(|e| self.runtime(e))
            })
            .collect()
    }

    fn runtime(&self, e: impl std::fmt::Display) -> CountError {
        CountError::Runtime {
            path: self.path.clone(),
            message: e.to_string(),
        }
    }
}

/// RGB bytes → `[3, H, W]` floats in [0, 1].
pub fn to_chw(img: &RgbImage) -> Vec<f32> {
    let (w, h) = img.dimensions();
    let plane = (w * h) as usize;
    let mut v = vec![0f32; 3 * plane];
    for (i, p) in img.as_raw().chunks_exact(3).enumerate() {
        for c in 0..3 {
            v[c * plane + i] = p[c] as f32 / 255.0;
        }
    }
    v
}

/// Our heads (see the module doc): `heat` `[h·w]`, `boxes` `[4·h·w]`.
pub fn decode_ours(
    heat: &[f32],
    boxes: &[f32],
    h: usize,
    w: usize,
    stride: f32,
    conf: f32,
) -> Vec<Detection> {
    let plane = h * w;
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let p = heat[y * w + x];
            if p < conf {
                continue;
            }
            let peak = (y.saturating_sub(1)..(y + 2).min(h))
                .all(|yy| (x.saturating_sub(1)..(x + 2).min(w)).all(|xx| heat[yy * w + xx] <= p));
            if !peak {
                continue;
            }
            let b = |c: usize| boxes[c * plane + y * w + x];
            let (cx, cy) = ((x as f32 + b(0)) * stride, (y as f32 + b(1)) * stride);
            let (bw, bh) = (b(2).min(8.0).exp() * stride, b(3).min(8.0).exp() * stride);
            out.push(Detection::from_centre(cx, cy, bw, bh, p));
        }
    }
    out
}

/// A YOLOv8 output `[channels = 4 + classes, anchors]`, row-major.
pub fn decode_yolov8(out: &[f32], channels: usize, anchors: usize, conf: f32) -> Vec<Detection> {
    let at = |c: usize, a: usize| out[c * anchors + a];
    (0..anchors)
        .filter_map(|a| {
            let score = (4..channels).map(|c| at(c, a)).fold(f32::MIN, f32::max);
            (score >= conf)
                .then(|| Detection::from_centre(at(0, a), at(1, a), at(2, a), at(3, a), score))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 × 4 heatmap with peaks 0.9 at (1, 1) and 0.6 at (3, 2); 0.7 at
    /// (0, 1), next to the 0.9, is no peak; stride 8. Boxes at (1, 1): offset (0.5, 0.25),
    /// ln size (ln 2, 0) → centre (12, 10), 16 × 8.
    #[test]
    fn ours_decodes_peaks_by_hand() {
        let (h, w) = (3, 4);
        #[rustfmt::skip]
        let heat = vec![
            0.1, 0.2, 0.1, 0.0,
            0.7, 0.9, 0.2, 0.1,
            0.1, 0.2, 0.1, 0.6,
        ];
        let mut boxes = vec![0f32; 4 * h * w];
        let i = w + 1;
        boxes[i] = 0.5;
        boxes[h * w + i] = 0.25;
        boxes[2 * h * w + i] = 2f32.ln();
        let d = decode_ours(&heat, &boxes, h, w, 8.0, 0.5);
        assert_eq!(d.len(), 2);
        let a = d[0];
        assert!(
            (a.x0 - 4.0).abs() < 1e-5 && (a.x1 - 20.0).abs() < 1e-5,
            "{a:?}"
        );
        assert!(
            (a.y0 - 6.0).abs() < 1e-5 && (a.y1 - 14.0).abs() < 1e-5,
            "{a:?}"
        );
        assert_eq!(d[1].score, 0.6);
        // Centre of cell (3, 2) with zero offsets: (24, 16), 8 × 8.
        assert!((d[1].x0 - 20.0).abs() < 1e-5 && (d[1].y0 - 12.0).abs() < 1e-5);
        assert_eq!(decode_ours(&heat, &boxes, h, w, 8.0, 0.95).len(), 0);
    }

    /// Two classes, three anchors: anchor 0 scores (0.2, 0.8), anchor 1 (0.4,
    /// 0.3), anchor 2 (0.9, 0.1); at 0.5 anchors 0 and 2 pass.
    #[test]
    fn yolov8_decodes_by_hand() {
        #[rustfmt::skip]
        let out = vec![
            10.0, 50.0, 100.0, // cx
            20.0, 60.0, 110.0, // cy
            4.0, 6.0, 8.0,     // w
            2.0, 4.0, 6.0,     // h
            0.2, 0.4, 0.9,     // class 0
            0.8, 0.3, 0.1,     // class 1
        ];
        let d = decode_yolov8(&out, 6, 3, 0.5);
        assert_eq!(d.len(), 2);
        assert_eq!(
            (d[0].x0, d[0].y0, d[0].x1, d[0].y1, d[0].score),
            (8.0, 19.0, 12.0, 21.0, 0.8)
        );
        assert_eq!((d[1].x0, d[1].y1, d[1].score), (96.0, 113.0, 0.9));
    }
}
