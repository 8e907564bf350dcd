//! The CPU renderer: a triangle rasteriser with a z-buffer and an id-buffer,
//! then a per-pixel pass that puts the water between the camera and whatever
//! each pixel sees.
//!
//! 1. Per fish (rayon over fish): transform its species' mesh (tail beat,
//!    body length, pose), shade the vertices (Lambert from the refracted sun
//!    plus the sky's diffuse light), project them, and rasterise the fish
//!    alone into a small buffer over its screen box. That buffer is the fish's
//!    unoccluded silhouette: its full 2D box, its pixel count, and whether it
//!    is cut by the image border.
//! 2. Per band of rows (rayon over bands): merge the fish buffers into the
//!    frame's depth, id and shade buffers with a depth test.
//! 3. Per row: cast each pixel's ray. A fish pixel's radiance is its vertex
//!    shade times `exp(−K·depth)`; any other ray leaves the cage through a net
//!    wall, the net bottom or the surface (Snell's window, total internal
//!    reflection outside it). Then `L·exp(−c·t) + in-scatter` (see
//!    [`crate::optics`]), auto exposure, tone curve, sRGB.
//!    What every pixel shows without fish (the background) depends only on
//!    the camera and the conditions, so it is computed once for them and
//!    kept ([`Renderer::background`]): a clip's frames share it while its
//!    light does not change (`ClipSetup::conditions` holds the light for
//!    [`crate::setup::LIGHT_STEP_SECONDS`]). Only fish pixels are shaded
//!    per frame; the largest channel difference between a fish pixel and
//!    the background there is the pixel's contrast.
//! 4. Labels from the id buffer: visible pixels, visible 2D box and mean
//!    contrast per fish; a fish with visible pixels and enough contrast is
//!    detectable (labelled for detectors).
//!
//! Fisheye cameras project the vertices with `r = f·θ` and rasterise straight
//! triangle edges between them; the meshes are fine enough (≈ 400 triangles
//! per fish) that the error is below a pixel except for a fish touching the
//! lens. Depth there is the distance, interpolated linearly on screen.
//! Pinhole depth is `z`, interpolated as `1/z` (exact); triangles crossing the
//! near plane are clipped.

use crate::camera::{Camera, Lens, NEAR};
use crate::mesh::{FishMesh, tail_beat_amplitude};
use crate::optics::{Light, N_WATER, Water, fresnel_air_water};
use glam::{Mat3, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::{Arc, Mutex};

/// Rendering options; every field has a documented default.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RenderConfig {
    /// Side of a net mesh square (m); 0.05. Farm nets for 0.3–0.5 m fish use 2–5 cm.
    pub net_mesh: f32,
    /// Twine thickness (m); 0.005.
    pub net_twine: f32,
    /// Albedo of the net (linear RGB); dark green-grey, (0.10, 0.13, 0.11).
    pub net_albedo: [f32; 3],
    /// How far the auto exposure may brighten beyond its noon setting (stops); 2.
    /// Dusk is darker than noon, night is black.
    pub exposure_stops: f32,
    /// Exposure: a white surface facing up at the camera's depth maps to this
    /// much of the tone curve's input; 1.2.
    pub exposure: f32,
    /// Animate the tail beat from each fish's speed; true.
    pub tail_beat: bool,
    /// A fish is *detectable* (labelled in YOLO and COCO) when it has visible
    /// pixels and its mean contrast against the water behind it is at least
    /// this (0–1 of the 8-bit range); 0.03 ≈ 8 grey levels. Measured: a
    /// randomised bottom-fisheye frame of `coho_default` labelled 44 fish at
    /// 0.01, the strongest at 0.028, and none could be made out in its JPEG;
    /// in clear water (`seabream_50`) fish range 0.03–0.19 (median 0.10), all
    /// plainly visible. Fish lost in turbid water or darkness keep their entry
    /// in the frame JSON and the mask (a detector's trainer ignores them).
    pub min_contrast: f32,
}

impl Default for RenderConfig {
    fn default() -> Self {
        Self {
            net_mesh: 0.05,
            net_twine: 0.005,
            net_albedo: [0.10, 0.13, 0.11],
            exposure_stops: 2.0,
            exposure: 1.2,
            tail_beat: true,
            min_contrast: 0.03,
        }
    }
}

