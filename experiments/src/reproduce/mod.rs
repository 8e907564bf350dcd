//! `deepfoids reproduce`: the experiments of thesis §4.5 with the two-step
//! scheme, each claim judged against a criterion written down before the runs
//! (`claims.rs`), and a report (`REPORT.md`, CSVs, PNGs) of what was measured.
//!
//! Layout of `--out DIR`:
//! - `s<seed>/<stage>/`: one run folder per training stage and training seed
//!   (`pretrain-<species>`, `transfer-<scene>`, `scratch-<scene>`,
//!   `sac-pretrain-coho`, `sac-transfer-coho_default`). A stage with a final
//!   policy is reused, one with checkpoints resumed, so an interrupted
//!   reproduction continues where it stopped.
//! - `s<seed>/<stage>/measure-<policy>-e<eval seed>.json`: the measurements of
//!   one evaluation (cached: the report is rebuilt from them without
//!   re-simulating).
//! - `report/`: `REPORT.md`, `claims.csv`, `stages.csv`, `measurements.csv` and
//!   the figures.

mod claims;
mod figures;
mod measure;
pub mod ship;

use crate::load_scene;
use crate::training::{TrainOptions, train_scene};
use anyhow::{Context, Result, bail};
use deepfoids_env::{ConfigDirs, Phase};
use deepfoids_learn::Algorithm;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub use claims::CLAIMS;

/// What to reproduce and where (the options of `deepfoids reproduce`).
#[derive(Debug, Clone)]
pub struct ReproduceOptions {
    /// Budgets: `full` (the thesis': coho 4 M + 1 M, yellowtail and seabream
    /// 2 M + 2 M, SAC on coho 4 M + 1 M) or `quick` (a tenth of them).
    pub profile: ProfileName,
    /// Only these claims, and the stages they need (empty: every claim).
    pub only: Vec<String>,
    /// Output folder: the runs (`s<seed>/<stage>`) and `report/`.
    pub out: PathBuf,
    /// Training seeds (empty: the profile's).
    pub seeds: Vec<u64>,
    /// Scale every training budget by this factor, in (0, 1] (tests; the
    /// report says so).
    pub budget_scale: f64,
    /// Scale the evaluation's simulated seconds by this factor, in (0, 1] (tests).
    pub eval_scale: f64,
    /// After the report, copy each [`ship::SHIPPED`] policy with a model card
    /// into this folder (`policies` ships them with the repository).
    pub ship: Option<PathBuf>,
    /// Ship only these (`coho`, `coho/density_dense`, …; empty: every
    /// shipped policy); the others already in the folder stay.
    pub ship_only: Vec<String>,
    /// No progress bars or progress lines while training.
    pub quiet: bool,
    /// Evaluate with the policies' means instead of sampled actions (SPEC §9).
    pub deterministic: bool,
    /// Everything, or one part of it for a cluster driver (`deepfoids.ray`).
    pub mode: Mode,
}

/// What [`run`] does. A cluster driver asks for the [`Mode::Plan`], trains
/// each (seed, stage) with [`Mode::Stage`] once the stages it starts from are
/// finished, then runs [`Mode::All`], which reuses every finished stage and
/// measures, judges and writes the report.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum Mode {
    #[default]
    All,
    /// Print the stages to train, one JSON object a line: `seed`, `stage`,
    /// `init_from` (stages of the same seed it starts from), `scene`,
    /// `phase`, `algo`; nothing is written.
    Plan,
    /// Train this one stage for each seed (the stages it starts from must be
    /// finished), without the folder-wide lock: stages of one reproduction
    /// may train in several processes at once.
    Stage(String),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProfileName {
    Full,
    Quick,
}

impl ProfileName {
    /// Every profile, by name.
    pub const ALL: [(&'static str, ProfileName); 2] =
        [("full", ProfileName::Full), ("quick", ProfileName::Quick)];

    /// Its name on the command line, as in [`Self::ALL`].
    pub fn as_str(self) -> &'static str {
        match self {
            ProfileName::Full => "full",
            ProfileName::Quick => "quick",
        }
    }
}

impl std::str::FromStr for ProfileName {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        Self::ALL
            .iter()
            .find(|(name, _)| *name == s)
            .map(|(_, p)| *p)
            .ok_or_else(|| format!("unknown profile `{s}`; allowed: full, quick"))
    }
}

