//! SAC, read top to bottom as CleanRL's `sac_continuous_action.py`:
//! hyperparameters → agent → at each decision (store the reward → updates due
//! → act and store) → update (targets → critic loss → actor loss → α →
//! Polyak) → log. The run itself (environment loop, budgets, resume,
//! transfer, checkpoints, logs) is `deepfoids_learn::driver`'s.
//!
//! # Choices
//! * One actor, twin critics, target critics, two Adams (ε 1e−8) and one
//!   entropy coefficient per behaviour; all its agents share them and fill one
//!   replay buffer ([`crate::replay`]).
//! * Acting: `a = tanh(μ + σ·ε)`, ε from the counter-based stream keyed by
//!   `(seed, fish, tick)`; also before `learning_starts` (the untrained policy
//!   collects the first transitions, as in ML-Agents; CleanRL acts uniformly).
//!   The actor acts on the fused kernels (no autodiff).
//! * Updates: once a behaviour has `learning_starts` agent steps, it makes
//!   `floor((steps − learning_starts) / steps_per_update)` gradient updates in
//!   all, each right after the decision that makes one due (with 1,000 fish and
//!   1,000 steps per update: one per decision).
//! * An update (Haarnoja et al. 2018; Fujimoto et al. 2018): a batch drawn
//!   uniformly with replacement; the twin-Q target [`twin_q_target`]
//!   (terminated ⇒ no bootstrap; truncated ⇒ bootstrap) from the actor and the
//!   target critics on the fused forward (no autodiff; the next observations'
//!   grids are convolved once for all three); critic loss
//!   `½·mean((Q_i(s, a) − y)²)` per critic and the actor loss
//!   `mean(α·log π(ã|s) − min_i Q_i(s, ã))`, `ã = tanh(μ + σ·ε)`, both from
//!   the same parameters and stepped together (as Haarnoja et al.'s code;
//!   CleanRL steps the critics first). The actor's loss reuses the critics'
//!   grid encodings, detached, with the critics' weights frozen: the action
//!   enters after the encoder, so each critic encodes a batch once. Then α's
//!   loss ([`EntropyCoef`]), then the target critics move by `τ` (Polyak).
//! * Rewards enter raw (−300 for a boundary collision): SAC's critics regress on
//!   them directly, as in ML-Agents.
//! * Learning rate constant: 0.001 pretraining, 0.0005 fine tuning (Table 4.5);
//!   initial α 0.3 pretraining, 0 fine tuning (no entropy term).
//! * Checkpoints hold the actor, critics and targets, both Adams, α with its
//!   Adam state and the update count (`<behaviour>.sac.json`), and the replay
//!   buffer. A resumed run continues with the same buffer, weights and
//!   counters (the replay's last transition before the reset is never sampled).