/// Light and water of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conditions {
    pub light: Light,
    /// The same place at solar noon (the auto exposure's reference).
    pub noon: Light,
    pub water: Water,
}

/// One fish to draw.
#[derive(Clone, Copy, Debug)]
pub struct FishPose {
    pub position: Vec3,
    /// Unit heading.
    pub heading: Vec3,
    /// Roll about the heading (rad).
    pub roll: f32,
    /// Body length (m).
    pub bl: f32,
    /// Speed (m/s).
    pub speed: f32,
    /// Index of the species' mesh.
    pub species: u16,
    /// Tail-beat phase (rad).
    pub tail_phase: f32,
}

/// A cage face as the renderer sees it.
#[derive(Clone, Copy, Debug)]
pub struct Face {
    /// Inward unit normal.
    pub normal: Vec3,
    pub offset: f32,
    pub surface: bool,
}

/// Labels of one fish in one frame (pixels; boxes are `[x0, y0, x1, y1]`
/// with `x1`, `y1` exclusive).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FishLabel {
    /// Fish index in the world (its id in the mask is `fish + 1`).
    pub fish: usize,
    pub species: u16,
    /// Box of the visible silhouette (None when fully occluded).
    pub box_visible: Option<[u32; 4]>,
    /// Box of the whole silhouette as if nothing occluded it (clipped to the image).
    pub box_full: [u32; 4],
    pub visible_pixels: u32,
    /// Pixels if unoccluded (inside the image).
    pub full_pixels: u32,
    /// `visible_pixels / full_pixels`.
    pub visibility: f32,
    /// The silhouette is cut by the image border (or the fisheye's circle).
    pub truncated: bool,
    /// The fish's oriented 3D box (mesh bounds with the tail beat), world (m).
    pub box3d_world: [[f32; 3]; 8],
    /// The same corners in camera coordinates (x right, y down, z forward).
    pub box3d_camera: [[f32; 3]; 8],
    /// Distance from the camera to the body centre (m).
    pub distance: f32,
    /// Mean over the visible pixels of the largest per-channel difference
    /// (0–1 of the 8-bit range) between the fish and what the pixel shows
    /// without it: how much the fish stands out from the water behind it.
    pub contrast: f32,
    /// Visible pixels and `contrast ≥ RenderConfig::min_contrast`: the fish
    /// can be seen in the image, so it is labelled for detectors.
    pub detectable: bool,
}

/// A rendered frame.
#[derive(Clone, Debug)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// sRGB, 3 bytes per pixel, row-major.
    pub rgb: Vec<u8>,
    /// Instance mask: 0 = no fish, `fish + 1` otherwise.
    pub ids: Vec<u16>,
    /// Every fish with at least one pixel if unoccluded, by fish index.
    pub fish: Vec<FishLabel>,
    /// The auto exposure's gain.
    pub gain: f32,
}

impl Frame {
    /// Fish with at least one visible pixel (in view and not hidden by others,
    /// however dark or turbid the water).
    pub fn in_view_count(&self) -> usize {
        self.fish.iter().filter(|f| f.visible_pixels > 0).count()
    }

    /// Fish that can be seen in the image: the per-frame visible fish count.
    pub fn visible_count(&self) -> usize {
        self.fish.iter().filter(|f| f.detectable).count()
    }
}

/// The renderer: per-species meshes, the cage, options.
#[derive(Clone, Debug)]
pub struct Renderer {
    pub config: RenderConfig,
    pub meshes: Vec<FishMesh>,
    pub faces: Vec<Face>,
    background: BackgroundCache,
}

/// The image without fish (sRGB after exposure) for one camera and one set
/// of conditions.
#[derive(Debug)]
pub struct Background {
    camera: Camera,
    cond: Conditions,
    /// 3 bytes per pixel, row-major.
    pub rgb: Vec<u8>,
}

/// The newest [`Background`]; a clone of the renderer starts empty.
#[derive(Debug, Default)]
struct BackgroundCache(Mutex<Option<Arc<Background>>>);

