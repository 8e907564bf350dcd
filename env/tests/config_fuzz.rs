//! Issue 13, item 7: the configuration loader under fuzzing. Whatever a
//! scene, species, site, reward or baseline file holds — arbitrary bytes,
//! TOML-like text with any value for any real key, or a valid file with
//! values replaced by anything (NaN, ±∞, 1e30, i64::MAX, strings, tables) —
//! loading never panics and never allocates beyond its bound:
//!
//! * `Scene::load` allocates at most [`LOAD_BOUND`] bytes at once (files are
//!   at most 1 MiB);
//! * an accepted scene needs at most `memory::max_env_bytes()` (the
//!   `limits` hold), and when small enough to build here, `Env::new`
//!   allocates no more than `memory::env_bytes` says — and the environment
//!   then steps with random, Foids and Boids actions without a panic and
//!   with every fish at a finite position.
//!
//! The allocator counts per thread, so the tests of this binary may run in parallel.
mod common;
use deepfoids_env::baselines::{Boids, BoidsConfig, Foids, FoidsConfig};
use deepfoids_env::memory::{env_bytes, max_env_bytes};
use deepfoids_env::policy::action_buffers;
use deepfoids_env::{ConfigDirs, Env, Phase, Policy, RandomPolicy, Scene};
use proptest::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use toml::Value;

#[global_allocator]
static GLOBAL: deepfoids_testkit::Counting = deepfoids_testkit::Counting;

use deepfoids_testkit::thread_peak_during as peak_during;

/// Loading a scene (five small TOML files of at most 1 MiB each) stays below this.
const LOAD_BOUND: i64 = 16 << 20;
/// Accepted scenes up to this estimate are built and stepped.
const BUILD_BOUND: u64 = 48 << 20;

/// The files a scene load reads, relative to the config root.
const FILES: [&str; 7] = [
    "scenes/seabream_default.toml",
    "scenes/three_species.toml",
    "species/seabream.toml",
    "species/coho.toml",
    "sites/nishiki.toml",
    "rewards/thesis/pretrain.toml",
    "baselines/foids.toml",
];

/// The scene whose load reads `file`.
fn scene_of(file: &str) -> &'static str {
    match file {
        "scenes/three_species.toml" | "species/coho.toml" => "three_species",
        _ => "seabream_default",
    }
}

static CASE: AtomicUsize = AtomicUsize::new(0);

/// A fresh copy of the configs with `file` replaced by `text`.
fn configs_with(file: &str, text: &[u8]) -> PathBuf {
    let root = std::env::temp_dir().join(format!(
        "deepfoids-fuzz-{}-{}",
        std::process::id(),
        CASE.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&root);
    for sub in ["species", "sites", "scenes", "rewards", "baselines"] {
        common::copy_dir(&common::dirs().root.join(sub), &root.join(sub));
    }
    std::fs::write(root.join(file), text).unwrap();
    root
}

/// Load the scene reading `file` from `root` and check everything the module
/// docs promise; returns the error message if it was refused.
fn load_and_check(root: &Path, file: &str) -> Result<(), TestCaseError> {
    let dirs = ConfigDirs::new(root);
    let (loaded, peak) = peak_during(|| Scene::load(&dirs, scene_of(file), Phase::Pretrain));
    prop_assert!(peak <= LOAD_BOUND, "loading took {} bytes at once", peak);
    let foids = FoidsConfig::load(&dirs.baseline("foids").unwrap());
    let result = match loaded {
        Err(e) => {
            let msg = e.to_string();
            // One line that names a file of the config root (or says the scene is unknown).
            prop_assert!(!msg.contains('\n') || msg.contains("line"), "{}", msg);
            prop_assert!(msg.contains(".toml") || msg.contains("unknown"), "{}", msg);
            Ok(())
        }
        Ok(scene) => {
            let need = env_bytes(&scene);
            prop_assert!(need <= max_env_bytes(), "{} bytes accepted", need);
            if need <= BUILD_BOUND {
                step(scene, need, foids.ok())?;
            }
            Ok(())
        }
    };
    let _ = std::fs::remove_dir_all(root);
    result
}

/// Build the env (within its estimate) and step it with three policies.
fn step(scene: Scene, need: u64, foids: Option<FoidsConfig>) -> Result<(), TestCaseError> {
    let (env, peak) = peak_during(|| Env::new(scene, 5));
    prop_assert!(
        peak as u64 <= need,
        "Env::new took {} bytes, estimate {}",
        peak,
        need
    );
    let mut env = env;
    let mut policies: Vec<Box<dyn Policy>> = vec![
        Box::new(RandomPolicy { seed: 1 }),
        Box::new(Boids::new(BoidsConfig::default())),
    ];
    if let Some(f) = foids {
        policies.push(Box::new(Foids::new(f, 2)));
    }
    let mut actions = action_buffers(&env);
    for policy in &mut policies {
        for _ in 0..2 {
            policy.act(&env, &mut actions).unwrap();
            env.step(&actions).unwrap();
        }
    }
    let w = env.world();
    prop_assert!(
        w.position.iter().all(|p| p.is_finite()),
        "a fish left the finite world"
    );
    Ok(())
}

/// Any TOML value, weighted towards the troublesome ones.
fn value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        any::<i64>().prop_map(Value::Integer),
        prop::sample::select(vec![
            0i64,
            1,
            -1,
            3,
            256,
            257,
            65_536,
            200_000,
            200_001,
            u32::MAX as i64,
            i64::MAX,
            i64::MIN,
        ])
        .prop_map(Value::Integer),
        any::<f64>().prop_map(Value::Float),
        prop::sample::select(vec![
            0.0,
            -0.0,
            1e-30,
            1e-7,
            0.02,
            0.5,
            1.0,
            3.0,
            90.0,
            1e3,
            1e4,
            1e30,
            -1e30,
            f64::MAX,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ])
        .prop_map(Value::Float),
        "[a-z_]{0,10}".prop_map(Value::String),
        any::<bool>().prop_map(Value::Boolean),
    ];
    leaf.prop_recursive(2, 8, 3, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..4).prop_map(Value::Array),
            prop::collection::vec(("[a-z_]{1,8}", inner), 0..3)
                .prop_map(|kv| Value::Table(kv.into_iter().collect())),
        ]
    })
}

