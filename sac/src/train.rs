//! SAC training, read top to bottom as CleanRL's `sac_continuous_action.py`:
//! arguments → environment → agents → loop of (act → step → store → updates →
//! log → checkpoint).
//!
//! # Choices
//! * One actor, twin critics, target critics, two Adams (ε 1e−8) and one
//!   entropy coefficient per behaviour; all its agents share them and fill one
//!   replay buffer ([`crate::replay`]).
//! * Acting: `a = tanh(μ + σ·ε)`, ε from the counter-based stream keyed by
//!   `(seed, fish, tick)`; also before `learning_starts` (the untrained policy
//!   collects the first transitions, as in ML-Agents; CleanRL acts uniformly).
//! * Updates: once a behaviour has `learning_starts` agent steps, it makes
//!   `floor((steps − learning_starts) / steps_per_update)` gradient updates in
//!   all, each right after the decision that makes one due (with 1,000 fish and
//!   1,000 steps per update: one per decision).
//! * An update (Haarnoja et al. 2018; Fujimoto et al. 2018): a batch drawn
//!   uniformly with replacement; critic loss `½·mean((Q_i(s, a) − y)²)` per
//!   critic with the twin-Q target [`twin_q_target`] (terminated ⇒ no
//!   bootstrap; truncated ⇒ bootstrap) and the actor loss
//!   `mean(α·log π(ã|s) − min_i Q_i(s, ã))`, `ã = tanh(μ + σ·ε)`, both from
//!   the same parameters and stepped together (as Haarnoja et al.'s code; CleanRL
//!   steps the critics first). The actor's loss reuses the critics' grid
//!   encodings, detached, with the critics' weights frozen: the action enters
//!   after the encoder, so each critic encodes a batch once (a third less work
//!   per update). Then α's loss ([`EntropyCoef`]), then the target critics move
//!   by `τ` (Polyak).
//! * Rewards enter raw (−300 for a boundary collision): SAC's critics regress on
//!   them directly, as in ML-Agents.
//! * Learning rate constant: 0.001 pretraining, 0.0005 fine tuning (Table 4.5);
//!   initial α 0.3 pretraining, 0 fine tuning (no entropy term).
//! * Checkpoints (weights of actor, critics and targets, both Adams, α and its
//!   Adam, counters and the replay buffer) are written atomically at the first
//!   decision past each `checkpoint_every` agent steps. A resumed run continues
//!   with the same buffer, weights and counters, from a reset environment
//!   reseeded with `seed + resets` (the replay's last transition before the
//!   reset is never sampled).

use crate::config::SacConfig;
use crate::model::{
    Actor, EntropyCoef, SacNetConfig, TwinQ, squashed_sample, squashed_sample_f32, twin_q_target,
};
use crate::policy::load_actor;
use crate::replay::{Batch, Replay, next_history};
use anyhow::{Context, Result, bail};
use burn::module::{ModuleMapper, ModuleVisitor, Param};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::prelude::*;
use deepfoids_env::rng::{Purpose, Stream};
use deepfoids_env::{BehaviourBatch, Env, Scene, StepOutput, VECTOR_OBS};
use deepfoids_ppo::checkpoint::{self, BehaviourState, RunState, RunningMeanStd};
use deepfoids_ppo::logger::Logger;
use deepfoids_ppo::model::ACTIONS;
use deepfoids_ppo::stats::EpisodeStats;
use deepfoids_ppo::train::{ForceInit, Timing, progress_bar, tensor2, tensor4, to_vec};
use deepfoids_ppo::{Backend, BufferMemory, TrainOutcome};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to train, where.
pub struct SacTrainArgs {
    pub scene: Scene,
    pub config: SacConfig,
    pub run_dir: PathBuf,
    pub run_id: String,
    pub seed: u64,
    /// Agent decisions to train for (all behaviours); default: the thesis' budget.
    pub steps: Option<u64>,
    pub resume: bool,
    /// A SAC run to take the initial weights from (transfer learning).
    pub init_from: Option<PathBuf>,
    pub backend: Backend,
    pub progress: bool,
    /// Write checkpoints and the final policy (off for benchmarks).
    pub save: bool,
}

