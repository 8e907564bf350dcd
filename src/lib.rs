//! The `deepfoids` command line's commands. Everything simulated or learned
//! lives in the library crates (`deepfoids-env`, `deepfoids-sensors`); this
//! crate parses arguments, drives the loops, and writes files and plots.

pub mod bounds;
pub mod cli;
pub mod clip;
pub mod commands;
pub mod io;
pub mod plot;
pub mod pretrained;
pub mod report;
