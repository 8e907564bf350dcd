//! Orientation and the action → velocity mapping (SPEC §4, Eq. 4.4).
//!
//! A fish's orientation is its unit heading `f` (it faces its velocity) and a
//! roll angle `ρ` about `f`, clamped to ±`θzt`. Its local frame is right-handed
//! with +z forward, +y up and +x to the fish's **left**:
//! the reference left `l0 = normalize(Y × f)` and up `u0 = f × l0` are rolled by
//! `ρ`: `l = cos ρ·l0 + sin ρ·u0`, `u = −sin ρ·l0 + cos ρ·u0`.
//!
//! Actions `(a0, a1, a2) ∈ [−1, 1]³` (clipped): the speed changes by
//! `a0·Δv_max` over one decision; the heading is rotated in the local frame by
//! `Δθy = a2·θ_max` about local y (positive towards local +x, the fish's left)
//! and `Δθx = a1·θ_max` about local x (positive pitches the nose down). The
//! desired velocity minus the current one is `Δv_f`, spread evenly over the k
//! physics steps of the decision.

use glam::{Mat3, Vec3};

/// The reference left vector for heading `f`: horizontal, perpendicular to `f`.
/// For a vertical heading (undefined) the world +x is used.
#[inline]
fn reference_left(f: Vec3) -> Vec3 {
    let l = Vec3::Y.cross(f);
    let n = l.length();
    if n > 1e-6 { l / n } else { Vec3::X }
}

/// Local-to-world rotation (columns: left, up, forward) for heading `f` and roll `roll` (rad).
#[inline]
pub fn basis(f: Vec3, roll: f32) -> Mat3 {
    let l0 = reference_left(f);
    let u0 = f.cross(l0);
    let (s, c) = roll.sin_cos();
    Mat3::from_cols(c * l0 + s * u0, -s * l0 + c * u0, f)
}

/// Roll (rad) of a frame with heading `f` and up vector `u`.
#[inline]
pub fn roll_of(f: Vec3, u: Vec3) -> f32 {
    let l0 = reference_left(f);
    let u0 = f.cross(l0);
    (-u.dot(l0)).atan2(u.dot(u0))
}

/// Pitch of a heading above the horizontal (degrees, nose up positive).
#[inline]
pub fn pitch_deg(f: Vec3) -> f32 {
    f.y.clamp(-1.0, 1.0).asin().to_degrees()
}

/// Angle between two unit vectors (degrees).
#[inline]
pub fn angle_deg(a: Vec3, b: Vec3) -> f32 {
    // atan2 of |a×b| and a·b is accurate for small and large angles alike.
    a.cross(b).length().atan2(a.dot(b)).to_degrees()
}

/// `acos(x)` in degrees by Abramowitz & Stegun 4.4.45 (error ≤ 6.8e−5 rad =
/// 0.004°): cheap enough to run on every neighbour of every fish.
#[inline]
pub fn fast_acos_deg(x: f32) -> f32 {
    let x = x.clamp(-1.0, 1.0);
    let a = x.abs();
    let r = (1.0 - a).sqrt()
        * (1.570_728_8 + a * (-0.212_114_4 + a * (0.074_261_0 + a * -0.018_729_3)));
    let r = if x < 0.0 { std::f32::consts::PI - r } else { r };
    r.to_degrees()
}

/// The heading and roll after turning by `yaw` about local y and `pitch` about
/// local x (radians; `R_d = R · R_y(yaw) · R_x(pitch)`), roll clamped to `±roll_max`.
pub fn turn(f: Vec3, roll: f32, yaw: f32, pitch: f32, roll_max: f32) -> (Vec3, f32) {
    let r = basis(f, roll);
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    // R_y(yaw)·R_x(pitch) applied to local z and local y.
    let fwd_local = Vec3::new(cp * sy, -sp, cp * cy);
    let up_local = Vec3::new(sp * sy, cp, sp * cy);
    let f_new = (r * fwd_local).normalize();
    let u_new = r * up_local;
    let roll_new = roll_of(f_new, u_new).clamp(-roll_max, roll_max);
    (f_new, roll_new)
}

/// What a decision asks of a fish.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decision {
    /// The desired velocity at the end of the decision (m/s).
    pub target: Vec3,
    /// Velocity change to add at each of the k physics steps (m/s), `Δv_f / k`.
    pub dv_step: Vec3,
    /// Roll after the turn (rad).
    pub roll: f32,
}

