//! Issue 13 through the binary: configs and options that could take the
//! machine down are refused with their bound, a scene too large for the
//! machine's memory is refused before it is allocated, and an output folder
//! is written by one process at a time.

mod support;
use deepfoids_testkit::copy_dir;

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};
use support::{
    TempDir, cli, cli_ok, command, command_line, deepfoids, fails, succeeds, temp_path, text,
};

fn temp(name: &str) -> TempDir {
    temp_path("robust", name)
}

/// A copy of `configs/` with `from` replaced by `to` in the seabream default scene.
fn configs_with(name: &str, from: &str, to: &str) -> TempDir {
    let root = temp(name);
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs");
    for sub in ["species", "sites", "scenes", "rewards", "baselines"] {
        copy_dir(&src.join(sub), &root.join(sub));
    }
    let scene = root.join("scenes/seabream_default.toml");
    let t = std::fs::read_to_string(&scene).unwrap();
    assert!(t.contains(from));
    std::fs::write(&scene, t.replace(from, to)).unwrap();
    root
}

/// `deepfoids [--configs ROOT] <cmd> --scene seabream_default --seconds S --out OUT`.
fn on_seabream(configs: Option<&Path>, cmd: &str, seconds: &str, out: &Path) -> Command {
    let mut args = vec![];
    if let Some(root) = configs {
        args.extend(["--configs", root.to_str().unwrap()]);
    }
    args.extend([cmd, "--scene", "seabream_default", "--seconds", seconds]);
    args.extend(["--out", out.to_str().unwrap()]);
    command(&args)
}

/// A failing run whose one-line error contains `want`.
#[track_caller]
fn assert_refused(o: &Output, want: &str) {
    let t = fails(o, want);
    assert!(
        !t.contains("panicked") && !t.contains("memory allocation"),
        "{t}"
    );
}

#[test]
fn a_typo_in_a_scene_is_refused_with_its_bound() {
    // Once "memory allocation of 4896000000000 bytes failed" and a backtrace.
    let root = configs_with("count", "count = 10", "count = 100000000");
    let out = temp("count-out");
    let o = on_seabream(Some(&root), "simulate", "1", &out)
        .output()
        .unwrap();
    assert_refused(
        &o,
        "scenes/seabream_default.toml: group[0].count = 100000000 is above the limit of 200000 fish",
    );
    assert_eq!(text(&o).lines().count(), 1, "{}", text(&o));
    // Once accepted, with a mean depth of 5·10²⁹ m.
    let root = configs_with("edge", "edge = 3.0", "edge = 1e30");
    let o = on_seabream(Some(&root), "eval", "1", &out)
        .output()
        .unwrap();
    assert_refused(&o, "cage.edge = 1e30 is above the limit of 1000 m");
    assert!(!out.exists(), "nothing is written");
}

#[test]
fn a_scene_too_large_for_the_memory_is_refused_before_it_is_allocated() {
    // 1,000 seabream need about 50 MB; say the machine has 20 MiB.
    let root = configs_with("memory", "count = 10", "count = 1000");
    let out = temp("memory-out");
    let o = on_seabream(Some(&root), "simulate", "0.2", &out)
        .env("DEEPFOIDS_MEMORY_AVAILABLE", "20M")
        .output()
        .unwrap();
    assert_refused(
        &o,
        "the environment of scene seabream_default (1000 fish) needs about 50.7 MB, but this machine has 21.0 MB available (set by DEEPFOIDS_MEMORY_AVAILABLE)",
    );
    assert!(text(&o).contains("use fewer fish"), "{}", text(&o));
    // With the machine's own figure it runs.
    let o = on_seabream(Some(&root), "simulate", "0.2", &out)
        .env_remove("DEEPFOIDS_MEMORY_AVAILABLE")
        .output()
        .unwrap();
    succeeds(&o);
    // A replay page is checked too: a day of frames of 10 fish in 10 MiB.
    let o = command_line(&format!(
        "replay --scene seabream_default --seconds 86400 --out {}",
        out.join("r.html").to_str().unwrap()
    ))
    .env("DEEPFOIDS_MEMORY_AVAILABLE", "10M")
    .output()
    .unwrap();
    assert_refused(
        &o,
        "a replay of 10 fish × 432001 frames needs about 691.2 MB, but this machine has 10.5 MB available",
    );
}

