//! Run folders, checkpoints and the saved state of a run.
//!
//! ```text
//! runs/<run-id>/
//!   config.toml                   the resolved config, scene and arguments
//!   scalars.csv                   behaviour, step, tag, value (the TensorBoard scalars)
//!   tb/<behaviour>/events.*       TensorBoard event files, one folder per behaviour
//!   checkpoints/step-NNNNNNNNNN/  state.json, the algorithm's files (weights,
//!                                 optimisers, its own state), per behaviour
//!   final/                        state.json, the weights, <behaviour>.onnx
//! ```
//! Checkpoint folders appear atomically (written under a temporary name, then
//! renamed), so a kill at any moment leaves only whole checkpoints.

pub use crate::algorithm::Algorithm;
use crate::body::ENCODER_LAYOUT;
use crate::error::{LearnError, Result};
use burn::module::Module;
use deepfoids_env::Phase;
use serde::{Deserialize, Deserializer, Serialize};
use std::path::{Path, PathBuf};

/// Per-behaviour training state.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BehaviourState {
    pub name: String,
    pub species: String,
    pub size_class: String,
    /// This behaviour's own agent decisions so far (its budget counts these).
    pub agent_steps: u64,
    /// Its budget of agent decisions (ML-Agents' `max_steps`, per behaviour).
    #[serde(default)]
    pub budget: u64,
    pub updates: u64,
}

/// Everything the driver needs to continue a run, besides each algorithm's
/// own files.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunState {
    pub algo: Algorithm,
    /// The network layout ([`ENCODER_LAYOUT`]); files without it are layout 1.
    #[serde(default = "layout_1")]
    pub layout: u32,
    pub run_id: String,
    pub scene: String,
    pub phase: Phase,
    pub seed: u64,
    pub backend: String,
    /// Agent decisions so far, all behaviours.
    pub agent_steps: u64,
    /// Environment ticks so far (the exploration noise is keyed by it).
    pub ticks: u64,
    /// Environment resets so far (the env is reseeded with `seed + resets`).
    pub resets: u64,
    pub wall_seconds: f64,
    /// The runs the weights came from (transfer learning).
    #[serde(default, deserialize_with = "one_or_many")]
    pub init_from: Vec<String>,
    /// Architecture, to rebuild the networks when loading.
    pub hidden: usize,
    pub layers: usize,
    pub behaviours: Vec<BehaviourState>,
    /// The reward profile the run trained with (`rewards/<profile>/`).
    /// Runs before it was recorded here name it in their `config.toml`
    /// ([`RunState::reward_profile_of`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reward_profile: Option<String>,
}

fn layout_1() -> u32 {
    1
}

/// `null`, one string or a list (runs before issue 11 stored one `init_from`).
fn one_or_many<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Vec<String>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Many {
        One(String),
        Many(Vec<String>),
    }
    Ok(match Option::<Many>::deserialize(d)? {
        None => vec![],
        Some(Many::One(s)) => vec![s],
        Some(Many::Many(v)) => v,
    })
}

impl RunState {
    /// What an ONNX export of this run's behaviour `behaviour` (of `species`)
    /// at `training_step` records.
    pub fn onnx_metadata(
        &self,
        species: &str,
        behaviour: &str,
        training_step: u64,
    ) -> crate::onnx::Metadata {
        crate::onnx::Metadata {
            species: species.into(),
            behaviour: behaviour.into(),
            scene: self.scene.clone(),
            algorithm: self.algo.as_str().into(),
            training_step,
            run: self.run_id.clone(),
            reward_profile: self.reward_profile.clone(),
        }
    }

    /// The reward profile run folder `run` (whose state this is) trained
    /// with: the state's own record, else its `config.toml`'s
    /// `[scene] reward_profile`; `None` when neither says.
    pub fn reward_profile_of(&self, run: &Path) -> Option<String> {
        self.reward_profile.clone().or_else(|| {
            let text = std::fs::read_to_string(run.join("config.toml")).ok()?;
            let config: toml::Table = text.parse().ok()?;
            let profile = config.get("scene")?.get("reward_profile")?.as_str()?;
            Some(profile.to_string())
        })
    }

