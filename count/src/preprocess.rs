//! Pre-processing (thesis §4.4.1): median-blur denoising, and the fisheye
//! correction to a perspective view.
//!
//! # The lens model
//! The renderer's fisheye (`deepfoids_render::camera`) is the reference: an
//! equidistant lens, a ray at angle `θ` from the optical axis lands at radius
//! `ρ = f·θ` from the image centre `(W/2, H/2)`, with the field of view's
//! image circle filling the shorter side, `f = min(W, H)/2 / θ_max`,
//! `θ_max = fov/2` (the thesis' camera: 235°).
//!
//! The corrected view is a virtual pinhole on the same optical axis with a
//! horizontal and vertical field of view `view_fov` (default 120°) on an
//! `S × S` image: `f_p = (S/2) / tan(view_fov/2)`. Its pixel centre
//! `(u + ½, v + ½)` is the ray `((u + ½ − S/2)/f_p, (v + ½ − S/2)/f_p, 1)`;
//! with `r` its distance from the axis on the plane `z = 1`, `θ = atan(r)`,
//! and the fisheye shows it at `(W/2, H/2) + f·θ·(x, y)/r`, sampled
//! bilinearly. A perspective view cannot hold 180° or more, so the fisheye's
//! rim beyond `view_fov/2` from the axis is not looked at: for the bottom
//! camera, fish seen near the horizon (far, low at the walls).

use deepfoids_render::Camera;
use glam::Vec3;
use image::RgbImage;
use rayon::prelude::*;

/// What filmed the input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InputCamera {
    /// A perspective camera: frames are used as they are.
    Pinhole,
    /// An equidistant fisheye with this full field of view (degrees).
    Fisheye { fov_deg: f32 },
}

/// Median of each channel over a `k × k` neighbourhood (`k` odd; 1 or 0: a
/// copy). Borders replicate the edge pixel.
pub fn median_blur(img: &RgbImage, k: u32) -> RgbImage {
    if k <= 1 {
        return img.clone();
    }
    let (w, h) = img.dimensions();
    let r = (k / 2) as i64;
    let src = img.as_raw();
    let mut out = vec![0u8; src.len()];
    out.par_chunks_mut(w as usize * 3)
        .enumerate()
        .for_each(|(y, row)| {
            let mut buf = Vec::with_capacity((k * k) as usize);
            for x in 0..w as i64 {
                for c in 0..3 {
                    buf.clear();
                    for dy in -r..=r {
                        let yy = (y as i64 + dy).clamp(0, h as i64 - 1) as usize;
                        for dx in -r..=r {
                            let xx = (x + dx).clamp(0, w as i64 - 1) as usize;
                            buf.push(src[(yy * w as usize + xx) * 3 + c]);
                        }
                    }
                    let mid = buf.len() / 2;
                    row[x as usize * 3 + c] = *buf.select_nth_unstable(mid).1;
                }
            }
        });
    RgbImage::from_raw(w, h, out).expect("same size")
}

/// The perspective view of a fisheye frame: a precomputed map from each view
/// pixel to its fisheye position (pixel units, continuous: the pixel `(i, j)`
/// covers `[i, i + 1) × [j, j + 1)`).
#[derive(Clone, Debug)]
pub struct PerspectiveView {
    /// Side of the square view (pixels).
    pub size: u32,
    /// Field of view of the view (degrees).
    pub view_fov_deg: f32,
    /// The fisheye it reads.
    pub source: (u32, u32),
    pub fisheye_fov_deg: f32,
    /// Focal length of the view (pixels).
    pub f_view: f32,
    map: Vec<[f32; 2]>,
}

impl PerspectiveView {
    /// The view of a `width × height` fisheye of `fov_deg`, `view_fov_deg`
    /// wide on `size × size` pixels.
    pub fn new(width: u32, height: u32, fov_deg: f32, view_fov_deg: f32, size: u32) -> Self {
        let lens = Camera::fisheye(Vec3::ZERO, Vec3::Z, -Vec3::Y, fov_deg, width, height);
        let f_view = size as f32 / 2.0 / (view_fov_deg.to_radians() / 2.0).tan();
        let half = size as f32 / 2.0;
        let map = (0..size * size)
            .map(|i| {
                let (u, v) = ((i % size) as f32 + 0.5, (i / size) as f32 + 0.5);
                let ray = Vec3::new((u - half) / f_view, (v - half) / f_view, 1.0);
                // The renderer's own projection (camera coordinates: x right, y down).
                let p = lens.project_camera(ray).expect("in front of the lens");
                [p.x, p.y]
            })
            .collect();
        Self {
            size,
            view_fov_deg,
            source: (width, height),
            fisheye_fov_deg: fov_deg,
            f_view,
            map,
        }
    }

