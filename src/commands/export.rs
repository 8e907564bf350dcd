//! `deepfoids export`: a trained policy as an ONNX file with Unity ML-Agents'
//! interface (see `deepfoids_onnx::export`).

use crate::cli::ExportArgs;
use anyhow::{Result, bail};
use burn::prelude::*;
use deepfoids_onnx::{Head, Metadata, export_actor, export_policy};
use deepfoids_ppo::checkpoint::{RunState, policy_dir};
use deepfoids_ppo::model::{ActorCriticConfig, BodyConfig};
use deepfoids_ppo::train::load_weights;

pub fn run(args: &ExportArgs) -> Result<()> {
    let dir = policy_dir(&args.run, args.checkpoint)?;
    let state = RunState::load(&dir)?;
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
    let dev = Device::flex();
    let meta = Metadata {
        species: behaviour.species.clone(),
        behaviour: behaviour.name.clone(),
        scene: state.scene.clone(),
        algorithm: state.algo.clone(),
        training_step: behaviour.agent_steps,
        run: state.run_id.clone(),
    };
    let bytes = match state.algo.as_str() {
        "sac" => {
            let extra = deepfoids_sac::train::SacExtra::load(&dir)?;
            let cfg = deepfoids_sac::train::net_config(
                state.hidden,
                state.layers,
                extra.log_std_bounds,
                deepfoids_ppo::Backend::Flex,
            );
            let actor = deepfoids_sac::policy::load_actor(
                &dir,
                &state,
                &behaviour.name,
                &behaviour.species,
                cfg.init_actor(&dev),
            )?;
            export_policy(
                &actor.body,
                Head::Squashed {
                    mean: &actor.mean,
                    log_std: &actor.log_std,
                    bounds: extra.log_std_bounds,
                },
                &meta,
            )
        }
        _ => {
            let cfg = ActorCriticConfig::new()
                .with_body(
                    BodyConfig::new()
                        .with_hidden(state.hidden)
                        .with_layers(state.layers),
                )
                .with_init_log_std(state.init_log_std);
            let model = load_weights(
                &dir,
                &state,
                &behaviour.name,
                &behaviour.species,
                cfg.init(&dev),
            )?;
            export_actor(&model, &meta)
        }
    };
    crate::io::write_atomic(&args.out, &bytes)?;
    println!(
        "wrote {} ({} bytes, ONNX opset {}): {} policy of {} ({}), step {}",
        args.out.display(),
        bytes.len(),
        deepfoids_onnx::export::OPSET,
        meta.algorithm,
        meta.behaviour,
        meta.scene,
        meta.training_step
    );
    Ok(())
}
