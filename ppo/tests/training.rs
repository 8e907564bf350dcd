//! Short training runs: the logs, checkpoints and resume, transfer from one
//! or several runs, per-behaviour budgets, the final ONNX files, progress
//! lines, and learning.

use deepfoids_env::{ConfigDirs, Env, Phase, Policy, Scene};
use deepfoids_learn::checkpoint::{RunState, checkpoints};
use deepfoids_learn::plan::TrainConfigFile;
use deepfoids_learn::policy::ActorPolicy;
use deepfoids_learn::{Backend, ProgressMode, RunArgs, TrainOutcome};
use deepfoids_ppo::{Ppo, PpoConfig, Rollout, load_actor, train};
use deepfoids_testkit::{TempDir, temp_path};
use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

fn dirs() -> ConfigDirs {
    ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs"))
}

fn temp(name: &str) -> TempDir {
    temp_path("ppo", name)
}

fn paths(dirs: &[TempDir]) -> Vec<PathBuf> {
    dirs.iter().map(|d| d.to_path_buf()).collect()
}

/// A small, fast configuration: 512-transition buffers, 128-sample minibatches.
fn small_config() -> PpoConfig {
    let mut c = PpoConfig::load(&dirs()).unwrap();
    c.buffer_size = 512;
    c.batch_size = 128;
    c.checkpoint_every = 1000;
    c.keep_checkpoints = 2;
    c
}

fn args(
    dir: &Path,
    scene: &str,
    steps: u64,
    seed: u64,
    resume: bool,
    init_from: Vec<PathBuf>,
) -> RunArgs {
    let phase = if init_from.is_empty() {
        Phase::Pretrain
    } else {
        Phase::Transfer
    };
    RunArgs {
        scene: Scene::load(&dirs(), scene, phase).unwrap(),
        run_dir: dir.to_path_buf(),
        run_id: "test".into(),
        seed,
        steps: Some(steps.into()),
        resume,
        init_from,
        backend: Backend::Flex,
        progress: ProgressMode::Quiet,
        progress_sink: None,
        save: true,
        config_toml: None,
    }
}

fn run(
    dir: &Path,
    scene: &str,
    cfg: PpoConfig,
    steps: u64,
    seed: u64,
    resume: bool,
    init_from: Vec<PathBuf>,
) -> TrainOutcome {
    train(
        &Ppo::new(cfg),
        args(dir, scene, steps, seed, resume, init_from),
    )
    .unwrap()
}

/// Tags and steps in a TensorBoard event file (TFRecord framing: u64 length,
/// u32 CRC, payload, u32 CRC; each payload an `Event` protobuf).
fn read_events(dir: &Path) -> Vec<(String, i64, f32)> {
    use protobuf::Message;
    let mut out = vec![];
    // By name, as TensorBoard reads them (the name starts with the time).
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    for file in files {
        let bytes = std::fs::read(file).unwrap();
        let mut at = 0;
        while at + 12 <= bytes.len() {
            let len = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
            let payload = &bytes[at + 12..at + 12 + len];
            at += 12 + len + 4;
            let event = tensorboard_proto::event::Event::parse_from_bytes(payload).unwrap();
            for v in event.get_summary().get_value() {
                out.push((
                    v.get_tag().to_string(),
                    event.get_step(),
                    v.get_simple_value(),
                ));
            }
        }
    }
    out
}

