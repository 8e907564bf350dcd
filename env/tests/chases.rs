//! Dominance and chases (SPEC §6): who starts, whom they chase, and the three ways a chase ends.
mod common;
use common::*;
use deepfoids_env::Chase;
use glam::Vec3;

/// With p_a = 1 every free dominant fish starts a chase at its first decision,
/// against its nearest subordinate within d_sense; subordinates never start one.
#[test]
fn chases_start_for_dominant_fish_against_the_nearest_subordinate() {
    let mut s = scene("seabream_default", 4);
    s.physics.chase_probability = 1.0;
    let mut env = deepfoids_env::Env::new(s, 3);
    for (i, x) in [-1.0f32, -0.5, -0.2, 1.2].into_iter().enumerate() {
        place(&mut env, i, Vec3::new(x, -1.5, 0.0), Vec3::Z, 0.0);
    }
    let w = env.world_mut();
    w.dominant = vec![true, false, false, false];
    for p in &mut w.light_pref {
        *p = [0.0, 999.0];
    }
    env.observe_now();
    env.step(&zeros(&env)).unwrap();
    let w = env.world();
    // Fish 1 (0.5 m) is nearer than fish 2 (0.8 m); fish 3 is out of range (2.2 m).
    assert!(
        matches!(w.chase[0], Chase::Aggressor { target: 1, .. }),
        "{:?}",
        w.chase
    );
    assert_eq!(w.chase[1], Chase::Target { aggressor: 0 });
    assert_eq!(w.chase[2], Chase::None);
    assert_eq!(w.chase[3], Chase::None);
    // The roles are observed at once.
    let v = &env.output().behaviours[0].vectors;
    assert_eq!((v[4], v[5], v[10], v[11]), (1.0, 0.0, 0.0, 1.0));
}

/// No dominant fish, no chase, even with p_a = 1.
#[test]
fn subordinates_never_start_chases() {
    let mut s = scene("seabream_default", 3);
    s.physics.chase_probability = 1.0;
    let mut env = deepfoids_env::Env::new(s, 3);
    env.world_mut().dominant = vec![false; 3];
    for _ in 0..3 {
        env.step(&zeros(&env)).unwrap();
    }
    assert!(env.world().chase.iter().all(|c| *c == Chase::None));
}

/// A running chase between fish 0 (aggressor) and 1 (target), both at rest, p_a = 0.
fn chasing(target_at: Vec3) -> deepfoids_env::Env {
    let mut env = calm_env(scene("seabream_default", 2));
    place(&mut env, 0, Vec3::new(0.0, -1.5, 0.0), Vec3::Z, 0.0);
    place(&mut env, 1, target_at, Vec3::Z, 0.0);
    start_chase(&mut env);
    env.observe_now();
    env
}

#[test]
fn a_chase_ends_when_they_collide() {
    let mut env = chasing(Vec3::new(0.0, -1.5, 0.3));
    env.step(&zeros(&env)).unwrap();
    assert_eq!(env.world().chase, vec![Chase::None, Chase::None]);
    assert_eq!(env.output().behaviours[0].terms[0][6], 100.0);
}

#[test]
fn a_chase_ends_when_the_target_gets_behind() {
    let mut env = chasing(Vec3::new(0.3, -1.5, -0.5));
    env.step(&zeros(&env)).unwrap();
    assert_eq!(env.world().chase, vec![Chase::None, Chase::None]);
    assert_ne!(env.output().behaviours[0].terms[0][6], 100.0);
}

#[test]
fn a_chase_ends_after_the_timeout() {
    let mut env = chasing(Vec3::new(0.0, -1.5, 0.8));
    // 3 s = 30 decisions of 0.1 s; still chasing after 29.
    for _ in 0..29 {
        env.step(&zeros(&env)).unwrap();
    }
    assert!(matches!(env.world().chase[0], Chase::Aggressor { .. }));
    env.step(&zeros(&env)).unwrap();
    assert_eq!(env.world().chase, vec![Chase::None, Chase::None]);
}
