//! `Env::step` allocates nothing: all buffers are made in `Env::new`.
use deepfoids_env::policy::action_buffers;
use deepfoids_env::{ConfigDirs, Env, GridFormat, Phase, Policy, RandomPolicy, Scene};

#[global_allocator]
static GLOBAL: deepfoids_testkit::Counting = deepfoids_testkit::Counting;

/// Measured on a worker of a 2-thread pool: calls from outside a pool go
/// through rayon's injector queue, which allocates a block per ~63 jobs (rayon's
/// own bookkeeping, not ours); trainers run their loop inside the pool.
#[test]
fn step_allocates_nothing() {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    pool.install(run);
}

fn run() {
    let dirs = ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs"));
    // Both grid formats: floats (the default) and the sensor's bytes.
    for (id, format) in [
        ("three_species", GridFormat::Floats),
        ("seabream_default", GridFormat::Floats),
        ("three_species", GridFormat::Bytes),
    ] {
        let mut scene = Scene::load(&dirs, id, Phase::Pretrain).unwrap();
        scene.physics.chase_probability = 0.5; // exercise chase starts and re-sensing too
        let mut env = Env::with_grid_format(scene, 3, format);
        let mut policy = RandomPolicy { seed: 4 };
        let mut actions = action_buffers(&env);
        for _ in 0..5 {
            policy.act(&env, &mut actions).unwrap();
            env.step(&actions).unwrap();
        }
        let mut during = 0;
        for _ in 0..30 {
            policy.act(&env, &mut actions).unwrap();
            let before = deepfoids_testkit::allocations();
            env.step(&actions).unwrap();
            during += deepfoids_testkit::allocations() - before;
        }
        assert_eq!(during, 0, "{id} ({format:?}): allocations during 30 steps");
    }
}
