//! Cameras: pinhole and equidistant fisheye (`r = f·θ`, up to 235°), and the
//! field set-ups of thesis Appendix A.4: a fisheye at the centre of the cage
//! bottom looking up, and side cameras at the middle of a wall at a depth,
//! facing the centre.
//!
//! Camera coordinates follow OpenCV: `x` right, `y` down, `z` forward
//! (the optical axis). Pixel `(u, v)` has its centre at `(u + 0.5, v + 0.5)`.

use glam::{Mat3, Vec3};
use serde::Serialize;

/// The lens model.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "model", rename_all = "lowercase")]
pub enum Lens {
    /// `u = fx·x/z + cx`, `v = fy·y/z + cy`.
    Pinhole { fx: f32, fy: f32, cx: f32, cy: f32 },
    /// Equidistant: a ray at angle `θ` from the axis lands at radius `f·θ`
    /// from `(cx, cy)`; rays beyond `θ_max` (half the field of view) are cut.
    Fisheye {
        f: f32,
        cx: f32,
        cy: f32,
        theta_max: f32,
    },
}

/// A camera in the world.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub lens: Lens,
    /// Optical centre (world, m).
    #[serde(serialize_with = "ser_vec3")]
    pub position: Vec3,
    /// Rows are the camera axes x, y, z in world coordinates (world → camera).
    #[serde(serialize_with = "ser_mat3")]
    pub rotation: Mat3,
}

fn ser_vec3<S: serde::Serializer>(v: &Vec3, s: S) -> Result<S::Ok, S::Error> {
    v.to_array().serialize(s)
}

fn ser_mat3<S: serde::Serializer>(m: &Mat3, s: S) -> Result<S::Ok, S::Error> {
    let t = m.transpose();
    [
        t.x_axis.to_array(),
        t.y_axis.to_array(),
        t.z_axis.to_array(),
    ]
    .serialize(s)
}

/// Closest a point may be to the camera to be drawn (m).
pub const NEAR: f32 = 0.02;

impl Camera {
    /// World → camera rotation for a camera looking along `forward` with the
    /// image's up direction as close to `up` as possible.
    pub fn look_rotation(forward: Vec3, up: Vec3) -> Mat3 {
        let z = forward.normalize();
        let x = z.cross(up).normalize_or(z.any_orthonormal_vector()); // right = forward × up
        let y = z.cross(x); // down
        Mat3::from_cols(x, y, z).transpose()
    }

    /// A pinhole camera with horizontal field of view `hfov_deg`.
    pub fn pinhole(
        position: Vec3,
        forward: Vec3,
        up: Vec3,
        hfov_deg: f32,
        width: u32,
        height: u32,
    ) -> Self {
        let fx = width as f32 / 2.0 / (hfov_deg.to_radians() / 2.0).tan();
        Self {
            width,
            height,
            lens: Lens::Pinhole {
                fx,
                fy: fx,
                cx: width as f32 / 2.0,
                cy: height as f32 / 2.0,
            },
            position,
            rotation: Self::look_rotation(forward, up),
        }
    }

    /// An equidistant fisheye whose `fov_deg` image circle fits the shorter side.
    pub fn fisheye(
        position: Vec3,
        forward: Vec3,
        up: Vec3,
        fov_deg: f32,
        width: u32,
        height: u32,
    ) -> Self {
        let theta_max = fov_deg.to_radians() / 2.0;
        let f = width.min(height) as f32 / 2.0 / theta_max;
        Self {
            width,
            height,
            lens: Lens::Fisheye {
                f,
                cx: width as f32 / 2.0,
                cy: height as f32 / 2.0,
                theta_max,
            },
            position,
            rotation: Self::look_rotation(forward, up),
        }
    }

    /// A world point in camera coordinates.
    #[inline]
    pub fn to_camera(&self, p: Vec3) -> Vec3 {
        self.rotation * (p - self.position)
    }

    /// Project a point in camera coordinates: `(u, v, depth)` with depth the
    /// z coordinate (pinhole) or the distance (fisheye). `None` behind the
    /// near plane (pinhole) or nearer than [`NEAR`] or beyond 179° (fisheye).
    /// Points outside the image or beyond the fisheye's `θ_max` still project.
    #[inline]
    pub fn project_camera(&self, c: Vec3) -> Option<Vec3> {
        match self.lens {
            Lens::Pinhole { fx, fy, cx, cy } => {
                (c.z >= NEAR).then(|| Vec3::new(fx * c.x / c.z + cx, fy * c.y / c.z + cy, c.z))
            }
            Lens::Fisheye { f, cx, cy, .. } => {
                let d = c.length();
                if d < NEAR {
                    return None;
                }
                let rxy = (c.x * c.x + c.y * c.y).sqrt();
                let theta = rxy.atan2(c.z);
                if theta > 179f32.to_radians() {
                    return None;
                }
                let (ux, uy) = if rxy > 0.0 {
                    (c.x / rxy, c.y / rxy)
                } else {
                    (0.0, 0.0)
                };
                Some(Vec3::new(cx + f * theta * ux, cy + f * theta * uy, d))
            }
        }
    }

    /// Project a world point (see [`Camera::project_camera`]).
    #[inline]
    pub fn project(&self, p: Vec3) -> Option<Vec3> {
        self.project_camera(self.to_camera(p))
    }

