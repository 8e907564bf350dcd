//! PPO training, read top to bottom as CleanRL's `ppo_continuous_action.py`:
//! arguments → environment → agents → loop of (rollout → GAE → flatten →
//! minibatches → losses → optimiser step → log).
//!
//! # Choices (the "implementation details" of PPO, and ML-Agents' conventions)
//! * One actor-critic and one Adam (ε 1e−8) per behaviour; all its agents share it.
//! * Rollout: each behaviour fills a buffer of `ceil(buffer_size / agents)`
//!   decisions of all its agents (≥ 10,240 transitions); each agent's trajectory
//!   is cut every `time_horizon` (64) decisions and bootstrapped from the critic
//!   there; *terminated* ⇒ no bootstrap; *truncated* ⇒ bootstrap (`gae`).
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
//! * Learning rate: linear from `learning_rate` to 0 over the budget, by agent steps.
//! * Minibatches: `epochs` passes, each a fresh shuffle (keyed by the update),
//!   in `floor(samples / batch_size)` minibatches (the remainder waits for the next pass).
//! * Observations are used as they are (the grid is in [0, 1]; the vector is small).
//! * Checkpoints are written at the first decision past each `checkpoint_every`
//!   agent steps (weights, Adam state, counters, reward statistics); a resumed
//!   run starts fresh rollouts (the partial one is not saved) from a reset
//!   environment reseeded with `seed + resets`.

use crate::checkpoint::{self, BehaviourState, RunState, RunningMeanStd};
use crate::config::{PpoConfig, Schedule};
use crate::gae::{BOOTSTRAP, CONTINUE, TERMINAL, gae};
use crate::gaussian::{entropy, entropy_f32, log_prob, log_prob_f32};
use crate::logger::Logger;
use crate::model::{ACTIONS, ActorCritic, ActorCriticConfig, BodyConfig};
use crate::stats::EpisodeStats;
use anyhow::{Context, Result, bail};
use burn::module::{ModuleVisitor, Param};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::prelude::*;
use deepfoids_env::rng::{Purpose, Stream};
use deepfoids_env::{BehaviourBatch, Env, Scene, StepOutput, VECTOR_OBS};
use deepfoids_sensors::{AZ_CELLS, EL_CELLS, STACKED_CHANNELS, STACKED_LEN};
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The compute backend.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// Burn's ndarray backend, with the `ndarray` cargo feature.
    #[cfg(feature = "ndarray")]
    NdArray,
    Flex,
}

impl Backend {
    #[allow(deprecated)] // Device::ndarray is deprecated in Burn 0.22.
    pub fn device(&self) -> Device {
        match self {
            #[cfg(feature = "ndarray")]
            Backend::NdArray => Device::ndarray(),
            Backend::Flex => Device::flex(),
        }
    }

    pub fn as_str(&self) -> &'static str {
        match self {
            #[cfg(feature = "ndarray")]
            Backend::NdArray => "ndarray",
            Backend::Flex => "flex",
        }
    }

    /// Whether the convolutions run as GEMMs on this backend (see `model::conv1_gemm`).
    pub fn gemm_conv(&self) -> bool {
        matches!(self, Backend::Flex)
    }
}

impl std::str::FromStr for Backend {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            #[cfg(feature = "ndarray")]
            "ndarray" => Ok(Backend::NdArray),
            #[cfg(not(feature = "ndarray"))]
            "ndarray" => Err(
                "the ndarray backend is not compiled in; build with `--features ndarray` (e.g. `cargo run --release --features ndarray -- …`)".into(),
            ),
            "flex" => Ok(Backend::Flex),
            _ => Err(format!("unknown backend `{s}`; allowed: flex, ndarray")),
        }
    }
}

/// What to train, where.
pub struct TrainArgs {
    pub scene: Scene,
    pub config: PpoConfig,
    pub run_dir: PathBuf,
    pub run_id: String,
    pub seed: u64,
    /// Agent decisions to train for (all behaviours); default: the thesis' budget.
    pub steps: Option<u64>,
    pub resume: bool,
    /// A run to take the initial weights from (transfer learning).
    pub init_from: Option<PathBuf>,
    pub backend: Backend,
    /// Show a progress bar.
    pub progress: bool,
    /// Write checkpoints and the final policy (off for benchmarks).
    pub save: bool,
}