impl Clone for BackgroundCache {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// One fish rasterised alone.
struct Local {
    fish: usize,
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
    depth: Vec<f32>,
    shade: Vec<Vec3>,
    truncated: bool,
    box3d: [Vec3; 8],
    distance: f32,
}

/// A vertex ready for rasterising.
#[derive(Clone, Copy)]
struct RVert {
    /// Screen x, y and depth.
    p: Vec3,
    shade: Vec3,
}

/// Fish-local axes: x to the side, y up, z forward (the heading), rolled.
pub fn fish_axes(heading: Vec3, roll: f32) -> Mat3 {
    let z = heading.normalize_or(Vec3::Z);
    let x = Vec3::Y.cross(z).normalize_or(Vec3::X);
    let y = z.cross(x);
    let (s, c) = roll.sin_cos();
    Mat3::from_cols(x * c + y * s, y * c - x * s, z)
}

impl Renderer {
    pub fn new(config: RenderConfig, meshes: Vec<FishMesh>, faces: Vec<Face>) -> Self {
        Self {
            config,
            meshes,
            faces,
            background: BackgroundCache::default(),
        }
    }

    /// The image without fish for `camera` under `cond`: the one kept if it
    /// was made for them, else made now (every pixel's ray to the net or the
    /// surface, rows in parallel) and kept instead.
    pub fn background(&self, camera: &Camera, cond: &Conditions) -> Arc<Background> {
        let mut kept = self.background.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(b) = kept
            .as_ref()
            .filter(|b| b.camera == *camera && b.cond == *cond)
        {
            return b.clone();
        }
        let (w, gain) = (camera.width as usize, self.gain(camera, cond));
        let mut rgb = vec![0u8; w * camera.height as usize * 3];
        rgb.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
            for x in 0..w {
                let c = self.pixel(camera, cond, x, y, f32::INFINITY, Vec3::ZERO, false);
                row[3 * x..3 * x + 3].copy_from_slice(&tone(c * gain));
            }
        });
        let b = Arc::new(Background {
            camera: *camera,
            cond: *cond,
            rgb,
        });
        *kept = Some(b.clone());
        b
    }

    /// The cage faces of `cage` (walls, bottom, surface).
    pub fn faces_of(cage: &deepfoids_env::cage::Cage) -> Vec<Face> {
        cage.boundaries
            .iter()
            .enumerate()
            .map(|(i, b)| Face {
                normal: b.plane.normal,
                offset: b.plane.offset,
                // `Cage::boundaries` lists the walls, the bottom, then the surface.
                surface: i + 1 == cage.boundaries.len(),
            })
            .collect()
    }

    /// Render `fish` seen by `camera` under `cond`.
    pub fn render(&self, fish: &[FishPose], camera: &Camera, cond: &Conditions) -> Frame {
        assert!(
            fish.len() < u16::MAX as usize,
            "the 16-bit mask holds up to 65,534 fish"
        );
        let (w, h) = (camera.width as usize, camera.height as usize);
        // 1. Each fish alone.
        let locals: Vec<Local> = fish
            .par_iter()
            .enumerate()
            .with_min_len(8)
            .filter_map(|(i, f)| self.raster_fish(i, f, camera, cond))
            .collect();
        // 2. Merge with a depth test, bands of rows in parallel.
        let mut depth = vec![f32::INFINITY; w * h];
        let mut ids = vec![0u16; w * h];
        let mut shade = vec![Vec3::ZERO; w * h];
        const BAND: usize = 16;
        depth
            .par_chunks_mut(BAND * w)
            .zip(ids.par_chunks_mut(BAND * w))
            .zip(shade.par_chunks_mut(BAND * w))
            .enumerate()
            .for_each(|(band, ((dep, id), sh))| {
                let y_lo = band * BAND;
                let y_hi = y_lo + dep.len() / w;
                for l in &locals {
                    let (ly0, ly1) = (l.y0 as usize, (l.y0 + l.h) as usize);
                    if ly1 <= y_lo || ly0 >= y_hi {
                        continue;
                    }
                    for y in ly0.max(y_lo)..ly1.min(y_hi) {
                        let lrow = (y - ly0) * l.w as usize;
                        let grow = (y - y_lo) * w + l.x0 as usize;
                        for x in 0..l.w as usize {
                            let d = l.depth[lrow + x];
                            if d < dep[grow + x] {
                                dep[grow + x] = d;
                                id[grow + x] = (l.fish + 1) as u16;
                                sh[grow + x] = l.shade[lrow + x];
                            }
                        }
                    }
                }
            });
        // 3. The background, then the fish pixels' water and light, and their
        // contrast against the background (largest channel difference, 0–255).
        let gain = self.gain(camera, cond);
        let background = self.background(camera, cond);
        let mut rgb = background.rgb.clone();
        let mut contrast = vec![0u8; w * h];
        rgb.par_chunks_mut(w * 3)
            .zip(contrast.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (row, crow))| {
                for x in (0..w).filter(|x| ids[y * w + x] != 0) {
                    let k = y * w + x;
                    let c = self.pixel(camera, cond, x, y, depth[k], shade[k], true);
                    let out = tone(c * gain);
                    let bg = &row[3 * x..3 * x + 3];
                    crow[x] = (0..3).map(|j| out[j].abs_diff(bg[j])).max().unwrap_or(0);
                    row[3 * x..3 * x + 3].copy_from_slice(&out);
                }
            });
        // 4. Labels.
        let mut vis = vec![(u32::MAX, u32::MAX, 0u32, 0u32, 0u32); fish.len()];
        let mut contrast_sum = vec![0u64; fish.len()];
        for y in 0..h {
            for x in 0..w {
                let id = ids[y * w + x];
                if id != 0 {
                    contrast_sum[id as usize - 1] += contrast[y * w + x] as u64;
                    let v = &mut vis[id as usize - 1];
                    v.0 = v.0.min(x as u32);
                    v.1 = v.1.min(y as u32);
                    v.2 = v.2.max(x as u32 + 1);
                    v.3 = v.3.max(y as u32 + 1);
                    v.4 += 1;
                }
            }
        }
        let labels = locals
            .iter()
            .filter_map(|l| {
                let (mut bx0, mut by0, mut bx1, mut by1, mut n) = (u32::MAX, u32::MAX, 0, 0, 0u32);
                for yy in 0..l.h {
                    for xx in 0..l.w {
                        if l.depth[(yy * l.w + xx) as usize].is_finite() {
                            bx0 = bx0.min(l.x0 + xx);
                            by0 = by0.min(l.y0 + yy);
                            bx1 = bx1.max(l.x0 + xx + 1);
                            by1 = by1.max(l.y0 + yy + 1);
                            n += 1;
                        }
                    }
                }
                if n == 0 {
                    return None;
                }
                let v = vis[l.fish];
                let contrast = if v.4 > 0 {
                    contrast_sum[l.fish] as f32 / (255.0 * v.4 as f32)
                } else {
                    0.0
                };
                let contrast = (contrast * 1e4).round() / 1e4;
                Some(FishLabel {
                    fish: l.fish,
                    species: fish[l.fish].species,
                    box_visible: (v.4 > 0).then_some([v.0, v.1, v.2, v.3]),
                    box_full: [bx0, by0, bx1, by1],
                    visible_pixels: v.4,
                    full_pixels: n,
                    visibility: v.4 as f32 / n as f32,
                    truncated: l.truncated,
                    // Millimetres are plenty and keep the label files small.
                    box3d_world: l.box3d.map(|p| mm(p).to_array()),
                    box3d_camera: l.box3d.map(|p| mm(camera.to_camera(p)).to_array()),
                    distance: (l.distance * 1e3).round() / 1e3,
                    contrast,
                    detectable: v.4 > 0 && contrast >= self.config.min_contrast,
                })
            })
            .collect();
        Frame {
            width: camera.width,
            height: camera.height,
            rgb,
            ids,
            fish: labels,
            gain,
        }
    }

    /// Auto exposure: a white surface facing up at the camera's depth maps to
    /// `exposure`, but the gain stays within `exposure_stops` of its noon value.
    pub fn gain(&self, camera: &Camera, cond: &Conditions) -> f32 {
        let d = (-camera.position.y).max(0.0);
        let lum = |e: Vec3| (0.2126 * e.x + 0.7152 * e.y + 0.0722 * e.z) / std::f32::consts::PI;
        let now = lum(cond.light.horizontal_irradiance(&cond.water, d));
        let noon = lum(cond.noon.horizontal_irradiance(&cond.water, d)).max(1e-12);
        let cap = self.config.exposure / noon * 2f32.powf(self.config.exposure_stops);
        if now > 0.0 {
            (self.config.exposure / now).min(cap)
        } else {
            cap
        }
    }

    fn raster_fish(
        &self,
        i: usize,
        f: &FishPose,
        cam: &Camera,
        cond: &Conditions,
    ) -> Option<Local> {
        let mesh = &self.meshes[f.species as usize];
        let axes = fish_axes(f.heading, f.roll);
        let amp = if self.config.tail_beat {
            tail_beat_amplitude(f.speed / f.bl)
        } else {
            0.0
        };
        let light = &cond.light;
        let s = light.sun_dir_water;
        let n = mesh.positions.len();
        let mut verts: Vec<Option<RVert>> = Vec::with_capacity(n);
        let mut shades: Vec<Vec3> = Vec::with_capacity(n);
        let mut cam_pts: Vec<Vec3> = Vec::with_capacity(n);
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        let (mut bx0, mut by0, mut bx1, mut by1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
        let mut truncated = false;
        for v in 0..n {
            let local = mesh.bent(v, amp, f.tail_phase);
            lo = lo.min(local);
            hi = hi.max(local);
            let world = f.position + axes * (local * f.bl);
            let c = cam.to_camera(world);
            cam_pts.push(c);
            let nw = axes * mesh.normals[v];
            let (lam, sky) = if mesh.two_sided[v] {
                (0.6 * nw.dot(s).abs(), 0.75)
            } else {
                (
                    nw.dot(s).max(0.0),
                    0.5 + 0.5 * nw.y + 0.1 * (0.5 - 0.5 * nw.y),
                )
            };
            let shade =
                mesh.albedo[v] * (light.e_beam0 * lam + light.e_diff0 * sky) / std::f32::consts::PI;
            let p = cam.project_camera(c);
            match p {
                Some(p) => {
                    bx0 = bx0.min(p.x);
                    by0 = by0.min(p.y);
                    bx1 = bx1.max(p.x);
                    by1 = by1.max(p.y);
                    if !cam.in_view(p.x, p.y) {
                        truncated = true;
                    }
                }
                None => truncated = true,
            }
            shades.push(shade);
            verts.push(p.map(|p| RVert { p, shade }));
        }
        // Screen box, clipped to the image (and the fisheye circle's box).
        let pinhole_clip = matches!(cam.lens, Lens::Pinhole { .. })
            && cam_pts.iter().any(|c| c.z < NEAR)
            && cam_pts.iter().any(|c| c.z >= NEAR);
        // Triangles crossing a pinhole's near plane are clipped in camera
        // space first; their new vertices widen the screen box.
        let mut clipped: Vec<([RVert; 3], bool)> = Vec::new();
        if pinhole_clip {
            for (t, tri) in mesh.triangles.iter().enumerate() {
                let [a, b, c] = tri.map(|k| k as usize);
                if [a, b, c].iter().all(|&k| cam_pts[k].z >= NEAR) {
                    continue;
                }
                let poly = clip_near([a, b, c].map(|k| (cam_pts[k], shades[k])));
                let pv: Vec<RVert> = poly
                    .iter()
                    .filter_map(|(c, s)| cam.project_camera(*c).map(|p| RVert { p, shade: *s }))
                    .collect();
                for v in &pv {
                    bx0 = bx0.min(v.p.x);
                    by0 = by0.min(v.p.y);
                    bx1 = bx1.max(v.p.x);
                    by1 = by1.max(v.p.y);
                }
                for k in 1..pv.len().saturating_sub(1) {
                    clipped.push(([pv[0], pv[k], pv[k + 1]], t < mesh.first_fin));
                }
            }
        }
        if bx0 > bx1 {
            return None;
        }
        let clamp = |v: f32, hi: u32| (v.max(0.0).min(hi as f32) as u32).min(hi);
        let (ix0, iy0, ix1, iy1) = (
            clamp(bx0.floor(), cam.width),
            clamp(by0.floor(), cam.height),
            clamp(bx1.ceil() + 1.0, cam.width),
            clamp(by1.ceil() + 1.0, cam.height),
        );
        if ix0 >= ix1 || iy0 >= iy1 {
            return None;
        }
        let (w, h) = (ix1 - ix0, iy1 - iy0);
        let mut local = Local {
            fish: i,
            x0: ix0,
            y0: iy0,
            w,
            h,
            depth: vec![f32::INFINITY; (w * h) as usize],
            shade: vec![Vec3::ZERO; (w * h) as usize],
            truncated,
            box3d: [Vec3::ZERO; 8],
            distance: (f.position - cam.position).length(),
        };
        let circle = match cam.lens {
            Lens::Fisheye {
                f,
                cx,
                cy,
                theta_max,
                ..
            } => Some((cx, cy, (f * theta_max).powi(2))),
            Lens::Pinhole { .. } => None,
        };
        let fisheye = circle.is_some();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let cull = t < mesh.first_fin;
            let [a, b, c] = tri.map(|k| k as usize);
            let (Some(va), Some(vb), Some(vc)) = (verts[a], verts[b], verts[c]) else {
                continue;
            };
            raster_tri(&mut local, [va, vb, vc], cull, fisheye, circle);
        }
        for (tri, cull) in clipped {
            raster_tri(&mut local, tri, cull, false, circle);
        }
        // 3D box from the bent mesh's local bounds.
        let mut k = 0;
        for z in [lo.z, hi.z] {
            for y in [lo.y, hi.y] {
                for x in [lo.x, hi.x] {
                    local.box3d[k] = f.position + axes * (Vec3::new(x, y, z) * f.bl);
                    k += 1;
                }
            }
        }
        Some(local)
    }

    /// Radiance reaching pixel `(x, y)`.
    #[allow(clippy::too_many_arguments)]
    fn pixel(
        &self,
        cam: &Camera,
        cond: &Conditions,
        x: usize,
        y: usize,
        depth: f32,
        shade: Vec3,
        is_fish: bool,
    ) -> Vec3 {
        let Some((v, k)) = cam.ray(x as f32 + 0.5, y as f32 + 0.5) else {
            return Vec3::ZERO;
        };
        let (water, light) = (&cond.water, &cond.light);
        let o = cam.position;
        let d0 = (-o.y).max(0.0);
        if is_fish {
            let t = depth * k;
            let d = (-(o.y + v.y * t)).max(0.0);
            let l = shade * (-water.k * d).exp();
            return light.composite(water, l, d0, v, t);
        }
        // Leave the (convex) cage.
        let (mut t, mut face) = (f32::INFINITY, None);
        for fc in &self.faces {
            let nv = fc.normal.dot(v);
            if nv < -1e-6 {
                let tt = (fc.normal.dot(o) - fc.offset).max(0.0) / -nv;
                if tt < t {
                    t = tt;
                    face = Some(fc);
                }
            }
        }
        let Some(fc) = face else {
            return light.inscatter(water, d0, v, 1e3);
        };
        let hit = o + v * t;
        let dh = (-hit.y).max(0.0);
        let l = if fc.surface {
            self.surface_radiance(cond, v)
        } else {
            let (beam, diff) = light.at_depth(water, dh);
            let albedo = Vec3::from(self.config.net_albedo);
            let l_net = albedo * (0.4 * beam + diff) / std::f32::consts::PI;
            // Pixel footprint on the net (m): distance × angle per pixel / obliquity.
            let ang = match cam.lens {
                Lens::Pinhole { fx, .. } => 1.0 / fx,
                Lens::Fisheye { f, .. } => 1.0 / f,
            };
            let foot = t * k.max(1.0) * ang / fc.normal.dot(v).abs().max(0.15);
            let (u, w) = if fc.normal.y.abs() > 0.5 {
                (hit.x, hit.z)
            } else {
                (hit.x * -fc.normal.z + hit.z * fc.normal.x, hit.y)
            };
            let mesh = self.config.net_mesh;
            let twine = self.config.net_twine;
            let cu = line_coverage(u, foot, mesh, twine);
            let cw = line_coverage(w, foot, mesh, twine);
            let cov = 1.0 - (1.0 - cu) * (1.0 - cw);
            let beyond_len = if v.y > 1e-4 { dh / v.y } else { 1e3 };
            let beyond = light.inscatter(water, dh, v, beyond_len);
            l_net * cov + beyond * (1.0 - cov)
        };
        light.composite(water, l, d0, v, t)
    }

    /// What the underside of the (flat) surface sends down along `−v`:
    /// inside Snell's window the sky and a glare of the sun; outside it the
    /// water below, totally reflected.
    fn surface_radiance(&self, cond: &Conditions, v: Vec3) -> Vec3 {
        let (water, light) = (&cond.water, &cond.light);
        let sin_i = (1.0 - v.y * v.y).max(0.0).sqrt();
        let sin_t = sin_i * N_WATER;
        if sin_t >= 1.0 {
            let r = Vec3::new(v.x, -v.y, v.z);
            return light.inscatter(water, 0.0, r, 1e3);
        }
        let cos_t = (1.0 - sin_t * sin_t).sqrt();
        let horiz = Vec3::new(v.x, 0.0, v.z).normalize_or(Vec3::X);
        let air = horiz * sin_t + Vec3::Y * cos_t;
        let ti = 1.0 - fresnel_air_water(sin_t.asin());
        // A wavy surface spreads the sun into a glare lobe of ≈ 0.06 sr.
        let sigma2 = 0.02;
        let cosg = air.dot(light.sun_dir_air);
        let glare = if light.sun_elevation_deg > 0.0 {
            light.sun_colour * ((cosg - 1.0) / sigma2).exp() / (std::f32::consts::PI * sigma2)
        } else {
            Vec3::ZERO
        };
        // Radiance is multiplied by n² entering the denser medium.
        (light.sky_radiance + glare) * ti * N_WATER * N_WATER
    }
}