#[test]
fn command_line_sizes_and_durations_have_bounds() {
    let out = temp("flags");
    let out = out.to_str().unwrap();
    #[rustfmt::skip]
    let cases: &[(&str, &str)] = &[
        ("simulate --scene seabream_default --seconds 1e9 --out {out}", "--seconds 1e9 is above the limit of 86400 s (one simulated day)"),
        ("eval --scene seabream_default --seconds 1e15 --out {out}", "--seconds 1e15 is above the limit of 86400 s"),
        ("eval --scene seabream_default --replay --replay-fps 1e6 --out {out}", "--replay-fps 1000000 is above the limit of 1000 frames/s"),
        ("replay --scene seabream_default --seconds 1e7", "--seconds 1e7 is above the limit of 86400 s"),
        ("replay --scene seabream_default --fps 1e6", "--fps 1000000 is above the limit of 1000 frames/s"),
        ("compare runs/a runs/b --seconds 1e9 --out {out}", "--seconds 1e9 is above the limit of 86400 s"),
        ("compare runs/a runs/b --seeds 1000000 --out {out}", "--seeds 1000000 is above the limit of 1000 seeds"),
        ("sensor-view --scene seabream_default --step 100000000000", "--step 100000000000 is above the limit of 1000000 ticks"),
        ("render --scene seabream_default --frames 10 --width 100000 --out {out}", "--width 100000 is above the limit of 8192 px"),
        ("render --scene seabream_default --frames 2000000 --out {out}", "--frames 2000000 is above the limit of 1000000 frames"),
        ("render --scene seabream_default --frames 10 --warmup 1e9 --out {out}", "--warmup 1e9 is above the limit of 86400 s"),
        ("render --scene seabream_default --frames 10 --fps 1e5 --out {out}", "--fps 100000 is above the limit of 1000 frames/s"),
    ];
    for (line, want) in cases {
        assert_refused(&cli(&line.replace("{out}", out)), want);
    }
    assert!(!Path::new(out).exists(), "nothing is written");
}

/// `--threads 0` once meant one thread, silently; it is refused, and so are
/// absurd counts.
#[test]
fn zero_threads_are_refused() {
    let o = cli("--threads 0 scenes");
    assert_refused(
        &o,
        "invalid value '0' for '--threads <N>': 0 threads cannot run anything; give 1 or more, or leave --threads out for one thread per core",
    );
    assert_refused(
        &cli("--threads 100000 scenes"),
        "100000 is above the limit of 1024 threads",
    );
    cli_ok("--threads 1 scenes");
}

