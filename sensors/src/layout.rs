//! The shape of a frame and of a stacked observation (SPEC §5): what the
//! sensor writes and the byte format packs, each in its own module.

/// Azimuth columns (W).
pub const AZ_CELLS: usize = 34;
/// Elevation rows (H).
pub const EL_CELLS: usize = 20;
/// Channels of one frame.
pub const CHANNELS: usize = 6;
/// Frames stacked into one observation.
pub const STACK: usize = 3;
/// Channels of a stacked observation.
pub const STACKED_CHANNELS: usize = CHANNELS * STACK;
/// Cells of one frame.
pub const CELLS: usize = AZ_CELLS * EL_CELLS;
/// Floats of one frame, `[6, 20, 34]`.
pub const FRAME_LEN: usize = CHANNELS * CELLS;
/// Floats of one stacked observation, `[18, 20, 34]`.
pub const STACKED_LEN: usize = STACK * FRAME_LEN;
