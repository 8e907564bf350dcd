//! The CPU renderer: a triangle rasteriser with a z-buffer and an id-buffer,
//! then a per-pixel pass that puts the water between the camera and whatever
//! each pixel sees.
//!
//! 1. Per fish (rayon over fish): transform its species' mesh (tail beat,
//!    body length, pose), shade the vertices (Lambert from the refracted sun
//!    plus the sky's diffuse light), project them, and rasterise the fish
//!    alone into a small buffer over its screen box (per pixel its depth and
//!    the triangle that drew it; wide triangles only along each row's span).
//!    That buffer is the fish's unoccluded silhouette: its full 2D box, its
//!    pixel count, and whether it is cut by the image border.
//! 2. Per band of rows (rayon over bands): merge the fish buffers with a
//!    depth test into the frame's owner buffer (which fish each pixel sees).
//! 3. Per row: cast each pixel's ray. A fish pixel's radiance is its shade,
//!    interpolated from its triangle's vertices, times `exp(−K·depth)`; any
//!    other ray leaves the cage through a net wall, the net bottom or the
//!    surface (Snell's window, total internal reflection outside it). Then
//!    `L·exp(−c·t) + in-scatter` (see [`crate::optics`]), auto exposure, tone
//!    curve, sRGB. What every pixel shows without fish (the background)
//!    depends only on the camera and the conditions, so it is computed once
//!    for them and kept ([`Renderer::background`]) with each pixel's ray and
//!    in-scattering source: a clip's frames share it while its light does not
//!    change (`ClipSetup::conditions` holds the light for
//!    [`crate::setup::LIGHT_STEP_SECONDS`]). Only fish pixels are shaded per
//!    frame; the largest channel difference between a fish pixel and the
//!    background there is the pixel's contrast.
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
use crate::optics::{Light, N_WATER, Water, fresnel_air_water, inscatter_along};
use glam::{Mat3, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::{Arc, Mutex, OnceLock};

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
/// of conditions, and each pixel's ray as fish pixels need it.
#[derive(Debug)]
pub struct Background {
    camera: Camera,
    cond: Conditions,
    /// 3 bytes per pixel, row-major.
    pub rgb: Vec<u8>,
    /// Per pixel, row-major; `None` outside a fisheye's circle.
    rays: Vec<Option<PixelRay>>,
}

/// What shading a fish pixel needs of the pixel's ray; it depends on the
/// camera and the conditions alone, so it is kept with the background.
#[derive(Clone, Copy, Debug)]
struct PixelRay {
    /// Vertical component of the unit ray.
    vy: f32,
    /// Distance along the ray per unit of depth-buffer value.
    k: f32,
    /// In-scattering source at the camera, [`Light::source`].
    j0: Vec3,
    /// `c − K·v_y`, the exponent of [`inscatter_along`].
    x: Vec3,
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
    /// Per pixel, the triangle that drew it ([`Local::triangle`]); its shade
    /// is interpolated only where the fish is seen (step 3).
    tri: Vec<u16>,
    /// The projected vertices (`None`: behind the camera or out of the lens).
    verts: Vec<Option<RVert>>,
    /// The mesh's triangles, then those clipped at a pinhole's near plane.
    mesh_tris: usize,
    clipped: Vec<[RVert; 3]>,
    fisheye: bool,
    truncated: bool,
    box3d: [Vec3; 8],
    distance: f32,
}

impl Local {
    /// Triangle `t` as [`raster_tri`] drew it (`mesh` is the fish's).
    fn triangle(&self, mesh: &FishMesh, t: u16) -> Sampler {
        let t = t as usize;
        let (v, linear) = match t.checked_sub(self.mesh_tris) {
            None => (
                mesh.triangles[t].map(|k| self.verts[k as usize].expect("drawn, so projected")),
                self.fisheye,
            ),
            Some(c) => (self.clipped[c], false),
        };
        Sampler::new(v, linear)
    }
}

/// A triangle set up for sampling at pixel centres: vertices, one over its
/// signed area, and the depth attribute at each vertex (1/z for a pinhole,
/// perspective-correct; the distance for a fisheye, `linear`).
struct Sampler {
    v: [RVert; 3],
    area: f32,
    inv: f32,
    q: [f32; 3],
    linear: bool,
}

impl Sampler {
    fn new(v: [RVert; 3], linear: bool) -> Self {
        let [a, b, c] = v.map(|v| v.p);
        let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        let q = v.map(|v| if linear { v.p.z } else { 1.0 / v.p.z });
        Self {
            v,
            area,
            inv: 1.0 / area,
            q,
            linear,
        }
    }

    /// Depth at the point with barycentric weights `w`.
    #[inline]
    fn depth(&self, (w0, w1, w2): (f32, f32, f32)) -> f32 {
        let qv = w0 * self.q[0] + w1 * self.q[1] + w2 * self.q[2];
        if self.linear { qv } else { 1.0 / qv }
    }

    /// Shade at the point with weights `w` and depth `d`.
    fn shade(&self, (w0, w1, w2): (f32, f32, f32), d: f32) -> Vec3 {
        let [a, b, c] = self.v;
        if self.linear {
            a.shade * w0 + b.shade * w1 + c.shade * w2
        } else {
            (a.shade * (w0 * self.q[0]) + b.shade * (w1 * self.q[1]) + c.shade * (w2 * self.q[2]))
                * d
        }
    }

    /// Shade at pixel `(x, y)`, which the triangle covers.
    fn shade_at(&self, x: usize, y: usize) -> Vec3 {
        let w = barycentric(&self.v, self.inv, x as f32 + 0.5, y as f32 + 0.5)
            .expect("the pixel was drawn by this triangle");
        self.shade(w, self.depth(w))
    }
}

/// A vertex ready for rasterising.
#[derive(Clone, Copy)]
struct RVert {
    /// Screen x, y and depth.
    p: Vec3,
    shade: Vec3,
}

/// The shaded frame before labelling.
struct Shaded {
    rgb: Vec<u8>,
    /// Instance mask: 0 = no fish, `fish + 1` otherwise.
    ids: Vec<u16>,
    /// Per pixel, the fish's contrast against the background (0–255).
    contrast: Vec<u8>,
}

/// What the id buffer shows of one fish.
#[derive(Clone, Copy)]
struct Visible {
    /// `[x0, y0, x1, y1]`, exclusive ends.
    bbox: [u32; 4],
    pixels: u32,
    contrast_sum: u64,
}

impl Visible {
    const NONE: Self = Self {
        bbox: [u32::MAX, u32::MAX, 0, 0],
        pixels: 0,
        contrast_sum: 0,
    };

    fn add(&mut self, x: u32, y: u32, contrast: u8) {
        self.join(&Self {
            bbox: [x, y, x + 1, y + 1],
            pixels: 1,
            contrast_sum: contrast as u64,
        });
    }

    fn join(&mut self, o: &Self) {
        let b = &mut self.bbox;
        b[0] = b[0].min(o.bbox[0]);
        b[1] = b[1].min(o.bbox[1]);
        b[2] = b[2].max(o.bbox[2]);
        b[3] = b[3].max(o.bbox[3]);
        self.pixels += o.pixels;
        self.contrast_sum += o.contrast_sum;
    }
}

/// Step 2: which fish each pixel of a `w × h` frame sees, as an index into
/// `locals` plus one (0 = none): the nearest of the fish buffers covering it
/// (the first in `locals` on a tie). Bands of rows in parallel, each with its
/// own small depth buffer.
fn merge(locals: &[Local], w: usize, h: usize) -> Vec<u32> {
    const BAND: usize = 16;
    let mut owner = vec![0u32; w * h];
    owner
        .par_chunks_mut(BAND * w)
        .enumerate()
        .for_each(|(band, own)| {
            let mut dep = vec![f32::INFINITY; own.len()];
            let y_lo = band * BAND;
            let y_hi = y_lo + own.len() / w;
            for (i, l) in locals.iter().enumerate() {
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
                            own[grow + x] = i as u32 + 1;
                        }
                    }
                }
            }
        });
    owner
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
        let mut rays = vec![None; w * camera.height as usize];
        rgb.par_chunks_mut(w * 3)
            .zip(rays.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (row, ray_row))| {
                for x in 0..w {
                    let c = self.pixel(camera, cond, x, y);
                    row[3 * x..3 * x + 3].copy_from_slice(&tone(c * gain));
                    ray_row[x] = pixel_ray(camera, cond, x, y);
                }
            });
        let b = Arc::new(Background {
            camera: *camera,
            cond: *cond,
            rgb,
            rays,
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
        // 1. Each fish alone.
        let locals: Vec<Local> = fish
            .par_iter()
            .enumerate()
            .with_min_len(8)
            .filter_map(|(i, f)| self.raster_fish(i, f, camera, cond))
            .collect();
        // 2. Which fish each pixel sees.
        let owner = merge(&locals, camera.width as usize, camera.height as usize);
        // 3. The fish pixels over the background.
        let gain = self.gain(camera, cond);
        let shaded = self.shade_fish(fish, &locals, &owner, camera, cond, gain);
        // 4. Labels.
        let fish = self.labels(fish, &locals, &shaded, camera);
        Frame {
            width: camera.width,
            height: camera.height,
            rgb: shaded.rgb,
            ids: shaded.ids,
            fish,
            gain,
        }
    }

    /// Step 3: the background, then each fish pixel's water and light, and
    /// its contrast against the background (largest channel difference,
    /// 0–255); rows in parallel.
    fn shade_fish(
        &self,
        fish: &[FishPose],
        locals: &[Local],
        owner: &[u32],
        camera: &Camera,
        cond: &Conditions,
        gain: f32,
    ) -> Shaded {
        let w = camera.width as usize;
        let background = self.background(camera, cond);
        let cam_dim = (-cond.water.k * (-camera.position.y).max(0.0)).exp();
        let mut rgb = background.rgb.clone();
        let mut ids = vec![0u16; owner.len()];
        let mut contrast = vec![0u8; owner.len()];
        rgb.par_chunks_mut(w * 3)
            .zip(ids.par_chunks_mut(w))
            .zip(contrast.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, ((row, id_row), crow))| {
                // Neighbouring pixels mostly share a triangle: keep its set-up.
                let mut last: Option<(u32, u16, Sampler)> = None;
                for x in 0..w {
                    let k = y * w + x;
                    let o = owner[k];
                    let Some(l) = o.checked_sub(1).map(|o| &locals[o as usize]) else {
                        continue;
                    };
                    id_row[x] = (l.fish + 1) as u16;
                    let lk = (y - l.y0 as usize) * l.w as usize + x - l.x0 as usize;
                    let t = l.tri[lk];
                    let c = background.rays[k].map_or(Vec3::ZERO, |ray| {
                        if !matches!(&last, Some((lo, lt, _)) if *lo == o && *lt == t) {
                            let mesh = &self.meshes[fish[l.fish].species as usize];
                            last = Some((o, t, l.triangle(mesh, t)));
                        }
                        let sampler = &last.as_ref().expect("set above").2;
                        let shade = sampler.shade_at(x, y);
                        fish_radiance(camera, cond, cam_dim, &ray, l.depth[lk], shade)
                    });
                    let out = tone(c * gain);
                    let bg = &row[3 * x..3 * x + 3];
                    crow[x] = (0..3).map(|j| out[j].abs_diff(bg[j])).max().unwrap_or(0);
                    row[3 * x..3 * x + 3].copy_from_slice(&out);
                }
            });
        Shaded { rgb, ids, contrast }
    }

    /// Step 4: each fish's visible box, pixels and mean contrast from the id
    /// buffer (bands of rows in parallel), then its label.
    fn labels(
        &self,
        fish: &[FishPose],
        locals: &[Local],
        shaded: &Shaded,
        camera: &Camera,
    ) -> Vec<FishLabel> {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let bands = 2 * rayon::current_num_threads();
        let rows = h.div_ceil(bands);
        let vis = (0..bands)
            .into_par_iter()
            .map(|b| {
                let mut vis = vec![Visible::NONE; fish.len()];
                for y in (b * rows).min(h)..((b + 1) * rows).min(h) {
                    for x in 0..w {
                        let id = shaded.ids[y * w + x];
                        if id != 0 {
                            vis[id as usize - 1].add(
                                x as u32,
                                y as u32,
                                shaded.contrast[y * w + x],
                            );
                        }
                    }
                }
                vis
            })
            .reduce(
                || vec![Visible::NONE; fish.len()],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(a, b)| a.join(b));
                    a
                },
            );
        locals
            .par_iter()
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
                let contrast = if v.pixels > 0 {
                    v.contrast_sum as f32 / (255.0 * v.pixels as f32)
                } else {
                    0.0
                };
                let contrast = (contrast * 1e4).round() / 1e4;
                Some(FishLabel {
                    fish: l.fish,
                    species: fish[l.fish].species,
                    box_visible: (v.pixels > 0).then_some(v.bbox),
                    box_full: [bx0, by0, bx1, by1],
                    visible_pixels: v.pixels,
                    full_pixels: n,
                    visibility: v.pixels as f32 / n as f32,
                    truncated: l.truncated,
                    // Millimetres are plenty and keep the label files small.
                    box3d_world: l.box3d.map(|p| mm(p).to_array()),
                    box3d_camera: l.box3d.map(|p| mm(camera.to_camera(p)).to_array()),
                    distance: (l.distance * 1e3).round() / 1e3,
                    contrast,
                    detectable: v.pixels > 0 && contrast >= self.config.min_contrast,
                })
            })
            .collect()
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
        let (clipped, clipped_cull) = if pinhole_clip {
            let (clipped, cull) = clip_near_triangles(mesh, cam, &cam_pts, &shades);
            for v in clipped.iter().flatten() {
                bx0 = bx0.min(v.p.x);
                by0 = by0.min(v.p.y);
                bx1 = bx1.max(v.p.x);
                by1 = by1.max(v.p.y);
            }
            (clipped, cull)
        } else {
            (Vec::new(), Vec::new())
        };
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
            tri: vec![0; (w * h) as usize],
            verts,
            mesh_tris: mesh.triangles.len(),
            clipped,
            fisheye: false,
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
        local.fisheye = circle.is_some();
        // Triangle ids are u16: the mesh and its clipped pieces must fit.
        debug_assert!(local.mesh_tris + local.clipped.len() <= u16::MAX as usize);
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let cull = t < mesh.first_fin;
            let [a, b, c] = tri.map(|k| k as usize);
            let (Some(va), Some(vb), Some(vc)) = (local.verts[a], local.verts[b], local.verts[c])
            else {
                continue;
            };
            let sampler = Sampler::new([va, vb, vc], local.fisheye);
            raster_tri(&mut local, &sampler, t as u16, cull, circle);
        }
        for (c, cull) in clipped_cull.into_iter().enumerate() {
            let (sampler, t) = (Sampler::new(local.clipped[c], false), local.mesh_tris + c);
            raster_tri(&mut local, &sampler, t as u16, cull, circle);
        }
        // 3D box from the bent mesh's local bounds.
        for (k, corner) in local.box3d.iter_mut().enumerate() {
            let pick = |bit: usize, lo: f32, hi: f32| if k >> bit & 1 == 0 { lo } else { hi };
            let v = Vec3::new(
                pick(0, lo.x, hi.x),
                pick(1, lo.y, hi.y),
                pick(2, lo.z, hi.z),
            );
            *corner = f.position + axes * (v * f.bl);
        }
        Some(local)
    }

    /// Radiance reaching pixel `(x, y)` when no fish is in the way: the ray
    /// leaves the (convex) cage through the net or the surface.
    fn pixel(&self, cam: &Camera, cond: &Conditions, x: usize, y: usize) -> Vec3 {
        let Some((v, k)) = cam.ray(x as f32 + 0.5, y as f32 + 0.5) else {
            return Vec3::ZERO;
        };
        let (water, light) = (&cond.water, &cond.light);
        let o = cam.position;
        let d0 = (-o.y).max(0.0);
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

/// The ray of pixel `(x, y)` as [`fish_radiance`] needs it.
fn pixel_ray(cam: &Camera, cond: &Conditions, x: usize, y: usize) -> Option<PixelRay> {
    let (v, k) = cam.ray(x as f32 + 0.5, y as f32 + 0.5)?;
    let (water, light) = (&cond.water, &cond.light);
    let d0 = (-cam.position.y).max(0.0);
    Some(PixelRay {
        vy: v.y,
        k,
        j0: light.source(water, d0, v),
        x: water.c - water.k * v.y,
    })
}

/// Radiance reaching the camera from a fish surface of shade `shade` at
/// depth-buffer value `depth` along `ray`: the surface's light is dimmed by
/// `exp(−K·d)` at its depth `d`, then [`Light::composite`] puts the water
/// between it and the camera (transmittance `exp(−c·t)` and the in-scattering
/// `j0·(1 − exp(−x·t))/x`, [`inscatter_along`]).
///
/// With the camera at depth `d0` under the surface and the fish below it,
/// `d = d0 − v_y·t`, so `exp(−K·d)·exp(−c·t) = exp(−K·d0)·exp(−x·t)` with the
/// ray's `x = c − K·v_y`: one exponential per channel serves all three terms
/// (`cam_dim = exp(−K·d0)` is the camera's). Otherwise (a camera or a fish
/// part above the surface) the terms are computed one by one.
fn fish_radiance(
    cam: &Camera,
    cond: &Conditions,
    cam_dim: Vec3,
    ray: &PixelRay,
    depth: f32,
    shade: Vec3,
) -> Vec3 {
    let t = depth * ray.k;
    let d = -(cam.position.y + ray.vy * t);
    if cam.position.y > 0.0 || d < 0.0 {
        return fish_radiance_by_terms(cond, ray, t, d, shade);
    }
    let e = (-ray.x * t).exp();
    let lit = shade * cam_dim * e;
    if !cond.water.scattering {
        return lit;
    }
    let along = |x: f32, e: f32| if x.abs() < 1e-5 { t } else { (1.0 - e) / x };
    lit + ray.j0
        * Vec3::new(
            along(ray.x.x, e.x),
            along(ray.x.y, e.y),
            along(ray.x.z, e.z),
        )
}

/// [`fish_radiance`] term by term, `t` metres along the ray at depth `d`
/// (negative above the surface, where the light is not dimmed): `exp(−K·d)`,
/// the transmittance and the in-scattering each with their own exponentials.
fn fish_radiance_by_terms(cond: &Conditions, ray: &PixelRay, t: f32, d: f32, shade: Vec3) -> Vec3 {
    let water = &cond.water;
    let l = shade * (-water.k * d.max(0.0)).exp();
    let scattered = if water.scattering {
        inscatter_along(ray.j0, ray.x, t)
    } else {
        Vec3::ZERO
    };
    l * water.transmittance(t) + scattered
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

/// Tone curve `1 − exp(−x)` and sRGB encoding of one channel.
fn encode_channel(x: f32) -> u8 {
    let y = 1.0 - (-x.max(0.0)).exp();
    let s = if y <= 0.0031308 {
        12.92 * y
    } else {
        1.055 * y.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5).clamp(0.0, 255.0) as u8
}

/// The smallest input of each output level 1..=255 of [`encode_channel`],
/// found once by bisection over the floats' bit patterns (non-negative floats
/// order as their bits, and the curve never falls).
fn tone_thresholds() -> &'static [f32; 255] {
    static T: OnceLock<[f32; 255]> = OnceLock::new();
    T.get_or_init(|| {
        std::array::from_fn(|i| {
            let level = i as u8 + 1;
            let (mut lo, mut hi) = (0u32, f32::MAX.to_bits());
            while hi - lo > 1 {
                let mid = lo + (hi - lo) / 2;
                if encode_channel(f32::from_bits(mid)) >= level {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            f32::from_bits(hi)
        })
    })
}

/// Bits of a float dropped to index [`tone_start`]'s buckets: 8 mantissa
/// bits are left, so a bucket spans under 0.4 % of its value and the curve
/// rises by at most one level across one.
const TONE_BUCKET_SHIFT: u32 = 15;

/// Per bucket of non-negative floats (their bits shifted right by
/// [`TONE_BUCKET_SHIFT`], up to infinity's), the output level at the
/// bucket's smallest float: how many thresholds lie at or below it.
fn tone_start() -> &'static [u8] {
    static S: OnceLock<Vec<u8>> = OnceLock::new();
    S.get_or_init(|| {
        let t = tone_thresholds();
        (0..=f32::INFINITY.to_bits() >> TONE_BUCKET_SHIFT)
            .map(|i| {
                let x = f32::from_bits(i << TONE_BUCKET_SHIFT);
                t.partition_point(|&th| th <= x) as u8
            })
            .collect()
    })
}

/// Tone curve and sRGB encoding ([`encode_channel`]) by table: the level at
/// the start of the input's bucket ([`tone_start`]), then up past each
/// threshold ([`tone_thresholds`]) at or below the input — one lookup and a
/// comparison or two per channel instead of an `exp` and a `powf`, with the
/// same bytes. NaN and negative inputs give 0, as the curve does.
fn tone(c: Vec3) -> [u8; 3] {
    let (t, start) = (tone_thresholds(), tone_start());
    let enc = |x: f32| {
        let b = x.to_bits();
        if b >= f32::INFINITY.to_bits() {
            // Infinity; NaN and negative floats (sign bit set) sort above it.
            return if x == f32::INFINITY { 255 } else { 0 };
        }
        let mut level = start[(b >> TONE_BUCKET_SHIFT) as usize];
        while level < 255 && x >= t[level as usize] {
            level += 1;
        }
        level
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

/// Barycentric weights of pixel centre `(px, py)` in triangle `v` (`inv` is
/// one over its signed area), or `None` when the centre lies outside. The
/// one coverage test: [`raster_tri`] and [`RowSpan`] are exact against it.
#[inline]
fn barycentric(v: &[RVert; 3], inv: f32, px: f32, py: f32) -> Option<(f32, f32, f32)> {
    let [a, b, c] = v.map(|v| v.p);
    let w0 = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) * inv;
    let w1 = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) * inv;
    let w2 = 1.0 - w0 - w1;
    (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0).then_some((w0, w1, w2))
}

/// The pixels of a row that can pass [`barycentric`]: along a row each
/// weight is affine in `px`, so the centres inside form an interval. It is
/// found in f64 with a tolerance that bounds the f32 rounding of the weights
/// (a few ulps of the products' magnitude), widened by a pixel each side:
/// every centre outside it fails the f32 test too, so scanning the span
/// covers exactly the pixels that scanning the whole box would.
struct RowSpan {
    /// Vertices (f64).
    v: [[f64; 2]; 3],
    inv: f64,
    /// Bound on the f32 error of `w0`, `w1`; of `w2`.
    tol01: f64,
    tol2: f64,
}

impl RowSpan {
    fn new(v: &[RVert; 3], inv: f32, x0: i64, x1: i64, y0: i64, y1: i64) -> Self {
        let u = f32::EPSILON as f64 / 2.0;
        // Largest distances between a vertex and a pixel centre of the box.
        let (mut mx, mut my) = (0f64, 0f64);
        for p in v.iter().map(|v| v.p) {
            let (x, y) = (p.x as f64, p.y as f64);
            mx = mx
                .max((x - (x0 as f64 + 0.5)).abs())
                .max((x - (x1 as f64 + 0.5)).abs());
            my = my
                .max((y - (y0 as f64 + 0.5)).abs())
                .max((y - (y1 as f64 + 0.5)).abs());
        }
        let inv = inv as f64;
        // Each product ≤ mx·my; two products, their difference and the
        // scaling by `inv` round at most 4 times: 16u·mx·my·|inv| is ample.
        let tol01 = 16.0 * u * mx * my * inv.abs() + 4.0 * u;
        // w2 = 1 − w0 − w1 adds both errors and two roundings of |w| ≤ 2·mx·my·|inv| + 1.
        let tol2 = 2.0 * tol01 + 8.0 * u * (1.0 + 4.0 * mx * my * inv.abs());
        Self {
            v: v.map(|v| [v.p.x as f64, v.p.y as f64]),
            inv,
            tol01,
            tol2,
        }
    }

    /// Columns `[lo, hi]` of row `y` (pixel centre `y + 0.5`) within
    /// `[x0, x1]` that may be covered; empty when `lo > hi`.
    fn columns(&self, y: i64, x0: i64, x1: i64) -> (i64, i64) {
        let [a, b, c] = self.v;
        let py = y as f64 + 0.5;
        let w = |px: f64| {
            let w0 = ((b[0] - px) * (c[1] - py) - (b[1] - py) * (c[0] - px)) * self.inv;
            let w1 = ((c[0] - px) * (a[1] - py) - (c[1] - py) * (a[0] - px)) * self.inv;
            [w0, w1, 1.0 - w0 - w1]
        };
        let (pl, pr) = (x0 as f64 + 0.5, x1 as f64 + 0.5);
        let (wl, wr) = (w(pl), w(pr));
        let (mut lo, mut hi) = (pl, pr);
        for j in 0..3 {
            let tol = if j == 2 { self.tol2 } else { self.tol01 };
            // w_j + tol ≥ 0 on [lo, hi], an affine function of px.
            let (fl, fr) = (wl[j] + tol, wr[j] + tol);
            if fl < 0.0 && fr < 0.0 {
                return (1, 0);
            }
            if fl >= 0.0 && fr >= 0.0 {
                continue;
            }
            let cross = pl + (pr - pl) * fl / (fl - fr);
            if fl < 0.0 {
                lo = lo.max(cross);
            } else {
                hi = hi.min(cross);
            }
        }
        if lo > hi {
            return (1, 0);
        }
        // Centres px = x + 0.5 in [lo, hi], a pixel more each side.
        let first = ((lo - 0.5).ceil() as i64 - 1).max(x0);
        let last = ((hi - 0.5).floor() as i64 + 1).min(x1);
        (first, last)
    }
}

/// The triangles of `mesh` that cross a pinhole camera's near plane, clipped
/// in camera space (`cam_pts`, with the vertices' `shades`) and projected:
/// fans of the clipped polygons, each with whether it is back-face culled
/// (a body triangle, not a fin).
fn clip_near_triangles(
    mesh: &FishMesh,
    cam: &Camera,
    cam_pts: &[Vec3],
    shades: &[Vec3],
) -> (Vec<[RVert; 3]>, Vec<bool>) {
    let (mut clipped, mut cull) = (Vec::new(), Vec::new());
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
        for k in 1..pv.len().saturating_sub(1) {
            clipped.push([pv[0], pv[k], pv[k + 1]]);
            cull.push(t < mesh.first_fin);
        }
    }
    (clipped, cull)
}

/// Rasterise triangle `t` into a fish's own buffer: its depth and, per
/// pixel, the triangle's id. Pixel centres inside (or on an edge of) the
/// triangle are covered. `cull`: drop back faces.
fn raster_tri(l: &mut Local, s: &Sampler, t: u16, cull: bool, circle: Option<(f32, f32, f32)>) {
    let [a, b, c] = s.v.map(|v| v.p);
    if s.area == 0.0 || !s.area.is_finite() {
        return;
    }
    // Mesh triangles wind counter-clockwise seen from outside; with the
    // image's y pointing down, front faces have negative area.
    if cull && s.area > 0.0 {
        return;
    }
    let x0 = a.x.min(b.x).min(c.x).floor().max(l.x0 as f32) as i64;
    let y0 = a.y.min(b.y).min(c.y).floor().max(l.y0 as f32) as i64;
    let x1 = (a.x.max(b.x).max(c.x).ceil() as i64).min((l.x0 + l.w) as i64 - 1);
    let y1 = (a.y.max(b.y).max(c.y).ceil() as i64).min((l.y0 + l.h) as i64 - 1);
    if x0 > x1 || y0 > y1 {
        return;
    }
    // Small boxes are scanned whole; wider ones only along each row's span.
    let span = (x1 - x0 >= 4).then(|| RowSpan::new(&s.v, s.inv, x0, x1, y0, y1));
    for y in y0..=y1 {
        let py = y as f32 + 0.5;
        let (xs, xe) = span.as_ref().map_or((x0, x1), |sp| sp.columns(y, x0, x1));
        for x in xs..=xe {
            let px = x as f32 + 0.5;
            let Some(w) = barycentric(&s.v, s.inv, px, py) else {
                continue;
            };
            if let Some((cx, cy, r2)) = circle
                && (px - cx).powi(2) + (py - cy).powi(2) > r2
            {
                continue;
            }
            let d = s.depth(w);
            let k = ((y as u32 - l.y0) * l.w + (x as u32 - l.x0)) as usize;
            if d < l.depth[k] {
                l.depth[k] = d;
                l.tri[k] = t;
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

    /// One exponential per channel gives the radiance the three terms give
    /// (relative 1e-5), for clear and murky water, near and far fish, rays up,
    /// down and level, with and without scattering; a fish part above the
    /// surface falls back to the terms.
    #[test]
    fn one_exponential_is_the_three_terms() {
        let place = SunPlace {
            latitude_deg: 38.0,
            longitude_deg: 141.0,
            utc_offset_hours: 9.0,
        };
        let light = Light::new(place, 2021, 6, 15, 9.0);
        let cam = Camera::fisheye(Vec3::new(0.0, -6.0, 0.0), Vec3::Y, Vec3::Z, 235.0, 64, 64);
        let mut checked = 0;
        for (params, scattering) in [
            (WaterParams::default(), true),
            (WaterParams::default(), false),
            (
                WaterParams {
                    chlorophyll: 9.0,
                    sediment: 5.0,
                    small_particles: 4.0,
                    large_particles: 4.0,
                },
                true,
            ),
        ] {
            let cond = Conditions {
                light,
                noon: light,
                water: Water::new(params, scattering),
            };
            let cam_dim = (-cond.water.k * 6.0).exp();
            for (x, y) in [(32, 32), (5, 30), (32, 2), (50, 50), (20, 40)] {
                let Some(ray) = pixel_ray(&cam, &cond, x, y) else {
                    continue;
                };
                for depth in [0.05, 0.5, 2.0, 5.5, 20.0] {
                    let shade = Vec3::new(0.3, 0.5, 0.7);
                    let one = fish_radiance(&cam, &cond, cam_dim, &ray, depth, shade);
                    let t = depth * ray.k;
                    let d = -(cam.position.y + ray.vy * t);
                    let terms = fish_radiance_by_terms(&cond, &ray, t, d, shade);
                    let err =
                        ((one - terms).abs() / terms.abs().max(Vec3::splat(1e-12))).max_element();
                    assert!(err < 1e-5, "{one} vs {terms} at ({x}, {y}), depth {depth}");
                    checked += 1;
                }
            }
        }
        assert!(checked >= 60, "{checked}");
    }

    /// The tone table gives the bytes of the curve it replaces: at each
    /// level's threshold and the float just below it, on a sweep of the
    /// non-negative floats, and for zero, negatives, infinity and NaN.
    #[test]
    fn the_tone_table_is_the_tone_curve() {
        let t = tone_thresholds();
        assert!(t.windows(2).all(|p| p[0] < p[1]), "thresholds rise");
        let one = |x: f32| tone(Vec3::splat(x))[0];
        for (i, &th) in t.iter().enumerate() {
            assert_eq!(encode_channel(th), i as u8 + 1);
            assert_eq!(one(th), i as u8 + 1);
            let below = f32::from_bits(th.to_bits() - 1);
            assert_eq!(one(below), encode_channel(below), "below level {}", i + 1);
            assert_eq!(encode_channel(below), i as u8);
        }
        // Every 4,099th float from 0 to infinity (a prime stride hits every
        // exponent and mantissas all over).
        for bits in (0..f32::INFINITY.to_bits()).step_by(4099) {
            let x = f32::from_bits(bits);
            assert_eq!(one(x), encode_channel(x), "x = {x:e}");
        }
        for x in [0.0, -0.0, -1.0, f32::NEG_INFINITY, f32::INFINITY, f32::NAN] {
            assert_eq!(one(x), encode_channel(x), "x = {x}");
        }
        assert_eq!((one(f32::NAN), one(-1.0), one(f32::INFINITY)), (0, 0, 255));
    }

    /// A row's span never drops a pixel the full-box scan would draw:
    /// random triangles (large, tiny, slivers, far off-screen vertices), every
    /// pixel of their box outside the span fails the coverage test.
    #[test]
    fn row_spans_keep_every_covered_pixel() {
        let mut rng = crate::setup::Rng::new(7, 0);
        let rv = |x: f32, y: f32| RVert {
            p: Vec3::new(x, y, 1.0),
            shade: Vec3::ZERO,
        };
        let (mut covered, mut skipped) = (0u64, 0u64);
        for case in 0..3000 {
            let scale = [4.0, 40.0, 400.0, 5e4][case % 4];
            let mut v = [0; 3].map(|_| rv(rng.range(-scale, scale), rng.range(-scale, scale)));
            if case % 3 == 0 {
                // A sliver: the third vertex almost on the first edge.
                let t = rng.range(0.0, 1.0);
                let (a, b) = (v[0].p, v[1].p);
                v[2] = rv(a.x + (b.x - a.x) * t + 1e-3, a.y + (b.y - a.y) * t);
            }
            let s = Sampler::new(v, true);
            if s.area == 0.0 || !s.area.is_finite() {
                continue;
            }
            let [a, b, c] = v.map(|v| v.p);
            let clampi = |z: f32| (z as i64).clamp(-600, 600);
            let (x0, x1) = (
                clampi(a.x.min(b.x).min(c.x).floor()),
                clampi(a.x.max(b.x).max(c.x).ceil()),
            );
            let (y0, y1) = (
                clampi(a.y.min(b.y).min(c.y).floor()),
                clampi(a.y.max(b.y).max(c.y).ceil()),
            );
            if x0 > x1 || y0 > y1 {
                continue;
            }
            let span = RowSpan::new(&v, s.inv, x0, x1, y0, y1);
            for y in y0..=y1 {
                let (lo, hi) = span.columns(y, x0, x1);
                for x in x0..=x1 {
                    let inside = barycentric(&v, s.inv, x as f32 + 0.5, y as f32 + 0.5).is_some();
                    if (lo..=hi).contains(&x) {
                        covered += inside as u64;
                    } else {
                        assert!(
                            !inside,
                            "case {case}: pixel ({x}, {y}) outside span {lo}..={hi}"
                        );
                        skipped += 1;
                    }
                }
            }
        }
        // The spans do skip most of the empty box, and cover something.
        assert!(
            covered > 100_000 && skipped > covered,
            "{covered} covered, {skipped} skipped"
        );
    }
}
