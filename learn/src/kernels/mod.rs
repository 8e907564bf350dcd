//! Hand-written kernels for the SPEC §8 network on the CPU: the visual encoder
//! (both convolutions, the dense layer after them) and the dense Swish layers,
//! forward and backward, as im2col + GEMM (the `gemm` crate, which picks the
//! CPU's widest SIMD at run time), in chunks of samples spread over rayon's
//! threads.
//!
//! * [`encoder`] and [`dense`]: the arithmetic on flat slices, one chunk of
//!   samples at a time; conv 1 as im2col + GEMM, or on the non-zero inputs
//!   only ([`sparse`]) when quantised grids (the updates') are sparse, as the
//!   sensor's are;
//! * [`ops`]: the same as Burn operations with a hand-written backward,
//!   registered in Burn's autodiff graph (custom ops on the Flex backend);
//! * [`infer`]: a fused forward without autodiff for acting (rollouts,
//!   evaluation, SAC's targets), on weights copied out of the Burn modules;
//!   on the sensor's byte frames conv 1 reads the bytes directly ([`bytes`]).
//!
//! Every kernel is tested against Burn's own layers (`Conv2d`, `Linear`,
//! `leaky_relu`, `silu`): outputs and gradients within 1e−4 (`tests/parity.rs`).
//!
//! # Determinism
//! The work is cut into tasks of [`TASK`] samples whatever the number of
//! threads, and the tasks' weight gradients are summed in task order, so a
//! seed gives the same bits on 1 or 2 threads.

pub mod bytes;
pub mod conv;
pub mod dense;
pub mod encoder;
pub mod grids;
pub mod infer;
pub mod ops;
pub mod sparse;

use deepfoids_sensors::{AZ_CELLS, EL_CELLS, STACKED_CHANNELS};
use rayon::prelude::*;

/// Samples per parallel task.
pub const TASK: usize = 64;
/// Samples per GEMM inside a task (keeps the im2col matrix in the L2 cache).
pub const SUB: usize = 16;

/// The encoder's geometry (SPEC §8, issue 11 item 2).
///
/// The grid's 34 azimuth columns are padded with one zero column on each side,
/// inside the network: those two columns are the 20° blind sector straight
/// behind the fish (±170°…±180°). On the padded 36 columns, Conv 8×8 stride 4
/// gives 8 columns and Conv 4×4 stride 2 gives 3, whose receptive fields
/// (padded columns 0–19, 8–27, 16–35) cover every input column and are
/// mirror images of each other about the heading. The stock encoder on 34
/// columns read only columns 0–27 (blind from +110° to +170° on the right).
pub mod geometry {
    use super::*;

    /// Zero columns added on each side of the azimuth axis.
    pub const AZ_PAD: usize = 1;
    /// Input channels: 3 stacked frames of 6.
    pub const C_IN: usize = STACKED_CHANNELS;
    /// Input rows (elevation) and padded columns (azimuth).
    pub const H_IN: usize = EL_CELLS;
    pub const W_PAD: usize = AZ_CELLS + 2 * AZ_PAD;
    /// Conv 1: 18 → 16 channels, 8 × 8, stride 4.
    pub const C1: usize = 16;
    pub const K1: usize = 8;
    pub const S1: usize = 4;
    pub const H1: usize = (H_IN - K1) / S1 + 1;
    pub const W1: usize = (W_PAD - K1) / S1 + 1;
    /// Output positions of conv 1 per sample (4 × 8).
    pub const P1: usize = H1 * W1;
    /// Length of a conv-1 patch (18 × 8 × 8).
    pub const PATCH1: usize = C_IN * K1 * K1;
    /// Conv 2: 16 → 32 channels, 4 × 4, stride 2.
    pub const C2: usize = 32;
    pub const K2: usize = 4;
    pub const S2: usize = 2;
    pub const H2: usize = (H1 - K2) / S2 + 1;
    pub const W2: usize = (W1 - K2) / S2 + 1;
    /// Output positions of conv 2 per sample (1 × 3).
    pub const P2: usize = H2 * W2;
    /// Length of a conv-2 patch (16 × 4 × 4).
    pub const PATCH2: usize = C1 * K2 * K2;
    /// Width of the flattened conv-2 output `[32, 1, 3]`.
    pub const CONV_FLAT: usize = C2 * P2;
    /// Floats of one padded input sample.
    pub const PADDED_LEN: usize = C_IN * H_IN * W_PAD;

    const _: () = assert!(H2 == 1 && W2 == 3 && P1 == 32);
    const _: () = assert!((W_PAD - K1).is_multiple_of(S1) && (W1 - K2).is_multiple_of(S2));
}