/// Wall-clock split of a run.
#[derive(Clone, Copy, Debug, Default)]
pub struct Timing {
    pub env: Duration,
    pub inference: Duration,
    pub update: Duration,
}

/// What a run reports back.
pub struct TrainOutcome {
    pub run_dir: PathBuf,
    pub agent_steps: u64,
    pub steps_this_run: u64,
    pub wall_seconds: f64,
    pub timing: Timing,
    /// `(agent steps, mean reward per decision)` after each update, all behaviours.
    pub curve: Vec<(u64, f64)>,
    /// `(agent steps, mean cumulative reward of the episodes finished)` where any finished.
    pub episode_curve: Vec<(u64, f64)>,
    pub final_dir: Option<PathBuf>,
    /// The experience buffers at the end: bytes allocated, bytes written to
    /// (resident), and transitions held — PPO's rollout buffers, SAC's replay.
    pub buffer: BufferMemory,
}

/// Size of a trainer's experience buffers.
#[derive(Clone, Copy, Debug, Default)]
pub struct BufferMemory {
    pub allocated: u64,
    pub resident: u64,
    pub transitions: u64,
}

/// The transitions of one behaviour, step-major: slot `s·n + a` is agent `a` at step `s`.
struct Buffer {
    steps: usize,
    len: usize,
    grids: Vec<f32>,
    vectors: Vec<f32>,
    actions: Vec<f32>,
    logprobs: Vec<f32>,
    values: Vec<f32>,
    rewards: Vec<f32>,
    stops: Vec<u8>,
}

impl Buffer {
    /// Bytes of the rollout buffer (all written by the first rollout).
    fn bytes(&self) -> u64 {
        4 * (self.grids.len()
            + self.vectors.len()
            + self.actions.len()
            + self.logprobs.len()
            + self.values.len()
            + self.rewards.len()) as u64
            + self.stops.len() as u64
    }

    fn new(steps: usize, n: usize) -> Self {
        let m = steps * n;
        Self {
            steps,
            len: 0,
            grids: vec![0.0; m * STACKED_LEN],
            vectors: vec![0.0; m * VECTOR_OBS],
            actions: vec![0.0; m * ACTIONS],
            logprobs: vec![0.0; m],
            values: vec![0.0; m],
            rewards: vec![0.0; m],
            stops: vec![0; m],
        }
    }
}

/// The critic's value estimates since the last log line.
#[derive(Default)]
struct ValueWindow {
    sum: f64,
    count: u64,
}

/// One behaviour's learner.
struct Learner {
    name: String,
    species: String,
    size_class: String,
    n: usize,
    first: usize,
    model: ActorCritic,
    optim: ModuleOptimizer,
    infer: ActorCritic,
    buf: Buffer,
    pending: bool,
    since_cut: Vec<u32>,
    discounted: Vec<f64>,
    reward_norm: RunningMeanStd,
    agent_steps: u64,
    updates: u64,
    stats: EpisodeStats,
    values: ValueWindow,
}

/// Everything an update reports.
struct UpdateStats {
    policy_loss: f64,
    value_loss: f64,
    entropy: f64,
    approx_kl: f64,
    clip_fraction: f64,
}

pub fn tensor4(data: Vec<f32>, n: usize, dev: &Device) -> Tensor<4> {
    Tensor::from_data(
        TensorData::new(data, [n, STACKED_CHANNELS, EL_CELLS, AZ_CELLS]),
        dev,
    )
}

pub fn tensor2(data: Vec<f32>, n: usize, width: usize, dev: &Device) -> Tensor<2> {
    Tensor::from_data(TensorData::new(data, [n, width]), dev)
}

pub fn to_vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().try_into_vec::<f32>().expect("an f32 tensor")
}

/// Burn initialises parameters lazily; touch them all so a seeded init is reproducible.
pub struct ForceInit;
impl ModuleVisitor for ForceInit {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        let _ = p.val();
    }
}

