//! Box colliders (SPEC §6): fish against fish, against the cage planes and
//! against obstacles.

use deepfoids_sensors::{Obstacle, Plane};
use glam::{Mat3, Vec3};

/// An oriented box: centre, local axes (columns of `axes`) and half extents.
#[derive(Clone, Copy, Debug)]
pub struct Obb {
    pub center: Vec3,
    pub axes: Mat3,
    pub half: Vec3,
}

impl Obb {
    /// Radius of the bounding sphere.
    #[inline]
    pub fn radius(&self) -> f32 {
        self.half.length()
    }

    /// Half the box's extent along unit direction `n`.
    #[inline]
    pub fn extent_along(&self, n: Vec3) -> f32 {
        self.half.x * self.axes.x_axis.dot(n).abs()
            + self.half.y * self.axes.y_axis.dot(n).abs()
            + self.half.z * self.axes.z_axis.dot(n).abs()
    }

    /// Signed clearance of the whole box from a plane: the smallest signed
    /// distance of any of its points. Negative: the box crossed the plane.
    #[inline]
    pub fn clearance(&self, plane: &Plane) -> f32 {
        plane.distance(self.center) - self.extent_along(plane.normal)
    }

    /// The 8 corners, the 6 face centres and the centre.
    pub fn sample_points(&self) -> [Vec3; 15] {
        let (x, y, z) = (
            self.axes.x_axis * self.half.x,
            self.axes.y_axis * self.half.y,
            self.axes.z_axis * self.half.z,
        );
        let c = self.center;
        [
            c,
            c + x,
            c - x,
            c + y,
            c - y,
            c + z,
            c - z,
            c + x + y + z,
            c + x + y - z,
            c + x - y + z,
            c + x - y - z,
            c - x + y + z,
            c - x + y - z,
            c - x - y + z,
            c - x - y - z,
        ]
    }

    /// Whether the box overlaps a solid obstacle: exact for spheres (closest
    /// point of the box to the centre); for cylinders, whether any of the
    /// 15 sample points lies inside (exact for the corner-first contacts of a
    /// thin fish body, conservative otherwise).
    pub fn overlaps_obstacle(&self, obstacle: &Obstacle) -> bool {
        match *obstacle {
            Obstacle::Sphere { center, radius } => {
                let d = center - self.center;
                let local = Vec3::new(
                    self.axes.x_axis.dot(d),
                    self.axes.y_axis.dot(d),
                    self.axes.z_axis.dot(d),
                );
                let closest = local.clamp(-self.half, self.half);
                (local - closest).length_squared() < radius * radius
            }
            Obstacle::Cylinder { .. } => self.sample_points().iter().any(|&p| obstacle.contains(p)),
        }
    }
}

