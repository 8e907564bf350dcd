//! Issue 13: every size, count and duration of a configuration has an upper
//! bound, named with the file, field, value and bound; a value a scene
//! overrides is blamed on the scene file.
mod common;
use common::{assert_mentions, configs_edited, configs_with, edit_err, load_err};
use deepfoids_env::baselines::{BoidsConfig, FoidsConfig};
use deepfoids_env::{ConfigDirs, Phase, Scene};

/// The scene file `seabream_default` with `from` replaced by `to`.
fn scene_err(name: &str, from: &str, to: &str) -> String {
    let root = configs_with(name, "scenes/seabream_default.toml", |t| {
        assert!(t.contains(from), "{from} is not in the scene");
        t.replace(from, to)
    });
    load_err(&root, "seabream_default")
}

/// The seabream default scene with `extra` appended (overrides, physics).
fn scene_plus_err(name: &str, extra: &str) -> String {
    let root = configs_with(name, "scenes/seabream_default.toml", |t| {
        format!("{t}\n{extra}\n")
    });
    load_err(&root, "seabream_default")
}

#[test]
fn a_typo_in_a_fish_count_is_refused_before_anything_is_allocated() {
    // This once asked the allocator for 4.9 TB and aborted.
    let e = scene_err("count", "count = 10", "count = 100000000");
    assert!(
        e.ends_with(
            "scenes/seabream_default.toml: group[0].count = 100000000 is above the limit of 200000 fish"
        ),
        "{e}"
    );
    // This once ran until the OOM killer stopped it at 23.6 GB.
    let e = scene_err("count-max", "count = 10", "count = 18446744073709551615");
    assert!(
        e.contains("group[0].count = 18446744073709551615 is above the limit of 200000 fish"),
        "{e}"
    );
}

#[test]
fn the_groups_together_stay_within_the_fish_bound() {
    let group = "[[group]]\nspecies = \"seabream\"\nsize_class = \"regular\"\ncount = 150000\n";
    let root = configs_with("total", "scenes/seabream_default.toml", |t| {
        format!("{}\n{group}\n{group}", t.replace("count = 10", "count = 1"))
    });
    let e = load_err(&root, "seabream_default");
    assert!(
        e.contains(
            "the groups' counts = 300001 fish in all is above the limit of 200000 fish in a scene"
        ),
        "{e}"
    );
}

#[test]
fn a_cage_of_1e30_metres_is_refused() {
    let e = scene_err("edge", "edge = 3.0", "edge = 1e30");
    assert!(
        e.ends_with("seabream_default.toml: cage.edge = 1e30 is above the limit of 1000 m"),
        "{e}"
    );
    let e = scene_err("edge-inf", "edge = 3.0", "edge = inf");
    assert!(e.contains("cage.edge") && e.contains("finite"), "{e}");
}

#[test]
fn a_physics_step_too_short_for_the_decision_interval_is_refused() {
    let e = scene_plus_err("dt", "[physics]\ndt_sim = 1e-7");
    assert!(
        e.contains("physics.dt_sim = 1e-7 s (giving")
            && e.contains(
                "physics steps per decision of seabream) is above the limit of 1000 steps"
            ),
        "{e}"
    );
    let e = scene_plus_err("episode", "[physics]\nmax_episode_decisions = 4000000000");
    assert!(
        e.contains(
            "physics.max_episode_decisions = 4000000000 is above the limit of 1000000 decisions"
        ),
        "{e}"
    );
    let e = scene_plus_err("chase", "[physics]\nchase_timeout = 1e9");
    assert!(
        e.contains("physics.chase_timeout = 1e9 is above the limit of 3600 s"),
        "{e}"
    );
    let e = scene_plus_err("pitch", "[physics]\npitch_threshold_deg = nan");
    assert!(
        e.contains("physics.pitch_threshold_deg") && e.contains("finite"),
        "{e}"
    );
}

#[test]
fn obstacles_are_bounded_in_number_and_size() {
    let sphere = "[[obstacle]]\nkind = \"sphere\"\ncenter = [0.0, -1.5, 0.0]\nradius = 0.2\n";
    let e = scene_plus_err("obstacles", &sphere.repeat(257));
    assert!(
        e.contains("obstacle = 257 is above the limit of 256 obstacles"),
        "{e}"
    );
    let e = scene_plus_err(
        "obstacle-nan",
        "[[obstacle]]\nkind = \"sphere\"\ncenter = [nan, -1.5, 0.0]\nradius = 0.2\n",
    );
    assert!(e.contains("obstacle[0]") && e.contains("finite"), "{e}");
}

#[test]
fn species_site_and_reward_values_have_bounds() {
    #[rustfmt::skip]
    let cases: [(&str, &str, &str, &str, &[&str]); 6] = [
        ("bl", "species/seabream.toml", "body_length = 0.34", "body_length = 1e30", &["species/seabream.toml: body_length = 1e30 is above the limit of 10 m"]),
        ("steep", "species/seabream.toml", "body_length", "light_steep = [nan, 1000.0]\nbody_length", &["light_steep[0]", "finite"]),
        ("temp", "sites/nishiki.toml", "surface_temperature = 22.0", "surface_temperature = nan", &["sites/nishiki.toml", "surface_temperature", "finite"]),
        ("light", "sites/nishiki.toml", "surface_light_max = 15.13", "surface_light_max = inf", &["surface_light_max", "finite"]),
        ("reward", "rewards/thesis/pretrain.toml", "w_nc = 0.5", "w_nc = nan", &["rewards/thesis/pretrain.toml", "w_nc", "finite"]),
        ("reward-big", "rewards/thesis/pretrain.toml", "catch_bonus = 100.0", "catch_bonus = 1e12", &["catch_bonus = 1e12 is above the limit of 10000"]),
    ];
    for (tag, file, from, to, says) in cases {
        assert_mentions(&edit_err(tag, file, from, to, "seabream_default"), says);
    }
}