    /// Whether image position `(x, y)` (pixel units) sees the scene: inside
    /// the image and, for a fisheye, inside its image circle.
    #[inline]
    pub fn in_view(&self, x: f32, y: f32) -> bool {
        if !(x >= 0.0 && y >= 0.0 && x <= self.width as f32 && y <= self.height as f32) {
            return false;
        }
        match self.lens {
            Lens::Pinhole { .. } => true,
            Lens::Fisheye {
                f,
                cx,
                cy,
                theta_max,
            } => {
                let r = f * theta_max;
                (x - cx).powi(2) + (y - cy).powi(2) <= r * r
            }
        }
    }

    /// Unit direction in camera coordinates of the ray through image position
    /// `(x, y)`, and the factor turning the rasteriser's depth into distance
    /// along the ray (`|ray|/z` for a pinhole, 1 for a fisheye). `None`
    /// outside the fisheye's image circle.
    #[inline]
    pub fn ray_camera(&self, x: f32, y: f32) -> Option<(Vec3, f32)> {
        match self.lens {
            Lens::Pinhole { fx, fy, cx, cy } => {
                let d = Vec3::new((x - cx) / fx, (y - cy) / fy, 1.0);
                let n = d.length();
                Some((d / n, n))
            }
            Lens::Fisheye {
                f,
                cx,
                cy,
                theta_max,
            } => {
                let (dx, dy) = (x - cx, y - cy);
                let r = (dx * dx + dy * dy).sqrt();
                let theta = r / f;
                if theta > theta_max {
                    return None;
                }
                let (st, ct) = theta.sin_cos();
                let (ux, uy) = if r > 0.0 {
                    (dx / r, dy / r)
                } else {
                    (0.0, 0.0)
                };
                Some((Vec3::new(st * ux, st * uy, ct), 1.0))
            }
        }
    }

    /// The world ray through image position `(x, y)` (see [`Camera::ray_camera`]).
    #[inline]
    pub fn ray(&self, x: f32, y: f32) -> Option<(Vec3, f32)> {
        self.ray_camera(x, y)
            .map(|(d, k)| (self.rotation.transpose() * d, k))
    }

    pub fn is_fisheye(&self) -> bool {
        matches!(self.lens, Lens::Fisheye { .. })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A camera at (0, −2, 5) looking along −z (up = +y), 90° horizontal FOV
    /// at 640 × 480: fx = 320. The world point (1, −1.5, 1) is 4 m in front,
    /// 1 m right and 0.5 m up: u = 320 + 320·1/4 = 400, v = 240 − 320·0.5/4 = 200.
    #[test]
    fn pinhole_projects_known_points() {
        let cam = Camera::pinhole(Vec3::new(0.0, -2.0, 5.0), -Vec3::Z, Vec3::Y, 90.0, 640, 480);
        let p = cam.project(Vec3::new(1.0, -1.5, 1.0)).unwrap();
        assert!((p - Vec3::new(400.0, 200.0, 4.0)).length() < 1e-4, "{p}");
        // Behind the camera: nothing.
        assert!(cam.project(Vec3::new(0.0, -2.0, 6.0)).is_none());
        // The ray through the projection points back at the point.
        let (d, k) = cam.ray(400.0, 200.0).unwrap();
        let dir = (Vec3::new(1.0, -1.5, 1.0) - cam.position).normalize();
        assert!((d - dir).length() < 1e-5);
        assert!((k * 4.0 - Vec3::new(1.0, 0.5, 4.0).length()).abs() < 1e-4);
    }

    /// A bottom camera at (0, −4, 0) looking up (image up = −z), 235° FOV on a
    /// 1000 × 1000 image: f = 500/(117.5° in rad). Seen from below with north
    /// up, west (−x) is on the right. A point 45° off the axis towards −x lands
    /// at radius f·π/4 right of the centre; a point 100° off the axis (below
    /// the horizon) still lands inside the circle.
    #[test]
    fn fisheye_projects_known_points() {
        let cam = Camera::fisheye(
            Vec3::new(0.0, -4.0, 0.0),
            Vec3::Y,
            -Vec3::Z,
            235.0,
            1000,
            1000,
        );
        let f = 500.0 / 117.5f32.to_radians();
        let p = cam.project(Vec3::new(-1.0, -3.0, 0.0)).unwrap();
        assert!(
            (p.x - (500.0 + f * std::f32::consts::FRAC_PI_4)).abs() < 1e-3,
            "{p}"
        );
        assert!((p.y - 500.0).abs() < 1e-3);
        assert!((p.z - 2f32.sqrt()).abs() < 1e-5);
        // North (−z) is up in the image.
        let n = cam.project(Vec3::new(0.0, -3.0, -1.0)).unwrap();
        assert!(n.y < 500.0 && (n.x - 500.0).abs() < 1e-3);
        // 100° from the axis: radius f·100°, inside θ_max = 117.5°.
        let a = 100f32.to_radians();
        let q = cam
            .project(Vec3::new(-a.sin(), -4.0 + a.cos(), 0.0))
            .unwrap();
        assert!((q.x - 500.0 - f * a).abs() < 1e-2, "{q}");
        assert!(cam.in_view(q.x, q.y));
        // The ray back.
        let (d, _) = cam.ray(q.x, q.y).unwrap();
        assert!((d - Vec3::new(-a.sin(), a.cos(), 0.0)).length() < 1e-4);
        // Outside the circle: no ray.
        assert!(cam.ray(0.0, 0.0).is_none());
    }
}