/// A child process killed when the test ends, even by a failed assertion.
struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The lines a child writes to stderr, until one contains `want` (or 120 s pass).
fn wait_for_stderr(child: &mut Child, want: &str) -> String {
    let stderr = child.stderr.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut seen = String::new();
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(120) {
        match rx.recv_timeout(Duration::from_millis(200)) {
            Ok(line) => {
                seen.push_str(&line);
                seen.push('\n');
                if line.contains(want) {
                    return seen;
                }
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            Err(_) => break,
        }
    }
    seen
}

/// Two renders into one folder: the second is refused while the first runs,
/// naming its PID; after `kill -9` of the first, the next one takes the
/// stale lock over with a note. Any other command writing the folder is
/// refused too.
#[test]
fn one_process_at_a_time_writes_a_render_folder() {
    let out = temp("lock");
    let lock_file = out.with_file_name(format!(
        ".{}.lock",
        out.file_name().unwrap().to_string_lossy()
    ));
    let _ = std::fs::remove_file(&lock_file);
    let args = [
        "render",
        "--scene",
        "seabream_default",
        "--frames",
        "100000",
        "--width",
        "64",
        "--height",
        "48",
        "--warmup",
        "0",
        "--format",
        "png",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ];
    let mut first = Killed(
        command(&args)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let start = Instant::now();
    while !out.join("scene.json").exists() && start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(out.join("scene.json").exists(), "the first render started");
    let record = std::fs::read_to_string(&lock_file).unwrap();
    assert!(
        record.contains(&format!("pid = {}", first.0.id())),
        "{record}"
    );

    let second = deepfoids(&args);
    let held = format!("is in use by PID {} on host", first.0.id());
    assert_refused(&second, &held);
    assert!(text(&second).contains("wait for it to finish or stop it"));
    let sim = on_seabream(None, "simulate", "0.2", &out).output().unwrap();
    assert_refused(&sim, &held);
    assert!(!out.join("trajectories.csv").exists());

    first.0.kill().unwrap(); // SIGKILL: no destructor runs, the lock file stays
    first.0.wait().unwrap();
    assert!(lock_file.exists(), "a killed process leaves its lock file");
    let mut third = Killed(
        command(&args)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let said = wait_for_stderr(&mut third.0, "taking the lock over");
    drop(third);
    assert!(
        said.contains(&format!("was locked by PID {} on host", first.0.id()))
            && said.contains("which ended without releasing it; taking the lock over"),
        "{said}"
    );
    let _ = std::fs::remove_file(&lock_file);
}

/// A finished command releases its folder: the lock file is gone.
#[test]
fn a_finished_command_leaves_no_lock() {
    let out = temp("released");
    let o = on_seabream(None, "simulate", "0.2", &out).output().unwrap();
    succeeds(&o);
    let parent = out.parent().unwrap();
    let name = format!(".{}.lock", out.file_name().unwrap().to_string_lossy());
    assert!(!parent.join(name).exists());
}

/// `configs/` with `configs/train/ppo.toml` checkpointing every 100 agent
/// decisions (so that a short run has checkpoints to resume from).
fn configs_checkpointing(name: &str) -> TempDir {
    let root = configs_with(name, "count = 10", "count = 10");
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/train");
    std::fs::create_dir_all(root.join("train")).unwrap();
    for algo in ["ppo.toml", "sac.toml"] {
        let t = std::fs::read_to_string(src.join(algo)).unwrap();
        let t = t
            .lines()
            .map(|l| {
                if l.starts_with("checkpoint_every") {
                    "checkpoint_every = 100".to_string()
                } else {
                    l.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
        std::fs::write(root.join("train").join(algo), t).unwrap();
    }
    root
}

/// `deepfoids --configs ROOT train` on seabream_default into `runs/<id>`.
fn train_cmd(configs: &Path, runs: &Path, id: &str, steps: &str, extra: &[&str]) -> Command {
    let mut args = vec![
        "--configs",
        configs.to_str().unwrap(),
        "train",
        "--scene",
        "seabream_default",
        "--steps",
        steps,
        "--allow-no-update",
        "--runs-dir",
        runs.to_str().unwrap(),
        "--run-id",
        id,
        "--eval-seconds",
        "0",
        "--quiet",
    ];
    args.extend(extra);
    command(&args)
}

/// A training run in the background until `file` appears in its run folder.
fn train_until(mut cmd: Command, file: &Path) -> Killed {
    let child = Killed(
        cmd.stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let start = Instant::now();
    while !file.exists() && start.elapsed() < Duration::from_secs(180) {
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(file.exists(), "{} appeared", file.display());
    child
}

/// Issue 13 item 2 for training: two fresh runs on one `--run-id` — exactly
/// one trains; a run in progress refuses a second fresh run, `--resume` and
/// `--force` alike, naming its PID, and keeps its folder; once it is killed,
/// `--force` replaces the folder; two `--resume` of one run — the second is
/// refused. (Before: both fresh runs could succeed, both resumes always ran,
/// and `--force` deleted the live run's folder.)
#[test]
fn one_process_at_a_time_trains_a_run() {
    let configs = configs_checkpointing("train-lock-configs");
    let runs = temp("train-lock");
    let dir = runs.join("r");

    // Two fresh runs at once: one trains, the other is refused.
    let both: Vec<Child> = (0..2)
        .map(|_| {
            train_cmd(&configs, &runs, "r", "300", &[])
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    let outs: Vec<Output> = both
        .into_iter()
        .map(|c| c.wait_with_output().unwrap())
        .collect();
    let ok = outs.iter().filter(|o| o.status.success()).count();
    assert_eq!(
        ok,
        1,
        "exactly one trains:\n{}\n{}",
        text(&outs[0]),
        text(&outs[1])
    );
    let refused = outs.iter().find(|o| !o.status.success()).unwrap();
    let t = text(refused);
    // "by another process" when the holder has not written its record yet.
    assert!(
        t.contains("is in use by PID")
            || t.contains("is in use by another process")
            || t.contains("exists; use --resume"),
        "{t}"
    );
    assert!(dir.join("final/state.json").is_file());

    // A run in progress (a long --resume) refuses everybody else.
    let live = train_until(
        train_cmd(&configs, &runs, "r", "100000000", &["--resume"]),
        &runs.join(".r.lock"),
    );
    let held = format!("is in use by PID {} on host", live.0.id());
    let fresh = train_cmd(&configs, &runs, "r", "300", &[])
        .output()
        .unwrap();
    assert_refused(&fresh, &held);
    let resume = train_cmd(&configs, &runs, "r", "300", &["--resume"])
        .output()
        .unwrap();
    assert_refused(&resume, &held);
    let force = train_cmd(&configs, &runs, "r", "300", &["--force"])
        .output()
        .unwrap();
    assert_refused(&force, "--force does not replace a run that is in use");
    assert_refused(&force, &held);
    assert!(
        dir.join("config.toml").is_file() && dir.join("final/state.json").is_file(),
        "the live run's folder is intact"
    );
    drop(live); // SIGKILL

    // Nobody holds it now: --force replaces the folder (a stale lock is taken over).
    std::fs::write(dir.join("marker"), "old").unwrap();
    let force = train_cmd(&configs, &runs, "r", "300", &["--force"])
        .output()
        .unwrap();
    succeeds(&force);
    assert!(!dir.join("marker").exists(), "--force replaced the folder");
    assert!(dir.join("final/state.json").is_file());
    assert!(!runs.join(".r.lock").exists(), "released at exit");
    // A resume says where it continues from (checkpoints every 100 steps).
    let resume = train_cmd(&configs, &runs, "r", "400", &["--resume"])
        .output()
        .unwrap();
    succeeds(&resume);
    assert!(
        text(&resume).contains("resumed from step 300 (checkpoint ")
            && text(&resume).contains("step-0000000300)"),
        "{}",
        text(&resume)
    );
}

/// Issue 13 item 5: `--steps 0` is refused before anything is written, and a
/// wrong `--init-from` leaves no run folder behind to block the `--run-id`.
#[test]
fn nothing_to_train_and_a_wrong_init_from_leave_no_folder() {
    let configs = configs_checkpointing("train-refuse-configs");
    let runs = temp("train-refuse");
    let o = train_cmd(&configs, &runs, "zero", "0", &[])
        .output()
        .unwrap();
    assert_refused(&o, "--steps 0 would train nothing");
    assert!(!runs.join("zero").exists());

    // `train --run-id t --phase transfer --init-from <from> [--algo <algo>]`.
    let transfer = |from: &Path, algo: &str| {
        let from = from.to_str().unwrap();
        let args = ["--phase", "transfer", "--init-from", from, "--algo", algo];
        train_cmd(&configs, &runs, "t", "300", &args)
            .output()
            .unwrap()
    };
    let o = transfer(&runs.join("no-such-run"), "ppo");
    assert_refused(&o, "no-such-run");
    assert!(!runs.join("t").exists(), "no stub folder");
    // A run of the other algorithm: refused by name, nothing created either.
    let o = train_cmd(&configs, &runs, "src", "300", &[])
        .output()
        .unwrap();
    succeeds(&o);
    let o = transfer(&runs.join("src"), "sac");
    assert_refused(&o, "ppo");
    assert!(!runs.join("t").exists(), "no stub folder");
    // The same --run-id then trains.
    let o = transfer(&runs.join("src"), "ppo");
    succeeds(&o);
}

/// A pipeline folder in use (here: locked by this test) is refused, naming
/// the holder, before any stage starts.
#[test]
fn a_pipeline_in_use_is_refused() {
    let runs = temp("pipeline-lock");
    let lock = deepfoids_io::DirLock::acquire(&runs.join("p")).unwrap();
    let o = cli(&format!(
        "pipeline --species seabream --pretrain-steps 100 --transfer-steps 100 --allow-no-update --runs-dir {} --run-id p",
        runs.display()
    ));
    assert_refused(&o, &format!("is in use by PID {}", std::process::id()));
    assert!(!runs.join("p").exists(), "no stage started");
    drop(lock);
    // Every stage's budget is checked before the first stage trains: a
    // transfer budget without an update is refused up front (issue 25).
    let o = cli(&format!(
        "pipeline --species seabream --pretrain-steps 20000 --transfer-steps 100 --runs-dir {} --run-id p",
        runs.display()
    ));
    assert_refused(&o, "pipeline stage seabream_default (transfer)");
    assert_refused(&o, "a budget of 100 agent steps makes no update");
    assert!(!runs.join("p").exists(), "no stage started");
    // A stage stopped before its first checkpoint starts again from nothing:
    // its old logs go.
    let stage = runs.join("p/pretrain");
    std::fs::create_dir_all(&stage).unwrap();
    std::fs::write(
        stage.join("scalars.csv"),
        "behaviour,step,tag,value\nold,1,x,1\n",
    )
    .unwrap();
    cli_ok(&format!(
        "pipeline --species seabream --scenes seabream_default --pretrain-steps 100 --transfer-steps 100 --allow-no-update --eval-seconds 1 --quiet --runs-dir {} --run-id p",
        runs.display()
    ));
    let csv = std::fs::read_to_string(stage.join("scalars.csv")).unwrap();
    assert!(!csv.contains("old,"), "{csv}");
    assert!(stage.join("final/state.json").is_file());
    let o = cli(&format!(
        "pipeline --species seabream --pretrain-steps 0 --runs-dir {}",
        runs.display()
    ));
    assert_refused(&o, "--pretrain-steps 0 would train nothing");
}

/// The names in folder `dir`, sorted (empty when it does not exist).
fn names_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// Issue 25: negative numbers were "unexpected argument '-1'" from clap; they
/// reach the option's check and get its range.
#[test]
fn negative_numbers_get_the_range_not_a_parse_error() {
    let out = temp("negative");
    let o = out.to_str().unwrap();
    #[rustfmt::skip]
    let cases: &[(&str, &str)] = &[
        ("eval --scene seabream_default --seconds -1 --out {out}", "--seconds must be above 0 and at most 86400 s (one simulated day), got -1"),
        ("eval --scene seabream_default --warmup -1 --out {out}", "--warmup must be ≥ 0 and at most 86400 s, got -1"),
        ("eval --scene seabream_default --seed -1 --out {out}", "'--seed <SEED>': must be ≥ 0, got -1"),
        ("train --scene seabream_default --steps -5", "'--steps <STEPS>': must be ≥ 0, got -5"),
        ("replay --scene seabream_default --fps -2", "--fps must be above 0 and at most 1000 frames/s, got -2"),
        ("render --scene seabream_default --frames -3 --out {out}", "'--frames <FRAMES>': must be ≥ 0, got -3"),
    ];
    for (line, want) in cases {
        let r = cli(&line.replace("{out}", o));
        assert_refused(&r, want);
        assert!(!text(&r).contains("unexpected argument"), "{}", text(&r));
    }
    assert!(!out.exists(), "nothing is written");
}

/// Issue 25: `replay --out` an existing folder simulated, then failed and
/// left `.NAME.PID.tmp`; `--gif-size 1000000` simulated and wrote the page
/// before failing. Both are refused before anything runs, leaving nothing.
#[test]
fn replay_checks_its_outputs_before_it_simulates() {
    let dir = temp("replay-out");
    std::fs::create_dir_all(dir.join("page.html")).unwrap();
    let page = dir.join("page.html");
    let o = cli(&format!(
        "replay --scene seabream_default --seconds 1 --out {}",
        page.display()
    ));
    assert_refused(
        &o,
        &format!(
            "--out {} is a folder; give the path of a file to write",
            page.display()
        ),
    );
    assert_eq!(names_in(&dir), ["page.html"], "no temporary file");
    let html = dir.join("r.html");
    let gif = dir.join("r.gif");
    let o = cli(&format!(
        "replay --scene seabream_default --seconds 1 --out {} --gif {} --gif-size 1000000",
        html.display(),
        gif.display()
    ));
    assert_refused(&o, "--gif-size must be 64 to 4096 pixels, got 1000000");
    assert_eq!(
        names_in(&dir),
        ["page.html"],
        "no page, no GIF, no temporary file"
    );
    assert_eq!(text(&o).lines().count(), 1, "{}", text(&o));
}

/// Issue 25: an output folder below a file was reported for its lock file
/// `.NAME.lock`; it is refused for `--out` before anything runs.
#[test]
fn an_output_folder_below_a_file_names_the_option() {
    let dir = temp("out-below-file");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("file"), "x").unwrap();
    let out = dir.join("file/run");
    let o = on_seabream(None, "simulate", "0.2", &out).output().unwrap();
    assert_refused(
        &o,
        &format!(
            "--out {}: {} is a file, not a folder",
            out.display(),
            dir.join("file").display()
        ),
    );
    assert!(!text(&o).contains(".lock"), "{}", text(&o));
    assert_eq!(names_in(&dir), ["file"], "no lock file, no stub folder");
}

/// Issue 25: configuration mistakes through the binary — a folder as a
/// species file, a missing `--configs`, a group count of the wrong sign, a
/// zero `time_horizon`, a binary scene file.
#[test]
fn configuration_mistakes_are_named_plainly() {
    // A folder where species/seabream.toml belongs: not "unknown species".
    let species_root = configs_with("species-dir", "count = 10", "count = 10");
    let root = &species_root;
    let species = root.join("species/seabream.toml");
    std::fs::remove_file(&species).unwrap();
    std::fs::create_dir(&species).unwrap();
    let out = temp("config-mistakes-out");
    let o = on_seabream(Some(root), "eval", "1", &out).output().unwrap();
    assert_refused(
        &o,
        &format!("{} is a folder, not a TOML file", species.display()),
    );
    assert!(!text(&o).contains("unknown species"), "{}", text(&o));

    // No configuration folder: not an empty "available:" list.
    let missing = temp("no-such-configs");
    let o = on_seabream(Some(&missing), "eval", "1", &out)
        .output()
        .unwrap();
    assert_refused(
        &o,
        &format!(
            "the configuration folder {} does not exist",
            missing.display()
        ),
    );
    assert!(!text(&o).contains("available:"), "{}", text(&o));

    // A negative count: not a bare "expected usize".
    let count_root = configs_with("negative-count", "count = 10", "count = -1");
    let o = on_seabream(Some(&count_root), "eval", "1", &out)
        .output()
        .unwrap();
    assert_refused(
        &o,
        "seabream_default.toml: line 14, column 9, field `group[0].count`: invalid value: integer `-1`, expected a whole number ≥ 0",
    );

    // time_horizon = 0: named by itself, not as buffer_size.
    let root = configs_checkpointing("horizon");
    let ppo = root.join("train/ppo.toml");
    let t = std::fs::read_to_string(&ppo).unwrap();
    let line = t
        .lines()
        .find(|l| l.starts_with("time_horizon"))
        .unwrap()
        .to_string();
    std::fs::write(&ppo, t.replace(&line, "time_horizon = 0")).unwrap();
    let runs = temp("horizon-runs");
    let o = train_cmd(&root, &runs, "h", "10", &[]).output().unwrap();
    assert_refused(
        &o,
        "ppo.toml: field `time_horizon`: must be at least 1, got 0",
    );
    assert!(!text(&o).contains("buffer_size"), "{}", text(&o));
    assert!(!runs.join("h").exists(), "no stub run folder");

    // A binary scene file: its cause once.
    let scene = temp("binary-scene.toml");
    std::fs::write(&scene, [0x7f, b'E', b'L', b'F', 0xff, 0xfe, 0]).unwrap();
    let o = cli(&format!(
        "eval --scene {} --seconds 1 --out {}",
        scene.display(),
        out.display()
    ));
    assert_refused(
        &o,
        &format!("cannot read {}: not UTF-8 text", scene.display()),
    );
    assert_eq!(text(&o).matches("not UTF-8").count(), 1, "{}", text(&o));
    assert!(!out.exists(), "nothing is written");
    let _ = std::fs::remove_file(&scene);
}

/// Issue 25: a text file given as an ONNX policy said "Reading proto model".
#[test]
fn a_text_file_as_an_onnx_policy_is_named() {
    let dir = temp("text-onnx");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("policy.onnx");
    std::fs::write(&file, "not a model\n").unwrap();
    let out = temp("text-onnx-out");
    let o = cli(&format!(
        "eval --scene seabream_default --policy {} --seconds 1 --out {}",
        file.display(),
        out.display()
    ));
    assert_refused(
        &o,
        &format!("{} is not an ONNX model (it is a text file", file.display()),
    );
    assert!(!text(&o).contains("Reading proto model"), "{}", text(&o));
    assert!(!out.exists(), "nothing is written");
}

/// `configs/train/<algo>` of `configs` with `key = value` lines replaced.
fn set_train_values(configs: &Path, algo: &str, values: &[(&str, &str)]) {
    let file = configs.join("train").join(algo);
    let t = std::fs::read_to_string(&file).unwrap();
    let t = t
        .lines()
        .map(
            |l| match values.iter().find(|(k, _)| l.starts_with(&format!("{k} "))) {
                Some((k, v)) => format!("{k} = {v}"),
                None => l.to_string(),
            },
        )
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(file, t).unwrap();
}

/// Issue 25 item 1: a training config is bounded and planned before any
/// folder is made — an absurd size is refused by field and range, a config
/// the machine cannot hold by its estimated memory and largest part, and a
/// budget that makes no update unless `--allow-no-update` is given.
#[test]
fn training_configs_are_planned_before_any_folder() {
    let configs = configs_checkpointing("train-plan-configs");
    let runs = temp("train-plan");
    set_train_values(&configs, "ppo.toml", &[("layers", "100000")]);
    let o = train_cmd(&configs, &runs, "a", "300", &[])
        .output()
        .unwrap();
    assert_refused(
        &o,
        "field `layers`: 100000 is out of range: allowed 1 to 32",
    );
    set_train_values(&configs, "ppo.toml", &[("layers", "4"), ("hidden", "4096")]);
    let o = train_cmd(&configs, &runs, "a", "300", &[])
        .env("DEEPFOIDS_MEMORY_AVAILABLE", "1G")
        .output()
        .unwrap();
    assert_refused(&o, "needs about");
    assert_refused(
        &o,
        "the largest part is the networks (hidden = 4096, layers = 4)",
    );
    // The file named is the one read (--configs), not the shipped one.
    let file = configs.join("train").join("ppo.toml");
    assert_refused(&o, &format!("training with {}", file.display()));
    set_train_values(&configs, "ppo.toml", &[("hidden", "128")]);
    // seabream_default's 10 fish: 16 joins of 10 × 64 = 10,240 transitions
    // (train_cmd allows runs without updates: that flag is dropped here).
    let allowed = train_cmd(&configs, &runs, "a", "300", &[]);
    let args: Vec<_> = allowed
        .get_args()
        .filter(|a| *a != "--allow-no-update")
        .collect();
    let o = command(&[]).args(args).output().unwrap();
    assert_refused(&o, "a budget of 300 agent steps makes no update");
    assert_refused(&o, "the first comes after 10241 agent steps");
    assert_refused(&o, &format!("time_horizon = 64 in {})", file.display()));
    assert_refused(&o, "--allow-no-update");
    assert!(names_in(&runs).is_empty(), "{:?}", names_in(&runs));
}

/// Issue 25 item 1, case by case as the issue listed them: each absurd
/// training value is refused by file, field and allowed range before any
/// folder is made (`layers = 100000` once took 24 GB and the OOM killer;
/// `hidden = 1e6` and a SAC `buffer_size = 4e9` aborted in the allocator;
/// `epochs = 1e9` hung; a PPO `buffer_size = 1e12` "finished" with no update).
#[test]
fn the_issues_training_configs_are_refused_by_field() {
    let configs = configs_checkpointing("train-cases-configs");
    let runs = temp("train-cases");
    let cases: [(&str, &str, &str, &str); 6] = [
        ("ppo.toml", "layers", "100000", "allowed 1 to 32"),
        ("ppo.toml", "hidden", "1000000", "allowed 1 to 4096"),
        (
            "sac.toml",
            "buffer_size",
            "4000000000",
            "allowed 1 to 100000000",
        ),
        ("ppo.toml", "epochs", "1000000000", "allowed 1 to 100"),
        (
            "ppo.toml",
            "buffer_size",
            "1000000000000",
            "allowed 1 to 100000000",
        ),
        ("ppo.toml", "time_horizon", "0", "must be at least 1, got 0"),
    ];
    for (file, field, value, allowed) in cases {
        let original = std::fs::read_to_string(configs.join("train").join(file)).unwrap();
        set_train_values(&configs, file, &[(field, value)]);
        let algo = if file == "sac.toml" { "sac" } else { "ppo" };
        let o = train_cmd(&configs, &runs, "a", "300", &["--algo", algo])
            .output()
            .unwrap();
        let path = configs.join("train").join(file);
        assert_refused(&o, &format!("{}: field `{field}`", path.display()));
        assert_refused(&o, allowed);
        assert!(names_in(&runs).is_empty(), "{field}: {:?}", names_in(&runs));
        std::fs::write(configs.join("train").join(file), original).unwrap();
    }
}

/// Issue 25 items 2 and 3: a run without its final policy is evaluated only
/// with `--checkpoint STEP` or `--latest`, and the summary names the step;
/// a failed `--init-from` (corrupt weights) leaves nothing that blocks the
/// run id; `--resume` passes over a truncated checkpoint with a note.
#[test]
fn checkpoints_are_never_used_silently() {
    let configs = configs_checkpointing("train-ckpt-configs");
    set_train_values(&configs, "ppo.toml", &[("keep_checkpoints", "2")]);
    let runs = temp("train-ckpt");
    let o = train_cmd(&configs, &runs, "src", "300", &[])
        .output()
        .unwrap();
    succeeds(&o);
    let run = runs.join("src");
    // Checkpoints every 100 agent steps (10 fish): the newest two are kept.
    let steps: Vec<String> = names_in(&run.join("checkpoints"));
    assert_eq!(steps.len(), 2, "{steps:?}");

    // No final/state.json: refused by name, then --latest records its step.
    let state = run.join("final/state.json");
    let saved = std::fs::read(&state).unwrap();
    std::fs::remove_file(&state).unwrap();
    let eval = |extra: &[&str]| {
        let out = runs.join("eval");
        let _ = std::fs::remove_dir_all(&out);
        let mut cmd = on_seabream(Some(&configs), "eval", "1", &out);
        cmd.args(["--policy", run.to_str().unwrap()]).args(extra);
        (cmd.output().unwrap(), out)
    };
    let (o, out) = eval(&[]);
    assert_refused(&o, "has no final policy");
    assert_refused(&o, "--latest");
    assert!(!out.exists());
    let (o, out) = eval(&["--latest"]);
    succeeds(&o);
    let summary = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(summary.contains("\"checkpoint\": 300"), "{summary}");
    // `export` takes the same two ways, and refuses without one.
    let onnx = runs.join("latest.onnx");
    let export = |extra: &[&str]| {
        let mut args = vec!["export", "--run", run.to_str().unwrap()];
        args.extend(["--out", onnx.to_str().unwrap()]);
        args.extend(extra);
        deepfoids(&args)
    };
    assert_refused(&export(&[]), "has no final policy");
    let o = export(&["--latest"]);
    assert!(o.status.success() && onnx.is_file(), "{}", text(&o));
    std::fs::write(&state, saved).unwrap();

    // Corrupt source weights: the transfer fails and leaves nothing behind.
    let model = run.join("final/seabream_regular.model.bpk");
    let weights = std::fs::read(&model).unwrap();
    std::fs::write(&model, &weights[..weights.len() / 2]).unwrap();
    let transfer = || {
        let from = run.to_str().unwrap();
        let args = ["--phase", "transfer", "--init-from", from];
        train_cmd(&configs, &runs, "t", "100", &args)
            .output()
            .unwrap()
    };
    let o = transfer();
    assert_refused(&o, "seabream_regular.model.bpk");
    assert_refused(&o, "a truncated file");
    assert!(!runs.join("t").exists(), "{:?}", names_in(&runs));
    assert!(
        !names_in(&runs).iter().any(|n| n.ends_with(".start")),
        "{:?}",
        names_in(&runs)
    );
    std::fs::write(&model, &weights).unwrap();
    let o = transfer();
    succeeds(&o);

    // A truncated newest checkpoint: resume from the one before, saying so.
    let newest = run.join("checkpoints").join(steps.last().unwrap());
    let file = newest.join("seabream_regular.model.bpk");
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() / 3]).unwrap();
    let o = train_cmd(&configs, &runs, "src", "400", &["--resume"])
        .output()
        .unwrap();
    succeeds(&o);
    assert!(
        text(&o).contains("note: resuming from the older checkpoint")
            && text(&o).contains("resumed from step 200"),
        "{}",
        text(&o)
    );
}
