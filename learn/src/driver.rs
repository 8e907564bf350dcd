//! The run driver: one environment loop for every algorithm.
//!
//! It owns what PPO and SAC share — the run folder, `--resume` (the newest
//! checkpoint: weights, optimisers, counters, the algorithm's own state),
//! `--init-from` (one or several runs: each behaviour takes the weights of a
//! behaviour of the same name, else of the same species), the environment
//! loop, per-behaviour budgets, logging, progress, checkpoints, the final
//! policy with its ONNX files, and the outcome — and leaves to the algorithm
//! ([`Trainer`], one [`Learner`] per behaviour) what happens at a decision.
//!
//! # The loop
//! ```text
//! reset → every learner: start (first actions)
//! loop until every behaviour has its budget:
//!     env.step(actions)
//!     for each behaviour that decided:
//!         stats ← rewards, episode ends, P, M         (while it trains)
//!         learner.decide: record, maybe update, next actions
//!         count its agent steps; log and print progress when due
//!     checkpoint every `checkpoint_every` agent steps (all behaviours)
//! final/: weights, state, <behaviour>.onnx
//! ```
//!
//! # Budgets (ML-Agents' `max_steps`, per behaviour; issue 11 item 5)
//! Each behaviour trains for its own budget of agent decisions — `--steps`,
//! or `--steps-per-fish` times its fish ([`Budget`]), else its species'
//! budget for the phase. A behaviour that has its budget
//! keeps acting (sampling from its policy, storing nothing, no updates) until
//! every behaviour has its own, so the others train in the same world.
//!
//! # Checkpoints and resume
//! A checkpoint is written at the first decision past each `checkpoint_every`
//! agent steps (all behaviours together), atomically. It holds every agent
//! step counted ([`Learner::before_checkpoint`]: PPO's open trajectories go
//! into its saved buffer, SAC's replay buffer is saved), so a run killed
//! after a checkpoint and resumed reaches the final step of the run never
//! stopped having learned from every step it counted, and makes the same
//! updates (see `deepfoids_ppo::inflight` for the one exception: ML-Agents'
//! rollout, where episode ends time the updates; issue 13 item 4). A resumed run continues
//! with the weights, optimisers, counters and the algorithm's saved state,
//! from a reset environment reseeded with `seed + resets` (so its later
//! experience, and its weights, differ from the uninterrupted run's); its
//! logs are first cut back to the checkpoint ([`Logger::open`]). The caller
//! holds the run folder's lock ([`run`]).

use crate::backend::Backend;
use crate::budget::Budget;
use crate::checkpoint::{
    self, Algorithm, BehaviourState, PolicySource, RunState, find_source, replace_dir_atomic,
};
use crate::error::{LearnError, Result};
use crate::logger::{Logger, Scalars};
use crate::onnx::Metadata;
use crate::plan::{MemoryPlan, Part, UpdatePlan};
use crate::progress::{Progress, ProgressMode};
use crate::stats::EpisodeStats;
use burn::prelude::Device;
use deepfoids_env::{BehaviourBatch, BehaviourInfo, Env, GridFormat, Phase, Scene};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// What to train, where.
pub struct RunArgs {
    pub scene: Scene,
    pub run_dir: PathBuf,
    pub run_id: String,
    pub seed: u64,
    /// Each behaviour's budget ([`Budget`]); `None`: the species' budget for the phase.
    pub steps: Option<Budget>,
    pub resume: bool,
    /// Runs to take the initial weights from (transfer learning).
    pub init_from: Vec<PathBuf>,
    pub backend: Backend,
    pub progress: ProgressMode,
    /// Where progress lines go (stdout if `None`).
    pub progress_sink: Option<Box<dyn Write + Send>>,
    /// Write checkpoints and the final policy (off for benchmarks).
    pub save: bool,
    /// The new run's `config.toml` (the resolved configuration), written
    /// into it before it appears.
    pub config_toml: Option<String>,
}

/// How often a run saves and reports, from the algorithm's config.
#[derive(Clone, Copy, Debug)]
pub struct RunSettings {
    pub checkpoint_every: u64,
    pub keep_checkpoints: usize,
    pub progress_every: u64,
}