/// A path to a value inside a TOML document.
#[derive(Clone, Debug)]
enum Seg {
    Key(String),
    Index(usize),
}

/// Every value's path, tables and arrays included.
fn paths(v: &Value, here: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
    match v {
        Value::Table(t) => {
            for (k, x) in t {
                here.push(Seg::Key(k.clone()));
                out.push(here.clone());
                paths(x, here, out);
                here.pop();
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                here.push(Seg::Index(i));
                out.push(here.clone());
                paths(x, here, out);
                here.pop();
            }
        }
        _ => {}
    }
}

fn at<'a>(v: &'a mut Value, path: &[Seg]) -> Option<&'a mut Value> {
    path.iter().try_fold(v, |v, s| match (s, v) {
        (Seg::Key(k), Value::Table(t)) => t.get_mut(k),
        (Seg::Index(i), Value::Array(a)) => a.get_mut(*i),
        _ => None,
    })
}

/// What to do to a valid file.
#[derive(Clone, Debug)]
enum Edit {
    /// Replace the value at the `n`-th path.
    Set(prop::sample::Index, Value),
    /// Remove the key at the `n`-th path.
    Remove(prop::sample::Index),
    /// Add `key = value` to the table at the `n`-th path (or the root).
    Add(prop::sample::Index, String, Value),
    /// Multiply every number at or under the `n`-th path by a factor,
    /// keeping its type: plausible values gone extreme (`count = 10000000`).
    Scale(prop::sample::Index, f64),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        4 => (any::<prop::sample::Index>(), value()).prop_map(|(i, v)| Edit::Set(i, v)),
        1 => any::<prop::sample::Index>().prop_map(Edit::Remove),
        1 => (any::<prop::sample::Index>(), "[a-z_]{1,8}", value()).prop_map(|(i, k, v)| Edit::Add(i, k, v)),
        4 => (
            any::<prop::sample::Index>(),
            prop::sample::select(vec![0.0, -1.0, 1e-9, 1e-3, 0.1, 0.5, 2.0, 10.0, 1e3, 1e6, 1e12, 1e30, f64::NAN, f64::INFINITY]),
        )
            .prop_map(|(i, f)| Edit::Scale(i, f)),
    ]
}

fn scale(v: &mut Value, f: f64) {
    match v {
        Value::Integer(i) => *i = (*i as f64 * f) as i64,
        Value::Float(x) => *x *= f,
        Value::Array(a) => a.iter_mut().for_each(|x| scale(x, f)),
        Value::Table(t) => t.iter_mut().for_each(|(_, x)| scale(x, f)),
        _ => {}
    }
}