/// Sum of squared gradients of the visited parameters.
struct GradSquares<'a> {
    grads: &'a GradientsParams,
    sum: Option<Tensor<1>>,
}
impl ModuleVisitor for GradSquares<'_> {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.get::<D>(p.id) {
            let s = g.square().sum();
            self.sum = Some(match self.sum.take() {
                Some(a) => a + s,
                None => s,
            });
        }
    }
}

/// Multiply the gradients of the visited parameters by `scale`.
struct GradScale<'a> {
    grads: &'a mut GradientsParams,
    scale: f32,
}
impl ModuleVisitor for GradScale<'_> {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.remove::<D>(p.id) {
            self.grads.register::<D>(p.id, g.mul_scalar(self.scale));
        }
    }
}

/// Clip the actor's and the critic's gradients each to a global norm of `max_norm`.
fn clip_gradients(model: &ActorCritic, grads: &mut GradientsParams, max_norm: f32) {
    let norm_of = |visit: &dyn Fn(&mut GradSquares)| {
        let mut v = GradSquares { grads, sum: None };
        visit(&mut v);
        v.sum.map_or(0.0, |s| s.into_scalar::<f32>().sqrt())
    };
    let actor = norm_of(&|v| {
        model.actor_body.visit(v);
        model.actor_mean.visit(v);
        v.visit_float(&model.log_std);
    });
    let critic = norm_of(&|v| {
        model.critic_body.visit(v);
        model.critic_head.visit(v);
    });
    if actor > max_norm {
        let mut s = GradScale {
            grads,
            scale: max_norm / (actor + 1e-6),
        };
        model.actor_body.visit(&mut s);
        model.actor_mean.visit(&mut s);
        s.visit_float(&model.log_std);
    }
    if critic > max_norm {
        let mut s = GradScale {
            grads,
            scale: max_norm / (critic + 1e-6),
        };
        model.critic_body.visit(&mut s);
        model.critic_head.visit(&mut s);
    }
}

/// The clipped surrogate loss (PPO, Eq. 7 of Schulman et al. 2017, negated):
/// `mean(max(−A·ρ, −A·clip(ρ, 1 − ε, 1 + ε)))` for ratios `ρ = π/π_old`.
pub fn clipped_surrogate(ratio: Tensor<1>, advantages: Tensor<1>, epsilon: f32) -> Tensor<1> {
    let pg_loss1 = -advantages.clone() * ratio.clone();
    let pg_loss2 = -advantages * ratio.clamp(1.0 - epsilon, 1.0 + epsilon);
    pg_loss1.max_pair(pg_loss2).mean()
}

fn adam(cfg: &PpoConfig) -> ModuleOptimizer {
    AdamConfig::new()
        .with_epsilon(cfg.adam_epsilon as f32)
        .init()
}

fn model_config(cfg: &PpoConfig, backend: Backend) -> ActorCriticConfig {
    ActorCriticConfig::new()
        .with_body(
            BodyConfig::new()
                .with_hidden(cfg.hidden)
                .with_layers(cfg.layers)
                .with_gemm_conv(backend.gemm_conv()),
        )
        .with_init_log_std(cfg.init_log_std)
}

