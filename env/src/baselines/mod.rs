//! Rule-based schools: the baselines DeepFoids is compared with.
//!
//! [`Foids`] (Ishiwaka et al. 2021, §4) and [`Boids`] (Reynolds 1987, with the
//! boundary avoidance of the thesis' §4.5.5 and the obstacle avoidance of the
//! CS275 report §4.4) are [`Policy`](crate::Policy)s: they act in the same
//! environment, through the same decision interval and the same action limits
//! as a learned policy, so their schools compare fairly.
//!
//! # From a rule's desired velocity to an action ([`steer`])
//!
//! A rule set yields a desired velocity `v_d` (m/s, world frame) for the next
//! decision. With the fish's current speed `s`, heading `f`, roll and body
//! length:
//! * `Δv` (`a0`): `(clamp(|v_d|, v_min, v_max) − s) / Δv_max`, clipped to [−1, 1];
//! * the desired direction in the fish's local frame `(x, y, z) = Rᵀ·v̂_d`
//!   gives the pitch `−asin y` and yaw `atan2(x, z)` of the turn `R·R_y·R_x`
//!   the environment applies (`env::kinematics`), divided by `θ_max`:
//!   `a1 = −asin(y)/θ_max`, `a2 = atan2(x, z)/θ_max`, clipped to [−1, 1].
//!
//! The light and temperature responses (Foids Eqs. 6–7) are not part of the
//! rules' sum: the environment adds them to every fish (Eq. 4.4), whoever acts,
//! so Foids' Eq. 8 sum is complete without double counting.

pub mod boids;
pub mod foids;

pub use boids::{Boids, BoidsConfig};
pub use foids::{Foids, FoidsConfig};

use crate::kinematics::basis;
use deepfoids_sensors::{Obstacle, SpatialGrid};
use glam::Vec3;

/// The action `[a0, a1, a2]` that moves a fish towards the desired velocity
/// `v_desired` (m/s) within one decision (see the module docs).
#[allow(clippy::too_many_arguments)]
pub fn steer(
    heading: Vec3,
    roll: f32,
    speed: f32,
    bl: f32,
    v_desired: Vec3,
    speed_range_bl: [f32; 2],
    max_delta_speed_bl: f32,
    max_turn: f32,
) -> [f32; 3] {
    let target = v_desired
        .length()
        .clamp(speed_range_bl[0] * bl, speed_range_bl[1] * bl);
    let a0 = ((target - speed) / (max_delta_speed_bl * bl)).clamp(-1.0, 1.0);
    let dir = v_desired.try_normalize().unwrap_or(heading);
    let local = basis(heading, roll).transpose() * dir;
    let pitch = -local.y.clamp(-1.0, 1.0).asin();
    let yaw = local.x.atan2(local.z);
    [
        a0,
        (pitch / max_turn).clamp(-1.0, 1.0),
        (yaw / max_turn).clamp(-1.0, 1.0),
    ]
}

/// Deflection away from an obstacle ahead (CS275 report §4.4): treating the fish
/// (radius `r_fish`) and the obstacle as spheres, `P3` is the point of nearest
/// approach of the fish's path to the obstacle's centre `P2`, and `P3 − P2` is
/// the direction to steer. Returns the unit deflection scaled by
/// `(look − gap)/look` (0 beyond `look` m or when the path clears the obstacle).
pub fn obstacle_deflection(
    p: Vec3,
    heading: Vec3,
    r_fish: f32,
    obstacle: &Obstacle,
    look: f32,
) -> Vec3 {
    let (centre, radius) = match *obstacle {
        Obstacle::Sphere { center, radius } => (center, radius),
        // A vertical cylinder acts as the circle at the fish's height.
        Obstacle::Cylinder {
            x,
            z,
            radius,
            y_min,
            y_max,
        } => (Vec3::new(x, p.y.clamp(y_min, y_max), z), radius),
    };
    let gap = (centre - p).length() - r_fish - radius;
    if gap >= look {
        return Vec3::ZERO;
    }
    let t = (centre - p).dot(heading);
    if t <= 0.0 {
        return Vec3::ZERO; // behind
    }
    let p3 = p + heading * t;
    let off = p3 - centre;
    if off.length() >= radius + r_fish {
        return Vec3::ZERO; // the path clears it
    }
    let dir = off
        .try_normalize()
        .unwrap_or_else(|| heading.cross(Vec3::Y).try_normalize().unwrap_or(Vec3::X));
    dir * ((look - gap.max(0.0)) / look)
}