/// A point rounded to whole millimetres.
fn mm(p: Vec3) -> Vec3 {
    (p * 1e3).round() / 1e3
}

/// Share of a footprint `[x − f/2, x + f/2]` covered by twines of width `w`
/// every `s` metres: the box-filtered square wave, in closed form, so far
/// nets fade to their mean coverage `w/s` instead of aliasing.
fn line_coverage(x: f32, f: f32, s: f32, w: f32) -> f32 {
    let cum = |x: f32| {
        let k = (x / s).floor();
        k * w + (x - k * s).min(w)
    };
    let f = f.max(1e-6);
    ((cum(x + f / 2.0) - cum(x - f / 2.0)) / f).clamp(0.0, 1.0)
}

/// Tone curve `1 − exp(−x)` and sRGB encoding.
fn tone(c: Vec3) -> [u8; 3] {
    let enc = |x: f32| {
        let y = 1.0 - (-x.max(0.0)).exp();
        let s = if y <= 0.0031308 {
            12.92 * y
        } else {
            1.055 * y.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0 + 0.5).clamp(0.0, 255.0) as u8
    };
    [enc(c.x), enc(c.y), enc(c.z)]
}

/// Clip a camera-space triangle (with shades) against `z ≥ NEAR`.
fn clip_near(tri: [(Vec3, Vec3); 3]) -> Vec<(Vec3, Vec3)> {
    let mut out = Vec::with_capacity(4);
    for i in 0..3 {
        let (a, sa) = tri[i];
        let (b, sb) = tri[(i + 1) % 3];
        let (ina, inb) = (a.z >= NEAR, b.z >= NEAR);
        if ina {
            out.push((a, sa));
        }
        if ina != inb {
            let t = (NEAR - a.z) / (b.z - a.z);
            out.push((a.lerp(b, t), sa.lerp(sb, t)));
        }
    }
    out
}

