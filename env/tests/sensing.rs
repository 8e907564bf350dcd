//! What a fish sees through the env (SPEC §5): coho (BL 0.49 m, d_sense 1.47 m,
//! visual radius 0.1225 m) and seabream in a 3 m cube.
mod common;
use common::*;
use deepfoids_sensors::{AZ_CELLS, CELLS, Channel, EL_CELLS, FRAME_LEN, STACKED_LEN};
use glam::Vec3;

/// Channel `ch` of cell (h, w) of the newest frame of agent `a`.
fn newest(env: &deepfoids_env::Env, a: usize, ch: Channel, h: usize, w: usize) -> f32 {
    let g = &env.output().behaviours[0].grids[a * STACKED_LEN..];
    g[2 * FRAME_LEN + ch as usize * CELLS + h * AZ_CELLS + w]
}

fn cells_with(env: &deepfoids_env::Env, a: usize, ch: Channel) -> Vec<(usize, usize)> {
    let mut v = vec![];
    for h in 0..EL_CELLS {
        for w in 0..AZ_CELLS {
            if newest(env, a, ch, h, w) > 0.5 {
                v.push((h, w));
            }
        }
    }
    v
}

/// A fish 1 m straight ahead: the four centre cells (angular radius
/// asin(0.1225/1) = 7.04° > 6.73° to their centres), proximity 1 − 1/1.47, type fish.
#[test]
fn a_fish_ahead_fills_the_centre_cells() {
    let mut env = calm_env(scene("coho_default", 2));
    place(&mut env, 0, Vec3::new(0.0, -2.3, -0.5), Vec3::Z, 0.2);
    place(&mut env, 1, Vec3::new(0.0, -2.3, 0.5), Vec3::X, 0.2);
    env.observe_now();
    assert_eq!(
        cells_with(&env, 0, Channel::Fish),
        vec![(9, 16), (9, 17), (10, 16), (10, 17)]
    );
    for (h, w) in [(9, 16), (9, 17), (10, 16), (10, 17)] {
        assert!(close(
            newest(&env, 0, Channel::Proximity, h, w),
            1.0 - 1.0 / 1.47,
            1e-5
        ));
    }
    // u = own forward (0,0,1) minus the neighbour's forward in the local frame: +x world is the
    // fish's left (+x local) → u = (−1, 0, 1).
    let v = &env.output().behaviours[0].vectors[..6];
    assert!(
        close(v[0], -1.0, 1e-5) && close(v[1], 0.0, 1e-5) && close(v[2], 1.0, 1e-5),
        "{v:?}"
    );
    assert!(close(v[3], 2.3 / 4.6, 1e-5), "depth / cage height");
}

/// At 0.45 m the same fish spans asin(0.1225/0.45) = 15.8° and covers more
/// cells: the 4 centre ones (6.7°), 4 at (±5°, ±13.5°) (14.4°) and 4 at (±15°, ±4.5°) (15.6°).
#[test]
fn a_nearer_fish_covers_more_cells() {
    let mut env = calm_env(scene("coho_default", 2));
    place(&mut env, 0, Vec3::new(0.0, -2.3, -0.5), Vec3::Z, 0.2);
    place(&mut env, 1, Vec3::new(0.0, -2.3, -0.05), Vec3::X, 0.2);
    env.observe_now();
    assert_eq!(cells_with(&env, 0, Channel::Fish).len(), 12);
}

/// A net wall 0.5 m to the fish's left shows as net on the left half only.
#[test]
fn a_wall_to_the_left_shows_as_net_on_the_left() {
    let mut env = calm_env(scene("seabream_default", 1));
    // Heading +z; the fish's left is +x; the wall x = 1.5 is 0.5 m away.
    place(&mut env, 0, Vec3::new(1.0, -1.5, 0.0), Vec3::Z, 0.2);
    env.observe_now();
    let net = cells_with(&env, 0, Channel::Net);
    assert!(!net.is_empty());
    assert!(net.iter().all(|&(_, w)| w < 17), "{net:?}");
    assert!(net.contains(&(9, 8)), "straight left at the horizon");
    assert!(cells_with(&env, 0, Channel::Surface).is_empty());
}

