//! GIF clips of a replay: the top view (x right, z down — looking down at the
//! surface) and the side view (x right, y up — looking along −z), side by side
//! or alone, one GIF frame per recorded frame, in the viewer's colours.
//!
//! Drawing: every frame is drawn with plotters into an RGB bitmap — cage,
//! obstacles, fish as flat silhouettes one body length long along their
//! projected heading (far fish first, shaded towards the water colour by
//! distance), chases, dominant marks, time and P/M — then mapped to one fixed
//! 256-colour palette. Only the pixels that changed since the previous frame
//! are stored (the rest transparent, cropped to the changed box), which is
//! what keeps a 1,000-fish minute in a few megabytes.
//!
//! Why GIF and not MP4: no maintained pure-Rust H.264 encoder exists (the
//! `openh264` crate wraps Cisco's C library), and AV1 through `rav1e` would
//! add minutes of build and a container writer for a clip. `gif` is pure Rust
//! and already in the dependency tree.

use crate::recording::Recording;
use crate::recording::{COLOURS, colour};
use glam::{Vec2, Vec3};
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// Why a clip could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ClipError {
    /// A size or speed out of range, or a clip too large for GIF.
    #[error("{0}")]
    Invalid(String),
    #[error("cannot create {}", path.display())]
    CreateDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Writing the file (the message names it).
    #[error(transparent)]
    Write(#[from] std::io::Error),
    /// The encoder's error (not a source: the message already holds it).
    #[error("GIF: {0}")]
    Gif(gif::EncodingError),
    #[error("plotting failed: {0}")]
    Plot(String),
}

type Result<T, E = ClipError> = std::result::Result<T, E>;

/// Which views a clip shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GifView {
    Top,
    Side,
    Both,
}

impl GifView {
    /// Every view, by name.
    pub const ALL: [(&'static str, GifView); 3] = [
        ("top", GifView::Top),
        ("side", GifView::Side),
        ("both", GifView::Both),
    ];
}

impl std::str::FromStr for GifView {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .iter()
            .find(|(name, _)| *name == s)
            .map(|(_, v)| *v)
            .ok_or_else(|| format!("unknown view `{s}`; allowed: top, side, both"))
    }
}

/// The font family name the clips use.
const FONT: &str = "sans-serif";

static FONTS: Once = Once::new();

/// Register the embedded font (DejaVu Sans, so text renders on a bare machine
/// without system fonts); idempotent.
fn init_fonts() {
    FONTS.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            // The bytes are a valid TrueType font shipped by the `dejavu` crate.
            let _ = plotters::style::register_font(FONT, style, dejavu::sans::regular());
        }
    });
}

/// A plotters error as a clip error.
fn pe<E: std::fmt::Debug>(e: E) -> ClipError {
    ClipError::Plot(format!("{e:?}"))
}

const WATER: [u8; 3] = [11, 34, 54];
const NET: [u8; 3] = [120, 160, 190];
const SURFACE: [u8; 3] = [143, 211, 255];
const TEXT: [u8; 3] = [230, 238, 245];
const CHASE: [u8; 3] = [255, 59, 48];
const DOMINANT: [u8; 3] = [255, 255, 255];
const OBSTACLE: [u8; 3] = [138, 122, 102];
/// Shades of each behaviour colour, from itself towards the water.
const SHADES: usize = 3;
/// Palette index left transparent in delta frames.
const TRANSPARENT: u8 = 255;
/// Header height (px), including the views' labels.
const HEADER: i32 = 58;
/// Padding around a panel (px).
const PAD: i32 = 12;

/// The fish silhouette in body lengths: `(along, across)`, head at +0.5.
const OUTLINE: [(f32, f32); 12] = [
    (0.5, 0.0),
    (0.38, 0.07),
    (0.15, 0.1),
    (-0.1, 0.09),
    (-0.32, 0.05),
    (-0.4, 0.02),
    (-0.5, 0.1),
    (-0.5, -0.1),
    (-0.4, -0.02),
    (-0.32, -0.05),
    (-0.1, -0.09),
    (0.15, -0.1),
];

/// The fixed palette: water, lines, text, behaviour shades, then a colour cube
/// for anti-aliased text; the last entry is the transparent one.
fn palette() -> Vec<[u8; 3]> {
    let mut p = vec![WATER, NET, SURFACE, TEXT, CHASE, DOMINANT, OBSTACLE];
    for s in 0..SHADES {
        p.push(shade(CHASE, s as f32 / SHADES as f32 * 0.75));
    }
    for c in COLOURS {
        for s in 0..SHADES {
            p.push(shade(c, s as f32 / SHADES as f32 * 0.75));
        }
    }
    'cube: for r in 0..6u8 {
        for g in 0..6u8 {
            for b in 0..5u8 {
                if p.len() >= 255 {
                    break 'cube;
                }
                p.push([r * 51, g * 51, b * 63]);
            }
        }
    }
    while p.len() < 256 {
        p.push([0, 0, 0]);
    }
    p
}