/// SAC's state besides [`RunState`], saved as `sac.json` next to `state.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SacExtra {
    pub log_std_bounds: [f32; 2],
    pub behaviours: Vec<SacBehaviour>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SacBehaviour {
    pub name: String,
    pub entropy: EntropyCoef,
    /// The checkpoint holds this behaviour's replay buffer.
    pub replay_saved: bool,
}

impl SacExtra {
    pub fn save(&self, dir: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self)?;
        deepfoids_env::io::write_atomic(dir.join("sac.json"), text.as_bytes())?;
        Ok(())
    }

    pub fn load(dir: &Path) -> Result<Self> {
        let path = dir.join("sac.json");
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        serde_json::from_str(&text)
            .with_context(|| format!("{} is not a SAC state", path.display()))
    }

    fn behaviour(&self, name: &str) -> Option<&SacBehaviour> {
        self.behaviours.iter().find(|b| b.name == name)
    }
}

fn critic_file(dir: &Path, name: &str) -> PathBuf {
    dir.join(format!("{name}.critic.bpk"))
}
fn target_file(dir: &Path, name: &str) -> PathBuf {
    dir.join(format!("{name}.target.bpk"))
}
fn critic_optim_file(dir: &Path, name: &str) -> PathBuf {
    dir.join(format!("{name}.critic-optim.bpk"))
}
fn replay_file(dir: &Path, name: &str) -> PathBuf {
    dir.join(format!("{name}.replay.bin"))
}

/// The networks' configuration for a run.
pub fn net_config(
    hidden: usize,
    layers: usize,
    bounds: [f32; 2],
    backend: Backend,
) -> SacNetConfig {
    SacNetConfig::new()
        .with_hidden(hidden)
        .with_layers(layers)
        .with_gemm_conv(backend.gemm_conv())
        .with_log_std_min(bounds[0])
        .with_log_std_max(bounds[1])
}

/// Every parameter of a module, flattened, in visiting order.
struct Flatten(Vec<Tensor<1>>);
impl ModuleVisitor for Flatten {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        let t = p.val();
        let n = t.shape().num_elements();
        self.0.push(t.reshape([n]));
    }
}

/// `θ' ← τ·θ + (1 − τ)·θ'` for the parameters of a module of the same structure.
struct Polyak {
    source: std::vec::IntoIter<Tensor<1>>,
    tau: f32,
}
impl ModuleMapper for Polyak {
    fn map_float<const D: usize>(&mut self, p: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let s = self.source.next().expect("modules of the same structure");
        let tau = self.tau;
        p.map(|t| {
            let dims = t.dims();
            t.mul_scalar(1.0 - tau) + s.reshape(dims).mul_scalar(tau)
        })
    }
}

/// Move `target` towards `online` (the same structure, on `target`'s device) by `tau`.
pub fn soft_update(target: TwinQ, online: &TwinQ, tau: f32) -> TwinQ {
    let mut flat = Flatten(Vec::new());
    online.visit(&mut flat);
    target.map(&mut Polyak {
        source: flat.0.into_iter(),
        tau,
    })
}

/// What an update reports.
#[derive(Default, Clone, Copy)]
struct UpdateStats {
    q1_loss: f64,
    q2_loss: f64,
    policy_loss: f64,
    entropy_loss: f64,
    entropy: f64,
    q: f64,
}

impl UpdateStats {
    fn add(&mut self, o: &UpdateStats) {
        self.q1_loss += o.q1_loss;
        self.q2_loss += o.q2_loss;
        self.policy_loss += o.policy_loss;
        self.entropy_loss += o.entropy_loss;
        self.entropy += o.entropy;
        self.q += o.q;
    }
}