/// The synchronous scheme on 10 fish with 512-transition buffers updates
/// every ceil(512 / 10) = 52 decisions: at agent steps 520, 1040, 1560 of a
/// 2,000-step run. ML-Agents' scheme updates when closed trajectories (64
/// decisions, or an episode's end) hold ≥ 512 transitions: the first at step
/// 1,280 at the latest (after 128 decisions every agent has closed at least
/// 64 transitions, whenever its episodes ended: 640 ≥ 512). Both log the
/// named scalars at each update, with the learning rate decaying linearly
/// over the budget, and the CSV carries the same.
#[test]
fn tensorboard_and_csv_have_the_named_scalars() {
    for rollout in [Rollout::Synchronous, Rollout::MlAgents] {
        let dir = temp(&format!("tb-{rollout:?}"));
        let cfg = PpoConfig {
            rollout,
            ..small_config()
        };
        let out = run(&dir, "seabream_default", cfg, 2000, 1, false, vec![]);
        assert_eq!(out.agent_steps, 2000);
        let events = read_events(&dir.join("tb/seabream_regular"));
        let tags: BTreeSet<&str> = events.iter().map(|e| e.0.as_str()).collect();
        for want in [
            "Losses/Policy Loss",
            "Losses/Value Loss",
            "Policy/Entropy",
            "Policy/Learning Rate",
            "Policy/Extrinsic Value Estimate",
            "Policy/Approx KL",
            "Policy/Clip Fraction",
            "School/P",
            "School/M",
            "Perf/Agent Steps per Second",
            "Environment/Reward per Decision",
            "Reward/boundary_collision",
            "Reward/neighbour_collision",
            "Reward/boundary_distance",
            "Reward/neighbour_distance",
            "Reward/energy",
            "Reward/movement",
            "Reward/chase",
        ] {
            assert!(
                tags.contains(want),
                "{rollout:?}: {want} missing from {tags:?}"
            );
        }
        let steps: Vec<i64> = events
            .iter()
            .filter(|e| e.0 == "Losses/Value Loss")
            .map(|e| e.1)
            .collect();
        match rollout {
            Rollout::Synchronous => assert_eq!(steps, [520, 1040, 1560]),
            Rollout::MlAgents => {
                assert!(!steps.is_empty() && steps[0] <= 1280, "{steps:?}");
                assert!(steps.windows(2).all(|w| w[1] > w[0]), "{steps:?}");
            }
        }
        assert!(events.iter().all(|e| e.2.is_finite()));
        // The learning rate decays linearly to 0 over the 2,000-step budget.
        for e in events.iter().filter(|e| e.0 == "Policy/Learning Rate") {
            let want = 0.001 * (1.0 - e.1 as f32 / 2000.0);
            assert!((e.2 - want).abs() < 1e-7, "{rollout:?}: {e:?}");
        }
        let csv = std::fs::read_to_string(dir.join("scalars.csv")).unwrap();
        assert!(csv.starts_with("behaviour,step,tag,value\n"));
        assert_eq!(
            csv.lines()
                .filter(|l| l.contains(",Losses/Value Loss,"))
                .count(),
            steps.len()
        );
        // The final policy carries the actor as ONNX.
        let onnx = std::fs::metadata(dir.join("final/seabream_regular.onnx")).unwrap();
        assert!(onnx.len() > 100_000, "{} bytes", onnx.len());
    }
}