/// Wall-clock split of a run, and the algorithm's own split of its updates.
#[derive(Clone, Debug, Default)]
pub struct Timing {
    pub env: Duration,
    pub inference: Duration,
    pub update: Duration,
    /// Parts of the updates (e.g. "gather", "forward", "backward", "optimiser").
    pub parts: BTreeMap<&'static str, Duration>,
}

impl Timing {
    pub fn part(&mut self, name: &'static str, d: Duration) {
        *self.parts.entry(name).or_default() += d;
    }
}

/// Size of a trainer's experience buffers.
#[derive(Clone, Copy, Debug, Default)]
pub struct BufferMemory {
    /// Bytes allocated.
    pub allocated: u64,
    /// Bytes written to (resident).
    pub resident: u64,
    /// Transitions held.
    pub transitions: u64,
    /// The most bytes held at once during the run.
    pub peak: u64,
}

impl std::ops::Add for BufferMemory {
    type Output = BufferMemory;
    fn add(self, o: BufferMemory) -> BufferMemory {
        BufferMemory {
            allocated: self.allocated + o.allocated,
            resident: self.resident + o.resident,
            transitions: self.transitions + o.transitions,
            peak: self.peak + o.peak,
        }
    }
}

/// What a run reports back.
pub struct TrainOutcome {
    pub run_dir: PathBuf,
    /// Agent decisions counted for training so far, all behaviours.
    pub agent_steps: u64,
    pub steps_this_run: u64,
    pub wall_seconds: f64,
    pub timing: Timing,
    /// `(agent steps, mean reward per decision)` at each log point, all behaviours.
    pub curve: Vec<(u64, f64)>,
    /// `(agent steps, mean cumulative reward of the episodes finished)` where any finished.
    pub episode_curve: Vec<(u64, f64)>,
    pub final_dir: Option<PathBuf>,
    pub buffer: BufferMemory,
    /// Gradient updates in this run, all behaviours.
    pub updates: u64,
}

/// Everything a learner gets at a decision.
pub struct StepCtx<'a> {
    pub seed: u64,
    /// The environment tick of the observations (exploration noise is keyed by it).
    pub tick: u64,
    /// Whether the next action is taken for training (false once the
    /// behaviour has its budget: act, store nothing, update nothing).
    pub training: bool,
    /// The behaviour's own agent steps counted so far, and its budget.
    pub agent_steps: u64,
    pub budget: u64,
    pub timing: &'a mut Timing,
}

/// Everything a trainer gets to build a behaviour's learner.
pub struct LearnerCtx<'a> {
    pub info: &'a BehaviourInfo,
    /// Index of the behaviour in the scene.
    pub index: usize,
    pub phase: Phase,
    pub seed: u64,
    pub backend: Backend,
    /// The device with autodiff (training) and without (acting).
    pub train_device: Device,
    pub device: Device,
}

/// One behaviour's learner: the algorithm at a decision.
pub trait Learner {
    /// First actions from the initial observations (no rewards yet).
    fn start(
        &mut self,
        batch: &BehaviourBatch,
        actions: &mut [f32],
        ctx: &mut StepCtx<'_>,
    ) -> Result<()>;

    /// The decision that just ended (its rewards and episode ends are in
    /// `batch`), maybe updates, and the next actions for `batch`'s observations.
    fn decide(
        &mut self,
        batch: &BehaviourBatch,
        actions: &mut [f32],
        ctx: &mut StepCtx<'_>,
    ) -> Result<()>;

    /// Whether the algorithm has a log point now (e.g. PPO after an update,
    /// SAC every `summary_every` steps), at `agent_steps` of the behaviour.
    fn log_due(&self, agent_steps: u64) -> bool;