/// One behaviour's learner.
struct Learner {
    name: String,
    species: String,
    size_class: String,
    n: usize,
    first: usize,
    actor: Actor,
    critic: TwinQ,
    target: TwinQ,
    actor_infer: Actor,
    actor_optim: ModuleOptimizer,
    critic_optim: ModuleOptimizer,
    entropy: EntropyCoef,
    replay: Replay,
    /// Older frames in each agent's stack (0–2).
    history: Vec<u8>,
    /// The next row continues the replay's previous one.
    continues: bool,
    pending: bool,
    agent_steps: u64,
    updates: u64,
    stats: EpisodeStats,
    update_sums: UpdateStats,
    updates_in_window: u64,
    next_log: u64,
    batch: Batch,
}

fn adam(cfg: &SacConfig) -> ModuleOptimizer {
    AdamConfig::new()
        .with_epsilon(cfg.adam_epsilon as f32)
        .init()
}

fn load_module<M: Module>(module: M, file: &Path) -> Result<M> {
    module
        .try_load_file(file)
        .map_err(|e| anyhow::anyhow!("cannot load {}: {e:?}", file.display()))
}

/// Train SAC on a scene. See the module documentation.
pub fn train(args: SacTrainArgs) -> Result<TrainOutcome> {
    // ---- Arguments ---------------------------------------------------------------
    let cfg = args.config.clone();
    let phase = args.scene.phase;
    let run_dir = args.run_dir.clone();
    std::fs::create_dir_all(&run_dir)
        .with_context(|| format!("cannot create {}", run_dir.display()))?;
    let budget = args.steps.unwrap_or_else(|| cfg.budget(&args.scene, phase));
    let dev = args.backend.device();
    let ad = dev.clone().autodiff();
    let net = net_config(cfg.hidden, cfg.layers, cfg.log_std_bounds, args.backend);
    let resume_from = if args.resume {
        match checkpoint::checkpoints(&run_dir).last() {
            Some((_, d)) => Some(d.clone()),
            None => bail!(
                "--resume: {} has no checkpoint to resume from",
                run_dir.display()
            ),
        }
    } else {
        None
    };
    let resumed: Option<(RunState, SacExtra)> = match &resume_from {
        Some(d) => Some((RunState::load(d)?, SacExtra::load(d)?)),
        None => None,
    };
    if let Some((st, _)) = &resumed {
        if st.scene != args.scene.id || st.algo != "sac" {
            bail!(
                "--resume: run {} trained {} on {}, not sac on {}",
                run_dir.display(),
                st.algo,
                st.scene,
                args.scene.id
            );
        }
        if st.hidden != cfg.hidden || st.layers != cfg.layers {
            bail!(
                "--resume: the run's network ({}×{}) differs from configs/train/sac.toml",
                st.layers,
                st.hidden
            );
        }
    }
    let init_source = match &args.init_from {
        Some(run) => {
            let dir = checkpoint::policy_dir(run, None)?;
            let st = RunState::load(&dir)?;
            if st.algo != "sac" {
                bail!(
                    "--init-from: {} is a {} run; SAC transfers from a SAC run",
                    run.display(),
                    st.algo
                );
            }
            if st.hidden != cfg.hidden || st.layers != cfg.layers {
                bail!(
                    "--init-from: the network of {} ({}×{}) differs from configs/train/sac.toml",
                    run.display(),
                    st.layers,
                    st.hidden
                );
            }
            Some((dir, st))
        }
        None => None,
    };

    // ---- Environment -------------------------------------------------------------
    let resets = resumed.as_ref().map_or(0, |s| s.0.resets + 1);
    let mut env = Env::new(args.scene.clone(), args.seed.wrapping_add(resets));
    let mut tick = resumed.as_ref().map_or(0, |s| s.0.ticks);

    // ---- Agents ------------------------------------------------------------------
    dev.seed(args.seed);
    let mut learners: Vec<Learner> = Vec::new();
    for info in env.behaviours() {
        let mut actor = net.init_actor(&ad);
        actor.visit(&mut ForceInit);
        let mut critic = net.init_critic(&ad);
        critic.visit(&mut ForceInit);
        let mut target = critic.valid();
        let (mut actor_optim, mut critic_optim) = (adam(&cfg), adam(&cfg));
        let mut entropy = EntropyCoef::new(cfg.init_alpha(phase));
        let (mut agent_steps, mut updates) = (0, 0);
        let mut replay = None;
        if let (Some(dir), Some((st, extra))) = (&resume_from, &resumed) {
            actor = load_actor(dir, st, &info.name, &info.species, actor)?;
            critic = load_module(critic, &critic_file(dir, &info.name))?;
            target = load_module(net.init_critic(&dev), &target_file(dir, &info.name))?;
            let load_optim = |f: PathBuf| {
                adam(&cfg)
                    .load(&f)
                    .map_err(|e| anyhow::anyhow!("cannot load {}: {e:?}", f.display()))
            };
            actor_optim = load_optim(RunState::optim_file(dir, &info.name))?;
            critic_optim = load_optim(critic_optim_file(dir, &info.name))?;
            if let Some(bs) = st.behaviour(&info.name) {
                (agent_steps, updates) = (bs.agent_steps, bs.updates);
            }
            if let Some(sb) = extra.behaviour(&info.name) {
                entropy = sb.entropy.clone();
                if sb.replay_saved {
                    replay = Some(Replay::load(
                        &replay_file(dir, &info.name),
                        cfg.buffer_size,
                        info.count,
                    )?);
                }
            }
        } else if let Some((dir, st)) = &init_source {
            actor = load_actor(dir, st, &info.name, &info.species, actor)?;
            let source = st
                .behaviour(&info.name)
                .or_else(|| st.behaviours.iter().find(|b| b.species == info.species))
                .map(|b| b.name.clone())
                .unwrap_or_else(|| info.name.clone());
            critic = load_module(critic, &critic_file(dir, &source))?;
            target = load_module(net.init_critic(&dev), &target_file(dir, &source))?;
        }
        learners.push(Learner {
            name: info.name.clone(),
            species: info.species.clone(),
            size_class: info.size_class.clone(),
            n: info.count,
            first: info.first,
            actor_infer: actor.valid(),
            actor,
            critic,
            target,
            actor_optim,
            critic_optim,
            entropy,
            replay: replay.unwrap_or_else(|| Replay::new(cfg.buffer_size, info.count)),
            history: vec![0; info.count],
            continues: false,
            pending: false,
            agent_steps,
            updates,
            stats: EpisodeStats::new(info.first, info.count),
            update_sums: UpdateStats::default(),
            updates_in_window: 0,
            next_log: (agent_steps / cfg.summary_every + 1) * cfg.summary_every,
            batch: Batch::default(),
        });
    }
    let names: Vec<String> = learners.iter().map(|l| l.name.clone()).collect();
    let mut logger = Logger::open(&run_dir, &names)?;
    let mut state = resumed
        .as_ref()
        .map(|s| s.0.clone())
        .unwrap_or_else(|| RunState {
            algo: "sac".into(),
            run_id: args.run_id.clone(),
            scene: args.scene.id.clone(),
            phase,
            seed: args.seed,
            backend: args.backend.as_str().into(),
            agent_steps: 0,
            budget,
            ticks: 0,
            resets: 0,
            wall_seconds: 0.0,
            init_from: args.init_from.as_ref().map(|p| p.display().to_string()),
            hidden: cfg.hidden,
            layers: cfg.layers,
            init_log_std: 0.0,
            behaviours: vec![],
        });
    state.resets = resets;
    state.budget = budget;
    let start_steps = state.agent_steps;
    let mut next_checkpoint = (state.agent_steps / cfg.checkpoint_every + 1) * cfg.checkpoint_every;
    let bar = progress_bar(args.progress, budget, state.agent_steps);
    let mut timing = Timing::default();
    let (mut curve, mut episode_curve) = (Vec::new(), Vec::new());
    let started = Instant::now();
    let wall_before = state.wall_seconds;
    let mut actions: Vec<Vec<f32>> = learners.iter().map(|l| vec![0.0; l.n * ACTIONS]).collect();
    let lr = cfg.lr(phase);

    let t0 = Instant::now();
    for (b, l) in learners.iter_mut().enumerate() {
        l.act(
            &env.output().behaviours[b],
            &mut actions[b],
            args.seed,
            tick,
            &dev,
        );
    }
    timing.inference += t0.elapsed();

    // ---- The loop ----------------------------------------------------------------
    while state.agent_steps < budget {
        let t0 = Instant::now();
        let out = env.step(&actions).context("environment step")?;
        tick += 1;
        timing.env += t0.elapsed();
        for (b, l) in learners.iter_mut().enumerate() {
            let batch = &out.behaviours[b];
            if !batch.decided {
                continue;
            }
            l.record(batch, out);
            state.agent_steps += l.n as u64;
            let t1 = Instant::now();
            while l.updates < l.updates_due(&cfg) && !l.replay.is_empty() {
                let s = l.update(&cfg, lr, args.seed, b, &dev, &ad)?;
                l.update_sums.add(&s);
                l.updates_in_window += 1;
            }
            timing.update += t1.elapsed();
            if l.agent_steps >= l.next_log {
                let rate = (state.agent_steps - start_steps) as f64
                    / started.elapsed().as_secs_f64().max(1e-9);
                let (reward, ep) = l.log(&mut logger, b, lr, rate)?;
                curve.push((state.agent_steps, reward));
                if let Some(ep) = ep {
                    episode_curve.push((state.agent_steps, ep));
                }
                if let Some(bar) = &bar {
                    bar.set_message(format!("{}: reward/decision {reward:.2}", l.name));
                }
                while l.next_log <= l.agent_steps {
                    l.next_log += cfg.summary_every;
                }
            }
            let t1 = Instant::now();
            l.act(batch, &mut actions[b], args.seed, tick, &dev);
            timing.inference += t1.elapsed();
        }
        if let Some(bar) = &bar {
            bar.set_position(state.agent_steps.min(budget));
        }
        if args.save && state.agent_steps >= next_checkpoint {
            state.ticks = tick;
            state.wall_seconds = wall_before + started.elapsed().as_secs_f64();
            save(
                &run_dir,
                Some(state.agent_steps),
                &learners,
                &mut state,
                &cfg,
            )?;
            checkpoint::prune(&run_dir, cfg.keep_checkpoints);
            logger.flush()?;
            while next_checkpoint <= state.agent_steps {
                next_checkpoint += cfg.checkpoint_every;
            }
        }
    }
    // The last, partial window (a short run may not reach `summary_every`).
    for (b, l) in learners.iter_mut().enumerate() {
        if l.stats.decisions() > 0 {
            let rate = (state.agent_steps - start_steps) as f64
                / started.elapsed().as_secs_f64().max(1e-9);
            let (reward, ep) = l.log(&mut logger, b, lr, rate)?;
            curve.push((state.agent_steps, reward));
            if let Some(ep) = ep {
                episode_curve.push((state.agent_steps, ep));
            }
        }
    }
    state.ticks = tick;
    state.wall_seconds = wall_before + started.elapsed().as_secs_f64();
    let final_dir = if args.save {
        let fin = run_dir.join("final");
        let _ = std::fs::remove_dir_all(&fin);
        save(&run_dir, None, &learners, &mut state, &cfg)?;
        Some(fin)
    } else {
        None
    };
    logger.close()?;
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    Ok(TrainOutcome {
        run_dir,
        agent_steps: state.agent_steps,
        steps_this_run: state.agent_steps - start_steps,
        wall_seconds: started.elapsed().as_secs_f64(),
        timing,
        curve,
        episode_curve,
        final_dir,
        buffer: learners
            .iter()
            .fold(BufferMemory::default(), |m, l| BufferMemory {
                allocated: m.allocated + l.replay.bytes() as u64,
                resident: m.resident + l.replay.resident_bytes() as u64,
                transitions: m.transitions + l.replay.len() as u64,
            }),
    })
}

