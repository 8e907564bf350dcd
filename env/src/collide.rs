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

/// Separating-axis test of two boxes. On overlap returns the unit axis of
/// least penetration, pointing from `a` to `b`, and the penetration depth (m).
pub fn overlap(a: &Obb, b: &Obb) -> Option<(Vec3, f32)> {
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