/// Budgets and evaluation lengths of one profile.
#[derive(Clone, Debug, Serialize)]
pub struct Profile {
    pub name: ProfileName,
    /// Pretraining and transfer budgets (agent decisions per behaviour) by species.
    pub budgets: Vec<(&'static str, [u64; 2])>,
    /// Training seeds.
    pub seeds: Vec<u64>,
    /// Evaluation seeds of each trained policy (environment seeds).
    pub eval_seeds: Vec<u64>,
    /// Simulated seconds before recording, and recorded.
    pub warmup: f64,
    pub seconds: f64,
    /// Evaluate with the policies' means instead of sampled actions (SPEC §9:
    /// sampled, as Unity ML-Agents 1.x did, unless asked).
    pub deterministic: bool,
}

impl Profile {
    pub fn new(name: ProfileName) -> Self {
        // Thesis §4.5.2 and §4.5.6: pretraining and transfer budgets.
        const THESIS: [(&str, [u64; 2]); 3] = [
            ("coho", [4_000_000, 1_000_000]),
            ("yellowtail", [2_000_000, 2_000_000]),
            ("seabream", [2_000_000, 2_000_000]),
        ];
        // `quick`: a tenth of the budgets, two evaluation seeds of 30 s.
        let (divisor, eval_seeds, seconds) = match name {
            ProfileName::Full => (1, vec![0, 1, 2], 60.0),
            ProfileName::Quick => (10, vec![0, 1], 30.0),
        };
        Self {
            name,
            budgets: THESIS
                .iter()
                .map(|&(species, [pre, tr])| (species, [pre / divisor, tr / divisor]))
                .collect(),
            seeds: vec![0],
            eval_seeds,
            warmup: 10.0,
            seconds,
            deterministic: false,
        }
    }

    pub fn budget(&self, species: &str, phase: Phase) -> Result<u64> {
        let b = self
            .budgets
            .iter()
            .find(|(s, _)| *s == species)
            .map(|(_, b)| *b)
            .ok_or_else(|| anyhow::anyhow!("the profile has no budget for species `{species}`"))?;
        Ok(match phase {
            Phase::Pretrain => b[0],
            Phase::Transfer => b[1],
        })
    }
}

/// One training stage of the reproduction.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    /// Folder name under `s<seed>/`.
    pub name: String,
    pub scene: String,
    pub phase: Phase,
    pub algo: Algorithm,
    /// Stages whose final policies this one starts from.
    pub init_from: Vec<String>,
}

impl Stage {
    fn pretrain(species: &str) -> Self {
        Self {
            name: format!("pretrain-{species}"),
            scene: format!("{species}_default"),
            phase: Phase::Pretrain,
            algo: Algorithm::Ppo,
            init_from: vec![],
        }
    }

    fn transfer(scene: &str, species: &[&str]) -> Self {
        Self {
            name: format!("transfer-{scene}"),
            scene: scene.to_string(),
            phase: Phase::Transfer,
            algo: Algorithm::Ppo,
            init_from: species.iter().map(|s| format!("pretrain-{s}")).collect(),
        }
    }

    /// Trained with the transfer weights from nothing, for the budget of
    /// pretraining plus transfer (equal steps, §4.5.2).
    fn scratch(scene: &str) -> Self {
        Self {
            name: format!("scratch-{scene}"),
            scene: scene.to_string(),
            phase: Phase::Transfer,
            algo: Algorithm::Ppo,
            init_from: vec![],
        }
    }

