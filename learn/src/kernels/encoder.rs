//! The visual encoder of SPEC §8 on flat slices, for `K` bodies at once (the
//! actor's and the critic's encoders read the same grids, so the grids are
//! unpacked once and conv 1 runs as one GEMM with `16·K` output channels):
//!
//! ```text
//! grid [18, 20, 34] ─ pad azimuth ─▶ [18, 20, 36] ─ im2col ─▶ [32, 1152]
//!   ─ GEMM W1ᵀ, + b1, LeakyReLU ─▶ a1 [32 positions, 16·K]
//!   per body: im2col ─▶ [3, 256] ─ GEMM W2ᵀ, + b2, LeakyReLU ─▶ a2 [3, 32]
//!   ─ flatten (channel-major, as Burn's [32, 1, 3]) ─▶ e [96]
//!   ─ GEMM Wfc, + bfc, LeakyReLU ─▶ h [hidden]
//! ```
//!
//! Backward, per body from `dh`: `dWfc = eᵀ·dz`, `de = dz·Wfcᵀ`; through the
//! LeakyReLU to `dz2`; `dW2 = dz2ᵀ·col2`, `dcol2 = dz2·W2` scattered back
//! (col2im) onto `da1`; then for all bodies `dz1 = da1·leaky'`,
//! `dW1 = dz1ᵀ·col1` (col1 rebuilt from the grids, not stored), and only if
//! asked the input's gradient `dcol1 = dz1·W1` scattered back onto the grid.
//! Bias gradients are column sums of the `dz`s.

use super::bytes::{self, ByteWeights};
use super::geometry::*;
pub use super::grids::GridsRef;
use super::sparse::{self, Nonzero, Spans, nonzeros, transpose};
use super::{SUB, TASK, add_bias, leaky_backward, leaky_inplace, par_tasks, sgemm, sum_rows};
use crate::frames::STACK_BYTES;
use deepfoids_sensors::{AZ_CELLS, STACKED_LEN};
use rayon::prelude::*;

/// Conv-1 patches of one padded sample: `cols` `[32, 1152]`, row `i·8 + j`,
/// column `c·64 + r·8 + q` = `xp[c][4i + r][4j + q]` (Burn's weight order).
pub fn im2col1(xp: &[f32], cols: &mut [f32]) {
    for i in 0..H1 {
        for j in 0..W1 {
            let row = &mut cols[(i * W1 + j) * PATCH1..(i * W1 + j + 1) * PATCH1];
            for c in 0..C_IN {
                for r in 0..K1 {
                    let src = (c * H_IN + S1 * i + r) * W_PAD + S1 * j;
                    let dst = (c * K1 + r) * K1;
                    row[dst..dst + K1].copy_from_slice(&xp[src..src + K1]);
                }
            }
        }
    }
}

/// The adjoint of [`im2col1`]: add the patches' gradients onto `dxp` `[18, 20, 36]`.
pub fn col2im1(dcols: &[f32], dxp: &mut [f32]) {
    for i in 0..H1 {
        for j in 0..W1 {
            let row = &dcols[(i * W1 + j) * PATCH1..(i * W1 + j + 1) * PATCH1];
            for c in 0..C_IN {
                for r in 0..K1 {
                    let dst = (c * H_IN + S1 * i + r) * W_PAD + S1 * j;
                    let src = (c * K1 + r) * K1;
                    for q in 0..K1 {
                        dxp[dst + q] += row[src + q];
                    }
                }
            }
        }
    }
}

/// Conv 1's dense patches of a chunk of samples, made on first use: a task
/// whose chunks all take the sparse path never allocates (nor zeroes) their
/// 2.4 MB, which had been 3 % of a PPO update.
#[derive(Default)]
struct Patches {
    xp: Vec<f32>,
    cols: Vec<f32>,
}

impl Patches {
    /// Both buffers at full size: `xp` `[18, 20, 36]`, `cols` `[SUB·32, 1152]`.
    fn buffers(&mut self) -> (&mut [f32], &mut [f32]) {
        if self.cols.is_empty() {
            self.xp = vec![0.0; PADDED_LEN];
            self.cols = vec![0.0; SUB * P1 * PATCH1];
        }
        (&mut self.xp, &mut self.cols)
    }