/// `c` mixed with the water by `amount` (0 = itself).
fn shade(c: [u8; 3], amount: f32) -> [u8; 3] {
    let mix = |a: u8, b: u8| (a as f32 + (b as f32 - a as f32) * amount).round() as u8;
    [
        mix(c[0], WATER[0]),
        mix(c[1], WATER[1]),
        mix(c[2], WATER[2]),
    ]
}

/// Nearest palette entry for every colour at 6 bits per channel.
struct Lut {
    table: Vec<u8>,
}

impl Lut {
    fn new(palette: &[[u8; 3]]) -> Self {
        let mut table = vec![0u8; 1 << 18];
        for (k, slot) in table.iter_mut().enumerate() {
            let c = [(k >> 12) as i32, ((k >> 6) & 63) as i32, (k & 63) as i32].map(|x| x * 4 + 2);
            let mut best = (i32::MAX, 0u8);
            for (i, p) in palette.iter().enumerate().take(TRANSPARENT as usize) {
                let d: i32 = (0..3).map(|a| (p[a] as i32 - c[a]).pow(2)).sum();
                if d < best.0 {
                    best = (d, i as u8);
                }
            }
            *slot = best.1;
        }
        Self { table }
    }

    fn index(&self, r: u8, g: u8, b: u8) -> u8 {
        self.table[((r as usize >> 2) << 12) | ((g as usize >> 2) << 6) | (b as usize >> 2)]
    }
}

/// One view: how world coordinates land on the bitmap.
#[derive(Clone, Copy)]
struct Panel {
    top_view: bool,
    /// Bitmap position of the panel's origin (world minimum corner), px.
    origin: (i32, i32),
    /// World minimum of the two drawn axes (m).
    min: Vec2,
    scale: f32,
    size: (i32, i32),
}

impl Panel {
    /// The drawn 2D coordinates of a world point (screen y grows downwards).
    fn world(&self, p: Vec3) -> Vec2 {
        if self.top_view {
            Vec2::new(p.x, p.z)
        } else {
            Vec2::new(p.x, -p.y)
        }
    }

    fn px(&self, p: Vec2) -> (i32, i32) {
        let q = (p - self.min) * self.scale;
        (
            self.origin.0 + q.x.round() as i32,
            self.origin.1 + q.y.round() as i32,
        )
    }

    /// Distance from the camera along its view axis, normalised 0 (near) … 1 (far).
    fn far(&self, p: Vec3, height: f32, half_z: f32) -> f32 {
        if self.top_view {
            (-p.y / height).clamp(0.0, 1.0)
        } else {
            ((half_z - p.z) / (2.0 * half_z)).clamp(0.0, 1.0)
        }
    }
}

/// Write the clip of `rec` to `path`; returns its size in bytes.
pub fn write_gif(
    path: &Path,
    rec: &Recording,
    view: GifView,
    size: u32,
    speed: f64,
) -> Result<usize> {
    check_gif(size, speed)?;
    let bytes = gif_bytes(rec, view, size, speed)?;
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|source| ClipError::CreateDir {
            path: parent.to_path_buf(),
            source,
        })?;
    }
    deepfoids_io::write_atomic(path, &bytes)?;
    Ok(bytes.len())
}

/// The size and speed a GIF can be written with: `size` 64 to 4096 px,
/// `speed` positive and finite. A command checks them before it simulates.
pub fn check_gif(size: u32, speed: f64) -> Result<()> {
    if !(GIF_SIZE_PX[0]..=GIF_SIZE_PX[1]).contains(&size) {
        return Err(ClipError::Invalid(format!(
            "--gif-size must be {} to {} pixels, got {size}",
            GIF_SIZE_PX[0], GIF_SIZE_PX[1]
        )));
    }
    if !(speed > 0.0 && speed.is_finite()) {
        return Err(ClipError::Invalid(format!(
            "--gif-speed must be a number above 0, got {speed}"
        )));
    }
    Ok(())
}

/// Width of a GIF view (px), `[min, max]`.
pub const GIF_SIZE_PX: [u32; 2] = [64, 4096];