    /// Every stage the reproduction knows, in the order they run: the
    /// pretraining (SAC's included) first, so that everything that depends on
    /// a pretrained policy has it.
    pub fn all() -> Vec<Stage> {
        let mut sac_pre = Stage::pretrain("coho");
        sac_pre.name = "sac-pretrain-coho".into();
        sac_pre.algo = Algorithm::Sac;
        let mut sac_tr = Stage::transfer("coho_default", &["coho"]);
        sac_tr.name = "sac-transfer-coho_default".into();
        sac_tr.algo = Algorithm::Sac;
        sac_tr.init_from = vec!["sac-pretrain-coho".into()];
        vec![
            Stage::pretrain("coho"),
            Stage::pretrain("yellowtail"),
            Stage::pretrain("seabream"),
            sac_pre,
            Stage::transfer("coho_default", &["coho"]),
            Stage::transfer("yellowtail_default", &["yellowtail"]),
            Stage::transfer("seabream_default", &["seabream"]),
            Stage::transfer("density_sparse", &["coho"]),
            Stage::transfer("density_dense", &["coho"]),
            Stage::transfer("seabream_cube5", &["seabream"]),
            Stage::transfer("seabream_50", &["seabream"]),
            Stage::transfer("coho_mixed", &["coho"]),
            Stage::transfer("three_species", &["coho", "yellowtail", "seabream"]),
            Stage::scratch("density_dense"),
            sac_tr,
        ]
    }

    pub fn find(name: &str) -> Stage {
        Stage::all()
            .into_iter()
            .find(|s| s.name == name)
            .unwrap_or_else(|| panic!("stage {name} is not in Stage::all()"))
    }

    /// Budget per behaviour species: scratch stages get pretraining plus
    /// transfer, as the two-step scheme spends.
    fn budget(&self, profile: &Profile, species: &str) -> Result<u64> {
        let tr = profile.budget(species, self.phase)?;
        Ok(if self.name.starts_with("scratch-") {
            profile.budget(species, Phase::Pretrain)? + tr
        } else {
            tr
        })
    }
}

/// Stages `claims` need, with everything they start from, in run order.
pub fn stages_for(claims: &[&claims::Claim]) -> Vec<Stage> {
    with_dependencies(
        claims
            .iter()
            .flat_map(|c| c.stages.iter().map(|s| s.to_string()))
            .collect(),
    )
}

/// The stages named in `want` and every stage they start from, in
/// [`Stage::all`]'s order.
fn with_dependencies(mut want: Vec<String>) -> Vec<Stage> {
    loop {
        let extra: Vec<String> = want
            .iter()
            .flat_map(|w| Stage::find(w).init_from)
            .filter(|d| !want.contains(d))
            .collect();
        if extra.is_empty() {
            break;
        }
        want.extend(extra);
    }
    Stage::all()
        .into_iter()
        .filter(|s| want.contains(&s.name))
        .collect()
}

/// How long a stage trained, kept beside it (`reproduce.json`).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct StageRecord {
    pub stage: String,
    pub scene: String,
    pub algo: String,
    pub phase: String,
    /// Budget per behaviour.
    pub budgets: Vec<(String, u64)>,
    /// Training wall seconds summed over every process that worked on it.
    pub wall_seconds: f64,
    pub agent_steps: u64,
    /// Whether the times come from this file (`false`: from file times).
    pub timed: bool,
}