#[test]
fn resume_continues_at_the_same_step_and_init_from_resets_it() {
    let dir = temp("resume");
    let cfg = PpoConfig {
        rollout: Rollout::Synchronous,
        ..small_config()
    };
    let first = run(
        &dir,
        "seabream_default",
        cfg.clone(),
        2100,
        2,
        false,
        vec![],
    );
    assert_eq!(first.agent_steps, 2100);
    let ck = checkpoints(&dir);
    assert_eq!(
        ck.iter().map(|c| c.0).collect::<Vec<_>>(),
        vec![1000, 2000],
        "every 1000 steps; kept the last 2"
    );
    // A "killed" run: remove the final policy, keep the checkpoints; resume to 4000.
    std::fs::remove_dir_all(dir.join("final")).unwrap();
    let second = run(&dir, "seabream_default", cfg.clone(), 4000, 2, true, vec![]);
    assert_eq!(second.agent_steps, 4000);
    assert_eq!(
        second.steps_this_run, 2000,
        "continued from the checkpoint at 2000"
    );
    let state = RunState::load(&dir.join("final")).unwrap();
    assert_eq!(state.agent_steps, 4000);
    assert_eq!(
        (state.behaviours[0].agent_steps, state.behaviours[0].budget),
        (4000, 4000)
    );
    // Updates every 52 decisions as if never stopped: 520, 1040, 1560, then
    // (the 44 decisions since 1560 kept in the checkpoint) 2080, 2600, 3120,
    // 3640. Before issue 13 the partial rollout was dropped: 2520, 3040, 3560.
    assert_eq!(state.behaviours[0].updates, 7);
    // Resuming another scene is refused with the reason.
    let e = train(
        &Ppo::new(cfg.clone()),
        args(&dir, "seabream_cube5", 5000, 2, true, vec![]),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        e.contains("seabream_default") && e.contains("seabream_cube5"),
        "{e}"
    );
    // So is resuming it under another reward profile than it trained with.
    let mut thesis = args(&dir, "seabream_default", 5000, 2, true, vec![]);
    thesis.scene = Scene::load(
        &dirs().with_reward_profile("thesis"),
        "seabream_default",
        Phase::Pretrain,
    )
    .unwrap();
    let e = train(&Ppo::new(cfg.clone()), thesis)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("trained with reward profile mean_then_budget_space20, not thesis"),
        "{e}"
    );

    // --init-from: weights come from the run, the step count starts at 0.
    let child = temp("child");
    let transfer = run(
        &child,
        "seabream_cube5",
        cfg,
        0,
        3,
        false,
        vec![dir.to_path_buf()],
    );
    assert_eq!(transfer.agent_steps, 0);
    let scene = Scene::load(&dirs(), "seabream_cube5", Phase::Transfer).unwrap();
    let env = Env::new(scene, 5);
    let load = |run: &Path| ActorPolicy::load(run, None, &env, true, 0, &load_actor).unwrap();
    let (mut parent, mut kid) = (load(&dir), load(&child));
    let (mut a, mut b) = (vec![vec![]], vec![vec![]]);
    parent.act(&env, &mut a).unwrap();
    kid.act(&env, &mut b).unwrap();
    assert_eq!(a, b, "same weights, same actions");
    let state = RunState::load(&child.join("final")).unwrap();
    assert_eq!(state.init_from, [dir.display().to_string()]);
}

/// `three_species` starts from three runs, one per species: each behaviour
/// acts exactly as its species' run. Each behaviour trains for its own
/// budget (`--steps 300` → 300 decisions of each of the three, whatever the
/// species' decision intervals), as ML-Agents' per-behaviour `max_steps`.
#[test]
fn three_species_from_three_runs_and_budgets_per_behaviour() {
    let mut cfg = small_config();
    cfg.checkpoint_every = 1_000_000;
    let mut parents: Vec<TempDir> = vec![];
    for species in ["coho", "yellowtail", "seabream"] {
        let dir = temp(&format!("parent-{species}"));
        run(
            &dir,
            &format!("{species}_default"),
            cfg.clone(),
            0,
            4,
            false,
            vec![],
        );
        parents.push(dir);
    }
    let child = temp("three");
    let out = run(
        &child,
        "three_species",
        cfg.clone(),
        300,
        4,
        false,
        paths(&parents),
    );
    let state = RunState::load(&child.join("final")).unwrap();
    let steps: Vec<(String, u64, u64)> = state
        .behaviours
        .iter()
        .map(|b| (b.name.clone(), b.agent_steps, b.budget))
        .collect();
    assert_eq!(
        steps,
        [
            ("coho_regular".into(), 300, 300),
            ("yellowtail_regular".into(), 300, 300),
            ("seabream_regular".into(), 300, 300)
        ]
    );
    assert_eq!(out.agent_steps, 900);
    for b in &state.behaviours {
        assert!(
            child
                .join("final")
                .join(format!("{}.onnx", b.name))
                .is_file()
        );
    }
    // Zero steps: the weights are the parents', behaviour by behaviour.
    let zero = temp("three-zero");
    run(&zero, "three_species", cfg, 0, 4, false, paths(&parents));
    let scene = Scene::load(&dirs(), "three_species", Phase::Transfer).unwrap();
    let env = Env::new(scene, 6);
    let mut kid = ActorPolicy::load(&zero, None, &env, true, 0, &load_actor).unwrap();
    let mut got = vec![vec![]; 3];
    kid.act(&env, &mut got).unwrap();
    for (b, parent) in parents.iter().enumerate() {
        let fin = parent.join("final");
        let st = RunState::load(&fin).unwrap();
        let actor = load_actor(&fin, &st, &st.behaviours[0]).unwrap();
        let batch = &env.output().behaviours[b];
        let want = actor.deterministic(batch.observations(), &batch.vectors);
        assert_eq!(got[b], want, "behaviour {b} acts as {}", parent.display());
    }
}

