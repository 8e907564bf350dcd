//! Seeded runs are bit-for-bit reproducible, whatever the number of threads (SPEC §7).
mod common;
use common::*;
use deepfoids_env::policy::action_buffers;
use deepfoids_env::{Env, Phase, Policy, RandomPolicy, Scene};

/// FNV-1a over every bit of the outputs of `ticks` random steps.
fn fingerprint(scene: &Scene, seed: u64, ticks: usize, threads: usize) -> u64 {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut env = Env::new(scene.clone(), seed);
        let mut policy = RandomPolicy { seed: seed + 1 };
        let mut actions = action_buffers(&env);
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |x: u32| {
            h ^= x as u64;
            h = h.wrapping_mul(0x100_0000_01b3);
        };
        for _ in 0..ticks {
            policy.act(&env, &mut actions).unwrap();
            let out = env.step(&actions).unwrap();
            for b in &out.behaviours {
                b.grids
                    .iter()
                    .chain(&b.vectors)
                    .chain(&b.rewards)
                    .for_each(|x| eat(x.to_bits()));
                b.terminated
                    .iter()
                    .chain(&b.truncated)
                    .for_each(|&x| eat(x as u32));
            }
            for p in &out.fish.position {
                eat(p.x.to_bits());
                eat(p.y.to_bits());
                eat(p.z.to_bits());
            }
        }
        h
    })
}

#[test]
fn same_seed_same_bits_with_one_or_two_threads() {
    for (id, ticks) in [("coho_default", 6), ("three_species", 8)] {
        let scene = Scene::load(&dirs(), id, Phase::Pretrain).unwrap();
        let one = fingerprint(&scene, 11, ticks, 1);
        let two = fingerprint(&scene, 11, ticks, 2);
        let again = fingerprint(&scene, 11, ticks, 2);
        assert_eq!(one, two, "{id}: 1 vs 2 threads");
        assert_eq!(two, again, "{id}: repeated run");
        assert_ne!(
            one,
            fingerprint(&scene, 12, ticks, 2),
            "{id}: another seed differs"
        );
    }
}

/// `reset` returns the very same initial state.
#[test]
fn reset_is_reproducible() {
    let mut env = Env::new(scene("seabream_50", 50), 5);
    let first = env.output().behaviours[0].grids.clone();
    let pos = env.world().position.clone();
    let mut policy = RandomPolicy { seed: 1 };
    let mut actions = action_buffers(&env);
    for _ in 0..5 {
        policy.act(&env, &mut actions).unwrap();
        env.step(&actions).unwrap();
    }
    env.reset();
    assert_eq!(env.world().position, pos);
    assert_eq!(env.output().behaviours[0].grids, first);
    assert_eq!(env.output().tick, 0);
}
