//! One module per command, each with its own options.

pub mod bench;
pub mod compare;
pub mod eval;
pub mod export;
pub mod pipeline;
pub mod quickstart;
pub mod render;
pub mod replay;
pub mod reproduce;
pub mod scenes;
pub mod sensor_view;
pub mod simulate;
pub mod train;