/// Turns an action into the per-step velocity change of Eq. 4.4.
///
/// * `action`: `[a0, a1, a2]`, clipped to [−1, 1];
/// * `heading`, `roll`, `speed` (m/s): the current state;
/// * `bl` (m), `max_delta_speed_bl` (BL/s), `max_turn` and `roll_max` (rad);
/// * `speed_range_bl`: the speed clamp `[min, max]` (BL/s) — the species'
///   schooling range (SPEC §4, Table 4.3), whose lower bound is a floor;
/// * `k`: physics steps per decision.
#[allow(clippy::too_many_arguments)]
pub fn decide(
    action: [f32; 3],
    heading: Vec3,
    roll: f32,
    speed: f32,
    bl: f32,
    max_delta_speed_bl: f32,
    speed_range_bl: [f32; 2],
    max_turn: f32,
    roll_max: f32,
    k: usize,
) -> Decision {
    let [a0, a1, a2] = action.map(|a| a.clamp(-1.0, 1.0));
    let target_speed = (speed + a0 * max_delta_speed_bl * bl)
        .clamp(speed_range_bl[0] * bl, speed_range_bl[1] * bl);
    let (f_new, roll_new) = turn(heading, roll, a2 * max_turn, a1 * max_turn, roll_max);
    let target = target_speed * f_new;
    Decision {
        target,
        dv_step: (target - speed * heading) / k as f32,
        roll: roll_new,
    }
}

