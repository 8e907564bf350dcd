//! `deepfoids reproduce` on a tiny budget: one claim end to end (stages,
//! measurements, verdict, report), resumption, shipping policies with model
//! cards, and `pretrained:<species>` in the commands that take a policy.

mod support;

use std::path::Path;
use std::process::Output;
use support::{TempDir, cli, cli_fails, command, fails, succeeds, temp_path};

/// The binary, with the shipped policies looked for in `policies` if given.
fn deepfoids(args: &[&str], policies: Option<&Path>) -> Output {
    let mut c = command(args);
    if let Some(p) = policies {
        c.env("DEEPFOIDS_POLICIES", p);
    }
    c.output().expect("the binary runs")
}

fn temp(name: &str) -> TempDir {
    temp_path("repro", name)
}

/// `seabream-cage` on the quick profile × 0.02 (4,000-step pretraining, two
/// 4,000-step transfers of 10 seabream) with 0.6 + 1.8 s evaluations, then
/// shipped; a second invocation reuses every stage and measurement.
#[test]
fn one_claim_on_a_tiny_budget_reports_ships_and_resumes() {
    let out = temp("tiny");
    let ship = out.join("policies");
    let args = [
        "reproduce",
        "--profile",
        "quick",
        "--only",
        "seabream-cage",
        "--budget-scale",
        "0.02",
        "--eval-scale",
        "0.06",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ];
    let o = deepfoids(&args, None);
    let t = succeeds(&o);
    assert!(t.contains("| seabream-cage |"), "{t}");
    // Its two transfer stages and the pretraining they start from, at the
    // quick budgets × 0.02: 200,000 × 0.02 = 4,000 agent steps each.
    for stage in [
        "pretrain-seabream",
        "transfer-seabream_default",
        "transfer-seabream_cube5",
    ] {
        let state = std::fs::read_to_string(out.join("s0").join(stage).join("final/state.json"))
            .unwrap_or_else(|e| panic!("{stage}: {e}"));
        assert!(state.contains("\"budget\": 4000"), "{stage}: {state}");
    }
    assert!(
        !out.join("s0/pretrain-coho").exists(),
        "only what the claim needs"
    );
    let report = out.join("report");
    let md = std::fs::read_to_string(report.join("REPORT.md")).unwrap();
    assert!(md.contains("## seabream-cage"), "{md}");
    // The default reward profile and sampled actions need no flag.
    assert!(
        md.contains(&format!(
            "Command: `deepfoids reproduce --profile quick --out {} --only seabream-cage`",
            out.display()
        )),
        "{md}"
    );
    assert!(
        md.contains("Criterion: 3 m cube: cage rotation ≥ 0.5"),
        "{md}"
    );
    let verdict = ["**holds**", "**does not hold**"];
    assert!(verdict.iter().any(|v| md.contains(v)), "{md}");
    assert!(md.contains("trajectories-transfer-seabream_cube5-seabream_cube5.png"));
    assert!(
        report
            .join("trajectories-transfer-seabream_cube5-seabream_cube5.png")
            .is_file()
    );
    // Two evaluation seeds (quick) × two policies, one row each.
    let meas = std::fs::read_to_string(report.join("measurements.csv")).unwrap();
    assert_eq!(meas.lines().count(), 1 + 4, "{meas}");
    assert!(
        meas.lines().skip(1).all(|l| l.contains("seabream")),
        "{meas}"
    );
    let claims = std::fs::read_to_string(report.join("claims.csv")).unwrap();
    assert!(
        claims.lines().nth(1).unwrap().starts_with("seabream-cage,"),
        "{claims}"
    );
    let stages = std::fs::read_to_string(report.join("stages.csv")).unwrap();
    assert_eq!(stages.lines().count(), 1 + 3, "{stages}");

    // The same folder under another reward profile: its stages learnt other
    // rewards, so none is reused (or resumed) for it.
    let mut other: Vec<&str> = args.to_vec();
    other.extend(["--reward-profile", "thesis"]);
    fails(
        &deepfoids(&other, None),
        "pretrain-seabream trained with reward profile mean_then_budget_space20, not thesis: reuse it with --reward-profile mean_then_budget_space20, or use another run folder",
    );

    // Again, shipping: nothing is trained or evaluated twice, the three
    // species' default stages are added for the policies.
    let mut again: Vec<&str> = args.to_vec();
    again.extend(["--ship", ship.to_str().unwrap()]);
    let o = deepfoids(&again, None);
    let t = succeeds(&o);
    assert!(
        t.contains("transfer-seabream_cube5: finished before, reusing it"),
        "{t}"
    );
    assert!(
        !t.contains("measuring transfer-seabream_cube5"),
        "cached:\n{t}"
    );
    for sp in ["coho", "yellowtail", "seabream"] {
        assert!(ship.join(sp).join("final/state.json").is_file(), "{sp}");
        assert!(
            ship.join(sp)
                .join(format!("final/{sp}_regular.onnx"))
                .is_file()
        );
        assert!(ship.join(sp).join("card.toml").is_file());
        let card = std::fs::read_to_string(ship.join(format!("{sp}.md"))).unwrap();
        assert!(card.contains(&format!("`pretrained:{sp}`")), "{card}");
        assert!(card.contains("boundary collisions per fish-hour"), "{card}");
    }
    // Coho in the density cages, inside coho's folder. Shipping two of the
    // five again (nothing trained or measured) keeps the third coho one when
    // it replaces coho's folder.
    let mut some = again.clone();
    some.extend(["--ship-only", "coho,coho/density_dense"]);
    let o = deepfoids(&some, None);
    let t = succeeds(&o);
    assert!(t.contains("shipped coho to"), "{t}");
    assert!(t.contains("shipped coho/density_dense to"), "{t}");
    assert!(!t.contains("shipped coho/density_sparse"), "{t}");
    assert!(!t.contains("shipped seabream"), "{t}");
    let mut unknown = again.clone();
    unknown.extend(["--ship-only", "coho/tuna"]);
    fails(
        &deepfoids(&unknown, None),
        "--ship-only: no shipped policy `coho/tuna`; the shipped ones are coho, yellowtail, seabream, coho/density_sparse, coho/density_dense",
    );
    for scene in ["density_sparse", "density_dense"] {
        let dir = ship.join("coho").join(scene);
        assert!(dir.join("final/coho_regular.onnx").is_file(), "{scene}");
        let card = std::fs::read_to_string(ship.join("coho").join(format!("{scene}.md"))).unwrap();
        assert!(
            card.contains(&format!("`pretrained:coho/{scene}`")),
            "{card}"
        );
        assert!(card.contains("pretraining in `coho_default`"), "{card}");
        assert!(card.contains("--only density"), "{card}");
    }

    // The shipped policy by name, in eval, and as --init-from.
    let ev = out.join("eval");
    let o = deepfoids(
        &[
            "eval",
            "--scene",
            "seabream_default",
            "--policy",
            "pretrained:seabream",
            "--seconds",
            "1",
            "--out",
            ev.to_str().unwrap(),
        ],
        Some(&ship),
    );
    succeeds(&o);
    assert!(ev.join("summary.json").is_file());
    let o = deepfoids(
        &[
            "train",
            "--scene",
            "seabream_cube5",
            "--phase",
            "transfer",
            "--init-from",
            "pretrained:seabream",
            "--steps",
            "1000",
            "--allow-no-update",
            "--eval-seconds",
            "0",
            "--quiet",
            "--runs-dir",
            out.to_str().unwrap(),
            "--run-id",
            "from-shipped",
        ],
        Some(&ship),
    );
    succeeds(&o);
    let cfg = std::fs::read_to_string(out.join("from-shipped/config.toml")).unwrap();
    assert!(
        cfg.contains(&ship.join("seabream").display().to_string()),
        "{cfg}"
    );
    // simulate, and compare against the run it started.
    let sim = out.join("sim");
    let o = deepfoids(
        &[
            "simulate",
            "--scene",
            "seabream_cube5",
            "--policy",
            "pretrained:seabream",
            "--seconds",
            "1",
            "--out",
            sim.to_str().unwrap(),
        ],
        Some(&ship),
    );
    succeeds(&o);
    assert!(sim.join("trajectories.csv").is_file());
    let cmp = out.join("cmp");
    let from = out.join("from-shipped");
    let o = deepfoids(
        &[
            "compare",
            "pretrained:seabream",
            from.to_str().unwrap(),
            "--scene",
            "seabream_cube5",
            "--seconds",
            "1",
            "--seeds",
            "1",
            "--out",
            cmp.to_str().unwrap(),
        ],
        Some(&ship),
    );
    succeeds(&o);
    assert!(cmp.join("compare.md").is_file());
    // A density-cage policy by name; a name that leaves the folder is refused.
    let o = deepfoids(
        &[
            "eval",
            "--scene",
            "density_sparse",
            "--phase",
            "transfer",
            "--policy",
            "pretrained:coho/density_sparse",
            "--seconds",
            "1",
            "--out",
            out.join("eval-sparse").to_str().unwrap(),
        ],
        Some(&ship),
    );
    succeeds(&o);
    let summary = std::fs::read_to_string(out.join("eval-sparse/summary.json")).unwrap();
    assert!(summary.contains("density_sparse"), "{summary}");
    for bad in [
        "pretrained:coho/../seabream",
        "pretrained:coho/",
        "pretrained:coho/x/y",
    ] {
        let o = deepfoids(
            &["eval", "--scene", "density_sparse", "--policy", bad],
            Some(&ship),
        );
        fails(&o, "no shipped policy");
    }
    // An unknown species names what there is.
    let o = deepfoids(
        &[
            "eval",
            "--scene",
            "seabream_default",
            "--policy",
            "pretrained:tuna",
        ],
        Some(&ship),
    );
    let t = fails(&o, "no shipped policy `tuna`");
    assert!(
        t.contains("pretrained:coho, pretrained:coho/density_dense, pretrained:coho/density_sparse, pretrained:seabream, pretrained:yellowtail"),
        "{t}"
    );
}