    /// Where view position `(u, v)` (continuous pixels) lies in the fisheye.
    pub fn to_fisheye(&self, u: f32, v: f32) -> (f32, f32) {
        let lens = Camera::fisheye(
            Vec3::ZERO,
            Vec3::Z,
            -Vec3::Y,
            self.fisheye_fov_deg,
            self.source.0,
            self.source.1,
        );
        let half = self.size as f32 / 2.0;
        let ray = Vec3::new((u - half) / self.f_view, (v - half) / self.f_view, 1.0);
        let p = lens.project_camera(ray).expect("in front of the lens");
        (p.x, p.y)
    }

    /// The view of `img` (bilinear; black outside the fisheye frame).
    pub fn apply(&self, img: &RgbImage) -> RgbImage {
        let (w, h) = img.dimensions();
        assert_eq!(
            (w, h),
            self.source,
            "the view was made for another frame size"
        );
        let src = img.as_raw();
        let mut out = vec![0u8; (self.size * self.size * 3) as usize];
        out.par_chunks_mut(self.size as usize * 3)
            .enumerate()
            .for_each(|(j, row)| {
                for i in 0..self.size as usize {
                    let [x, y] = self.map[j * self.size as usize + i];
                    // Continuous position → index space of pixel centres.
                    let (fx, fy) = (x - 0.5, y - 0.5);
                    let (x0, y0) = (fx.floor(), fy.floor());
                    let (ax, ay) = (fx - x0, fy - y0);
                    let mut px = [0f32; 3];
                    for (dy, wy) in [(0, 1.0 - ay), (1, ay)] {
                        for (dx, wx) in [(0, 1.0 - ax), (1, ax)] {
                            let (xx, yy) = (x0 as i64 + dx, y0 as i64 + dy);
                            if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                                continue;
                            }
                            let k = (yy as usize * w as usize + xx as usize) * 3;
                            for c in 0..3 {
                                px[c] += wx * wy * src[k + c] as f32;
                            }
                        }
                    }
                    for c in 0..3 {
                        row[i * 3 + c] = px[c].round().clamp(0.0, 255.0) as u8;
                    }
                }
            });
        RgbImage::from_raw(self.size, self.size, out).expect("square view")
    }

    /// The view of a 16-bit instance mask (nearest pixel, 0 outside).
    pub fn apply_mask(&self, mask: &[u16]) -> Vec<u16> {
        let (w, h) = self.source;
        self.map
            .iter()
            .map(|&[x, y]| {
                let (xi, yi) = (x.floor() as i64, y.floor() as i64);
                if xi < 0 || yi < 0 || xi >= w as i64 || yi >= h as i64 {
                    0
                } else {
                    mask[yi as usize * w as usize + xi as usize]
                }
            })
            .collect()
    }
}