    /// Write the algorithm's scalars of the window since the last log point.
    fn log(&mut self, out: &mut Scalars<'_>) -> Result<()>;

    /// Gradient updates so far.
    fn updates(&self) -> u64;

    /// Just before a checkpoint is saved: put what is in flight where the
    /// checkpoint keeps it (PPO closes its open trajectories into the
    /// buffer), so that it holds every agent step counted. The run goes on
    /// from this state whether or not it is killed later, so a resumed run
    /// continues as the uninterrupted one (issue 13 item 4).
    fn before_checkpoint(&mut self) -> Result<()> {
        Ok(())
    }

    /// Save into `dir` under behaviour `name`: the weights, and for a
    /// checkpoint also the optimisers and the algorithm's state.
    fn save(&self, dir: &Path, name: &str, checkpoint: bool) -> Result<()>;

    /// The actor as ONNX with ML-Agents' interface.
    fn actor_onnx(&self, meta: &Metadata) -> Vec<u8>;

    /// The experience buffers' size.
    fn memory(&self) -> BufferMemory;
}

/// The [`Trainer`] methods that read the config file's shared fields the
/// same way in every algorithm: `algorithm`, `config_name`, `architecture`,
/// `budget` and `settings`. The implementing type has `source: PathBuf` and a
/// `config` with `hidden`, `layers`, `checkpoint_every`, `keep_checkpoints`,
/// `progress_every` and `budget(species, phase)` (SPEC §8).
#[macro_export]
macro_rules! trainer_config_methods {
    ($algorithm:expr) => {
        fn algorithm(&self) -> $crate::Algorithm {
            $algorithm
        }

        fn config_name(&self) -> String {
            self.source.display().to_string()
        }

        fn architecture(&self) -> (usize, usize) {
            (self.config.hidden, self.config.layers)
        }

        fn budget(&self, species: &str, phase: deepfoids_env::Phase) -> u64 {
            self.config.budget(species, phase)
        }

        fn settings(&self) -> $crate::RunSettings {
            $crate::RunSettings {
                checkpoint_every: self.config.checkpoint_every,
                keep_checkpoints: self.config.keep_checkpoints,
                progress_every: self.config.progress_every,
            }
        }
    };
}

/// An algorithm as the driver sees it: its config's answers, its memory and
/// update plans, and how it builds a learner (fresh, resumed or transferred).
/// PPO and SAC implement the first five with [`trainer_config_methods!`].
pub trait Trainer {
    type Learner: Learner;

    fn algorithm(&self) -> Algorithm;

    /// The config file, for error messages (e.g. "configs/train/ppo.toml").
    fn config_name(&self) -> String;

    /// `(hidden, layers)` of the networks.
    fn architecture(&self) -> (usize, usize);

    /// The budget of a behaviour of `species` in `phase` (agent decisions).
    fn budget(&self, species: &str, phase: Phase) -> u64;

    fn settings(&self) -> RunSettings;

    /// The memory a learner of `agents` agents needs at most, by part
    /// ([`crate::plan`]), with the config fields that set each part.
    fn memory_plan(&self, agents: usize) -> MemoryPlan;

    /// When a learner of `agents` agents makes its first update, and how often after.
    fn update_plan(&self, agents: usize) -> UpdatePlan;

    /// The config fields that time the updates (for the message refusing a
    /// budget that makes none), e.g. "buffer_size = 10240, time_horizon = 64".
    fn update_fields(&self) -> String;