/// The surface 0.3 m above shows as surface in the upper rows.
#[test]
fn the_surface_above_shows_as_surface() {
    let mut env = calm_env(scene("seabream_default", 1));
    place(&mut env, 0, Vec3::new(0.0, -0.3, 0.0), Vec3::Z, 0.2);
    env.observe_now();
    let surface = cells_with(&env, 0, Channel::Surface);
    assert!(surface.iter().any(|&(h, _)| h == 0));
    assert!(surface.iter().all(|&(h, _)| h < 10), "{surface:?}");
    // Straight up (row 0, el 85.5°): t = 0.3 / sin 85.5°.
    let t = 0.3 / 85.5f32.to_radians().sin();
    assert!(close(
        newest(&env, 0, Channel::Proximity, 0, 16),
        1.0 - t / 1.02,
        1e-5
    ));
}

/// A fish straight behind is in the blind sector: nothing is seen.
#[test]
fn the_blind_sector_behind_stays_empty() {
    let mut env = calm_env(scene("seabream_default", 2));
    place(&mut env, 0, Vec3::new(0.0, -1.5, 0.3), Vec3::Z, 0.2);
    place(&mut env, 1, Vec3::new(0.0, -1.5, -0.3), Vec3::Z, 0.2);
    env.observe_now();
    let g = &env.output().behaviours[0].grids[..STACKED_LEN];
    assert!(g[2 * FRAME_LEN..].iter().all(|&x| x == 0.0));
}

/// Frames stack oldest first: after a step the old newest frame is the middle one.
#[test]
fn frames_stack_oldest_first() {
    let mut env = calm_env(scene("seabream_default", 2));
    place(&mut env, 0, Vec3::new(0.0, -1.5, -0.5), Vec3::Z, 0.2);
    place(&mut env, 1, Vec3::new(0.0, -1.5, 0.2), Vec3::X, 0.2);
    env.observe_now();
    let before = env.output().behaviours[0].grids[2 * FRAME_LEN..STACKED_LEN].to_vec();
    assert!(before.iter().any(|&x| x != 0.0));
    env.step(&zeros(&env)).unwrap();
    let g = &env.output().behaviours[0].grids[..STACKED_LEN];
    assert_eq!(&g[FRAME_LEN..2 * FRAME_LEN], &before[..]);
    assert!(
        g[..FRAME_LEN].iter().all(|&x| x == 0.0),
        "the oldest frame was the reset's zeros"
    );
}

/// The chase partner is seen as such, and the role is in the vector observation.
#[test]
fn the_chase_partner_has_its_own_channel() {
    let mut env = calm_env(scene("coho_default", 2));
    place(&mut env, 0, Vec3::new(0.0, -2.3, -0.5), Vec3::Z, 0.2);
    place(&mut env, 1, Vec3::new(0.0, -2.3, 0.5), Vec3::X, 0.2);
    let w = env.world_mut();
    w.dominant[0] = true;
    w.chase[0] = deepfoids_env::Chase::Aggressor {
        target: 1,
        since: 0.0,
    };
    w.chase[1] = deepfoids_env::Chase::Target { aggressor: 0 };
    env.observe_now();
    assert_eq!(cells_with(&env, 0, Channel::ChasePartner).len(), 4);
    assert!(cells_with(&env, 0, Channel::Fish).is_empty());
    let v = &env.output().behaviours[0].vectors;
    assert_eq!((v[4], v[5]), (1.0, 0.0));
    assert_eq!((v[10], v[11]), (0.0, 1.0));
}

