//! The `sensor-view` picture: a fish's three stacked grid-sensor frames
//! (oldest left), proximity as brightness and object type as colour.

use crate::plot::{FONT, pe, save_png};
use anyhow::Result;
use deepfoids_sensors::{AZ_CELLS, CELLS, EL_CELLS, FRAME_LEN, GridSensor, STACK};
use plotters::prelude::*;

/// Colour of each seen type at full proximity, in channel order 1..=5.
pub const TYPE_COLOURS: [(&str, RGBColor); 5] = [
    ("fish", RGBColor(40, 200, 255)),
    ("net", RGBColor(70, 220, 70)),
    ("surface", RGBColor(250, 235, 80)),
    ("obstacle", RGBColor(210, 90, 255)),
    ("chase partner", RGBColor(255, 50, 50)),
];

/// Colour of cell `c` of a frame.
fn cell_colour(frame: &[f32], c: usize) -> RGBColor {
    let prox = frame[c];
    for (k, (_, col)) in TYPE_COLOURS.iter().enumerate() {
        if frame[(k + 1) * CELLS + c] > 0.5 {
            let s = 0.25 + 0.75 * prox.clamp(0.0, 1.0);
            return RGBColor(
                (col.0 as f32 * s) as u8,
                (col.1 as f32 * s) as u8,
                (col.2 as f32 * s) as u8,
            );
        }
    }
    RGBColor(18, 18, 24)
}

/// Draw the three frames side by side with axes in degrees and a legend.
pub fn draw(path: &std::path::Path, stack: &[f32], title: &str, subtitle: &str) -> Result<()> {
    let (width, height) = (1800u32, 560u32);
    save_png(path, width, height, |root| {
        root.fill(&WHITE).map_err(pe)?;
        root.draw(&Text::new(
            title.to_string(),
            (20, 12),
            (FONT, 24).into_font(),
        ))
        .map_err(pe)?;
        root.draw(&Text::new(
            subtitle.to_string(),
            (20, 44),
            (FONT, 16).into_font(),
        ))
        .map_err(pe)?;
        let body = root.margin(70, 60, 10, 10);
        let panels = body.split_evenly((1, STACK));
        let labels = ["t − 2 (oldest)", "t − 1", "t (newest)"];
        for (f, panel) in panels.iter().enumerate() {
            let frame = &stack[f * FRAME_LEN..(f + 1) * FRAME_LEN];
            let mut chart = ChartBuilder::on(panel)
                .caption(labels[f], (FONT, 18))
                .margin(8)
                .x_label_area_size(40)
                .y_label_area_size(45)
                .build_cartesian_2d(-170f32..170f32, -90f32..90f32)
                .map_err(pe)?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc("azimuth (°, right +)")
                .y_desc("elevation (°)")
                .x_labels(9)
                .y_labels(7)
                .x_label_formatter(&|v| format!("{v:.0}"))
                .y_label_formatter(&|v| format!("{v:.0}"))
                .label_style((FONT, 13))
                .axis_desc_style((FONT, 14))
                .draw()
                .map_err(pe)?;
            chart
                .draw_series((0..EL_CELLS).flat_map(|h| {
                    (0..AZ_CELLS).map(move |w| {
                        let az = GridSensor::azimuth_deg(w);
                        let el = GridSensor::elevation_deg(h);
                        let colour = cell_colour(frame, h * AZ_CELLS + w);
                        Rectangle::new(
                            [(az - 5.0, el - 4.5), (az + 5.0, el + 4.5)],
                            colour.filled(),
                        )
                    })
                }))
                .map_err(pe)?;
            // Heading marker.
            chart
                .draw_series(std::iter::once(Cross::new(
                    (0f32, 0f32),
                    6,
                    WHITE.stroke_width(2),
                )))
                .map_err(pe)?;
        }
        // Legend.
        let mut x = 20;
        let y = height as i32 - 30;
        for (name, col) in TYPE_COLOURS {
            root.draw(&Rectangle::new([(x, y), (x + 18, y + 18)], col.filled()))
                .map_err(pe)?;
            root.draw(&Text::new(name, (x + 24, y + 1), (FONT, 16).into_font()))
                .map_err(pe)?;
            x += 40 + 9 * name.len() as i32;
        }
        root.draw(&Text::new(
            "brightness = proximity (1 − distance / sensing range); black = nothing within range; × = heading; columns ±170–180° behind are blind",
            (x + 20, y + 1),
            (FONT, 15).into_font(),
        ))
        .map_err(pe)?;
        Ok(())
    })
}