/// The loading error of baseline `name` (`baselines/<name>.toml`) with `from`
/// replaced by `to`, loaded by `load`.
fn baseline_err<T, E: std::fmt::Display>(
    tag: &str,
    name: &str,
    from: &str,
    to: &str,
    load: fn(&std::path::Path) -> Result<T, E>,
) -> String {
    let root = configs_edited(tag, &format!("baselines/{name}.toml"), from, to);
    match load(&ConfigDirs::new(&root).baseline(name).unwrap()) {
        Ok(_) => panic!("{name}.toml with {to} loaded"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn baseline_parameters_have_bounds() {
    let foids = |tag, from, to| baseline_err(tag, "foids", from, to, FoidsConfig::load);
    let e = foids(
        "foids",
        "night_speed = [0.0, 0.4]",
        "night_speed = [0.4, 0.0]",
    );
    assert!(e.contains("foids.toml") && e.contains("night_speed"), "{e}");
    let e = foids("foids-nan", "hover_start = 0.01", "hover_start = nan");
    assert!(e.contains("hover_start") && e.contains("finite"), "{e}");
    let e = baseline_err(
        "boids",
        "boids",
        "perception = 3.0",
        "perception = 1e9",
        BoidsConfig::load,
    );
    assert!(
        e.contains("boids.toml: perception = 1e9 is above the limit of 100 BL"),
        "{e}"
    );
}

#[test]
fn a_config_file_over_a_mebibyte_is_not_read() {
    let e = scene_plus_err("huge", &format!("# {}", "x".repeat(2 << 20)));
    assert!(
        e.contains(
            "seabream_default.toml: the file is larger than 1048576 bytes, the limit of a configuration file"
        ),
        "{e}"
    );
}

#[test]
fn a_bad_species_override_names_the_scene_file() {
    let e = scene_plus_err(
        "ov-species",
        "[species_overrides.seabream]\nsense_range_bl = -1.0",
    );
    assert!(
        e.contains("scenes/seabream_default.toml: field `species_overrides.seabream.sense_range_bl`: must be a positive number"),
        "{e}"
    );
    assert!(!e.contains("species/seabream.toml"), "{e}");
    // Bounds and nested tables too.
    let e = scene_plus_err(
        "ov-scale",
        "[species_overrides.seabream.size_classes.regular]\nbody_scale = 1e9",
    );
    assert!(
        e.contains("scenes/seabream_default.toml: species_overrides.seabream.size_classes.regular.body_scale = 1e9 is above the limit of 10 ×"),
        "{e}"
    );
    // A wrong type and an unknown key are the override's too.
    let e = scene_plus_err(
        "ov-type",
        "[species_overrides.seabream]\nsense_range_bl = \"far\"",
    );
    assert!(
        e.contains("scenes/seabream_default.toml: field `species_overrides.seabream.sense_range_bl`: invalid type")
            && e.contains("applied to")
            && e.contains("species/seabream.toml"),
        "{e}"
    );
    let e = scene_plus_err(
        "ov-key",
        "[species_overrides.seabream]\nsense_rnage_bl = 2.0",
    );
    assert!(
        e.contains("scenes/seabream_default.toml: field `species_overrides.seabream.sense_rnage_bl`: unknown field"),
        "{e}"
    );
    // An override that makes another value of the species file invalid.
    let e = scene_plus_err(
        "ov-cross",
        "[species_overrides.seabream]\nspeed_bl = [0.05, 0.1]",
    );
    assert!(
        e.contains("scenes/seabream_default.toml: field `species_overrides.seabream.speed_bl`: field `initial_speed_bl`"),
        "{e}"
    );
}

#[test]
fn a_bad_site_override_names_the_scene_file() {
    let e = scene_plus_err("ov-site", "[site_overrides]\nsurface_temperature = 1e9");
    assert!(
        e.contains("scenes/seabream_default.toml: site_overrides.surface_temperature = 1e9 is above the limit of 50 °C"),
        "{e}"
    );
    let e = scene_plus_err("ov-site-lat", "[site_overrides]\nlatitude_deg = 100.0");
    assert!(
        e.contains("scenes/seabream_default.toml: field `site_overrides.latitude_deg`: must lie in [-90, 90]"),
        "{e}"
    );
    // An error of the site file itself still names the site file.
    let e = edit_err(
        "site-own",
        "sites/nishiki.toml",
        "attenuation = 0.26",
        "attenuation = -1.0",
        "seabream_default",
    );
    assert_mentions(&e, &["sites/nishiki.toml: field `attenuation`"]);
}

#[test]
fn every_shipped_configuration_is_within_the_bounds() {
    let dirs = common::dirs();
    for id in dirs.list("scenes") {
        Scene::load(&dirs, &id, Phase::Pretrain).unwrap();
        Scene::load(&dirs, &id, Phase::Transfer).unwrap();
    }
    FoidsConfig::load(&dirs.baseline("foids").unwrap()).unwrap();
    BoidsConfig::load(&dirs.baseline("boids").unwrap()).unwrap();
}
