//! Counting fish in cage videos: the thesis' counting system (§4.4, Fig. 4.5)
//! on a detector trained from our own renders.
//!
//! The pipeline, in the order [`count::Counter::frame`] runs it:
//! 1. [`frames`]: a video (decoded by the system's `ffmpeg` into raw RGB) or a
//!    folder of PNG/JPEG frames.
//! 2. [`preprocess`]: median-blur denoising; a fisheye frame is corrected to
//!    a perspective view with the renderer's lens model (equidistant,
//!    `r = f·θ`, the image circle filling the shorter side).
//! 3. [`windows`]: 416 × 416 sliding windows stepped by half a window (the
//!    thesis' Eq. 4.7 gives their number R), one more flush with the far edge
//!    when the steps do not reach it.
//! 4. [`detector`]: an ONNX detector through tract on every window — ours
//!    (a heatmap and box sizes, CenterNet-style) or a YOLOv8 export.
//! 5. [`boxes`]: detections mapped back to the frame, those cut by an inner
//!    window edge dropped (the half-step overlap shows them whole in a
//!    neighbour), then one NMS over all windows.
//! 6. [`count`]: per-frame counts; the estimate is their maximum (the thesis'
//!    MAX method), with the median and the 90th percentile beside it.
//!
//! The detector is trained by [`train`] (Burn, from scratch, on `render`
//! output) on the network of [`model`], exported by [`export`] and scored by
//! [`eval`] (mAP50). [`stats`] is Fig. 4.12: black-pixel density in 16 annuli.

pub mod boxes;
pub mod count;
pub mod detector;
pub mod error;
pub mod eval;
pub mod export;
pub mod frames;
pub mod model;
pub mod preprocess;
pub mod stats;
pub mod train;
pub mod windows;

pub use boxes::Detection;
pub use count::{CountConfig, Counter, Summary};
pub use detector::{Detector, DetectorFormat};
pub use error::CountError;
pub use preprocess::{InputCamera, PerspectiveView};