use crate::config::SacConfig;
use crate::model::{
    Actor, EntropyCoef, SacNetConfig, TwinQ, squash_heads, squashed_sample, squashed_sample_f32,
    twin_q_target,
};
use crate::replay::{Batch, Replay, next_history};
use burn::module::{ModuleMapper, ModuleVisitor, Param};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::prelude::*;
use deepfoids_env::rng::{Purpose, Stream};
use deepfoids_env::{BehaviourBatch, VECTOR_OBS};
use deepfoids_learn::checkpoint::{
    BehaviourState, behaviour_file, load_json, load_module, save_json, save_module,
};
use deepfoids_learn::driver::{BufferMemory, Learner, LearnerCtx, StepCtx, Trainer};
use deepfoids_learn::kernels::encoder::GridsRef;
use deepfoids_learn::kernels::infer::{InferNet, TrunkInputs};
use deepfoids_learn::logger::Scalars;
use deepfoids_learn::onnx::Metadata;
use deepfoids_learn::plan::{self, MemoryPlan, Part, TrainConfigFile, UpdatePlan};
use deepfoids_learn::policy::NoiseKey;
use deepfoids_learn::tensor::{ForceInit, tensor1, tensor2};
use deepfoids_learn::{ACTIONS, Algorithm, Grids, LearnError, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// The SAC algorithm with its hyperparameters.
pub struct Sac {
    pub config: SacConfig,
    /// The file `config` came from, named in errors.
    pub source: PathBuf,
}

impl Sac {
    /// The shipped config file's name: `configs/train/sac.toml`.
    pub const DEFAULT_SOURCE: &str = "configs/train/sac.toml";

    /// `config`, named as the shipped file.
    pub fn new(config: SacConfig) -> Self {
        Self {
            config,
            source: PathBuf::from(Self::DEFAULT_SOURCE),
        }
    }

    /// `<configs>/train/sac.toml`, loaded and checked.
    pub fn load(dirs: &deepfoids_env::ConfigDirs) -> Result<Self> {
        Ok(Self {
            config: SacConfig::load(dirs)?,
            source: SacConfig::path(dirs),
        })
    }
}

/// SAC's own state of a behaviour, `<behaviour>.sac.json` (final policies too:
/// the actor's log-std bounds are needed to load it).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SacState {
    pub log_std_bounds: [f32; 2],
    pub entropy: EntropyCoef,
    pub updates: u64,
    /// The checkpoint holds this behaviour's replay buffer.
    pub replay_saved: bool,
}

pub fn actor_file(dir: &Path, name: &str) -> PathBuf {
    behaviour_file(dir, name, "model.bpk")
}
fn critic_file(dir: &Path, name: &str) -> PathBuf {
    behaviour_file(dir, name, "critic.bpk")
}
fn target_file(dir: &Path, name: &str) -> PathBuf {
    behaviour_file(dir, name, "target.bpk")
}
pub fn state_file(dir: &Path, name: &str) -> PathBuf {
    behaviour_file(dir, name, "sac.json")
}
fn replay_file(dir: &Path, name: &str) -> PathBuf {
    behaviour_file(dir, name, "replay.bin")
}

/// The networks' configuration for a run.
pub fn net_config(hidden: usize, layers: usize, bounds: [f32; 2]) -> SacNetConfig {
    SacNetConfig::new()
        .with_hidden(hidden)
        .with_layers(layers)
        .with_log_std_min(bounds[0])
        .with_log_std_max(bounds[1])
}

fn adam(cfg: &SacConfig) -> ModuleOptimizer {
    AdamConfig::new()
        .with_epsilon(cfg.adam_epsilon as f32)
        .init()
}

fn load_optim(cfg: &SacConfig, file: &Path) -> Result<ModuleOptimizer> {
    adam(cfg).load(file).map_err(|e| LearnError::Record {
        action: "load",
        path: file.to_path_buf(),
        reason: format!("{e:?}"),
    })
}