/// A sink for progress lines that the test can read.
#[derive(Clone, Default)]
struct Lines(Arc<Mutex<Vec<u8>>>);
impl Write for Lines {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Without a terminal, a line every `progress_every` steps of a behaviour
/// (and one at its end), and `scalars.csv` grows while the run goes on.
#[test]
fn progress_lines_when_stdout_is_not_a_terminal() {
    let dir = temp("lines");
    let mut cfg = small_config();
    cfg.rollout = Rollout::Synchronous;
    cfg.progress_every = 1000;
    let lines = Lines::default();
    let mut a = args(&dir, "seabream_default", 2500, 3, false, vec![]);
    a.progress = ProgressMode::Lines;
    a.progress_sink = Some(Box::new(lines.clone()));
    train(&Ppo::new(cfg), a).unwrap();
    let text = String::from_utf8(lines.0.lock().unwrap().clone()).unwrap();
    let got: Vec<&str> = text.lines().collect();
    // Log points at 520, 1040, 1560, 2080 (updates) and 2500 (the end):
    // lines at the first log point past 1000 and 2000, and at the end.
    assert_eq!(got.len(), 3, "{text}");
    assert!(
        got[0].starts_with("seabream_regular: step 1,040/2,500 · "),
        "{text}"
    );
    assert!(
        got[1].starts_with("seabream_regular: step 2,080/2,500 · "),
        "{text}"
    );
    assert!(
        got[2].starts_with("seabream_regular: step 2,500/2,500 · "),
        "{text}"
    );
    for l in &got {
        assert!(
            l.contains("agent-steps/s") && l.contains(" · P ") && l.contains(" · M "),
            "{l}"
        );
    }
}

/// Learning: ten seabream in the 3 m cube, 40,000 agent steps (2,048-transition
/// buffers, 512-sample minibatches, ML-Agents' rollout), in the `legacy` profile. What PPO learns first,
/// reliably, is to stop hitting the net: an untrained fish crosses it about once
/// every 30 decisions (−300 each), and with the energy term measured per physics
/// step (README, SPEC deviations) its own jitter costs little (≈ −0.3 per
/// decision), so nothing else dominates the start. The mean reward per decision
/// of the last three log points must beat the first two's by at least 3.0.
/// Swimming faster than the floor comes later (the quickstart's 300,000 steps),
/// so it is not asserted here.
#[test]
fn ppo_improves_over_the_untrained_policy() {
    let dir = temp("learn");
    let mut cfg = small_config();
    cfg.buffer_size = 2048;
    cfg.batch_size = 512;
    cfg.checkpoint_every = 1_000_000;
    // The per-decision reading (the `legacy` profile) this test's numbers were
    // derived for; under the default per-step timing 40,000 steps are too few to
    // show the same rise (docs/reproduction/NOTES.md trains it for 600,000).
    let mut a = args(&dir, "seabream_default", 40_000, 0, false, vec![]);
    a.scene = Scene::load(
        &dirs().with_reward_profile("legacy"),
        "seabream_default",
        Phase::Pretrain,
    )
    .unwrap();
    let out = train(&Ppo::new(cfg), a).unwrap();
    assert!(out.curve.len() >= 10, "{} log points", out.curve.len());
    let v: Vec<f64> = out.curve.iter().map(|x| x.1).collect();
    let first = (v[0] + v[1]) / 2.0;
    let last = v[v.len() - 3..].iter().sum::<f64>() / 3.0;
    eprintln!("reward per decision: first {first:.3}, last three {last:.3}; curve {v:?}");
    assert!(
        last > first + 3.0,
        "reward per decision: first {first:.3}, last {last:.3}"
    );
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let dst = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &dst);
        } else {
            std::fs::copy(e.path(), dst).unwrap();
        }
    }
}

