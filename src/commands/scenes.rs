//! `deepfoids scenes`: the scenes with species, fish count, cage and density.

use anyhow::Result;
use deepfoids_env::{ConfigDirs, Phase, Scene};

pub fn run(dirs: &ConfigDirs) -> Result<()> {
    dirs.check_root()?;
    let ids = dirs.list("scenes");
    if ids.is_empty() {
        anyhow::bail!("no scenes in {}", dirs.root.join("scenes").display());
    }
    println!(
        "{:<22} {:<34} {:>5} {:<26} {:>7} {:>9}  site, date, time",
        "scene", "behaviours (fish)", "fish", "cage", "m³", "fish/m³"
    );
    for id in ids {
        match Scene::load(dirs, &id, Phase::Pretrain) {
            Ok(s) => {
                let behaviours: Vec<String> = s
                    .behaviours
                    .iter()
                    .map(|b| format!("{} ({})", b.name, b.count))
                    .collect();
                let cage = s.cage();
                println!(
                    "{:<22} {:<34} {:>5} {:<26} {:>7.1} {:>9.3}  {}, {}-{:02}-{:02}, {:02}:{:02}{}",
                    id,
                    behaviours.join(", "),
                    s.fish_count(),
                    cage.describe(),
                    cage.volume(),
                    s.density(),
                    s.site.name,
                    s.clock.year,
                    s.clock.month,
                    s.clock.day,
                    s.clock.start_hours as u32,
                    ((s.clock.start_hours.fract()) * 60.0).round() as u32,
                    if s.clock.runs { " (clock runs)" } else { "" }
                );
            }
            Err(e) => println!("{id:<22} error: {e}"),
        }
    }
    Ok(())
}
