//! The replay buffer against the real environment, resume, and learning.

use deepfoids_env::policy::action_buffers;
use deepfoids_env::{ConfigDirs, Env, Phase, Policy, RandomPolicy, Scene};
use deepfoids_learn::checkpoint::{RunState, checkpoints};
use deepfoids_learn::plan::TrainConfigFile;
use deepfoids_learn::{Backend, ProgressMode, RunArgs, TrainOutcome};
use deepfoids_sac::replay::{PROXIMITY_TOLERANCE, Replay, next_history};
use deepfoids_sac::{Sac, SacConfig, train};
use deepfoids_sensors::{CELLS, FRAME_LEN, STACKED_LEN};
use deepfoids_testkit::{TempDir, temp_path};
use std::path::Path;

fn dirs() -> ConfigDirs {
    ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs"))
}

fn temp(name: &str) -> TempDir {
    temp_path("sac", name)
}

/// A small, fast configuration: 64-transition batches, one update per 100
/// agent steps after the first 1,000, no wrap-around of the buffer.
fn small_config() -> SacConfig {
    let mut c = SacConfig::load(&dirs()).unwrap();
    c.batch_size = 64;
    c.buffer_size = 10_000;
    c.learning_starts = 1000;
    c.steps_per_update = 100.0;
    c.summary_every = 1000;
    c.checkpoint_every = 1000;
    c.keep_checkpoints = 2;
    c
}

fn run(dir: &Path, cfg: SacConfig, steps: u64, seed: u64, resume: bool) -> TrainOutcome {
    run_in(&dirs(), dir, cfg, steps, seed, resume)
}

/// [`run`] with the reward profile of `dirs`.
fn run_in(
    dirs: &ConfigDirs,
    dir: &Path,
    cfg: SacConfig,
    steps: u64,
    seed: u64,
    resume: bool,
) -> TrainOutcome {
    train(
        &Sac::new(cfg),
        RunArgs {
            scene: Scene::load(dirs, "seabream_default", Phase::Pretrain).unwrap(),
            run_dir: dir.to_path_buf(),
            run_id: "test".into(),
            seed,
            steps: Some(steps.into()),
            resume,
            init_from: vec![],
            backend: Backend::Flex,
            progress: ProgressMode::Quiet,
            progress_sink: None,
            save: true,
            config_toml: None,
        },
    )
    .unwrap()
}

/// Random fish in the 3 m cube for 400 decisions (several respawns: the
/// `thesis` profile, where a net collision ends the episode): every stack
/// rebuilt from the buffer equals the environment's, the proximity up to
/// 1/510 and the type channels exactly, including the zero frames after respawns.
#[test]
fn rebuilt_observations_equal_the_environments() {
    let thesis = dirs().with_reward_profile("thesis");
    let scene = Scene::load(&thesis, "seabream_default", Phase::Pretrain).unwrap();
    let mut env = Env::new(scene, 3);
    let n = env.behaviours()[0].count;
    let mut policy = RandomPolicy { seed: 3 };
    let mut actions = action_buffers(&env);
    let mut replay = Replay::new(100_000, n);
    let mut history = vec![0u8; n];
    let mut originals: Vec<Vec<f32>> = vec![env.output().behaviours[0].grids.clone()];
    replay.push(
        env.output().behaviours[0].observations(),
        &env.output().behaviours[0].vectors,
        &actions[0],
        &history,
        true,
    );
    let mut respawns = 0;
    while originals.len() < 400 {
        policy.act(&env, &mut actions).unwrap();
        let out = env.step(&actions).unwrap();
        let batch = &out.behaviours[0];
        if !batch.decided {
            continue;
        }
        replay.reward(&batch.rewards, &batch.terminated);
        for (h, &t) in history.iter_mut().zip(&batch.terminated) {
            *h = next_history(*h, t);
            respawns += t as usize;
        }
        originals.push(batch.grids.clone());
        replay.push(
            batch.observations(),
            &batch.vectors,
            &actions[0],
            &history,
            true,
        );
    }
    assert!(
        respawns >= 3,
        "only {respawns} respawns: the test needs some"
    );
    let mut rebuilt = vec![0.0; STACKED_LEN];
    let mut worst = 0.0f32;
    for (row, grids) in originals.iter().enumerate() {
        for a in 0..n {
            replay.stack_into(row as u64, a, &mut rebuilt);
            let orig = &grids[a * STACKED_LEN..(a + 1) * STACKED_LEN];
            for k in 0..3 {
                let (o, r) = (
                    &orig[k * FRAME_LEN..(k + 1) * FRAME_LEN],
                    &rebuilt[k * FRAME_LEN..(k + 1) * FRAME_LEN],
                );
                for c in 0..CELLS {
                    worst = worst.max((o[c] - r[c]).abs());
                }
                assert_eq!(
                    &o[CELLS..],
                    &r[CELLS..],
                    "row {row} agent {a} frame {k}: types"
                );
            }
        }
    }
    assert!(worst <= PROXIMITY_TOLERANCE, "proximity error {worst}");
    assert!(worst > 0.0, "quantisation should show somewhere");
}

