//! PPO, read top to bottom as CleanRL's `ppo_continuous_action.py`:
//! hyperparameters → agent → at each decision (rewards → act → trajectories
//! → GAE) → update (flatten → minibatches → losses → optimiser step) → log.
//! The run itself (environment loop, budgets, resume, transfer, checkpoints,
//! logs) is `deepfoids_learn::driver`'s.
//!
//! # Choices (the "implementation details" of PPO, and ML-Agents' conventions)
//! * One actor-critic and one Adam (ε 1e−8) per behaviour; all its agents share it.
//! * Rollout ([`crate::rollout`], `rollout = "ml-agents"`): each agent's
//!   trajectory ends after `time_horizon` (64) decisions (bootstrapped from the
//!   critic's value of the next observation) or at the end of its episode
//!   (*terminated* ⇒ no bootstrap; *truncated* ⇒ bootstrap); closed
//!   trajectories get GAE and join the buffer; an update once it holds
//!   ≥ `buffer_size` transitions, over all of them. `rollout = "synchronous"`
//!   is the scheme before issue 12 (see `PpoConfig::rollout`).
//! * Values and log-probabilities are those of the policy that acted (the
//!   fused forward's; a decision's observations are evaluated before an
//!   update that decision triggers, and their actions come from there).
//! * Actions: `a = μ + σ·ε` with ε from the counter-based stream keyed by
//!   `(seed, fish, tick)`; the environment gets `a` clipped to [−1, 1]; the
//!   log-probability is of the unclipped `a`.
//! * Rewards are divided by the running std of the discounted return
//!   (`normalize_rewards`; gym's NormalizeReward as in CleanRL) — the thesis'
//!   rewards span −300 to +100 per decision; the logs show raw rewards.
//! * Advantages are normalised per minibatch; the value loss is the plain MSE
//!   (no clipping) times `value_coef`; the entropy bonus is `entropy_coef · H`.
//! * Gradients are clipped to a global norm of `max_grad_norm`, separately for
//!   the actor's and the critic's parameters (separate networks: the value
//!   loss's scale must not shrink the policy's step).
//! * Learning rate: linear from `learning_rate` to 0 over the behaviour's
//!   budget, by its own agent steps.
//! * Minibatches: `epochs` passes over the buffer, each a fresh shuffle
//!   (keyed by the update), in `floor(transitions / batch_size)` minibatches.
//! * Checkpoints hold the weights, Adam's state, the update count, the
//!   reward statistics, the synchronous scheme's clock and the experience not
//!   yet learned from: open trajectories are cut before their newest step
//!   (bootstrapped as at the time horizon) and the buffer is saved
//!   ([`crate::inflight`]), so a resumed run loses no counted step.

use crate::config::{PpoConfig, Rollout as RolloutScheme, Schedule};
use crate::gae::{BOOTSTRAP, CONTINUE, TERMINAL};
use crate::gaussian::{entropy, entropy_f32, log_prob, log_prob_f32};
use crate::inflight::{cut_open, load_buffer, save_buffer};
use crate::model::{ActorCritic, ActorCriticConfig};
use crate::reward_scale::RunningMeanStd;
use crate::rollout::{Rollout, stack_of};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::prelude::*;
use deepfoids_env::rng::{Purpose, Stream};
use deepfoids_env::{BehaviourBatch, VECTOR_OBS};
use deepfoids_learn::checkpoint::{
    BehaviourState, behaviour_file, load_json, load_module, save_json, save_module,
};
use deepfoids_learn::driver::{BufferMemory, Learner, LearnerCtx, StepCtx, Trainer};
use deepfoids_learn::frames::FRAME_BYTES;
use deepfoids_learn::kernels::infer::InferNet;
use deepfoids_learn::logger::Scalars;
use deepfoids_learn::onnx::Metadata;
use deepfoids_learn::plan::{self, MemoryPlan, Part, TrainConfigFile, UpdatePlan};
use deepfoids_learn::policy::NoiseKey;
use deepfoids_learn::tensor::{ForceInit, ParamIds, clip_grad_norm, tensor1, tensor2};
use deepfoids_learn::{ACTIONS, Algorithm, BodyConfig, Grids, LearnError, Result};
use deepfoids_sensors::STACK;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// The PPO algorithm with its hyperparameters.
pub struct Ppo {
    pub config: PpoConfig,
    /// The file `config` came from, named in errors.
    pub source: PathBuf,
}