    /// Refuse to continue or reuse run `run` (whose state this is) under
    /// reward profile `want` when it trained with another: its policy learnt
    /// other rewards. `what` is the verb of the refusal ("resume", "reuse").
    pub fn check_reward_profile(&self, run: &Path, want: &str, what: &'static str) -> Result<()> {
        match self.reward_profile_of(run) {
            Some(had) if had != want => Err(LearnError::RewardProfile {
                run: run.to_path_buf(),
                had,
                want: want.to_string(),
                what,
            }),
            _ => Ok(()),
        }
    }

    pub fn save(&self, dir: &Path) -> Result<()> {
        save_json(&dir.join("state.json"), self)
    }

    /// `state.json` of a checkpoint or final folder, whatever its layout.
    pub fn load(dir: &Path) -> Result<Self> {
        load_json(&dir.join("state.json"), "a run state")
    }

    /// `state.json` of a policy folder of algorithm `want` and this build's
    /// network layout; `context` says what for (in the error).
    pub fn load_policy(dir: &Path, want: Algorithm, context: &'static str) -> Result<Self> {
        let state = Self::load(dir)?;
        state.check_layout(dir)?;
        if state.algo != want {
            return Err(LearnError::WrongAlgorithm {
                path: dir.to_path_buf(),
                found: state.algo,
                wanted: want,
                context,
            });
        }
        Ok(state)
    }

    /// Refuse networks of another layout (issue 11 item 2: layout 1 was blind
    /// to azimuth columns 28–33).
    pub fn check_layout(&self, dir: &Path) -> Result<()> {
        if self.layout != ENCODER_LAYOUT {
            return Err(LearnError::Layout {
                path: dir.to_path_buf(),
                found: self.layout,
                expected: ENCODER_LAYOUT,
                why: "layout 1 is the stock encoder that read azimuth columns 0–27 only; layout 2 pads the azimuth and sees all 34",
            });
        }
        Ok(())
    }

    pub fn behaviour(&self, name: &str) -> Option<&BehaviourState> {
        self.behaviours.iter().find(|b| b.name == name)
    }

    /// The network size must be the configuration's.
    pub fn check_architecture(
        &self,
        dir: &Path,
        hidden: usize,
        layers: usize,
        config: &str,
    ) -> Result<()> {
        if self.hidden != hidden || self.layers != layers {
            return Err(LearnError::Architecture {
                path: dir.to_path_buf(),
                found_layers: self.layers,
                found_hidden: self.hidden,
                want_layers: layers,
                want_hidden: hidden,
                config: config.to_string(),
            });
        }
        Ok(())
    }
}

/// A file of behaviour `name` in a checkpoint or final folder: `<name>.<part>`.
pub fn behaviour_file(dir: &Path, name: &str, part: &str) -> PathBuf {
    dir.join(format!("{name}.{part}"))
}

/// Write `value` as pretty JSON, atomically.
pub fn save_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value).map_err(|e| LearnError::Corrupt {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    deepfoids_io::write_atomic(path, text.as_bytes()).map_err(LearnError::io(path))
}

/// Read JSON that should hold `what`.
pub fn load_json<T: for<'de> Deserialize<'de>>(path: &Path, what: &str) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(LearnError::io(path))?;
    serde_json::from_str(&text).map_err(|e| LearnError::Corrupt {
        path: path.to_path_buf(),
        reason: format!("not {what}: {e}"),
    })
}

/// Load a module's record from `file` into `module`.
pub fn load_module<M: Module>(module: M, file: &Path) -> Result<M> {
    module.try_load_file(file).map_err(|e| LearnError::Record {
        action: "load",
        path: file.to_path_buf(),
        reason: format!("{e} (a truncated file, or not the weights of this network)"),
    })
}

/// Save a module's record to `file`.
pub fn save_module<M: Module>(module: &M, file: &Path) -> Result<()> {
    module
        .clone()
        .save_file(file)
        .map_err(|e| LearnError::Record {
            action: "save",
            path: file.to_path_buf(),
            reason: format!("{e:?}"),
        })
}