/// Save every learner into a checkpoint (`Some(step)`: with optimisers and
/// replay buffers) or `final/` (weights only), atomically.
fn save(
    run_dir: &Path,
    step: Option<u64>,
    learners: &[Learner],
    state: &mut RunState,
    cfg: &SacConfig,
) -> Result<()> {
    state.behaviours = learners
        .iter()
        .map(|l| BehaviourState {
            name: l.name.clone(),
            species: l.species.clone(),
            size_class: l.size_class.clone(),
            agent_steps: l.agent_steps,
            updates: l.updates,
            reward_norm: RunningMeanStd::default(),
        })
        .collect();
    let with_replay = step.is_some() && cfg.save_replay_buffer;
    let extra = SacExtra {
        log_std_bounds: cfg.log_std_bounds,
        behaviours: learners
            .iter()
            .map(|l| SacBehaviour {
                name: l.name.clone(),
                entropy: l.entropy.clone(),
                replay_saved: with_replay,
            })
            .collect(),
    };
    let dir = match step {
        Some(s) => checkpoint::checkpoint_dir(run_dir, s),
        None => run_dir.join("final"),
    };
    if dir.exists() {
        std::fs::remove_dir_all(&dir)
            .with_context(|| format!("cannot replace {}", dir.display()))?;
    }
    std::fs::create_dir_all(dir.parent().expect("a run folder")).ok();
    let io = |what: &str, name: &str, e: String| {
        std::io::Error::other(format!("saving the {what} of {name}: {e}"))
    };
    deepfoids_env::io::create_dir_atomic(&dir, |tmp| {
        for l in learners {
            l.actor
                .clone()
                .save_file(RunState::model_file(tmp, &l.name))
                .map_err(|e| io("actor", &l.name, format!("{e:?}")))?;
            l.critic
                .clone()
                .save_file(critic_file(tmp, &l.name))
                .map_err(|e| io("critics", &l.name, format!("{e:?}")))?;
            l.target
                .clone()
                .save_file(target_file(tmp, &l.name))
                .map_err(|e| io("target critics", &l.name, format!("{e:?}")))?;
            if step.is_some() {
                l.actor_optim
                    .save(RunState::optim_file(tmp, &l.name))
                    .map_err(|e| io("actor's optimiser", &l.name, format!("{e:?}")))?;
                l.critic_optim
                    .save(critic_optim_file(tmp, &l.name))
                    .map_err(|e| io("critics' optimiser", &l.name, format!("{e:?}")))?;
            }
            if with_replay {
                l.replay
                    .save(&replay_file(tmp, &l.name))
                    .map_err(|e| io("replay buffer", &l.name, e.to_string()))?;
            }
        }
        extra.save(tmp).map_err(std::io::Error::other)?;
        state.save(tmp).map_err(std::io::Error::other)
    })
    .with_context(|| format!("cannot write {}", dir.display()))
}