impl Ppo {
    /// The shipped config file's name: `configs/train/ppo.toml`.
    pub const DEFAULT_SOURCE: &str = "configs/train/ppo.toml";

    /// `config`, named as the shipped file.
    pub fn new(config: PpoConfig) -> Self {
        Self {
            config,
            source: PathBuf::from(Self::DEFAULT_SOURCE),
        }
    }

    /// `<configs>/train/ppo.toml`, loaded and checked.
    pub fn load(dirs: &deepfoids_env::ConfigDirs) -> Result<Self> {
        Ok(Self {
            config: PpoConfig::load(dirs)?,
            source: PpoConfig::path(dirs),
        })
    }
}

/// The longest a trajectory of `n` agents gets: `time_horizon`, or the
/// synchronous scheme's cut every `ceil(buffer_size / n)` decisions.
fn trajectory_steps(cfg: &PpoConfig, n: usize) -> usize {
    match cfg.rollout {
        RolloutScheme::MlAgents => cfg.time_horizon,
        RolloutScheme::Synchronous => cfg.time_horizon.min(cfg.buffer_size.div_ceil(n.max(1))),
    }
}

impl Ppo {
    fn trajectory_steps(&self, n: usize) -> usize {
        trajectory_steps(&self.config, n)
    }
}

/// PPO's own state of a behaviour, saved as `<behaviour>.ppo.json` in checkpoints.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PpoState {
    pub updates: u64,
    pub reward_norm: RunningMeanStd,
    /// Decisions stored since the last update (the synchronous scheme's clock).
    #[serde(default)]
    pub since_update: usize,
}

fn adam(cfg: &PpoConfig) -> ModuleOptimizer {
    AdamConfig::new()
        .with_epsilon(cfg.adam_epsilon as f32)
        .init()
}

/// The actor-critic of a configuration.
pub fn model_config(hidden: usize, layers: usize, init_log_std: f32) -> ActorCriticConfig {
    ActorCriticConfig::new()
        .with_body(BodyConfig::new().with_hidden(hidden).with_layers(layers))
        .with_init_log_std(init_log_std)
}

/// The experience not yet learned from, in a checkpoint ([`crate::inflight`]).
fn rollout_file(dir: &Path, name: &str) -> std::path::PathBuf {
    behaviour_file(dir, name, "rollout.bin")
}

/// The model file of a behaviour in a checkpoint or final folder.
pub fn model_file(dir: &Path, name: &str) -> std::path::PathBuf {
    behaviour_file(dir, name, "model.bpk")
}

/// A learner with fresh optimiser and counters for `model` (new or transferred weights).
fn fresh_learner(cfg: &PpoConfig, ctx: &LearnerCtx<'_>, model: ActorCritic) -> PpoLearner {
    PpoLearner::new(
        cfg.clone(),
        ctx,
        model,
        adam(cfg),
        PpoState {
            updates: 0,
            reward_norm: RunningMeanStd::default(),
            since_update: 0,
        },
    )
}

impl Trainer for Ppo {
    type Learner = PpoLearner;

    deepfoids_learn::trainer_config_methods!(Algorithm::Ppo);