/// 3,000 steps with checkpoints every 1,000, then a resume to 4,000. Ten fish:
/// 300 decisions. The checkpoint at 3,000 holds rows 0–300 (row 300 still
/// awaiting its reward); rows 2–299 are sampleable: 2,980 transitions. The
/// resumed run adds rows 301–401, of which 301–400 are complete (row 300 never
/// will be: the environment was reset), so 3,980 — against 980 had the buffer
/// been lost.
#[test]
fn resume_restores_the_step_count_and_the_replay_buffer() {
    let dir = temp("resume");
    let first = run(&dir, small_config(), 3000, 1, false);
    assert_eq!(first.agent_steps, 3000);
    assert_eq!(first.buffer.transitions, 2980);
    let cps = checkpoints(&dir);
    assert_eq!(cps.len(), 2);
    let last = &cps.last().unwrap().1;
    let state = RunState::load(last).unwrap();
    assert_eq!((state.agent_steps, state.algo.as_str()), (3000, "sac"));
    assert!(last.join("seabream_regular.sac.json").is_file());
    // 1,000 steps before the first update, then one per 100 steps: 20 updates.
    assert_eq!(state.behaviours[0].updates, 20);
    let replay = Replay::load(&last.join("seabream_regular.replay.bin"), 10_000, 10).unwrap();
    assert_eq!(replay.len(), 2980);

    let second = run(&dir, small_config(), 4000, 1, true);
    assert_eq!(second.agent_steps, 4000);
    assert_eq!(second.steps_this_run, 1000);
    assert_eq!(second.buffer.transitions, 3980);
    let state = RunState::load(&dir.join("final")).unwrap();
    assert_eq!(state.behaviours[0].updates, 30);
    assert_eq!(state.resets, 1);

    // Without the buffer in the checkpoint, a resumed run starts empty.
    let dir2 = temp("resume-no-replay");
    let mut cfg = small_config();
    cfg.save_replay_buffer = false;
    run(&dir2, cfg.clone(), 3000, 1, false);
    let resumed = run(&dir2, cfg, 4000, 1, true);
    assert_eq!(resumed.buffer.transitions, 980);
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&dir2);
}

