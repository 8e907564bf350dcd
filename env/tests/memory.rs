//! `memory::env_bytes` is an upper bound of what `Env::new` allocates, and not
//! a loose one: measured with a counting allocator (one test in this binary,
//! so no other test allocates meanwhile).
mod common;
use deepfoids_env::config::{CageConfig, Range};
use deepfoids_env::memory::env_bytes;
use deepfoids_env::{Env, Phase, Scene};
use proptest::test_runner::{Config, TestRunner};

#[global_allocator]
static GLOBAL: deepfoids_testkit::Counting = deepfoids_testkit::Counting;

/// The most memory in use at once while building the env, above what was in use before.
fn measured(scene: &Scene) -> usize {
    let (env, peak) = deepfoids_testkit::peak_during(|| Env::new(scene.clone(), 1));
    drop(env);
    peak as usize
}

/// The estimate is an upper bound; with fixed body scales (so the neighbour
/// grids' cells are known) it is also within 10 % + 2 MiB.
fn assert_bounds(scene: &Scene) {
    let need = env_bytes(scene) as f64;
    let got = measured(scene) as f64;
    assert!(
        got <= need,
        "{}: Env::new took {got} bytes, more than the estimate of {need}",
        scene.id
    );
    let fixed = scene.behaviours.iter().all(|b| {
        b.body_scales
            .iter()
            .all(|(_, r)| matches!(r, Range::Fixed(_)))
    });
    if fixed {
        assert!(
            need <= 1.1 * got + (2 << 20) as f64,
            "{}: estimate {need} bytes for {got} measured",
            scene.id
        );
    }
}

#[test]
fn the_estimate_bounds_what_env_new_allocates() {
    // Thread pool and lazy statics first, so they are not counted.
    drop(Env::new(common::scene("seabream_default", 3), 0));
    let dirs = common::dirs();
    for id in dirs.list("scenes") {
        assert_bounds(&Scene::load(&dirs, &id, Phase::Pretrain).unwrap());
    }
    // Fish counts, cage sizes and body scales drawn at random.
    let base = Scene::load(&dirs, "seabream_default", Phase::Pretrain).unwrap();
    let mut runner = TestRunner::new(Config {
        cases: 16,
        ..Config::default()
    });
    runner
        .run(
            &(1usize..2500, 3.0f32..400.0, 0.3f32..2.0, 1.0f32..50.0),
            |(n, edge, scale, sense)| {
                let mut s = base.clone();
                s.cage_config = CageConfig::Cube { edge };
                s.behaviours[0].count = n;
                s.behaviours[0].species.sense_range_bl = sense;
                for range in [Range::Fixed(scale), Range::Uniform([scale, scale * 1.2])] {
                    s.behaviours[0].body_scales = vec![(n, range)];
                    assert_bounds(&s);
                }
                Ok(())
            },
        )
        .unwrap();
}
