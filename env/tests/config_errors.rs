//! Bad configuration gets a clear error naming the file, the field and what is allowed.
mod common;
use common::{assert_mentions, configs_with, dirs, edit_err, load_err};
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
    let e = edit_err(
        "key",
        "scenes/seabream_default.toml",
        "clock_runs = false",
        "clock_runs = false\nfish_count = 3",
        "seabream_default",
    );
    assert_mentions(&e, &["seabream_default.toml", "fish_count", "line"]);
}

/// A file edit (`tag`, `file`, `from`, `to`), the scene loaded, and what
/// its error must mention.
type Case = (
    &'static str,
    &'static str,
    &'static str,
    &'static str,
    &'static str,
    &'static [&'static str],
);

/// Bad values in scene, species and site files: each refused naming the
/// file, the field and what is allowed (or, for a name, the list of names).
#[test]
fn bad_values_are_refused_by_file_and_field() {
    #[rustfmt::skip]
    let cases: [Case; 5] = [
        ("species", "species/seabream.toml", "sense_range_bl = 3.0", "sense_range_bl = -1.0", "seabream_default", &["seabream.toml", "sense_range_bl", "positive"]),
        ("class", "scenes/coho_small.toml", "size_class = \"small\"", "size_class = \"tiny\"", "coho_small", &["group[0].size_class", "large, regular, small"]),
        ("sp", "scenes/seabream_default.toml", "species = \"seabream\"", "species = \"tuna\"", "seabream_default", &["unknown species `tuna`", "coho, seabream, yellowtail"]),
        ("cage", "scenes/coho_large.toml", "edge = 3.0\nheight = 4.6", "edge = 0.5\nheight = 0.6", "coho_large", &["field `cage`", "too small"]),
        ("date", "scenes/seabream_default.toml", "2021-11-15", "2021-13-01", "seabream_default", &["field `date`", "YYYY-MM-DD"]),
    ];
    for (tag, file, from, to, scene, says) in cases {
        assert_mentions(&edit_err(tag, file, from, to, scene), says);
    }
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

/// Issue 25: a negative fish count once said only "expected usize" — now the
/// file, line, field and the numbers allowed.
#[test]
fn a_negative_count_names_the_field_and_the_range() {
    let root = configs_with("negcount", "scenes/seabream_default.toml", |t| {
        t.replace("count = 10", "count = -1")
    });
    let e = load_err(&root, "seabream_default");
    assert!(
        e.contains("seabream_default.toml: line ")
            && e.contains("field `group[0].count`")
            && e.contains("expected a whole number ≥ 0")
            && !e.contains("usize"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&root);
}

/// Issue 25: a species file that is a folder was "unknown species `seabream`
/// … available: …, seabream, …".
#[test]
fn a_species_file_that_is_a_folder_is_called_a_folder() {
    let root = configs_with("spdir", "species/seabream.toml", |t| t);
    let file = root.join("species/seabream.toml");
    std::fs::remove_file(&file).unwrap();
    std::fs::create_dir(&file).unwrap();
    let e = load_err(&root, "seabream_default");
    assert!(
        e.ends_with("species/seabream.toml is a folder, not a TOML file"),
        "{e}"
    );
    assert!(!e.contains("unknown"), "{e}");
    let _ = std::fs::remove_dir_all(&root);
}

/// Issue 25: a missing configuration folder gave "unknown scene … available: "
/// with nothing after it.
#[test]
fn a_missing_configuration_folder_is_named() {
    let root = std::env::temp_dir().join(format!("deepfoids-no-configs-{}", std::process::id()));
    let e = load_err(&root, "seabream_default");
    assert_eq!(
        e,
        format!(
            "the configuration folder {} does not exist; it should hold species/, sites/, scenes/, rewards/ and train/",
            root.display()
        )
    );
    // A root without the sub-folder says so rather than listing nothing.
    std::fs::create_dir_all(&root).unwrap();
    let e = load_err(&root, "seabream_default");
    assert!(
        e.contains("unknown scene `seabream_default`")
            && e.ends_with(&format!("{} does not exist", root.join("scenes").display())),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&root);
}

/// Issue 25: `temperature_pref` has no lower bound; its message printed
/// f32::MIN, "at least -340282350000000000000000000000000000000".
#[test]
fn an_unbounded_range_prints_no_huge_bound() {
    let root = configs_with("temp", "species/seabream.toml", |t| {
        let line = t
            .lines()
            .find(|l| l.starts_with("temperature_pref"))
            .unwrap()
            .to_string();
        t.replace(&line, "temperature_pref = [25.0, 15.0]")
    });
    let e = load_err(&root, "seabream_default");
    assert!(
        e.contains("field `temperature_pref`: range [25, 15] must be two finite numbers, ordered low to high"),
        "{e}"
    );
    assert!(!e.contains("000000"), "{e}");
    let _ = std::fs::remove_dir_all(&root);
}

/// Issue 25: a binary file as a scene printed its cause twice.
#[test]
fn a_binary_scene_file_says_its_cause_once() {
    let root = configs_with("binary", "scenes/seabream_default.toml", |t| t);
    std::fs::write(
        root.join("scenes/seabream_default.toml"),
        [0xff, 0xfe, 0, 1],
    )
    .unwrap();
    let err =
        Scene::load(&ConfigDirs::new(&root), "seabream_default", Phase::Pretrain).unwrap_err();
    let chain = anyhow_like(&err);
    assert_eq!(chain.matches("not UTF-8 text").count(), 1, "{chain}");
    let _ = std::fs::remove_dir_all(&root);
}

/// The error and its sources as the binary prints them (`{:#}` of anyhow).
fn anyhow_like(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut source = e.source();
    while let Some(c) = source {
        s.push_str(&format!(": {c}"));
        source = c.source();
    }
    s
}

/// A spawn pitch out of range is blamed on its own field (it was blamed on
/// `physics.spawn_margin_bl`).
#[test]
fn a_bad_spawn_pitch_names_its_own_field() {
    let root = configs_with("pitch", "scenes/seabream_default.toml", |t| {
        format!("{t}\n[physics]\nspawn_pitch_deg = 95.0\n")
    });
    let e = load_err(&root, "seabream_default");
    assert!(
        e.contains("physics.spawn_pitch_deg") && e.contains("[0, 90)") && e.contains("95"),
        "{e}"
    );
}

/// Every reward profile in the repository's `configs/rewards/` loads in both
/// phases within the limits, and docs/reward-profiles.md lists it: a profile
/// committed for an experiment is usable from the CLI and documented.
#[test]
fn every_shipped_reward_profile_loads_and_is_documented() {
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let dirs = ConfigDirs::new(repo.join("configs"));
    let profiles = dirs.reward_profiles();
    for needed in [
        "thesis",
        "legacy",
        deepfoids_env::config::DEFAULT_REWARD_PROFILE,
    ] {
        assert!(
            profiles.iter().any(|p| p == needed),
            "{needed} missing: {profiles:?}"
        );
    }
    let doc = std::fs::read_to_string(repo.join("docs/reward-profiles.md")).unwrap();
    for p in &profiles {
        let dirs = dirs.clone().with_reward_profile(p.as_str());
        for phase in [Phase::Pretrain, Phase::Transfer] {
            if let Err(e) = dirs.rewards(phase) {
                panic!("profile {p}, {phase:?}: {e}");
            }
        }
        assert!(
            doc.contains(&format!("| `{p}` |")),
            "docs/reward-profiles.md has no row for `{p}`"
        );
    }
}

/// A lane-ahead personal space needs the personal space it stretches: alone it
/// is refused naming the file, the field and the one it needs.
#[test]
fn a_lane_ahead_without_a_personal_space_is_refused() {
    let root = configs_with("ahead", "rewards/thesis/pretrain.toml", |t| {
        format!("{t}\n[extensions]\npersonal_space_ahead_bl = 1.0\n")
    });
    assert_mentions(
        &load_err(&root, "seabream_default"),
        &[
            "pretrain.toml",
            "extensions.personal_space_ahead_bl",
            "extensions.personal_space_bl > 0",
        ],
    );
}

/// A share of mirrored fish above 1 (or negative) is refused naming the file,
/// the field, the value and the bound.
#[test]
fn a_mirrored_share_outside_zero_to_one_is_refused() {
    for (v, says) in [
        ("1.5", "above the limit of 1"),
        ("-0.2", "below the limit of 0"),
    ] {
        let root = configs_with("mirrored", "rewards/thesis/pretrain.toml", |t| {
            format!("{t}\n[extensions]\nmirrored_share = {v}\n")
        });
        assert_mentions(
            &load_err(&root, "seabream_default"),
            &["pretrain.toml", "extensions.mirrored_share", v, says],
        );
    }
}

/// What the policy sees must be the same in both phases of a profile: a
/// `closing` heading in the pretraining alone is refused naming the file,
/// the field and the other phase's file.
#[test]
fn a_heading_of_one_phase_only_is_refused() {
    let root = configs_with("heading", "rewards/thesis/pretrain.toml", |t| {
        format!("{t}\n[extensions]\nheading_of = \"closing\"\n")
    });
    assert_mentions(
        &load_err(&root, "seabream_default"),
        &[
            "pretrain.toml",
            "extensions.heading_of",
            "closing here but front in",
            "transfer.toml",
        ],
    );
}

/// A profile is checked whole: a broken transfer file is refused when the
/// pretraining loads, naming that file and its field, not hours later when
/// the transfer starts.
#[test]
fn a_broken_transfer_file_is_refused_before_the_pretraining() {
    let root = configs_with("transfer-nan", "rewards/thesis/transfer.toml", |t| {
        t.replace("w_nc = 4.0", "w_nc = nan")
    });
    assert_mentions(
        &load_err(&root, "seabream_default"),
        &["rewards/thesis/transfer.toml", "w_nc", "finite"],
    );
    let root = configs_with("transfer-gone", "rewards/thesis/transfer.toml", |t| t);
    std::fs::remove_file(root.join("rewards/thesis/transfer.toml")).unwrap();
    assert_mentions(
        &load_err(&root, "seabream_default"),
        &["reward weights", "transfer", "rewards/thesis"],
    );
}