pub fn run(dirs: &ConfigDirs, args: &ReproduceOptions) -> Result<()> {
    let start = Instant::now();
    let mut profile = Profile::new(args.profile);
    profile.deterministic = args.deterministic;
    if !args.seeds.is_empty() {
        profile.seeds = args.seeds.clone();
    }
    for (name, v) in [
        ("--budget-scale", args.budget_scale),
        ("--eval-scale", args.eval_scale),
    ] {
        if !(v.is_finite() && v > 0.0 && v <= 1.0) {
            bail!("{name} must be in (0, 1], not {v}");
        }
    }
    if args.budget_scale < 1.0 {
        for (_, b) in profile.budgets.iter_mut() {
            for x in b.iter_mut() {
                *x = ((*x as f64 * args.budget_scale).round() as u64).max(1);
            }
        }
    }
    profile.warmup *= args.eval_scale;
    profile.seconds *= args.eval_scale;
    let chosen = claims::select(&args.only)?;
    // Shipping needs the stages of the policies it ships.
    let shipped = ship::select(&args.ship_only)?;
    let mut want: Vec<String> = stages_for(&chosen).into_iter().map(|s| s.name).collect();
    if args.ship.is_some() {
        want.extend(shipped.iter().map(|(_, scene)| ship::stage_of(scene)));
    }
    let stages = with_dependencies(want);
    match &args.mode {
        Mode::All => {}
        Mode::Plan => {
            for &seed in &profile.seeds {
                for stage in &stages {
                    println!("{}", plan_line(seed, stage));
                }
            }
            return Ok(());
        }
        Mode::Stage(name) => {
            let Some(stage) = stages.iter().find(|s| &s.name == name) else {
                let names: Vec<&str> = stages.iter().map(|s| s.name.as_str()).collect();
                bail!(
                    "--stage {name} is not a stage of these claims; they train: {}",
                    names.join(", ")
                );
            };
            for &seed in &profile.seeds {
                let root = args.out.join(format!("s{seed}"));
                run_stage(dirs, &profile, stage, &root, seed, args)?;
            }
            return Ok(());
        }
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let _lock = crate::lock_dir(&args.out)?;
    eprintln!(
        "reproduce ({:?}): claims {}; stages {}; training seeds {:?}",
        profile.name,
        chosen.iter().map(|c| c.id).collect::<Vec<_>>().join(", "),
        stages
            .iter()
            .map(|s| s.name.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        profile.seeds
    );
    let mut records = Vec::new();
    for &seed in &profile.seeds {
        let root = args.out.join(format!("s{seed}"));
        for stage in &stages {
            records.push((seed, run_stage(dirs, &profile, stage, &root, seed, args)?));
        }
    }
    eprintln!("training done; measuring");
    // Every (policy, scene) the chosen claims name, once each.
    let mut wanted: Vec<(&str, &str)> = Vec::new();
    for c in &chosen {
        for e in c.evals {
            if !wanted.contains(e) {
                wanted.push(*e);
            }
        }
    }
    let measured = measure::measure_all(dirs, &profile, &wanted, &stages_for(&chosen), &args.out)?;
    let verdicts: Vec<claims::Verdict> = chosen.iter().map(|c| (c.judge)(&measured)).collect();
    figures::write_report(
        &args.out.join("report"),
        &figures::Report {
            profile: &profile,
            args,
            claims: &chosen,
            verdicts: &verdicts,
            records: &records,
            measured: &measured,
            reward_profile: &dirs.reward_profile,
            total_seconds: start.elapsed().as_secs_f64(),
        },
    )?;
    println!("\n| claim | verdict | measured |\n|---|---|---|");
    for (c, v) in chosen.iter().zip(&verdicts) {
        println!("| {} | {} | {} |", c.id, v.verdict(), v.summary);
    }
    println!(
        "\nwrote {}",
        args.out.join("report").join("REPORT.md").display()
    );
    if let Some(dest) = &args.ship {
        ship::ship(dirs, &profile, &args.out, dest, &shipped)?;
    }
    Ok(())
}

/// One line of the [`Mode::Plan`].
fn plan_line(seed: u64, stage: &Stage) -> String {
    serde_json::json!({
        "seed": seed,
        "stage": stage.name,
        "init_from": stage.init_from,
        "scene": stage.scene,
        "phase": stage.phase.as_str(),
        "algo": stage.algo.as_str(),
    })
    .to_string()
}

/// Reuse a finished stage, resume an interrupted one, or train it.
fn run_stage(
    dirs: &ConfigDirs,
    profile: &Profile,
    stage: &Stage,
    root: &Path,
    seed: u64,
    args: &ReproduceOptions,
) -> Result<StageRecord> {
    let dir = root.join(&stage.name);
    let record_path = dir.join("reproduce.json");
    let scene = load_scene(dirs, &stage.scene, stage.phase)?;
    let mut budgets = Vec::new();
    for b in &scene.behaviours {
        budgets.push((b.name.clone(), stage.budget(profile, &b.species.name)?));
    }
    let mut record: StageRecord = std::fs::read_to_string(&record_path)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or_else(|| StageRecord {
            stage: stage.name.clone(),
            scene: stage.scene.clone(),
            algo: stage.algo.as_str().into(),
            phase: stage.phase.as_str().into(),
            budgets: budgets.clone(),
            ..Default::default()
        });
    if dir.join("final").join("state.json").is_file() {
        let state = deepfoids_learn::checkpoint::RunState::load(&dir.join("final"))?;
        check_budgets(&dir, &state, &budgets)?;
        state.check_reward_profile(&dir, &dirs.reward_profile, "reuse")?;
        if !record.timed {
            // Trained outside `reproduce` (same layout): time it by its files.
            record.wall_seconds = file_seconds(&dir).unwrap_or(f64::NAN);
            record.agent_steps = state.agent_steps;
        }
        eprintln!(
            "{}/{}: finished before, reusing it",
            root.display(),
            stage.name
        );
        return Ok(record);
    }
    let _lock = crate::lock_dir(&dir)?;
    let resume = !deepfoids_learn::checkpoint::checkpoints(&dir).is_empty();
    if !resume && dir.exists() {
        // Stopped before its first checkpoint: start it again from nothing.
        std::fs::remove_dir_all(&dir)
            .with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    let init: Vec<PathBuf> = stage.init_from.iter().map(|s| root.join(s)).collect();
    for i in &init {
        if !i.join("final").join("state.json").is_file() {
            bail!(
                "stage {} starts from {}, which has no final policy",
                stage.name,
                i.display()
            );
        }
    }
    // Each species' budget for this stage (the driver reads the phase's).
    let mut species_budgets = std::collections::BTreeMap::new();
    for b in &scene.behaviours {
        let sp = b.species.name.clone();
        let this = stage.budget(profile, &sp)?;
        let other = profile.budget(&sp, Phase::Pretrain)?;
        let pair = match stage.phase {
            Phase::Pretrain => [this, other],
            Phase::Transfer => [other, this],
        };
        species_budgets.insert(sp, pair);
    }
    let opts = TrainOptions {
        algo: stage.algo,
        seed,
        runs_dir: root.to_path_buf(),
        backend: deepfoids_learn::Backend::Flex,
        eval_seconds: 0.0,
        quiet: args.quiet,
        budgets: species_budgets,
        // A scaled-down reproduction (the tests' `--budget-scale`) may be
        // too short for an update; a real one never is.
        allow_no_update: args.budget_scale < 1.0,
    };
    let t0 = Instant::now();
    let trained = train_scene(
        dirs,
        scene,
        &dir,
        &format!("{}/{}", root.display(), stage.name),
        None,
        &init,
        resume,
        &opts,
    )
    .with_context(|| format!("stage {} (seed {seed})", stage.name))?;
    record.wall_seconds = if record.timed {
        record.wall_seconds
    } else {
        0.0
    } + t0.elapsed().as_secs_f64();
    record.agent_steps = trained.outcome.agent_steps;
    record.timed = true;
    deepfoids_io::write_atomic(
        &record_path,
        serde_json::to_string_pretty(&record)?.as_bytes(),
    )?;
    Ok(record)
}

/// A reused stage must have been trained to this profile's budgets.
fn check_budgets(
    dir: &Path,
    state: &deepfoids_learn::checkpoint::RunState,
    budgets: &[(String, u64)],
) -> Result<()> {
    for (name, want) in budgets {
        let got = state
            .behaviours
            .iter()
            .find(|b| &b.name == name)
            .map(|b| b.agent_steps);
        match got {
            Some(s) if s >= *want => {}
            Some(s) => bail!(
                "{} holds behaviour {name} trained {s} steps, but this profile trains it {want}: use another --out for another profile",
                dir.display()
            ),
            None => bail!("{} has no behaviour {name}", dir.display()),
        }
    }
    Ok(())
}

/// Seconds from a run's `config.toml` to its `final/state.json`.
fn file_seconds(dir: &Path) -> Option<f64> {
    let t = |p: PathBuf| std::fs::metadata(p).ok()?.modified().ok();
    let a = t(dir.join("config.toml"))?;
    let b = t(dir.join("final").join("state.json"))?;
    b.duration_since(a).ok().map(|d| d.as_secs_f64())
}