/// Issue 13 items 3 and 4 for SAC: a run killed after its checkpoint at
/// 2,000 agent steps (3,500-step budget, checkpoints every 1,000) and resumed
/// ends at the same step with the same number of updates as the run never
/// stopped — 1,000 steps before the first update, then one per 100: 25 — and
/// its TensorBoard events and `scalars.csv` hold one value per tag and step,
/// the points up to the checkpoint kept.
#[test]
fn a_killed_run_resumes_as_the_run_never_stopped() {
    use deepfoids_learn::tfevents::scalars;
    use std::collections::BTreeSet;
    let mut cfg = small_config();
    cfg.keep_checkpoints = 10;
    let whole = temp("whole");
    run(&whole, cfg.clone(), 3500, 2, false);
    let never_stopped = RunState::load(&whole.join("final")).unwrap();
    assert_eq!(never_stopped.behaviours[0].updates, 25);
    // The killed run: the same folder without final/ and the checkpoint at 3,000.
    let killed = temp("killed");
    std::fs::create_dir_all(&killed).unwrap();
    let cp = std::process::Command::new("cp")
        .args([
            "-a",
            &format!("{}/.", whole.display()),
            killed.to_str().unwrap(),
        ])
        .status()
        .unwrap();
    assert!(cp.success());
    std::fs::remove_dir_all(killed.join("final")).unwrap();
    for (step, d) in checkpoints(&killed) {
        if step > 2000 {
            std::fs::remove_dir_all(d).unwrap();
        }
    }
    let tb = killed.join("tb/seabream_regular");
    let before = scalars(&tb).unwrap();
    assert!(before.iter().any(|p| p.step > 2000));
    run(&killed, cfg, 3500, 2, true);
    let resumed = RunState::load(&killed.join("final")).unwrap();
    assert_eq!(
        (resumed.agent_steps, resumed.behaviours[0].updates),
        (3500, 25)
    );
    let after = scalars(&tb).unwrap();
    let mut seen = BTreeSet::new();
    for p in &after {
        assert!(
            seen.insert((p.tag.clone(), p.step)),
            "{} twice at step {} in TensorBoard",
            p.tag,
            p.step
        );
    }
    for p in before.iter().filter(|p| p.step <= 2000) {
        assert!(after.contains(p), "{p:?} kept");
    }
    let csv = std::fs::read_to_string(killed.join("scalars.csv")).unwrap();
    let mut rows = BTreeSet::new();
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.splitn(4, ',').collect();
        assert!(rows.insert((f[1], f[2])), "{line}: twice in scalars.csv");
    }
    assert_eq!(rows.len(), after.len());
    let _ = std::fs::remove_dir_all(&whole);
    let _ = std::fs::remove_dir_all(&killed);
}

/// Learning: ten seabream in the 3 m cube, 8,000 agent steps, one update of 128
/// transitions per decision after the first 500 steps, in the `legacy` profile. What SAC learns first is
/// to stop hitting the net: the boundary-collision term (≈ −6 to −8 per decision
/// for the untrained policy: a crossing every ~40 decisions) averaged over the
/// second half of the run must beat the first two log points by at least 2.0
/// (seeds 0 and 1: +4.6 and +2.9). With the energy term measured per physics step
/// (README, SPEC deviations) the untrained policy's jitter costs only ≈ −0.6 per
/// decision, so it no longer dominates the start; the total reward of so short a
/// run is too noisy to assert (seed 1 ends on a −15 log point).
#[test]
fn sac_improves_over_the_untrained_policy() {
    let dir = temp("learn");
    let mut cfg = small_config();
    cfg.batch_size = 128;
    cfg.learning_starts = 500;
    cfg.steps_per_update = 10.0;
    cfg.checkpoint_every = 1_000_000;
    // The per-decision reading (the `legacy` profile) these numbers were derived
    // for; under the default per-step timing 8,000 steps are too few to show it.
    let legacy = dirs().with_reward_profile("legacy");
    let out = run_in(&legacy, &dir, cfg, 8000, 0, false);
    assert_eq!(out.curve.len(), 8);
    let csv = std::fs::read_to_string(dir.join("scalars.csv")).unwrap();
    let term = |tag: &str| -> Vec<f64> {
        csv.lines()
            .skip(1)
            .filter_map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                (f[2] == tag).then(|| f[3].parse().unwrap())
            })
            .collect()
    };
    let boundary = term("Reward/boundary_collision");
    eprintln!("boundary {boundary:?}\nreward {:?}", out.curve);
    let first = (boundary[0] + boundary[1]) / 2.0;
    let half = &boundary[boundary.len() / 2..];
    let later = half.iter().sum::<f64>() / half.len() as f64;
    assert!(
        later > first + 2.0,
        "boundary collisions: first {first:.3}, second half {later:.3}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