    /// A learner with fresh weights.
    fn new_learner(&self, ctx: &LearnerCtx<'_>) -> Result<Self::Learner>;

    /// A learner continued from checkpoint folder `dir` (behaviour `state`).
    fn resume_learner(
        &self,
        ctx: &LearnerCtx<'_>,
        dir: &Path,
        state: &BehaviourState,
    ) -> Result<Self::Learner>;

    /// A fresh learner with the weights of behaviour `source` of policy
    /// folder `from` (transfer learning: fresh optimisers and counters).
    fn transfer_learner(
        &self,
        ctx: &LearnerCtx<'_>,
        from: &Path,
        source: &BehaviourState,
    ) -> Result<Self::Learner>;
}

/// A behaviour's learner and its counters in the driver.
struct Behaviour<L> {
    learner: L,
    name: String,
    species: String,
    size_class: String,
    n: usize,
    agent_steps: u64,
    budget: u64,
    /// The last action was taken for training (its transition counts).
    acting_for_training: bool,
    stats: EpisodeStats,
}

/// Where a new run is made before it is known to start: `<parent>/.<name>.<pid>.start`,
/// renamed to the run folder once its learners exist (issue 25).
pub fn staging_dir(run_dir: &Path) -> PathBuf {
    let name = run_dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    run_dir.with_file_name(format!(".{name}.{}.start", std::process::id()))
}

/// The policies of `init_from` — each of `trainer`'s algorithm, this build's
/// layout and the configured architecture — with a source for every
/// behaviour of `scene`. Callers check this before they create a run folder,
/// so a wrong `--init-from` leaves nothing behind (issue 13 item 5).
pub fn open_sources<T: Trainer>(
    trainer: &T,
    init_from: &[PathBuf],
    scene: &Scene,
) -> Result<Vec<PolicySource>> {
    let (hidden, layers) = trainer.architecture();
    let sources = init_from
        .iter()
        .map(|run| {
            let src = PolicySource::open(
                run,
                trainer.algorithm(),
                "--init-from transfers between runs of the same algorithm",
            )?;
            src.state
                .check_architecture(&src.dir, hidden, layers, &trainer.config_name())?;
            Ok(src)
        })
        .collect::<Result<Vec<_>>>()?;
    if !sources.is_empty() {
        for b in &scene.behaviours {
            find_source(&sources, &b.name, &b.species.name)?;
        }
    }
    Ok(sources)
}

/// What a run of `trainer` on `scene` needs, checked before its folder is
/// made (issue 25): no behaviour's budget (`steps`, else its species'
/// budget for the phase) is too small for any update unless
/// `allow_no_update` (a budget that updates only if episodes end early gets
/// a note), and the environment with every learner fits into
/// the machine's memory ([`deepfoids_env::memory::check`], as `load_scene`
/// checks an environment). Returns the memory plan and the notes, which the
/// caller prints once (a check may run before its run starts and again at it).
pub fn check_run<T: Trainer>(
    trainer: &T,
    scene: &Scene,
    steps: Option<Budget>,
    allow_no_update: bool,
) -> Result<RunCheck> {
    let mut notes = Vec::new();
    let mut plan = MemoryPlan {
        parts: vec![Part {
            name: "environment",
            bytes: deepfoids_env::memory::env_bytes(scene),
            fields: format!("{} fish of scene {}", scene.fish_count(), scene.id),
        }],
    };
    for b in &scene.behaviours {
        let budget = Budget::resolve(steps, b.count, || {
            trainer.budget(&b.species.name, scene.phase)
        });
        let updates = trainer.update_plan(b.count);
        if budget < updates.earliest && !allow_no_update {
            return Err(LearnError::NoUpdate {
                behaviour: b.name.clone(),
                agents: b.count,
                budget,
                first: updates.earliest,
                first_per_fish: updates.earliest.div_ceil(b.count.max(1) as u64),
                fields: trainer.update_fields(),
                config: trainer.config_name(),
            });
        }
        if budget < updates.first {
            notes.push(format!(
                "note: behaviour {} makes an update within {budget} agent steps only if episodes end early (without episode ends the first comes after {}; {} in {})",
                b.name,
                updates.first,
                trainer.update_fields(),
                trainer.config_name()
            ));
        }
        plan.merge(trainer.memory_plan(b.count));
    }
    let need = plan.total();
    let largest = plan.largest().cloned();
    deepfoids_env::memory::check(
        &format!("training with {} ({})", trainer.config_name(), plan.describe()),
        need,
        &largest.map_or_else(String::new, |p| {
            format!(
                "the largest part is the {} ({}): lower those values in {}, use fewer fish, or free memory",
                p.name,
                p.fields,
                trainer.config_name()
            )
        }),
    )
    .map_err(|error| LearnError::Memory {
        config: trainer.config_name(),
        error,
    })?;
    Ok(RunCheck { plan, notes })
}

/// What [`check_run`] found: the memory plan, and notes for the user
/// (a budget that updates only if episodes end early).
#[derive(Clone, Debug)]
pub struct RunCheck {
    pub plan: MemoryPlan,
    pub notes: Vec<String>,
}

/// Train `trainer`'s algorithm on a scene. See the module documentation.
///
/// A new run is made under [`staging_dir`] (with `args.config_toml` as its
/// `config.toml`) and appears under its name only once every learner exists
/// — fresh, or with the `--init-from` weights loaded — so a start that fails
/// leaves nothing that blocks a rerun. The caller holds the run folder's
/// lock (`deepfoids_io::DirLock`) and has checked that it does not exist.
/// `--resume` starts from the newest checkpoint whose files all load, and
/// says so when it falls back to an older one.
pub fn run<T: Trainer>(trainer: &T, mut args: RunArgs) -> Result<TrainOutcome> {
    let mut session = if args.resume {
        resume_session(trainer, &mut args)?
    } else {
        start_session(trainer, &mut args)?
    };
    session.first_actions(args.seed)?;
    session.train(&args, &trainer.settings())?;
    session.finish(&args)
}

/// A new run: built in the staging folder, then renamed into place.
fn start_session<T: Trainer>(trainer: &T, args: &mut RunArgs) -> Result<Session<T::Learner>> {
    let staging = staging_dir(&args.run_dir);
    let _ = std::fs::remove_dir_all(&staging);
    let built = (|| -> Result<(Env, Vec<Behaviour<T::Learner>>)> {
        std::fs::create_dir_all(&staging).map_err(LearnError::io(&staging))?;
        if let Some(text) = &args.config_toml {
            let file = staging.join("config.toml");
            deepfoids_io::write_atomic(&file, text.as_bytes()).map_err(LearnError::io(&file))?;
        }
        let sources = open_sources(trainer, &args.init_from, &args.scene)?;
        let env = new_env(args, None);
        let behaviours = learners(trainer, args, &env, None, &sources)?;
        std::fs::rename(&staging, &args.run_dir).map_err(LearnError::io(&args.run_dir))?;
        Ok((env, behaviours))
    })();
    let (env, behaviours) = built.inspect_err(|_| {
        let _ = std::fs::remove_dir_all(&staging);
    })?;
    setup(trainer, args, None, env, behaviours)
}

/// `--resume`: the newest checkpoint whose state and files load, of this
/// algorithm, scene and architecture; an unreadable one (a truncated or
/// corrupt file) is passed over with a note for the one before it.
fn resume_session<T: Trainer>(trainer: &T, args: &mut RunArgs) -> Result<Session<T::Learner>> {
    let resume_error = |reason: String| LearnError::Resume {
        run: args.run_dir.clone(),
        reason,
    };
    let mut all = checkpoint::checkpoints(&args.run_dir);
    if all.is_empty() {
        let finished = args.run_dir.join("final");
        return Err(resume_error(if finished.is_dir() {
            format!(
                "it has no checkpoint to resume from; it finished ({}): to train on from \
                 its weights, start a new run with --init-from {}",
                finished.display(),
                args.run_dir.display()
            )
        } else {
            "it has no checkpoint to resume from".into()
        }));
    }
    let mut passed = Vec::new();
    while let Some((_, dir)) = all.pop() {
        match resume_from(trainer, args, &dir) {
            Ok((state, env, behaviours)) => {
                if !passed.is_empty() {
                    eprintln!(
                        "note: resuming from the older checkpoint {}: {}",
                        dir.display(),
                        passed.join("; ")
                    );
                }
                eprintln!(
                    "resumed from step {} (checkpoint {})",
                    state.agent_steps,
                    dir.display()
                );
                return setup(trainer, args, Some(state), env, behaviours);
            }
            Err(
                e
                @ (LearnError::Io { .. } | LearnError::Corrupt { .. } | LearnError::Record { .. }),
            ) => {
                passed.push(format!("{} is unreadable ({e})", dir.display()));
            }
            Err(e) => return Err(e),
        }
    }
    Err(resume_error(format!(
        "no checkpoint loads: {}",
        passed.join("; ")
    )))
}

/// The state and learners of checkpoint `dir`, which must be of this
/// algorithm, scene and architecture.
#[allow(clippy::type_complexity)]
fn resume_from<T: Trainer>(
    trainer: &T,
    args: &RunArgs,
    dir: &Path,
) -> Result<(RunState, Env, Vec<Behaviour<T::Learner>>)> {
    let (hidden, layers) = trainer.architecture();
    let st = RunState::load_policy(
        dir,
        trainer.algorithm(),
        "--resume continues the run's own algorithm",
    )?;
    if st.scene != args.scene.id {
        return Err(LearnError::Resume {
            run: args.run_dir.clone(),
            reason: format!("the run trained on {}, not {}", st.scene, args.scene.id),
        });
    }
    st.check_architecture(dir, hidden, layers, &trainer.config_name())?;
    st.check_reward_profile(&args.run_dir, &args.scene.reward_profile, "resume")?;
    let env = new_env(args, Some(&st));
    let behaviours = learners(trainer, args, &env, Some((dir, &st)), &[])?;
    Ok((st, env, behaviours))
}

/// The environment, reseeded with `seed + resets` on resume. It hands the
/// grids out as floats: the learners act on them and store them as bytes.
/// (Acting on the sensor's bytes works too — the learners read either — and
/// since conv 1 reads them directly it makes `train` 1.15–1.2× faster; but it
/// changes every seeded run, and runs trained as the quickstart then hit the
/// net 15.6 and 16.8 times per fish-hour for two of three seeds, over the
/// quickstart's ≤ 10 (docs/speed.md, session 45). With floats, training
/// reproduces the committed runs and the quickstart bit for bit.)
fn new_env(args: &RunArgs, resumed: Option<&RunState>) -> Env {
    let resets = resumed.map_or(0, |s| s.resets + 1);
    Env::with_grid_format(
        args.scene.clone(),
        args.seed.wrapping_add(resets),
        GridFormat::Floats,
    )
}

/// Everything the loop changes, from [`setup`] to [`Session::finish`].
struct Session<L> {
    env: Env,
    tick: u64,
    behaviours: Vec<Behaviour<L>>,
    actions: Vec<Vec<f32>>,
    state: RunState,
    logger: Logger,
    progress: Progress,
    timing: Timing,
    /// `(agent steps, reward per decision)` and `(agent steps, cumulative
    /// reward per episode)` at every log point.
    curve: Vec<(u64, f64)>,
    episode_curve: Vec<(u64, f64)>,
    /// Agent steps, wall seconds and updates before this process.
    start_steps: u64,
    wall_before: f64,
    updates_before: u64,
    started: Instant,
}

/// The session of a run whose environment and learners exist: the logger
/// (cut back to the checkpoint on resume), the run state and the progress.
fn setup<T: Trainer>(
    trainer: &T,
    args: &mut RunArgs,
    resumed: Option<RunState>,
    env: Env,
    behaviours: Vec<Behaviour<T::Learner>>,
) -> Result<Session<T::Learner>> {
    let (hidden, layers) = trainer.architecture();
    let settings = trainer.settings();
    let resets = resumed.as_ref().map_or(0, |s| s.resets + 1);
    let tick = resumed.as_ref().map_or(0, |s| s.ticks);
    let names: Vec<String> = behaviours.iter().map(|b| b.name.clone()).collect();
    let resumed_at: Option<Vec<u64>> = resumed
        .as_ref()
        .map(|_| behaviours.iter().map(|b| b.agent_steps).collect());
    let logger = Logger::open(&args.run_dir, &names, resumed_at.as_deref())?;
    let mut state = resumed.unwrap_or_else(|| RunState {
        algo: trainer.algorithm(),
        layout: crate::body::ENCODER_LAYOUT,
        run_id: args.run_id.clone(),
        scene: args.scene.id.clone(),
        phase: args.scene.phase,
        seed: args.seed,
        backend: args.backend.as_str().into(),
        agent_steps: 0,
        ticks: 0,
        resets: 0,
        wall_seconds: 0.0,
        init_from: args
            .init_from
            .iter()
            .map(|p| p.display().to_string())
            .collect(),
        hidden,
        layers,
        behaviours: vec![],
        reward_profile: None,
    });
    state.resets = resets;
    // New and resumed runs alike (a resumed run from before the profile was
    // recorded passed the check by its config.toml).
    state.reward_profile = Some(args.scene.reward_profile.clone());
    let total_budget: u64 = behaviours.iter().map(|b| b.budget).sum();
    let done: u64 = behaviours.iter().map(|b| b.agent_steps.min(b.budget)).sum();
    let progress = Progress::new(
        args.progress,
        total_budget,
        done,
        &behaviours.iter().map(|b| b.agent_steps).collect::<Vec<_>>(),
        settings.progress_every,
        args.progress_sink.take(),
    );
    Ok(Session {
        env,
        tick,
        actions: behaviours.iter().map(|b| vec![0.0; b.n * 3]).collect(),
        start_steps: state.agent_steps,
        wall_before: state.wall_seconds,
        updates_before: behaviours.iter().map(|b| b.learner.updates()).sum(),
        behaviours,
        state,
        logger,
        progress,
        timing: Timing::default(),
        curve: Vec::new(),
        episode_curve: Vec::new(),
        started: Instant::now(),
    })
}

/// Serialises seeding Burn's device and drawing initial weights ([`learners`]).
static SEEDED_INIT: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// One learner per behaviour of `env`: resumed from the checkpoint, else
/// transferred from a source policy, else fresh.
fn learners<T: Trainer>(
    trainer: &T,
    args: &RunArgs,
    env: &Env,
    resumed: Option<(&Path, &RunState)>,
    sources: &[PolicySource],
) -> Result<Vec<Behaviour<T::Learner>>> {
    let phase = args.scene.phase;
    let device = args.backend.device();
    let train_device = device.clone().autodiff();
    // Burn's device RNG is one per process: held from the seed until every
    // learner has drawn its weights, so that runs in one process (the test
    // suites, `pipeline`) never interleave their draws.
    let _seeded = SEEDED_INIT.lock().unwrap_or_else(|e| e.into_inner());
    device.seed(args.seed);
    let mut behaviours = Vec::new();
    for (b, info) in env.behaviours().iter().enumerate() {
        let ctx = LearnerCtx {
            info,
            index: b,
            phase,
            seed: args.seed,
            backend: args.backend,
            train_device: train_device.clone(),
            device: device.clone(),
        };
        let mut agent_steps = 0;
        let learner = if let Some((dir, st)) = resumed {
            let bs = st.behaviour(&info.name).ok_or_else(|| LearnError::Resume {
                run: args.run_dir.clone(),
                reason: format!(
                    "checkpoint {} has no behaviour {}",
                    dir.display(),
                    info.name
                ),
            })?;
            agent_steps = bs.agent_steps;
            trainer.resume_learner(&ctx, dir, bs)?
        } else if !sources.is_empty() {
            let (src, bs) = find_source(sources, &info.name, &info.species)?;
            trainer.transfer_learner(&ctx, &src.dir, bs)?
        } else {
            trainer.new_learner(&ctx)?
        };
        behaviours.push(Behaviour {
            learner,
            name: info.name.clone(),
            species: info.species.clone(),
            size_class: info.size_class.clone(),
            n: info.count,
            agent_steps,
            budget: Budget::resolve(args.steps, info.count, || {
                trainer.budget(&info.species, phase)
            }),
            acting_for_training: false,
            stats: EpisodeStats::new(info.first, info.count),
        });
    }
    Ok(behaviours)
}

impl<L: Learner> Session<L> {
    /// First actions from the initial observations.
    fn first_actions(&mut self, seed: u64) -> Result<()> {
        for (b, beh) in self.behaviours.iter_mut().enumerate() {
            let training = beh.agent_steps < beh.budget;
            let mut ctx = StepCtx {
                seed,
                tick: self.tick,
                training,
                agent_steps: beh.agent_steps,
                budget: beh.budget,
                timing: &mut self.timing,
            };
            beh.learner.start(
                &self.env.output().behaviours[b],
                &mut self.actions[b],
                &mut ctx,
            )?;
            beh.acting_for_training = training;
        }
        Ok(())
    }