/// `n × 3` standard normals from `stream`.
fn normals(stream: &mut Stream, n: usize) -> Vec<f32> {
    (0..n * ACTIONS).map(|_| stream.normal()).collect()
}

impl Learner {
    /// Updates owed after `agent_steps` (see the module documentation).
    fn updates_due(&self, cfg: &SacConfig) -> u64 {
        if self.agent_steps < cfg.learning_starts {
            return 0;
        }
        ((self.agent_steps - cfg.learning_starts) as f64 / cfg.steps_per_update).floor() as u64
    }

    /// Sample actions for the batch's observations and store the row.
    fn act(
        &mut self,
        batch: &BehaviourBatch,
        actions: &mut [f32],
        seed: u64,
        tick: u64,
        dev: &Device,
    ) {
        let n = self.n;
        let (mean, log_std) = self.actor_infer.forward(
            tensor4(batch.grids.clone(), n, dev),
            tensor2(batch.vectors.clone(), n, VECTOR_OBS, dev),
        );
        let (mean, log_std) = (to_vec(mean), to_vec(log_std));
        for a in 0..n {
            let mut noise = Stream::new(seed, Purpose::Exploration, (self.first + a) as u64, tick);
            let eps = [noise.normal(), noise.normal(), noise.normal()];
            let r = a * ACTIONS..(a + 1) * ACTIONS;
            squashed_sample_f32(&mean[r.clone()], &log_std[r.clone()], &eps, &mut actions[r]);
        }
        self.replay.push(
            &batch.grids,
            &batch.vectors,
            actions,
            &self.history,
            self.continues,
        );
        self.continues = true;
        self.pending = true;
    }

