//! Planes and obstacles: what a fish can bump into and what its rays can hit.
//!
//! Every cage boundary is a plane with an inward unit normal (SPEC §1), so the
//! distance to it and a ray's hit on it are closed-form. Obstacles are solid
//! spheres and vertical cylinders.

use glam::Vec3;

/// A plane `n·p = offset` with a unit normal `n` pointing into the cage.
///
/// `distance(p) = n·p − offset` is positive inside the cage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal pointing into the cage.
    pub normal: Vec3,
    /// Plane offset along the normal, metres.
    pub offset: f32,
}

impl Plane {
    /// The plane through `point` with inward normal `normal` (normalised here).
    pub fn through(point: Vec3, normal: Vec3) -> Self {
        let normal = normal.normalize();
        Self {
            normal,
            offset: normal.dot(point),
        }
    }

    /// Signed distance of `p` from the plane, positive on the inner side (m).
    #[inline]
    pub fn distance(&self, p: Vec3) -> f32 {
        self.normal.dot(p) - self.offset
    }
}

/// What a boundary plane is made of; the sensor reports the two differently.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoundaryKind {
    /// A net wall or the net bottom.
    Net,
    /// The water surface.
    Surface,
}

/// One face of the cage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Boundary {
    pub plane: Plane,
    pub kind: BoundaryKind,
}

/// A solid obstacle inside the cage (SPEC §1: optional spheres and vertical cylinders).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Obstacle {
    Sphere {
        /// Centre, metres.
        center: Vec3,
        /// Radius, metres.
        radius: f32,
    },
    /// A cylinder with a vertical (y) axis through `(x, z)`, spanning `y_min..y_max`.
    Cylinder {
        x: f32,
        z: f32,
        radius: f32,
        y_min: f32,
        y_max: f32,
    },
}

impl Obstacle {
    /// Distance from `p` to the obstacle's surface (m); negative inside.
    pub fn distance(&self, p: Vec3) -> f32 {
        match *self {
            Obstacle::Sphere { center, radius } => (p - center).length() - radius,
            Obstacle::Cylinder {
                x,
                z,
                radius,
                y_min,
                y_max,
            } => {
                // Signed distance to a capped cylinder: radial and axial excess.
                let radial = (p.x - x).hypot(p.z - z) - radius;
                let axial = (y_min - p.y).max(p.y - y_max);
                if radial <= 0.0 && axial <= 0.0 {
                    radial.max(axial)
                } else {
                    radial.max(0.0).hypot(axial.max(0.0))
                }
            }
        }
    }

    /// Whether `p` lies inside the solid.
    #[inline]
    pub fn contains(&self, p: Vec3) -> bool {
        self.distance(p) < 0.0
    }

    /// The nearest hit `t ∈ (0, max_t)` of the ray `origin + t·dir` (`dir` a unit
    /// vector) on the obstacle's surface, if any. A ray starting inside reports no hit.
    pub fn ray_cast(&self, origin: Vec3, dir: Vec3, max_t: f32) -> Option<f32> {
        let t = match *self {
            Obstacle::Sphere { center, radius } => {
                // |o + t d − c|² = r²  ⇒  t² + 2 b t + c = 0 with b = d·(o−c).
                let m = origin - center;
                let b = m.dot(dir);
                let c = m.length_squared() - radius * radius;
                if c <= 0.0 {
                    return None;
                }
                let disc = b * b - c;
                if disc < 0.0 || b >= 0.0 {
                    return None;
                }
                -b - disc.sqrt()
            }
            Obstacle::Cylinder {
                x,
                z,
                radius,
                y_min,
                y_max,
            } => {
                if self.contains(origin) {
                    return None;
                }
                let mut best = f32::INFINITY;
                // Side: the 2-D ray in the x-z plane against the circle.
                let (ox, oz) = (origin.x - x, origin.z - z);
                let a = dir.x * dir.x + dir.z * dir.z;
                if a > 1e-12 {
                    let b = ox * dir.x + oz * dir.z;
                    let c = ox * ox + oz * oz - radius * radius;
                    let disc = b * b - a * c;
                    if disc >= 0.0 {
                        let t = (-b - disc.sqrt()) / a;
                        let y = origin.y + t * dir.y;
                        if t > 0.0 && y >= y_min && y <= y_max {
                            best = t;
                        }
                    }
                }
                // Caps: the horizontal discs at y_min and y_max.
                if dir.y.abs() > 1e-12 {
                    for cap in [y_min, y_max] {
                        let t = (cap - origin.y) / dir.y;
                        if t > 0.0 && t < best {
                            let (hx, hz) = (ox + t * dir.x, oz + t * dir.z);
                            if hx * hx + hz * hz <= radius * radius {
                                best = t;
                            }
                        }
                    }
                }
                best
            }
        };
        (t > 0.0 && t < max_t).then_some(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_distance_is_positive_inside() {
        // Wall at x = 1.5 facing −x (into a cube centred on the axis).
        let p = Plane::through(Vec3::new(1.5, 0.0, 0.0), Vec3::new(-1.0, 0.0, 0.0));
        assert_eq!(p.distance(Vec3::new(0.5, -1.0, 0.0)), 1.0);
        assert_eq!(p.distance(Vec3::new(2.0, 0.0, 0.0)), -0.5);
    }

    #[test]
    fn sphere_ray_hits_front_surface() {
        let s = Obstacle::Sphere {
            center: Vec3::new(0.0, 0.0, 5.0),
            radius: 1.0,
        };
        let t = s.ray_cast(Vec3::ZERO, Vec3::Z, 10.0).unwrap();
        assert!((t - 4.0).abs() < 1e-6);
        assert_eq!(s.ray_cast(Vec3::ZERO, Vec3::Z, 3.9), None);
        assert_eq!(s.ray_cast(Vec3::ZERO, -Vec3::Z, 10.0), None);
        assert_eq!(s.ray_cast(Vec3::ZERO, Vec3::X, 10.0), None);
        assert!((s.distance(Vec3::ZERO) - 4.0).abs() < 1e-6);
    }

    #[test]
    fn cylinder_ray_hits_side_and_cap() {
        let c = Obstacle::Cylinder {
            x: 2.0,
            z: 0.0,
            radius: 0.5,
            y_min: -3.0,
            y_max: -1.0,
        };
        let o = Vec3::new(0.0, -2.0, 0.0);
        // Side hit at x = 1.5.
        assert!((c.ray_cast(o, Vec3::X, 10.0).unwrap() - 1.5).abs() < 1e-6);
        // From above the cylinder straight down: cap at y = −1.
        let above = Vec3::new(2.0, -0.2, 0.0);
        assert!((c.ray_cast(above, -Vec3::Y, 10.0).unwrap() - 0.8).abs() < 1e-6);
        // Passing over the top misses.
        let high = Vec3::new(0.0, -0.5, 0.0);
        assert_eq!(c.ray_cast(high, Vec3::X, 10.0), None);
        // Distances: beside (radial), above (axial), diagonal (both).
        assert!((c.distance(o) - 1.5).abs() < 1e-6);
        assert!((c.distance(above) - 0.8).abs() < 1e-6);
        let corner = Vec3::new(2.5 + 0.3, -1.0 + 0.4, 0.0);
        assert!((c.distance(corner) - 0.5).abs() < 1e-6);
        assert!(c.contains(Vec3::new(2.0, -2.0, 0.1)));
    }
}
