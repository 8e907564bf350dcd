//! Fig. 4.12: fisheye frames of the cage bottom camera made black and white
//! with a threshold, and the density of black pixels in 16 annuli around the
//! image centre — to hold a simulated school against a real one.
//!
//! Black = darker than the threshold: seen from below, fish are dark against
//! the bright surface. The thesis says "some threshold"; three are offered
//! ([`Threshold`]), on the Rec. 601 luma. The default is local: a pixel is
//! black when it is darker than 85 % of the mean grey of the square around
//! it (side 1/12 of the image circle's diameter). A single global level
//! (fixed, or Otsu's) mostly separates the bright Snell's window from the dark
//! rim of a fisheye frame instead of the fish from the water. The annuli
//! split the image circle (radius = half the shorter side, the renderer's
//! fisheye) into 16 rings of equal width; pixels outside the circle are not
//! counted. A folder's density per ring is the mean over its frames.

use crate::error::{CountError, Result};
use crate::frames::{list_images, read_image};
use image::{GrayImage, RgbImage};
use plotters::prelude::*;
use std::path::Path;

/// Rings of Fig. 4.12.
pub const ANNULI: usize = 16;

/// Rec. 601 luma of an RGB image.
pub fn grey(img: &RgbImage) -> GrayImage {
    let (w, h) = img.dimensions();
    GrayImage::from_fn(w, h, |x, y| {
        let p = img.get_pixel(x, y).0;
        image::Luma([
            (0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32).round() as u8,
        ])
    })
}

/// Otsu's threshold: the level `t` that maximises the between-class variance
/// of `{< t}` and `{≥ t}` inside the image circle.
pub fn otsu(g: &GrayImage) -> u8 {
    let mut hist = [0u64; 256];
    for_circle(g, |_, v| hist[v as usize] += 1);
    let total: u64 = hist.iter().sum();
    let sum: f64 = hist
        .iter()
        .enumerate()
        .map(|(i, &c)| i as f64 * c as f64)
        .sum();
    let (mut w0, mut s0, mut best, mut t_best) = (0u64, 0f64, -1f64, 0u8);
    for t in 1..256 {
        w0 += hist[t - 1];
        s0 += (t - 1) as f64 * hist[t - 1] as f64;
        let w1 = total - w0;
        if w0 == 0 || w1 == 0 {
            continue;
        }
        let (m0, m1) = (s0 / w0 as f64, (sum - s0) / w1 as f64);
        let between = w0 as f64 * w1 as f64 * (m0 - m1).powi(2);
        if between > best {
            best = between;
            t_best = t as u8;
        }
    }
    t_best
}

/// Calls `f(ring radius share in [0, 1), value)` for each pixel inside the image circle.
fn for_circle(g: &GrayImage, mut f: impl FnMut(f32, u8)) {
    let (w, h) = g.dimensions();
    let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
    let r = w.min(h) as f32 / 2.0;
    for (x, y, p) in g.enumerate_pixels() {
        let d = ((x as f32 + 0.5 - cx).powi(2) + (y as f32 + 0.5 - cy).powi(2)).sqrt() / r;
        if d < 1.0 {
            f(d, p.0[0]);
        }
    }
}

/// How a grey frame is made black and white.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Threshold {
    /// Black below this grey level.
    Fixed(u8),
    /// Otsu's global level, per frame.
    Otsu,
    /// Black below 85 % of the local mean (square of side 1/12 of the circle's diameter).
    Local,
}

impl std::str::FromStr for Threshold {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "otsu" => Ok(Self::Otsu),
            "local" => Ok(Self::Local),
            n => n.parse().map(Self::Fixed).map_err(|_| {
                format!("unknown threshold `{n}`; allowed: local, otsu or a grey level 0–255")
            }),
        }
    }
}

