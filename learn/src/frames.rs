//! Grid frames stored compactly: the experience buffers of both trainers keep
//! each frame once, in the sensor's bytes ([`deepfoids_sensors::frames`]).
//!
//! A frame is `[proximity, fish, net, surface, obstacle, chase partner]` over
//! 20 × 34 cells; the five type channels are one-hot (or all zero where nothing
//! is seen), so a cell takes two bytes: the proximity as `round(255·p)` (error
//! ≤ 1/510) and the index of the hot channel (0 for none), rebuilt exactly.
//! A frame is [`FRAME_BYTES`] = 1,360 bytes: 680 proximity bytes, then 680
//! type bytes. A stacked observation (3 frames, oldest first) is 4,080 bytes
//! against 48,960 as floats; a frame missing from a stack (the two older
//! frames after a respawn, SPEC §7) is all zero bytes, which rebuilds as zeros.

pub use deepfoids_sensors::frames::{
    FRAME_BYTES, PROXIMITY_TOLERANCE, STACK_BYTES, dequantise, quantise,
};
use deepfoids_sensors::{FRAME_LEN, GridsRef, STACK, STACKED_LEN};

/// The newest frame of each stacked observation in `grids` as bytes into
/// `out` (`n` × [`FRAME_BYTES`]): floats quantised, bytes copied.
pub fn newest_frames(grids: GridsRef<'_>, out: &mut [u8]) {
    use rayon::prelude::*;
    match grids {
        GridsRef::Dense(x) => out
            .par_chunks_mut(FRAME_BYTES)
            .zip(x.par_chunks(STACKED_LEN))
            .for_each(|(dst, stack)| quantise(&stack[(STACK - 1) * FRAME_LEN..], dst)),
        GridsRef::Compact(b) => {
            for (dst, stack) in out
                .chunks_exact_mut(FRAME_BYTES)
                .zip(b.chunks_exact(STACK_BYTES))
            {
                dst.copy_from_slice(&stack[(STACK - 1) * FRAME_BYTES..]);
            }
        }
    }
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
        Self {
            bytes: GridsRef::Dense(grids).to_bytes().into_owned(),
        }
    }

    /// The stacks as floats `[n, 18, 20, 34]`.
    pub fn to_dense(&self) -> Vec<f32> {
        GridsRef::Compact(&self.bytes).to_dense().into_owned()
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

    /// Two stacks whose `k`-th frame (k = 1…6) holds proximity `k / 10` and a
    /// fish in cell `k`: the newest frames as bytes are the same from floats
    /// (quantised) and from the stacks' bytes (copied): stack 0's newest frame
    /// has 3/10 → round(76.5) = 77 in cell 3, stack 1's 6/10 → 153 in cell 6.
    #[test]
    fn newest_frames_from_floats_and_from_bytes_agree() {
        use deepfoids_sensors::CELLS;
        let mut g = vec![0.0f32; 2 * STACKED_LEN];
        for (f, frame) in g.chunks_exact_mut(FRAME_LEN).enumerate() {
            let k = f + 1;
            frame[k] = k as f32 / 10.0;
            frame[CELLS + k] = 1.0;
        }
        let bytes = CompactGrids::from_dense(&g);
        let (mut a, mut b) = (vec![0u8; 2 * FRAME_BYTES], vec![0u8; 2 * FRAME_BYTES]);
        newest_frames(GridsRef::Dense(&g), &mut a);
        newest_frames(GridsRef::Compact(&bytes.bytes), &mut b);
        assert_eq!(a, b);
        assert_eq!((a[3], a[CELLS + 3]), (77, 1));
        assert_eq!((a[FRAME_BYTES + 6], a[FRAME_BYTES + CELLS + 6]), (153, 1));
        assert_eq!(a.iter().filter(|&&x| x != 0).count(), 4);
    }
}