    /// Networks: actor and critic bodies, the mean head `[hidden → 3]`, the
    /// log-std `[3]` and the value head `[hidden → 1]`. Experience: at most
    /// `buffer_size` closed transitions plus one join and the open
    /// trajectories (`2·n·steps` more), each [`FRAME_BYTES`] + 61 bytes, and
    /// each trajectory's two older frames. Update: a minibatch through both
    /// bodies ([`plan::update_bytes`]); acting: each agent's outputs and scratch.
    fn memory_plan(&self, agents: usize) -> MemoryPlan {
        let c = &self.config;
        let (h, l, n) = (c.hidden as u64, c.layers as u64, agents as u64);
        let params = 2 * plan::body_params(h, l, 0) + (h * 3 + 3) + 3 + (h + 1);
        let steps = self.trajectory_steps(agents) as u64;
        let transitions = (c.buffer_size as u64).saturating_add(2 * n * steps);
        let per_transition = (FRAME_BYTES + 4 * (VECTOR_OBS + ACTIONS + 6) + 1) as u64;
        let experience = transitions
            .saturating_mul(per_transition)
            .saturating_add(4 * n * (STACK as u64 - 1) * FRAME_BYTES as u64);
        MemoryPlan {
            parts: vec![
                plan::networks_part(params, c.hidden, c.layers),
                Part {
                    name: "experience",
                    bytes: experience,
                    fields: format!(
                        "buffer_size = {}, time_horizon = {}, {agents} agents",
                        c.buffer_size, c.time_horizon
                    ),
                },
                plan::update_part(
                    c.batch_size.min(c.buffer_size),
                    2,
                    c.hidden,
                    c.layers,
                    agents,
                ),
            ],
        }
    }

    /// ML-Agents' rollout: `n` trajectories join every `time_horizon`
    /// decisions, and an update needs `buffer_size` transitions; the
    /// synchronous one updates every `ceil(buffer_size / n)` decisions. The
    /// update comes at the decision that completes the buffer if the
    /// behaviour is still training then: the budget must exceed the
    /// transitions by one.
    fn update_plan(&self, agents: usize) -> UpdatePlan {
        let c = &self.config;
        let n = agents.max(1) as u64;
        let every = match c.rollout {
            RolloutScheme::MlAgents => {
                let join = n * c.time_horizon as u64;
                (c.buffer_size as u64).div_ceil(join) * join
            }
            RolloutScheme::Synchronous => (c.buffer_size as u64).div_ceil(n) * n,
        };
        // However the episodes end, the buffer needs `buffer_size`
        // transitions, `n` a decision.
        let earliest = match c.rollout {
            RolloutScheme::MlAgents => (c.buffer_size as u64).div_ceil(n) * n + 1,
            RolloutScheme::Synchronous => every + 1,
        };
        UpdatePlan {
            earliest,
            first: every + 1,
            every,
        }
    }

    fn update_fields(&self) -> String {
        let c = &self.config;
        match c.rollout {
            RolloutScheme::MlAgents => format!(
                "buffer_size = {}, time_horizon = {}",
                c.buffer_size, c.time_horizon
            ),
            RolloutScheme::Synchronous => {
                format!("buffer_size = {}, rollout = \"synchronous\"", c.buffer_size)
            }
        }
    }

    fn new_learner(&self, ctx: &LearnerCtx<'_>) -> Result<PpoLearner> {
        let cfg = &self.config;
        let model = model_config(cfg.hidden, cfg.layers, cfg.init_log_std).init(&ctx.train_device);
        model.visit(&mut ForceInit);
        Ok(fresh_learner(cfg, ctx, model))
    }

    fn resume_learner(
        &self,
        ctx: &LearnerCtx<'_>,
        dir: &Path,
        state: &BehaviourState,
    ) -> Result<PpoLearner> {
        let cfg = &self.config;
        let model = self.load_model(ctx, dir, &state.name)?;
        let of = behaviour_file(dir, &state.name, "optim.bpk");
        let optim = adam(cfg).load(&of).map_err(|e| LearnError::Record {
            action: "load",
            path: of.clone(),
            reason: format!("{e:?}"),
        })?;
        let ppo: PpoState =
            load_json(&behaviour_file(dir, &state.name, "ppo.json"), "PPO's state")?;
        let mut learner = PpoLearner::new(cfg.clone(), ctx, model, optim, ppo);
        // Checkpoints before issue 13 hold no rollout: start with an empty buffer.
        let file = rollout_file(dir, &state.name);
        if file.is_file() {
            learner.rollout.buffer = load_buffer(&file)?;
        }
        learner.since_update = learner.state.since_update;
        Ok(learner)
    }

    fn transfer_learner(
        &self,
        ctx: &LearnerCtx<'_>,
        from: &Path,
        source: &BehaviourState,
    ) -> Result<PpoLearner> {
        let model = self.load_model(ctx, from, &source.name)?;
        Ok(fresh_learner(&self.config, ctx, model))
    }
}