/// Load the weights of behaviour `name` (or, failing that, of a behaviour of the same
/// species) from a policy folder.
pub fn load_weights(
    dir: &std::path::Path,
    state: &RunState,
    name: &str,
    species: &str,
    model: ActorCritic,
) -> Result<ActorCritic> {
    let source = state
        .behaviour(name)
        .or_else(|| state.behaviours.iter().find(|b| b.species == species))
        .with_context(|| {
            format!(
                "{} has no policy for behaviour {name} or species {species}; it has: {}",
                dir.display(),
                state
                    .behaviours
                    .iter()
                    .map(|b| b.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })?;
    let file = RunState::model_file(dir, &source.name);
    model
        .try_load_file(&file)
        .map_err(|e| anyhow::anyhow!("cannot load {}: {e:?}", file.display()))
}

/// Train PPO on a scene. See the module documentation.
pub fn train(args: TrainArgs) -> Result<TrainOutcome> {
    // ---- Arguments ---------------------------------------------------------------
    let cfg = args.config.clone();
    let run_dir = args.run_dir.clone();
    std::fs::create_dir_all(&run_dir)
        .with_context(|| format!("cannot create {}", run_dir.display()))?;
    let budget = args
        .steps
        .unwrap_or_else(|| cfg.budget(&args.scene, args.scene.phase));
    let dev = args.backend.device();
    let ad = dev.clone().autodiff();
    let resume_from = if args.resume {
        let all = checkpoint::checkpoints(&run_dir);
        match all.last() {
            Some((_, d)) => Some(d.clone()),
            None => bail!(
                "--resume: {} has no checkpoint to resume from",
                run_dir.display()
            ),
        }
    } else {
        None
    };
    let resumed: Option<RunState> = resume_from.as_deref().map(RunState::load).transpose()?;
    if let Some(st) = &resumed {
        if st.scene != args.scene.id || st.algo != "ppo" {
            bail!(
                "--resume: run {} trained {} on {}, not ppo on {}",
                run_dir.display(),
                st.algo,
                st.scene,
                args.scene.id
            );
        }
        if !st.matches_architecture(&cfg) {
            bail!(
                "--resume: the run's network ({}×{}) differs from configs/train/ppo.toml",
                st.layers,
                st.hidden
            );
        }
    }

    // ---- Environment -------------------------------------------------------------
    let resets = resumed.as_ref().map_or(0, |s| s.resets + 1);
    let mut env = Env::new(args.scene.clone(), args.seed.wrapping_add(resets));
    let mut tick = resumed.as_ref().map_or(0, |s| s.ticks);

    // ---- Agents: one actor-critic and optimiser per behaviour --------------------
    let init_source = match &args.init_from {
        Some(run) => {
            let dir = checkpoint::policy_dir(run, None)?;
            let st = RunState::load(&dir)?;
            if !st.matches_architecture(&cfg) {
                bail!(
                    "--init-from: the network of {} ({}×{}) differs from configs/train/ppo.toml",
                    run.display(),
                    st.layers,
                    st.hidden
                );
            }
            Some((dir, st))
        }
        None => None,
    };
    dev.seed(args.seed);
    let mut learners: Vec<Learner> = Vec::new();
    for (b, info) in env.behaviours().iter().enumerate() {
        let mut model = model_config(&cfg, args.backend).init(&ad);
        model.visit(&mut ForceInit);
        let mut optim = adam(&cfg);
        let (mut agent_steps, mut updates, mut reward_norm) = (0, 0, RunningMeanStd::default());
        if let (Some(dir), Some(st)) = (&resume_from, &resumed) {
            model = load_weights(dir, st, &info.name, &info.species, model)?;
            let of = RunState::optim_file(dir, &info.name);
            optim = adam(&cfg)
                .load(&of)
                .map_err(|e| anyhow::anyhow!("cannot load {}: {e:?}", of.display()))?;
            if let Some(bs) = st.behaviour(&info.name) {
                (agent_steps, updates, reward_norm) =
                    (bs.agent_steps, bs.updates, bs.reward_norm.clone());
            }
        } else if let Some((dir, st)) = &init_source {
            model = load_weights(dir, st, &info.name, &info.species, model)?;
        }
        let steps = cfg.buffer_size.div_ceil(info.count);
        let _ = b;
        learners.push(Learner {
            name: info.name.clone(),
            species: info.species.clone(),
            size_class: info.size_class.clone(),
            n: info.count,
            first: info.first,
            infer: model.valid(),
            model,
            optim,
            buf: Buffer::new(steps, info.count),
            pending: false,
            since_cut: vec![0; info.count],
            discounted: vec![0.0; info.count],
            reward_norm,
            agent_steps,
            updates,
            stats: EpisodeStats::new(info.first, info.count),
            values: ValueWindow::default(),
        });
    }
    let names: Vec<String> = learners.iter().map(|l| l.name.clone()).collect();
    let mut logger = Logger::open(&run_dir, &names)?;
    let mut state = resumed.clone().unwrap_or_else(|| RunState {
        algo: "ppo".into(),
        run_id: args.run_id.clone(),
        scene: args.scene.id.clone(),
        phase: args.scene.phase,
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
        init_log_std: cfg.init_log_std,
        behaviours: vec![],
    });
    state.resets = resets;
    state.budget = budget;
    let start_steps = state.agent_steps;
    let mut next_checkpoint = (state.agent_steps / cfg.checkpoint_every + 1) * cfg.checkpoint_every;
    let bar = progress_bar(args.progress, budget, state.agent_steps);
    let mut timing = Timing::default();
    let mut curve = Vec::new();
    let mut episode_curve = Vec::new();
    let started = Instant::now();
    let wall_before = state.wall_seconds;
    let mut actions: Vec<Vec<f32>> = learners.iter().map(|l| vec![0.0; l.n * ACTIONS]).collect();

    // First actions from the initial observations.
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
            l.record(batch, out, &cfg);
            state.agent_steps += l.n as u64;
            if l.buf.len == l.buf.steps {
                // Bootstrap values with the policy that collected the rollout, then update.
                let t1 = Instant::now();
                let last_values = l.values(batch, &dev);
                timing.inference += t1.elapsed();
                let t2 = Instant::now();
                let progress = state.agent_steps as f64 / budget as f64;
                let lr = match cfg.lr_schedule {
                    Schedule::Linear => cfg.learning_rate * (1.0 - progress).max(0.0),
                    Schedule::Constant => cfg.learning_rate,
                };
                let stats = l.update(&last_values, &cfg, lr, args.seed, &dev, b)?;
                timing.update += t2.elapsed();
                let elapsed = wall_before + started.elapsed().as_secs_f64();
                let rate = (state.agent_steps - start_steps) as f64
                    / started.elapsed().as_secs_f64().max(1e-9);
                let (reward, ep) = l.log(&mut logger, b, &stats, lr, rate)?;
                curve.push((state.agent_steps, reward));
                if let Some(ep) = ep {
                    episode_curve.push((state.agent_steps, ep));
                }
                if let Some(bar) = &bar {
                    bar.set_message(format!("{}: reward/decision {reward:.2}", l.name));
                }
                state.wall_seconds = elapsed;
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
            save(&run_dir, Some(state.agent_steps), &learners, &mut state)?;
            checkpoint::prune(&run_dir, cfg.keep_checkpoints);
            logger.flush()?;
            next_checkpoint += cfg.checkpoint_every;
        }
    }
    state.ticks = tick;
    state.wall_seconds = wall_before + started.elapsed().as_secs_f64();
    let final_dir = if args.save {
        let fin = run_dir.join("final");
        let _ = std::fs::remove_dir_all(&fin);
        save(&run_dir, None, &learners, &mut state)?;
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
        buffer: learners.iter().fold(BufferMemory::default(), |m, l| {
            let bytes = l.buf.bytes();
            BufferMemory {
                allocated: m.allocated + bytes,
                resident: m.resident + bytes,
                transitions: m.transitions + (l.buf.steps * l.n) as u64,
            }
        }),
    })
}

