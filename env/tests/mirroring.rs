//! The reward profile's `mirrored_share` (an extension, not in the sources): a
//! mirrored fish acts as the policy's mirror image — its grid's azimuth
//! columns reversed, `u_x` negated, its yaw action negated — so a school
//! driven by one policy need not share one handedness.
mod common;
use common::*;
use deepfoids_env::baselines::{Foids, FoidsConfig};
use deepfoids_env::policy::{act_and_step, action_buffers};
use deepfoids_env::{Env, Policy};
use deepfoids_sensors::{AZ_CELLS, EL_CELLS};

/// `n` coho of `coho_default` with `share` of them mirrored, seed 3.
fn env_with(share: f32, n: usize) -> Env {
    let mut s = scene("coho_default", n);
    s.rewards.extensions.mirrored_share = share;
    Env::new(s, 3)
}

/// The stacked grids `[n, 18, 20, 34]` with every row's columns reversed.
fn columns_reversed(grids: &[f32]) -> Vec<f32> {
    let mut out = grids.to_vec();
    for row in out.chunks_exact_mut(AZ_CELLS) {
        row.reverse();
    }
    assert_eq!(grids.len() % (AZ_CELLS * EL_CELLS), 0);
    out
}

#[test]
fn exactly_the_share_of_fish_is_mirrored_and_none_by_default() {
    let env = env_with(0.25, 10);
    let mirrored = (0..10).filter(|&i| env.is_mirrored(i)).count();
    assert_eq!(
        mirrored, 3,
        "round(0.25 · 10) = 3 (2.5 rounds away from zero)"
    );
    let again = env_with(0.25, 10);
    assert!((0..10).all(|i| env.is_mirrored(i) == again.is_mirrored(i)));
    let default = Env::new(scene("coho_default", 10), 3);
    assert!((0..10).all(|i| !default.is_mirrored(i)));
    assert!((0..10).all(|i| env_with(1.0, 10).is_mirrored(i)));
}

/// Two envs of the same seed, one with every fish mirrored: they see mirror
/// images (grids reversed column by column, `u_x` negated, the rest equal),
/// and the mirrored fish given the opposite yaw move exactly as the others,
/// decision after decision.
#[test]
fn a_mirrored_fish_sees_and_steers_as_the_mirror_image() {
    let (mut plain, mut mirror) = (env_with(0.0, 12), env_with(1.0, 12));
    plain.reset();
    mirror.reset();
    let mut saw_u = false;
    for decision in 0..6 {
        let (p, m) = (
            &plain.output().behaviours[0],
            &mirror.output().behaviours[0],
        );
        assert!(p.grids.iter().any(|&g| g > 0.0), "the fish see something");
        assert_eq!(columns_reversed(&p.grids), m.grids, "decision {decision}");
        for (vp, vm) in p.vectors.chunks(6).zip(m.vectors.chunks(6)) {
            assert_eq!(vm[0], -vp[0]);
            assert_eq!(vm[1..], vp[1..]);
            saw_u |= vp[0] != 0.0;
        }
        // Turning hard one way and the other, climbing, speeding up and down.
        let actions: Vec<f32> = (0..12)
            .flat_map(|a| {
                let t = (a + decision) as f32;
                [(0.7 * t).sin(), 0.3 * (0.5 * t).cos(), (1.3 * t).sin()]
            })
            .collect();
        let opposite: Vec<f32> = actions
            .chunks(3)
            .flat_map(|a| [a[0], a[1], -a[2]])
            .collect();
        plain.step(&[actions]).unwrap();
        mirror.step(&[opposite]).unwrap();
        let (wp, wm) = (plain.world(), mirror.world());
        assert_eq!(wp.position, wm.position, "decision {decision}");
        assert_eq!(wp.heading, wm.heading);
        assert_eq!(
            plain.output().behaviours[0].rewards,
            mirror.output().behaviours[0].rewards
        );
    }
    assert!(saw_u, "some fish had a neighbour in front");
}

/// The same yaw turns a mirrored fish the other way.
#[test]
fn the_same_yaw_turns_a_mirrored_fish_the_other_way() {
    let (mut plain, mut mirror) = (env_with(0.0, 1), env_with(1.0, 1));
    plain.reset();
    mirror.reset();
    let before = plain.world().heading[0];
    plain.step(&[vec![0.0, 0.0, 1.0]]).unwrap();
    mirror.step(&[vec![0.0, 0.0, 1.0]]).unwrap();
    let up = glam::Vec3::Y;
    let turn = |h: glam::Vec3| before.cross(h).dot(up);
    let (tp, tm) = (
        turn(plain.world().heading[0]),
        turn(mirror.world().heading[0]),
    );
    assert!(
        tp.abs() > 0.05,
        "a full yaw for a decision turns ≈ 10°: {tp}"
    );
    assert!((tp + tm).abs() < 1e-3 * tp.abs(), "{tp} against {tm}");
}

/// A rule-based baseline steers from the world: mirroring is off while it
/// drives, so the school is the same whatever the share.
#[test]
fn a_baseline_is_not_mirrored() {
    let run = |share: f32| {
        let mut env = env_with(share, 12);
        env.reset();
        let mut foids = Foids::new(FoidsConfig::default(), 1);
        assert!(!foids.mirrors());
        let mut actions = action_buffers(&env);
        for _ in 0..20 {
            act_and_step(&mut foids, &mut env, &mut actions).unwrap();
        }
        assert!((0..12).all(|i| !env.is_mirrored(i)));
        env.world().position.clone()
    };
    assert_eq!(run(0.0), run(1.0));
}

/// `mirror_redraw = "decision"`: each fish draws its handedness anew at every
/// decision (about half mirrored at 0.5), and a fish whose hand changed sees
/// its older frames mirrored too, so its stack is one consistent view: the
/// middle frame of a decision is the newest of the one before, reversed
/// column by column exactly when the hand changed.
#[test]
fn a_hand_drawn_anew_each_decision_keeps_the_stack_consistent() {
    use deepfoids_env::config::MirrorRedraw;
    use deepfoids_sensors::FRAME_LEN;
    let mut s = scene("coho_default", 12);
    s.rewards.extensions.mirrored_share = 0.5;
    s.rewards.extensions.mirror_redraw = MirrorRedraw::Decision;
    let mut env = Env::new(s, 3);
    env.reset();
    let (mut flips, mut mirrored) = (0, 0);
    let newest = |g: &[f32], a: usize| g[(a * 3 + 2) * FRAME_LEN..(a * 3 + 3) * FRAME_LEN].to_vec();
    let middle = |g: &[f32], a: usize| g[(a * 3 + 1) * FRAME_LEN..(a * 3 + 2) * FRAME_LEN].to_vec();
    for _ in 0..20 {
        let before: Vec<bool> = (0..12).map(|i| env.is_mirrored(i)).collect();
        let grids = env.output().behaviours[0].grids.clone();
        env.step(&[vec![0.2; 36]]).unwrap();
        let after = &env.output().behaviours[0];
        for (a, &was_mirrored) in before.iter().enumerate() {
            if after.terminated[a] {
                continue;
            }
            let flipped = env.is_mirrored(a) != was_mirrored;
            let was = newest(&grids, a);
            let expected = if flipped { columns_reversed(&was) } else { was };
            assert_eq!(middle(&after.grids, a), expected, "fish {a}");
            flips += flipped as usize;
            mirrored += env.is_mirrored(a) as usize;
        }
    }
    assert!(
        (60..180).contains(&mirrored),
        "{mirrored} of 240 draws mirrored"
    );
    assert!(flips > 40, "{flips} changes of hand");
}