/// The black mask of a grey frame (true = black) and the mean level used.
pub fn black_mask(g: &GrayImage, t: Threshold) -> (Vec<bool>, f64) {
    match t {
        Threshold::Fixed(v) => (g.as_raw().iter().map(|&p| p < v).collect(), v as f64),
        Threshold::Otsu => {
            let v = otsu(g);
            (g.as_raw().iter().map(|&p| p < v).collect(), v as f64)
        }
        Threshold::Local => {
            let (w, h) = (g.width() as usize, g.height() as usize);
            let r = ((w.min(h) as f64 / 24.0).round() as usize).max(1);
            // Summed-area table.
            let mut sat = vec![0u64; (w + 1) * (h + 1)];
            for y in 0..h {
                let mut row = 0u64;
                for x in 0..w {
                    row += g.as_raw()[y * w + x] as u64;
                    sat[(y + 1) * (w + 1) + x + 1] = sat[y * (w + 1) + x + 1] + row;
                }
            }
            let mut sum_level = 0f64;
            let mask = (0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    let (x0, y0) = (x.saturating_sub(r), y.saturating_sub(r));
                    let (x1, y1) = ((x + r + 1).min(w), (y + r + 1).min(h));
                    let s = sat[y1 * (w + 1) + x1] + sat[y0 * (w + 1) + x0]
                        - sat[y0 * (w + 1) + x1]
                        - sat[y1 * (w + 1) + x0];
                    let level = 0.85 * s as f64 / ((x1 - x0) * (y1 - y0)) as f64;
                    sum_level += level;
                    (g.as_raw()[i] as f64) < level
                })
                .collect();
            (mask, sum_level / (w * h).max(1) as f64)
        }
    }
}

/// As [`for_circle`], with the pixel's index instead of its value.
fn for_circle_indexed(g: &GrayImage, mut f: impl FnMut(f32, usize)) {
    let (w, h) = g.dimensions();
    let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
    let r = w.min(h) as f32 / 2.0;
    for y in 0..h {
        for x in 0..w {
            let d = ((x as f32 + 0.5 - cx).powi(2) + (y as f32 + 0.5 - cy).powi(2)).sqrt() / r;
            if d < 1.0 {
                f(d, (y * w + x) as usize);
            }
        }
    }
}

/// The black-and-white image of a black mask.
pub fn binarise(g: &GrayImage, mask: &[bool]) -> GrayImage {
    let w = g.width();
    GrayImage::from_fn(w, g.height(), |x, y| {
        image::Luma([if mask[(y * w + x) as usize] { 0 } else { 255 }])
    })
}

/// Share of black pixels in each of the 16 rings.
pub fn annulus_density(g: &GrayImage, mask: &[bool]) -> [f64; ANNULI] {
    let (mut black, mut all) = ([0u64; ANNULI], [0u64; ANNULI]);
    for_circle_indexed(g, |d, idx| {
        let k = ((d * ANNULI as f32) as usize).min(ANNULI - 1);
        all[k] += 1;
        black[k] += mask[idx] as u64;
    });
    std::array::from_fn(|k| {
        if all[k] == 0 {
            0.0
        } else {
            black[k] as f64 / all[k] as f64
        }
    })
}

/// A folder's statistics.
#[derive(Clone, Debug)]
pub struct FolderStats {
    pub frames: usize,
    /// Mean density per ring.
    pub mean: [f64; ANNULI],
    /// Standard deviation over frames per ring.
    pub std: [f64; ANNULI],
    /// Mean grey level of the threshold used (for `Local`: of the local levels).
    pub threshold: f64,
    /// The first frame, black and white.
    pub example: GrayImage,
}

/// Statistics of every PNG/JPEG in `dir`.
pub fn folder_stats(dir: &Path, threshold: Threshold) -> Result<FolderStats> {
    let files = list_images(dir)?;
    let mut rows = Vec::with_capacity(files.len());
    let (mut thr_sum, mut example) = (0f64, None);
    for f in &files {
        let g = grey(&read_image(f)?);
        let (mask, level) = black_mask(&g, threshold);
        thr_sum += level;
        rows.push(annulus_density(&g, &mask));
        if example.is_none() {
            example = Some(binarise(&g, &mask));
        }
    }
    let n = rows.len() as f64;
    let mean: [f64; ANNULI] = std::array::from_fn(|k| rows.iter().map(|r| r[k]).sum::<f64>() / n);
    let std = std::array::from_fn(|k| {
        (rows.iter().map(|r| (r[k] - mean[k]).powi(2)).sum::<f64>() / n).sqrt()
    });
    Ok(FolderStats {
        frames: rows.len(),
        mean,
        std,
        threshold: thr_sum / n,
        example: example.expect("list_images is never empty"),
    })
}