#[test]
fn an_unknown_claim_is_refused_with_the_list() {
    let out = temp("unknown");
    let o = deepfoids(
        &[
            "reproduce",
            "--only",
            "learn,fly",
            "--out",
            out.to_str().unwrap(),
        ],
        None,
    );
    let t = fails(&o, "unknown claim `fly`");
    assert!(t.contains("learn, transfer, circle, seabream-cage, seabream-50, layers, species, density, chase, ppo-sac, boids"), "{t}");
    assert!(!out.exists(), "nothing written for a refused command");
}

/// What a cluster driver (`deepfoids.ray`) schedules: `--plan` lists each
/// (seed, stage) with the stages it starts from and writes nothing; `--stage`
/// trains one stage, refusing a stage the claims do not train and one whose
/// pretraining has not finished — before any folder appears.
#[test]
fn the_plan_and_single_stages_for_a_cluster_driver() {
    let out = temp("plan");
    let o = out.to_str().unwrap();
    let base = format!("reproduce --profile quick --only seabream-cage --out {o}");
    let p = cli(&format!("{base} --plan --seeds 7"));
    succeeds(&p);
    let plan = String::from_utf8_lossy(&p.stdout).to_string();
    let lines: Vec<&str> = plan.lines().collect();
    assert_eq!(lines.len(), 3, "{plan}");
    assert_eq!(
        lines[2],
        r#"{"algo":"ppo","init_from":["pretrain-seabream"],"phase":"transfer","scene":"seabream_cube5","seed":7,"stage":"transfer-seabream_cube5"}"#
    );
    cli_fails(
        &format!("{base} --stage transfer-density_dense"),
        "--stage transfer-density_dense is not a stage of these claims; they train: pretrain-seabream, transfer-seabream_default, transfer-seabream_cube5",
    );
    cli_fails(
        &format!("{base} --stage transfer-seabream_cube5"),
        "which has no final policy",
    );
    assert!(!out.join("s0").join("transfer-seabream_cube5").exists());
}