/// The local contrast of [`crate::model::local_contrast`] on a whole image,
/// as `[3, H, W]` floats: per channel `(x − m) / √(v + ε²)`, with `m` and `v`
/// the mean and variance of the `k × k` square around the pixel (`k` odd),
/// the part outside the image not counted. Pixels are `x = byte / 255`.
///
/// Running sums (column prefix sums, then a row prefix sum: a few adds a
/// pixel whatever `k`, in f64), so the counting pipeline normalises each view
/// once and cuts its windows from the result, where the exported graph pools
/// every window again (`Detector::load` bypasses that part of the graph).
/// Inside a window this equals the graph's output; within `k/2` of a window's
/// inner edge it is better, as the square sees the neighbouring pixels.
pub fn local_contrast(img: &RgbImage, k: usize, eps: f32) -> Vec<f32> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let (p, plane) = (k / 2, w * h);
    let eps2 = f64::from(eps) * f64::from(eps);
    let mut out = vec![0f32; 3 * plane];
    out.par_chunks_mut(plane.max(1))
        .enumerate()
        .for_each(|(c, out)| {
            let x: Vec<f64> = img.as_raw()[c..]
                .iter()
                .step_by(3)
                .map(|&b| f64::from(f32::from(b) / 255.0))
                .collect();
            let row_span = |y: usize| (y.saturating_sub(p), (y + p + 1).min(h));
            let col_span = |x: usize| (x.saturating_sub(p), (x + p + 1).min(w));
            // Column prefix sums of x and x²: `sums[(y + 1)·w + x]` holds rows 0..=y.
            let mut sums = vec![[0f64; 2]; (h + 1) * w];
            for y in 0..h {
                for i in 0..w {
                    let (v, [s, s2]) = (x[y * w + i], sums[y * w + i]);
                    sums[(y + 1) * w + i] = [s + v, s2 + v * v];
                }
            }
            let mut row = vec![[0f64; 2]; w + 1];
            for y in 0..h {
                let (y0, y1) = row_span(y);
                for i in 0..w {
                    let (a, b) = (sums[y0 * w + i], sums[y1 * w + i]);
                    row[i + 1] = [row[i][0] + b[0] - a[0], row[i][1] + b[1] - a[1]];
                }
                for i in 0..w {
                    let (x0, x1) = col_span(i);
                    let n = ((y1 - y0) * (x1 - x0)) as f64;
                    let m = (row[x1][0] - row[x0][0]) / n;
                    let v = ((row[x1][1] - row[x0][1]) / n - m * m).max(0.0);
                    out[y * w + i] = ((x[y * w + i] - m) / (v + eps2).sqrt()) as f32;
                }
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 × 1 image, channel 0 = 0, 0.2, 0.4 (bytes 0, 51, 102), k = 3,
    /// ε = 0.02: pixel 0's square holds 0 and 0.2 (m 0.1, v 0.01), so
    /// −0.1/√0.0104 = −0.98058; pixel 1's holds all three (m 0.2), so 0;
    /// pixel 2 mirrors pixel 0. A flat channel gives 0 everywhere.
    #[test]
    fn local_contrast_by_hand() {
        let img = RgbImage::from_fn(3, 1, |x, _| image::Rgb([51 * x as u8, 9, 9]));
        let out = local_contrast(&img, 3, 0.02);
        let want = [-0.98058, 0.0, 0.98058];
        for (got, want) in out[..3].iter().zip(want) {
            assert!((got - want).abs() < 1e-4, "{:?}", &out[..3]);
        }
        assert!(out[3..].iter().all(|v| v.abs() < 1e-6), "{out:?}");
    }

    /// 3 × 3 median of a single bright speck on grey: the speck disappears,
    /// an edge stays where it was.
    #[test]
    fn median_removes_specks_and_keeps_edges() {
        let mut img = RgbImage::from_pixel(7, 5, image::Rgb([50, 60, 70]));
        img.put_pixel(3, 2, image::Rgb([255, 255, 255]));
        let m = median_blur(&img, 3);
        assert_eq!(m.get_pixel(3, 2).0, [50, 60, 70]);
        let edge = RgbImage::from_fn(6, 4, |x, _| {
            if x < 3 {
                image::Rgb([0, 0, 0])
            } else {
                image::Rgb([200, 200, 200])
            }
        });
        let m = median_blur(&edge, 3);
        assert_eq!(m.get_pixel(2, 1).0, [0, 0, 0]);
        assert_eq!(m.get_pixel(3, 1).0, [200, 200, 200]);
    }

    /// The view and the renderer's fisheye agree: a world direction seen by a
    /// pinhole of `f_p` at view position `p` lands, through the view's map, where
    /// the renderer's fisheye camera projects it. Straight through the centre
    /// the magnification is `f_p/f`.
    #[test]
    fn view_follows_the_renderer_lens() {
        let (w, h, fov) = (1280, 720, 235.0);
        let view = PerspectiveView::new(w, h, fov, 120.0, 832);
        let f = 360.0 / (117.5f32.to_radians());
        assert!((view.f_view - 416.0 / 60f32.to_radians().tan()).abs() < 1e-3);
        let cam = Camera::fisheye(Vec3::ZERO, Vec3::Z, -Vec3::Y, fov, w, h);
        for dir in [
            Vec3::new(0.3, -0.2, 1.0),
            Vec3::new(-1.2, 0.9, 1.0),
            Vec3::Z,
        ] {
            let (u, v) = (
                416.0 + view.f_view * dir.x / dir.z,
                416.0 + view.f_view * dir.y / dir.z,
            );
            let (x, y) = view.to_fisheye(u, v);
            let p = cam.project_camera(dir).unwrap();
            assert!((x - p.x).abs() < 1e-2 && (y - p.y).abs() < 1e-2, "{dir}");
            // By hand: θ = atan(|xy|/z), ρ = f·θ.
            let r = (dir.x * dir.x + dir.y * dir.y).sqrt();
            let rho = f * r.atan2(dir.z);
            let got = ((x - 640.0).powi(2) + (y - 360.0).powi(2)).sqrt();
            assert!((got - rho).abs() < 1e-2, "{got} vs {rho}");
        }
        // A dot rendered into the fisheye at the projection of a direction shows
        // up in the view at the pinhole position of that direction.
        let dir = Vec3::new(0.5, 0.25, 1.0);
        let p = cam.project_camera(dir).unwrap();
        let mut img = RgbImage::new(w, h);
        for y in (p.y as u32 - 3)..(p.y as u32 + 4) {
            for x in (p.x as u32 - 3)..(p.x as u32 + 4) {
                img.put_pixel(x, y, image::Rgb([255, 255, 255]));
            }
        }
        let out = view.apply(&img);
        let (u, v) = (416.0 + view.f_view * 0.5, 416.0 + view.f_view * 0.25);
        assert_eq!(out.get_pixel(u as u32, v as u32).0, [255, 255, 255]);
        assert_eq!(out.get_pixel(416, 416).0, [0, 0, 0]);
    }
}