/// One physics step of Eq. 4.4: `v += Δv_f/k + (Δv_light + Δv_temp)·BL/k`, the
/// speed clamped to `speed_range = [min, max]` (m/s); the fish then faces its
/// velocity (the heading is kept if the velocity vanishes). Returns `(heading, speed)`.
#[inline]
pub fn integrate_velocity(
    heading: Vec3,
    speed: f32,
    dv_step: Vec3,
    vertical_step: f32,
    speed_range: [f32; 2],
) -> (Vec3, f32) {
    let v = speed * heading + dv_step + Vec3::new(0.0, vertical_step, 0.0);
    let s = v.length();
    // Below a micrometre per second (a model whose range reaches 0 braking to a
    // halt) the direction is rounding noise: keep the heading.
    let f = if s > 1e-6 { v / s } else { heading };
    (f, s.clamp(speed_range[0], speed_range[1]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::FRAC_PI_2;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn basis_is_right_handed_with_left_x() {
        let r = basis(Vec3::Z, 0.0);
        assert!(close(r.x_axis, Vec3::X) && close(r.y_axis, Vec3::Y) && close(r.z_axis, Vec3::Z));
        // Heading +x: left is Y × X = −Z.
        let r = basis(Vec3::X, 0.0);
        assert!(close(r.x_axis, -Vec3::Z));
        assert!(close(r.x_axis.cross(r.y_axis), r.z_axis));
        assert!((roll_of(Vec3::X, basis(Vec3::X, 0.1).y_axis) - 0.1).abs() < 1e-6);
    }

    /// Yaw +90° about local y from heading +z turns to +x (the left); pitch +20°
    /// about local x tilts the nose down by 20°.
    #[test]
    fn turn_directions() {
        let (f, roll) = turn(Vec3::Z, 0.0, FRAC_PI_2, 0.0, 0.2);
        assert!(close(f, Vec3::X), "{f}");
        assert!(roll.abs() < 1e-6);
        let (f, _) = turn(Vec3::Z, 0.0, 0.0, 20f32.to_radians(), 0.2);
        assert!((pitch_deg(f) + 20.0).abs() < 1e-4);
    }

    /// A pitched fish that yaws picks up roll, which is clamped.
    #[test]
    fn roll_is_clamped() {
        let (f, roll) = turn(Vec3::Z, 0.0, 0.0, (-60f32).to_radians(), 0.17);
        let (_, roll) = turn(f, roll, 80f32.to_radians(), 0.0, 0.17);
        assert!(roll.abs() <= 0.17 + 1e-6);
    }

    /// [`decide`] for a fish of BL 0.5 m heading +z without roll: Δv_max
    /// 4.1 BL/s, speeds 0.2–1.9 BL/s, turns up to 0.35 rad, roll up to 0.17 rad.
    fn half_metre_fish(action: [f32; 3], speed: f32, k: usize) -> Decision {
        decide(
            action,
            Vec3::Z,
            0.0,
            speed,
            0.5,
            4.1,
            [0.2, 1.9],
            0.35,
            0.17,
            k,
        )
    }

    /// Hand-computed: speed 0.1 m/s heading +z, BL 0.5, a0 = 0.5 with Δv_max 4.1 BL/s
    /// → target 0.1 + 1.025 = 1.125 m/s, clamped to 1.9 BL/s × 0.5 = 0.95 m/s; no turn.
    /// Δv_f = (0.95 − 0.1)·z = 0.85 z, over k = 10 steps: 0.085 z per step.
    #[test]
    fn speed_action_is_clamped_and_spread_over_k_steps() {
        let d = half_metre_fish([0.5, 0.0, 0.0], 0.1, 10);
        assert!(
            close(d.dv_step, Vec3::new(0.0, 0.0, 0.085)),
            "{}",
            d.dv_step
        );
        // Clipping: a0 = −7 acts as −1; from 0.5 m/s the target 0.5 − 2.05 < 0 is
        // raised to the floor 0.2 BL/s × 0.5 = 0.1 m/s: Δv_f = −0.4 z, over 5 steps −0.08 z.
        let d = half_metre_fish([-7.0, 0.0, 0.0], 0.5, 5);
        assert!(
            close(d.dv_step, Vec3::new(0.0, 0.0, -0.08)),
            "{}",
            d.dv_step
        );
    }

    /// Regression (issue 11, "a policy can park its fish"): the speed never falls
    /// below the floor. A fish at the floor 0.1 m/s (0.2 BL/s, BL 0.5) braking
    /// by 0.05 m/s per step stays at 0.1 m/s heading on; one whose velocity is
    /// cancelled exactly keeps its heading at 0.1 m/s; the maximum still clamps.
    #[test]
    fn speed_floor_holds_at_every_step() {
        let range = [0.1, 0.95];
        let (f, s) = integrate_velocity(Vec3::Z, 0.1, -0.05 * Vec3::Z, 0.0, range);
        assert!(close(f, Vec3::Z) && (s - 0.1).abs() < 1e-7, "{f} {s}");
        let (f, s) = integrate_velocity(Vec3::X, 0.1, -0.1 * Vec3::X, 0.0, range);
        assert!(close(f, Vec3::X) && (s - 0.1).abs() < 1e-7, "{f} {s}");
        let (_, s) = integrate_velocity(Vec3::Z, 0.9, 0.2 * Vec3::Z, 0.0, range);
        assert!((s - 0.95).abs() < 1e-7, "{s}");
        // At the floor, a full brake asks for nothing: the target is the floor itself.
        let d = half_metre_fish([-1.0, 0.0, 0.0], 0.1, 10);
        assert!(close(d.dv_step, Vec3::ZERO), "{}", d.dv_step);
    }

    /// After the k steps the velocity reaches the decision's target (no vertical push).
    #[test]
    fn k_steps_reach_the_target_velocity() {
        let (mut f, mut s) = (Vec3::Z, 0.2);
        let d = decide(
            [0.2, 0.0, 1.0],
            f,
            0.0,
            s,
            0.34,
            4.1,
            [0.2, 2.7],
            20f32.to_radians(),
            0.17,
            5,
        );
        for _ in 0..5 {
            (f, s) = integrate_velocity(f, s, d.dv_step, 0.0, [0.2 * 0.34, 2.7 * 0.34]);
        }
        assert!((s - (0.2 + 0.2 * 4.1 * 0.34)).abs() < 1e-5, "{s}");
        assert!((angle_deg(Vec3::Z, f) - 20.0).abs() < 1e-3);
    }

    #[test]
    fn fast_acos_is_close() {
        for k in 0..=2000 {
            let x = -1.0 + k as f32 / 1000.0;
            assert!(
                (fast_acos_deg(x) - x.acos().to_degrees()).abs() < 0.005,
                "{x}"
            );
        }
    }

    #[test]
    fn angles() {
        assert!((angle_deg(Vec3::Z, Vec3::X) - 90.0).abs() < 1e-5);
        assert!((angle_deg(Vec3::Z, -Vec3::Z) - 180.0).abs() < 1e-5);
        assert!(angle_deg(Vec3::Z, Vec3::Z).abs() < 1e-5);
        assert!((pitch_deg(Vec3::new(0.0, 1.0, 1.0).normalize()) - 45.0).abs() < 1e-4);
    }
}
