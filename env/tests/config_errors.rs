//! Bad configuration gets a clear error naming the file, the field and what is allowed.
mod common;
use common::{configs_with, dirs, load_err};
use deepfoids_env::{ConfigDirs, Phase, Scene};

#[test]
fn an_unknown_scene_lists_the_available_ones() {
    let e = Scene::load(&dirs(), "coho_defualt", Phase::Pretrain)
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown scene `coho_defualt`"), "{e}");
    assert!(
        e.contains("coho_default") && e.contains("seabream_default") && e.contains("density_dense"),
        "{e}"
    );
}

#[test]
fn an_unknown_key_is_rejected_with_file_and_line() {
    let root = configs_with("key", "scenes/seabream_default.toml", |t| {
        t.replace("clock_runs = false", "clock_runs = false\nfish_count = 3")
    });
    let e = load_err(&root, "seabream_default");
    assert!(
        e.contains("seabream_default.toml") && e.contains("fish_count"),
        "{e}"
    );
    assert!(e.contains("line"), "{e}");
}

#[test]
fn a_bad_species_value_names_the_field() {
    let root = configs_with("species", "species/seabream.toml", |t| {
        t.replace("sense_range_bl = 3.0", "sense_range_bl = -1.0")
    });
    let e = load_err(&root, "seabream_default");
    assert!(
        e.contains("seabream.toml") && e.contains("sense_range_bl") && e.contains("positive"),
        "{e}"
    );
}

#[test]
fn an_unknown_size_class_lists_the_allowed() {
    let root = configs_with("class", "scenes/coho_small.toml", |t| {
        t.replace("size_class = \"small\"", "size_class = \"tiny\"")
    });
    let e = load_err(&root, "coho_small");
    assert!(
        e.contains("group[0].size_class") && e.contains("large, regular, small"),
        "{e}"
    );
}

#[test]
fn an_unknown_species_lists_the_available() {
    let root = configs_with("sp", "scenes/seabream_default.toml", |t| {
        t.replace("species = \"seabream\"", "species = \"tuna\"")
    });
    let e = load_err(&root, "seabream_default");
    assert!(
        e.contains("unknown species `tuna`") && e.contains("coho, seabream, yellowtail"),
        "{e}"
    );
}

#[test]
fn a_cage_too_small_for_its_fish_is_rejected() {
    let root = configs_with("cage", "scenes/coho_large.toml", |t| {
        t.replace("edge = 3.0\nheight = 4.6", "edge = 0.5\nheight = 0.6")
    });
    let e = load_err(&root, "coho_large");
    assert!(e.contains("field `cage`") && e.contains("too small"), "{e}");
}

#[test]
fn a_bad_date_names_the_field() {
    let root = configs_with("date", "scenes/seabream_default.toml", |t| {
        t.replace("2021-11-15", "2021-13-01")
    });
    let e = load_err(&root, "seabream_default");
    assert!(
        e.contains("field `date`") && e.contains("YYYY-MM-DD"),
        "{e}"
    );
}

#[test]
fn species_overrides_apply() {
    let root = configs_with("override", "scenes/seabream_default.toml", |t| {
        format!(
            "{t}\n[species_overrides.seabream]\nsense_range_bl = 2.5\n[species_overrides.seabream.size_classes.regular]\nlight_lpref = 1.0\n"
        )
    });
    let s = Scene::load(&ConfigDirs::new(&root), "seabream_default", Phase::Transfer).unwrap();
    assert_eq!(s.behaviours[0].species.sense_range_bl, 2.5);
    assert_eq!(
        s.behaviours[0].light_lpref,
        deepfoids_env::config::Range::Fixed(1.0)
    );
    assert_eq!(
        s.behaviours[0].light_hpref,
        deepfoids_env::config::Range::Fixed(368.0)
    );
    assert_eq!(s.rewards.w_nc, 4.0, "transfer weights");
    // The resolved scene serialises (run folders store it).
    assert!(
        s.to_toml().contains("sense_range_bl = 2.5"),
        "{}",
        s.to_toml()
    );
}

#[test]
fn every_shipped_scene_matches_the_thesis() {
    let want = [
        ("coho_default", 1000, 199.9),
        ("yellowtail_default", 45, 27.0),
        ("seabream_default", 10, 27.0),
        ("seabream_cube5", 10, 125.0),
        ("seabream_50", 50, 27.0),
        ("coho_small", 300, 199.9),
        ("coho_regular", 300, 199.9),
        ("coho_large", 300, 199.9),
        ("coho_mixed_small_cage", 1000, 46.9),
        ("coho_mixed", 1000, 199.9),
        ("three_species", 300, 199.9),
    ];
    for (id, n, volume) in want {
        let s = Scene::load(&dirs(), id, Phase::Pretrain).unwrap();
        assert_eq!(s.fish_count(), n, "{id}");
        assert!(
            (s.cage().volume() - volume).abs() < 0.1,
            "{id}: {}",
            s.cage().volume()
        );
    }
    let sparse = Scene::load(&dirs(), "density_sparse", Phase::Pretrain).unwrap();
    assert!(
        (sparse.density() - 0.59).abs() < 0.01,
        "{}",
        sparse.density()
    );
    let dense = Scene::load(&dirs(), "density_dense", Phase::Pretrain).unwrap();
    assert!((dense.density() - 14.7).abs() < 0.05, "{}", dense.density());
}
