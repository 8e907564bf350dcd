//! Issue 25: the training configs under fuzzing, as `env/tests/config_fuzz.rs`
//! fuzzes the scene files. Whatever `configs/train/ppo.toml` or `sac.toml`
//! holds — sizes from 0 to 10¹², negative numbers, any value for any key —
//!
//! * loading never panics and allocates at most [`LOAD_BOUND`] at once;
//! * an accepted config's memory plan (`driver::check_run`) stays within the
//!   plan of the largest sizes the bounds admit ([`max_plan`]), so no
//!   accepted file can ask for more than that finite figure;
//! * an accepted config whose plan is at most [`BUILD_BOUND`] trains on a
//!   10-fish scene (through its first update where that comes within
//!   [`UPDATE_WITHIN`] agent steps), and the whole run's peak allocation
//!   stays below its plan.
//!
//! The allocator counts every thread (Burn and rayon allocate on theirs), so
//! this binary holds one test.
use deepfoids_env::{ConfigDirs, Phase, Scene};
use deepfoids_learn::driver::{Trainer, check_run};
use deepfoids_learn::plan::{MAX_BUFFER, MAX_HIDDEN, MAX_LAYERS, TrainConfigFile};
use deepfoids_learn::{Backend, ProgressMode, RunArgs};
use deepfoids_ppo::{Ppo, PpoConfig};
use deepfoids_sac::{Sac, SacConfig};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

#[global_allocator]
static GLOBAL: deepfoids_testkit::Counting = deepfoids_testkit::Counting;

use deepfoids_testkit::peak_during;

/// Loading a training config (one small TOML file) stays below this.
const LOAD_BOUND: u64 = 16 << 20;
/// Accepted configs whose plan is at most this are trained.
const BUILD_BOUND: u64 = 600 << 20;
/// Trained through the first update when it comes within this many agent steps.
const UPDATE_WITHIN: u64 = 3_000;

fn configs() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs"))
}

