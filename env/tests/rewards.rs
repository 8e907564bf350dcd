//! Each reward term on hand-built scenes (SPEC §6). Seabream, BL = 0.34 m,
//! d_sense = 1.02 m, k = 5, decision 0.1 s, pretraining weights; light and
//! temperature never push (the helpers widen the light band; 21–22 °C is preferred).
//! The terms' definitions in the `legacy` profile's timing (every term once per
//! decision, the action spread over the decision, no contact kicks); the
//! per-step timing of SPEC §4 / §6.1 is tested in timing.rs.
mod common;
use common::*;

/// Scene `id` with `n` fish in the `legacy` profile's timing.
fn scene(id: &str, n: usize) -> deepfoids_env::Scene {
    use deepfoids_env::config::{ActionTiming, RewardTiming};
    let mut s = common::scene(id, n);
    s.rewards.timing.actions = ActionTiming::PerDecision;
    s.rewards.timing.rewards = RewardTiming::PerDecision;
    s.rewards.contacts.kick = 0.0;
    s.rewards.contacts.push = 0.0;
    s
}
use deepfoids_env::Chase;
use glam::Vec3;

/// Two fish 0.5 m apart in mid-water, headings 30° apart:
/// r_ND = 1.5 · (90 − 30)/90 = 1.0 for each; nothing else within range.
#[test]
fn neighbour_distance_term() {
    let mut env = calm_env(scene("seabream_default", 2));
    let c = Vec3::new(-0.25, -1.5, -0.2);
    place(&mut env, 0, c, Vec3::Z, 0.2);
    let f1 = Vec3::new(30f32.to_radians().sin(), 0.0, 30f32.to_radians().cos());
    place(&mut env, 1, c + Vec3::new(0.5, 0.0, 0.0), f1, 0.2);
    env.observe_now();
    env.step(&zeros(&env)).unwrap();
    for i in 0..2 {
        let t = terms(&env, i);
        assert!(close(t[ND], 1.0, 1e-3), "fish {i}: {t:?}");
        assert_eq!(t[BD], 0.0);
        assert_eq!(t[NC], 0.0);
    }
}

/// Fish 0 with four neighbours in range (0.3, 0.5, 0.7, 0.9 m to its side),
/// headings 0°, 30°, 60°, 90° off its own: the thesis' sum gives
/// r_ND = 1.5 · (1 + 2/3 + 1/3 + 0) = 3.0; capped at the 2 nearest,
/// 1.5 · (1 + 2/3) = 2.5; capped at 1, 1.5.
#[test]
fn neighbour_distance_term_capped_at_the_nearest() {
    for (cap, want) in [(0u32, 3.0f32), (2, 2.5), (1, 1.5), (8, 3.0)] {
        let mut sc = scene("seabream_default", 5);
        sc.rewards.neighbour_cap = cap;
        let t = four_neighbours_terms(calm_env(sc));
        assert!(close(t[ND], want, 2e-3), "cap {cap}: {t:?}");
    }
}

/// A fish 0.5 m from the wall at x = 1.5, swimming along it:
/// r_BD = −2 · (1.02 − 0.5)/1.02 = −1.019608.
#[test]
fn boundary_distance_term() {
    let t = lone_fish_terms(scene("seabream_default", 1), Vec3::new(1.0, -1.5, 0.0), 0.2);
    assert!(close(t[BD], -1.019608, 1e-4), "{t:?}");
    assert_eq!(t[BC], 0.0);
}

/// Two fish side by side 0.03 m apart (each 0.0476 m wide) overlap: N_hit = 1,
/// r_NC = −0.5 each; a third fish far away has none.
#[test]
fn neighbour_collision_term() {
    let mut env = calm_env(scene("seabream_default", 3));
    let c = Vec3::new(0.0, -1.5, 0.0);
    place(&mut env, 0, c, Vec3::Z, 0.2);
    place(&mut env, 1, c + Vec3::new(0.03, 0.0, 0.0), Vec3::Z, 0.2);
    place(&mut env, 2, Vec3::new(-1.0, -2.5, -1.0), Vec3::X, 0.2);
    env.observe_now();
    env.step(&zeros(&env)).unwrap();
    assert_eq!(terms(&env, 0)[NC], -0.5);
    assert_eq!(terms(&env, 1)[NC], -0.5);
    assert_eq!(terms(&env, 2)[NC], 0.0);
    assert_eq!(env.output().behaviours[0].new_collisions[..], [1, 1, 0]);
    // The mild repulsion pushed them apart along x.
    let gap = (env.world().position[1] - env.world().position[0]).x;
    assert!(gap > 0.03, "gap {gap}");
}

