//! An exported policy driving scenes through tract (pure-Rust ONNX runtime).

use deepfoids_env::{Env, GridFormat, Policy, PolicyError, VECTOR_OBS};
use deepfoids_sensors::{AZ_CELLS, EL_CELLS, STACKED_CHANNELS};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use tract_onnx::prelude::*;

type Plan = Arc<TypedRunnableModel>;

/// What went wrong with an ONNX policy; each message names the file. (The
/// underlying error is part of the message, not a `source`, so that one
/// line says it all wherever it is printed.)
#[derive(Debug, thiserror::Error)]
pub enum OnnxError {
    #[error("cannot read {}: {error}", path.display())]
    Read {
        path: PathBuf,
        error: std::io::Error,
    },
    /// The file is no ONNX protobuf at all (a text file, say).
    #[error("{} is not an ONNX model ({why})", path.display())]
    NotOnnx { path: PathBuf, why: String },
    #[error("{} is not a loadable ONNX model: {error}", path.display())]
    Unloadable { path: PathBuf, error: TractError },
    #[error("{} has no output `{name}` (outputs: {})", path.display(), outputs.join(", "))]
    MissingOutput {
        path: PathBuf,
        name: String,
        outputs: Vec<String>,
    },
    #[error("tract cannot prepare {}: {error}", path.display())]
    Prepare { path: PathBuf, error: TractError },
    /// Running the model on a batch failed (wrong sizes, or tract's error).
    #[error("{}: {error}", path.display())]
    Run { path: PathBuf, error: TractError },
    #[error("{} is a {species} policy; scene {scene} also holds {}", path.display(), others.join(", "))]
    WrongSpecies {
        path: PathBuf,
        species: String,
        scene: String,
        others: Vec<String>,
    },
}

pub type Result<T, E = OnnxError> = std::result::Result<T, E>;

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

/// Why `bytes` did not decode as an ONNX protobuf, for a person: an empty or
/// text file is called so (tract says only "Reading proto model"); `writer`
/// ends the text file's case (e.g. ", as `deepfoids export` writes").
pub fn why_not_onnx(bytes: &[u8], error: &TractError, writer: &str) -> String {
    if bytes.is_empty() {
        "the file is empty".into()
    } else if std::str::from_utf8(bytes).is_ok_and(|t| !t.contains('\0')) {
        format!("it is a text file; an ONNX model is a binary protobuf{writer}")
    } else {
        format!("{error:#}")
    }
}

