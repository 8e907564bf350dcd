//! One module per command.

pub mod bench;
pub mod eval;
pub mod scenes;
pub mod sensor_view;
pub mod simulate;

use anyhow::{Result, bail};
use deepfoids_env::baselines::{Boids, BoidsConfig, Foids, FoidsConfig};
use deepfoids_env::{ConfigDirs, Env, Phase, Policy, RandomPolicy, Scene};

/// Load a scene with its reward weights; the error names the file and field.
pub fn load_scene(dirs: &ConfigDirs, id: &str, phase: Phase) -> Result<Scene> {
    Ok(Scene::load(dirs, id, phase)?)
}

/// The policy named on the command line: a scripted baseline (parameters from
/// `configs/baselines/<name>.toml`) or random actions.
pub fn make_policy(
    dirs: &ConfigDirs,
    name: &str,
    seed: u64,
    _env: &Env,
) -> Result<Box<dyn Policy>> {
    match name {
        "random" => Ok(Box::new(RandomPolicy { seed })),
        "foids" => Ok(Box::new(Foids::new(
            FoidsConfig::load(&dirs.baseline("foids")?)?,
            seed,
        ))),
        "boids" => Ok(Box::new(Boids::new(BoidsConfig::load(
            &dirs.baseline("boids")?,
        )?))),
        other => bail!("unknown policy `{other}`; allowed: random, foids, boids"),
    }
}

/// `deepfoids` without a command: simulate the coho default scene for 60 s.
pub fn default_job(dirs: &ConfigDirs) -> Result<()> {
    eprintln!(
        "no command given: simulating coho_default for 60 s with random actions (see --help for the commands)"
    );
    let args = crate::cli::SimulateArgs {
        scene: crate::cli::SceneArgs {
            scene: "coho_default".into(),
            seed: 0,
            phase: Phase::Pretrain,
        },
        policy: "random".into(),
        seconds: 60.0,
        out: None,
    };
    simulate::run(dirs, &args)
}
