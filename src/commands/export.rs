//! `deepfoids export`: a trained policy as an ONNX file with Unity ML-Agents'
//! interface (see `deepfoids_learn::onnx`). Runs also write one per behaviour
//! into their `final/` folder.

use crate::cli::ExportArgs;
use anyhow::{Result, bail};
use deepfoids_learn::checkpoint::{RunState, policy_dir};
use deepfoids_learn::onnx::{Metadata, OPSET};

pub fn run(args: &ExportArgs) -> Result<()> {
    let dir = policy_dir(&args.run, args.checkpoint)?;
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
    let meta = Metadata {
        species: behaviour.species.clone(),
        behaviour: behaviour.name.clone(),
        scene: state.scene.clone(),
        algorithm: state.algo.as_str().into(),
        training_step: behaviour.agent_steps,
        run: state.run_id.clone(),
    };
    let bytes = super::load_actor(&dir, &state, behaviour)?.onnx(&meta);
    crate::io::write_atomic(&args.out, &bytes)?;
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
