//! Frames as bytes: the sensor's compact output, which the policies act on and
//! the experience buffers store.
//!
//! A frame is `[proximity, fish, net, surface, obstacle, chase partner]` over
//! 20 × 34 cells; the five type channels are one-hot (or all zero where nothing
//! is seen), so a cell takes two bytes: the proximity as `round(255·p)` (error
//! ≤ 1/510) and the index of the hot channel (0 for none), rebuilt exactly.
//! A frame is [`FRAME_BYTES`] = 1,360 bytes: 680 proximity bytes, then 680
//! type bytes. A stacked observation (3 frames, oldest first) is 4,080 bytes
//! against 48,960 as floats; a frame missing from a stack (the two older
//! frames after a respawn, SPEC §7) is all zero bytes, which rebuilds as zeros.

use crate::layout::{CELLS, CHANNELS, FRAME_LEN, STACK, STACKED_LEN};
use std::borrow::Cow;

/// Bytes of one quantised frame.
pub const FRAME_BYTES: usize = 2 * CELLS;
/// Bytes of one quantised stacked observation.
pub const STACK_BYTES: usize = STACK * FRAME_BYTES;
/// Largest error of a rebuilt proximity value: 1/510, plus f32 rounding.
pub const PROXIMITY_TOLERANCE: f32 = 0.5 / 255.0 + 1e-6;

/// A proximity in [0, 1] as its byte: `(p · 255).round()`, computed without
/// `roundf` (x86-64's baseline has no rounding instruction, so `round()` is a
/// library call, a few per cent of the 30,000-fish step): the whole part
/// plus one when the fraction, exact below 2²³, is at least ½.
#[inline]
pub fn proximity_byte(p: f32) -> u8 {
    let x = p.clamp(0.0, 1.0) * 255.0;
    let whole = x as u8;
    whole + (x - whole as f32 >= 0.5) as u8
}

/// Frame `[6, 20, 34]` floats → [`FRAME_BYTES`] bytes.
pub fn quantise(frame: &[f32], out: &mut [u8]) {
    debug_assert_eq!(frame.len(), FRAME_LEN);
    let (prox, kind) = out.split_at_mut(CELLS);
    for c in 0..CELLS {
        prox[c] = proximity_byte(frame[c]);
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

/// How an environment hands out its stacked grids.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GridFormat {
    /// `[n, 18, 20, 34]` floats (what ML-Agents hands out; Python, ONNX).
    #[default]
    Floats,
    /// `n` stacks of 3 frames of [`FRAME_BYTES`] bytes: 12× smaller, and what
    /// the fused kernels act on without expanding the zeros.
    Bytes,
}

/// A batch of stacked grids in either format, as the policies read them.
#[derive(Clone, Copy, Debug)]
pub enum GridsRef<'a> {
    /// `[n, 18, 20, 34]` floats.
    Dense(&'a [f32]),
    /// `n` stacks of 3 quantised frames, [`STACK_BYTES`] bytes each.
    Compact(&'a [u8]),
}

impl<'a> GridsRef<'a> {
    /// Observations in the batch.
    pub fn len(&self) -> usize {
        match self {
            GridsRef::Dense(x) => x.len() / STACKED_LEN,
            GridsRef::Compact(x) => x.len() / STACK_BYTES,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The batch as floats `[n, 18, 20, 34]` (rebuilt from bytes, or borrowed).
    pub fn to_dense(self) -> Cow<'a, [f32]> {
        match self {
            GridsRef::Dense(x) => Cow::Borrowed(x),
            GridsRef::Compact(bytes) => {
                let mut out = vec![0.0; self.len() * STACKED_LEN];
                for (src, dst) in bytes
                    .chunks_exact(FRAME_BYTES)
                    .zip(out.chunks_exact_mut(FRAME_LEN))
                {
                    dequantise(src, dst);
                }
                Cow::Owned(out)
            }
        }
    }

    /// The batch as bytes, `n` × [`STACK_BYTES`] (quantised from floats, or borrowed).
    pub fn to_bytes(self) -> Cow<'a, [u8]> {
        match self {
            GridsRef::Compact(bytes) => Cow::Borrowed(bytes),
            GridsRef::Dense(x) => {
                let mut out = vec![0; self.len() * STACK_BYTES];
                for (src, dst) in x
                    .chunks_exact(FRAME_LEN)
                    .zip(out.chunks_exact_mut(FRAME_BYTES))
                {
                    quantise(src, dst);
                }
                Cow::Owned(out)
            }
        }
    }
}

/// What a stacked observation is made of: floats (a frame is [`FRAME_LEN`]
/// of them) or bytes (a frame is [`FRAME_BYTES`]).
pub trait FrameCell: Copy + Default + Send + Sync + 'static {
    /// Cells of one frame in this format.
    const FRAME: usize;
    /// Write `frame` into `out` (one frame's length).
    fn write(frame: &crate::Frame, out: &mut [Self]);
}

impl FrameCell for f32 {
    const FRAME: usize = FRAME_LEN;
    fn write(frame: &crate::Frame, out: &mut [f32]) {
        frame.write(out)
    }
}

impl FrameCell for u8 {
    const FRAME: usize = FRAME_BYTES;
    fn write(frame: &crate::Frame, out: &mut [u8]) {
        frame.write_bytes(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The byte is `(p · 255).round()` for every proximity: each byte's value,
    /// the halves between bytes and their neighbouring floats, a fine sweep,
    /// and what lies outside [0, 1] or is NaN.
    #[test]
    fn the_byte_is_the_rounded_proximity() {
        let reference = |p: f32| (p.clamp(0.0, 1.0) * 255.0).round() as u8;
        let mut ps = vec![-1.0, -0.0, 2.0, f32::NAN, f32::INFINITY];
        for k in 0..=510u32 {
            let p = k as f32 / 510.0;
            ps.extend([
                p,
                f32::from_bits(p.to_bits() + 1),
                f32::from_bits(p.to_bits().max(1) - 1),
            ]);
        }
        ps.extend((0..=1_000_000).map(|i| i as f32 / 1e6));
        for p in ps {
            assert_eq!(proximity_byte(p), reference(p), "p = {p:e}");
        }
        assert_eq!((proximity_byte(0.5 / 255.0), proximity_byte(1.0)), (1, 255));
    }

    /// A frame with proximity 0.5 (→ 128/255 = 0.50196) and a fish (channel 1)
    /// in cell 3, a net (channel 2) at proximity 1 in cell 680 − 1, nothing
    /// elsewhere: two bytes per cell, rebuilt within 1/510.
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
        let stack = [b.clone(), b.clone(), b].concat();
        let grids = GridsRef::Compact(&stack);
        assert_eq!(grids.len(), 1);
        let dense = grids.to_dense();
        assert_eq!(&dense[2 * FRAME_LEN..], &g[..]);
        assert_eq!(GridsRef::Dense(&dense).to_bytes(), &stack[..]);
    }
}