/// `dir` as a run killed right after its checkpoint at `step`: no final
/// policy, no later checkpoint, but the points logged after it (as a killed
/// run leaves them).
fn kill_after_checkpoint(dir: &Path, step: u64) {
    std::fs::remove_dir_all(dir.join("final")).unwrap();
    let all = checkpoints(dir);
    assert!(all.iter().any(|c| c.0 == step), "{all:?}");
    for (s, d) in all {
        if s > step {
            std::fs::remove_dir_all(d).unwrap();
        }
    }
}

/// Every `(behaviour, tag, step)` of `scalars.csv` once.
fn csv_rows_once(dir: &Path) -> BTreeSet<(String, String, u64)> {
    let csv = std::fs::read_to_string(dir.join("scalars.csv")).unwrap();
    let mut seen = BTreeSet::new();
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.splitn(4, ',').collect();
        let key = (f[0].to_string(), f[2].to_string(), f[1].parse().unwrap());
        assert!(seen.insert(key.clone()), "{key:?} twice in scalars.csv");
    }
    seen
}

/// Issue 13 items 3 and 4. A run killed after its checkpoint at 1,400 agent
/// steps (2,700-step budget, 10 fish, 512-transition buffers) and resumed
/// makes as many updates and ends at the same step as the run never stopped:
/// with the synchronous scheme 5 updates (every 52 decisions: 520 … 2600)
/// at the same steps — before issue 13 the 36 decisions since the update at
/// 1,040 were dropped and counted, so the resumed run updated at 1,920 and
/// 2,440 only: 4. TensorBoard's event files (read with tensorboard-proto)
/// and `scalars.csv` hold one value per tag and step, the points up to the
/// checkpoint kept.
#[test]
fn a_killed_run_resumes_as_the_run_never_stopped() {
    for rollout in [Rollout::Synchronous, Rollout::MlAgents] {
        let cfg = PpoConfig {
            rollout,
            checkpoint_every: 700,
            keep_checkpoints: 10,
            ..small_config()
        };
        let whole = temp(&format!("whole-{rollout:?}"));
        run(
            &whole,
            "seabream_default",
            cfg.clone(),
            2700,
            4,
            false,
            vec![],
        );
        let never_stopped = RunState::load(&whole.join("final")).unwrap();
        let killed = temp(&format!("killed-{rollout:?}"));
        copy_dir(&whole, &killed);
        kill_after_checkpoint(&killed, 1400);
        let before = read_events(&killed.join("tb/seabream_regular"));
        assert!(
            before.iter().any(|e| e.1 > 1400),
            "the killed run logged after its checkpoint"
        );
        run(
            &killed,
            "seabream_default",
            cfg.clone(),
            2700,
            4,
            true,
            vec![],
        );
        let resumed = RunState::load(&killed.join("final")).unwrap();
        assert_eq!(
            (resumed.agent_steps, resumed.behaviours[0].updates),
            (
                never_stopped.agent_steps,
                never_stopped.behaviours[0].updates
            ),
            "{rollout:?}: final step and updates"
        );
        assert_eq!(resumed.agent_steps, 2700);

        let events = read_events(&killed.join("tb/seabream_regular"));
        let mut seen = BTreeSet::new();
        for (tag, step, _) in &events {
            assert!(
                seen.insert((tag.clone(), *step)),
                "{rollout:?}: {tag} twice at step {step} in TensorBoard"
            );
        }
        let kept: Vec<_> = before.iter().filter(|e| e.1 <= 1400).collect();
        assert!(!kept.is_empty());
        for e in kept {
            assert!(events.contains(e), "{e:?} kept");
        }
        let rows = csv_rows_once(&killed);
        assert_eq!(rows.len(), events.len(), "the CSV holds the same points");
        let update_steps = |ev: &[(String, i64, f32)]| -> Vec<i64> {
            ev.iter()
                .filter(|e| e.0 == "Losses/Value Loss")
                .map(|e| e.1)
                .collect()
        };
        if rollout == Rollout::Synchronous {
            let whole_events = read_events(&whole.join("tb/seabream_regular"));
            assert_eq!(update_steps(&events), [520, 1040, 1560, 2080, 2600]);
            assert_eq!(update_steps(&events), update_steps(&whole_events));
        }
        let _ = std::fs::remove_dir_all(&whole);
        let _ = std::fs::remove_dir_all(&killed);
    }
}