pub fn progress_bar(show: bool, budget: u64, done: u64) -> Option<indicatif::ProgressBar> {
    if !show {
        return None;
    }
    let bar = indicatif::ProgressBar::new(budget);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:30} {pos}/{len} steps · {per_sec} · ETA {eta} · {msg}",
        )
        .expect("a valid template"),
    );
    bar.set_position(done);
    Some(bar)
}

/// Save every learner into a checkpoint (`Some(step)`) or `final/`, atomically.
fn save(
    run_dir: &std::path::Path,
    step: Option<u64>,
    learners: &[Learner],
    state: &mut RunState,
) -> Result<()> {
    state.behaviours = learners
        .iter()
        .map(|l| BehaviourState {
            name: l.name.clone(),
            species: l.species.clone(),
            size_class: l.size_class.clone(),
            agent_steps: l.agent_steps,
            updates: l.updates,
            reward_norm: l.reward_norm.clone(),
        })
        .collect();
    let dir = match step {
        Some(s) => checkpoint::checkpoint_dir(run_dir, s),
        None => run_dir.join("final"),
    };
    if dir.exists() {
        std::fs::remove_dir_all(&dir)
            .with_context(|| format!("cannot replace {}", dir.display()))?;
    }
    std::fs::create_dir_all(dir.parent().expect("a run folder")).ok();
    deepfoids_env::io::create_dir_atomic(&dir, |tmp| {
        for l in learners {
            l.model
                .clone()
                .save_file(RunState::model_file(tmp, &l.name))
                .map_err(|e| std::io::Error::other(format!("saving {}: {e:?}", l.name)))?;
            if step.is_some() {
                l.optim
                    .save(RunState::optim_file(tmp, &l.name))
                    .map_err(|e| {
                        std::io::Error::other(format!("saving the optimiser of {}: {e:?}", l.name))
                    })?;
            }
        }
        state.save(tmp).map_err(std::io::Error::other)
    })
    .with_context(|| format!("cannot write {}", dir.display()))
}