    /// The loop: step, let each behaviour that decided record, learn and
    /// act, log when due, checkpoint when due — until every behaviour has
    /// its budget.
    fn train(&mut self, args: &RunArgs, settings: &RunSettings) -> Result<()> {
        let mut next_checkpoint =
            (self.state.agent_steps / settings.checkpoint_every + 1) * settings.checkpoint_every;
        while self.behaviours.iter().any(|b| b.agent_steps < b.budget) {
            let t0 = Instant::now();
            let out = self.env.step(&self.actions)?;
            self.tick += 1;
            self.timing.env += t0.elapsed();
            for (b, beh) in self.behaviours.iter_mut().enumerate() {
                let batch = &out.behaviours[b];
                if !batch.decided {
                    continue;
                }
                if beh.acting_for_training {
                    beh.stats.record(batch, out);
                    beh.agent_steps += beh.n as u64;
                    self.state.agent_steps += beh.n as u64;
                }
                let training = beh.agent_steps < beh.budget;
                let mut ctx = StepCtx {
                    seed: args.seed,
                    tick: self.tick,
                    training,
                    agent_steps: beh.agent_steps,
                    budget: beh.budget,
                    timing: &mut self.timing,
                };
                beh.learner.decide(batch, &mut self.actions[b], &mut ctx)?;
                let was_training = beh.acting_for_training;
                beh.acting_for_training = training;
                let finished_now = was_training && !training;
                if !(beh.learner.log_due(beh.agent_steps)
                    || finished_now && beh.stats.decisions() > 0)
                {
                    continue;
                }
                let mut sc = Scalars {
                    logger: &mut self.logger,
                    behaviour: b,
                    step: beh.agent_steps,
                };
                let summary = beh.stats.log(&mut sc)?;
                beh.learner.log(&mut sc)?;
                let rate = (self.state.agent_steps - self.start_steps) as f64
                    / self.started.elapsed().as_secs_f64().max(1e-9);
                sc.put("Perf/Agent Steps per Second", rate)?;
                self.logger.flush()?;
                self.curve
                    .push((self.state.agent_steps, summary.reward_per_decision));
                if let Some(ep) = summary.cumulative_reward {
                    self.episode_curve.push((self.state.agent_steps, ep));
                }
                self.progress.message(format!(
                    "{}: reward/decision {:.2}",
                    beh.name, summary.reward_per_decision
                ));
                if self.progress.line_due(b, beh.agent_steps) || finished_now {
                    let s = beh.stats.take_progress();
                    self.progress
                        .print_line(b, &beh.name, beh.agent_steps, beh.budget, rate, &s);
                }
            }
            self.progress.set_position(
                self.behaviours
                    .iter()
                    .map(|b| b.agent_steps.min(b.budget))
                    .sum(),
            );
            if args.save && self.state.agent_steps >= next_checkpoint {
                self.checkpoint(&args.run_dir, settings)?;
                while next_checkpoint <= self.state.agent_steps {
                    next_checkpoint += settings.checkpoint_every;
                }
            }
        }
        Ok(())
    }

