//! The fish's eyes: an angular grid vision sensor (SPEC §5) and the geometry
//! queries it needs — planes and obstacles to cast rays against, and a uniform
//! spatial grid to find neighbours.
//!
//! This crate knows nothing of fish dynamics or learning; it takes positions,
//! orientations and shapes and writes flat `f32` buffers, or the same frames
//! as bytes ([`frames`]).

pub mod frames;
pub mod geometry;
pub mod grid_sensor;
pub mod layout;
pub mod spatial;

pub use frames::{FRAME_BYTES, FrameCell, GridFormat, GridsRef, STACK_BYTES};
pub use geometry::{Boundary, BoundaryKind, Obstacle, Plane};
pub use grid_sensor::{
    Channel, Frame, GridSensor, SPHERE_BATCH, SeenKind, SphereBatch, mirror_columns, push_frame,
    reset_stack,
};
pub use layout::{
    AZ_CELLS, CELLS, CHANNELS, EL_CELLS, FRAME_LEN, STACK, STACKED_CHANNELS, STACKED_LEN,
};
pub use spatial::SpatialGrid;
