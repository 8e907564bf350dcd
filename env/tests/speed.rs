//! The speed clamp (SPEC §4; issue 11, item 1): every fish's speed stays in its
//! species' schooling range `speed_bl·BL`, whoever acts; the lower bound is a floor.
mod common;
use common::*;
use deepfoids_env::FishParams;
use glam::Vec3;

/// One seabream (range [0.2, 2.7] BL/s, Δv_max 4.1 BL/s) given a0 for `n` decisions.
fn speeds_after(a0: f32, start_bl: f32, n: usize, params: Option<FishParams>) -> Vec<f32> {
    let mut env = calm_env(scene("seabream_default", 1));
    if let Some(p) = params {
        env.set_fish_params(0, p).unwrap();
    }
    common::place(&mut env, 0, Vec3::new(0.0, -1.5, 0.0), Vec3::Z, start_bl);
    env.observe_now();
    let bl = env.world().bl[0];
    (0..n)
        .map(|_| {
            env.step(&[vec![a0, 0.0, 0.0]]).unwrap();
            env.world().speed[0] / bl
        })
        .collect()
}

/// Regression (issue 11: "a policy can park its fish"): full braking from
/// 1 BL/s changes the speed by −4.1 BL/s per second (SPEC §4), −0.41 per
/// decision of k = 5 steps: 0.59, then the floor 0.2 BL/s at every decision
/// after; full acceleration from 0.2 climbs by 0.41 per decision and stops at 2.7.
#[test]
fn braking_stops_at_the_floor_and_acceleration_at_the_maximum() {
    let want = [0.59, 0.2, 0.2, 0.2];
    for (s, w) in speeds_after(-1.0, 1.0, 4, None).into_iter().zip(want) {
        assert!(close(s, w, 1e-5), "{s} vs {w}");
    }
    let want = [0.61, 1.02, 1.43, 1.84, 2.25, 2.66, 2.7, 2.7];
    for (s, w) in speeds_after(1.0, 0.2, 8, None).into_iter().zip(want) {
        assert!(close(s, w, 1e-4), "{s} vs {w}");
    }
}

/// A model with its own speed range (Foids at night: [0, 0.4] BL/s) may go
/// below the species' floor — only when it says so: full braking from 1 BL/s
/// (clamped into the range, 0.4, at the decision) then reaches 0 (the fish
/// keeps its heading), and full acceleration 0.4.
#[test]
fn fish_params_set_their_own_range() {
    let night = FishParams {
        speed_bl: [0.0, 0.4],
        light_steep: [-20.0, 1000.0],
    };
    for s in speeds_after(-1.0, 1.0, 3, Some(night)) {
        assert!(s.abs() < 1e-5, "{s}");
    }
    for s in speeds_after(1.0, 0.2, 2, Some(night)) {
        assert!(close(s, 0.4, 1e-5), "{s}");
    }
}

/// Bad parameters are refused with a message naming the fish and the value;
/// reset restores the species' values.
#[test]
fn fish_params_are_checked_and_reset() {
    let mut env = calm_env(scene("seabream_default", 2));
    let species = env.species_params(1);
    assert_eq!(species.speed_bl, [0.2, 2.7]);
    let err = env
        .set_fish_params(
            1,
            FishParams {
                speed_bl: [0.5, 0.1],
                ..species
            },
        )
        .unwrap_err()
        .to_string();
    assert!(err.contains("fish 1") && err.contains("speed_bl"), "{err}");
    assert!(env.set_fish_params(5, species).is_err());
    let slow = FishParams {
        speed_bl: [0.0, 0.4],
        ..species
    };
    env.set_fish_params(1, slow).unwrap();
    assert_eq!(env.fish_params(1), slow);
    env.reset();
    assert_eq!(env.fish_params(1), species);
}