impl Ppo {
    /// Behaviour `name`'s actor-critic from policy or checkpoint folder `dir`.
    fn load_model(&self, ctx: &LearnerCtx<'_>, dir: &Path, name: &str) -> Result<ActorCritic> {
        let cfg = &self.config;
        let model = model_config(cfg.hidden, cfg.layers, cfg.init_log_std).init(&ctx.train_device);
        load_module(model, &model_file(dir, name))
    }
}

/// What an update reports.
#[derive(Clone, Copy, Debug, Default)]
struct UpdateStats {
    policy_loss: f64,
    value_loss: f64,
    entropy: f64,
    approx_kl: f64,
    clip_fraction: f64,
    learning_rate: f64,
}

/// A decision's forward pass.
struct Acted {
    values: Vec<f32>,
    mean: Vec<f32>,
    /// The unclipped samples `μ + σ·ε`.
    sampled: Vec<f32>,
}

/// One behaviour's PPO.
pub struct PpoLearner {
    cfg: PpoConfig,
    index: usize,
    name: String,
    first: usize,
    n: usize,
    model: ActorCritic,
    optim: ModuleOptimizer,
    /// The actor and critic for acting (fused forward), refreshed after each update.
    net: InferNet,
    log_std: Vec<f32>,
    rollout: Rollout,
    /// The last actions were stored: their rewards come at the next decision.
    pending: bool,
    /// Decisions stored since the last update (the synchronous scheme's clock).
    since_update: usize,
    discounted: Vec<f64>,
    state: PpoState,
    dev: Device,
    /// Critic values since the last log point.
    value_sum: f64,
    value_count: u64,
    last_update: Option<UpdateStats>,
}

impl PpoLearner {
    fn new(
        cfg: PpoConfig,
        ctx: &LearnerCtx<'_>,
        model: ActorCritic,
        optim: ModuleOptimizer,
        state: PpoState,
    ) -> Self {
        let n = ctx.info.count;
        let steps = trajectory_steps(&cfg, n);
        Self {
            net: model.infer_net(),
            log_std: model.log_std_values(),
            cfg,
            index: ctx.index,
            name: ctx.info.name.clone(),
            first: ctx.info.first,
            n,
            model,
            optim,
            rollout: Rollout::new(n, steps),
            pending: false,
            since_update: 0,
            discounted: vec![0.0; n],
            state,
            dev: ctx.train_device.clone(),
            value_sum: 0.0,
            value_count: 0,
            last_update: None,
        }
    }

    /// Transitions in the buffer (closed trajectories waiting for an update).
    pub fn buffered(&self) -> usize {
        self.rollout.buffer.transitions()
    }

    /// Steps in each agent's open trajectory.
    pub fn open_lengths(&self) -> Vec<usize> {
        self.rollout.open.iter().map(|t| t.len()).collect()
    }

    /// Rewards and episode ends of the decision that just ended, scaled, into
    /// the open trajectories with their stop codes.
    fn record(&mut self, batch: &BehaviourBatch) {
        let cfg = &self.cfg;
        let returns: Vec<f64> = (0..self.n)
            .map(|a| {
                self.discounted[a] =
                    cfg.gamma as f64 * self.discounted[a] + batch.rewards[a] as f64;
                self.discounted[a]
            })
            .collect();
        self.state.reward_norm.update(&returns);
        let scale = if cfg.normalize_rewards {
            1.0 / self.state.reward_norm.std() as f32
        } else {
            1.0
        };
        self.since_update += 1;
        let boundary = cfg.rollout == RolloutScheme::Synchronous
            && self.since_update >= cfg.buffer_size.div_ceil(self.n);
        for a in 0..self.n {
            let (term, trunc) = (batch.terminated[a], batch.truncated[a]);
            let t = &mut self.rollout.open[a];
            let stop = if term {
                TERMINAL
            } else if trunc || t.len() >= cfg.time_horizon || boundary {
                BOOTSTRAP
            } else {
                CONTINUE
            };
            t.reward(batch.rewards[a] * scale, stop);
            if term || trunc {
                self.discounted[a] = 0.0;
            }
        }
        self.pending = false;
    }