/// A copy of the config root's `train/` and the files the 10-fish scene
/// reads, with `file` of `train/` replaced by `text`.
fn root_with(case: usize, file: &str, text: &str) -> PathBuf {
    let root = std::env::temp_dir().join(format!(
        "deepfoids-train-fuzz-{}-{case}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(root.join("train")).unwrap();
    for f in ["ppo.toml", "sac.toml"] {
        std::fs::copy(configs().join("train").join(f), root.join("train").join(f)).unwrap();
    }
    std::fs::write(root.join("train").join(file), text).unwrap();
    root
}

/// The shipped file with `key = value` lines replaced (or added).
fn with_values(file: &str, values: &[(&str, String)]) -> String {
    let text = std::fs::read_to_string(configs().join("train").join(file)).unwrap();
    let (head, budgets) = text.split_once("[budgets]").unwrap();
    let mut lines: Vec<String> = head
        .lines()
        .filter(|l| {
            let key = l.split('=').next().unwrap_or("").trim();
            !values.iter().any(|(k, _)| *k == key)
        })
        .map(str::to_string)
        .collect();
    for (k, v) in values {
        lines.push(format!("{k} = {v}"));
    }
    format!("{}\n[budgets]{budgets}", lines.join("\n"))
}

/// The plan of the largest sizes the bounds admit, on `scene`: no accepted
/// config may plan more.
fn max_plan(scene: &Scene, ppo: bool) -> u64 {
    let big = |hidden: u64, layers: u64, buffer: u64| {
        if ppo {
            let config = PpoConfig {
                hidden: hidden as usize,
                layers: layers as usize,
                buffer_size: buffer as usize,
                batch_size: buffer as usize,
                time_horizon: deepfoids_learn::plan::MAX_TIME_HORIZON as usize,
                ..PpoConfig::default()
            };
            check_run(&Ppo::new(config), scene, Some(u64::MAX.into()), true)
                .map(|c| c.plan.total())
                .unwrap_or_else(|e| memory_need(&e))
        } else {
            let config = SacConfig {
                hidden: hidden as usize,
                layers: layers as usize,
                buffer_size: buffer as usize,
                batch_size: buffer as usize,
                ..SacConfig::default()
            };
            check_run(&Sac::new(config), scene, Some(u64::MAX.into()), true)
                .map(|c| c.plan.total())
                .unwrap_or_else(|e| memory_need(&e))
        }
    };
    big(MAX_HIDDEN, MAX_LAYERS, MAX_BUFFER)
}

/// The need a memory refusal names (the plan of a refused run).
fn memory_need(e: &deepfoids_learn::LearnError) -> u64 {
    match e {
        deepfoids_learn::LearnError::Memory { error, .. } => match error {
            deepfoids_env::memory::MemoryError::TooLarge { need, .. } => *need,
            other => panic!("{other}"),
        },
        other => panic!("{other}"),
    }
}

/// Any value for a size field, weighted towards the troublesome ones.
fn size() -> impl Strategy<Value = String> {
    prop_oneof![
        prop::sample::select(vec![
            "0",
            "1",
            "2",
            "3",
            "8",
            "16",
            "64",
            "128",
            "512",
            "1024",
            "4096",
            "4097",
            "10240",
            "100000",
            "1000000",
            "100000000",
            "100000001",
            "1000000000000",
            "-1",
            "-1024",
            "1.5",
            "1e6",
            "\"128\"",
            "true",
            "nan",
            "inf",
        ])
        .prop_map(str::to_string),
        (1u64..3000).prop_map(|v| v.to_string()),
    ]
}

const PPO_FIELDS: [&str; 6] = [
    "hidden",
    "layers",
    "buffer_size",
    "batch_size",
    "epochs",
    "time_horizon",
];
const SAC_FIELDS: [&str; 6] = [
    "hidden",
    "layers",
    "buffer_size",
    "batch_size",
    "learning_starts",
    "steps_per_update",
];

/// Load, plan and (when small) train one fuzzed config.
fn check_case(case: usize, ppo: bool, values: Vec<(&str, String)>) -> Result<(), TestCaseError> {
    let file = if ppo { "ppo.toml" } else { "sac.toml" };
    let root = root_with(case, file, &with_values(file, &values));
    let dirs = ConfigDirs::new(&root);
    let scene = Scene::load(
        &ConfigDirs::new(configs()),
        "seabream_cube5",
        Phase::Pretrain,
    )
    .unwrap();
    let result = if ppo {
        load_and_train(&dirs, file, &scene, ppo, &root, |mut c: PpoConfig| {
            c.checkpoint_every = u64::MAX / 2;
            Ppo::new(c)
        })
    } else {
        load_and_train(&dirs, file, &scene, ppo, &root, |mut c: SacConfig| {
            c.checkpoint_every = u64::MAX / 2;
            Sac::new(c)
        })
    };
    let _ = std::fs::remove_dir_all(&root);
    result
}

/// Load `file` within [`LOAD_BOUND`] bytes: a refusal names it; a
/// configuration it takes trains within its plan (`trainer` makes the trainer).
fn load_and_train<C: TrainConfigFile, T: Trainer + Trains>(
    dirs: &ConfigDirs,
    file: &str,
    scene: &Scene,
    ppo: bool,
    root: &Path,
    trainer: impl FnOnce(C) -> T,
) -> Result<(), TestCaseError> {
    let (loaded, peak) = peak_during(|| C::load(dirs));
    prop_assert!(peak <= LOAD_BOUND, "loading took {} bytes", peak);
    match loaded {
        Err(e) => refused(&e.to_string(), file),
        Ok(config) => train_within_plan(&trainer(config), scene, ppo, root),
    }
}

/// A refusal names the file (one line, or the TOML parser's with its line).
fn refused(msg: &str, file: &str) -> Result<(), TestCaseError> {
    prop_assert!(msg.contains(file), "{}", msg);
    prop_assert!(!msg.contains('\n') || msg.contains("line"), "{}", msg);
    Ok(())
}

fn train_within_plan<T: Trainer + Trains>(
    trainer: &T,
    scene: &Scene,
    ppo: bool,
    root: &Path,
) -> Result<(), TestCaseError> {
    let plan = check_run(trainer, scene, Some(u64::MAX.into()), true)
        .map(|c| c.plan.total())
        .unwrap_or_else(|e| memory_need(&e));
    let max = max_plan(scene, ppo);
    prop_assert!(plan <= max, "planned {} > the bounds' {}", plan, max);
    if plan > BUILD_BOUND {
        return Ok(());
    }
    let n = scene.fish_count();
    let first = trainer.update_plan(n).first;
    // Twice the first update's steps: episode ends can shift PPO's joins by
    // up to a time horizon (n · time_horizon ≤ the first update's steps).
    let steps = if first <= UPDATE_WITHIN {
        2 * first
    } else {
        4 * n as u64
    };
    let args = RunArgs {
        scene: scene.clone(),
        run_dir: root.join("run"),
        run_id: "fuzz".into(),
        seed: 1,
        steps: Some(steps.into()),
        resume: false,
        init_from: vec![],
        backend: Backend::Flex,
        progress: ProgressMode::Quiet,
        progress_sink: None,
        save: false,
        config_toml: None,
    };
    let (out, peak) = peak_during(|| trainer.train(args));
    let out = out.map_err(|e| TestCaseError::fail(e.to_string()))?;
    if first <= UPDATE_WITHIN {
        prop_assert!(out.updates >= 1, "no update in {} steps", steps);
    }
    prop_assert!(
        peak <= plan,
        "training took {} bytes at its peak, above its plan of {}",
        peak,
        plan
    );
    eprintln!(
        "{}: peak {:.1} MB of a plan of {:.1} MB ({:.0} %), {} updates",
        if ppo { "ppo" } else { "sac" },
        peak as f64 / 1e6,
        plan as f64 / 1e6,
        100.0 * peak as f64 / plan as f64,
        out.updates
    );
    Ok(())
}

/// Either algorithm's training entry point.
trait Trains {
    fn train(&self, args: RunArgs) -> deepfoids_learn::Result<deepfoids_learn::TrainOutcome>;
}

impl Trains for Ppo {
    fn train(&self, args: RunArgs) -> deepfoids_learn::Result<deepfoids_learn::TrainOutcome> {
        deepfoids_ppo::train(self, args)
    }
}

impl Trains for Sac {
    fn train(&self, args: RunArgs) -> deepfoids_learn::Result<deepfoids_learn::TrainOutcome> {
        deepfoids_sac::train(self, args)
    }
}

#[test]
fn any_training_config_loads_within_bounds_and_trains_within_its_plan() {
    // The shipped configs first (their plan must hold with the real sizes)…
    check_case(
        0,
        true,
        vec![("buffer_size", "512".into()), ("batch_size", "128".into())],
    )
    .unwrap();
    check_case(1, false, vec![("learning_starts", "100".into())]).unwrap();
    // …then fuzzed ones.
    let mut runner = TestRunner::new(Config {
        cases: std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|c| c.parse().ok())
            .unwrap_or(if std::env::var_os("CI").is_some() {
                24
            } else {
                12
            }),
        failure_persistence: None,
        ..Config::default()
    });
    let case = AtomicUsize::new(2);
    let strategy = (
        any::<bool>(),
        prop::collection::vec((0..6usize, size()), 1..4),
    );
    runner
        .run(&strategy, |(ppo, changes)| {
            let fields = if ppo { PPO_FIELDS } else { SAC_FIELDS };
            let values = changes.into_iter().map(|(i, v)| (fields[i], v)).collect();
            check_case(case.fetch_add(1, Ordering::Relaxed), ppo, values)
        })
        .unwrap();
}
