//! `deepfoids image-stats`: Fig. 4.12 — fisheye frames made black and white,
//! the density of black pixels in 16 annuli, folder A against folder B
//! (`deepfoids_count::stats`).

use anyhow::{Result, bail};
use clap::Args;
use deepfoids_count::count::png_bytes;
use deepfoids_count::stats::{Threshold, csv, folder_stats, plot};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ImageStatsArgs {
    /// Folder A of fisheye frames (PNG/JPEG), e.g. renders
    #[arg(value_name = "A")]
    pub a: PathBuf,
    /// Folder B, e.g. frames of a real cage video
    #[arg(value_name = "B")]
    pub b: PathBuf,
    /// Output folder: annuli.csv, annuli.png, a_binary.png, b_binary.png
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Black pixels: `local` (darker than 85 % of the surrounding mean), `otsu` (Otsu's level per
    /// frame) or a grey level 0–255
    #[arg(long, default_value = "local")]
    pub threshold: Threshold,
    /// Names of A and B in the plot and CSV
    #[arg(long, value_delimiter = ',', default_values_t = vec!["A".to_string(), "B".to_string()])]
    pub names: Vec<String>,
}

pub fn run(args: &ImageStatsArgs) -> Result<()> {
    if args.names.len() != 2 {
        bail!("--names takes two names, got {}", args.names.len());
    }
    let (na, nb) = (&args.names[0], &args.names[1]);
    let a = folder_stats(&args.a, args.threshold)?;
    let b = folder_stats(&args.b, args.threshold)?;
    std::fs::create_dir_all(&args.out)?;
    let w = |name: &str, bytes: &[u8]| deepfoids_io::write_atomic(args.out.join(name), bytes);
    w("annuli.csv", csv(&a, &b, na, nb).as_bytes())?;
    w("annuli.png", &plot(&a, &b, na, nb)?)?;
    let grey_png =
        |g: &image::GrayImage| png_bytes(&image::DynamicImage::ImageLuma8(g.clone()).to_rgb8());
    w("a_binary.png", &grey_png(&a.example))?;
    w("b_binary.png", &grey_png(&b.example))?;
    let fmt = |m: &[f64]| {
        m.iter()
            .map(|v| format!("{v:.3}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    println!(
        "{na} ({} frames, threshold {:.0}): {}",
        a.frames,
        a.threshold,
        fmt(&a.mean)
    );
    println!(
        "{nb} ({} frames, threshold {:.0}): {}",
        b.frames,
        b.threshold,
        fmt(&b.mean)
    );
    println!("written to {}", args.out.display());
    Ok(())
}
