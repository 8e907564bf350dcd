//! The policies that ship in `policies/` (issue 14): each loads, its Burn
//! weights act as its ONNX twin does (≤ 1e-4), and a deterministic evaluation
//! in its default scene still gives its model card's figures — so a change to
//! the environment that breaks the shipped policies fails here.

use deepfoids_env::policy::{act_and_step, action_buffers};
use deepfoids_env::{ConfigDirs, Env, Phase, Policy};
use deepfoids_experiments::reproduce::ship::{Card, SPECIES};
use deepfoids_experiments::{load_scene, load_trained};
use std::path::PathBuf;

fn shipped(species: &str) -> (PathBuf, Card) {
    let dir = deepfoids_experiments::pretrained::resolve(&format!("pretrained:{species}"))
        .unwrap_or_else(|e| panic!("{e}"));
    let card: Card = toml::from_str(
        &std::fs::read_to_string(dir.join("card.toml"))
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display())),
    )
    .unwrap();
    assert_eq!(card.species, species);
    (dir, card)
}

fn configs() -> ConfigDirs {
    ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/configs"))
}

#[test]
fn every_species_ships_a_policy_with_a_card() {
    let root = deepfoids_experiments::pretrained::root();
    assert_eq!(
        deepfoids_experiments::pretrained::available(&root),
        vec!["coho", "seabream", "yellowtail"],
        "in {}",
        root.display()
    );
    for sp in SPECIES {
        let (dir, card) = shipped(sp);
        let md = root.join(format!("{sp}.md"));
        assert!(md.is_file(), "{}", md.display());
        assert!(
            dir.join("final")
                .join(format!("{sp}_regular.onnx"))
                .is_file()
        );
        assert_eq!(card.scene, format!("{sp}_default"));
        for k in ["p", "m", "speed_bl", "boundary_per_fish_hour", "milling"] {
            assert!(card.figures.contains_key(k), "{sp}: {k}");
        }
    }
}

/// Burn (both the fused kernels that act and Burn's own layers) against
/// tract running the exported ONNX, on observations of the school after 2 s.
#[test]
fn shipped_policies_match_their_onnx_twins() {
    for sp in SPECIES {
        let (dir, card) = shipped(sp);
        let scene = load_scene(&configs(), &card.scene, Phase::Transfer).unwrap();
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
            let grids = &batch.grids[..n * 18 * 20 * 34];
            let vectors = &batch.vectors[..n * 6];
            let onnx_path = dir.join("final").join(format!("{}.onnx", batch.name));
            let onnx = deepfoids_onnx::OnnxPolicy::load(&onnx_path, false).unwrap();
            let want = onnx.run(grids, vectors, n).unwrap();
            let actor = policy.actor(b);
            for (what, got) in [
                ("fused kernels", actor.deterministic(grids, vectors)),
                ("Burn layers", actor.deterministic_reference(grids, vectors)),
            ] {
                assert_eq!(got.len(), want.len());
                let worst = got
                    .iter()
                    .zip(&want)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0f32, f32::max);
                assert!(worst <= 1e-4, "{sp} {what}: max |Δ| {worst} against ONNX");
            }
        }
        let _ = policy.name();
    }
}

/// The card's protocol with its first evaluation seed.
#[test]
fn shipped_policies_still_give_their_cards_figures() {
    for sp in SPECIES {
        let (dir, card) = shipped(sp);
        let scene = load_scene(&configs(), &card.scene, Phase::Transfer).unwrap();
        let mut env = Env::new(scene, card.env_seed(card.eval_seeds[0]));
        let mut policy = load_trained(&dir, None, &env, true, card.train_seed).unwrap();
        let eval = deepfoids_experiments::evaluate::evaluate(
            &mut env,
            &mut policy,
            card.warmup,
            card.seconds,
            |_, _, _| {},
        )
        .unwrap();
        let s = eval.recorder.summary(eval.seconds);
        let share = |st: deepfoids_env::metrics::SchoolState| {
            s.state_share
                .iter()
                .find(|q| q.0 == st)
                .map_or(0.0, |q| q.1 as f64)
        };
        use deepfoids_env::metrics::SchoolState::*;
        let measured = [
            ("p", s.p_mean as f64),
            ("m", s.m_mean as f64),
            ("speed_bl", s.mean_speed_bl as f64),
            ("nn_bl", s.nn_mean_bl as f64),
            (
                "boundary_per_fish_hour",
                s.boundary_collisions_per_fish_hour,
            ),
            (
                "neighbour_per_fish_hour",
                s.neighbour_collisions_per_fish_hour,
            ),
            ("reward_per_decision", s.reward_per_decision),
            ("swarm", share(Swarm)),
            ("milling", share(Milling)),
            ("polarised", share(Polarised)),
            ("transitional", share(Transitional)),
        ];
        for (k, x) in measured {
            let f = &card.figures[k];
            assert!(
                f.admits(x),
                "{sp}: {k} = {x:.4}, the card says {:.4} ± {:.4} (tolerance {:.4})",
                f.mean,
                f.sd,
                f.tolerance()
            );
        }
    }
}