    /// The patches ([`im2col1`]) of samples `first..first + s`: `[s·32, 1152]`.
    fn of(&mut self, grids: GridsRef<'_>, first: usize, s: usize) -> &[f32] {
        let (xp, cols) = self.buffers();
        for t in 0..s {
            super::grids::expand(grids, first + t, xp);
            im2col1(xp, &mut cols[t * P1 * PATCH1..(t + 1) * P1 * PATCH1]);
        }
        &cols[..s * P1 * PATCH1]
    }
}

/// Conv-2 patches of body `b` for `s` samples from `a1` (`[s·32, 16·K]`):
/// `cols` `[s·3, 256]`, row `t·3 + j`, column `c·16 + r·4 + q` = `a1[t·32 + r·8 + 2j + q][16b + c]`.
fn im2col2(a1: &[f32], k: usize, b: usize, s: usize, cols: &mut [f32]) {
    let width = C1 * k;
    for t in 0..s {
        for j in 0..W2 {
            let row = &mut cols[(t * P2 + j) * PATCH2..(t * P2 + j + 1) * PATCH2];
            for r in 0..K2 {
                for q in 0..K2 {
                    let pos = t * P1 + r * W1 + S2 * j + q;
                    let src = &a1[pos * width + C1 * b..pos * width + C1 * (b + 1)];
                    for (c, &v) in src.iter().enumerate() {
                        row[c * K2 * K2 + r * K2 + q] = v;
                    }
                }
            }
        }
    }
}

/// The adjoint of [`im2col2`]: add `dcols` onto body `b`'s columns of `da1`.
fn col2im2(dcols: &[f32], k: usize, b: usize, s: usize, da1: &mut [f32]) {
    let width = C1 * k;
    for t in 0..s {
        for j in 0..W2 {
            let row = &dcols[(t * P2 + j) * PATCH2..(t * P2 + j + 1) * PATCH2];
            for r in 0..K2 {
                for q in 0..K2 {
                    let pos = t * P1 + r * W1 + S2 * j + q;
                    let dst = &mut da1[pos * width + C1 * b..pos * width + C1 * (b + 1)];
                    for (c, d) in dst.iter_mut().enumerate() {
                        *d += row[c * K2 * K2 + r * K2 + q];
                    }
                }
            }
        }
    }
}

/// Use conv 1 on the non-zeros ([`sparse`]) when at most this fraction of a
/// chunk's inputs is non-zero, for quantised grids (PPO's buffer, SAC's
/// replay: the updates). Measured here (one thread, actor forward on 1,000
/// observations): at 30 % random non-zeros im2col + GEMM took 28 ms and the
/// sparse loop 33 ms; at the sensor's 21 % (coho) the updates' forward +
/// backward is 1.27× faster on the non-zeros, at seabream's 9 % 1.8×
/// (`benches/encoder.rs`). Break-even ≈ 25 %.
pub const SPARSE_BELOW: f32 = 0.25;

/// The same when acting on the sensor's bytes (a forward pass with no
/// backward to feed): always. With AVX-512 conv 1 then reads the bytes
/// directly ([`bytes`]), elsewhere it runs on their non-zeros, a frame being
/// at most a third non-zero (two of six channels a cell); 0 sends acting to
/// im2col + GEMM. The actor's encoder on 1,024 sensor-like stacks, 2 threads
/// (`benches/encoder.rs`, session 45): at 21 % non-zero (coho_default) 3.8 ms
/// on the bytes, 9.3 ms on the non-zeros, 18.8 ms im2col + GEMM.
pub const SPARSE_BELOW_ACTING: f32 = 1.0;

/// The same for f32 grids (acting on float observations): never.
/// Unpacking f32 grids is a copy, and listing their non-zeros reads every
/// input, so im2col + GEMM wins even at 9 % (`benches/encoder.rs`: the actor's
/// encoder on 1,000 grids, 13.5 ms against 22.6 ms at coho's density).
pub const SPARSE_BELOW_DENSE: f32 = 0.0;

