//! The replay buffer of one behaviour: each grid frame stored once, quantised.
//!
//! All agents of a behaviour decide together, so the buffer is a ring of
//! *rows*, one per decision: row `t` holds, for every agent, the newest frame
//! of its observation at decision `t`, its vector observation, the action it
//! took, and — once the next decision arrives — the reward and whether it was
//! terminated. The transition `(s_t, a_t, r_t, s_{t+1})` is row `t` plus row
//! `t + 1`'s observation, so next observations are not stored twice, and the
//! stacked observation `[frame t−2, frame t−1, frame t]` is rebuilt from the
//! rows by index. `history` (0–2) records how many older frames the stack had
//! (a new episode's stack starts with zeros, SPEC §7); older frames are zeros.
//!
//! # Quantisation and size
//! Frames are stored as `deepfoids_learn::frames` quantises them: two bytes a
//! cell, the proximity (error ≤ 1/510) and the index of the hot type channel
//! (exact). Sampled stacks stay quantised ([`CompactGrids`]): the encoder
//! kernels read them as they are. Per transition:
//!
//! | part | bytes |
//! |---|---|
//! | frame: proximity u8 × 680 + type u8 × 680 | 1,360 |
//! | vector observation, 6 × f32 | 24 |
//! | action (squashed, as the critics see it), 3 × f32 | 12 |
//! | reward f32, terminated u8, history u8 | 6 |
//! | **total** | **1,402** |
//!
//! 102,400 transitions take 143.6 MB (plus 3 spare rows), against ≈ 10 GB for
//! two f32 stacks per transition. Rows: `ceil(capacity / agents) + 3` — two
//! rows of history before the oldest sampled one, and the newest row, whose
//! transition is not complete yet.
//!
//! A checkpoint's replay file (`<behaviour>.replay.bin`) holds only the rows
//! written so far ([`Replay::file_bytes`]): 10,000 transitions of a
//! 102,400-transition buffer take 14 MB, not 143.6 MB.

use deepfoids_env::VECTOR_OBS;
use deepfoids_learn::ACTIONS;
use deepfoids_learn::frames::{CompactGrids, FRAME_BYTES, STACK_BYTES, dequantise, newest_frames};
use deepfoids_learn::{LearnError, Result};
use deepfoids_sensors::{FRAME_LEN, GridsRef, STACK};
use rayon::prelude::*;
use std::io::{Read, Write};
use std::path::Path;

pub use deepfoids_learn::frames::PROXIMITY_TOLERANCE;

/// Bytes stored per transition (see the module documentation).
pub const BYTES_PER_TRANSITION: usize = FRAME_BYTES + 4 * VECTOR_OBS + 4 * ACTIONS + 4 + 1 + 1;

/// Files written since issue 13: only the rows written so far.
const MAGIC: &[u8; 8] = b"DFREPLY3";
/// Files before: every row of the capacity, filled or not (still read).
const MAGIC_FULL: &[u8; 8] = b"DFREPLY2";
/// Bytes of a file's header: magic, agents, rows, head.
const HEADER_BYTES: usize = 8 + 3 * 8;

/// The history of an agent's next stack: 0 after a respawn (the stack restarts
/// with zeros, SPEC §7), else one more older frame, at most two.
pub fn next_history(history: u8, terminated: bool) -> u8 {
    if terminated { 0 } else { (history + 1).min(2) }
}

/// A sampled minibatch: quantised stacks and flat f32 buffers.
#[derive(Default)]
pub struct Batch {
    pub len: usize,
    pub grids: CompactGrids,
    pub vectors: Vec<f32>,
    pub actions: Vec<f32>,
    pub rewards: Vec<f32>,
    pub terminated: Vec<bool>,
    pub next_grids: CompactGrids,
    pub next_vectors: Vec<f32>,
}

pub struct Replay {
    agents: usize,
    rows: usize,
    /// Rows written so far (absolute); row `t` lives in slot `t % rows`.
    head: u64,
    /// Quantised frames, `FRAME_BYTES` per slot.
    frames: Vec<u8>,
    vectors: Vec<f32>,
    actions: Vec<f32>,
    rewards: Vec<f32>,
    terminated: Vec<u8>,
    history: Vec<u8>,
    /// Per row: the reward is in (the next decision arrived).
    rewarded: Vec<bool>,
    /// Per row: the next row continues it (its observation is `s_{t+1}`).
    linked: Vec<bool>,
}

