//! PPO's experience as ML-Agents collects it (SPEC §8): per-agent
//! trajectories, each frame stored once, in bytes.
//!
//! Every agent has an open [`Trajectory`]. At each decision of its behaviour
//! it gets the step's reward and episode end; it closes when its episode ends
//! (terminated: no bootstrap; truncated: bootstrap) or when it holds
//! `time_horizon` decisions (cut: bootstrap from the critic's value of the
//! next observation). A closed trajectory gets its advantages and returns by
//! GAE and joins the [`Buffer`]; PPO updates once the buffer holds at least
//! `buffer_size` transitions and then empties it. Trajectories still open
//! carry over into the next update's buffer.
//!
//! # Storage
//! A trajectory of `L` steps keeps `2 + L` quantised frames
//! ([`deepfoids_learn::frames`], 1,360 bytes each): the two older frames of
//! its first step's stack (zero bytes where the stack had none, after a
//! respawn), then each step's newest frame; step `t`'s stacked observation is
//! frames `t, t + 1, t + 2`. A trajectory never spans a respawn (termination
//! closes it), so its frames are consecutive. Per step besides the frame:
//! vector 24 B, action 12 B, log-probability, value, reward, advantage and
//! return 4 B each, the stop code 1 B: ≈ 1,417 bytes a transition, against
//! ≈ 49,000 for an f32 stack. Closed trajectories move (not copy) into the
//! buffer and their storage is reused after the update.

use crate::gae::gae;
use deepfoids_env::VECTOR_OBS;
use deepfoids_learn::ACTIONS;
use deepfoids_learn::frames::{CompactGrids, FRAME_BYTES, STACK_BYTES, quantise};
use deepfoids_sensors::{FRAME_LEN, GridsRef, STACK, STACKED_LEN};

/// One agent's consecutive decisions.
#[derive(Clone, Debug, Default)]
pub struct Trajectory {
    /// `(2 + len) × FRAME_BYTES`: the first step's two older frames, then each step's newest.
    pub frames: Vec<u8>,
    pub vectors: Vec<f32>,
    pub actions: Vec<f32>,
    pub logprobs: Vec<f32>,
    pub values: Vec<f32>,
    pub rewards: Vec<f32>,
    /// GAE stop codes (`gae::CONTINUE`, `BOOTSTRAP`, `TERMINAL`); the last one ends it.
    pub stops: Vec<u8>,
    pub advantages: Vec<f32>,
    pub returns: Vec<f32>,
}

impl Trajectory {
    /// An empty trajectory with room for exactly `steps` decisions: growing
    /// by doubling would leave up to half of every frame buffer unused
    /// (measured on `coho_default`: 331 MB allocated against 180 MB reserved exactly).
    pub fn with_capacity(steps: usize) -> Self {
        Self {
            frames: Vec::with_capacity((STACK - 1 + steps) * FRAME_BYTES),
            vectors: Vec::with_capacity(steps * VECTOR_OBS),
            actions: Vec::with_capacity(steps * ACTIONS),
            logprobs: Vec::with_capacity(steps),
            values: Vec::with_capacity(steps),
            rewards: Vec::with_capacity(steps),
            stops: Vec::with_capacity(steps),
            advantages: Vec::with_capacity(steps),
            returns: Vec::with_capacity(steps),
        }
    }

