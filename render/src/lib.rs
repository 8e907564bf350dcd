//! The dataset renderer (SPEC §10, thesis §4.3 and Appendix A.2/A.4):
//! synthetic, perfectly labelled images of caged fish on the CPU.
//!
//! - [`mesh`]: fish meshes per species, with a tail beat.
//! - [`optics`]: water colour (Eq. A.1), Kopelevich scattering (Eq. A.2), the sun.
//! - [`camera`]: pinhole and equidistant fisheye (up to 235°).
//! - [`render`]: rasteriser with depth and id buffers, water per pixel, labels.
//! - [`setup`]: field camera set-ups, per-clip randomisation, poses from the world.
//! - [`dataset`]: YOLO, COCO, masks and per-frame JSON, written atomically.

pub mod camera;
pub mod dataset;
pub mod mesh;
pub mod optics;
pub mod render;
pub mod setup;

pub use camera::{Camera, Lens};
pub use dataset::{Dataset, DatasetError, FrameMeta, FrameWriter, ImageFormat, Split};
pub use optics::{Light, Water, WaterParams};
pub use render::{Conditions, FishLabel, FishPose, Frame, RenderConfig, Renderer};
pub use setup::{CameraKind, CameraPlacement, ClipParams, RandomRanges, TailPhases};