/// Checkpoint folders of a run, oldest first.
pub fn checkpoints(run_dir: &Path) -> Vec<(u64, PathBuf)> {
    let mut v: Vec<(u64, PathBuf)> = std::fs::read_dir(run_dir.join("checkpoints"))
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .filter_map(|e| {
                    let name = e.file_name().to_string_lossy().into_owned();
                    let step = name.strip_prefix("step-")?.parse().ok()?;
                    Some((step, e.path()))
                })
                .filter(|(_, p)| p.join("state.json").is_file())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// The folder of checkpoint `step`.
pub fn checkpoint_dir(run_dir: &Path, step: u64) -> PathBuf {
    run_dir.join("checkpoints").join(format!("step-{step:010}"))
}

/// Delete all but the newest `keep` checkpoints.
pub fn prune(run_dir: &Path, keep: usize) {
    let all = checkpoints(run_dir);
    for (_, dir) in all.iter().take(all.len().saturating_sub(keep.max(1))) {
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// The folder holding a run's policy: `final/`, or with `step` that
/// checkpoint. A run without a complete `final/` (still training, stopped,
/// or its `final/state.json` lost) is refused, naming its checkpoints: it
/// is never silently replaced by one (issue 25).
pub fn policy_dir(run_dir: &Path, step: Option<u64>) -> Result<PathBuf> {
    let not_a_run = |reason: String| LearnError::NotARun {
        path: run_dir.to_path_buf(),
        reason,
    };
    if !run_dir.is_dir() {
        return Err(not_a_run("not a run folder (it does not exist)".into()));
    }
    let all = checkpoints(run_dir);
    let steps = || {
        all.iter()
            .map(|(s, _)| s.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Some(step) = step {
        return match all.iter().find(|(s, _)| *s == step) {
            Some((_, p)) => Ok(p.clone()),
            None if all.is_empty() => Err(not_a_run(format!(
                "no checkpoint at step {step}; it has no checkpoints"
            ))),
            None => Err(not_a_run(format!(
                "no checkpoint at step {step}; it has: {}",
                steps()
            ))),
        };
    }
    let fin = run_dir.join("final");
    if fin.join("state.json").is_file() {
        return Ok(fin);
    }
    if all.is_empty() {
        return Err(not_a_run(
            "holds no trained policy (no final/ and no checkpoints/step-*/)".into(),
        ));
    }
    Err(not_a_run(format!(
        "has no final policy (final/state.json): the run is still training, was stopped, or lost it; name a checkpoint with --checkpoint STEP (it has: {}) or the newest with --latest, or finish the run with `train --resume`",
        steps()
    )))
}

/// The step of a run's newest checkpoint (what `--latest` loads).
pub fn latest_checkpoint(run_dir: &Path) -> Result<u64> {
    checkpoints(run_dir)
        .last()
        .map(|(s, _)| *s)
        .ok_or_else(|| LearnError::NotARun {
            path: run_dir.to_path_buf(),
            reason: "--latest: it has no checkpoints/step-*/".into(),
        })
}

/// Replace `dir` by a folder written by `fill` under a temporary name: the
/// new folder appears whole (a kill while `fill` runs leaves the old one).
pub fn replace_dir_atomic(dir: &Path, fill: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    if let Some(parent) = dir.parent() {
        std::fs::create_dir_all(parent).map_err(LearnError::io(parent))?;
    }
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    let old = dir.with_file_name(format!(".{name}.{}.old", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).map_err(LearnError::io(&tmp))?;
    if let Err(e) = fill(&tmp) {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    let had_old = dir.exists();
    if had_old {
        std::fs::rename(dir, &old).map_err(LearnError::io(dir))?;
    }
    std::fs::rename(&tmp, dir).map_err(LearnError::io(dir))?;
    if had_old {
        let _ = std::fs::remove_dir_all(&old);
    }
    Ok(())
}

/// A policy folder and its state: where `--init-from` and `--resume` take weights from.
#[derive(Clone, Debug)]
pub struct PolicySource {
    pub dir: PathBuf,
    pub state: RunState,
}

impl PolicySource {
    /// The final policy of run folder `run`, which must be of algorithm
    /// `want` and this build's layout.
    pub fn open(run: &Path, want: Algorithm, context: &'static str) -> Result<Self> {
        let dir = policy_dir(run, None)?;
        let state = RunState::load_policy(&dir, want, context)?;
        Ok(Self { dir, state })
    }
}

/// The source of behaviour `name` (species `species`) among `sources`: a
/// behaviour of the same name, else the first of the same species.
pub fn find_source<'a>(
    sources: &'a [PolicySource],
    name: &str,
    species: &str,
) -> Result<(&'a PolicySource, &'a BehaviourState)> {
    let by_name = sources
        .iter()
        .find_map(|s| s.state.behaviour(name).map(|b| (s, b)));
    let by_species = || {
        sources.iter().find_map(|s| {
            s.state
                .behaviours
                .iter()
                .find(|b| b.species == species)
                .map(|b| (s, b))
        })
    };
    by_name.or_else(by_species).ok_or_else(|| {
        let list = |f: &dyn Fn(&PolicySource) -> String| {
            sources.iter().map(f).collect::<Vec<_>>().join("; ")
        };
        LearnError::MissingBehaviour {
            behaviour: name.into(),
            species: species.into(),
            searched: list(&|s| s.dir.display().to_string()),
            available: list(&|s| {
                s.state
                    .behaviours
                    .iter()
                    .map(|b| format!("{} ({})", b.name, b.species))
                    .collect::<Vec<_>>()
                    .join(", ")
            }),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(behaviours: &[(&str, &str)]) -> RunState {
        RunState {
            algo: Algorithm::Ppo,
            layout: ENCODER_LAYOUT,
            run_id: "r".into(),
            scene: "s".into(),
            phase: Phase::Pretrain,
            seed: 0,
            backend: "flex".into(),
            agent_steps: 0,
            ticks: 0,
            resets: 0,
            wall_seconds: 0.0,
            init_from: vec![],
            hidden: 128,
            layers: 4,
            behaviours: behaviours
                .iter()
                .map(|(n, s)| BehaviourState {
                    name: n.to_string(),
                    species: s.to_string(),
                    size_class: "regular".into(),
                    agent_steps: 0,
                    budget: 0,
                    updates: 0,
                })
                .collect(),
            reward_profile: None,
        }
    }

    /// Three pretrained species, one run each: every behaviour of a mixed
    /// scene finds its species; a behaviour name present in a later run wins
    /// over an earlier run of the same species; an unknown species is named.
    #[test]
    fn sources_by_name_then_species() {
        let src = |d: &str, b: &[(&str, &str)]| PolicySource {
            dir: PathBuf::from(d),
            state: state(b),
        };
        let sources = [
            src("coho", &[("coho_regular", "coho")]),
            src("yt", &[("yellowtail_regular", "yellowtail")]),
            src(
                "sb",
                &[("seabream_regular", "seabream"), ("coho_small", "coho")],
            ),
        ];
        let pick = |n, s| find_source(&sources, n, s).map(|(p, b)| (p.dir.clone(), b.name.clone()));
        assert_eq!(
            pick("yellowtail_regular", "yellowtail").unwrap().0,
            PathBuf::from("yt")
        );
        assert_eq!(
            pick("coho_small", "coho").unwrap(),
            (PathBuf::from("sb"), "coho_small".into())
        );
        assert_eq!(
            pick("coho_large", "coho").unwrap(),
            (PathBuf::from("coho"), "coho_regular".into())
        );
        let e = pick("tuna_regular", "tuna").unwrap_err().to_string();
        assert!(
            e.contains("tuna_regular") && e.contains("seabream_regular (seabream)"),
            "{e}"
        );
    }

    /// A state.json written before the layout field (and with one
    /// `init_from`) reads as layout 1 and is refused with the reason.
    #[test]
    fn old_layout_is_refused_by_name() {
        let mut v = serde_json::to_value(state(&[("a", "coho")])).unwrap();
        let o = v.as_object_mut().unwrap();
        o.remove("layout");
        o.insert("init_from".into(), serde_json::json!("runs/old"));
        let old: RunState = serde_json::from_value(v).unwrap();
        assert_eq!(
            (old.layout, old.init_from.clone()),
            (1, vec!["runs/old".to_string()])
        );
        let e = old
            .check_layout(Path::new("runs/x/final"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("runs/x/final") && e.contains("layout 1") && e.contains("retrain"),
            "{e}"
        );
    }
}