    pub fn len(&self) -> usize {
        self.values.len()
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    fn clear(&mut self) {
        self.frames.clear();
        self.vectors.clear();
        self.actions.clear();
        self.logprobs.clear();
        self.values.clear();
        self.rewards.clear();
        self.stops.clear();
        self.advantages.clear();
        self.returns.clear();
    }

    /// Append a step: its stacked observation `stack` (one stack, floats
    /// `[18, 20, 34]` or bytes; the older frames are kept only for the first
    /// step), vector, action (the unclipped sample), log-probability and value.
    pub fn push(
        &mut self,
        stack: GridsRef<'_>,
        vector: &[f32],
        action: &[f32],
        logprob: f32,
        value: f32,
    ) {
        let first = if self.is_empty() { 0 } else { STACK - 1 };
        for k in first..STACK {
            match stack {
                GridsRef::Dense(x) => {
                    let at = self.frames.len();
                    self.frames.resize(at + FRAME_BYTES, 0);
                    quantise(
                        &x[k * FRAME_LEN..(k + 1) * FRAME_LEN],
                        &mut self.frames[at..],
                    );
                }
                GridsRef::Compact(b) => self
                    .frames
                    .extend_from_slice(&b[k * FRAME_BYTES..(k + 1) * FRAME_BYTES]),
            }
        }
        self.vectors.extend_from_slice(vector);
        self.actions.extend_from_slice(action);
        self.logprobs.push(logprob);
        self.values.push(value);
    }

    /// The reward and stop code of the last step.
    pub fn reward(&mut self, reward: f32, stop: u8) {
        self.rewards.push(reward);
        self.stops.push(stop);
    }

    /// The last step's stop code, once its reward is in.
    pub fn last_stop(&self) -> Option<u8> {
        if self.is_empty() || self.stops.len() != self.len() {
            return None;
        }
        self.stops.last().copied()
    }

    /// Advantages and returns by GAE; `next_value` is the critic's value of
    /// the observation after the last step (unused after a termination).
    pub fn finish(&mut self, next_value: f32, gamma: f32, lambda: f32) {
        let n = self.len();
        self.advantages.resize(n, 0.0);
        self.returns.resize(n, 0.0);
        gae(
            &self.rewards,
            &self.values,
            next_value,
            &self.stops,
            gamma,
            lambda,
            &mut self.advantages,
            &mut self.returns,
        );
    }

    /// Bytes held (capacity).
    pub fn capacity_bytes(&self) -> usize {
        self.frames.capacity()
            + 4 * (self.vectors.capacity()
                + self.actions.capacity()
                + self.logprobs.capacity()
                + self.values.capacity()
                + self.rewards.capacity()
                + self.advantages.capacity()
                + self.returns.capacity())
            + self.stops.capacity()
    }

    /// Bytes written.
    pub fn len_bytes(&self) -> usize {
        self.frames.len() + self.len() * STEP_BYTES
    }

    /// Copy step `t`'s stacked observation (three frames) into `out` (`STACK_BYTES`).
    pub fn stack_into(&self, t: usize, out: &mut [u8]) {
        out.copy_from_slice(&self.frames[t * FRAME_BYTES..t * FRAME_BYTES + STACK_BYTES]);
    }
}

/// Bytes per step besides the frame: vector, action, and five floats
/// (log-probability, value, reward, advantage, return), and the stop code.
pub const STEP_BYTES: usize = 4 * (VECTOR_OBS + ACTIONS + 5) + 1;

/// Closed trajectories waiting for an update.
#[derive(Debug, Default)]
pub struct Buffer {
    pub trajectories: Vec<Trajectory>,
    transitions: usize,
}

/// A minibatch gathered from the buffer.
pub struct Minibatch {
    pub grids: CompactGrids,
    pub vectors: Vec<f32>,
    pub actions: Vec<f32>,
    pub logprobs: Vec<f32>,
    pub advantages: Vec<f32>,
    pub returns: Vec<f32>,
}

impl Buffer {
    pub fn transitions(&self) -> usize {
        self.transitions
    }

    pub fn push(&mut self, t: Trajectory) {
        self.transitions += t.len();
        self.trajectories.push(t);
    }

    /// Every transition as `(trajectory, step)`, in the order they joined.
    pub fn indices(&self) -> Vec<(u32, u32)> {
        self.trajectories
            .iter()
            .enumerate()
            .flat_map(|(i, t)| (0..t.len()).map(move |s| (i as u32, s as u32)))
            .collect()
    }

    /// The transitions `inds` as flat buffers.
    pub fn gather(&self, inds: &[(u32, u32)]) -> Minibatch {
        let m = inds.len();
        let mut mb = Minibatch {
            grids: CompactGrids::with_len(m),
            vectors: Vec::with_capacity(m * VECTOR_OBS),
            actions: Vec::with_capacity(m * ACTIONS),
            logprobs: Vec::with_capacity(m),
            advantages: Vec::with_capacity(m),
            returns: Vec::with_capacity(m),
        };
        for (i, &(tr, s)) in inds.iter().enumerate() {
            let (t, s) = (&self.trajectories[tr as usize], s as usize);
            t.stack_into(
                s,
                &mut mb.grids.bytes[i * STACK_BYTES..(i + 1) * STACK_BYTES],
            );
            mb.vectors
                .extend_from_slice(&t.vectors[s * VECTOR_OBS..(s + 1) * VECTOR_OBS]);
            mb.actions
                .extend_from_slice(&t.actions[s * ACTIONS..(s + 1) * ACTIONS]);
            mb.logprobs.push(t.logprobs[s]);
            mb.advantages.push(t.advantages[s]);
            mb.returns.push(t.returns[s]);
        }
        mb
    }

    /// Empty the buffer; the trajectories' storage goes to `spare` for reuse.
    pub fn drain_into(&mut self, spare: &mut Vec<Trajectory>) {
        for mut t in self.trajectories.drain(..) {
            t.clear();
            spare.push(t);
        }
        self.transitions = 0;
    }
}

/// Every agent's open trajectory and the buffer of closed ones.
pub struct Rollout {
    pub open: Vec<Trajectory>,
    /// The most decisions a trajectory holds (room reserved for each).
    steps: usize,
    pub buffer: Buffer,
    spare: Vec<Trajectory>,
    /// The most bytes held at once (capacity), measured at updates.
    pub peak_bytes: usize,
}

impl Rollout {
    /// Open trajectories for `agents`, each of at most `steps` decisions.
    pub fn new(agents: usize, steps: usize) -> Self {
        Self {
            open: (0..agents)
                .map(|_| Trajectory::with_capacity(steps))
                .collect(),
            steps,
            buffer: Buffer::default(),
            spare: vec![],
            peak_bytes: 0,
        }
    }