/// Rasterise one triangle into a fish's own buffer. Pixel centres inside (or
/// on an edge of) the triangle are covered. `cull`: drop back faces.
fn raster_tri(
    l: &mut Local,
    v: [RVert; 3],
    cull: bool,
    linear_depth: bool,
    circle: Option<(f32, f32, f32)>,
) {
    let [a, b, c] = v;
    let area = (b.p.x - a.p.x) * (c.p.y - a.p.y) - (b.p.y - a.p.y) * (c.p.x - a.p.x);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    // Mesh triangles wind counter-clockwise seen from outside; with the
    // image's y pointing down, front faces have negative area.
    if cull && area > 0.0 {
        return;
    }
    let x0 = a.p.x.min(b.p.x).min(c.p.x).floor().max(l.x0 as f32) as i64;
    let y0 = a.p.y.min(b.p.y).min(c.p.y).floor().max(l.y0 as f32) as i64;
    let x1 = (a.p.x.max(b.p.x).max(c.p.x).ceil() as i64).min((l.x0 + l.w) as i64 - 1);
    let y1 = (a.p.y.max(b.p.y).max(c.p.y).ceil() as i64).min((l.y0 + l.h) as i64 - 1);
    if x0 > x1 || y0 > y1 {
        return;
    }
    let inv = 1.0 / area;
    // Depth attribute: 1/z for a pinhole (perspective-correct), distance for a fisheye.
    let q = |p: Vec3| if linear_depth { p.z } else { 1.0 / p.z };
    let (qa, qb, qc) = (q(a.p), q(b.p), q(c.p));
    for y in y0..=y1 {
        let py = y as f32 + 0.5;
        for x in x0..=x1 {
            let px = x as f32 + 0.5;
            let w0 = ((b.p.x - px) * (c.p.y - py) - (b.p.y - py) * (c.p.x - px)) * inv;
            let w1 = ((c.p.x - px) * (a.p.y - py) - (c.p.y - py) * (a.p.x - px)) * inv;
            let w2 = 1.0 - w0 - w1;
            if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                continue;
            }
            if let Some((cx, cy, r2)) = circle
                && (px - cx).powi(2) + (py - cy).powi(2) > r2
            {
                continue;
            }
            let qv = w0 * qa + w1 * qb + w2 * qc;
            let d = if linear_depth { qv } else { 1.0 / qv };
            let k = ((y as u32 - l.y0) * l.w + (x as u32 - l.x0)) as usize;
            if d < l.depth[k] {
                l.depth[k] = d;
                // Perspective-correct shade for a pinhole.
                l.shade[k] = if linear_depth {
                    a.shade * w0 + b.shade * w1 + c.shade * w2
                } else {
                    (a.shade * (w0 * qa) + b.shade * (w1 * qb) + c.shade * (w2 * qc)) * d
                };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::FishStyle;
    use crate::optics::WaterParams;
    use deepfoids_env::sun::SunPlace;

    /// Back faces are culled, not front faces: a fish seen side-on 2 m away
    /// shows its near flank, at z = 2 − half its width.
    #[test]
    fn culling_keeps_the_near_surface() {
        let style = FishStyle::for_species("coho", [0.12, 0.25, 1.0], [0.4, 0.5, 0.6]);
        let r = Renderer::new(
            RenderConfig::default(),
            vec![FishMesh::standard(&style)],
            vec![],
        );
        let cam = Camera::pinhole(
            Vec3::ZERO - Vec3::Y * 2.0,
            -Vec3::Z,
            Vec3::Y,
            60.0,
            200,
            200,
        );
        let place = SunPlace {
            latitude_deg: 38.0,
            longitude_deg: 141.0,
            utc_offset_hours: 9.0,
        };
        let light = Light::new(place, 2021, 3, 15, 11.5);
        let cond = Conditions {
            light,
            noon: light,
            water: Water::new(WaterParams::default(), true),
        };
        let f = FishPose {
            position: Vec3::new(0.0, -2.0, -2.0),
            heading: Vec3::X,
            roll: 0.0,
            bl: 1.0,
            speed: 0.0,
            species: 0,
            tail_phase: 0.0,
        };
        let l = r.raster_fish(0, &f, &cam, &cond).unwrap();
        let (cx, cy) = (100 - l.x0, 100 - l.y0);
        let z = l.depth[(cy * l.w + cx) as usize];
        let half = style.width / 2.0;
        assert!((z - (2.0 - half)).abs() < 0.01, "z {z}, half width {half}");
    }
}