/// A neighbour grid over the cage for a policy's own queries.
pub(crate) fn neighbour_grid(env: &crate::Env, cell: f32) -> SpatialGrid {
    let (lo, hi) = env.cage().bounds;
    let mut g = SpatialGrid::new(lo, hi, cell.max(0.05), env.world().len());
    g.rebuild(&env.world().position, &[]);
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Straight ahead at the same speed: no action.
    #[test]
    fn steering_straight_on_is_zero() {
        let a = steer(
            Vec3::Z,
            0.0,
            0.5,
            0.5,
            Vec3::Z * 0.5,
            [0.2, 1.9],
            4.1,
            20f32.to_radians(),
        );
        assert!(a.iter().all(|x| x.abs() < 1e-6), "{a:?}");
    }

    /// A desired velocity 10° to the fish's left (+x for heading +z) and 10° up:
    /// yaw +10° → a2 = 0.5; pitch up 10° is −10° about local x → a1 = −0.5; speed
    /// from 0.5 to 0.9 m/s with BL 0.5 → 0.4/(4.1·0.5) = 0.195122.
    #[test]
    fn steering_turn_and_speed() {
        let (y, p) = (10f32.to_radians(), 10f32.to_radians());
        let d = Vec3::new(p.cos() * y.sin(), p.sin(), p.cos() * y.cos());
        let a = steer(
            Vec3::Z,
            0.0,
            0.5,
            0.5,
            d * 0.9,
            [0.2, 1.9],
            4.1,
            20f32.to_radians(),
        );
        assert!(
            (a[0] - 0.195_122).abs() < 1e-5
                && (a[1] + 0.5).abs() < 1e-4
                && (a[2] - 0.5).abs() < 1e-4,
            "{a:?}"
        );
        // The environment's turn with these actions gives back the desired direction.
        let (f, _) = crate::kinematics::turn(
            Vec3::Z,
            0.0,
            a[2] * 20f32.to_radians(),
            a[1] * 20f32.to_radians(),
            0.2,
        );
        assert!(f.dot(d) > 0.999_999, "{f} vs {d}");
    }

    /// Behind the fish: the turn saturates; speed is clamped to the range.
    #[test]
    fn steering_saturates() {
        let a = steer(
            Vec3::Z,
            0.0,
            0.1,
            0.5,
            -Vec3::Z * 9.0,
            [0.2, 1.9],
            4.1,
            20f32.to_radians(),
        );
        assert_eq!(a[2].abs(), 1.0);
        assert!((a[0] - (0.95 - 0.1) / 2.05).abs() < 1e-5);
    }

    #[test]
    fn obstacles_deflect_sideways() {
        let s = Obstacle::Sphere {
            center: Vec3::new(0.1, -2.0, 1.0),
            radius: 0.3,
        };
        let d = obstacle_deflection(Vec3::new(0.0, -2.0, 0.0), Vec3::Z, 0.1, &s, 1.0);
        // Nearest approach P3 = (0, −2, 1); P3 − P2 = (−0.1, 0, 0): steer to −x.
        assert!(d.x < 0.0 && d.y.abs() < 1e-6 && d.z.abs() < 1e-6, "{d}");
        assert_eq!(
            obstacle_deflection(Vec3::new(0.0, -2.0, 0.0), -Vec3::Z, 0.1, &s, 1.0),
            Vec3::ZERO
        );
    }
}
