//! Conv 1 read straight from the sensor's byte frames, for acting.
//!
//! A cell of a byte frame ([`crate::frames`]) is a proximity byte `p` and the
//! index `k` of its one hot type channel (0: none), so its inputs are
//! `p/255` on channel 0 and `1` on channel `k`. Conv 1's output at position
//! `(i, j)` (8×8, stride 4, SPEC §8) is then, over the cells of its patch and
//! the three frames `f`,
//!
//! ```text
//! z[i, j, :] = Σ_f Σ_{r,q} p/255 · W[:, 6f, r, q] + W[:, 6f + k, r, q]
//! ```
//!
//! with `W[:, 6f + 0, …]` read as zero for `k = 0`: two vector operations a
//! cell and position, branch-free, with no list of non-zeros. `positions`
//! runs kernel offset by kernel offset over blocks of output positions whose
//! accumulators stay in registers. The scatter of [`super::sparse`] does
//! fewer multiply-adds at the sensor's densities, but each one loads and
//! stores its output row, and consecutive inputs of a cell hit the same rows;
//! on 1,024 coho-like stacks the actor's encoder here takes 3.8–4.8 ms
//! against 9.3 ms (`benches/encoder.rs`). The updates keep the scatter: its
//! list of non-zeros also serves their backward pass, and at two bodies
//! (K = 2) this loop was no faster.
//!
//! The sums run in another order than the scatter's, so a seeded evaluation
//! acting on bytes gives other actions (≤ 1e−6 apart, then a chaotic school)
//! on a CPU without AVX-512 than on one with it; on one machine it
//! reproduces exactly. Training acts on floats and is not affected.

use super::geometry::*;
use super::sparse::{Isa, isa};
use crate::frames::FRAME_BYTES;
use deepfoids_sensors::{AZ_CELLS, CELLS, CHANNELS, STACK};

/// Rows of the type table per type: one per frame and kernel offset.
const KIND_STRIDE: usize = STACK * K1 * K1;

/// Conv 1's weights rearranged for [`forward`], for `width` = 16·K output
/// channels: per frame `f` and kernel offset `(r, q)` the proximity's row
/// and the type channels' rows (row 0, "no type", all zeros).
#[derive(Clone, Debug)]
pub struct ByteWeights {
    width: usize,
    /// `[STACK, 8, 8, width]`.
    prox: Vec<f32>,
    /// `[CHANNELS, STACK, 8, 8, width]`.
    kind: Vec<f32>,
}

impl ByteWeights {
    /// From conv 1's weights `w1` `[width, 1152]` (Burn's `[o, c, r, q]`).
    pub fn new(w1: &[f32], width: usize) -> Self {
        assert_eq!(
            w1.len(),
            width * PATCH1,
            "conv-1 weights of {width} channels"
        );
        let mut prox = vec![0.0; STACK * K1 * K1 * width];
        let mut kind = vec![0.0; STACK * K1 * K1 * CHANNELS * width];
        for f in 0..STACK {
            for rq in 0..K1 * K1 {
                let at = f * K1 * K1 + rq;
                for o in 0..width {
                    let w = |c: usize| w1[o * PATCH1 + (f * CHANNELS + c) * K1 * K1 + rq];
                    prox[at * width + o] = w(0);
                    for k in 1..CHANNELS {
                        kind[(k * KIND_STRIDE + at) * width + o] = w(k);
                    }
                }
            }
        }
        Self { width, prox, kind }
    }
}

/// Padded cells of a stack, `[STACK, 20, 36]`.
const STACK_CELLS: usize = STACK * H_IN * W_PAD;

/// Whether this CPU runs [`forward`] (AVX-512). Elsewhere acting takes conv 1
/// on the non-zeros ([`super::sparse`]).
pub fn available() -> bool {
    isa() == Isa::Avx512
}

/// Each cell of a stack once, into the scratch: its proximity as a float and
/// its type's offset in the table (`k·192·width`; type 0 and bytes out of
/// range: the zero rows). The padding columns stay zero.
fn unpack(stack: &[u8], width: usize, v: &mut [f32], koff: &mut [u32]) {
    for f in 0..STACK {
        let (prox, kind) = stack[f * FRAME_BYTES..(f + 1) * FRAME_BYTES].split_at(CELLS);
        for h in 0..H_IN {
            let row = (f * H_IN + h) * W_PAD + AZ_PAD;
            let cells = h * AZ_CELLS..(h + 1) * AZ_CELLS;
            for (u, (&p, &k)) in prox[cells.clone()].iter().zip(&kind[cells]).enumerate() {
                let k = k as usize;
                v[row + u] = p as f32 * (1.0 / 255.0);
                koff[row + u] = (if k < CHANNELS { k } else { 0 } * KIND_STRIDE * width) as u32;
            }
        }
    }
}