    /// Close the trajectories that ended, bootstrapping from `values` of the
    /// next observations.
    fn close_ended(&mut self, values: &[f32]) {
        for (a, &v) in values.iter().enumerate() {
            if matches!(self.rollout.open[a].last_stop(), Some(s) if s != CONTINUE) {
                self.rollout
                    .close(a, v, self.cfg.gamma, self.cfg.gae_lambda);
            }
        }
    }

    /// Whether the buffer is ready for an update.
    fn update_due(&self) -> bool {
        match self.cfg.rollout {
            RolloutScheme::MlAgents => self.rollout.buffer.transitions() >= self.cfg.buffer_size,
            RolloutScheme::Synchronous => {
                self.since_update >= self.cfg.buffer_size.div_ceil(self.n)
            }
        }
    }

    /// The policy and the critic on the batch's observations (fused forward,
    /// no autodiff) and sampled actions: the environment's (clipped) into
    /// `actions`.
    fn policy(&self, batch: &BehaviourBatch, actions: &mut [f32], ctx: &mut StepCtx<'_>) -> Acted {
        let t0 = Instant::now();
        let mut out = self.net.forward(batch.observations(), &batch.vectors);
        let values = out.pop().expect("the critic's output");
        let mean = out.pop().expect("the actor's output");
        let mut sampled = vec![0.0f32; self.n * ACTIONS];
        let key = NoiseKey {
            seed: ctx.seed,
            first: self.first,
            tick: ctx.tick,
        };
        for a in 0..self.n {
            let mut noise = key.stream(a);
            for k in 0..ACTIONS {
                let i = a * ACTIONS + k;
                sampled[i] = mean[i] + self.log_std[k].exp() * noise.normal();
                actions[i] = sampled[i].clamp(-1.0, 1.0);
            }
        }
        ctx.timing.inference += t0.elapsed();
        Acted {
            values,
            mean,
            sampled,
        }
    }

    /// The decision's steps into the open trajectories (log-probabilities of
    /// the unclipped samples).
    fn store(&mut self, batch: &BehaviourBatch, acted: &Acted) {
        for a in 0..self.n {
            let r = a * ACTIONS..(a + 1) * ACTIONS;
            let lp = log_prob_f32(
                &acted.mean[r.clone()],
                &self.log_std,
                &acted.sampled[r.clone()],
            );
            self.rollout.open[a].push(
                stack_of(batch.observations(), a),
                &batch.vectors[a * VECTOR_OBS..(a + 1) * VECTOR_OBS],
                &acted.sampled[r],
                lp,
                acted.values[a],
            );
            self.value_sum += acted.values[a] as f64;
        }
        self.value_count += self.n as u64;
        self.pending = true;
    }

