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

/// An env handing out bytes is the same world: at every tick of a random run
/// (chases and respawns in `three_species`) its stacks are the float env's
/// stacks quantised, frame by frame, and the rest of the output is equal.
/// Switching formats mid-run converts the stacks held, and going back to
/// floats senses the newest frames again exactly.
#[test]
fn byte_frames_are_the_float_frames_quantised() {
    use deepfoids_env::{GridFormat, GridsRef};
    use deepfoids_sensors::frames::quantise;
    use deepfoids_sensors::{FRAME_BYTES, FRAME_LEN, STACK, STACK_BYTES, STACKED_LEN};
    let quantised = |grids: &[f32]| {
        let mut out = vec![0u8; grids.len() / STACKED_LEN * STACK_BYTES];
        for (src, dst) in grids
            .chunks_exact(FRAME_LEN)
            .zip(out.chunks_exact_mut(FRAME_BYTES))
        {
            quantise(src, dst);
        }
        out
    };
    let scene = Scene::load(&dirs(), "three_species", Phase::Pretrain).unwrap();
    let mut floats = Env::new(scene.clone(), 4);
    let mut bytes = Env::with_grid_format(scene, 4, GridFormat::Bytes);
    assert_eq!(bytes.grid_format(), GridFormat::Bytes);
    let mut policy = RandomPolicy { seed: 9 };
    let mut actions = action_buffers(&floats);
    let mut respawns = 0;
    for tick in 0..40 {
        for (f, b) in floats
            .output()
            .behaviours
            .iter()
            .zip(&bytes.output().behaviours)
        {
            assert!(b.grids.is_empty() && f.frames.is_empty());
            assert!(matches!(b.observations(), GridsRef::Compact(_)));
            assert_eq!(b.frames, quantised(&f.grids), "tick {tick}, {}", b.name);
            assert_eq!((&b.vectors, &b.rewards), (&f.vectors, &f.rewards));
            respawns += f.terminated.iter().filter(|&&t| t).count();
        }
        assert_eq!(bytes.world().position, floats.world().position);
        policy.act(&floats, &mut actions).unwrap();
        floats.step(&actions).unwrap();
        bytes.step(&actions).unwrap();
    }
    assert!(respawns > 0, "the run should see respawns");
    // Floats → bytes: the same bytes; bytes → floats: the older frames
    // within 1/510, the newest sensed again (exact).
    let before = floats.output().behaviours[0].grids.clone();
    floats.set_grid_format(GridFormat::Bytes);
    assert_eq!(
        floats.output().behaviours[0].frames,
        bytes.output().behaviours[0].frames
    );
    bytes.set_grid_format(GridFormat::Floats);
    let back = &bytes.output().behaviours[0].grids;
    assert_eq!(back.len(), before.len());
    for (a, (x, y)) in back
        .chunks_exact(STACKED_LEN)
        .zip(before.chunks_exact(STACKED_LEN))
        .enumerate()
    {
        let newest = (STACK - 1) * FRAME_LEN;
        assert_eq!(x[newest..], y[newest..], "agent {a}'s newest frame");
        let worst = x[..newest]
            .iter()
            .zip(&y[..newest])
            .map(|(p, q)| (p - q).abs())
            .fold(0.0f32, f32::max);
        assert!(
            worst <= deepfoids_sensors::frames::PROXIMITY_TOLERANCE,
            "agent {a}: {worst}"
        );
    }
}