impl Learner {
    /// Observation slices of this behaviour's batch as tensors.
    fn obs_tensors(batch: &BehaviourBatch, dev: &Device) -> (Tensor<4>, Tensor<2>) {
        let n = batch.n_agents;
        (
            tensor4(batch.grids.clone(), n, dev),
            tensor2(batch.vectors.clone(), n, VECTOR_OBS, dev),
        )
    }

    /// Critic values of the batch's observations, with the rollout policy.
    fn values(&self, batch: &BehaviourBatch, dev: &Device) -> Vec<f32> {
        let (g, v) = Self::obs_tensors(batch, dev);
        to_vec(self.infer.value(g, v))
    }

    /// Choose actions for the batch's observations and remember them in the buffer.
    fn act(
        &mut self,
        batch: &BehaviourBatch,
        actions: &mut [f32],
        seed: u64,
        tick: u64,
        dev: &Device,
    ) {
        let n = self.n;
        let (g, v) = Self::obs_tensors(batch, dev);
        let (mean, log_std) = self.infer.actor(g.clone(), v.clone());
        let values = to_vec(self.infer.value(g, v));
        let (mean, log_std) = (to_vec(mean), to_vec(log_std));
        let slot = self.buf.len;
        let at = slot * n;
        self.buf.grids[at * STACKED_LEN..(at + n) * STACKED_LEN].copy_from_slice(&batch.grids);
        self.buf.vectors[at * VECTOR_OBS..(at + n) * VECTOR_OBS].copy_from_slice(&batch.vectors);
        for a in 0..n {
            let mut noise = Stream::new(seed, Purpose::Exploration, (self.first + a) as u64, tick);
            let mu = &mean[a * ACTIONS..(a + 1) * ACTIONS];
            let mut act = [0.0f32; ACTIONS];
            for k in 0..ACTIONS {
                act[k] = mu[k] + log_std[k].exp() * noise.normal();
                actions[a * ACTIONS + k] = act[k].clamp(-1.0, 1.0);
            }
            self.buf.actions[(at + a) * ACTIONS..(at + a + 1) * ACTIONS].copy_from_slice(&act);
            self.buf.logprobs[at + a] = log_prob_f32(mu, &log_std, &act);
            self.buf.values[at + a] = values[a];
            self.values.sum += values[a] as f64;
        }
        self.values.count += n as u64;
        self.pending = true;
    }

    /// The rewards and episode ends of the decision that just finished.
    fn record(&mut self, batch: &BehaviourBatch, out: &StepOutput, cfg: &PpoConfig) {
        if !self.pending {
            return;
        }
        let n = self.n;
        let at = self.buf.len * n;
        // Reward scaling: running std of the discounted return (reset at episode ends).
        let mut returns = Vec::with_capacity(n);
        for a in 0..n {
            self.discounted[a] = cfg.gamma as f64 * self.discounted[a] + batch.rewards[a] as f64;
            returns.push(self.discounted[a]);
        }
        self.reward_norm.update(&returns);
        let scale = if cfg.normalize_rewards {
            1.0 / self.reward_norm.std() as f32
        } else {
            1.0
        };
        for a in 0..n {
            let (r, term, trunc) = (batch.rewards[a], batch.terminated[a], batch.truncated[a]);
            self.buf.rewards[at + a] = r * scale;
            self.since_cut[a] += 1;
            self.buf.stops[at + a] = if term {
                TERMINAL
            } else if trunc || self.since_cut[a] as usize >= cfg.time_horizon {
                BOOTSTRAP
            } else {
                CONTINUE
            };
            if self.buf.stops[at + a] != CONTINUE {
                self.since_cut[a] = 0;
            }
            if term || trunc {
                self.discounted[a] = 0.0;
            }
        }
        self.stats.record(batch, out);
        self.agent_steps += n as u64;
        self.buf.len += 1;
        self.pending = false;
    }

