//! The visual encoder's forward + backward on a minibatch of 1,024 stacked
//! grids (actor and critic encoders together, K = 2, as PPO's update runs
//! them), conv 1 as im2col + GEMM against conv 1 on the non-zeros, at the
//! sensor's densities (21 % of the inputs non-zero in `coho_default`, 9 % in
//! `seabream_default`, 24 % in `field_dense`, 30 % in `density_dense`). Interleaved repetitions, the fastest of each kept
//! (the machine is shared). `cargo bench -p deepfoids-learn --bench encoder`.

use deepfoids_learn::frames::CompactGrids;
use deepfoids_learn::kernels::bytes;
use deepfoids_learn::kernels::encoder::{EncoderPack, GridsRef};
use deepfoids_learn::kernels::geometry::*;
use deepfoids_sensors::{CELLS, CHANNELS, FRAME_LEN, STACKED_LEN};
use std::time::Instant;

/// A small deterministic generator (xorshift) in [0, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// `n` stacks in which each cell of each frame sees something with
/// probability `occupied` (a proximity and one type channel: 2 of the 6
/// channels non-zero), quantised as PPO's buffer keeps them.
fn grids(n: usize, occupied: f32, rng: &mut Rng) -> CompactGrids {
    let mut g = vec![0.0f32; n * STACKED_LEN];
    for frame in g.chunks_exact_mut(FRAME_LEN) {
        for c in 0..CELLS {
            if rng.next() < occupied {
                frame[c] = 0.01 + 0.99 * rng.next();
                let k = 1 + (rng.next() * (CHANNELS - 1) as f32) as usize;
                frame[k.min(CHANNELS - 1) * CELLS + c] = 1.0;
            }
        }
    }
    CompactGrids::from_dense(&g)
}

fn pack(k: usize, hidden: usize, rng: &mut Rng) -> EncoderPack {
    let mut w = |len: usize, scale: f32| -> Vec<f32> {
        (0..len).map(|_| (rng.next() - 0.5) * scale).collect()
    };
    let w1 = w(C1 * k * PATCH1, 0.06);
    let b1 = w(C1 * k, 0.1);
    let (mut w2, mut b2, mut wfc, mut bfc) = (vec![], vec![], vec![], vec![]);
    for _ in 0..k {
        w2.push(w(C2 * PATCH2, 0.12));
        b2.push(w(C2, 0.1));
        wfc.push(w(CONV_FLAT * hidden, 0.2));
        bfc.push(w(hidden, 0.1));
    }
    EncoderPack::new(k, hidden, 0.01, w1, b1, w2, b2, wfc, bfc)
}

/// The first body of a pack, alone.
fn pack1(p: &EncoderPack) -> EncoderPack {
    EncoderPack::new(
        1,
        p.hidden,
        p.slope,
        p.w1[..C1 * PATCH1].to_vec(),
        p.b1[..C1].to_vec(),
        vec![p.w2[0].clone()],
        vec![p.b2[0].clone()],
        vec![p.wfc[0].clone()],
        vec![p.bfc[0].clone()],
    )
}

fn main() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let (n, k, hidden, reps) = (1024, 2, 128, 7);
    let mut pack = pack(k, hidden, &mut rng);
    println!(
        "encoder forward + backward, {n} samples, K = {k}, {} threads",
        rayon::current_num_threads()
    );
    // Cells seeing something: 63 % gives coho_default's 21 % of the inputs
    // non-zero, 27 % seabream_default's 9 %, 73 % field_dense's 24 % and
    // 90 % density_dense's 30 % (their newest frames at reset).
    for (scene, occupied) in [
        ("coho_default", 0.63f32),
        ("seabream_default", 0.27),
        ("field_dense", 0.73),
        ("density_dense", 0.90),
    ] {
        let g = grids(n, occupied, &mut rng);
        let nz = g.to_dense().iter().filter(|&&v| v != 0.0).count();
        let dh: Vec<f32> = (0..n * k * hidden).map(|_| rng.next() - 0.5).collect();
        let mut best = [f64::MAX; 2];
        for _ in 0..reps {
            for (i, sparse_below) in [0.0f32, 1.0].into_iter().enumerate() {
                pack.sparse_below = sparse_below;
                let t = Instant::now();
                let saved = pack.forward(GridsRef::Compact(&g.bytes));
                let grads = pack.backward(GridsRef::Compact(&g.bytes), &saved, &dh, false);
                std::hint::black_box(grads);
                best[i] = best[i].min(t.elapsed().as_secs_f64());
            }
        }
        // Acting: the actor's encoder alone (K = 1), on f32 grids and on the
        // sensor's byte frames (what acting reads since the sensor hands them out).
        let dense = g.to_dense();
        let mut actor = pack1(&pack);
        let mut out = vec![0.0f32; n * hidden];
        let inputs = [
            ("f32 grids", GridsRef::Dense(&dense)),
            ("byte frames", GridsRef::Compact(&g.bytes)),
        ];
        for (what, grids) in inputs {
            let mut best_infer = [f64::MAX; 2];
            for _ in 0..reps {
                for (i, sparse_below) in [0.0f32, 1.0].into_iter().enumerate() {
                    actor.sparse_below = sparse_below;
                    actor.sparse_below_acting = sparse_below;
                    actor.sparse_below_dense = sparse_below;
                    let t = Instant::now();
                    actor.infer(grids, &mut out);
                    std::hint::black_box(&out);
                    best_infer[i] = best_infer[i].min(t.elapsed().as_secs_f64());
                }
            }
            println!(
                "{scene}: actor encoder inference on {what} (K = 1): im2col + GEMM {:.1} ms, {} {:.1} ms",
                1e3 * best_infer[0],
                match grids {
                    GridsRef::Compact(_) if bytes::available() => "straight from the bytes",
                    _ => "non-zeros",
                },
                1e3 * best_infer[1]
            );
        }
        println!(
            "{scene} ({:.0} % non-zero): im2col + GEMM {:.1} ms, non-zeros {:.1} ms: {:.2}×",
            100.0 * nz as f64 / (n * STACKED_LEN) as f64,
            1e3 * best[0],
            1e3 * best[1],
            best[0] / best[1]
        );
    }
}
