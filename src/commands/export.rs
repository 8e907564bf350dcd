//! `deepfoids export`: a trained policy as an ONNX file with Unity ML-Agents'
//! interface (see `deepfoids_learn::onnx`). Runs also write one per behaviour
//! into their `final/` folder.

use crate::args::whole;
use anyhow::{Result, bail};
use clap::Args;
use deepfoids_experiments::load_actor;
use deepfoids_learn::checkpoint::{RunState, latest_checkpoint, policy_dir};
use deepfoids_learn::onnx::OPSET;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Run folder
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,
    /// Export this checkpoint step instead of the final policy
    #[arg(value_parser = whole::<u64>, long, value_name = "STEP")]
    pub checkpoint: Option<u64>,
    /// Export the newest checkpoint (a run without a final policy yet)
    #[arg(long, conflicts_with = "checkpoint")]
    pub latest: bool,
    /// Behaviour to export (required when the run has several)
    #[arg(long, value_name = "NAME")]
    pub behaviour: Option<String>,
    /// Output file
    #[arg(long, default_value = "policy.onnx", value_name = "FILE")]
    pub out: PathBuf,
}

pub fn run(args: &ExportArgs) -> Result<()> {
    let step = match args.latest {
        true => Some(latest_checkpoint(&args.run)?),
        false => args.checkpoint,
    };
    let dir = policy_dir(&args.run, step)?;
    let state = RunState::load(&dir)?;
    state.check_layout(&dir)?;
    let names: Vec<&str> = state.behaviours.iter().map(|b| b.name.as_str()).collect();
    let behaviour = match (&args.behaviour, state.behaviours.as_slice()) {
        (Some(name), _) => match state.behaviour(name) {
            Some(b) => b,
            None => bail!(
                "run {} has no behaviour `{name}`; it has: {}",
                args.run.display(),
                names.join(", ")
            ),
        },
        (None, [only]) => only,
        (None, _) => bail!(
            "run {} has several behaviours; choose one with --behaviour: {}",
            args.run.display(),
            names.join(", ")
        ),
    };
    let meta = state.onnx_metadata(&behaviour.species, &behaviour.name, behaviour.agent_steps);
    let bytes = load_actor(&dir, &state, behaviour)?.onnx(&meta);
    deepfoids_io::write_atomic(&args.out, &bytes)?;
    println!(
        "wrote {} ({} bytes, ONNX opset {OPSET}): {} policy of {} ({}), step {}",
        args.out.display(),
        bytes.len(),
        meta.algorithm,
        meta.behaviour,
        meta.scene,
        meta.training_step
    );
    Ok(())
}