/// Action (0.5, 0, 0.5) from 0.2 BL/s heading +z: target 0.2 + 0.5·4.1 = 2.25
/// BL/s turned 10° (yaw): Δv_f = 2.25·(sin 10°, 0, cos 10°) − (0, 0, 0.2) =
/// (0.390708, 0, 2.015818), |Δv_f| = 2.053333 BL/s, spread over k = 5 steps:
/// |Δv_a| = 0.410667 BL/s per step (no light or temperature push here).
/// r_E = −0.001 · 10 − 5 · 0.410667 = −2.063333. Level at ≥ 0.3 BL/s: r_M = +2.
#[test]
fn energy_and_movement_terms() {
    let mut env = calm_env(scene("seabream_default", 1));
    place(&mut env, 0, Vec3::new(0.0, -1.5, -0.5), Vec3::Z, 0.2);
    env.observe_now();
    let out = env.step(&[vec![0.5, 0.0, 0.5]]).unwrap();
    let t = out.behaviours[0].terms[0];
    assert!(close(t[E], -2.063333, 1e-4), "{t:?}");
    assert_eq!(t[M], 2.0);
    // Slow (v0 = 0.2 BL/s < 0.3) and level: r_M = 0.
    let mut env = calm_env(scene("seabream_default", 1));
    place(&mut env, 0, Vec3::new(0.0, -1.5, -0.5), Vec3::Z, 0.2);
    env.observe_now();
    let t = env.step(&[vec![0.0, 0.0, 0.0]]).unwrap().behaviours[0].terms[0];
    assert_eq!(t[M], 0.0);
    assert!(close(t[E], 0.0, 1e-6));
}

/// The light push is part of Eq. 4.4's Δv_a, so it costs energy too: a seabream
/// at night (Δv_light = 5.75/25.75 = 0.223301 BL/s up), level at the floor with
/// a zero action: |Δv_a| = 0.223301/5 = 0.0446602 BL/s per step; the body turns
/// from (0, 0, 0.2) to (0, 0.223301, 0.2) BL/s, atan(1.116505) = 48.1511°:
/// r_E = −0.001 · 48.1511 − 5 · 0.0446602 = −0.271452.
#[test]
fn environmental_push_costs_energy() {
    let mut s = scene("seabream_default", 1);
    s.clock.start_hours = 22.0;
    s.physics.chase_probability = 0.0;
    let mut env = deepfoids_env::Env::new(s, 1);
    place(&mut env, 0, Vec3::new(0.0, -1.5, -0.5), Vec3::Z, 0.2);
    env.observe_now();
    let t = env.step(&zeros(&env)).unwrap().behaviours[0].terms[0];
    assert!(close(t[E], -0.271452, 1e-4), "{t:?}");
}

/// Pitched 60° up (≥ θrt = 53°): r_M = −10.
#[test]
fn steep_pitch_is_penalised() {
    let mut env = calm_env(scene("seabream_default", 1));
    let f = Vec3::new(0.0, 60f32.to_radians().sin(), 60f32.to_radians().cos());
    place(&mut env, 0, Vec3::new(0.0, -2.0, 0.0), f, 1.0);
    env.observe_now();
    let t = env.step(&zeros(&env)).unwrap().behaviours[0].terms[0];
    assert_eq!(t[M], -10.0);
}

/// Chase: aggressor 0 swims at 0.2 BL/s straight at target 1, 0.8 m ahead, which
/// swims away at 0.2 BL/s: r_C = 8 · 0.2 = 1.6 for the aggressor and
/// −1 · (d̂_t · v) = −1 · (−0.2) = +0.2 for the target.
#[test]
fn chase_terms() {
    let mut env = calm_env(scene("seabream_default", 2));
    place(&mut env, 0, Vec3::new(0.0, -1.5, -0.4), Vec3::Z, 0.2);
    place(&mut env, 1, Vec3::new(0.0, -1.5, 0.4), Vec3::Z, 0.2);
    start_chase(&mut env);
    env.observe_now();
    let t = env.step(&zeros(&env)).unwrap().behaviours[0].terms.clone();
    assert!(close(t[0][C], 1.6, 1e-4), "{:?}", t[0]);
    assert!(close(t[1][C], 0.2, 1e-4), "{:?}", t[1]);
}

