//! An exported policy driving scenes through tract (pure-Rust ONNX runtime).

use anyhow::{Context, Result, bail};
use deepfoids_env::{Env, Policy, PolicyError, VECTOR_OBS};
use deepfoids_sensors::{AZ_CELLS, EL_CELLS, STACKED_CHANNELS};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use tract_onnx::prelude::*;

type Plan = Arc<TypedRunnableModel>;

/// An ONNX policy file, loaded with tract.
pub struct OnnxPolicy {
    plan: Plan,
    deterministic_output: usize,
    sampled_output: usize,
    /// Act with `continuous_actions` (sampled by the model) instead of the
    /// deterministic output.
    pub stochastic: bool,
    pub path: PathBuf,
    pub metadata: HashMap<String, String>,
}

impl OnnxPolicy {
    pub fn load(path: &Path, stochastic: bool) -> Result<Self> {
        let bytes =
            std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        let inference = tract_onnx::onnx()
            .model_for_read(&mut bytes.as_slice())
            .map_err(|e| anyhow::anyhow!("{} is not a loadable ONNX model: {e}", path.display()))?;
        let names: Vec<String> = inference
            .output_outlets()?
            .iter()
            .map(|o| {
                inference
                    .outlet_label(*o)
                    .map_or_else(|| inference.node(o.node).name.clone(), str::to_string)
            })
            .collect();
        let find = |n: &str| {
            names.iter().position(|x| x == n).with_context(|| {
                format!(
                    "{} has no output `{n}` (outputs: {})",
                    path.display(),
                    names.join(", ")
                )
            })
        };
        let (deterministic_output, sampled_output) = (
            find("deterministic_continuous_actions")?,
            find("continuous_actions")?,
        );
        let plan = inference
            .into_optimized()
            .and_then(|m| m.into_runnable())
            .map_err(|e| anyhow::anyhow!("tract cannot prepare {}: {e}", path.display()))?;
        Ok(Self {
            plan,
            deterministic_output,
            sampled_output,
            stochastic,
            path: path.to_path_buf(),
            metadata: read_metadata(&bytes),
        })
    }

    /// Actions `[n, 3]` for `n` observations (`grids` `[n, 18, 20, 34]`, `vectors` `[n, 6]`).
    pub fn run(&self, grids: &[f32], vectors: &[f32], n: usize) -> Result<Vec<f32>> {
        let g = Tensor::from_shape(&[n, STACKED_CHANNELS, EL_CELLS, AZ_CELLS], grids)?;
        let v = Tensor::from_shape(&[n, VECTOR_OBS], vectors)?;
        let out = self.plan.run(tvec!(g.into(), v.into()))?;
        let k = if self.stochastic {
            self.sampled_output
        } else {
            self.deterministic_output
        };
        Ok(out[k]
            .to_plain_array_view::<f32>()?
            .iter()
            .copied()
            .collect())
    }
}

/// `metadata_props` of a ModelProto, decoded with tract's message types (so
/// the runtime needs no exporter).
fn read_metadata(bytes: &[u8]) -> HashMap<String, String> {
    use prost::Message;
    tract_onnx::pb::ModelProto::decode(bytes)
        .map(|m| {
            m.metadata_props
                .into_iter()
                .map(|p| (p.key, p.value))
                .collect()
        })
        .unwrap_or_default()
}

impl Policy for OnnxPolicy {
    fn name(&self) -> String {
        self.path
            .file_name()
            .map_or_else(|| "onnx".into(), |n| n.to_string_lossy().into_owned())
    }

    fn act(&mut self, env: &Env, actions: &mut [Vec<f32>]) -> Result<(), PolicyError> {
        for (b, batch) in env.output().behaviours.iter().enumerate() {
            if !env.awaiting(b) {
                continue;
            }
            let a = self
                .run(&batch.grids, &batch.vectors, batch.n_agents)
                .map_err(|e| e.to_string())?;
            actions[b].clear();
            actions[b].extend_from_slice(&a);
        }
        Ok(())
    }
}

/// Check that an ONNX policy fits a scene: every behaviour must be of the file's species.
pub fn check_species(policy: &OnnxPolicy, env: &Env) -> Result<()> {
    if let Some(species) = policy.metadata.get("species") {
        let others: Vec<&str> = env
            .behaviours()
            .iter()
            .filter(|b| &b.species != species)
            .map(|b| b.name.as_str())
            .collect();
        if !others.is_empty() {
            bail!(
                "{} is a {species} policy; scene {} also holds {}",
                policy.path.display(),
                env.scene().id,
                others.join(", ")
            );
        }
    }
    Ok(())
}