    /// The rewards and episode ends of the decision that just finished.
    fn record(&mut self, batch: &BehaviourBatch, out: &StepOutput) {
        if !self.pending {
            return;
        }
        self.replay.reward(&batch.rewards, &batch.terminated);
        for (h, &term) in self.history.iter_mut().zip(&batch.terminated) {
            *h = next_history(*h, term);
        }
        self.stats.record(batch, out);
        self.agent_steps += self.n as u64;
        self.pending = false;
    }

    /// One gradient update of the critics, the actor and α, then the targets.
    fn update(
        &mut self,
        cfg: &SacConfig,
        lr: f64,
        seed: u64,
        b: usize,
        dev: &Device,
        ad: &Device,
    ) -> Result<UpdateStats> {
        let key = self.updates * 3;
        let mut draw = Stream::new(seed, Purpose::Replay, b as u64, key);
        self.replay
            .sample(cfg.batch_size, |k| draw.below(k), &mut self.batch);
        let bt = &self.batch;
        let m = bt.len;
        let alpha = self.entropy.alpha() as f32;

        // Targets, without gradients.
        let (ng, nv) = (
            tensor4(bt.next_grids.clone(), m, dev),
            tensor2(bt.next_vectors.clone(), m, VECTOR_OBS, dev),
        );
        let (nmean, nlog_std) = self.actor_infer.forward(ng.clone(), nv.clone());
        let eps = normals(
            &mut Stream::new(seed, Purpose::Replay, b as u64, key + 1),
            m,
        );
        let (next_a, next_logp) = squashed_sample(nmean, nlog_std, tensor2(eps, m, ACTIONS, dev));
        let (tq1, tq2) = self.target.forward(ng, nv, next_a);
        let y = twin_q_target(
            &bt.rewards,
            &bt.terminated,
            &to_vec(tq1),
            &to_vec(tq2),
            &to_vec(next_logp),
            alpha,
            cfg.gamma,
        );

        // Critics and actor, both from this update's parameters (the simultaneous
        // step of Haarnoja et al.'s implementation). The actor's loss goes through
        // the critics' trunks with their weights frozen, on the critics' grid
        // encodings detached: the action enters after the encoder, so the encoder
        // runs once per critic and update.
        let g = tensor4(bt.grids.clone(), m, ad);
        let v = tensor2(bt.vectors.clone(), m, VECTOR_OBS, ad);
        let a = tensor2(bt.actions.clone(), m, ACTIONS, ad);
        let y = Tensor::<1>::from_data(TensorData::new(y, [m]), ad);
        let encoded = self.critic.encode(g.clone());
        let detached = (encoded.0.clone().detach(), encoded.1.clone().detach());
        let (q1, q2) = self.critic.from_encoded(encoded, v.clone(), a);
        let q_mean = q1.clone().mean().into_scalar::<f32>() as f64;
        let q1_loss = (q1 - y.clone()).powf_scalar(2.0).mean().mul_scalar(0.5);
        let q2_loss = (q2 - y).powf_scalar(2.0).mean().mul_scalar(0.5);
        let (l1, l2) = (
            q1_loss.clone().into_scalar::<f32>(),
            q2_loss.clone().into_scalar::<f32>(),
        );
        if !(l1.is_finite() && l2.is_finite()) {
            bail!(
                "update {} of {}: the critic loss is not finite (Q1 {l1}, Q2 {l2}); training stopped, the last good checkpoint is kept",
                self.updates + 1,
                self.name
            );
        }

        let (mean, log_std) = self.actor.forward(g, v.clone());
        let eps = normals(
            &mut Stream::new(seed, Purpose::Replay, b as u64, key + 2),
            m,
        );
        let (new_a, logp) = squashed_sample(mean, log_std, tensor2(eps, m, ACTIONS, ad));
        let frozen = self.critic.clone().no_grad();
        let (q1p, q2p) = frozen.from_encoded(detached, v, new_a);
        let actor_loss = (logp.clone().mul_scalar(alpha) - q1p.min_pair(q2p)).mean();
        let pl = actor_loss.clone().into_scalar::<f32>();
        let mean_logp = logp.mean().into_scalar::<f32>() as f64;
        if !(pl.is_finite() && mean_logp.is_finite()) {
            bail!(
                "update {} of {}: the policy loss is not finite ({pl}); training stopped, the last good checkpoint is kept",
                self.updates + 1,
                self.name
            );
        }
        let grads = GradientsParams::from_grads((q1_loss + q2_loss).backward(), &self.critic);
        self.critic = self.critic_optim.step(lr, self.critic.clone(), grads);
        let grads = GradientsParams::from_grads(actor_loss.backward(), &self.actor);
        self.actor = self.actor_optim.step(lr, self.actor.clone(), grads);
        self.actor_infer = self.actor.valid();

        // Entropy coefficient, then the target critics.
        let entropy_loss = self
            .entropy
            .step(mean_logp, cfg.target_entropy, lr, cfg.adam_epsilon);
        self.target = soft_update(self.target.clone(), &self.critic.valid(), cfg.tau);
        self.updates += 1;
        Ok(UpdateStats {
            q1_loss: l1 as f64,
            q2_loss: l2 as f64,
            policy_loss: pl as f64,
            entropy_loss,
            entropy: -mean_logp,
            q: q_mean,
        })
    }

