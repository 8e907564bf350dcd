//! `deepfoids replay` and `eval --replay` as a user runs them (issue 16).
//! What the page looks like in a browser is checked by `.ci/check_replay.py`.

mod support;

use std::path::Path;
use support::{TempDir, cli_fails, cli_ok, json, temp_path, text};

/// A fresh, empty temporary folder.
fn temp(name: &str) -> TempDir {
    let d = temp_path("replay", name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Frames and the delay of each (centiseconds) of a GIF.
fn gif_frames(path: &Path) -> (u16, u16, Vec<u16>) {
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::Indexed);
    let mut d = opts.read_info(std::fs::File::open(path).unwrap()).unwrap();
    let (w, h) = (d.width(), d.height());
    let mut delays = vec![];
    while let Some(f) = d.read_next_frame().unwrap() {
        delays.push(f.delay);
    }
    (w, h, delays)
}

/// 4 s of seabream at 5 frames/s: 21 frames (t = 0 … 4); the GIF holds one
/// frame per recorded frame, 20 cs apart, 10 at --gif-speed 2.
#[test]
fn replay_writes_a_page_and_a_gif() {
    let dir = temp("scene");
    let (html, gif) = (dir.join("r.html"), dir.join("r.gif"));
    let o = cli_ok(&format!(
        "replay --scene seabream_default --policy foids --seconds 4 --seed 2 --out {} --gif {}",
        s(&html),
        s(&gif)
    ));
    assert!(
        text(&o).contains("21 frames × 10 fish over 4.0 s (5.00 frames/s)"),
        "{}",
        text(&o)
    );
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.starts_with("<!doctype html>"));
    assert!(page.contains("<title>seabream_default · foids · seed 2</title>"));
    assert!(page.contains("id=\"replay-data\"") && page.contains("id=\"lib-three-core\""));
    assert!(
        !page.contains("https://") && !page.contains(" src="),
        "nothing is fetched at view time"
    );
    let (w, h, delays) = gif_frames(&gif);
    assert_eq!(delays.len(), 21);
    assert!(delays.iter().all(|&d| d == 20), "{delays:?}");
    assert!(
        w > 2 * 360 && h > 360,
        "top and side views side by side: {w} × {h}"
    );

    cli_ok(&format!(
        "replay --scene seabream_default --seconds 2 --out {} --gif {} --gif-view top --gif-speed 2 --gif-size 200 --fps 2",
        s(&html),
        s(&gif)
    ));
    let (w, h, delays) = gif_frames(&gif);
    assert_eq!(delays, vec![25; 5], "t = 0, 0.5, … 2 s shown twice as fast");
    assert!(
        w == 360 && h < 300,
        "one 200 px view (the header keeps 360 px): {w} × {h}"
    );
}

/// `eval --replay` writes replay.html next to the plots, and summary.json
/// records how to run the evaluation again; `replay --from` re-runs it and
/// insists on the same P and M at every tick.
#[test]
fn eval_folders_replay_only_if_they_reproduce() {
    let dir = temp("eval");
    let run = dir.join("eval");
    cli_ok(&format!(
        "eval --scene seabream_50 --policy boids --seconds 3 --seed 5 --out {} --replay",
        s(&run)
    ));
    assert!(run.join("replay.html").is_file() && run.join("pm.png").is_file());
    let summary = json(&run.join("summary.json"));
    assert_eq!(summary["rerun"]["scene"], "seabream_50");
    assert_eq!(summary["rerun"]["policy"], "boids");
    assert_eq!(summary["rerun"]["seed"], 5);
    // The evaluation mode: sampled actions by default (a rule-based policy has
    // nothing to sample, and replays the same either way).
    assert_eq!(summary["deterministic"], false);

    let html = dir.join("again.html");
    let o = cli_ok(&format!("replay --from {} --out {}", s(&run), s(&html)));
    assert!(
        text(&o).contains("16 frames × 50 fish over 3.0 s"),
        "{}",
        text(&o)
    );
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.contains("P and M match its metrics.csv"));

    // A changed run is refused, naming the tick and both values.
    let metrics = run.join("metrics.csv");
    let csv = std::fs::read_to_string(&metrics).unwrap();
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    let mut cols: Vec<String> = lines[10].split(',').map(String::from).collect();
    let saved_p = cols[1].clone();
    cols[1] = "0.12345".into();
    lines[10] = cols.join(",");
    std::fs::write(&metrics, lines.join("\n")).unwrap();
    let t = cli_fails(
        &format!("replay --from {} --out {}", s(&run), s(&html)),
        "does not reproduce",
    );
    assert!(t.contains("at t = 0.900 s"), "{t}");
    assert!(t.contains(&saved_p) && t.contains("0.12345"), "{t}");
}

/// A simulate folder replays from its trajectories.csv, in the scene and with
/// the seed its simulate.json names; the wrong seed is refused.
#[test]
fn simulate_folders_replay_their_csv() {
    let dir = temp("simulate");
    let run = dir.join("sim");
    cli_ok(&format!(
        "simulate --scene seabream_50 --policy random --seconds 2 --seed 3 --out {}",
        s(&run)
    ));
    let meta = json(&run.join("simulate.json"));
    assert_eq!(meta["scene"], "seabream_50");
    assert_eq!(meta["seed"], 3);
    let (html, gif) = (dir.join("sim.html"), dir.join("sim.gif"));
    let o = cli_ok(&format!(
        "replay --from {} --out {} --gif {}",
        s(&run),
        s(&html),
        s(&gif)
    ));
    assert!(
        text(&o).contains("11 frames × 50 fish over 2.0 s"),
        "{}",
        text(&o)
    );
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.contains("holds no chases or reward terms"));
    assert_eq!(gif_frames(&gif).2.len(), 11);

    let wrong = std::fs::read_to_string(run.join("simulate.json"))
        .unwrap()
        .replace("\"seed\": 3", "\"seed\": 4");
    std::fs::write(run.join("simulate.json"), wrong).unwrap();
    cli_fails(
        &format!("replay --from {} --out {}", s(&run), s(&html)),
        "another scene or seed",
    );

    std::fs::remove_file(run.join("simulate.json")).unwrap();
    cli_fails(
        &format!("replay --from {} --out {}", s(&run), s(&html)),
        "simulate.json is missing",
    );
    cli_ok(&format!(
        "replay --from {} --scene seabream_50 --seed 3 --out {}",
        s(&run),
        s(&html)
    ));
}

#[test]
fn replay_explains_what_it_needs() {
    cli_fails("replay", "give --scene (and --policy)");
    cli_fails(
        "replay --from runs/no-such-run",
        "--from runs/no-such-run: no such folder",
    );
    cli_fails("replay --from runs --policy boids", "cannot be used with");
    cli_fails("replay --from runs", "neither trajectories.csv");
    cli_fails(
        "replay --scene seabream_default --fps 0",
        "--fps must be above 0 and at most 1000 frames/s, got 0",
    );
}
