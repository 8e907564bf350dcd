//! `Env::step` allocates nothing: all buffers are made in `Env::new`.
use deepfoids_env::policy::action_buffers;
use deepfoids_env::{ConfigDirs, Env, Phase, Policy, RandomPolicy, Scene};

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
    for id in ["three_species", "seabream_default"] {
        let mut scene = Scene::load(&dirs, id, Phase::Pretrain).unwrap();
        scene.physics.chase_probability = 0.5; // exercise chase starts and re-sensing too
        let mut env = Env::new(scene, 3);
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
        assert_eq!(during, 0, "{id}: allocations during 30 steps");
    }
}
