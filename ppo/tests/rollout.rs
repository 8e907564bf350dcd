//! ML-Agents' rollout, decision by decision, with hand-computed expectations:
//! ten agents, `time_horizon` 4, `buffer_size` 30, agent 0 terminated at the
//! second decision.

use burn::prelude::Device;
use deepfoids_env::{ConfigDirs, Env, Phase, Scene};
use deepfoids_learn::Backend;
use deepfoids_learn::driver::{Learner, LearnerCtx, StepCtx, Timing, Trainer};
use deepfoids_learn::plan::TrainConfigFile;
use deepfoids_ppo::train::PpoLearner;
use deepfoids_ppo::{Ppo, PpoConfig, Rollout};

fn dirs() -> ConfigDirs {
    ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs"))
}

/// Runs decisions 1..=9 after the first actions; returns `(updates, buffered)`
/// after each and the open trajectories' lengths after the last.
fn run(rollout: Rollout) -> (Vec<(u64, usize)>, Vec<usize>) {
    let env = Env::new(
        Scene::load(&dirs(), "seabream_default", Phase::Pretrain).unwrap(),
        1,
    );
    let info = env.behaviours()[0].clone();
    assert_eq!(info.count, 10);
    let mut batch = env.output().behaviours[0].clone();
    let config = PpoConfig {
        rollout,
        time_horizon: 4,
        buffer_size: 30,
        batch_size: 10,
        epochs: 1,
        hidden: 16,
        layers: 1,
        ..PpoConfig::load(&dirs()).unwrap()
    };
    let ppo = Ppo::new(config);
    let ctx = LearnerCtx {
        info: &info,
        index: 0,
        phase: Phase::Pretrain,
        seed: 0,
        backend: Backend::Flex,
        train_device: Device::flex().autodiff(),
        device: Device::flex(),
    };
    let mut l: PpoLearner = ppo.new_learner(&ctx).unwrap();
    let mut timing = Timing::default();
    let mut actions = vec![0.0; 30];
    fn step(d: u64, timing: &mut Timing) -> StepCtx<'_> {
        StepCtx {
            seed: 0,
            tick: d,
            training: true,
            agent_steps: 10 * d,
            budget: 10_000,
            timing,
        }
    }
    l.start(&batch, &mut actions, &mut step(0, &mut timing))
        .unwrap();
    let mut seen = vec![];
    for d in 1..=9u64 {
        batch.rewards = vec![1.0; 10];
        batch.terminated = (0..10).map(|a| a == 0 && d == 2).collect();
        batch.truncated = vec![false; 10];
        l.decide(&batch, &mut actions, &mut step(d, &mut timing))
            .unwrap();
        seen.push((l.updates(), l.buffered()));
    }
    (seen, l.open_lengths())
}

/// Agent 0's first trajectory ends at decision 2 (terminated, 2 steps); the
/// others reach the horizon at decision 4 (4 steps each): 2 + 36 = 38 ≥ 30,
/// an update. Agent 0's second trajectory (steps at decisions 2–5) reaches
/// the horizon at 6 (buffer 4); the others' second ones at 8: 4 + 36 = 40,
/// the second update. After decision 9 agent 0 holds steps 6–9 (4; it closes
/// at the next decision), the others steps 8–9.
#[test]
fn ml_agents_rollout_by_hand() {
    let (seen, open) = run(Rollout::MlAgents);
    assert_eq!(
        seen,
        vec![
            (0, 0),
            (0, 2),
            (0, 2),
            (1, 0),
            (1, 0),
            (1, 4),
            (1, 4),
            (2, 0),
            (2, 0)
        ]
    );
    assert_eq!(open, [4, 2, 2, 2, 2, 2, 2, 2, 2, 2]);
}

/// The synchronous scheme: `ceil(30 / 10) = 3` decisions per update, every
/// trajectory cut there, whatever the terminations (agent 0's terminated
/// trajectory waits in the buffer for the update at decision 3).
#[test]
fn synchronous_rollout_by_hand() {
    let (seen, open) = run(Rollout::Synchronous);
    assert_eq!(
        seen,
        vec![
            (0, 0),
            (0, 2),
            (1, 0),
            (1, 0),
            (1, 0),
            (2, 0),
            (2, 0),
            (2, 0),
            (3, 0)
        ]
    );
    assert_eq!(open, [1; 10]);
}
