//! The policies that ship in `policies/` (issues 14 and 21): each loads, its
//! Burn weights act as its ONNX twin does (≤ 1e-4), and an evaluation in its
//! own scene, in the card's reward profile and evaluation mode, still gives
//! its model card's figures — so a change to the environment that breaks the
//! shipped policies fails here.

use deepfoids_env::policy::{act_and_step, action_buffers};
use deepfoids_env::{ConfigDirs, Env, GridsRef, Phase, Policy};
use deepfoids_experiments::reproduce::ship::{Card, SHIPPED, figure_values, shipped_name};
use deepfoids_experiments::{load_scene, load_trained};
use std::path::PathBuf;

/// Every shipped policy by name: `coho`, …, `coho/density_dense`.
fn names() -> Vec<String> {
    SHIPPED
        .iter()
        .map(|(sp, scene)| shipped_name(sp, scene))
        .collect()
}

fn shipped(name: &str) -> (PathBuf, Card) {
    let dir = deepfoids_experiments::pretrained::resolve(&format!("pretrained:{name}"))
        .unwrap_or_else(|e| panic!("{e}"));
    let card: Card = toml::from_str(
        &std::fs::read_to_string(dir.join("card.toml"))
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display())),
    )
    .unwrap();
    assert_eq!(card.name(), name);
    (dir, card)
}

fn configs() -> ConfigDirs {
    ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/configs"))
}

#[test]
fn every_shipped_policy_has_a_card() {
    let root = deepfoids_experiments::pretrained::root();
    let mut want = names();
    want.sort();
    assert_eq!(
        deepfoids_experiments::pretrained::available(&root),
        want,
        "in {}",
        root.display()
    );
    for (sp, scene) in SHIPPED {
        let name = shipped_name(sp, scene);
        let (dir, card) = shipped(&name);
        let md = root.join(format!("{name}.md"));
        assert!(md.is_file(), "{}", md.display());
        assert!(
            dir.join("final")
                .join(format!("{sp}_regular.onnx"))
                .is_file()
        );
        assert_eq!((card.species.as_str(), card.scene.as_str()), (sp, scene));
        for k in ["p", "m", "speed_bl", "boundary_per_fish_hour", "milling"] {
            assert!(card.figures.contains_key(k), "{name}: {k}");
        }
    }
}

/// Burn (both the fused kernels that act and Burn's own layers) against
/// tract running the exported ONNX, on observations of the school after 2 s.
#[test]
fn shipped_policies_match_their_onnx_twins() {
    for name in names() {
        let (dir, card) = shipped(&name);
        let dirs = configs().with_reward_profile(&card.reward_profile);
        let scene = load_scene(&dirs, &card.scene, Phase::Transfer).unwrap();
        let mut env = Env::new(scene, 7);
        let mut policy = load_trained(&dir, None, &env, true, 0).unwrap();
        let mut actions = action_buffers(&env);
        let ticks = (2.0 / env.tick_seconds()).round() as usize;
        for _ in 0..ticks {
            act_and_step(&mut policy, &mut env, &mut actions).unwrap();
        }
        env.observe_now();
        for (b, batch) in env.output().behaviours.iter().enumerate() {
            let n = batch.n_agents.min(64);
            // Driven by its policy, the env hands out the sensor's bytes; ONNX
            // and Burn read the same observations rebuilt as floats.
            let bytes = &batch.frames[..n * deepfoids_sensors::STACK_BYTES];
            let dense = GridsRef::Compact(bytes).to_dense();
            let grids = &dense[..];
            let vectors = &batch.vectors[..n * 6];
            let onnx_path = dir.join("final").join(format!("{}.onnx", batch.name));
            let onnx = deepfoids_onnx::OnnxPolicy::load(&onnx_path, false).unwrap();
            let want = onnx.run(grids, vectors, n).unwrap();
            let actor = policy.actor(b);
            for (what, got) in [
                (
                    "fused kernels on bytes",
                    actor.deterministic(GridsRef::Compact(bytes), vectors),
                ),
                (
                    "fused kernels on floats",
                    actor.deterministic(GridsRef::Dense(grids), vectors),
                ),
                ("Burn layers", actor.deterministic_reference(grids, vectors)),
            ] {
                assert_eq!(got.len(), want.len());
                let worst = got
                    .iter()
                    .zip(&want)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0f32, f32::max);
                assert!(worst <= 1e-4, "{name} {what}: max |Δ| {worst} against ONNX");
            }
        }
        let _ = policy.name();
    }
}

/// The card's protocol with its first evaluation seed.
#[test]
fn shipped_policies_still_give_their_cards_figures() {
    let mut failures = vec![];
    for name in names() {
        let (dir, card) = shipped(&name);
        let dirs = configs().with_reward_profile(&card.reward_profile);
        let scene = load_scene(&dirs, &card.scene, Phase::Transfer).unwrap();
        let env_seed = card.env_seed(card.eval_seeds[0]);
        let mut env = Env::new(scene, env_seed);
        // A card records its evaluation mode; sampling is seeded by the env's seed.
        let seed = if card.deterministic() {
            card.train_seed
        } else {
            env_seed
        };
        let mut policy = load_trained(&dir, None, &env, card.deterministic(), seed).unwrap();
        let eval = deepfoids_experiments::evaluate::evaluate(
            &mut env,
            &mut policy,
            card.warmup,
            card.seconds,
            |_, _, _| {},
        )
        .unwrap();
        let s = eval.recorder.summary(eval.seconds);
        let measured = figure_values(&s);
        eprintln!("{name}: measured {measured:?}");
        for (k, x) in measured {
            let f = &card.figures[k];
            if !f.admits(x) {
                failures.push(format!(
                    "{name}: {k} = {x:.4}, the card says {:.4} (first seed; mean {:.4} ± {:.4}, tolerance {:.4})",
                    f.first.unwrap_or(f.mean),
                    f.mean,
                    f.sd,
                    f.tolerance()
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