    /// Close agent `a`'s trajectory: GAE with `next_value`, into the buffer.
    pub fn close(&mut self, a: usize, next_value: f32, gamma: f32, lambda: f32) {
        let fresh = self
            .spare
            .pop()
            .unwrap_or_else(|| Trajectory::with_capacity(self.steps));
        let mut t = std::mem::replace(&mut self.open[a], fresh);
        t.finish(next_value, gamma, lambda);
        self.buffer.push(t);
    }

    /// Drop every open trajectory (after a reset, or when training stops).
    pub fn drop_open(&mut self) {
        for t in &mut self.open {
            t.clear();
        }
    }

    /// Bytes allocated by every trajectory (open, buffered, spare).
    pub fn capacity_bytes(&self) -> usize {
        self.open
            .iter()
            .chain(&self.buffer.trajectories)
            .chain(&self.spare)
            .map(Trajectory::capacity_bytes)
            .sum()
    }

    /// Bytes written in the open and buffered trajectories.
    pub fn len_bytes(&self) -> usize {
        self.open
            .iter()
            .chain(&self.buffer.trajectories)
            .map(Trajectory::len_bytes)
            .sum()
    }

    /// After an update: note the size, empty the buffer, keep its storage for reuse.
    pub fn clear_buffer(&mut self) {
        self.peak_bytes = self.peak_bytes.max(self.capacity_bytes());
        self.buffer.drain_into(&mut self.spare);
    }
}

/// The stacked observation of agent `a` in a batch, in the batch's format.
pub fn stack_of(grids: GridsRef<'_>, a: usize) -> GridsRef<'_> {
    match grids {
        GridsRef::Dense(x) => GridsRef::Dense(&x[a * STACKED_LEN..(a + 1) * STACKED_LEN]),
        GridsRef::Compact(b) => GridsRef::Compact(&b[a * STACK_BYTES..(a + 1) * STACK_BYTES]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gae::{BOOTSTRAP, CONTINUE};
    use deepfoids_learn::frames::{FRAME_BYTES, quantise};
    use deepfoids_sensors::CELLS;

    /// A frame whose cell 0 holds proximity `i / 10` and a fish.
    fn frame(i: usize) -> Vec<f32> {
        let mut f = vec![0.0; FRAME_LEN];
        f[0] = i as f32 / 10.0;
        f[CELLS] = 1.0;
        f
    }

    /// Stack `t` = frames `t − 2, t − 1, t`, with zeros before frame 0 (a fresh stack).
    fn stack(t: usize) -> Vec<f32> {
        (0..STACK)
            .flat_map(|k| {
                let i = t as isize - 2 + k as isize;
                if i < 0 {
                    vec![0.0; FRAME_LEN]
                } else {
                    frame(i as usize)
                }
            })
            .collect()
    }

    /// Three steps keep 2 + 3 frames; each step's stack comes back exactly
    /// as it was quantised, zero frames included; GAE with γ = 0.9, λ = 0.5
    /// over rewards (1, 2, 3), values (0.5, 1, 1.5), cut with V = 2 after:
    /// A = (3.12575, 3.835, 3.3) (gae.rs's hand-computed case).
    #[test]
    fn frames_are_stored_once_and_stacks_rebuild() {
        let mut t = Trajectory::default();
        for s in 0..3 {
            t.push(
                GridsRef::Dense(&stack(s)),
                &[0.0; VECTOR_OBS],
                &[0.0; ACTIONS],
                0.0,
                0.5 * (s + 1) as f32,
            );
            t.reward((s + 1) as f32, if s == 2 { BOOTSTRAP } else { CONTINUE });
        }
        assert_eq!(t.frames.len(), 5 * FRAME_BYTES);
        for s in 0..3 {
            let mut got = vec![0u8; STACK_BYTES];
            t.stack_into(s, &mut got);
            let mut want = vec![0u8; STACK_BYTES];
            for (k, chunk) in want.chunks_exact_mut(FRAME_BYTES).enumerate() {
                quantise(&stack(s)[k * FRAME_LEN..(k + 1) * FRAME_LEN], chunk);
            }
            assert_eq!(got, want, "step {s}");
        }
        assert_eq!(t.last_stop(), Some(BOOTSTRAP));
        // The same steps handed over as the sensor's bytes store the same frames.
        let mut b = Trajectory::default();
        for s in 0..3 {
            let mut bytes = vec![0u8; STACK_BYTES];
            t.stack_into(s, &mut bytes);
            b.push(
                GridsRef::Compact(&bytes),
                &[0.0; VECTOR_OBS],
                &[0.0; ACTIONS],
                0.0,
                0.0,
            );
        }
        assert_eq!(b.frames, t.frames);
        t.finish(2.0, 0.9, 0.5);
        for (a, w) in t.advantages.iter().zip([3.12575f32, 3.835, 3.3]) {
            assert!((a - w).abs() < 1e-5, "{:?}", t.advantages);
        }
    }
}
