//! Replays of a school for the browser (issue 16).
//!
//! 1. [`recording`]: every fish at every frame — position, heading, speed,
//!    respawns, chases and the reward terms of its latest decision — quantised
//!    as the viewer reads it, plus P and M over time. [`EnvRecorder`] takes it
//!    from a running [`deepfoids_env::Env`]; [`trajectories`] reads the CSV of
//!    `deepfoids simulate`.
//! 2. [`encode`]: the recording as typed sections of one byte buffer, gzipped.
//! 3. [`html`]: one self-contained HTML page — the viewer (`viewer/`), the
//!    recording and three.js (`vendor/three/`, from npm, embedded at build
//!    time), nothing fetched at view time.
//! 4. [`clip`]: the top and side views as an animated GIF, for papers and
//!    slides.

pub mod clip;
pub mod encode;
pub mod html;
pub mod recording;
pub mod trajectories;

pub use clip::{ClipError, GifView, check_gif, write_gif};
pub use html::{PageSize, page};
pub use recording::{EnvRecorder, Info, Recording, ReplayError, stride};
pub use trajectories::from_trajectories;
