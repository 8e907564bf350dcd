//! The `deepfoids` command line: argument parsing ([`cli`], [`args`]),
//! dispatch, and what each command prints ([`commands`]). Everything simulated,
//! learned, evaluated or reproduced lives in the library crates
//! (`deepfoids-env`, `-learn`, `-ppo`, `-sac`, `-onnx`, `-render`, `-replay`
//! and `deepfoids-experiments`).

pub mod args;
pub mod cli;
pub mod commands;