/// Separating-axis test of two boxes, in the frame of `a` with the rotation
/// `R = Aᵀ·B` shared by all 15 axes (the classic OBB formulation). On overlap
/// returns the unit axis of least penetration, pointing from `a` to `b`, and the
/// penetration depth (m).
pub fn overlap(a: &Obb, b: &Obb) -> Option<(Vec3, f32)> {
    let (ea, eb) = (a.half.to_array(), b.half.to_array());
    let (ax, bx) = (
        [a.axes.x_axis, a.axes.y_axis, a.axes.z_axis],
        [b.axes.x_axis, b.axes.y_axis, b.axes.z_axis],
    );
    let mut r = [[0f32; 3]; 3];
    let mut abs_r = [[0f32; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = ax[i].dot(bx[j]);
            // The epsilon keeps near-parallel edge pairs from producing false separations.
            abs_r[i][j] = r[i][j].abs() + 1e-6;
        }
    }
    let d = b.center - a.center;
    let t = [d.dot(ax[0]), d.dot(ax[1]), d.dot(ax[2])];
    let mut best = (f32::INFINITY, Vec3::ZERO);
    // Candidate axis `n` (unit, world) with projected gap `dist` (signed) and radii sum.
    let mut consider = |depth: f32, dist: f32, n: Vec3| {
        if depth < best.0 {
            best = (depth, if dist >= 0.0 { n } else { -n });
        }
    };
    // A's faces.
    for i in 0..3 {
        let rb = eb[0] * abs_r[i][0] + eb[1] * abs_r[i][1] + eb[2] * abs_r[i][2];
        let depth = ea[i] + rb - t[i].abs();
        if depth <= 0.0 {
            return None;
        }
        consider(depth, t[i], ax[i]);
    }
    // B's faces.
    for j in 0..3 {
        let ra = ea[0] * abs_r[0][j] + ea[1] * abs_r[1][j] + ea[2] * abs_r[2][j];
        let dist = t[0] * r[0][j] + t[1] * r[1][j] + t[2] * r[2][j];
        let depth = ra + eb[j] - dist.abs();
        if depth <= 0.0 {
            return None;
        }
        consider(depth, dist, bx[j]);
    }
    // Edge pairs A_i × B_j; |A_i × B_j| = √(1 − R_ij²) normalises the depth.
    for i in 0..3 {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        for j in 0..3 {
            let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
            let ra = ea[i1] * abs_r[i2][j] + ea[i2] * abs_r[i1][j];
            let rb = eb[j1] * abs_r[i][j2] + eb[j2] * abs_r[i][j1];
            let dist = t[i2] * r[i1][j] - t[i1] * r[i2][j];
            let gap = ra + rb - dist.abs();
            if gap <= 0.0 {
                return None;
            }
            let len = (1.0 - r[i][j] * r[i][j]).max(0.0).sqrt();
            if len > 1e-3 {
                consider(gap / len, dist, ax[i].cross(bx[j]) / len);
            }
        }
    }
    Some((best.1, best.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fish(center: Vec3, heading: Vec3) -> Obb {
        Obb {
            center,
            axes: crate::kinematics::basis(heading, 0.0),
            half: Vec3::new(0.05, 0.1, 0.25),
        }
    }

    /// Two fish side by side, 0.08 m apart (widths 0.1 each): overlap 0.02 along x.
    #[test]
    fn side_by_side_overlap_depth() {
        let a = fish(Vec3::ZERO, Vec3::Z);
        let b = fish(Vec3::new(0.08, 0.0, 0.0), Vec3::Z);
        let (axis, depth) = overlap(&a, &b).unwrap();
        assert!((depth - 0.02).abs() < 1e-6, "{depth}");
        assert!((axis - Vec3::X).length() < 1e-6);
        assert!(overlap(&a, &fish(Vec3::new(0.11, 0.0, 0.0), Vec3::Z)).is_none());
    }

    /// Nose to tail 0.45 m apart (lengths 0.5): overlap 0.05 along z.
    #[test]
    fn nose_to_tail() {
        let a = fish(Vec3::ZERO, Vec3::Z);
        let b = fish(Vec3::new(0.0, 0.0, -0.45), Vec3::Z);
        let (axis, depth) = overlap(&a, &b).unwrap();
        assert!((depth - 0.05).abs() < 1e-6);
        assert!((axis + Vec3::Z).length() < 1e-6);
    }

    /// A crossing fish (T-shape) 0.2 m ahead: b's half-width 0.05 along z meets a's nose
    /// at 0.25 → overlap 0.25 + 0.05 − 0.2 = 0.1.
    #[test]
    fn crossing_fish() {
        let a = fish(Vec3::ZERO, Vec3::Z);
        let b = fish(Vec3::new(0.0, 0.0, 0.2), Vec3::X);
        let (_, depth) = overlap(&a, &b).unwrap();
        assert!((depth - 0.1).abs() < 1e-6, "{depth}");
        // Diagonal boxes whose bounding spheres overlap but which don't touch.
        let c = fish(
            Vec3::new(0.3, 0.0, 0.3),
            Vec3::new(1.0, 0.0, -1.0).normalize(),
        );
        assert!(overlap(&a, &c).is_none());
    }

    /// The straightforward SAT (every axis projected afresh): the reference. On overlap returns the unit axis of
    /// least penetration, pointing from `a` to `b`, and the penetration depth (m).
    fn reference_overlap(a: &Obb, b: &Obb) -> Option<(Vec3, f32)> {
        let t = b.center - a.center;
        let mut best_depth = f32::INFINITY;
        let mut best_axis = Vec3::ZERO;
        let mut test = |axis: Vec3| -> bool {
            let len2 = axis.length_squared();
            if len2 < 1e-10 {
                return true; // parallel edges: the face axes cover this case
            }
            let n = axis / len2.sqrt();
            let dist = t.dot(n);
            let depth = a.extent_along(n) + b.extent_along(n) - dist.abs();
            if depth <= 0.0 {
                return false;
            }
            if depth < best_depth {
                best_depth = depth;
                best_axis = if dist >= 0.0 { n } else { -n };
            }
            true
        };
        let (ax, bx) = (
            [a.axes.x_axis, a.axes.y_axis, a.axes.z_axis],
            [b.axes.x_axis, b.axes.y_axis, b.axes.z_axis],
        );
        for u in ax {
            if !test(u) {
                return None;
            }
        }
        for v in bx {
            if !test(v) {
                return None;
            }
        }
        for u in ax {
            for v in bx {
                if !test(u.cross(v)) {
                    return None;
                }
            }
        }
        Some((best_axis, best_depth))
    }

    /// The fast SAT agrees with the straightforward one on random pairs.
    #[test]
    fn fast_sat_matches_the_reference() {
        let mut seed = 7u64;
        let mut u = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 40) as f32) / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        let mut hits = 0;
        for _ in 0..20_000 {
            let a = fish(
                Vec3::new(u(), u(), u()) * 0.2,
                Vec3::new(u(), u(), u()).normalize(),
            );
            let b = fish(
                Vec3::new(u(), u(), u()) * 0.4,
                Vec3::new(u(), u(), u()).normalize(),
            );
            match (overlap(&a, &b), reference_overlap(&a, &b)) {
                (None, None) => {}
                (Some((n1, d1)), Some((n2, d2))) => {
                    hits += 1;
                    assert!((d1 - d2).abs() < 1e-4, "depth {d1} vs {d2}");
                    assert!(
                        n1.dot(n2) > 0.999 || (d1 - d2).abs() < 1e-4,
                        "axis {n1} vs {n2}"
                    );
                }
                (x, y) => assert!(
                    x.map_or(0.0, |v| v.1) < 1e-4 && y.map_or(0.0, |v| v.1) < 1e-4,
                    "disagree beyond grazing contact: {x:?} vs {y:?}"
                ),
            }
        }
        assert!(hits > 2000, "{hits}");
    }

    #[test]
    fn clearance_from_a_plane() {
        let floor = Plane::through(Vec3::new(0.0, -3.0, 0.0), Vec3::Y);
        let level = fish(Vec3::new(0.0, -2.8, 0.0), Vec3::Z);
        assert!((level.clearance(&floor) - 0.1).abs() < 1e-6);
        let diving = fish(Vec3::new(0.0, -2.8, 0.0), -Vec3::Y);
        assert!((diving.clearance(&floor) + 0.05).abs() < 1e-6);
    }

    #[test]
    fn obstacle_overlap() {
        let s = Obstacle::Sphere {
            center: Vec3::new(0.0, 0.0, 0.5),
            radius: 0.3,
        };
        assert!(fish(Vec3::ZERO, Vec3::Z).overlaps_obstacle(&s));
        assert!(!fish(Vec3::new(0.0, 0.0, -0.1), Vec3::Z).overlaps_obstacle(&s));
        let cyl = Obstacle::Cylinder {
            x: 0.0,
            z: 0.4,
            radius: 0.2,
            y_min: -1.0,
            y_max: 1.0,
        };
        assert!(fish(Vec3::ZERO, Vec3::Z).overlaps_obstacle(&cyl));
        assert!(!fish(Vec3::ZERO, Vec3::X).overlaps_obstacle(&cyl));
    }
}