impl OnnxPolicy {
    pub fn load(path: &Path, stochastic: bool) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|error| OnnxError::Read {
            path: path.to_path_buf(),
            error,
        })?;
        let inference = tract_onnx::onnx()
            .model_for_read(&mut bytes.as_slice())
            .map_err(|e| OnnxError::NotOnnx {
                path: path.to_path_buf(),
                why: why_not_onnx(&bytes, &e, ", as `deepfoids export` writes"),
            })?;
        let not_onnx = |error| OnnxError::Unloadable {
            path: path.to_path_buf(),
            error,
        };
        let names: Vec<String> = inference
            .output_outlets()
            .map_err(not_onnx)?
            .iter()
            .map(|o| {
                inference
                    .outlet_label(*o)
                    .map_or_else(|| inference.node(o.node).name.clone(), str::to_string)
            })
            .collect();
        let find = |n: &str| {
            names
                .iter()
                .position(|x| x == n)
                .ok_or_else(|| OnnxError::MissingOutput {
                    path: path.to_path_buf(),
                    name: n.to_string(),
                    outputs: names.clone(),
                })
        };
        let (deterministic_output, sampled_output) = (
            find("deterministic_continuous_actions")?,
            find("continuous_actions")?,
        );
        let plan = inference
            .into_optimized()
            .and_then(|m| m.into_runnable())
            .map_err(|error| OnnxError::Prepare {
                path: path.to_path_buf(),
                error,
            })?;
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
        self.run_tract(grids, vectors, n)
            .map_err(|error| OnnxError::Run {
                path: self.path.clone(),
                error,
            })
    }

    fn run_tract(&self, grids: &[f32], vectors: &[f32], n: usize) -> TractResult<Vec<f32>> {
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
pub fn read_metadata(bytes: &[u8]) -> HashMap<String, String> {
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

/// The ModelProto `bytes` (read from `path`) with the metadata entries `set`
/// put in: an entry of the same key is replaced, a new key is appended, and
/// the rest of the file (graph, weights, other entries) is re-encoded as
/// decoded with tract's message types, which declare the whole of onnx.proto.
pub fn with_metadata(bytes: &[u8], path: &Path, set: &[(String, String)]) -> Result<Vec<u8>> {
    use prost::Message;
    let mut model = tract_onnx::pb::ModelProto::decode(bytes).map_err(|e| OnnxError::NotOnnx {
        path: path.to_path_buf(),
        why: e.to_string(),
    })?;
    for (key, value) in set {
        match model.metadata_props.iter_mut().find(|p| &p.key == key) {
            Some(p) => p.value.clone_from(value),
            None => model
                .metadata_props
                .push(tract_onnx::pb::StringStringEntryProto {
                    key: key.clone(),
                    value: value.clone(),
                }),
        }
    }
    Ok(model.encode_to_vec())
}

impl Policy for OnnxPolicy {
    fn name(&self) -> String {
        self.path
            .file_name()
            .map_or_else(|| "onnx".into(), |n| n.to_string_lossy().into_owned())
    }

    /// The ONNX graph reads the grids as floats.
    fn grid_format(&self) -> Option<GridFormat> {
        Some(GridFormat::Floats)
    }

    fn act(&mut self, env: &Env, actions: &mut [Vec<f32>]) -> Result<(), PolicyError> {
        for (b, batch) in env.output().behaviours.iter().enumerate() {
            if !env.awaiting(b) {
                continue;
            }
            let grids = batch.observations().to_dense();
            let a = self
                .run(&grids, &batch.vectors, batch.n_agents)
                .map_err(|e| PolicyError::Inference(e.to_string()))?;
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
            return Err(OnnxError::WrongSpecies {
                path: policy.path.clone(),
                species: species.clone(),
                scene: env.scene().id.clone(),
                others: others.into_iter().map(str::to_string).collect(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost::Message;
    use tract_onnx::pb::{GraphProto, ModelProto, StringStringEntryProto};

    /// Entries a=1, b=2 and a graph named "g"; putting in b=3 and c=4
    /// replaces b in place, appends c, and keeps a and the graph.
    #[test]
    fn metadata_is_replaced_by_key_and_the_rest_kept() {
        let entry = |k: &str, v: &str| StringStringEntryProto {
            key: k.into(),
            value: v.into(),
        };
        let model = ModelProto {
            ir_version: 8,
            graph: Some(GraphProto {
                name: "g".into(),
                ..Default::default()
            }),
            metadata_props: vec![entry("a", "1"), entry("b", "2")],
            ..Default::default()
        };
        let set = [("b".to_string(), "3".to_string()), ("c".into(), "4".into())];
        let out = with_metadata(&model.encode_to_vec(), Path::new("m.onnx"), &set).unwrap();
        let back = ModelProto::decode(out.as_slice()).unwrap();
        let props: Vec<(&str, &str)> = back
            .metadata_props
            .iter()
            .map(|p| (p.key.as_str(), p.value.as_str()))
            .collect();
        assert_eq!(props, [("a", "1"), ("b", "3"), ("c", "4")]);
        assert_eq!(
            (back.ir_version, back.graph.unwrap().name.as_str()),
            (8, "g")
        );
        let err = with_metadata(b"not onnx", Path::new("x.onnx"), &set).unwrap_err();
        assert!(
            err.to_string().contains("x.onnx is not an ONNX model"),
            "{err}"
        );
    }
}