    /// GAE is done per trajectory; here: flatten → minibatches → losses →
    /// optimiser steps, `epochs` passes over the buffer (CleanRL's update).
    fn update(&mut self, ctx: &mut StepCtx<'_>) -> Result<()> {
        let t_update = Instant::now();
        let cfg = self.cfg.clone();
        let lr = match cfg.lr_schedule {
            Schedule::Linear => {
                cfg.learning_rate
                    * (1.0 - ctx.agent_steps as f64 / ctx.budget.max(1) as f64).max(0.0)
            }
            Schedule::Constant => cfg.learning_rate,
        };
        let actor_ids = ParamIds::default()
            .with(&self.model.actor_body)
            .with(&self.model.actor_mean)
            .with_param(&self.model.log_std);
        let critic_ids = ParamIds::default()
            .with(&self.model.critic_body)
            .with(&self.model.critic_head);
        let mut b_inds = self.rollout.buffer.indices();
        let total = b_inds.len();
        let mb_size = cfg.batch_size.min(total);
        let (mut pg_sum, mut v_sum, mut kl_sum, mut clip_sum, mut count) =
            (0.0, 0.0, 0.0, 0.0, 0usize);
        let mut entropy_now = None;
        let dev = self.dev.clone();
        for epoch in 0..cfg.epochs {
            let mut shuffle = Stream::new(
                ctx.seed,
                Purpose::Shuffle,
                self.index as u64,
                self.state.updates * cfg.epochs as u64 + epoch as u64,
            );
            for i in (1..total).rev() {
                b_inds.swap(i, shuffle.below(i + 1));
            }
            for mb_inds in b_inds.chunks_exact(mb_size.max(1)) {
                let t = Instant::now();
                let m = mb_inds.len();
                let mb = self.rollout.buffer.gather(mb_inds);
                let mut mb_advantages = mb.advantages;
                if cfg.normalize_advantages && m > 1 {
                    let mean = mb_advantages.iter().sum::<f32>() / m as f32;
                    let var = mb_advantages
                        .iter()
                        .map(|x| (x - mean).powi(2))
                        .sum::<f32>()
                        / (m - 1) as f32;
                    let std = var.sqrt();
                    for x in &mut mb_advantages {
                        *x = (*x - mean) / (std + 1e-8);
                    }
                }
                let grids = Grids::Compact(Arc::new(mb.grids));
                let vector = tensor2(mb.vectors, m, VECTOR_OBS, &dev);
                ctx.timing.part("gather", t.elapsed());
                let t = Instant::now();
                let (mean, log_std, newvalue) = self.model.forward(&grids, vector);
                let newlogprob =
                    log_prob(mean, log_std.clone(), tensor2(mb.actions, m, ACTIONS, &dev));
                let entropy_t = entropy(log_std);
                let logratio = newlogprob - tensor1(mb.logprobs, &dev);
                let ratio = logratio.clone().exp();
                let pg_loss = clipped_surrogate(
                    ratio.clone(),
                    tensor1(mb_advantages, &dev),
                    cfg.clip_epsilon,
                );
                let v_loss = (newvalue - tensor1(mb.returns, &dev))
                    .powf_scalar(2.0)
                    .mean();
                let loss = pg_loss.clone() + v_loss.clone().mul_scalar(cfg.value_coef)
                    - entropy_t.clone().mul_scalar(cfg.entropy_coef);
                // Diagnostics (no gradient): approx KL and clip fraction (CleanRL).
                let approx_kl = ((ratio.clone() - 1.0) - logratio)
                    .mean()
                    .into_scalar::<f32>();
                let clipped = (ratio - 1.0)
                    .abs()
                    .greater_elem(cfg.clip_epsilon)
                    .float()
                    .mean()
                    .into_scalar::<f32>();
                let (pg, vl) = (pg_loss.into_scalar::<f32>(), v_loss.into_scalar::<f32>());
                let loss_value = loss.clone().into_scalar::<f32>();
                ctx.timing.part("forward", t.elapsed());
                if !loss_value.is_finite() {
                    return Err(LearnError::NonFinite {
                        update: self.state.updates + 1,
                        behaviour: self.name.clone(),
                        what: format!("the loss (policy loss {pg}, value loss {vl})"),
                    });
                }
                let t = Instant::now();
                let mut grads = GradientsParams::from_grads(loss.backward(), &self.model);
                ctx.timing.part("backward", t.elapsed());
                let t = Instant::now();
                clip_grad_norm(&mut grads, &actor_ids, cfg.max_grad_norm);
                clip_grad_norm(&mut grads, &critic_ids, cfg.max_grad_norm);
                self.model = self.optim.step(lr, self.model.clone(), grads);
                ctx.timing.part("optimiser", t.elapsed());
                pg_sum += pg as f64;
                v_sum += vl as f64;
                kl_sum += approx_kl as f64;
                clip_sum += clipped as f64;
                entropy_now = Some(entropy_t.into_scalar::<f32>() as f64);
                count += 1;
            }
        }
        self.net = self.model.infer_net();
        self.log_std = self.model.log_std_values();
        if self.log_std.iter().any(|x| !x.is_finite()) {
            return Err(LearnError::NonFinite {
                update: self.state.updates + 1,
                behaviour: self.name.clone(),
                what: "the policy's log-std".into(),
            });
        }
        self.state.updates += 1;
        self.rollout.clear_buffer();
        self.since_update = 0;
        let c = count.max(1) as f64;
        self.last_update = Some(UpdateStats {
            policy_loss: pg_sum / c,
            value_loss: v_sum / c,
            entropy: entropy_now.unwrap_or_else(|| entropy_f32(&self.log_std) as f64),
            approx_kl: kl_sum / c,
            clip_fraction: clip_sum / c,
            learning_rate: lr,
        });
        ctx.timing.update += t_update.elapsed();
        Ok(())
    }
}