    /// GAE → flatten → minibatches → losses → optimiser steps (CleanRL's update).
    fn update(
        &mut self,
        last_values: &[f32],
        cfg: &PpoConfig,
        lr: f64,
        seed: u64,
        dev: &Device,
        b: usize,
    ) -> Result<UpdateStats> {
        let (n, steps) = (self.n, self.buf.steps);
        let total = n * steps;
        // GAE per agent over its sequence.
        let mut b_advantages = vec![0.0f32; total];
        let mut b_returns = vec![0.0f32; total];
        let (mut r, mut v, mut s) = (vec![0.0; steps], vec![0.0; steps], vec![0u8; steps]);
        let (mut adv, mut ret) = (vec![0.0; steps], vec![0.0; steps]);
        for a in 0..n {
            for t in 0..steps {
                r[t] = self.buf.rewards[t * n + a];
                v[t] = self.buf.values[t * n + a];
                s[t] = self.buf.stops[t * n + a];
            }
            gae(
                &r,
                &v,
                last_values[a],
                &s,
                cfg.gamma,
                cfg.gae_lambda,
                &mut adv,
                &mut ret,
            );
            for t in 0..steps {
                b_advantages[t * n + a] = adv[t];
                b_returns[t * n + a] = ret[t];
            }
        }
        // Minibatches of shuffled indices, `epochs` passes.
        let mb_size = cfg.batch_size.min(total);
        let mut b_inds: Vec<usize> = (0..total).collect();
        let (mut pg_sum, mut v_sum, mut kl_sum, mut clip_sum, mut count) =
            (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0usize);
        let mut entropy_now = 0.0f64;
        for epoch in 0..cfg.epochs {
            let mut shuffle = Stream::new(
                seed,
                Purpose::Shuffle,
                b as u64,
                self.updates * cfg.epochs as u64 + epoch as u64,
            );
            for i in (1..total).rev() {
                b_inds.swap(i, shuffle.below(i + 1));
            }
            for mb_inds in b_inds.chunks_exact(mb_size) {
                let m = mb_inds.len();
                let mut mb_grids = vec![0.0f32; m * STACKED_LEN];
                mb_grids
                    .par_chunks_mut(STACKED_LEN)
                    .zip(mb_inds.par_iter())
                    .for_each(|(dst, &i)| {
                        dst.copy_from_slice(
                            &self.buf.grids[i * STACKED_LEN..(i + 1) * STACKED_LEN],
                        );
                    });
                let gather = |src: &[f32], w: usize| -> Vec<f32> {
                    mb_inds
                        .iter()
                        .flat_map(|&i| src[i * w..(i + 1) * w].iter().copied())
                        .collect()
                };
                let mb_vectors = gather(&self.buf.vectors, VECTOR_OBS);
                let mb_actions = gather(&self.buf.actions, ACTIONS);
                let mb_logprobs = gather(&self.buf.logprobs, 1);
                let mut mb_advantages = gather(&b_advantages, 1);
                let mb_returns = gather(&b_returns, 1);
                if cfg.normalize_advantages && m > 1 {
                    let mean = mb_advantages.iter().sum::<f32>() / m as f32;
                    let std = (mb_advantages
                        .iter()
                        .map(|x| (x - mean).powi(2))
                        .sum::<f32>()
                        / (m - 1) as f32)
                        .sqrt();
                    for x in &mut mb_advantages {
                        *x = (*x - mean) / (std + 1e-8);
                    }
                }
                let grid = tensor4(mb_grids, m, dev);
                let vector = tensor2(mb_vectors, m, VECTOR_OBS, dev);
                let (mean, log_std) = self.model.actor(grid.clone(), vector.clone());
                let newvalue = self.model.value(grid, vector);
                let newlogprob =
                    log_prob(mean, log_std.clone(), tensor2(mb_actions, m, ACTIONS, dev));
                let entropy_t = entropy(log_std);
                let logratio =
                    newlogprob - Tensor::<1>::from_data(TensorData::new(mb_logprobs, [m]), dev);
                let ratio = logratio.clone().exp();
                let mb_adv = Tensor::<1>::from_data(TensorData::new(mb_advantages, [m]), dev);
                let pg_loss = clipped_surrogate(ratio.clone(), mb_adv, cfg.clip_epsilon);
                let v_loss = (newvalue
                    - Tensor::<1>::from_data(TensorData::new(mb_returns, [m]), dev))
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
                let loss_value = loss.clone().into_scalar::<f32>();
                let (pg, vl) = (pg_loss.into_scalar::<f32>(), v_loss.into_scalar::<f32>());
                if !loss_value.is_finite() {
                    bail!(
                        "update {} of {}: the loss is not finite (policy loss {pg}, value loss {vl}); training stopped, the last good checkpoint is kept",
                        self.updates + 1,
                        self.name
                    );
                }
                let mut grads = GradientsParams::from_grads(loss.backward(), &self.model);
                clip_gradients(&self.model, &mut grads, cfg.max_grad_norm);
                self.model = self.optim.step(lr, self.model.clone(), grads);
                pg_sum += pg as f64;
                v_sum += vl as f64;
                kl_sum += approx_kl as f64;
                clip_sum += clipped as f64;
                entropy_now = entropy_t.into_scalar::<f32>() as f64;
                count += 1;
            }
        }
        self.infer = self.model.valid();
        let log_std = to_vec(self.infer.log_std.val());
        if log_std.iter().any(|x| !x.is_finite()) {
            bail!(
                "update {} of {}: the policy's log-std is not finite; training stopped",
                self.updates + 1,
                self.name
            );
        }
        self.updates += 1;
        self.buf.len = 0;
        let c = count.max(1) as f64;
        Ok(UpdateStats {
            policy_loss: pg_sum / c,
            value_loss: v_sum / c,
            entropy: if count > 0 {
                entropy_now
            } else {
                entropy_f32(&log_std) as f64
            },
            approx_kl: kl_sum / c,
            clip_fraction: clip_sum / c,
        })
    }