/// The GIF file's bytes; each view `size` pixels wide.
pub fn gif_bytes(rec: &Recording, view: GifView, size: u32, speed: f64) -> Result<Vec<u8>> {
    init_fonts();
    let outline: Vec<Vec2> = rec
        .cage
        .outline
        .iter()
        .map(|&[x, z]| Vec2::new(x, z))
        .collect();
    let lo = outline.iter().fold(Vec2::splat(f32::MAX), |a, &b| a.min(b));
    let hi = outline.iter().fold(Vec2::splat(f32::MIN), |a, &b| a.max(b));
    let height = rec.cage.height;
    let margin = 0.1;
    let s = size as f32 / (hi.x - lo.x + 2.0 * margin);
    let top_size = (
        ((hi.x - lo.x + 2.0 * margin) * s).ceil() as i32,
        ((hi.y - lo.y + 2.0 * margin) * s).ceil() as i32,
    );
    let side_size = (top_size.0, ((height + 2.0 * margin) * s).ceil() as i32);
    let mut panels = vec![];
    let mut x = PAD;
    if matches!(view, GifView::Top | GifView::Both) {
        panels.push(Panel {
            top_view: true,
            origin: (x, HEADER + PAD),
            min: lo - Vec2::splat(margin),
            scale: s,
            size: top_size,
        });
        x += top_size.0 + 2 * PAD;
    }
    if matches!(view, GifView::Side | GifView::Both) {
        panels.push(Panel {
            top_view: false,
            origin: (x, HEADER + PAD),
            min: Vec2::new(lo.x - margin, -margin),
            scale: s,
            size: side_size,
        });
        x += side_size.0 + 2 * PAD;
    }
    let width = x.max(360);
    let height_px = HEADER + 2 * PAD + panels.iter().map(|p| p.size.1).max().unwrap_or(0);
    if width > u16::MAX as i32 || height_px > u16::MAX as i32 {
        return Err(ClipError::Invalid(format!(
            "a {width} × {height_px} px GIF is too large; lower --gif-size"
        )));
    }
    let (w, h) = (width as u32, height_px as u32);

    let pal = palette();
    let lut = Lut::new(&pal);
    let flat: Vec<u8> = pal.iter().flatten().copied().collect();
    let mut out = Vec::new();
    {
        let mut enc =
            gif::Encoder::new(&mut out, w as u16, h as u16, &flat).map_err(ClipError::Gif)?;
        enc.set_repeat(gif::Repeat::Infinite)
            .map_err(ClipError::Gif)?;
        let mut rgb = vec![0u8; (w * h * 3) as usize];
        let mut prev: Option<Vec<u8>> = None;
        let mut shown_cs = 0u64; // centiseconds of GIF time written so far
        let t0 = rec.times[0] as f64;
        for f in 0..rec.frames() {
            draw_frame(&mut rgb, (w, h), rec, f, &panels, &outline)?;
            let idx: Vec<u8> = rgb
                .chunks_exact(3)
                .map(|c| lut.index(c[0], c[1], c[2]))
                .collect();
            // Delay: until the next frame's time, in whole centiseconds without drift.
            let next_t = if f + 1 < rec.frames() {
                rec.times[f + 1] as f64
            } else {
                rec.times[f] as f64 + (rec.times[f] as f64 - t0) / (f.max(1)) as f64
            };
            let until = (((next_t - t0) / speed) * 100.0)
                .round()
                .max(shown_cs as f64 + 2.0) as u64;
            let delay = (until - shown_cs).min(u16::MAX as u64) as u16;
            shown_cs += delay as u64;
            let frame = delta_frame(&idx, prev.as_deref(), w as usize, h as usize, delay);
            enc.write_frame(&frame).map_err(ClipError::Gif)?;
            prev = Some(idx);
        }
    }
    Ok(out)
}

