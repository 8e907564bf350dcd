//! The sea cage (SPEC §1): net walls, net bottom and water surface, each a
//! plane with an inward normal; y is up, the surface is `y = 0`.

use crate::config::CageConfig;
use deepfoids_sensors::{Boundary, BoundaryKind, Plane};
use glam::Vec3;
use std::f32::consts::PI;

/// A cage's geometry.
#[derive(Clone, Debug)]
pub struct Cage {
    pub config: CageConfig,
    /// Walls, then the bottom, then the surface.
    pub boundaries: Vec<Boundary>,
    /// Depth of the bottom (m).
    pub height: f32,
    /// Axis-aligned bounds `(min, max)`.
    pub bounds: (Vec3, Vec3),
}

impl Cage {
    pub fn new(config: CageConfig) -> Self {
        let (walls, half_x, half_z, height) = match config {
            CageConfig::Cube { edge } => (
                box_walls(edge / 2.0, edge / 2.0),
                edge / 2.0,
                edge / 2.0,
                edge,
            ),
            CageConfig::Box {
                width,
                length,
                height,
            } => (
                box_walls(width / 2.0, length / 2.0),
                width / 2.0,
                length / 2.0,
                height,
            ),
            CageConfig::Octagon { edge, height } => {
                let apothem = octagon_apothem(edge);
                let walls = (0..8)
                    .map(|k| {
                        let phi = k as f32 * PI / 4.0;
                        let out = Vec3::new(phi.cos(), 0.0, phi.sin());
                        Plane::through(out * apothem, -out)
                    })
                    .collect();
                (walls, apothem, apothem, height)
            }
        };
        let mut boundaries: Vec<Boundary> = walls
            .into_iter()
            .map(|plane| Boundary {
                plane,
                kind: BoundaryKind::Net,
            })
            .collect();
        boundaries.push(Boundary {
            plane: Plane::through(Vec3::new(0.0, -height, 0.0), Vec3::Y),
            kind: BoundaryKind::Net,
        });
        boundaries.push(Boundary {
            plane: Plane::through(Vec3::ZERO, -Vec3::Y),
            kind: BoundaryKind::Surface,
        });
        Self {
            config,
            boundaries,
            height,
            bounds: (
                Vec3::new(-half_x, -height, -half_z),
                Vec3::new(half_x, 0.0, half_z),
            ),
        }
    }

    /// Water volume (m³).
    pub fn volume(&self) -> f32 {
        match self.config {
            CageConfig::Cube { edge } => edge.powi(3),
            CageConfig::Box {
                width,
                length,
                height,
            } => width * length * height,
            CageConfig::Octagon { edge, height } => octagon_area(edge) * height,
        }
    }

    /// Smallest distance of `p` to any boundary (m), negative outside.
    pub fn clearance(&self, p: Vec3) -> f32 {
        self.boundaries
            .iter()
            .map(|b| b.plane.distance(p))
            .fold(f32::INFINITY, f32::min)
    }

    /// Where the cage's vertical axis crosses the horizontal plane, `(x, z)`:
    /// the centre of its bounds.
    pub fn axis(&self) -> (f32, f32) {
        let (lo, hi) = self.bounds;
        (0.5 * (lo.x + hi.x), 0.5 * (lo.z + hi.z))
    }

    /// Half the narrowest horizontal width (m): how much room a fish has at most.
    pub fn inner_radius(&self) -> f32 {
        let (lo, hi) = self.bounds;
        ((hi.x - lo.x) / 2.0)
            .min((hi.z - lo.z) / 2.0)
            .min(self.height / 2.0)
    }

    /// The horizontal outline `(x, z)` of the walls, counter-clockwise, closed
    /// (the first vertex repeated at the end).
    pub fn outline(&self) -> Vec<(f32, f32)> {
        let mut v: Vec<(f32, f32)> = match self.config {
            CageConfig::Octagon { edge, .. } => {
                let r = octagon_apothem(edge) / (PI / 8.0).cos();
                (0..8)
                    .map(|k| {
                        let a = PI / 8.0 + k as f32 * PI / 4.0;
                        (r * a.cos(), r * a.sin())
                    })
                    .collect()
            }
            _ => {
                let (lo, hi) = self.bounds;
                vec![(lo.x, lo.z), (hi.x, lo.z), (hi.x, hi.z), (lo.x, hi.z)]
            }
        };
        v.push(v[0]);
        v
    }

    /// A short description, e.g. `octagon edge 3 × 4.6 m`.
    pub fn describe(&self) -> String {
        match self.config {
            CageConfig::Cube { edge } => format!("cube {edge} m"),
            CageConfig::Box {
                width,
                length,
                height,
            } => format!("box {width} × {length} × {height} m"),
            CageConfig::Octagon { edge, height } => format!("octagon edge {edge} × {height} m"),
        }
    }
}

fn box_walls(hx: f32, hz: f32) -> Vec<Plane> {
    vec![
        Plane::through(Vec3::new(hx, 0.0, 0.0), -Vec3::X),
        Plane::through(Vec3::new(-hx, 0.0, 0.0), Vec3::X),
        Plane::through(Vec3::new(0.0, 0.0, hz), -Vec3::Z),
        Plane::through(Vec3::new(0.0, 0.0, -hz), Vec3::Z),
    ]
}

/// Apothem of a regular octagon with edge `edge`: `edge / (2 tan 22.5°)`.
pub fn octagon_apothem(edge: f32) -> f32 {
    edge / (2.0 * (PI / 8.0).tan())
}

/// Area of a regular octagon with edge `edge`: `2 (1 + √2) edge²`.
pub fn octagon_area(edge: f32) -> f32 {
    2.0 * (1.0 + 2f32.sqrt()) * edge * edge
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_planes_and_volume() {
        let c = Cage::new(CageConfig::Cube { edge: 3.0 });
        assert_eq!(c.boundaries.len(), 6);
        assert_eq!(c.volume(), 27.0);
        assert!((c.clearance(Vec3::new(0.0, -1.5, 0.0)) - 1.5).abs() < 1e-6);
        assert!((c.clearance(Vec3::new(1.0, -0.2, 0.0)) - 0.2).abs() < 1e-6);
        assert!(c.clearance(Vec3::new(1.6, -1.0, 0.0)) < 0.0);
        assert_eq!(c.boundaries[5].kind, BoundaryKind::Surface);
    }

    /// Octagon edge 3: apothem 3 / (2 tan 22.5°) = 3.6213; area 43.456 m².
    #[test]
    fn octagon_geometry() {
        let c = Cage::new(CageConfig::Octagon {
            edge: 3.0,
            height: 4.6,
        });
        assert_eq!(c.boundaries.len(), 10);
        assert!((octagon_apothem(3.0) - 3.62132).abs() < 1e-4);
        assert!((c.volume() - 43.4558 * 4.6).abs() < 1e-2);
        // On the diagonal (22.5°) the wall at 45° is at the apothem along its normal.
        let d = Vec3::new(1.0, 0.0, 1.0).normalize();
        assert!((c.clearance(d * 3.0 + Vec3::new(0.0, -2.0, 0.0)) - 0.62132).abs() < 1e-4);
        // A corner lies at the circumradius 3.62132 / cos 22.5° = 3.9197, outside by a hair beyond.
        let corner =
            Vec3::new((PI / 8.0).cos(), 0.0, (PI / 8.0).sin()) * (3.62132 / (PI / 8.0).cos());
        assert!(c.clearance(corner * 1.001 + Vec3::new(0.0, -2.0, 0.0)) < 0.0);
    }
}