/// The instruction set this machine's kernels run on: `"avx512"`, `"avx2"` or
/// `"plain"` — the one [`sparse`]'s loops dispatch on and the one `gemm` picks
/// for [`sgemm`] (both at run time, AVX-512 first). Seeded runs reproduce bit
/// for bit only on one instruction set: the products sum in another order on
/// another (docs/training.md, "Seeds"). A run records it in its `config.toml`.
pub fn instruction_set() -> &'static str {
    match sparse::isa() {
        sparse::Isa::Avx512 => "avx512",
        sparse::Isa::Avx2 => "avx2",
        sparse::Isa::Plain => "plain",
    }
}

/// `C ← A·B` (or `C ← C + A·B` with `accumulate`), A `[m, k]`, B `[k, n]`,
/// C `[m, n]`, each given by its row and column strides, single-threaded
/// (the callers split the work into tasks).
#[allow(clippy::too_many_arguments)]
pub fn sgemm(
    m: usize,
    n: usize,
    k: usize,
    a: &[f32],
    [a_rs, a_cs]: [usize; 2],
    b: &[f32],
    [b_rs, b_cs]: [usize; 2],
    c: &mut [f32],
    [c_rs, c_cs]: [usize; 2],
    accumulate: bool,
) {
    if m == 0 || n == 0 {
        return;
    }
    let last = |rows: usize, cols: usize, rs: usize, cs: usize| (rows - 1) * rs + (cols - 1) * cs;
    assert!(last(m, n, c_rs, c_cs) < c.len(), "sgemm: C too short");
    if k == 0 {
        if !accumulate {
            for i in 0..m {
                for j in 0..n {
                    c[i * c_rs + j * c_cs] = 0.0;
                }
            }
        }
        return;
    }
    assert!(last(m, k, a_rs, a_cs) < a.len(), "sgemm: A too short");
    assert!(last(k, n, b_rs, b_cs) < b.len(), "sgemm: B too short");
    // SAFETY: every element the product reads or writes lies inside the
    // slices (checked above); `c` does not alias `a` or `b` (borrow rules).
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            c.as_mut_ptr(),
            c_cs as isize,
            c_rs as isize,
            accumulate,
            a.as_ptr(),
            a_cs as isize,
            a_rs as isize,
            b.as_ptr(),
            b_cs as isize,
            b_rs as isize,
            1.0f32,
            1.0f32,
            false,
            false,
            false,
            gemm::Parallelism::None,
        );
    }
}

/// LeakyReLU in place: `x ← x` if `x > 0`, else `slope·x`. Every element is
/// written (a select, not a branch), so the loop vectorises.
#[inline]
pub fn leaky_inplace(x: &mut [f32], slope: f32) {
    for v in x {
        *v = if *v <= 0.0 { *v * slope } else { *v };
    }
}

/// `dz ← dy · leaky'(z)` given the activation's output `a` (its sign is `z`'s).
#[inline]
pub fn leaky_backward(dy: &mut [f32], a: &[f32], slope: f32) {
    for (g, &v) in dy.iter_mut().zip(a) {
        *g = if v <= 0.0 { *g * slope } else { *g };
    }
}

/// Add `bias` to every row of the `[rows, bias.len()]` matrix `x` (row stride `rs`).
#[inline]
pub fn add_bias(x: &mut [f32], rows: usize, rs: usize, bias: &[f32]) {
    for r in 0..rows {
        for (v, b) in x[r * rs..r * rs + bias.len()].iter_mut().zip(bias) {
            *v += b;
        }
    }
}

/// `acc[j] += Σ_r x[r][j]` over the rows of a `[rows, acc.len()]` matrix (row stride `rs`).
#[inline]
pub fn sum_rows(x: &[f32], rows: usize, rs: usize, acc: &mut [f32]) {
    let n = acc.len();
    for r in 0..rows {
        for (a, v) in acc.iter_mut().zip(&x[r * rs..r * rs + n]) {
            *a += v;
        }
    }
}

/// The backward passes' parallel loop: `task(t, dx)` for each task `t` of
/// [`TASK`] samples out of `n`, the results in task order (so that summing
/// them gives the same bits on any number of threads). With `input_grad`,
/// task `t` also gets its rows of a fresh `[n, width]` input gradient, which
/// is returned beside the results.
pub fn par_tasks<G: Send>(
    n: usize,
    width: usize,
    input_grad: bool,
    task: impl Fn(usize, Option<&mut [f32]>) -> G + Sync,
) -> (Vec<G>, Option<Vec<f32>>) {
    if input_grad {
        let mut dx = vec![0.0f32; n * width];
        let parts = dx
            .par_chunks_mut(TASK * width)
            .enumerate()
            .map(|(t, d)| task(t, Some(d)))
            .collect();
        (parts, Some(dx))
    } else {
        let parts = (0..n.div_ceil(TASK))
            .into_par_iter()
            .map(|t| task(t, None))
            .collect();
        (parts, None)
    }
}

/// The tasks a batch of `n` samples is cut into: `(first sample, samples)`.
pub fn tasks(n: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..n.div_ceil(TASK)).map(move |t| (t * TASK, TASK.min(n - t * TASK)))
}
