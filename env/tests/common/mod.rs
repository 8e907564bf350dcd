//! Helpers for the env tests: small scenes with fish placed by the test.
#![allow(dead_code)]

use deepfoids_env::config::Range;
use deepfoids_env::{ConfigDirs, Env, Phase, Scene};
pub use deepfoids_testkit::copy_dir;
use glam::Vec3;
use std::path::{Path, PathBuf};

/// The shipped configs with the `thesis` reward profile (Table 4.1 with
/// SPEC §4 and §6.1 timing): the hand-computed expectations use its weights,
/// whatever the default profile is.
pub fn dirs() -> ConfigDirs {
    ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs")).with_reward_profile(THESIS)
}

/// The reward profile the hand-computed expectations use.
pub const THESIS: &str = "thesis";

/// A copy of the real configs in a temp folder, with `edit` applied to one file.
pub fn configs_with(name: &str, file: &str, edit: impl FnOnce(String) -> String) -> PathBuf {
    let root = std::env::temp_dir().join(format!(
        "deepfoids-config-test-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&root);
    for sub in ["species", "sites", "scenes", "rewards", "baselines"] {
        copy_dir(&dirs().root.join(sub), &root.join(sub));
    }
    let path = root.join(file);
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, edit(text)).unwrap();
    root
}

/// The error of loading `scene` from the configs at `root`.
pub fn load_err(root: &Path, scene: &str) -> String {
    Scene::load(
        &ConfigDirs::new(root).with_reward_profile(THESIS),
        scene,
        Phase::Pretrain,
    )
    .unwrap_err()
    .to_string()
}

/// Scene `id` cut down to `n` fish of body scale exactly 1.0.
pub fn scene(id: &str, n: usize) -> Scene {
    let mut s = Scene::load(&dirs(), id, Phase::Pretrain).unwrap();
    s.behaviours.truncate(1);
    s.behaviours[0].count = n;
    s.behaviours[0].body_scales = vec![(n, Range::Fixed(1.0))];
    s
}

/// The error loading `scene` from a copy of the configs (named `tag`) whose
/// `file` has `from` replaced by `to` (`from` must be in the file).
pub fn edit_err(tag: &str, file: &str, from: &str, to: &str, scene: &str) -> String {
    load_err(&configs_edited(tag, file, from, to), scene)
}

/// The configuration with `from` replaced by `to` in `file` (which must hold it).
pub fn configs_edited(tag: &str, file: &str, from: &str, to: &str) -> PathBuf {
    configs_with(tag, file, |t| {
        assert!(t.contains(from), "`{from}` is not in {file}");
        t.replace(from, to)
    })
}

/// `e` mentions every one of `parts`.
#[track_caller]
pub fn assert_mentions(e: &str, parts: &[&str]) {
    for part in parts {
        assert!(e.contains(part), "`{part}` is not in: {e}");
    }
}

/// An env of `scene` with light preferences wide enough that light never pushes,
/// no dominant fish, and chases never starting unless the test says so.
pub fn calm_env(mut scene: Scene) -> Env {
    scene.physics.chase_probability = 0.0;
    let mut env = Env::new(scene, 7);
    let w = env.world_mut();
    for p in &mut w.light_pref {
        *p = [0.0, 999.0];
    }
    for d in &mut w.dominant {
        *d = false;
    }
    env
}

/// Put fish `i` at `p` heading `f` with speed `bl_per_s` body lengths per second.
pub fn place(env: &mut Env, i: usize, p: Vec3, f: Vec3, bl_per_s: f32) {
    let w = env.world_mut();
    w.position[i] = p;
    w.heading[i] = f.normalize();
    w.roll[i] = 0.0;
    w.speed[i] = bl_per_s * w.bl[i];
}

/// Park fish `i` far from everything else (in a corner region, level, slow).
pub fn park(env: &mut Env, i: usize, slot: usize) {
    let p = Vec3::new(
        -1.2 + 0.6 * (slot % 5) as f32,
        -2.6,
        -1.1 + 0.5 * (slot / 5) as f32,
    );
    place(env, i, p, Vec3::X, 0.0);
}

/// Zero actions for every behaviour.
pub fn zeros(env: &Env) -> Vec<Vec<f32>> {
    env.behaviours()
        .iter()
        .map(|b| vec![0.0; b.count * 3])
        .collect()
}

pub fn close(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol
}

/// Indices of the reward terms in `BehaviourBatch::terms` (`TERM_NAMES` order, Eq. 4.5).
pub const BC: usize = 0;
pub const NC: usize = 1;
pub const BD: usize = 2;
pub const ND: usize = 3;
pub const E: usize = 4;
pub const M: usize = 5;
pub const C: usize = 6;

/// The reward terms of agent `i` of the first behaviour at the latest decision.
pub fn terms(env: &Env, i: usize) -> [f32; 7] {
    env.output().behaviours[0].terms[i]
}

/// Fish 0 at (−0.5, −1.5, −0.3) heading +z, with four neighbours 0.7, 0.3,
/// 0.9 and 0.5 m off along x, headed 60°, 0°, 90° and 30° away from it
/// (r_ND's heading factors 1/3, 1, 0 and 2/3; out of order, so a cap must
/// sort by distance); one step of `env`, and fish 0's reward terms.
pub fn four_neighbours_terms(mut env: Env) -> [f32; 7] {
    let c = Vec3::new(-0.5, -1.5, -0.3);
    place(&mut env, 0, c, Vec3::Z, 0.2);
    for (k, (dx, deg)) in [(0.7f32, 60f32), (0.3, 0.0), (0.9, 90.0), (0.5, 30.0)]
        .into_iter()
        .enumerate()
    {
        let f = Vec3::new(deg.to_radians().sin(), 0.0, deg.to_radians().cos());
        place(&mut env, k + 1, c + Vec3::new(dx, 0.0, 0.0), f, 0.2);
    }
    env.observe_now();
    env.step(&zeros(&env)).unwrap();
    terms(&env, 0)
}

/// Fish 0, dominant, chases fish 1 (a running chase started now).
pub fn start_chase(env: &mut Env) {
    use deepfoids_env::Chase;
    let w = env.world_mut();
    w.dominant[0] = true;
    w.chase[0] = Chase::Aggressor {
        target: 1,
        since: 0.0,
    };
    w.chase[1] = Chase::Target { aggressor: 0 };
}

/// One fish of `scene` at `p`, heading +z at `bl_per_s`, alone and calm: its
/// reward terms after one step.
pub fn lone_fish_terms(scene: Scene, p: Vec3, bl_per_s: f32) -> [f32; 7] {
    let mut env = calm_env(scene);
    place(&mut env, 0, p, Vec3::Z, bl_per_s);
    env.observe_now();
    env.step(&zeros(&env)).unwrap();
    terms(&env, 0)
}

/// Two fish of `scene` side by side 0.03 m apart at (0, −1.5, −1), both
/// heading +z at 0.5 BL/s (each 0.0476 m wide if seabream: they overlap).
pub fn touching_pair(scene: Scene) -> Env {
    let mut env = calm_env(scene);
    let c = Vec3::new(0.0, -1.5, -1.0);
    place(&mut env, 0, c, Vec3::Z, 0.5);
    place(&mut env, 1, c + Vec3::new(0.03, 0.0, 0.0), Vec3::Z, 0.5);
    env.observe_now();
    env
}