/// The frame to store: all of `idx` at first, later only the box of pixels
/// that changed, with unchanged pixels transparent.
fn delta_frame<'a>(
    idx: &'a [u8],
    prev: Option<&[u8]>,
    w: usize,
    h: usize,
    delay: u16,
) -> gif::Frame<'a> {
    let mut frame = gif::Frame {
        width: w as u16,
        height: h as u16,
        delay,
        dispose: gif::DisposalMethod::Keep,
        buffer: std::borrow::Cow::Borrowed(idx),
        ..Default::default()
    };
    let Some(prev) = prev else {
        return frame;
    };
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for y in 0..h {
        for x in 0..w {
            if idx[y * w + x] != prev[y * w + x] {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
    }
    if x0 > x1 {
        // Nothing changed: one transparent pixel.
        (x0, y0, x1, y1) = (0, 0, 0, 0);
    }
    let mut buf = Vec::with_capacity((x1 - x0 + 1) * (y1 - y0 + 1));
    for y in y0..=y1 {
        for x in x0..=x1 {
            let k = y * w + x;
            buf.push(if idx[k] == prev[k] {
                TRANSPARENT
            } else {
                idx[k]
            });
        }
    }
    frame.left = x0 as u16;
    frame.top = y0 as u16;
    frame.width = (x1 - x0 + 1) as u16;
    frame.height = (y1 - y0 + 1) as u16;
    frame.transparent = Some(TRANSPARENT);
    frame.buffer = std::borrow::Cow::Owned(buf);
    frame
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// Draw frame `f` of `rec` into `buf`.
fn draw_frame(
    buf: &mut [u8],
    (w, h): (u32, u32),
    rec: &Recording,
    f: usize,
    panels: &[Panel],
    outline: &[Vec2],
) -> Result<()> {
    let root = BitMapBackend::with_buffer(buf, (w, h)).into_drawing_area();
    root.fill(&rgb(WATER)).map_err(pe)?;
    let height = rec.cage.height;
    let half_z = outline.iter().map(|p| p.y.abs()).fold(0.1, f32::max);
    let t = rec.times[f];
    // Header: title, then time and the order parameters at this time.
    let k = rec
        .curves
        .t
        .partition_point(|&x| x <= t + 1e-4)
        .saturating_sub(1);
    let (p, m, state) = (
        rec.curves.p.get(k).copied().unwrap_or(f32::NAN),
        rec.curves.m.get(k).copied().unwrap_or(f32::NAN),
        rec.curves.state.get(k).copied().unwrap_or(0),
    );
    let state = ["swarm", "polarised", "milling", "transitional"][state.min(3) as usize];
    root.draw(&Text::new(
        rec.info.title.clone(),
        (PAD, 5),
        (FONT, 15).into_font().color(&rgb(TEXT)),
    ))
    .map_err(pe)?;
    root.draw(&Text::new(
        format!("t = {t:5.1} s   P {p:.2}   M {m:.2}   {state}"),
        (PAD, 22),
        (FONT, 14).into_font().color(&rgb(SURFACE)),
    ))
    .map_err(pe)?;

    for panel in panels {
        // Cage.
        let net = rgb(NET);
        if panel.top_view {
            let pts: Vec<(i32, i32)> = outline
                .iter()
                .chain(outline.first())
                .map(|&q| panel.px(q))
                .collect();
            root.draw(&PathElement::new(pts, net.stroke_width(2)))
                .map_err(pe)?;
        } else {
            let xs: Vec<f32> = outline.iter().map(|q| q.x).collect();
            let (x_lo, x_hi) = (
                xs.iter().copied().fold(f32::MAX, f32::min),
                xs.iter().copied().fold(f32::MIN, f32::max),
            );
            for &x in &xs {
                let a = panel.px(Vec2::new(x, 0.0));
                let b = panel.px(Vec2::new(x, height));
                root.draw(&PathElement::new(vec![a, b], net.mix(0.5)))
                    .map_err(pe)?;
            }
            let corners = [(x_lo, 0.0), (x_lo, height), (x_hi, height), (x_hi, 0.0)];
            let pts: Vec<(i32, i32)> = corners
                .iter()
                .map(|&(x, y)| panel.px(Vec2::new(x, y)))
                .collect();
            root.draw(&PathElement::new(pts, net.stroke_width(2)))
                .map_err(pe)?;
            let surface = [
                panel.px(Vec2::new(x_lo, 0.0)),
                panel.px(Vec2::new(x_hi, 0.0)),
            ];
            root.draw(&PathElement::new(
                surface.to_vec(),
                rgb(SURFACE).stroke_width(2),
            ))
            .map_err(pe)?;
        }
        for o in &rec.obstacles {
            draw_obstacle(&root, panel, o)?;
        }
        let label = if panel.top_view {
            "top (x →, z ↓)"
        } else {
            "side (x →, y ↑)"
        };
        root.draw(&Text::new(
            label,
            (panel.origin.0, panel.origin.1 - 18),
            (FONT, 12).into_font().color(&rgb(NET)),
        ))
        .map_err(pe)?;

        // Fish in a chase are red (as in the viewer); far fish first.
        let chasing: std::collections::HashSet<u32> =
            rec.chases_at(f).iter().flatten().copied().collect();
        let mut order: Vec<(f32, usize)> = (0..rec.fish)
            .map(|i| (panel.far(rec.position_at(f, i), height, half_z), i))
            .collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0));
        for &(far, i) in &order {
            let pos = rec.position_at(f, i);
            let dir = rec.heading_at(f, i);
            let c = panel.world(pos);
            let along = panel.world(dir);
            let len = along.length();
            let bl = rec.bl[i];
            let (axis, foreshorten) = if len > 1e-3 {
                (along / len, len)
            } else {
                (Vec2::X, 0.0)
            };
            let across = Vec2::new(-axis.y, axis.x);
            let pts: Vec<(i32, i32)> = OUTLINE
                .iter()
                .map(|&(u, v)| {
                    let q = c + axis * (u * bl * foreshorten.max(0.25)) + across * (v * bl);
                    panel.px(q)
                })
                .collect();
            let shade_step = ((far * SHADES as f32) as usize).min(SHADES - 1);
            let base = if chasing.contains(&(i as u32)) {
                CHASE
            } else {
                colour(rec.behaviour[i] as usize)
            };
            let col = shade(base, shade_step as f32 / SHADES as f32 * 0.75);
            root.draw(&Polygon::new(pts, rgb(col).filled()))
                .map_err(pe)?;
            if rec.dominant[i] {
                let (x, y) = panel.px(c);
                root.draw(&Rectangle::new(
                    [(x - 1, y - 1), (x + 1, y + 1)],
                    rgb(DOMINANT).filled(),
                ))
                .map_err(pe)?;
            }
        }
        for &[a, b] in rec.chases_at(f) {
            let pa = panel.px(panel.world(rec.position_at(f, a as usize)));
            let pb = panel.px(panel.world(rec.position_at(f, b as usize)));
            root.draw(&PathElement::new(vec![pa, pb], rgb(CHASE).stroke_width(2)))
                .map_err(pe)?;
        }
    }
    root.present().map_err(pe)?;
    Ok(())
}

