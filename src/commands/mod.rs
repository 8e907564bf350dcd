//! One module per command, each with its own options.

pub mod bench;
pub mod compare;
pub mod count;
pub mod eval;
pub mod export;
pub mod image_stats;
pub mod pipeline;
pub mod quickstart;
pub mod render;
pub mod replay;
pub mod reproduce;
pub mod scenes;
pub mod sensor_view;
pub mod simulate;
pub mod train;
pub mod train_detector;