impl Replay {
    /// The bytes [`Replay::new`] allocates for `capacity` transitions of
    /// `agents` agents (what [`bytes`](Self::bytes) will say), saturating.
    pub fn bytes_for(capacity: usize, agents: usize) -> u64 {
        let rows = (capacity.div_ceil(agents.max(1)) as u64).saturating_add(3);
        let slots = rows.saturating_mul(agents as u64);
        let per_slot = (FRAME_BYTES + 4 * (VECTOR_OBS + ACTIONS + 1) + 2) as u64;
        slots.saturating_mul(per_slot).saturating_add(2 * rows)
    }

    /// A buffer holding at least `capacity` complete transitions of `agents` agents.
    pub fn new(capacity: usize, agents: usize) -> Self {
        let rows = capacity.div_ceil(agents.max(1)) + 3;
        let slots = rows * agents;
        Self {
            agents,
            rows,
            head: 0,
            frames: vec![0; slots * FRAME_BYTES],
            vectors: vec![0.0; slots * VECTOR_OBS],
            actions: vec![0.0; slots * ACTIONS],
            rewards: vec![0.0; slots],
            terminated: vec![0; slots],
            history: vec![0; slots],
            rewarded: vec![false; rows],
            linked: vec![false; rows],
        }
    }

    pub fn agents(&self) -> usize {
        self.agents
    }

    /// Bytes held by the buffer's storage (its resident size once filled).
    pub fn bytes(&self) -> usize {
        self.frames.len()
            + 4 * (self.vectors.len() + self.actions.len() + self.rewards.len())
            + self.terminated.len()
            + self.history.len()
            + 2 * self.rows
    }

    /// Bytes of the rows written so far: the part of [`bytes`](Self::bytes)
    /// the process has touched (untouched zeroed pages are not resident).
    pub fn resident_bytes(&self) -> usize {
        let rows = (self.head as usize).min(self.rows);
        rows * self.agents * BYTES_PER_TRANSITION + 2 * self.rows
    }

    fn slot(&self, row: u64) -> usize {
        (row % self.rows as u64) as usize
    }

    /// Oldest row still stored.
    fn oldest(&self) -> u64 {
        self.head.saturating_sub(self.rows as u64)
    }

