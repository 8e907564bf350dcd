//! Grid frames stored compactly: the experience buffers of both trainers keep
//! each frame once, in bytes.
//!
//! A frame is `[proximity, fish, net, surface, obstacle, chase partner]` over
//! 20 × 34 cells; the five type channels are one-hot (or all zero where nothing
//! is seen), so a cell takes two bytes: the proximity as `round(255·p)` (error
//! ≤ 1/510) and the index of the hot channel (0 for none), rebuilt exactly.
//! A frame is [`FRAME_BYTES`] = 1,360 bytes: 680 proximity bytes, then 680
//! type bytes. A stacked observation (3 frames, oldest first) is 4,080 bytes
//! against 48,960 as floats; a frame missing from a stack (the two older
//! frames after a respawn, SPEC §7) is all zero bytes, which rebuilds as zeros.

use deepfoids_sensors::{CELLS, CHANNELS, FRAME_LEN, STACK, STACKED_LEN};

/// Bytes of one quantised frame.
pub const FRAME_BYTES: usize = 2 * CELLS;
/// Bytes of one quantised stacked observation.
pub const STACK_BYTES: usize = STACK * FRAME_BYTES;
/// Largest error of a rebuilt proximity value: 1/510, plus f32 rounding.
pub const PROXIMITY_TOLERANCE: f32 = 0.5 / 255.0 + 1e-6;

/// Frame `[6, 20, 34]` floats → [`FRAME_BYTES`] bytes.
pub fn quantise(frame: &[f32], out: &mut [u8]) {
    debug_assert_eq!(frame.len(), FRAME_LEN);
    let (prox, kind) = out.split_at_mut(CELLS);
    for c in 0..CELLS {
        prox[c] = (frame[c].clamp(0.0, 1.0) * 255.0).round() as u8;
        kind[c] = (1..CHANNELS)
            .find(|&k| frame[k * CELLS + c] > 0.5)
            .unwrap_or(0) as u8;
    }
}

/// [`FRAME_BYTES`] bytes → frame `[6, 20, 34]` floats.
pub fn dequantise(bytes: &[u8], frame: &mut [f32]) {
    let (prox, kind) = bytes.split_at(CELLS);
    let (p, types) = frame.split_at_mut(CELLS);
    for (dst, &q) in p.iter_mut().zip(prox) {
        *dst = q as f32 * (1.0 / 255.0);
    }
    for (k, channel) in types.chunks_exact_mut(CELLS).enumerate() {
        let k = k as u8 + 1;
        for (v, &kd) in channel.iter_mut().zip(kind) {
            *v = (kd == k) as u8 as f32;
        }
    }
}

/// The newest frame of each stacked observation in `grids` (`[n, 18, 20, 34]`),
/// quantised into `out` (`n` × [`FRAME_BYTES`]).
pub fn quantise_newest(grids: &[f32], out: &mut [u8]) {
    use rayon::prelude::*;
    out.par_chunks_mut(FRAME_BYTES)
        .zip(grids.par_chunks(STACKED_LEN))
        .for_each(|(dst, stack)| quantise(&stack[(STACK - 1) * FRAME_LEN..], dst));
}

/// A batch of quantised stacked observations: `n` × [`STACK_BYTES`] bytes,
/// frames oldest first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CompactGrids {
    pub bytes: Vec<u8>,
}

impl CompactGrids {
    pub fn with_len(n: usize) -> Self {
        Self {
            bytes: vec![0; n * STACK_BYTES],
        }
    }

    /// Observations held.
    pub fn len(&self) -> usize {
        self.bytes.len() / STACK_BYTES
    }

    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Quantise every frame of dense stacked grids `[n, 18, 20, 34]`.
    pub fn from_dense(grids: &[f32]) -> Self {
        let n = grids.len() / STACKED_LEN;
        let mut out = Self::with_len(n);
        for (dst, src) in out
            .bytes
            .chunks_exact_mut(FRAME_BYTES)
            .zip(grids.chunks_exact(FRAME_LEN))
        {
            quantise(src, dst);
        }
        out
    }

    /// The stacks as floats `[n, 18, 20, 34]`.
    pub fn to_dense(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.len() * STACKED_LEN];
        for (src, dst) in self
            .bytes
            .chunks_exact(FRAME_BYTES)
            .zip(out.chunks_exact_mut(FRAME_LEN))
        {
            dequantise(src, dst);
        }
        out
    }

    /// Frame `k` (0 = oldest) of observation `s`.
    pub fn frame_mut(&mut self, s: usize, k: usize) -> &mut [u8] {
        let at = s * STACK_BYTES + k * FRAME_BYTES;
        &mut self.bytes[at..at + FRAME_BYTES]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame with proximity 0.5 (→ 128/255 = 0.50196) and a fish (channel 1)
    /// in cell 3, a net (channel 2) at proximity 1 in cell 700 − 20 = 680 − 1,
    /// nothing elsewhere: two bytes per cell, rebuilt within 1/510.
    #[test]
    fn a_frame_round_trips() {
        let mut f = vec![0.0f32; FRAME_LEN];
        f[3] = 0.5;
        f[CELLS + 3] = 1.0;
        f[CELLS - 1] = 1.0;
        f[2 * CELLS + CELLS - 1] = 1.0;
        let mut b = vec![0u8; FRAME_BYTES];
        quantise(&f, &mut b);
        assert_eq!((b[3], b[CELLS + 3]), (128, 1));
        assert_eq!((b[CELLS - 1], b[2 * CELLS - 1]), (255, 2));
        assert_eq!(b.iter().filter(|&&x| x != 0).count(), 4);
        let mut g = vec![9.0f32; FRAME_LEN];
        dequantise(&b, &mut g);
        assert!((g[3] - 128.0 / 255.0).abs() < 1e-7);
        assert!((g[3] - 0.5).abs() <= PROXIMITY_TOLERANCE);
        for k in 1..CHANNELS {
            assert_eq!(g[k * CELLS + 3], (k == 1) as u8 as f32);
            assert_eq!(g[k * CELLS + CELLS - 1], (k == 2) as u8 as f32);
        }
        assert_eq!(g.iter().filter(|&&x| x != 0.0).count(), 4);
    }
}