    /// Write the window's scalars; returns the mean reward per decision and, if
    /// episodes ended, their mean cumulative reward.
    fn log(
        &mut self,
        logger: &mut Logger,
        b: usize,
        lr: f64,
        rate: f64,
    ) -> Result<(f64, Option<f64>)> {
        let step = self.agent_steps;
        let (reward, episode) = self.stats.log(logger, b, step)?;
        let s = std::mem::take(&mut self.update_sums);
        let k = std::mem::take(&mut self.updates_in_window);
        if k > 0 {
            let k = k as f64;
            logger.scalar(b, "Losses/Q1 Loss", s.q1_loss / k, step)?;
            logger.scalar(b, "Losses/Q2 Loss", s.q2_loss / k, step)?;
            logger.scalar(b, "Losses/Policy Loss", s.policy_loss / k, step)?;
            logger.scalar(b, "Losses/Entropy Coeff Loss", s.entropy_loss / k, step)?;
            logger.scalar(b, "Policy/Entropy", s.entropy / k, step)?;
            logger.scalar(b, "Policy/Extrinsic Value Estimate", s.q / k, step)?;
        }
        logger.scalar(b, "Policy/Entropy Coeff", self.entropy.alpha(), step)?;
        logger.scalar(b, "Policy/Learning Rate", lr, step)?;
        logger.scalar(b, "Policy/Updates", self.updates as f64, step)?;
        logger.scalar(b, "Perf/Agent Steps per Second", rate, step)?;
        Ok((reward, episode))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(m: &TwinQ) -> Vec<f32> {
        let mut f = Flatten(Vec::new());
        m.visit(&mut f);
        f.0.into_iter().flat_map(to_vec).collect()
    }

    /// τ = 0.25: every target parameter moves a quarter of the way to the online one.
    #[test]
    fn polyak_moves_targets_by_tau() {
        let dev = Device::flex();
        let cfg = SacNetConfig::new().with_hidden(8).with_layers(1);
        let online = cfg.init_critic(&dev);
        let target = cfg.init_critic(&dev);
        let (o, t) = (params(&online), params(&target));
        let moved = params(&soft_update(target, &online, 0.25));
        assert_eq!(moved.len(), o.len());
        for i in (0..o.len()).step_by(97) {
            let want = 0.75 * t[i] + 0.25 * o[i];
            assert!(
                (moved[i] - want).abs() < 1e-6,
                "{i}: {} vs {want}",
                moved[i]
            );
        }
    }
}