    /// Rows whose transition can be sampled: complete, with their two older
    /// frames and their successor still stored.
    fn sampleable_rows(&self) -> impl Iterator<Item = u64> + '_ {
        let from = self.oldest() + 2;
        (from..self.head.saturating_sub(1)).filter(move |&t| self.linked[self.slot(t)])
    }

    /// Complete transitions that can be sampled.
    pub fn len(&self) -> usize {
        self.sampleable_rows().count() * self.agents
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Append the observations of a decision and the actions taken.
    ///
    /// `grids` are the stacked observations of the agents, floats or the
    /// sensor's bytes (only each stack's newest frame is stored), `history[a]` how many of the two older
    /// frames of agent `a`'s stack are real (0 after a reset or a respawn).
    /// `continues` says whether this decision follows the previous row in the
    /// same environment (false after a reset, e.g. on resume).
    pub fn push(
        &mut self,
        grids: GridsRef<'_>,
        vectors: &[f32],
        actions: &[f32],
        history: &[u8],
        continues: bool,
    ) {
        let n = self.agents;
        debug_assert_eq!(grids.len(), n);
        if self.head > 0 {
            let prev = self.slot(self.head - 1);
            self.linked[prev] = continues && self.rewarded[prev];
        }
        let s = self.slot(self.head);
        self.rewarded[s] = false;
        self.linked[s] = false;
        let at = s * n;
        newest_frames(
            grids,
            &mut self.frames[at * FRAME_BYTES..(at + n) * FRAME_BYTES],
        );
        self.vectors[at * VECTOR_OBS..(at + n) * VECTOR_OBS].copy_from_slice(vectors);
        self.actions[at * ACTIONS..(at + n) * ACTIONS].copy_from_slice(actions);
        self.history[at..at + n].copy_from_slice(history);
        self.head += 1;
    }

    /// The rewards and terminations that ended the newest row's decision.
    pub fn reward(&mut self, rewards: &[f32], terminated: &[bool]) {
        if self.head == 0 {
            return;
        }
        let s = self.slot(self.head - 1);
        let at = s * self.agents;
        self.rewards[at..at + self.agents].copy_from_slice(rewards);
        for (d, &t) in self.terminated[at..at + self.agents]
            .iter_mut()
            .zip(terminated)
        {
            *d = t as u8;
        }
        self.rewarded[s] = true;
    }

    /// The quantised stacked observation of agent `a` at `row` into `out`
    /// (`STACK_BYTES`): frames oldest first, zero bytes where the stack had none.
    pub fn stack_bytes_into(&self, row: u64, a: usize, out: &mut [u8]) {
        let hist = self.history[self.slot(row) * self.agents + a] as usize;
        for k in 0..STACK {
            let dst = &mut out[k * FRAME_BYTES..(k + 1) * FRAME_BYTES];
            let back = (STACK - 1 - k) as u64;
            if back as usize > hist {
                dst.fill(0);
                continue;
            }
            let at = (self.slot(row - back) * self.agents + a) * FRAME_BYTES;
            dst.copy_from_slice(&self.frames[at..at + FRAME_BYTES]);
        }
    }

    /// Rebuild the stacked observation `[18, 20, 34]` of agent `a` at `row` into `out`.
    pub fn stack_into(&self, row: u64, a: usize, out: &mut [f32]) {
        let mut bytes = vec![0u8; STACK_BYTES];
        self.stack_bytes_into(row, a, &mut bytes);
        for k in 0..STACK {
            dequantise(
                &bytes[k * FRAME_BYTES..(k + 1) * FRAME_BYTES],
                &mut out[k * FRAME_LEN..(k + 1) * FRAME_LEN],
            );
        }
    }

    /// The vector observation of agent `a` at `row`.
    pub fn vector(&self, row: u64, a: usize) -> &[f32] {
        let at = (self.slot(row) * self.agents + a) * VECTOR_OBS;
        &self.vectors[at..at + VECTOR_OBS]
    }

    /// `size` transitions drawn uniformly (with replacement) by `draw(k)`, which
    /// returns a number below `k`.
    pub fn sample(&self, size: usize, mut draw: impl FnMut(usize) -> usize, out: &mut Batch) {
        let rows: Vec<u64> = self.sampleable_rows().collect();
        assert!(!rows.is_empty(), "sampling an empty replay buffer");
        let n = self.agents;
        let picks: Vec<(u64, usize)> = (0..size)
            .map(|_| {
                let k = draw(rows.len() * n);
                (rows[k / n], k % n)
            })
            .collect();
        out.len = size;
        out.grids.bytes.resize(size * STACK_BYTES, 0);
        out.next_grids.bytes.resize(size * STACK_BYTES, 0);
        out.grids
            .bytes
            .par_chunks_mut(STACK_BYTES)
            .zip(out.next_grids.bytes.par_chunks_mut(STACK_BYTES))
            .zip(picks.par_iter())
            .for_each(|((g, ng), &(t, a))| {
                self.stack_bytes_into(t, a, g);
                self.stack_bytes_into(t + 1, a, ng);
            });
        out.vectors.clear();
        out.next_vectors.clear();
        out.actions.clear();
        out.rewards.clear();
        out.terminated.clear();
        for &(t, a) in &picks {
            out.vectors.extend_from_slice(self.vector(t, a));
            out.next_vectors.extend_from_slice(self.vector(t + 1, a));
            let i = self.slot(t) * n + a;
            out.actions
                .extend_from_slice(&self.actions[i * ACTIONS..(i + 1) * ACTIONS]);
            out.rewards.push(self.rewards[i]);
            out.terminated.push(self.terminated[i] != 0);
        }
    }

    /// Rows holding data: slots `0..filled_rows()` (row `t` lives in slot
    /// `t % rows`, so until the ring wraps only the first `head` slots are written).
    fn filled_rows(&self) -> usize {
        (self.head as usize).min(self.rows)
    }

    /// The size of the file [`save`](Self::save) writes: the header, then
    /// [`BYTES_PER_TRANSITION`] per agent and one flag byte per filled row —
    /// proportional to what the buffer holds, not to its capacity.
    pub fn file_bytes(&self) -> usize {
        let rows = self.filled_rows();
        HEADER_BYTES + rows * self.agents * BYTES_PER_TRANSITION + rows
    }

    /// Write the buffer's filled rows to `path` (inside a checkpoint folder
    /// being written atomically).
    pub fn save(&self, path: &Path) -> Result<()> {
        self.write(path).map_err(LearnError::io(path))
    }

    fn write(&self, path: &Path) -> std::io::Result<()> {
        let file = std::fs::File::create(path)?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
        w.write_all(MAGIC)?;
        for x in [self.agents as u64, self.rows as u64, self.head] {
            w.write_all(&x.to_le_bytes())?;
        }
        let slots = self.filled_rows() * self.agents;
        w.write_all(&self.frames[..slots * FRAME_BYTES])?;
        for (xs, width) in [
            (&self.vectors, VECTOR_OBS),
            (&self.actions, ACTIONS),
            (&self.rewards, 1),
        ] {
            for x in &xs[..slots * width] {
                w.write_all(&x.to_le_bytes())?;
            }
        }
        w.write_all(&self.terminated[..slots])?;
        w.write_all(&self.history[..slots])?;
        let flags: Vec<u8> = self.rewarded[..self.filled_rows()]
            .iter()
            .zip(&self.linked)
            .map(|(&r, &l)| r as u8 | (l as u8) << 1)
            .collect();
        w.write_all(&flags)?;
        w.flush()
    }

    /// Read a buffer written by [`save`](Self::save); it must match `capacity` and `agents`.
    pub fn load(path: &Path, capacity: usize, agents: usize) -> Result<Self> {
        let file = std::fs::File::open(path).map_err(LearnError::io(path))?;
        let mut r = std::io::BufReader::with_capacity(1 << 20, file);
        let bad = |what: &str| LearnError::Corrupt {
            path: path.to_path_buf(),
            reason: format!("not a replay buffer of this version: {what}"),
        };
        let mut magic = [0u8; 8];
        r.read_exact(&mut magic).map_err(|_| bad("too short"))?;
        if &magic != MAGIC && &magic != MAGIC_FULL {
            return Err(bad("wrong magic bytes"));
        }
        let mut word = || -> Result<u64> {
            let mut b = [0u8; 8];
            r.read_exact(&mut b).map_err(|_| bad("too short"))?;
            Ok(u64::from_le_bytes(b))
        };
        let (n, rows, head) = (word()? as usize, word()? as usize, word()?);
        let mut buf = Self::new(capacity, agents);
        if n != agents || rows != buf.rows {
            return Err(LearnError::Corrupt {
                path: path.to_path_buf(),
                reason: format!(
                    "the replay buffer holds {n} agents × {rows} rows, the run needs {agents} × {} (buffer_size changed?)",
                    buf.rows
                ),
            });
        }
        buf.head = head;
        let filled = if &magic == MAGIC_FULL {
            buf.rows
        } else {
            buf.filled_rows()
        };
        let slots = filled * agents;
        let read = |r: &mut dyn Read, dst: &mut [u8]| -> Result<()> {
            r.read_exact(dst).map_err(|_| bad("truncated"))
        };
        read(&mut r, &mut buf.frames[..slots * FRAME_BYTES])?;
        for (xs, width) in [
            (&mut buf.vectors, VECTOR_OBS),
            (&mut buf.actions, ACTIONS),
            (&mut buf.rewards, 1),
        ] {
            let mut bytes = vec![0u8; slots * width * 4];
            read(&mut r, &mut bytes)?;
            for (x, b) in xs.iter_mut().zip(bytes.chunks_exact(4)) {
                *x = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            }
        }
        read(&mut r, &mut buf.terminated[..slots])?;
        read(&mut r, &mut buf.history[..slots])?;
        let mut flags = vec![0u8; filled];
        read(&mut r, &mut flags)?;
        let mut rest = [0u8; 1];
        if r.read(&mut rest).map_err(|_| bad("unreadable"))? != 0 {
            return Err(bad("longer than its rows"));
        }
        for (i, f) in flags.iter().enumerate() {
            buf.rewarded[i] = f & 1 != 0;
            buf.linked[i] = f & 2 != 0;
        }
        Ok(buf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deepfoids_sensors::CELLS;
    use deepfoids_sensors::STACKED_LEN;

    /// A stack whose newest frame encodes `(row, agent)`: proximity `(r + a)/100`
    /// in cell 0, type `1 + (r + a) % 5` there; the older frames are arbitrary.
    fn stack(r: u64, a: usize) -> Vec<f32> {
        let mut s = vec![0.7; STACKED_LEN];
        let f = &mut s[(STACK - 1) * FRAME_LEN..];
        f.fill(0.0);
        let v = (r as usize + a) % 100;
        f[0] = v as f32 / 100.0;
        f[(1 + v % 5) * CELLS] = 1.0;
        s
    }

    fn push_row(buf: &mut Replay, r: u64, hist: u8, continues: bool) {
        let n = buf.agents();
        let grids: Vec<f32> = (0..n).flat_map(|a| stack(r, a)).collect();
        let vectors: Vec<f32> = (0..n * VECTOR_OBS)
            .map(|i| (r * 10) as f32 + i as f32)
            .collect();
        let actions = vec![r as f32; n * ACTIONS];
        buf.push(
            GridsRef::Dense(&grids),
            &vectors,
            &actions,
            &vec![hist; n],
            continues,
        );
    }

    #[test]
    fn bytes_per_transition_as_documented() {
        assert_eq!(BYTES_PER_TRANSITION, 1402);
        let b = Replay::new(102_400, 1000);
        assert_eq!(b.rows, 106);
        // 106 rows × 1000 agents × 1,402 bytes + 2 flag bytes per row.
        assert_eq!(b.bytes(), 106 * 1000 * 1402 + 2 * 106);
    }

    /// Capacity 6 with 2 agents: 3 + 3 = 6 rows. After 10 rows only rows 4..9
    /// are stored; rows 6, 7, 8 are sampleable (two older frames each, and a
    /// successor); row 9 awaits its reward.
    #[test]
    fn the_ring_wraps_around() {
        let mut b = Replay::new(6, 2);
        assert_eq!(b.rows, 6);
        for r in 0..10 {
            push_row(&mut b, r, 2, true);
            b.reward(&[r as f32, -(r as f32)], &[false, r == 7]);
        }
        let rows: Vec<u64> = b.sampleable_rows().collect();
        assert_eq!(rows, vec![6, 7, 8]);
        assert_eq!(b.len(), 6);
        // Every sample comes from rows 6–8 and its successor.
        let mut batch = Batch::default();
        let mut k = 0;
        b.sample(
            6,
            |m| {
                k += 1;
                (k - 1) % m
            },
            &mut batch,
        );
        for i in 0..6 {
            let (t, a) = ((6 + i / 2) as u64, i % 2);
            assert_eq!(batch.actions[i * ACTIONS], t as f32);
            assert_eq!(
                batch.rewards[i],
                if a == 0 { t as f32 } else { -(t as f32) }
            );
            assert_eq!(batch.terminated[i], t == 7 && a == 1);
            assert_eq!(
                batch.vectors[i * VECTOR_OBS],
                (t * 10) as f32 + (a * VECTOR_OBS) as f32
            );
            assert_eq!(
                batch.next_vectors[i * VECTOR_OBS],
                ((t + 1) * 10) as f32 + (a * VECTOR_OBS) as f32
            );
            // The stack is frames t−2, t−1, t of the same agent.
            let dense = batch.grids.to_dense();
            let g = &dense[i * STACKED_LEN..(i + 1) * STACKED_LEN];
            for k in 0..STACK {
                let want = ((t as usize - 2 + k) + a) % 100;
                let frame = &g[k * FRAME_LEN..(k + 1) * FRAME_LEN];
                assert!((frame[0] - want as f32 / 100.0).abs() <= PROXIMITY_TOLERANCE);
                assert_eq!(frame[(1 + want % 5) * CELLS], 1.0);
            }
            let next = batch.next_grids.to_dense();
            let ng = &next[i * STACKED_LEN..(i + 1) * STACKED_LEN];
            let want = ((t as usize + 1) + a) % 100;
            assert!(
                (ng[2 * FRAME_LEN] - want as f32 / 100.0).abs() <= PROXIMITY_TOLERANCE,
                "sample {i}: row {t} agent {a}: next {} want {want}",
                ng[2 * FRAME_LEN]
            );
        }
    }

    /// A stack with history 0 rebuilds with two zero frames; a row after a
    /// discontinuity (resume) leaves the previous row unsampleable.
    #[test]
    fn history_and_breaks() {
        let mut b = Replay::new(100, 1);
        for r in 0..4 {
            push_row(&mut b, r, r.min(2) as u8, true);
            b.reward(&[1.0], &[false]);
        }
        push_row(&mut b, 4, 0, false); // a reset: row 3 has no successor
        let rows: Vec<u64> = b.sampleable_rows().collect();
        assert_eq!(rows, vec![2]);
        let mut out = vec![1.0; STACKED_LEN];
        b.stack_into(4, 0, &mut out);
        assert!(out[..2 * FRAME_LEN].iter().all(|&x| x == 0.0));
        assert!((out[2 * FRAME_LEN] - 0.04).abs() <= PROXIMITY_TOLERANCE);
        b.stack_into(1, 0, &mut out);
        assert!(out[..FRAME_LEN].iter().all(|&x| x == 0.0));
        assert!((out[FRAME_LEN] - 0.0).abs() <= PROXIMITY_TOLERANCE);
        assert!((out[2 * FRAME_LEN] - 0.01).abs() <= PROXIMITY_TOLERANCE);
    }

    #[test]
    fn save_and_load_round_trip() {
        let mut b = Replay::new(6, 2);
        for r in 0..8 {
            push_row(&mut b, r, 2, true);
            b.reward(&[r as f32, 1.0], &[r == 5, false]);
        }
        let path = std::env::temp_dir().join(format!("replay-{}.bin", std::process::id()));
        b.save(&path).unwrap();
        let c = Replay::load(&path, 6, 2).unwrap();
        assert_eq!(c.head, b.head);
        assert_eq!(c.len(), b.len());
        assert_eq!(c.frames, b.frames);
        assert_eq!(c.rewards, b.rewards);
        assert_eq!(c.linked, b.linked);
        let e = Replay::load(&path, 60, 2).err().unwrap().to_string();
        assert!(e.contains("buffer_size"), "{e}");
        std::fs::write(&path, b"nonsense").unwrap();
        assert!(Replay::load(&path, 6, 2).is_err());
        let _ = std::fs::remove_file(&path);
    }

    /// Issue 13 item 6: a checkpoint's replay file holds the rows written,
    /// not the capacity (once 143.6 MB for 10,000 transitions). Capacity
    /// 1,000 with 4 agents is 253 rows; after 10 rows the file is the header
    /// plus 10 × 4 × 1,402 bytes plus 10 flag bytes, after 20 rows twice the
    /// data; a full ring is 253 rows. Each reads back identical, and
    /// samples the same transitions.
    #[test]
    fn the_file_holds_only_the_filled_rows() {
        let path = std::env::temp_dir().join(format!("replay-fill-{}.bin", std::process::id()));
        let mut b = Replay::new(1000, 4);
        assert_eq!(b.rows, 253);
        let mut sizes = vec![];
        for (from, to) in [(0, 10), (10, 20), (20, 300)] {
            for r in from..to {
                push_row(&mut b, r, 2, true);
                b.reward(
                    &[r as f32, 1.0, 2.0, -1.0],
                    &[r % 7 == 3, false, false, false],
                );
            }
            b.save(&path).unwrap();
            let len = std::fs::metadata(&path).unwrap().len() as usize;
            assert_eq!(len, b.file_bytes());
            sizes.push(len);
            let c = Replay::load(&path, 1000, 4).unwrap();
            assert_eq!(
                (c.head, &c.frames, &c.vectors, &c.actions),
                (b.head, &b.frames, &b.vectors, &b.actions)
            );
            assert_eq!(
                (
                    &c.rewards,
                    &c.terminated,
                    &c.history,
                    &c.rewarded,
                    &c.linked
                ),
                (
                    &b.rewards,
                    &b.terminated,
                    &b.history,
                    &b.rewarded,
                    &b.linked
                )
            );
            let (mut x, mut y) = (Batch::default(), Batch::default());
            let mut k = 0usize;
            b.sample(
                16,
                |m| {
                    k = (k * 31 + 7) % m;
                    k
                },
                &mut x,
            );
            let mut k = 0usize;
            c.sample(
                16,
                |m| {
                    k = (k * 31 + 7) % m;
                    k
                },
                &mut y,
            );
            assert_eq!((x.grids.bytes, x.rewards), (y.grids.bytes, y.rewards));
        }
        assert_eq!(sizes[0], HEADER_BYTES + 10 * 4 * 1402 + 10);
        assert_eq!(sizes[1] - HEADER_BYTES, 2 * (sizes[0] - HEADER_BYTES));
        assert_eq!(sizes[2], HEADER_BYTES + 253 * 4 * 1402 + 253);
        // A file cut short, or with bytes past its rows, is refused.
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        assert!(Replay::load(&path, 1000, 4).is_err());
        std::fs::write(&path, [&bytes[..], &[0]].concat()).unwrap();
        assert!(Replay::load(&path, 1000, 4).is_err());
        let _ = std::fs::remove_file(&path);
    }
}
