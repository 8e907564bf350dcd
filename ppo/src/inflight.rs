//! PPO's experience in flight at a checkpoint (issue 13 item 4).
//!
//! A checkpoint falls between updates: the agent steps counted so far include
//! steps in open trajectories and in a buffer not yet learned from. Were they
//! dropped, a resumed run would count them against its budget without ever
//! learning from them, and make fewer updates than the run never stopped.
//! So at a checkpoint — in every run, killed or not, so that both go on from
//! the same state —
//!
//! 1. [`cut_open`] closes each agent's open trajectory before its newest step
//!    (the one still waiting for its reward), bootstrapped from that step's
//!    value — the critic's value of the next observation, exactly what a cut
//!    at `time_horizon` uses — and moves it into the buffer; the newest step
//!    starts the agent's next trajectory;
//! 2. the buffer (closed trajectories with their advantages and returns) is
//!    saved beside the weights ([`save_buffer`], `<behaviour>.rollout.bin`).
//!
//! A resumed run loads the buffer and starts new trajectories from its reset
//! environment; the newest steps at the checkpoint were not counted yet, so
//! nothing counted is lost. With the synchronous scheme the updates then fall
//! at the same steps as in the run never stopped. With ML-Agents' scheme an
//! update comes once the closed trajectories hold `buffer_size` transitions,
//! and episode ends close trajectories early; the resumed run's environment
//! is reseeded, so its episode ends — and the step of an update — can
//! differ by up to a time horizon, and an update close to the end of the
//! budget can fall on either side of it.
//!
//! # File
//! `DFROLL01`, the trajectory count (`u64`), then per trajectory its length
//! `L` (`u64`), its `(2 + L)` quantised frames, and `L` vectors, actions,
//! log-probabilities, values, rewards, advantages, returns (`f32`) and stop
//! codes (`u8`), little-endian.

use crate::gae::{BOOTSTRAP, CONTINUE};
use crate::rollout::{Buffer, Rollout, Trajectory};
use deepfoids_env::VECTOR_OBS;
use deepfoids_learn::frames::FRAME_BYTES;
use deepfoids_learn::{ACTIONS, LearnError, Result};
use std::io::{Read, Write};
use std::path::Path;

const MAGIC: &[u8; 8] = b"DFROLL01";

/// Close every open trajectory before its newest, unrewarded step (see the
/// module documentation); returns the steps moved into the buffer.
pub fn cut_open(rollout: &mut Rollout, gamma: f32, lambda: f32) -> usize {
    let mut moved = 0;
    for a in 0..rollout.open.len() {
        let t = &mut rollout.open[a];
        let l = t.len();
        // Only `L − 1` rewarded steps, the last of them continuing: a trajectory
        // ended by its stop code was closed at the decision.
        if l < 2 || t.rewards.len() != l - 1 || t.stops.last() != Some(&CONTINUE) {
            continue;
        }
        let newest = Trajectory {
            frames: t.frames[(l - 1) * FRAME_BYTES..(l + 2) * FRAME_BYTES].to_vec(),
            vectors: t.vectors.split_off((l - 1) * VECTOR_OBS),
            actions: t.actions.split_off((l - 1) * ACTIONS),
            logprobs: t.logprobs.split_off(l - 1),
            values: t.values.split_off(l - 1),
            ..Trajectory::default()
        };
        t.frames.truncate((l + 1) * FRAME_BYTES);
        *t.stops.last_mut().expect("L − 1 ≥ 1 stop codes") = BOOTSTRAP;
        let next_value = newest.values[0];
        let mut closed = std::mem::replace(t, newest);
        closed.finish(next_value, gamma, lambda);
        moved += closed.len();
        rollout.buffer.push(closed);
    }
    moved
}

/// Write the buffer's trajectories to `path`.
pub fn save_buffer(buffer: &Buffer, path: &Path) -> Result<()> {
    write(buffer, path).map_err(LearnError::io(path))
}

fn write(buffer: &Buffer, path: &Path) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::with_capacity(1 << 20, std::fs::File::create(path)?);
    w.write_all(MAGIC)?;
    w.write_all(&(buffer.trajectories.len() as u64).to_le_bytes())?;
    for t in &buffer.trajectories {
        w.write_all(&(t.len() as u64).to_le_bytes())?;
        w.write_all(&t.frames)?;
        for xs in [
            &t.vectors,
            &t.actions,
            &t.logprobs,
            &t.values,
            &t.rewards,
            &t.advantages,
            &t.returns,
        ] {
            for x in xs {
                w.write_all(&x.to_le_bytes())?;
            }
        }
        w.write_all(&t.stops)?;
    }
    w.flush()
}

