//! PNG plots with an embedded font (DejaVu Sans from the `dejavu` crate), so
//! text renders on a bare machine without system fonts.

use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// The font family name plots use.
pub const FONT: &str = "sans-serif";

static FONTS: Once = Once::new();

/// Register the embedded font (idempotent).
pub fn init_fonts() {
    FONTS.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            // The bytes are a valid TrueType font shipped by the `dejavu` crate.
            let _ = plotters::style::register_font(FONT, style, dejavu::sans::regular());
        }
    });
}

/// The caption's font size: `size`, or smaller so that `text` fits across
/// `area` with a 12-px margin each side (a long run id was cut off at both
/// ends of `trajectories.png`); never under 9.
pub fn caption_size<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    text: &str,
    size: f64,
) -> f64 {
    let room = area.dim_in_pixel().0 as f64 - 24.0;
    let width = area
        .estimate_text_size(text, &(FONT, size).into_text_style(area))
        .map_or(0.0, |(w, _)| w as f64);
    if width > room {
        (size * room / width).floor().max(9.0)
    } else {
        size
    }
}

/// Draw into an in-memory RGB bitmap and return it encoded as PNG.
pub fn render_png(
    width: u32,
    height: u32,
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
) -> Result<Vec<u8>> {
    init_fonts();
    let mut rgb = vec![0u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        draw(&root)?;
        root.present().map_err(|e| anyhow!("drawing failed: {e}"))?;
    }
    encode_png(width, height, rgb)
}

/// Encode an RGB8 buffer as PNG.
pub fn encode_png(width: u32, height: u32, rgb: Vec<u8>) -> Result<Vec<u8>> {
    let img = image::RgbImage::from_raw(width, height, rgb)
        .ok_or_else(|| anyhow!("bitmap of the wrong size"))?;
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )?;
    Ok(bytes)
}

/// Render and write a PNG atomically.
pub fn save_png(
    path: &Path,
    width: u32,
    height: u32,
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
) -> Result<()> {
    let bytes = render_png(width, height, draw)?;
    deepfoids_io::write_atomic(path, &bytes)?;
    Ok(())
}

/// Turn a plotters error into anyhow.
pub fn pe<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plotting failed: {e:?}")
}

/// A legend entry's mark: a 20 px line in the series' colour.
pub fn legend_line(colour: RGBColor) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
}

/// The legend of `chart`'s labelled series at `position`: a white box,
/// a thin border and `size` pt labels, as every plot draws it.
pub fn draw_legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    size: u32,
) -> Result<()> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font((FONT, size))
        .draw()
        .map_err(pe)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A short caption keeps its size; one twice as wide as a 300-px area
    /// shrinks to about half and then fits; nothing goes under 9.
    #[test]
    fn captions_shrink_to_fit() {
        init_fonts();
        let mut rgb = vec![0u8; 300 * 20 * 3];
        let root = BitMapBackend::with_buffer(&mut rgb, (300, 20)).into_drawing_area();
        assert_eq!(caption_size(&root, "P and M", 18.0), 18.0);
        let long = "coho_default · bounce_budget_space20-thesis-pre (ppo) · seed 11";
        let size = caption_size(&root, long, 18.0);
        let width = |s: f64| {
            root.estimate_text_size(long, &(FONT, s).into_text_style(&root))
                .unwrap()
                .0
        };
        assert!(width(18.0) > 276 && (9.0..18.0).contains(&size), "{size}");
        assert!(width(size) <= 276, "{}", width(size));
        assert_eq!(caption_size(&root, &long.repeat(10), 18.0), 9.0);
    }
}
