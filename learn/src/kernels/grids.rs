//! The kernels' view of a batch of stacked grids: dense floats as the
//! environment hands them out, or the quantised frames of the rollout and
//! replay buffers.

use super::geometry::*;
use crate::frames::FRAME_BYTES;
use deepfoids_sensors::{AZ_CELLS, CELLS, CHANNELS, STACK, STACKED_LEN};

pub use deepfoids_sensors::GridsRef;

/// Write sample `s` of `grids` into `xp` `[18, 20, 36]` with the padding columns zero.
pub fn expand(grids: GridsRef<'_>, s: usize, xp: &mut [f32]) {
    debug_assert_eq!(xp.len(), PADDED_LEN);
    match grids {
        GridsRef::Dense(x) => {
            let x = &x[s * STACKED_LEN..(s + 1) * STACKED_LEN];
            for (row_in, row_out) in x.chunks_exact(AZ_CELLS).zip(xp.chunks_exact_mut(W_PAD)) {
                row_out[..AZ_PAD].fill(0.0);
                row_out[AZ_PAD..AZ_PAD + AZ_CELLS].copy_from_slice(row_in);
                row_out[AZ_PAD + AZ_CELLS..].fill(0.0);
            }
        }
        GridsRef::Compact(bytes) => {
            let stack = &bytes[s * STACK * FRAME_BYTES..(s + 1) * STACK * FRAME_BYTES];
            xp.fill(0.0);
            for (f, frame) in stack.chunks_exact(FRAME_BYTES).enumerate() {
                let (prox, kind) = frame.split_at(CELLS);
                for cell in 0..CELLS {
                    let k = kind[cell] as usize;
                    if k == 0 && prox[cell] == 0 {
                        continue;
                    }
                    let (h, w) = (cell / AZ_CELLS, cell % AZ_CELLS + AZ_PAD);
                    let at = |c: usize| (c * H_IN + h) * W_PAD + w;
                    xp[at(f * CHANNELS)] = prox[cell] as f32 * (1.0 / 255.0);
                    if (1..CHANNELS).contains(&k) {
                        xp[at(f * CHANNELS + k)] = 1.0;
                    }
                }
            }
        }
    }
}