fn draw_obstacle<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    panel: &Panel,
    o: &crate::recording::ObstacleShape,
) -> Result<()> {
    use crate::recording::ObstacleShape as O;
    let fill = rgb(OBSTACLE).filled();
    let r_px = |r: f32| (r * panel.scale).round() as i32;
    match *o {
        O::Sphere { center, radius } => {
            let c = panel.px(panel.world(Vec3::from(center)));
            root.draw(&Circle::new(c, r_px(radius), fill)).map_err(pe)?;
        }
        O::Cylinder {
            x,
            z,
            radius,
            y_min,
            y_max,
        } => {
            if panel.top_view {
                let c = panel.px(Vec2::new(x, z));
                root.draw(&Circle::new(c, r_px(radius), fill)).map_err(pe)?;
            } else {
                let a = panel.px(Vec2::new(x - radius, -y_max));
                let b = panel.px(Vec2::new(x + radius, -y_min));
                root.draw(&Rectangle::new([a, b], fill)).map_err(pe)?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every exact drawing colour maps to itself; transparent is never chosen.
    #[test]
    fn palette_holds_the_drawing_colours() {
        let pal = palette();
        assert_eq!(pal.len(), 256);
        let lut = Lut::new(&pal);
        for c in [WATER, NET, SURFACE, TEXT, CHASE, DOMINANT, OBSTACLE] {
            let i = lut.index(c[0], c[1], c[2]);
            let d: i32 = (0..3)
                .map(|a| (pal[i as usize][a] as i32 - c[a] as i32).abs())
                .sum();
            assert!(d <= 6, "{c:?} → {:?}", pal[i as usize]);
            assert_ne!(i, TRANSPARENT);
        }
    }

    /// 3 × 2 image, one pixel changed: the delta is that pixel alone.
    #[test]
    fn delta_frame_keeps_only_the_changed_box() {
        let prev = [1, 1, 1, 1, 1, 1];
        let now = [1, 1, 1, 1, 7, 1];
        let f = delta_frame(&now, Some(&prev), 3, 2, 20);
        assert_eq!((f.left, f.top, f.width, f.height), (1, 1, 1, 1));
        assert_eq!(&*f.buffer, &[7]);
        assert_eq!(f.transparent, Some(TRANSPARENT));
        let same = delta_frame(&prev, Some(&prev), 3, 2, 20);
        assert_eq!((same.width, same.height), (1, 1));
        assert_eq!(&*same.buffer, &[TRANSPARENT]);
        let first = delta_frame(&now, None, 3, 2, 20);
        assert_eq!((first.width, first.height, first.transparent), (3, 2, None));
    }
}