/// The encoders of `K` bodies, their weights copied out of the Burn modules.
#[derive(Clone, Debug)]
pub struct EncoderPack {
    pub k: usize,
    pub hidden: usize,
    pub slope: f32,
    /// Conv-1 weights side by side: `[16·K, 1152]`, body `b` in rows `16b..16b + 16`.
    pub w1: Vec<f32>,
    /// The same transposed, `[1152, 16·K]`, for the sparse loop.
    pub w1t: Vec<f32>,
    /// Conv 1 on the non-zeros when their fraction is at most this: for
    /// quantised grids in the updates ([`SPARSE_BELOW`]), for them when acting
    /// ([`SPARSE_BELOW_ACTING`]: above 0, straight from the bytes where the
    /// CPU can) and for f32 grids ([`SPARSE_BELOW_DENSE`]).
    pub sparse_below: f32,
    pub sparse_below_acting: f32,
    pub sparse_below_dense: f32,
    pub spans: Spans,
    /// The same rearranged for acting on the sensor's bytes ([`bytes`]).
    pub w1_bytes: ByteWeights,
    /// `[16·K]`.
    pub b1: Vec<f32>,
    /// Per body: conv-2 weights `[32, 256]`, bias `[32]`, dense weights `[96, hidden]`, bias `[hidden]`.
    pub w2: Vec<Vec<f32>>,
    pub b2: Vec<Vec<f32>>,
    pub wfc: Vec<Vec<f32>>,
    pub bfc: Vec<Vec<f32>>,
}

/// Weight gradients of an [`EncoderPack`], in the same layout.
#[derive(Clone, Debug)]
pub struct EncoderGrads {
    pub w1: Vec<f32>,
    pub b1: Vec<f32>,
    pub w2: Vec<Vec<f32>>,
    pub b2: Vec<Vec<f32>>,
    pub wfc: Vec<Vec<f32>>,
    pub bfc: Vec<Vec<f32>>,
}

impl EncoderGrads {
    pub fn zeros(k: usize, hidden: usize) -> Self {
        Self {
            w1: vec![0.0; C1 * k * PATCH1],
            b1: vec![0.0; C1 * k],
            w2: vec![vec![0.0; C2 * PATCH2]; k],
            b2: vec![vec![0.0; C2]; k],
            wfc: vec![vec![0.0; CONV_FLAT * hidden]; k],
            bfc: vec![vec![0.0; hidden]; k],
        }
    }

    /// `self += other`.
    pub fn add(&mut self, other: &EncoderGrads) {
        let add = |a: &mut [f32], b: &[f32]| a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        add(&mut self.w1, &other.w1);
        add(&mut self.b1, &other.b1);
        for b in 0..self.w2.len() {
            add(&mut self.w2[b], &other.w2[b]);
            add(&mut self.b2[b], &other.b2[b]);
            add(&mut self.wfc[b], &other.wfc[b]);
            add(&mut self.bfc[b], &other.bfc[b]);
        }
    }
}

/// What the backward pass needs of a forward pass, for a whole batch.
#[derive(Clone, Debug, Default)]
pub struct EncoderSaved {
    /// Conv-1 activations `[n·32, 16·K]`.
    pub a1: Vec<f32>,
    /// Conv-2 activations, flattened per body: `[n, K, 96]` (Burn's order `o·3 + j`).
    pub e: Vec<f32>,
    /// The outputs `[n, K·hidden]` (their signs are the last LeakyReLU's).
    pub h: Vec<f32>,
    /// Per chunk of [`SUB`] samples, its non-zero inputs if conv 1 took the
    /// sparse path (`None`: dense): the backward pass follows the forward
    /// pass's choice with its lists instead of finding them a second time
    /// (that search had been half of its 7 % of an update).
    pub nonzeros: Vec<ChunkNonzeros>,
}

/// The non-zero inputs of a chunk's samples, one list a sample, if conv 1 ran
/// on them; `None` if it ran dense.
pub type ChunkNonzeros = Option<Vec<Vec<Nonzero>>>;

/// One task's part of an [`EncoderSaved`].
#[derive(Clone, Copy)]
pub struct SavedPart<'a> {
    pub a1: &'a [f32],
    pub e: &'a [f32],
    pub h: &'a [f32],
    /// The task's chunks.
    pub nonzeros: &'a [ChunkNonzeros],
}