fn save_optim(optim: &ModuleOptimizer, file: &Path) -> Result<()> {
    optim.save(file).map_err(|e| LearnError::Record {
        action: "save",
        path: file.to_path_buf(),
        reason: format!("{e:?}"),
    })
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

impl Trainer for Sac {
    type Learner = SacLearner;

    deepfoids_learn::trainer_config_methods!(Algorithm::Sac);

    /// Networks: the actor (body, mean and log-std heads `[hidden → 3]`),
    /// the twin critics and their targets (bodies taking the action, heads
    /// `[hidden → 1]`). Experience: the replay buffer, exactly
    /// ([`Replay::bytes_for`]), and a sampled minibatch. Update: a minibatch
    /// through six bodies (actor, twin critics on `s`, the actor and the
    /// targets on `s'`); acting: each agent's outputs and scratch.
    fn memory_plan(&self, agents: usize) -> MemoryPlan {
        let c = &self.config;
        let (h, l) = (c.hidden as u64, c.layers as u64);
        let actor = plan::body_params(h, l, 0) + 2 * (h * 3 + 3);
        let critic = 2 * (plan::body_params(h, l, ACTIONS as u64) + h + 1);
        let params = actor + 2 * critic;
        let batch = c.batch_size as u64;
        MemoryPlan {
            parts: vec![
                plan::networks_part(params, c.hidden, c.layers),
                Part {
                    name: "experience",
                    bytes: Replay::bytes_for(c.buffer_size, agents)
                        .saturating_add(batch.saturating_mul(2 * 4 * 1024)),
                    fields: format!("buffer_size = {}, {agents} agents", c.buffer_size),
                },
                plan::update_part(c.batch_size, 6, c.hidden, c.layers, agents),
            ],
        }
    }

    /// The first update once `learning_starts + steps_per_update` agent
    /// steps are in (counted at decisions, `n` at a time), then one every
    /// `steps_per_update`, if the behaviour is still training at that
    /// decision (the budget exceeds those steps by one).
    fn update_plan(&self, agents: usize) -> UpdatePlan {
        let c = &self.config;
        let n = agents.max(1) as u64;
        let first = c.learning_starts + c.steps_per_update.ceil() as u64;
        let first = first.div_ceil(n) * n + 1;
        UpdatePlan {
            earliest: first,
            first,
            every: c.steps_per_update.ceil() as u64,
        }
    }

    fn update_fields(&self) -> String {
        format!(
            "learning_starts = {}, steps_per_update = {}",
            self.config.learning_starts, self.config.steps_per_update
        )
    }

    fn new_learner(&self, ctx: &LearnerCtx<'_>) -> Result<SacLearner> {
        let cfg = &self.config;
        let net = net_config(cfg.hidden, cfg.layers, cfg.log_std_bounds);
        let actor = net.init_actor(&ctx.train_device);
        actor.visit(&mut ForceInit);
        let critic = net.init_critic(&ctx.train_device);
        critic.visit(&mut ForceInit);
        let target = critic.valid();
        Ok(self.fresh_learner(ctx, (actor, critic, target), cfg.log_std_bounds))
    }

    fn resume_learner(
        &self,
        ctx: &LearnerCtx<'_>,
        dir: &Path,
        state: &BehaviourState,
    ) -> Result<SacLearner> {
        let cfg = &self.config;
        let name = &state.name;
        let st: SacState = load_json(&state_file(dir, name), "SAC's state")?;
        let net = net_config(cfg.hidden, cfg.layers, st.log_std_bounds);
        let replay = if st.replay_saved {
            let replay = Replay::load(&replay_file(dir, name), cfg.buffer_size, ctx.info.count)?;
            eprintln!(
                "{name}: replay buffer restored: {} transitions",
                replay.len()
            );
            Some(replay)
        } else {
            eprintln!(
                "{name}: the checkpoint holds no replay buffer (save_replay_buffer = false): it starts empty"
            );
            None
        };
        let (actor, critic, target) = load_nets(&net, ctx, dir, name)?;
        let parts = Parts {
            actor,
            critic,
            target,
            actor_optim: load_optim(cfg, &behaviour_file(dir, name, "optim.bpk"))?,
            critic_optim: load_optim(cfg, &behaviour_file(dir, name, "critic-optim.bpk"))?,
            state: st,
            replay,
        };
        Ok(SacLearner::new(cfg.clone(), ctx, parts))
    }

    fn transfer_learner(
        &self,
        ctx: &LearnerCtx<'_>,
        from: &Path,
        source: &BehaviourState,
    ) -> Result<SacLearner> {
        let cfg = &self.config;
        let name = &source.name;
        let src: SacState = load_json(&state_file(from, name), "SAC's state")?;
        let net = net_config(cfg.hidden, cfg.layers, src.log_std_bounds);
        let nets = load_nets(&net, ctx, from, name)?;
        Ok(self.fresh_learner(ctx, nets, src.log_std_bounds))
    }
}

impl Sac {
    /// A learner with networks `(actor, critic, target)` and fresh
    /// optimisers, entropy coefficient and counters.
    fn fresh_learner(
        &self,
        ctx: &LearnerCtx<'_>,
        (actor, critic, target): (Actor, TwinQ, TwinQ),
        log_std_bounds: [f32; 2],
    ) -> SacLearner {
        let cfg = &self.config;
        let parts = Parts {
            actor,
            critic,
            target,
            actor_optim: adam(cfg),
            critic_optim: adam(cfg),
            state: SacState {
                log_std_bounds,
                entropy: EntropyCoef::new(cfg.init_alpha(ctx.phase)),
                updates: 0,
                replay_saved: false,
            },
            replay: None,
        };
        SacLearner::new(cfg.clone(), ctx, parts)
    }
}

/// Behaviour `name`'s actor, critic and target critic from folder `dir`.
fn load_nets(
    net: &SacNetConfig,
    ctx: &LearnerCtx<'_>,
    dir: &Path,
    name: &str,
) -> Result<(Actor, TwinQ, TwinQ)> {
    Ok((
        load_module(net.init_actor(&ctx.train_device), &actor_file(dir, name))?,
        load_module(net.init_critic(&ctx.train_device), &critic_file(dir, name))?,
        load_module(net.init_critic(&ctx.device), &target_file(dir, name))?,
    ))
}

/// What a learner is built from.
struct Parts {
    actor: Actor,
    critic: TwinQ,
    target: TwinQ,
    actor_optim: ModuleOptimizer,
    critic_optim: ModuleOptimizer,
    state: SacState,
    replay: Option<Replay>,
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

/// `n × 3` standard normals from `stream`.
fn normals(stream: &mut Stream, n: usize) -> Vec<f32> {
    (0..n * ACTIONS).map(|_| stream.normal()).collect()
}

/// One behaviour's SAC.
pub struct SacLearner {
    cfg: SacConfig,
    index: usize,
    name: String,
    first: usize,
    lr: f64,
    actor: Actor,
    critic: TwinQ,
    target: TwinQ,
    /// The actor for acting (fused forward).
    actor_net: InferNet,
    /// The actor, target critic 1 and 2 on next observations (fused forward).
    next_net: InferNet,
    actor_optim: ModuleOptimizer,
    critic_optim: ModuleOptimizer,
    state: SacState,
    replay: Replay,
    /// Older frames in each agent's stack (0–2).
    history: Vec<u8>,
    /// The next row continues the replay's previous one.
    continues: bool,
    pending: bool,
    update_sums: UpdateStats,
    updates_in_window: u64,
    next_log: Option<u64>,
    batch: Batch,
    dev: Device,
}

impl SacLearner {
    fn new(cfg: SacConfig, ctx: &LearnerCtx<'_>, p: Parts) -> Self {
        let n = ctx.info.count;
        let mut l = Self {
            lr: cfg.lr(ctx.phase),
            index: ctx.index,
            name: ctx.info.name.clone(),
            first: ctx.info.first,
            actor_net: p.actor.infer_net(),
            next_net: p.actor.infer_net(),
            actor: p.actor,
            critic: p.critic,
            target: p.target,
            actor_optim: p.actor_optim,
            critic_optim: p.critic_optim,
            state: p.state,
            replay: p.replay.unwrap_or_else(|| Replay::new(cfg.buffer_size, n)),
            history: vec![0; n],
            continues: false,
            pending: false,
            update_sums: UpdateStats::default(),
            updates_in_window: 0,
            next_log: None,
            batch: Batch::default(),
            dev: ctx.train_device.clone(),
            cfg,
        };
        l.refresh_nets();
        l
    }

    /// New snapshots of the actor and the target critics for the fused forward.
    fn refresh_nets(&mut self) {
        self.actor_net = self.actor.infer_net();
        let target = self.target.infer_net();
        let mut next = deepfoids_learn::body::infer_net(&[
            (&self.actor.body, None),
            (&self.target.q1.body, Some(&self.target.q1.head)),
            (&self.target.q2.body, Some(&self.target.q2.head)),
        ]);
        next.trunks[0] = self.actor_net.trunks[0].clone();
        next.trunks[1] = target.trunks[0].clone();
        next.trunks[2] = target.trunks[1].clone();
        self.next_net = next;
    }

    /// Updates owed after `agent_steps` (see the module documentation).
    fn updates_due(&self, agent_steps: u64) -> u64 {
        let cfg = &self.cfg;
        if agent_steps < cfg.learning_starts {
            return 0;
        }
        ((agent_steps - cfg.learning_starts) as f64 / cfg.steps_per_update).floor() as u64
    }

    /// `tanh(μ + σ·ε)` for the actor's output `[n, 6]` (mean, raw log-std),
    /// the noise of agent `a` keyed by `(seed, first + a, tick)`.
    fn squash(&self, out: &[f32], actions: &mut [f32], seed: u64, tick: u64) {
        let key = NoiseKey {
            seed,
            first: self.first,
            tick,
        };
        squash_heads(out, key, |x| self.actor.squash_log_std(x), actions);
    }

    /// Act on the batch's observations and, when training, store the row.
    /// The first decision after the budget still stores its observations
    /// (not its actions' rewards): they complete the last transition.
    fn act(
        &mut self,
        batch: &BehaviourBatch,
        actions: &mut [f32],
        ctx: &mut StepCtx<'_>,
        last: bool,
    ) {
        let t0 = Instant::now();
        let out = self
            .actor_net
            .forward(batch.observations(), &batch.vectors)
            .remove(0);
        self.squash(&out, actions, ctx.seed, ctx.tick);
        ctx.timing.inference += t0.elapsed();
        if ctx.training || last {
            self.replay.push(
                batch.observations(),
                &batch.vectors,
                actions,
                &self.history,
                self.continues,
            );
            self.continues = true;
            self.pending = ctx.training;
        }
    }

    /// One gradient update of the critics, the actor and α, then the targets.
    fn update(&mut self, ctx: &mut StepCtx<'_>) -> Result<UpdateStats> {
        let cfg = self.cfg.clone();
        let (seed, b) = (ctx.seed, self.index as u64);
        let key = self.state.updates * 3;
        let t = Instant::now();
        let mut draw = Stream::new(seed, Purpose::Replay, b, key);
        self.replay
            .sample(cfg.batch_size, |k| draw.below(k), &mut self.batch);
        let bt = &self.batch;
        let m = bt.len;
        let alpha = self.state.entropy.alpha() as f32;
        ctx.timing.part("sample", t.elapsed());

        // Targets, without gradients: the actor and both target critics on
        // the next observations (their grids convolved once for all three).
        let t = Instant::now();
        let enc = self
            .next_net
            .encode(GridsRef::Compact(&bt.next_grids.bytes));
        let plain = TrunkInputs {
            vectors: &bt.next_vectors,
            extra: &[],
            extra_width: 0,
        };
        let out = self.next_net.trunk(0, &enc, plain);
        let eps = normals(&mut Stream::new(seed, Purpose::Replay, b, key + 1), m);
        let mut next_a = vec![0.0f32; m * ACTIONS];
        let mut next_logp = vec![0.0f32; m];
        for (i, row) in out.chunks_exact(2 * ACTIONS).enumerate() {
            let log_std: Vec<f32> = row[ACTIONS..]
                .iter()
                .map(|&x| self.actor.squash_log_std(x))
                .collect();
            let r = i * ACTIONS..(i + 1) * ACTIONS;
            next_logp[i] =
                squashed_sample_f32(&row[..ACTIONS], &log_std, &eps[r.clone()], &mut next_a[r]);
        }
        let with_action = TrunkInputs {
            extra: &next_a,
            extra_width: ACTIONS,
            ..plain
        };
        let tq1 = self.next_net.trunk(1, &enc, with_action);
        let tq2 = self.next_net.trunk(2, &enc, with_action);
        let y = twin_q_target(
            &bt.rewards,
            &bt.terminated,
            &tq1,
            &tq2,
            &next_logp,
            alpha,
            cfg.gamma,
        );
        ctx.timing.part("targets", t.elapsed());

        // Critics and actor, both from this update's parameters (the simultaneous
        // step of Haarnoja et al.'s implementation). The actor's loss goes through
        // the critics' trunks with their weights frozen, on the critics' grid
        // encodings detached: the action enters after the encoder, so the encoder
        // runs once per critic and update.
        let t = Instant::now();
        let ad = self.dev.clone();
        let grids = Grids::Compact(Arc::new(bt.grids.clone()));
        let v = tensor2(bt.vectors.clone(), m, VECTOR_OBS, &ad);
        let a = tensor2(bt.actions.clone(), m, ACTIONS, &ad);
        let y = tensor1(y, &ad);
        let encoded = self.critic.encode(&grids);
        let detached = (encoded.0.clone().detach(), encoded.1.clone().detach());
        let (q1, q2) = self.critic.from_encoded(encoded, v.clone(), a);
        let q_mean = q1.clone().mean().into_scalar::<f32>() as f64;
        let q1_loss = (q1 - y.clone()).powf_scalar(2.0).mean().mul_scalar(0.5);
        let q2_loss = (q2 - y).powf_scalar(2.0).mean().mul_scalar(0.5);
        let (l1, l2) = (
            q1_loss.clone().into_scalar::<f32>(),
            q2_loss.clone().into_scalar::<f32>(),
        );
        let non_finite = |what: String| LearnError::NonFinite {
            update: self.state.updates + 1,
            behaviour: self.name.clone(),
            what,
        };
        if !(l1.is_finite() && l2.is_finite()) {
            return Err(non_finite(format!("the critic loss (Q1 {l1}, Q2 {l2})")));
        }
        let (mean, log_std) = self.actor.forward(&grids, v.clone());
        let eps = normals(&mut Stream::new(seed, Purpose::Replay, b, key + 2), m);
        let (new_a, logp) = squashed_sample(mean, log_std, tensor2(eps, m, ACTIONS, &ad));
        let frozen = self.critic.clone().no_grad();
        let (q1p, q2p) = frozen.from_encoded(detached, v, new_a);
        let actor_loss = (logp.clone().mul_scalar(alpha) - q1p.min_pair(q2p)).mean();
        let pl = actor_loss.clone().into_scalar::<f32>();
        let mean_logp = logp.mean().into_scalar::<f32>() as f64;
        if !(pl.is_finite() && mean_logp.is_finite()) {
            return Err(non_finite(format!("the policy loss ({pl})")));
        }
        ctx.timing.part("forward", t.elapsed());
        let t = Instant::now();
        let critic_grads =
            GradientsParams::from_grads((q1_loss + q2_loss).backward(), &self.critic);
        let actor_grads = GradientsParams::from_grads(actor_loss.backward(), &self.actor);
        ctx.timing.part("backward", t.elapsed());
        let t = Instant::now();
        self.critic = self
            .critic_optim
            .step(self.lr, self.critic.clone(), critic_grads);
        self.actor = self
            .actor_optim
            .step(self.lr, self.actor.clone(), actor_grads);

        // Entropy coefficient, then the target critics.
        let entropy_loss =
            self.state
                .entropy
                .step(mean_logp, cfg.target_entropy, self.lr, cfg.adam_epsilon);
        self.target = soft_update(self.target.clone(), &self.critic.valid(), cfg.tau);
        self.state.updates += 1;
        self.refresh_nets();
        ctx.timing.part("optimiser", t.elapsed());
        Ok(UpdateStats {
            q1_loss: l1 as f64,
            q2_loss: l2 as f64,
            policy_loss: pl as f64,
            entropy_loss,
            entropy: -mean_logp,
            q: q_mean,
        })
    }
}

impl Learner for SacLearner {
    fn start(
        &mut self,
        batch: &BehaviourBatch,
        actions: &mut [f32],
        ctx: &mut StepCtx<'_>,
    ) -> Result<()> {
        // A fresh environment: stacks restart, and the replay's previous row
        // has no successor.
        self.history.fill(0);
        self.continues = false;
        self.pending = false;
        self.next_log =
            Some((ctx.agent_steps / self.cfg.summary_every + 1) * self.cfg.summary_every);
        self.act(batch, actions, ctx, false);
        Ok(())
    }

    fn decide(
        &mut self,
        batch: &BehaviourBatch,
        actions: &mut [f32],
        ctx: &mut StepCtx<'_>,
    ) -> Result<()> {
        let last = self.pending && !ctx.training;
        if self.pending {
            self.replay.reward(&batch.rewards, &batch.terminated);
            for (h, &term) in self.history.iter_mut().zip(&batch.terminated) {
                *h = next_history(*h, term);
            }
            self.pending = false;
        }
        let t = Instant::now();
        while self.state.updates < self.updates_due(ctx.agent_steps) && !self.replay.is_empty() {
            let s = self.update(ctx)?;
            self.update_sums.add(&s);
            self.updates_in_window += 1;
        }
        ctx.timing.update += t.elapsed();
        self.act(batch, actions, ctx, last);
        Ok(())
    }

    fn log_due(&self, agent_steps: u64) -> bool {
        self.next_log.is_some_and(|n| agent_steps >= n)
    }

    fn log(&mut self, out: &mut Scalars<'_>) -> Result<()> {
        let s = std::mem::take(&mut self.update_sums);
        let k = std::mem::take(&mut self.updates_in_window);
        if k > 0 {
            let k = k as f64;
            out.put("Losses/Q1 Loss", s.q1_loss / k)?;
            out.put("Losses/Q2 Loss", s.q2_loss / k)?;
            out.put("Losses/Policy Loss", s.policy_loss / k)?;
            out.put("Losses/Entropy Coeff Loss", s.entropy_loss / k)?;
            out.put("Policy/Entropy", s.entropy / k)?;
            out.put("Policy/Extrinsic Value Estimate", s.q / k)?;
        }
        out.put("Policy/Entropy Coeff", self.state.entropy.alpha())?;
        out.put("Policy/Learning Rate", self.lr)?;
        out.put("Policy/Updates", self.state.updates as f64)?;
        if let Some(n) = &mut self.next_log {
            while *n <= out.step {
                *n += self.cfg.summary_every;
            }
        }
        Ok(())
    }

    fn updates(&self) -> u64 {
        self.state.updates
    }

    fn save(&self, dir: &Path, name: &str, checkpoint: bool) -> Result<()> {
        save_module(&self.actor, &actor_file(dir, name))?;
        save_module(&self.critic, &critic_file(dir, name))?;
        save_module(&self.target, &target_file(dir, name))?;
        let with_replay = checkpoint && self.cfg.save_replay_buffer;
        if checkpoint {
            save_optim(&self.actor_optim, &behaviour_file(dir, name, "optim.bpk"))?;
            save_optim(
                &self.critic_optim,
                &behaviour_file(dir, name, "critic-optim.bpk"),
            )?;
        }
        if with_replay {
            self.replay.save(&replay_file(dir, name))?;
        }
        let st = SacState {
            replay_saved: with_replay,
            ..self.state.clone()
        };
        save_json(&state_file(dir, name), &st)
    }

    fn actor_onnx(&self, meta: &Metadata) -> Vec<u8> {
        self.actor.onnx(meta)
    }

    fn memory(&self) -> BufferMemory {
        BufferMemory {
            allocated: self.replay.bytes() as u64,
            resident: self.replay.resident_bytes() as u64,
            transitions: self.replay.len() as u64,
            peak: self.replay.resident_bytes() as u64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deepfoids_learn::tensor::to_vec;

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