/// Conv 1 for `V` vectors of 16 output channels, `PB` output positions at a
/// time (their accumulators fill half the vector registers).
///
/// The kernel offsets are the outer loop: one offset's proximity row stays
/// in registers for the block's positions, and its six type rows (384 bytes
/// for 16 channels) in the L1 cache, where a loop over positions first would
/// read the whole 74 KB type table for each position. Per cell and position:
/// a broadcast, a multiply-add and an add per vector.
///
/// # Safety
/// AVX-512F; `t` is built for `16·V` channels, `z` holds `32·16·V` floats,
/// `v` and `koff` are [`unpack`]ed for that width.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn positions<const V: usize, const PB: usize>(
    t: &ByteWeights,
    v: &[f32],
    koff: &[u32],
    z: &mut [f32],
) {
    use std::arch::x86_64::*;
    let w = 16 * V;
    let (prox_w, kind_w) = (t.prox.as_ptr(), t.kind.as_ptr());
    for block in 0..P1 / PB {
        // Where each position's patch starts among the padded cells.
        let start: [usize; PB] = std::array::from_fn(|b| {
            let p = block * PB + b;
            (p / W1 * W_PAD + p % W1) * S1
        });
        let mut acc = [[_mm512_setzero_ps(); V]; PB];
        for f in 0..STACK {
            for r in 0..K1 {
                for q in 0..K1 {
                    let at = (f * K1 + r) * K1 + q;
                    let cell0 = (f * H_IN + r) * W_PAD + q;
                    // SAFETY (all below): at < 192 and the type offsets
                    // < 6·192·w, inside the tables; cell < STACK_CELLS (a
                    // patch lies inside the padded grid).
                    let wp: [__m512; V] = std::array::from_fn(|l| unsafe {
                        _mm512_loadu_ps(prox_w.add(at * w + 16 * l))
                    });
                    let wk = unsafe { kind_w.add(at * w) };
                    for (b, acc) in acc.iter_mut().enumerate() {
                        let cell = cell0 + start[b];
                        let (x, kp) = unsafe {
                            (
                                _mm512_set1_ps(*v.get_unchecked(cell)),
                                wk.add(*koff.get_unchecked(cell) as usize),
                            )
                        };
                        for l in 0..V {
                            let k = unsafe { _mm512_loadu_ps(kp.add(16 * l)) };
                            acc[l] = _mm512_add_ps(_mm512_fmadd_ps(wp[l], x, acc[l]), k);
                        }
                    }
                }
            }
        }
        for (b, acc) in acc.iter().enumerate() {
            let p = block * PB + b;
            for (l, a) in acc.iter().enumerate() {
                // SAFETY: p < 32 and l < V: inside z's 32·w floats.
                unsafe { _mm512_storeu_ps(z.as_mut_ptr().add(p * w + 16 * l), *a) };
            }
        }
    }
}

/// Scratch of [`forward`], reused across samples.
#[derive(Clone, Debug)]
pub struct Scratch {
    v: Vec<f32>,
    koff: Vec<u32>,
}

impl Default for Scratch {
    fn default() -> Self {
        Self {
            v: vec![0.0; STACK_CELLS],
            koff: vec![0; STACK_CELLS],
        }
    }
}

/// Conv 1 (without its bias) of one stack of byte frames into `z`
/// `[32 positions, 16·K]`, every output written. Only where [`available`].
pub fn forward(stack: &[u8], t: &ByteWeights, scratch: &mut Scratch, z: &mut [f32]) {
    let width = t.width;
    assert!(stack.len() >= STACK * FRAME_BYTES && z.len() >= P1 * width);
    assert!(available(), "conv 1 on bytes needs AVX-512");
    let Scratch { v, koff } = scratch;
    unpack(stack, width, v, koff);
    #[cfg(target_arch = "x86_64")]
    // SAFETY: the CPU has AVX-512F (checked); the lengths are checked above.
    unsafe {
        match width {
            16 => positions::<1, 16>(t, v, koff, z),
            32 => positions::<2, 8>(t, v, koff, z),
            48 => positions::<3, 4>(t, v, koff, z),
            w => panic!("conv 1 on bytes: {w} output channels (16, 32 or 48 allowed)"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::encoder::im2col1;
    use crate::kernels::grids::{GridsRef, expand};

    /// A deterministic stack: every pattern of the bytes (empty cells, a
    /// proximity without a type, a type without a proximity, both, a type
    /// byte out of range) at every cell, the padding's neighbours included.
    fn stack() -> Vec<u8> {
        let mut s = vec![0u8; STACK * FRAME_BYTES];
        let mut x = 0x2545_f491_u32;
        for f in 0..STACK {
            for cell in 0..CELLS {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                let (p, k) = match x % 5 {
                    0 => (0, 0),
                    1 => ((x >> 8) as u8 | 1, 0),
                    2 => (0, 1 + (x >> 16) as u8 % 5),
                    3 => ((x >> 8) as u8 | 1, 1 + (x >> 16) as u8 % 5),
                    _ => ((x >> 8) as u8, 200),
                };
                s[f * FRAME_BYTES + cell] = p;
                s[f * FRAME_BYTES + CELLS + cell] = k;
            }
        }
        s
    }

    /// The same sums as im2col + a plain matrix product on the unpacked
    /// floats, for 1, 2 and 3 bodies.
    #[test]
    fn conv1_on_bytes_is_conv1_on_their_floats() {
        if !available() {
            eprintln!("no AVX-512 here: acting takes conv 1 on the non-zeros");
            return;
        }
        let s = stack();
        let mut xp = vec![0.0; PADDED_LEN];
        expand(GridsRef::Compact(&s), 0, &mut xp);
        let mut cols = vec![0.0; P1 * PATCH1];
        im2col1(&xp, &mut cols);
        for k in 1..=3 {
            let width = C1 * k;
            let w1: Vec<f32> = (0..width * PATCH1)
                .map(|i| ((i * 7919 % 1000) as f32 / 1000.0 - 0.5) * 0.1)
                .collect();
            let mut z = vec![f32::NAN; P1 * width];
            forward(
                &s,
                &ByteWeights::new(&w1, width),
                &mut Scratch::default(),
                &mut z,
            );
            for p in 0..P1 {
                for o in 0..width {
                    let want: f64 = (0..PATCH1)
                        .map(|c| cols[p * PATCH1 + c] as f64 * w1[o * PATCH1 + c] as f64)
                        .sum();
                    let got = z[p * width + o] as f64;
                    assert!(
                        (got - want).abs() < 1e-5,
                        "K {k}, position {p}, channel {o}: {got} against {want}"
                    );
                }
            }
        }
    }
}