    /// Write the scalars of the window since the last update; returns the mean reward
    /// per decision and, if episodes ended, their mean cumulative reward.
    fn log(
        &mut self,
        logger: &mut Logger,
        b: usize,
        s: &UpdateStats,
        lr: f64,
        rate: f64,
    ) -> Result<(f64, Option<f64>)> {
        let step = self.agent_steps;
        let (reward, episode) = self.stats.log(logger, b, step)?;
        let values = std::mem::take(&mut self.values);
        logger.scalar(b, "Losses/Policy Loss", s.policy_loss, step)?;
        logger.scalar(b, "Losses/Value Loss", s.value_loss, step)?;
        logger.scalar(b, "Policy/Entropy", s.entropy, step)?;
        logger.scalar(b, "Policy/Learning Rate", lr, step)?;
        logger.scalar(
            b,
            "Policy/Extrinsic Value Estimate",
            values.sum / values.count.max(1) as f64,
            step,
        )?;
        logger.scalar(b, "Policy/Approx KL", s.approx_kl, step)?;
        logger.scalar(b, "Policy/Clip Fraction", s.clip_fraction, step)?;
        logger.scalar(b, "Perf/Agent Steps per Second", rate, step)?;
        Ok((reward, episode))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ρ = (0.5, 1, 1.5), A = (1, −1, 2), ε = 0.2:
    /// max(−0.5, −0.8) = −0.5; max(1, 1) = 1; max(−3, −2.4) = −2.4; mean −0.633333.
    #[test]
    fn clipped_surrogate_by_hand() {
        let dev = Device::flex();
        let ratio = Tensor::<1>::from_data(TensorData::new(vec![0.5f32, 1.0, 1.5], [3]), &dev);
        let adv = Tensor::<1>::from_data(TensorData::new(vec![1.0f32, -1.0, 2.0], [3]), &dev);
        let loss = clipped_surrogate(ratio, adv, 0.2).into_scalar::<f32>();
        assert!((loss + 0.633_333).abs() < 1e-5, "{loss}");
    }
}