/// Read a buffer written by [`save_buffer`].
pub fn load_buffer(path: &Path) -> Result<Buffer> {
    let file = std::fs::File::open(path).map_err(LearnError::io(path))?;
    let size = file.metadata().map_err(LearnError::io(path))?.len();
    let mut r = std::io::BufReader::with_capacity(1 << 20, file);
    let bad = |what: &str| LearnError::Corrupt {
        path: path.to_path_buf(),
        reason: format!("not a PPO rollout of this version: {what}"),
    };
    let mut read = |dst: &mut [u8]| r.read_exact(dst).map_err(|_| bad("truncated"));
    let mut magic = [0u8; 8];
    read(&mut magic)?;
    if &magic != MAGIC {
        return Err(bad("wrong magic bytes"));
    }
    let mut word = [0u8; 8];
    read(&mut word)?;
    let count = u64::from_le_bytes(word);
    let mut buffer = Buffer::default();
    let mut left = size.saturating_sub(16);
    for _ in 0..count {
        read(&mut word)?;
        let l = u64::from_le_bytes(word);
        // The trajectory's bytes must be in the file (no allocation from a bad length).
        let need = l
            .checked_add(2)
            .and_then(|f| f.checked_mul(FRAME_BYTES as u64))
            .and_then(|f| f.checked_add(l.checked_mul(4 * (VECTOR_OBS + ACTIONS + 5) as u64 + 1)?))
            .filter(|&n| n + 8 <= left)
            .ok_or_else(|| bad("a trajectory longer than the file"))?;
        left -= need + 8;
        let l = l as usize;
        let mut t = Trajectory {
            frames: vec![0; (2 + l) * FRAME_BYTES],
            stops: vec![0; l],
            ..Trajectory::default()
        };
        read(&mut t.frames)?;
        for (xs, width) in [
            (&mut t.vectors, VECTOR_OBS),
            (&mut t.actions, ACTIONS),
            (&mut t.logprobs, 1),
            (&mut t.values, 1),
            (&mut t.rewards, 1),
            (&mut t.advantages, 1),
            (&mut t.returns, 1),
        ] {
            let mut bytes = vec![0u8; l * width * 4];
            read(&mut bytes)?;
            xs.extend(
                bytes
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            );
        }
        read(&mut t.stops)?;
        buffer.push(t);
    }
    if left != 0 {
        return Err(bad("bytes after the last trajectory"));
    }
    Ok(buffer)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gae::TERMINAL;
    use deepfoids_sensors::{GridsRef, STACKED_LEN};

    /// A stack whose three frames hold proximity `(i, i + 1, i + 2) / 100` in cell 0.
    fn stack(i: usize) -> Vec<f32> {
        let mut s = vec![0.0; STACKED_LEN];
        for k in 0..3 {
            s[k * deepfoids_sensors::FRAME_LEN] = (i + k) as f32 / 100.0;
        }
        s
    }

    /// Agent 0 has three rewarded steps and a fourth waiting: the cut closes
    /// steps 0–2 bootstrapped from step 3's value (GAE with λ = 1, γ = 0.5:
    /// returns 3 + 0.5·8 = 7, 2 + 0.5·7 = 5.5, 1 + 0.5·5.5 = 3.75) and keeps step 3 open with its whole stack. Agent 1 has
    /// one waiting step only: nothing to cut. The buffer round-trips exactly.
    #[test]
    fn cut_before_the_newest_step_and_round_trip() {
        let mut r = Rollout::new(2, 8);
        for (i, value) in [1.0, 2.0, 3.0, 8.0].into_iter().enumerate() {
            r.open[0].push(
                GridsRef::Dense(&stack(i)),
                &[i as f32; VECTOR_OBS],
                &[0.5; ACTIONS],
                -1.0,
                value,
            );
            if i < 3 {
                r.open[0].reward(i as f32 + 1.0, CONTINUE);
            }
        }
        r.open[1].push(
            GridsRef::Dense(&stack(40)),
            &[0.0; VECTOR_OBS],
            &[0.0; ACTIONS],
            -1.0,
            0.0,
        );
        let newest_stack = {
            let mut s = vec![0u8; deepfoids_learn::frames::STACK_BYTES];
            r.open[0].stack_into(3, &mut s);
            s
        };
        assert_eq!(cut_open(&mut r, 0.5, 1.0), 3);
        assert_eq!(r.buffer.transitions(), 3);
        let closed = &r.buffer.trajectories[0];
        assert_eq!(closed.stops, [CONTINUE, CONTINUE, BOOTSTRAP]);
        assert_eq!(closed.returns, [3.75, 5.5, 7.0]);
        assert_eq!(closed.frames.len(), 5 * FRAME_BYTES);
        let open = &r.open[0];
        assert_eq!(
            (open.len(), open.values[0], open.rewards.len()),
            (1, 8.0, 0)
        );
        let mut s = vec![0u8; newest_stack.len()];
        open.stack_into(0, &mut s);
        assert_eq!(s, newest_stack);
        assert_eq!(r.open[1].len(), 1);

        // A terminated trajectory in the buffer too, then the file.
        let mut t = Trajectory::default();
        t.push(
            GridsRef::Dense(&stack(7)),
            &[1.0; VECTOR_OBS],
            &[0.1; ACTIONS],
            -2.0,
            4.0,
        );
        t.reward(-300.0, TERMINAL);
        t.finish(0.0, 0.5, 1.0);
        r.buffer.push(t);
        let path = std::env::temp_dir().join(format!("rollout-{}.bin", std::process::id()));
        save_buffer(&r.buffer, &path).unwrap();
        let back = load_buffer(&path).unwrap();
        assert_eq!(back.transitions(), 4);
        for (a, b) in back.trajectories.iter().zip(&r.buffer.trajectories) {
            assert_eq!(
                (&a.frames, &a.vectors, &a.actions, &a.logprobs, &a.values),
                (&b.frames, &b.vectors, &b.actions, &b.logprobs, &b.values)
            );
            assert_eq!(
                (&a.rewards, &a.advantages, &a.returns, &a.stops),
                (&b.rewards, &b.advantages, &b.returns, &b.stops)
            );
        }
        // Cut short or padded: refused.
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        assert!(load_buffer(&path).is_err());
        std::fs::write(&path, [&bytes[..], &[0]].concat()).unwrap();
        assert!(load_buffer(&path).is_err());
        let _ = std::fs::remove_file(&path);
    }
}