/// The clipped surrogate loss (PPO, Eq. 7 of Schulman et al. 2017, negated):
/// `mean(max(−A·ρ, −A·clip(ρ, 1 − ε, 1 + ε)))` for ratios `ρ = π/π_old`.
pub fn clipped_surrogate(ratio: Tensor<1>, advantages: Tensor<1>, epsilon: f32) -> Tensor<1> {
    let pg_loss1 = -advantages.clone() * ratio.clone();
    let pg_loss2 = -advantages * ratio.clamp(1.0 - epsilon, 1.0 + epsilon);
    pg_loss1.max_pair(pg_loss2).mean()
}

impl Learner for PpoLearner {
    fn start(
        &mut self,
        batch: &BehaviourBatch,
        actions: &mut [f32],
        ctx: &mut StepCtx<'_>,
    ) -> Result<()> {
        // A fresh environment: nothing collected before belongs with what follows.
        self.rollout.drop_open();
        let acted = self.policy(batch, actions, ctx);
        if ctx.training {
            self.store(batch, &acted);
        }
        Ok(())
    }

    fn decide(
        &mut self,
        batch: &BehaviourBatch,
        actions: &mut [f32],
        ctx: &mut StepCtx<'_>,
    ) -> Result<()> {
        if self.pending {
            self.record(batch);
        }
        // The next observations' values bootstrap the trajectories that ended.
        let acted = self.policy(batch, actions, ctx);
        self.close_ended(&acted.values);
        if !ctx.training {
            // The budget is reached: what is left is never trained on (as ML-Agents).
            self.rollout.drop_open();
            return Ok(());
        }
        if self.update_due() {
            self.update(ctx)?;
        }
        self.store(batch, &acted);
        Ok(())
    }

    fn log_due(&self, _agent_steps: u64) -> bool {
        self.last_update.is_some()
    }

    fn log(&mut self, out: &mut Scalars<'_>) -> Result<()> {
        if let Some(s) = self.last_update.take() {
            out.put("Losses/Policy Loss", s.policy_loss)?;
            out.put("Losses/Value Loss", s.value_loss)?;
            out.put("Policy/Entropy", s.entropy)?;
            out.put("Policy/Learning Rate", s.learning_rate)?;
            out.put("Policy/Approx KL", s.approx_kl)?;
            out.put("Policy/Clip Fraction", s.clip_fraction)?;
        }
        if self.value_count > 0 {
            out.put(
                "Policy/Extrinsic Value Estimate",
                self.value_sum / self.value_count as f64,
            )?;
        }
        self.value_sum = 0.0;
        self.value_count = 0;
        Ok(())
    }

    fn updates(&self) -> u64 {
        self.state.updates
    }

    fn before_checkpoint(&mut self) -> Result<()> {
        cut_open(&mut self.rollout, self.cfg.gamma, self.cfg.gae_lambda);
        Ok(())
    }

    fn save(&self, dir: &Path, name: &str, checkpoint: bool) -> Result<()> {
        save_module(&self.model, &model_file(dir, name))?;
        if checkpoint {
            let of = behaviour_file(dir, name, "optim.bpk");
            self.optim.save(&of).map_err(|e| LearnError::Record {
                action: "save",
                path: of.clone(),
                reason: format!("{e:?}"),
            })?;
            let state = PpoState {
                since_update: self.since_update,
                ..self.state.clone()
            };
            save_json(&behaviour_file(dir, name, "ppo.json"), &state)?;
            save_buffer(&self.rollout.buffer, &rollout_file(dir, name))?;
        }
        Ok(())
    }

    fn actor_onnx(&self, meta: &Metadata) -> Vec<u8> {
        self.model.actor_onnx(meta)
    }

    fn memory(&self) -> BufferMemory {
        let open: usize = self.rollout.open.iter().map(|t| t.len()).sum();
        BufferMemory {
            allocated: self.rollout.capacity_bytes() as u64,
            resident: self.rollout.len_bytes() as u64,
            transitions: (self.rollout.buffer.transitions() + open) as u64,
            peak: self.rollout.peak_bytes.max(self.rollout.capacity_bytes()) as u64,
        }
    }
}