/// `u` of the nearest fish in front (SPEC §5) or, with `heading_of =
/// "closing"`, of the one coming closest within 1 s. Coho of 0.49 m. Fish 0
/// heads +z at 0.5 BL/s (0.245 m/s); fish 1 swims 0.5 m ahead on its path,
/// parallel and as fast (closest approach 0.5 m); fish 2, 1.17 m off to the
/// left front at (1, 0, 0.6), crosses towards its path at 2 BL/s (0.98 m/s):
/// relative velocity (−0.98, 0, −0.245), t* = 1.127/1.0204 s → the horizon,
/// 1 s, offset then (0.02, 0, 0.355): 0.356 m. Front: fish 1, u = 0.
/// Closing: fish 2, heading −x world = −x local (the fish's right), u =
/// (0, 0, 1) − (−1, 0, 0) = (1, 0, 1).
#[test]
fn u_of_the_closing_neighbour() {
    use deepfoids_env::config::HeadingOf;
    for (of, want) in [
        (HeadingOf::Front, [0.0, 0.0, 0.0]),
        (HeadingOf::Closing, [1.0, 0.0, 1.0]),
    ] {
        let mut s = scene("coho_default", 3);
        s.rewards.extensions.heading_of = of;
        let mut env = calm_env(s);
        let c = Vec3::new(0.0, -2.3, -0.5);
        place(&mut env, 0, c, Vec3::Z, 0.5);
        place(&mut env, 1, c + Vec3::new(0.0, 0.0, 0.5), Vec3::Z, 0.5);
        place(&mut env, 2, c + Vec3::new(1.0, 0.0, 0.6), -Vec3::X, 2.0);
        env.observe_now();
        let v = &env.output().behaviours[0].vectors[..3];
        assert!(
            (0..3).all(|k| close(v[k], want[k], 1e-5)),
            "{of:?}: u = {v:?}, want {want:?}"
        );
    }
}

/// `heading_of = "rewarded"`: `u` of the mean heading of the neighbours
/// `r_ND` is paid for. Coho of 0.49 m, personal space 0.66 BL = 0.3234 m.
/// Fish 0 heads +z; fish 1, 0.2 m ahead heading +x, is inside the personal
/// space (the nearest in front: `"front"` gives u = (−1, 0, 1)); fish 2 and 3,
/// 1 m to either side, head +z and −x; fish 4, 1.2 m behind, heads −z. With
/// `neighbour_cap` 2 the rewarded ones are fish 2 and 3, mean heading
/// (−1, 0, 1)/√2 → u = (1/√2, 0, 1 − 1/√2); uncapped, fish 4 too, the sum
/// (−1, 0, 0) → u = (1, 0, 1).
#[test]
fn u_of_the_rewarded_neighbours() {
    use deepfoids_env::config::HeadingOf;
    let h = std::f32::consts::FRAC_1_SQRT_2;
    for (of, cap, want) in [
        (HeadingOf::Front, 2, [-1.0, 0.0, 1.0]),
        (HeadingOf::Rewarded, 2, [h, 0.0, 1.0 - h]),
        (HeadingOf::Rewarded, 0, [1.0, 0.0, 1.0]),
    ] {
        let mut s = scene("coho_default", 5);
        s.rewards.extensions.heading_of = of;
        s.rewards.extensions.personal_space_bl = 0.66;
        s.rewards.neighbour_cap = cap;
        let mut env = calm_env(s);
        let c = Vec3::new(0.0, -2.3, 0.0);
        place(&mut env, 0, c, Vec3::Z, 0.5);
        place(&mut env, 1, c + Vec3::new(0.0, 0.0, 0.2), Vec3::X, 0.5);
        place(&mut env, 2, c + Vec3::new(1.0, 0.0, 0.0), Vec3::Z, 0.5);
        place(&mut env, 3, c + Vec3::new(-1.0, 0.0, 0.0), -Vec3::X, 0.5);
        place(&mut env, 4, c + Vec3::new(0.0, 0.0, -1.2), -Vec3::Z, 0.5);
        env.observe_now();
        let v = &env.output().behaviours[0].vectors[..3];
        assert!(
            (0..3).all(|k| close(v[k], want[k], 1e-5)),
            "{of:?} cap {cap}: u = {v:?}, want {want:?}"
        );
    }
}
