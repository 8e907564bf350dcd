//! Property: for random cages, species, school sizes, seeds and actions, after
//! every step every fish's collider lies inside the cage (a fish that crossed
//! was flagged terminated and respawned).
mod common;
use common::*;
use deepfoids_env::collide::Obb;
use deepfoids_env::config::CageConfig;
use deepfoids_env::kinematics::basis;
use deepfoids_env::rng::{Purpose, Stream};
use deepfoids_env::{Env, Phase, Scene};
use glam::Vec3;
use proptest::prelude::*;

fn cage_strategy() -> impl Strategy<Value = CageConfig> {
    prop_oneof![
        (2.0f32..6.0).prop_map(|edge| CageConfig::Cube { edge }),
        (2.0f32..6.0, 2.0f32..6.0, 2.0f32..5.0).prop_map(|(width, length, height)| {
            CageConfig::Box {
                width,
                length,
                height,
            }
        }),
        (1.2f32..3.5, 2.0f32..5.0).prop_map(|(edge, height)| CageConfig::Octagon { edge, height }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
    #[test]
    fn every_fish_stays_inside_the_cage(
        cage in cage_strategy(),
        species in prop::sample::select(vec!["seabream_default", "yellowtail_default", "coho_default"]),
        n in 1usize..40,
        seed in any::<u64>(),
        ticks in 1usize..25,
    ) {
        let mut s: Scene = Scene::load(&dirs(), species, Phase::Pretrain).unwrap();
        s.cage_config = cage;
        s.behaviours[0].count = n;
        s.behaviours[0].body_scales = vec![(n, s.behaviours[0].body_scales[0].1)];
        let collider = Vec3::from(s.behaviours[0].species.collider_bl);
        let mut env = Env::new(s, seed);
        let cage = env.cage().clone();
        for t in 0..ticks {
            // Bold actions: full speed and sharp turns.
            let acts: Vec<f32> = (0..n * 3)
                .map(|k| {
                    let u = Stream::new(seed, Purpose::Policy, k as u64, t as u64).uniform();
                    if k % 3 == 0 { 1.0 - 0.5 * u } else { 2.0 * u - 1.0 }
                })
                .collect();
            env.step(&[acts]).unwrap();
            let w = env.world();
            for i in 0..n {
                let obb = Obb { center: w.position[i], axes: basis(w.heading[i], w.roll[i]), half: collider * 0.5 * w.bl[i] };
                for b in &cage.boundaries {
                    prop_assert!(obb.clearance(&b.plane) >= -1e-4, "fish {} outside after tick {}: clearance {}", i, t, obb.clearance(&b.plane));
                }
            }
        }
    }
}
