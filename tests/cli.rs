//! Integration tests of the `deepfoids` binary: the commands a user runs.

mod support;

use support::{TempDir, cli, cli_fails, cli_ok, json, temp_path, text};

fn temp(name: &str) -> TempDir {
    temp_path("cli", name)
}

#[test]
fn scenes_lists_every_scene_with_density() {
    let o = cli_ok("scenes");
    let t = text(&o);
    for id in [
        "coho_default",
        "yellowtail_default",
        "seabream_default",
        "three_species",
        "density_sparse",
        "density_dense",
    ] {
        assert!(t.contains(id), "{id} missing:\n{t}");
    }
    assert!(t.contains("14.706") && t.contains("0.594"), "{t}");
}

/// 2 s of seabream (k = 5, 0.1 s decisions): 21 snapshots (t = 0 and 20 decisions) × 10 fish.
#[test]
fn simulate_writes_trajectories() {
    let out = temp("simulate");
    let o = cli_ok(&format!(
        "simulate --scene seabream_default --seconds 2 --seed 4 --out {}",
        out.display()
    ));
    let csv = std::fs::read_to_string(out.join("trajectories.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("t,fish,behaviour,x,y,z,dx,dy,dz,speed,bl")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 21 * 10);
    for r in &rows {
        assert_eq!(r.len(), 11);
        assert_eq!(r[2], "seabream_regular");
        let f: Vec<f32> = [3, 4, 5, 6, 7, 8, 9, 10]
            .iter()
            .map(|&i| r[i].parse().unwrap())
            .collect();
        let norm = (f[3] * f[3] + f[4] * f[4] + f[5] * f[5]).sqrt();
        assert!((norm - 1.0).abs() < 1e-3, "heading is a unit vector: {r:?}");
        assert!(
            f[0].abs() < 1.5 && f[1] < 0.0 && f[1] > -3.0 && f[2].abs() < 1.5,
            "inside the 3 m cube: {r:?}"
        );
        assert!((0.3..0.38).contains(&f[7]), "bl {r:?}");
    }
    assert_eq!(rows.last().unwrap()[0], "2.000");
    // Same seed, same file.
    let again = temp("simulate-again");
    cli(&format!(
        "simulate --scene seabream_default --seconds 2 --seed 4 --out {}",
        again.display()
    ));
    assert_eq!(
        csv,
        std::fs::read_to_string(again.join("trajectories.csv")).unwrap()
    );
    assert!(text(&o).contains("seabream_regular"));
}

/// With `bounce` a net collision pays r_BC (300) without ending the episode;
/// the table's BC/fish·h counts those collisions, not episode ends: seabream
/// decide every 0.1 s, so 36,000 decisions make a fish-hour and
/// BC/fish·h = −r_BC per decision / 300 × 36,000.
#[test]
fn simulate_counts_collisions_that_do_not_end_the_episode() {
    let out = temp("simulate-bounce");
    let o = cli_ok(&format!(
        "simulate --scene seabream_default --reward-profile bounce --seconds 20 --seed 4 --out {}",
        out.display()
    ));
    let t = text(&o);
    let row: Vec<f64> = t
        .lines()
        .find(|l| l.starts_with("seabream_regular") && l.contains("2000"))
        .unwrap_or_else(|| panic!("no tally row:\n{t}"))
        .split_whitespace()
        .skip(1)
        .map(|v| v.parse().unwrap())
        .collect();
    let (r_bc, bc) = (row[2], row[9]);
    assert!(r_bc < 0.0, "random fish hit the net in 20 s:\n{t}");
    assert!((bc - -r_bc / 300.0 * 36_000.0).abs() < 0.6, "{t}");
}

#[test]
fn sensor_view_writes_a_png() {
    let dir = temp("view");
    let out = dir.join("view.png");
    cli_ok(&format!(
        "sensor-view --scene seabream_default --fish 3 --step 5 --out {}",
        out.display()
    ));
    let img = image::open(&out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (1800, 560));
    // Not blank: the black background of the grid and white margins both appear.
    let dark = img.pixels().filter(|p| p.0.iter().all(|&c| c < 40)).count();
    let white = img
        .pixels()
        .filter(|p| p.0.iter().all(|&c| c > 250))
        .count();
    assert!(
        dark > 10_000 && white > 10_000,
        "dark {dark}, white {white}"
    );
}

#[test]
fn an_unknown_scene_fails_with_the_list() {
    let t = cli_fails("simulate --scene salmon", "unknown scene `salmon`");
    assert!(t.contains("coho_default"), "{t}");
    assert_eq!(
        t.lines().filter(|l| l.starts_with("error:")).count(),
        1,
        "one clear line: {t}"
    );
}

#[test]
fn an_unknown_policy_fails_clearly() {
    cli_fails(
        "simulate --scene seabream_default --policy genius",
        "unknown policy `genius`",
    );
    cli_fails(
        "simulate --scene seabream_default --policy runs/none/policy.onnx",
        "policy `runs/none/policy.onnx` does not exist",
    );
}

/// `eval` on a small scene writes every file; the CSV parses; the PNGs decode;
/// the summary carries scene, policy and seed.
#[test]
fn eval_writes_metrics_summary_and_plots() {
    for policy in ["foids", "boids", "random"] {
        let out = temp(&format!("eval-{policy}"));
        let o = cli_ok(&format!(
            "eval --scene seabream_50 --policy {} --seconds 5 --seed 2 --out {}",
            policy,
            out.display()
        ));
        assert!(
            text(&o).contains("P ") && text(&o).contains("state:"),
            "{}",
            text(&o)
        );
        let csv = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(&header[..4], &["t", "P", "M", "state"]);
        let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
        assert_eq!(rows.len(), 51, "t = 0 and 50 ticks of 0.1 s");
        for r in &rows {
            assert_eq!(r.len(), header.len());
            let (p, m): (f32, f32) = (r[1].parse().unwrap(), r[2].parse().unwrap());
            assert!((0.0..=1.0).contains(&p) && (0.0..=1.0).contains(&m));
            assert!(["swarm", "milling", "polarised", "transitional"].contains(&r[3]));
        }
        let json = json(&out.join("summary.json"));
        assert_eq!(json["scene"], "seabream_50");
        assert_eq!(json["policy"], policy);
        assert_eq!(json["seed"], 2);
        let shares: f64 = json["summary"]["state_share"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x[1].as_f64().unwrap())
            .sum();
        assert!((shares - 1.0).abs() < 1e-5);
        assert!(
            json["summary"]["behaviours"][0]["terms_per_decision"]
                .as_array()
                .unwrap()
                .len()
                == 7
        );
        for png in ["pm.png", "depth.png", "trajectories.png"] {
            let img = image::open(out.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
            assert!(img.width() > 500 && img.height() > 400, "{png}");
        }
    }
}

/// `--fish-count` resizes a scene of one group: a lone seabream in `seabream_50`'s
/// cage, recorded in summary.json so that `replay --from` simulates the same
/// lone fish again (it checks P and M against metrics.csv); its turning is
/// measured. A scene of several groups, or 0 fish, is refused by name.
#[test]
fn fish_count_resizes_a_scene_of_one_group() {
    let out = temp("eval-lone");
    let o = cli_ok(&format!(
        "eval --scene seabream_50 --fish-count 1 --policy foids --seconds 3 --seed 4 --out {}",
        out.display()
    ));
    assert!(
        text(&o).contains("nearest neighbour none (a lone fish)") && text(&o).contains("turning "),
        "{}",
        text(&o)
    );
    let summary = json(&out.join("summary.json"));
    assert_eq!(summary["summary"]["fish"], 1);
    assert_eq!(summary["rerun"]["fish"], 1);
    let turn = summary["summary"]["turn_rate_deg_s"].as_f64().unwrap();
    assert!(turn.is_finite() && turn.abs() < 180.0, "{turn}");
    let share = summary["summary"]["clockwise_share"].as_f64().unwrap();
    assert!(
        share == 0.0 || share == 1.0,
        "one fish turns one way: {share}"
    );
    let page = out.join("replay.html");
    cli_ok(&format!(
        "replay --from {} --out {}",
        out.display(),
        page.display()
    ));
    // Without --fish-count the summary keeps the scene's 50 and no `fish` key.
    let full = temp("eval-fifty");
    cli_ok(&format!(
        "eval --scene seabream_50 --policy foids --seconds 0.5 --out {}",
        full.display()
    ));
    let summary = json(&full.join("summary.json"));
    assert_eq!(summary["summary"]["fish"], 50);
    assert!(summary["rerun"].get("fish").is_none(), "{summary}");

    let refused = temp("eval-refused");
    cli_fails(
        &format!(
            "eval --scene three_species --fish-count 10 --seconds 1 --out {}",
            refused.display()
        ),
        "three_species.toml: field `group`: --fish-count resizes a scene of one [[group]] of fish; this one has 3 groups",
    );
    cli_fails(
        &format!(
            "simulate --scene seabream_50 --fish-count 0 --seconds 1 --out {}",
            refused.display()
        ),
        "--fish-count must be 1 to 200000, got 0",
    );
    assert!(!refused.exists(), "nothing is written");
}

#[test]
fn simulate_takes_the_baselines_too() {
    let out = temp("simulate-foids");
    let o = cli_ok(&format!(
        "simulate --scene yellowtail_default --policy foids --seconds 1 --out {}",
        out.display()
    ));
    assert!(text(&o).contains("policy foids"));
}

/// `--steps-per-fish` gives each behaviour its fish count times the decisions:
/// seabream_default's 10 fish × 30 = 300 agent steps, recorded as the run's
/// budget; it cannot be given with `--steps`.
#[test]
fn a_budget_per_fish_is_the_school_times_it() {
    let runs = temp("per-fish");
    cli_ok(&format!(
        "train --scene seabream_default --steps-per-fish 30 --allow-no-update --seed 5 --runs-dir {} --run-id pf --eval-seconds 0 --quiet",
        runs.display()
    ));
    let config = std::fs::read_to_string(runs.join("pf/config.toml")).unwrap();
    assert!(config.contains("seabream_regular = 300"), "{config}");
    // The instruction set the kernels ran on: a seed reproduces bit for bit only on one.
    let isa = deepfoids_learn::kernels::instruction_set();
    assert!(["avx512", "avx2", "plain"].contains(&isa));
    assert!(
        config.contains(&format!("instruction_set = \"{isa}\"")),
        "{config}"
    );
    let state = json(&runs.join("pf/final/state.json"));
    assert_eq!(state["agent_steps"], 300, "{state}");
    cli_fails(
        "train --scene seabream_default --steps 100 --steps-per-fish 30",
        "cannot be used with",
    );
    cli_fails(
        "train --scene seabream_default --steps-per-fish 0",
        "--steps-per-fish 0 would train nothing",
    );
    // seabream_default's first update comes after 10,241 agent steps: 1,025 per fish.
    cli_fails(
        "train --scene seabream_default --steps-per-fish 100",
        "(or --steps-per-fish to at least 1025)",
    );
}

/// train (a few decisions) → export → eval with the .onnx (tract) and with the run
/// folder (Burn): the same seed drives the same school.
#[test]
fn train_export_and_eval_through_onnx() {
    let runs = temp("train");
    cli_ok(&format!(
        "train --scene seabream_default --steps 600 --allow-no-update --seed 5 --runs-dir {} --run-id tiny --eval-seconds 0 --quiet",
        runs.display()
    ));
    let run = runs.join("tiny");
    for f in [
        "config.toml",
        "scalars.csv",
        "final/state.json",
        "final/seabream_regular.model.bpk",
        "final/seabream_regular.onnx",
    ] {
        assert!(run.join(f).exists(), "{f} missing");
    }
    // Refuses to overwrite without --resume/--force.
    cli_fails(
        &format!(
            "train --scene seabream_default --steps 600 --allow-no-update --seed 5 --runs-dir {} --run-id tiny",
            runs.display()
        ),
        "--resume",
    );
    // A finished run has no checkpoint to resume: the refusal says how to go on.
    cli_fails(
        &format!(
            "train --scene seabream_default --steps 1200 --allow-no-update --seed 5 --runs-dir {} --run-id tiny --resume",
            runs.display()
        ),
        "it finished",
    );

    let onnx = runs.join("policy.onnx");
    let o = cli_ok(&format!(
        "export --run {} --out {}",
        run.display(),
        onnx.display()
    ));
    assert!(text(&o).contains("opset 9"), "{}", text(&o));
    // The run's own final/<behaviour>.onnx is the same file.
    assert_eq!(
        std::fs::read(&onnx).unwrap(),
        std::fs::read(run.join("final/seabream_regular.onnx")).unwrap()
    );
    // It names the reward profile the run trained under (the default one).
    let meta = deepfoids_onnx::runtime::read_metadata(&std::fs::read(&onnx).unwrap());
    let profile = std::fs::read_to_string(run.join("config.toml")).unwrap();
    let profile: toml::Table = profile.parse().unwrap();
    assert_eq!(
        meta["reward_profile"],
        profile["scene"]["reward_profile"].as_str().unwrap()
    );
    // A SAC run does not start from a PPO run.
    cli_fails(
        &format!(
            "train --algo sac --scene seabream_default --phase transfer --init-from {} --runs-dir {} --run-id sac-from-ppo --quiet",
            run.display(),
            runs.display()
        ),
        "holds a ppo policy; sac is needed",
    );
    let mut pm = vec![];
    for policy in [onnx.to_str().unwrap(), run.to_str().unwrap()] {
        let out = runs.join(format!("eval-{}", pm.len()));
        cli_ok(&format!(
            "eval --scene seabream_default --policy {} --seconds 3 --seed 9 {} --out {}",
            policy, // The mean action: the ONNX runtime and Burn draw samples differently.
            "--deterministic",
            out.display()
        ));
        let json = json(&out.join("summary.json"));
        pm.push((
            json["summary"]["p_mean"].as_f64().unwrap(),
            json["summary"]["m_mean"].as_f64().unwrap(),
        ));
    }
    assert!(
        (pm[0].0 - pm[1].0).abs() < 1e-3 && (pm[0].1 - pm[1].1).abs() < 1e-3,
        "onnx {:?} vs burn {:?}",
        pm[0],
        pm[1]
    );
    // A seabream policy cannot drive a coho scene.
    cli_fails(
        &format!(
            "eval --scene coho_small --policy {} --seconds 1",
            onnx.display()
        ),
        "seabream policy",
    );
}

/// A PPO and a SAC run of 1,000 steps each, then `compare`: both PNGs, the
/// Markdown and CSV tables, and the table printed, one row per run.
#[test]
fn compare_ppo_and_sac_runs() {
    let runs = temp("compare");
    for algo in ["ppo", "sac"] {
        let o = cli(&format!(
            "train --algo {} --scene seabream_default --steps 1000 --allow-no-update --runs-dir {} --run-id {} --eval-seconds 0 --quiet",
            algo,
            runs.display(),
            algo
        ));
        assert!(o.status.success(), "{algo}: {}", text(&o));
        let state = std::fs::read_to_string(runs.join(algo).join("final/state.json")).unwrap();
        assert!(state.contains(&format!("\"algo\": \"{algo}\"")), "{state}");
    }
    let sac_csv = std::fs::read_to_string(runs.join("sac/scalars.csv")).unwrap();
    // 1,000 steps end before the first update (learning_starts is 5,000): no
    // losses yet, but the entropy coefficient and the environment's scalars.
    assert!(sac_csv.contains("Policy/Entropy Coeff") && !sac_csv.contains("Losses/Q1 Loss"));
    assert!(sac_csv.contains("Environment/Reward per Decision"));
    let out = runs.join("cmp");
    let o = cli_ok(&format!(
        "compare {} {} --seconds 2 --seeds 2 --out {}",
        runs.join("ppo").to_str().unwrap(),
        runs.join("sac").to_str().unwrap(),
        out.display()
    ));
    let printed = text(&o);
    assert!(
        printed.contains("| ppo (ppo) |") && printed.contains("| sac (sac) |"),
        "{printed}"
    );
    for f in ["learning_curves.png", "reward_terms.png"] {
        let img = image::open(out.join(f)).unwrap();
        assert!(img.width() >= 1200, "{f}");
    }
    let csv = std::fs::read_to_string(out.join("compare.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 3, "{csv}");
    let header: Vec<&str> = lines[0].split(',').collect();
    assert!(
        header.contains(&"P") && header.contains(&"agent-steps/s"),
        "{csv}"
    );
    assert!(lines[2].split(',').nth(1) == Some("sac"), "{csv}");
    let md = std::fs::read_to_string(out.join("compare.md")).unwrap();
    assert!(md.contains("2 seed(s)"), "{md}");

    // One run is not a comparison; a missing run is named.
    cli_fails(
        &format!("compare {} --out x", runs.join("ppo").to_str().unwrap()),
        "2 values required",
    );
    cli_fails(
        &format!(
            "compare {} {} --out {}",
            runs.join("ppo").to_str().unwrap(),
            runs.join("nope").to_str().unwrap(),
            out.display()
        ),
        "nope",
    );
    // A run that cannot drive the scene (another species) is refused before
    // anything is evaluated or written.
    let mismatch = runs.join("mismatch");
    let t = cli_fails(
        &format!(
            "compare {} pretrained:coho --seconds 2 --seeds 1 --out {}",
            runs.join("ppo").to_str().unwrap(),
            mismatch.display()
        ),
        "cannot drive scene seabream_default",
    );
    assert!(
        t.contains("coho_regular") && !t.contains("evaluating"),
        "{t}"
    );
    assert!(!mismatch.exists(), "{t}");
}

/// `pipeline --species all`: the three species pretrained (here one decision
/// each: 0 is refused),
/// then `three_species` transferred from all three runs, one per species;
/// the summary has a row per stage.
#[test]
fn pipeline_all_species_transfers_into_three_species() {
    let runs = temp("pipeline-all");
    cli_ok(&format!(
        "pipeline --species all --scenes three_species --pretrain-steps 1 --transfer-steps 200 --allow-no-update --eval-seconds 0.5 --runs-dir {} --run-id p --quiet",
        runs.display()
    ));
    let root = runs.join("p");
    let csv = std::fs::read_to_string(root.join("summary.csv")).unwrap();
    let scenes: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(
        scenes,
        [
            "coho_default",
            "seabream_default",
            "yellowtail_default",
            "three_species"
        ],
        "{csv}"
    );
    let state: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("transfer-three_species/final/state.json")).unwrap(),
    )
    .unwrap();
    let init: Vec<&str> = state["init_from"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    for species in ["coho", "yellowtail", "seabream"] {
        assert!(
            init.iter()
                .any(|p| p.ends_with(&format!("pretrain-{species}"))),
            "{init:?}"
        );
    }
    for b in state["behaviours"].as_array().unwrap() {
        assert_eq!(b["agent_steps"], 200, "{b}");
    }
}

/// `bench train` with a budget too small for an update says so (issue 23:
/// it printed a rate with no update and nothing else).
#[test]
fn bench_train_warns_when_its_budget_makes_no_update() {
    let o = cli_ok("bench train --scene seabream_cube5 --steps 100");
    let t = text(&o);
    assert!(
        t.contains("warning: 100 agent steps make no update of seabream_regular")
            && t.contains("its first comes after 10241")
            && t.contains("updates: 0 (0 planned"),
        "{t}"
    );
}