/// The aggressor touching its target earns +100 once, and the chase ends.
#[test]
fn catching_the_target() {
    let mut env = calm_env(scene("seabream_default", 2));
    place(&mut env, 0, Vec3::new(0.0, -1.5, 0.0), Vec3::Z, 0.2);
    place(&mut env, 1, Vec3::new(0.0, -1.5, 0.3), Vec3::Z, 0.2);
    let w = env.world_mut();
    w.chase[0] = Chase::Aggressor {
        target: 1,
        since: 0.0,
    };
    w.chase[1] = Chase::Target { aggressor: 0 };
    env.observe_now();
    let t = env.step(&zeros(&env)).unwrap().behaviours[0].terms[0];
    assert_eq!(t[C], 100.0);
    assert_eq!(env.world().chase[0], Chase::None);
    assert_eq!(env.world().chase[1], Chase::None);
}

/// Crossing the wall: r_BC = −300, terminated, respawned inside at v0, fresh frame stack.
#[test]
fn boundary_collision_terminates_and_respawns() {
    let mut env = calm_env(scene("seabream_default", 1));
    // 0.25 m from the wall at z = 1.5, nose at 0.08 m from it, full speed ahead.
    place(&mut env, 0, Vec3::new(0.0, -1.5, 1.25), Vec3::Z, 2.7);
    env.observe_now();
    env.step(&[vec![1.0, 0.0, 0.0]]).unwrap();
    let b = &env.output().behaviours[0];
    assert!(b.terminated[0] && !b.truncated[0]);
    assert_eq!(b.terms[0][BC], -300.0);
    assert_eq!(b.rewards[0], -300.0);
    let w = env.world();
    let bl = w.bl[0];
    assert!(env.cage().clearance(w.position[0]) > 0.0);
    // Respawned with v0 and gliding since (no action): speed still ≈ 0.2 BL/s.
    assert!(close(w.speed[0] / bl, 0.2, 1e-3), "{}", w.speed[0] / bl);
    // A fresh stack: the two older frames are zeros.
    let older = &b.grids[..2 * deepfoids_sensors::FRAME_LEN];
    assert!(older.iter().all(|&x| x == 0.0));
    assert!(
        b.grids[2 * deepfoids_sensors::FRAME_LEN..]
            .iter()
            .any(|&x| x != 0.0)
            || env.cage().clearance(w.position[0]) > 1.02
    );
}

/// With max_episode_decisions = 3 a safe fish is truncated at decisions 3 and 6, not between.
#[test]
fn truncation_at_max_length() {
    let mut s = scene("seabream_default", 1);
    s.physics.max_episode_decisions = 3;
    let mut env = calm_env(s);
    place(&mut env, 0, Vec3::new(0.0, -1.5, -1.0), Vec3::Z, 0.0);
    env.observe_now();
    let mut flags = vec![];
    for _ in 0..7 {
        let out = env.step(&zeros(&env)).unwrap();
        flags.push((
            out.behaviours[0].truncated[0],
            out.behaviours[0].terminated[0],
        ));
    }
    let truncated: Vec<bool> = flags.iter().map(|f| f.0).collect();
    assert_eq!(
        truncated,
        vec![false, false, true, false, false, true, false]
    );
    assert!(flags.iter().all(|f| !f.1));
}

/// Collision counting for the metrics: one placed collision between two fish is
/// one new collision each (2 over the pair); a second decision of the same
/// contact adds none; the recorder turns it into collisions per fish-hour:
/// 2 collisions / (3 fish × 0.2 s / 3600 s/h) = 12,000 per fish-hour.
#[test]
fn collision_counting_for_the_metrics() {
    let mut env = calm_env(scene("seabream_default", 3));
    let c = Vec3::new(0.0, -1.5, 0.0);
    place(&mut env, 0, c, Vec3::Z, 0.0);
    place(&mut env, 1, c + Vec3::new(0.02, 0.0, 0.0), Vec3::Z, 0.0);
    place(&mut env, 2, Vec3::new(-1.0, -2.5, -1.0), Vec3::X, 0.0);
    env.observe_now();
    let mut rec = deepfoids_env::metrics::Recorder::new(&env);
    rec.sample(env.output());
    for _ in 0..2 {
        let out = env.step(&zeros(&env)).unwrap();
        rec.count(out);
        rec.sample(out);
    }
    assert_eq!(rec.samples[1].neighbour_collisions, 2);
    // Still touching (repulsion is mild): not a new collision.
    assert_eq!(
        rec.samples[2].neighbour_collisions,
        0,
        "{:?}",
        env.output().behaviours[0].new_collisions
    );
    let s = rec.summary(0.2);
    assert!(
        (s.neighbour_collisions_per_fish_hour - 12_000.0).abs() < 1e-6,
        "{}",
        s.neighbour_collisions_per_fish_hour
    );
    assert_eq!(s.boundary_collisions_per_fish_hour, 0.0);
}