/// The CSV of two folders' densities.
pub fn csv(a: &FolderStats, b: &FolderStats, name_a: &str, name_b: &str) -> String {
    let mut s = format!(
        "annulus,r_inner,r_outer,{name_a}_density,{name_a}_std,{name_b}_density,{name_b}_std\n"
    );
    for k in 0..ANNULI {
        s.push_str(&format!(
            "{},{:.4},{:.4},{:.6},{:.6},{:.6},{:.6}\n",
            k + 1,
            k as f64 / ANNULI as f64,
            (k + 1) as f64 / ANNULI as f64,
            a.mean[k],
            a.std[k],
            b.mean[k],
            b.std[k]
        ));
    }
    s
}

/// The font family the plot uses (DejaVu Sans, embedded: no system fonts needed).
const FONT: &str = "sans-serif";

fn init_fonts() {
    static FONTS: std::sync::Once = std::sync::Once::new();
    FONTS.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            let _ = plotters::style::register_font(FONT, style, dejavu::sans::regular());
        }
    });
}

/// Fig. 4.12's right panel for two folders, as PNG bytes (800 × 500).
pub fn plot(a: &FolderStats, b: &FolderStats, name_a: &str, name_b: &str) -> Result<Vec<u8>> {
    init_fonts();
    let (w, h) = (800u32, 500u32);
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    let err = |e: &dyn std::fmt::Debug| CountError::Train(format!("plotting failed: {e:?}"));
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let top = a.mean.iter().chain(&b.mean).fold(0.0f64, |m, &v| m.max(v));
        let mut chart = ChartBuilder::on(&root)
            .caption("Black pixels in 16 annuli of the fisheye image", (FONT, 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(0.5f64..16.5f64, 0.0f64..(top * 1.15).max(0.01))
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("annulus (1 = image centre, 16 = rim)")
            .y_desc("density of black pixels")
            .label_style((FONT, 15))
            .draw()
            .map_err(|e| err(&e))?;
        for (stats, name, colour) in [
            (a, name_a, RGBColor(200, 60, 40)),
            (b, name_b, RGBColor(40, 90, 200)),
        ] {
            let pts: Vec<(f64, f64)> = (0..ANNULI)
                .map(|k| ((k + 1) as f64, stats.mean[k]))
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(3)))
                .map_err(|e| err(&e))?
                .label(format!("{name} ({} frames)", stats.frames))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
                });
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                .map_err(|e| err(&e))?;
        }
        chart
            .configure_series_labels()
            .label_font((FONT, 15))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))?;
    }
    Ok(crate::count::png_bytes(
        &RgbImage::from_raw(w, h, rgb).expect("plot size"),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64 × 64 image, white, with the disc of radius 8 around the centre
    /// black: rings are 2 px wide (radius 32 / 16), so rings 1–4 are black,
    /// the rest white (pixel centres at exactly r = 8 fall in ring 5: white).
    #[test]
    fn annuli_by_hand() {
        let g = GrayImage::from_fn(64, 64, |x, y| {
            let d = ((x as f32 + 0.5 - 32.0).powi(2) + (y as f32 + 0.5 - 32.0).powi(2)).sqrt();
            image::Luma([if d < 8.0 { 10 } else { 240 }])
        });
        let d = annulus_density(&g, &black_mask(&g, Threshold::Fixed(128)).0);
        assert!(d[..4].iter().all(|&v| v == 1.0), "{d:?}");
        assert!(d[4..].iter().all(|&v| v == 0.0), "{d:?}");
        // Otsu splits the two levels.
        let t = otsu(&g);
        assert!((11..=240).contains(&t), "{t}");
        assert_eq!(annulus_density(&g, &black_mask(&g, Threshold::Otsu).0), d);
        // Local: a dark speck on a brightness ramp is black, the ramp is not.
        let mut ramp = GrayImage::from_fn(64, 64, |x, _| image::Luma([100 + 2 * x as u8]));
        ramp.put_pixel(40, 30, image::Luma([60]));
        let (m, _) = black_mask(&ramp, Threshold::Local);
        assert!(m[30 * 64 + 40]);
        assert_eq!(m.iter().filter(|&&b| b).count(), 1);
        assert_eq!("otsu".parse::<Threshold>(), Ok(Threshold::Otsu));
        assert_eq!("77".parse::<Threshold>(), Ok(Threshold::Fixed(77)));
        assert!("dark".parse::<Threshold>().is_err());
    }
}