    /// A checkpoint of every behaviour at the current agent steps; the
    /// oldest beyond `keep_checkpoints` are pruned.
    fn checkpoint(&mut self, run_dir: &Path, settings: &RunSettings) -> Result<()> {
        self.state.ticks = self.tick;
        self.state.wall_seconds = self.wall_before + self.started.elapsed().as_secs_f64();
        let dir = checkpoint::checkpoint_dir(run_dir, self.state.agent_steps);
        for b in &mut self.behaviours {
            b.learner.before_checkpoint()?;
        }
        save_all(&dir, &self.behaviours, &mut self.state, true, false)?;
        checkpoint::prune(run_dir, settings.keep_checkpoints);
        self.logger.flush()?;
        Ok(())
    }

    /// `final/` (weights, state, ONNX), the logs closed, and the outcome.
    fn finish(mut self, args: &RunArgs) -> Result<TrainOutcome> {
        self.state.ticks = self.tick;
        self.state.wall_seconds = self.wall_before + self.started.elapsed().as_secs_f64();
        let final_dir = if args.save {
            let fin = args.run_dir.join("final");
            save_all(&fin, &self.behaviours, &mut self.state, false, true)?;
            Some(fin)
        } else {
            None
        };
        self.logger.close()?;
        self.progress.finish();
        let behaviours = &self.behaviours;
        Ok(TrainOutcome {
            run_dir: args.run_dir.clone(),
            agent_steps: self.state.agent_steps,
            steps_this_run: self.state.agent_steps - self.start_steps,
            wall_seconds: self.started.elapsed().as_secs_f64(),
            timing: self.timing,
            curve: self.curve,
            episode_curve: self.episode_curve,
            final_dir,
            buffer: behaviours
                .iter()
                .fold(BufferMemory::default(), |m, b| m + b.learner.memory()),
            updates: behaviours.iter().map(|b| b.learner.updates()).sum::<u64>()
                - self.updates_before,
        })
    }
}

/// Save every learner and the run state into `dir` (a checkpoint, or
/// `final/` with each behaviour's actor as ONNX), atomically.
fn save_all<L: Learner>(
    dir: &Path,
    behaviours: &[Behaviour<L>],
    state: &mut RunState,
    checkpoint: bool,
    onnx: bool,
) -> Result<()> {
    state.behaviours = behaviours
        .iter()
        .map(|b| BehaviourState {
            name: b.name.clone(),
            species: b.species.clone(),
            size_class: b.size_class.clone(),
            agent_steps: b.agent_steps,
            budget: b.budget,
            updates: b.learner.updates(),
        })
        .collect();
    replace_dir_atomic(dir, |tmp| {
        for b in behaviours {
            b.learner.save(tmp, &b.name, checkpoint)?;
            if onnx {
                let meta = state.onnx_metadata(&b.species, &b.name, b.agent_steps);
                let path = tmp.join(format!("{}.onnx", b.name));
                std::fs::write(&path, b.learner.actor_onnx(&meta))
                    .map_err(LearnError::io(&path))?;
            }
        }
        state.save(tmp)
    })
}