fn apply(doc: &mut Value, e: &Edit) {
    let mut all = Vec::new();
    paths(doc, &mut Vec::new(), &mut all);
    if all.is_empty() {
        return;
    }
    match e {
        Edit::Set(i, v) => {
            if let Some(x) = at(doc, i.get::<Vec<Seg>>(&all)) {
                *x = v.clone();
            }
        }
        Edit::Remove(i) => {
            let path = i.get::<Vec<Seg>>(&all);
            if let (Some(Seg::Key(k)), Some(Value::Table(t))) =
                (path.last(), at(doc, &path[..path.len() - 1]))
            {
                t.remove(k);
            }
        }
        Edit::Scale(i, f) => {
            if let Some(x) = at(doc, i.get::<Vec<Seg>>(&all)) {
                scale(x, *f);
            }
        }
        Edit::Add(i, k, v) => match at(doc, i.get::<Vec<Seg>>(&all)) {
            Some(Value::Table(t)) => {
                t.insert(k.clone(), v.clone());
            }
            _ => {
                if let Value::Table(t) = doc {
                    t.insert(k.clone(), v.clone());
                }
            }
        },
    }
}

/// Real keys of the species, site and physics tables, for overrides.
fn override_keys() -> Vec<String> {
    let mut keys = Vec::new();
    for f in ["species/seabream.toml", "sites/nishiki.toml"] {
        let t: toml::Table =
            toml::from_str(&std::fs::read_to_string(common::dirs().root.join(f)).unwrap()).unwrap();
        keys.extend(t.keys().cloned());
    }
    keys.extend(
        toml::Table::try_from(deepfoids_env::config::PhysicsConfig::default())
            .unwrap()
            .keys()
            .cloned(),
    );
    keys.extend(
        [
            "collider_bl",
            "visual_radius_bl",
            "initial_speed_bl",
            "max_delta_speed_bl",
            "light_steep",
            "temperature_steep",
            "dominant_fraction",
            "colour",
        ]
        .map(String::from),
    );
    keys
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

    /// Any bytes in any of the files.
    #[test]
    fn arbitrary_bytes_never_panic(
        file in prop::sample::select(FILES.to_vec()),
        bytes in prop::collection::vec(any::<u8>(), 0..1500),
    ) {
        load_and_check(&configs_with(file, &bytes), file)?;
    }

    /// TOML-like text: real keys with any value (as text, so that integers
    /// beyond i64 and malformed numbers occur), some of them in tables.
    #[test]
    fn toml_like_text_never_panics(
        file in prop::sample::select(FILES.to_vec()),
        lines in prop::collection::vec((
            prop::sample::select(override_keys()),
            prop_oneof![
                value().prop_map(|v| v.to_string()),
                Just("18446744073709551615".to_string()),
                Just("1e999".to_string()),
                Just("[1e30, nan]".to_string()),
                Just("\"\u{1F41F}\"".to_string()),
                "[ -~]{0,12}",
            ],
            prop::sample::select(vec!["", "[physics]\n", "[cage]\nshape = \"cube\"\n", "[[group]]\nspecies = \"seabream\"\n"]),
        ), 0..12),
    ) {
        let text: String = lines
            .iter()
            .map(|(k, v, table)| format!("{table}{k} = {v}\n"))
            .collect();
        load_and_check(&configs_with(file, text.as_bytes()), file)?;
    }

    /// A valid file with one to four values replaced, removed or added.
    #[test]
    fn arbitrary_values_in_valid_files(
        file in prop::sample::select(FILES.to_vec()),
        edits in prop::collection::vec(edit(), 1..5),
    ) {
        let original = std::fs::read_to_string(common::dirs().root.join(file)).unwrap();
        let mut doc = Value::Table(toml::from_str(&original).unwrap());
        for e in &edits {
            apply(&mut doc, e);
        }
        let text = toml::to_string(&doc).unwrap_or_default();
        load_and_check(&configs_with(file, text.as_bytes()), file)?;
    }

    /// Any value for any species, site or physics key, through a scene's
    /// `[species_overrides]`, `[site_overrides]` and `[physics]`.
    #[test]
    fn arbitrary_overrides_never_panic(
        sets in prop::collection::vec((
            prop::sample::select(vec!["species_overrides.seabream", "site_overrides", "physics"]),
            prop::sample::select(override_keys()),
            value(),
        ), 1..4),
    ) {
        let file = "scenes/seabream_default.toml";
        let original = std::fs::read_to_string(common::dirs().root.join(file)).unwrap();
        let mut doc: toml::Table = toml::from_str(&original).unwrap();
        for (section, key, v) in &sets {
            let mut t = &mut doc;
            for part in section.split('.') {
                t = t
                    .entry(part.to_string())
                    .or_insert_with(|| Value::Table(toml::Table::new()))
                    .as_table_mut()
                    .unwrap();
            }
            t.insert(key.clone(), v.clone());
        }
        let text = toml::to_string(&doc).unwrap_or_default();
        load_and_check(&configs_with(file, text.as_bytes()), file)?;
    }
}