impl EncoderPack {
    /// The encoders of `k` bodies from their weights (Burn's layouts; see the fields).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        k: usize,
        hidden: usize,
        slope: f32,
        w1: Vec<f32>,
        b1: Vec<f32>,
        w2: Vec<Vec<f32>>,
        b2: Vec<Vec<f32>>,
        wfc: Vec<Vec<f32>>,
        bfc: Vec<Vec<f32>>,
    ) -> Self {
        Self {
            w1t: transpose(&w1, C1 * k, PATCH1),
            w1_bytes: ByteWeights::new(&w1, C1 * k),
            k,
            hidden,
            slope,
            w1,
            b1,
            sparse_below: SPARSE_BELOW,
            sparse_below_acting: SPARSE_BELOW_ACTING,
            sparse_below_dense: SPARSE_BELOW_DENSE,
            spans: Spans::default(),
            w2,
            b2,
            wfc,
            bfc,
        }
    }

    /// Whether conv 1 runs on a sub-chunk's non-zeros (`acting`: no backward
    /// pass follows), and if so the non-zeros.
    fn sparse_chunk(
        &self,
        grids: GridsRef<'_>,
        first: usize,
        s: usize,
        nzs: &mut [Vec<Nonzero>],
        acting: bool,
    ) -> bool {
        let below = match grids {
            GridsRef::Dense(_) => self.sparse_below_dense,
            GridsRef::Compact(_) if acting => self.sparse_below_acting,
            GridsRef::Compact(_) => self.sparse_below,
        };
        if below <= 0.0 {
            return false;
        }
        let limit = below * (s * STACKED_LEN) as f32;
        if let GridsRef::Dense(x) = grids {
            // Count first (a vectorised pass): building the list costs more.
            let part = &x[first * STACKED_LEN..(first + s) * STACKED_LEN];
            let count = part.iter().map(|&v| (v != 0.0) as u32).sum::<u32>();
            if count as f32 > limit {
                return false;
            }
        }
        let mut total = 0;
        for (t, nz) in nzs.iter_mut().enumerate().take(s) {
            nonzeros(grids, first + t, nz);
            total += nz.len();
        }
        total as f32 <= limit
    }

    /// Floats per sample of the [`EncoderSaved`] parts.
    fn widths(&self) -> (usize, usize, usize) {
        (P1 * C1 * self.k, self.k * CONV_FLAT, self.k * self.hidden)
    }

    /// Forward for the `n` samples of a task: `out` `[n, K·hidden]`; `a1` and
    /// `e` (the task's parts of [`EncoderSaved`]) are written too, and with
    /// `kept` (its chunks' slots) the non-zero inputs of the chunks that conv 1
    /// ran sparse on.
    #[allow(clippy::too_many_arguments)]
    pub fn forward_task(
        &self,
        grids: GridsRef<'_>,
        first: usize,
        n: usize,
        out: &mut [f32],
        a1: &mut [f32],
        e: &mut [f32],
        mut kept: Option<&mut [ChunkNonzeros]>,
    ) {
        let (wa1, we, wh) = self.widths();
        let (k, hid) = (self.k, self.hidden);
        let mut patches = Patches::default();
        let mut cols2 = vec![0.0f32; SUB * P2 * PATCH2];
        let mut z2 = vec![0.0f32; SUB * P2 * C2];
        let mut nzs: Vec<Vec<Nonzero>> = vec![Vec::new(); SUB];
        let mut scratch: Option<bytes::Scratch> = None;
        for s0 in (0..n).step_by(SUB) {
            let s = SUB.min(n - s0);
            let a1c = &mut a1[s0 * wa1..(s0 + s) * wa1];
            // Acting on the sensor's bytes: conv 1 read straight from them.
            let acting_bytes = match grids {
                GridsRef::Compact(b)
                    if kept.is_none() && self.sparse_below_acting > 0.0 && bytes::available() =>
                {
                    Some(b)
                }
                _ => None,
            };
            if let Some(b) = acting_bytes {
                let scratch = scratch.get_or_insert_with(bytes::Scratch::default);
                for (t, z) in a1c.chunks_exact_mut(wa1).enumerate() {
                    let at = (first + s0 + t) * STACK_BYTES;
                    bytes::forward(&b[at..at + STACK_BYTES], &self.w1_bytes, scratch, z);
                }
            } else if self.sparse_chunk(grids, first + s0, s, &mut nzs, kept.is_none()) {
                a1c.fill(0.0);
                for (t, nz) in nzs.iter().enumerate().take(s) {
                    sparse::forward(
                        nz,
                        &self.w1t,
                        C1 * k,
                        &self.spans,
                        &mut a1c[t * wa1..(t + 1) * wa1],
                    );
                }
                if let Some(kept) = kept.as_deref_mut() {
                    // Copies the size of each list (the buffers stay for reuse).
                    kept[s0 / SUB] = Some(nzs[..s].to_vec());
                }
            } else {
                // Conv 1 for all bodies: [s·32, 1152] × W1ᵀ → [s·32, 16K].
                sgemm(
                    s * P1,
                    C1 * k,
                    PATCH1,
                    patches.of(grids, first + s0, s),
                    [PATCH1, 1],
                    &self.w1,
                    [1, PATCH1],
                    a1c,
                    [C1 * k, 1],
                    false,
                );
            }
            add_bias(a1c, s * P1, C1 * k, &self.b1);
            leaky_inplace(a1c, self.slope);
            for b in 0..k {
                im2col2(a1c, k, b, s, &mut cols2);
                sgemm(
                    s * P2,
                    C2,
                    PATCH2,
                    &cols2,
                    [PATCH2, 1],
                    &self.w2[b],
                    [1, PATCH2],
                    &mut z2,
                    [C2, 1],
                    false,
                );
                add_bias(&mut z2, s * P2, C2, &self.b2[b]);
                leaky_inplace(&mut z2[..s * P2 * C2], self.slope);
                // Flatten as Burn does [32, 1, 3]: e[o·3 + j] = a2[j][o].
                for t in 0..s {
                    let et =
                        &mut e[(s0 + t) * we + b * CONV_FLAT..(s0 + t) * we + (b + 1) * CONV_FLAT];
                    for j in 0..P2 {
                        for o in 0..C2 {
                            et[o * P2 + j] = z2[(t * P2 + j) * C2 + o];
                        }
                    }
                }
                let hb = &mut out[s0 * wh + b * hid..];
                sgemm(
                    s,
                    hid,
                    CONV_FLAT,
                    &e[s0 * we + b * CONV_FLAT..],
                    [we, 1],
                    &self.wfc[b],
                    [hid, 1],
                    hb,
                    [wh, 1],
                    false,
                );
                for t in 0..s {
                    let row = &mut hb[t * wh..t * wh + hid];
                    for (v, bias) in row.iter_mut().zip(&self.bfc[b]) {
                        *v += bias;
                    }
                    leaky_inplace(row, self.slope);
                }
            }
        }
    }

    /// Backward for the `n` samples of a task from `dh` `[n, K·hidden]`:
    /// adds the weight gradients to `grads` and, with `dx` `[n, 18, 20, 34]`,
    /// writes the grids' gradient.
    #[allow(clippy::too_many_arguments)]
    pub fn backward_task(
        &self,
        grids: GridsRef<'_>,
        first: usize,
        n: usize,
        saved: SavedPart<'_>,
        dh: &[f32],
        grads: &mut EncoderGrads,
        mut dx: Option<&mut [f32]>,
    ) {
        let SavedPart { a1, e, h, .. } = saved;
        let (wa1, we, wh) = self.widths();
        let (k, hid) = (self.k, self.hidden);
        let mut patches = Patches::default();
        let mut cols2 = vec![0.0f32; SUB * P2 * PATCH2];
        let mut dz = vec![0.0f32; SUB * hid];
        let mut de = vec![0.0f32; SUB * CONV_FLAT];
        let mut dz2 = vec![0.0f32; SUB * P2 * C2];
        let mut da1 = vec![0.0f32; SUB * wa1];
        let mut dw1t: Option<Vec<f32>> = None;
        for s0 in (0..n).step_by(SUB) {
            let s = SUB.min(n - s0);
            let a1c = &a1[s0 * wa1..(s0 + s) * wa1];
            da1[..s * wa1].fill(0.0);
            for b in 0..k {
                // Dense layer: dz = dh·leaky'(h).
                for t in 0..s {
                    let at = (s0 + t) * wh + b * hid;
                    let row = &mut dz[t * hid..(t + 1) * hid];
                    row.copy_from_slice(&dh[at..at + hid]);
                    leaky_backward(row, &h[at..at + hid], self.slope);
                }
                let eb = &e[s0 * we + b * CONV_FLAT..];
                // dWfc [96, hid] += eᵀ [96, s] · dz [s, hid]
                sgemm(
                    CONV_FLAT,
                    hid,
                    s,
                    eb,
                    [1, we],
                    &dz,
                    [hid, 1],
                    &mut grads.wfc[b],
                    [hid, 1],
                    true,
                );
                sum_rows(&dz, s, hid, &mut grads.bfc[b]);
                // de [s, 96] = dz [s, hid] · Wfcᵀ [hid, 96]
                sgemm(
                    s,
                    CONV_FLAT,
                    hid,
                    &dz,
                    [hid, 1],
                    &self.wfc[b],
                    [1, hid],
                    &mut de,
                    [CONV_FLAT, 1],
                    false,
                );
                // Back to [s·3, 32], through conv 2's LeakyReLU.
                for t in 0..s {
                    for j in 0..P2 {
                        for o in 0..C2 {
                            let (r, c) = ((t * P2 + j) * C2 + o, t * CONV_FLAT + o * P2 + j);
                            let a = eb[t * we + o * P2 + j];
                            dz2[r] = if a > 0.0 { de[c] } else { de[c] * self.slope };
                        }
                    }
                }
                im2col2(a1c, k, b, s, &mut cols2);
                // dW2 [32, 256] += dz2ᵀ [32, s·3] · cols2 [s·3, 256]
                sgemm(
                    C2,
                    PATCH2,
                    s * P2,
                    &dz2,
                    [1, C2],
                    &cols2,
                    [PATCH2, 1],
                    &mut grads.w2[b],
                    [PATCH2, 1],
                    true,
                );
                sum_rows(&dz2, s * P2, C2, &mut grads.b2[b]);
                // dcols2 [s·3, 256] = dz2 [s·3, 32] · W2 [32, 256]
                sgemm(
                    s * P2,
                    PATCH2,
                    C2,
                    &dz2,
                    [C2, 1],
                    &self.w2[b],
                    [PATCH2, 1],
                    &mut cols2,
                    [PATCH2, 1],
                    false,
                );
                col2im2(&cols2, k, b, s, &mut da1);
            }
            // Conv 1, all bodies: dz1 = da1·leaky'(a1).
            let dz1 = &mut da1[..s * wa1];
            leaky_backward(dz1, a1c, self.slope);
            // The forward pass's lists: it chose sparse or dense for this chunk.
            if let Some(lists) = saved.nonzeros[s0 / SUB].as_deref() {
                // dW1ᵀ [1152, 16K] += Σ over non-zeros (transposed back below).
                let dwt = dw1t.get_or_insert_with(|| vec![0.0; PATCH1 * C1 * k]);
                for (t, nz) in lists.iter().enumerate() {
                    sparse::backward(nz, &dz1[t * wa1..(t + 1) * wa1], C1 * k, &self.spans, dwt);
                }
            } else {
                // dW1 [16K, 1152] += dz1ᵀ [16K, s·32] · cols [s·32, 1152]
                sgemm(
                    C1 * k,
                    PATCH1,
                    s * P1,
                    dz1,
                    [1, C1 * k],
                    patches.of(grids, first + s0, s),
                    [PATCH1, 1],
                    &mut grads.w1,
                    [PATCH1, 1],
                    true,
                );
            }
            sum_rows(dz1, s * P1, C1 * k, &mut grads.b1);
            if let Some(dx) = dx.as_deref_mut() {
                let (xp, cols) = patches.buffers();
                self.grid_gradient(dz1, s0, s, cols, xp, dx);
            }
        }
        if let Some(dwt) = dw1t {
            let width = C1 * k;
            for (kk, row) in dwt.chunks_exact(width).enumerate() {
                for (o, v) in row.iter().enumerate() {
                    grads.w1[o * PATCH1 + kk] += v;
                }
            }
        }
    }

    /// The grids' gradient of the `s` samples from `s0` of a task, into
    /// `dx`: `dcols = dz1·W1` with conv 1's `dz1` `[s·32, 16K]`, folded back
    /// onto the padded grid and unpadded.
    fn grid_gradient(
        &self,
        dz1: &[f32],
        s0: usize,
        s: usize,
        cols: &mut [f32],
        xp: &mut [f32],
        dx: &mut [f32],
    ) {
        let k = self.k;
        // dcols [s·32, 1152] = dz1 [s·32, 16K] · W1 [16K, 1152]
        sgemm(
            s * P1,
            PATCH1,
            C1 * k,
            dz1,
            [C1 * k, 1],
            &self.w1,
            [PATCH1, 1],
            cols,
            [PATCH1, 1],
            false,
        );
        for t in 0..s {
            xp.fill(0.0);
            col2im1(&cols[t * P1 * PATCH1..(t + 1) * P1 * PATCH1], xp);
            let out = &mut dx[(s0 + t) * STACKED_LEN..(s0 + t + 1) * STACKED_LEN];
            for (row_out, row_in) in out.chunks_exact_mut(AZ_CELLS).zip(xp.chunks_exact(W_PAD)) {
                row_out.copy_from_slice(&row_in[AZ_PAD..AZ_PAD + AZ_CELLS]);
            }
        }
    }

    /// Forward for a batch, in parallel tasks: the outputs `[n, K·hidden]` and
    /// what [`backward`](Self::backward) needs.
    pub fn forward(&self, grids: GridsRef<'_>) -> EncoderSaved {
        let n = grids.len();
        let (wa1, we, wh) = self.widths();
        let mut saved = EncoderSaved {
            a1: vec![0.0; n * wa1],
            e: vec![0.0; n * we],
            h: vec![0.0; n * wh],
            nonzeros: vec![None; n.div_ceil(SUB)],
        };
        saved
            .h
            .par_chunks_mut(TASK * wh)
            .zip(saved.a1.par_chunks_mut(TASK * wa1))
            .zip(saved.e.par_chunks_mut(TASK * we))
            .zip(saved.nonzeros.par_chunks_mut(TASK / SUB))
            .enumerate()
            .for_each(|(t, (((h, a1), e), kept))| {
                self.forward_task(grids, t * TASK, h.len() / wh, h, a1, e, Some(kept))
            });
        saved
    }

    /// Forward for a batch without keeping anything for a backward pass: the
    /// outputs `[n, K·hidden]`, written into `out`.
    pub fn infer(&self, grids: GridsRef<'_>, out: &mut [f32]) {
        let (wa1, we, wh) = self.widths();
        debug_assert_eq!(out.len(), grids.len() * wh);
        out.par_chunks_mut(TASK * wh)
            .enumerate()
            .for_each(|(t, h)| {
                let n = h.len() / wh;
                let (mut a1, mut e) = (vec![0.0; n * wa1], vec![0.0; n * we]);
                self.forward_task(grids, t * TASK, n, h, &mut a1, &mut e, None)
            });
    }

    /// Backward for a batch from `dh` `[n, K·hidden]`: the weight gradients and,
    /// with `input_grad`, the grids' gradient `[n, 18, 20, 34]`.
    pub fn backward(
        &self,
        grids: GridsRef<'_>,
        saved: &EncoderSaved,
        dh: &[f32],
        input_grad: bool,
    ) -> (EncoderGrads, Option<Vec<f32>>) {
        let n = grids.len();
        let (wa1, we, wh) = self.widths();
        let task = |t: usize, dx: Option<&mut [f32]>| {
            let (first, m) = (t * TASK, TASK.min(n - t * TASK));
            let mut g = EncoderGrads::zeros(self.k, self.hidden);
            fn part(v: &[f32], w: usize, first: usize, m: usize) -> &[f32] {
                &v[first * w..(first + m) * w]
            }
            self.backward_task(
                grids,
                first,
                m,
                SavedPart {
                    a1: part(&saved.a1, wa1, first, m),
                    e: part(&saved.e, we, first, m),
                    h: part(&saved.h, wh, first, m),
                    nonzeros: &saved.nonzeros[first / SUB..(first + m).div_ceil(SUB)],
                },
                part(dh, wh, first, m),
                &mut g,
                dx,
            );
            g
        };
        let (parts, dx) = par_tasks(n, STACKED_LEN, input_grad, task);
        // Summed in task order: the same bits whatever the number of threads.
        let mut parts = parts.into_iter();
        let mut grads = parts
            .next()
            .unwrap_or_else(|| EncoderGrads::zeros(self.k, self.hidden));
        for p in parts {
            grads.add(&p);
        }
        (grads, dx)
    }
}
