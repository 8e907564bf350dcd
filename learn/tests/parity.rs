//! The hand-written kernels against Burn's own layers (`Conv2d` with the
//! azimuth padding, `Linear`, `leaky_relu`, `silu`): outputs and gradients
//! (every weight and bias, and the input where it is differentiable) within
//! 1e−4, relative to the largest reference value where that exceeds 1.

use burn::prelude::*;
use deepfoids_env::VECTOR_OBS;
use deepfoids_learn::Grids;
use deepfoids_learn::body::{Body, BodyConfig, infer_net};
use deepfoids_learn::frames::CompactGrids;
use deepfoids_learn::kernels::encoder::GridsRef;
use deepfoids_learn::kernels::infer::TrunkInputs;
use deepfoids_learn::tensor::{tensor2, tensor4, to_vec};
use deepfoids_sensors::{CELLS, CHANNELS, FRAME_LEN, STACKED_LEN};
use std::sync::Arc;

/// Deterministic pseudo-random numbers in [−1, 1).
fn noise(n: usize, seed: u32) -> Vec<f32> {
    (0..n)
        .map(|i| {
            let x = (i as u32)
                .wrapping_mul(2_654_435_761)
                .wrapping_add(seed.wrapping_mul(0x9E37_79B9));
            let x = (x ^ (x >> 15)).wrapping_mul(0x2C1B_3C6D);
            ((x >> 8) as f32 / (1u32 << 23) as f32) - 1.0
        })
        .collect()
}

/// Grids like the sensor's: in each frame about a third of the cells see
/// something (a proximity in (0, 1] and one type channel hot), the rest zero.
fn sensor_like(n: usize, seed: u32) -> Vec<f32> {
    let r = noise(n * 3 * CELLS * 2, seed);
    let mut g = vec![0.0f32; n * STACKED_LEN];
    for (f, frame) in g.chunks_exact_mut(FRAME_LEN).enumerate() {
        for c in 0..CELLS {
            let (u, v) = (r[2 * (f * CELLS + c)], r[2 * (f * CELLS + c) + 1]);
            if u < -0.33 {
                frame[c] = (v + 1.0) / 2.0 * 0.99 + 0.01;
                let k = 1 + ((u + 1.0) * 1000.0) as usize % (CHANNELS - 1);
                frame[k * CELLS + c] = 1.0;
            }
        }
    }
    g
}

fn max_abs(v: &[f32]) -> f32 {
    v.iter().fold(0.0f32, |m, x| m.max(x.abs()))
}

/// `|a − b| ≤ 1e−4 · max(1, max |a|)` elementwise.
fn assert_close(what: &str, a: &[f32], b: &[f32]) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    let tol = 1e-4 * max_abs(a).max(1.0);
    let worst = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    assert!(worst <= tol, "{what}: max |Δ| {worst:.3e} > {tol:.3e}");
    assert!(max_abs(a) > 0.0, "{what}: all zero, nothing compared");
}

fn body(dev: &Device, extra: usize) -> Body {
    BodyConfig::new().with_extra_inputs(extra).init(dev)
}

/// Weights to fold outputs into a scalar loss (so that every output gets its own gradient).
fn fold(out: Tensor<2>, seed: u32) -> Tensor<1> {
    let [n, w] = out.dims();
    let dev = out.device();
    (out * tensor2(noise(n * w, seed), n, w, &dev)).sum()
}

fn grads_of(b: &Body, g: &burn::tensor::Gradients) -> Vec<(&'static str, Vec<f32>)> {
    let v1 = |p: &burn::module::Param<Tensor<1>>| to_vec(p.val().grad(g).expect("a gradient"));
    let v2 = |p: &burn::module::Param<Tensor<2>>| to_vec(p.val().grad(g).expect("a gradient"));
    let v4 = |p: &burn::module::Param<Tensor<4>>| to_vec(p.val().grad(g).expect("a gradient"));
    vec![
        ("conv1.weight", v4(&b.conv1.weight)),
        ("conv1.bias", v1(b.conv1.bias.as_ref().unwrap())),
        ("conv2.weight", v4(&b.conv2.weight)),
        ("conv2.bias", v1(b.conv2.bias.as_ref().unwrap())),
        ("fc_grid.weight", v2(&b.fc_grid.weight)),
        ("fc_grid.bias", v1(b.fc_grid.bias.as_ref().unwrap())),
    ]
}

/// The encoder kernel (dense grids, tracked) against Conv2d → LeakyReLU →
/// Conv2d → LeakyReLU → flatten → Linear → LeakyReLU: outputs, the six
/// parameter gradients and the input gradient. 70 samples: a full task of 64
/// and a partial one, sub-chunks of 16 and a partial one.
#[test]
fn encoder_matches_burn_layers() {
    // Conv 1 as im2col + GEMM (0), and on the non-zeros only (1).
    for sparse_below in [0.0, 1.0] {
        encoder_case(sparse_below);
    }
}

fn encoder_case(sparse_below: f32) {
    let dev = Device::flex().autodiff();
    let b = body(&dev, 0);
    let n = 70;
    let grid = sensor_like(n, 1);
    let x_k = tensor4(grid.clone(), n, &dev).require_grad();
    let x_r = tensor4(grid, n, &dev).require_grad();
    // The kernel itself, not a fallback to Burn's layers.
    let layers = deepfoids_learn::kernels::ops::EncoderLayers {
        conv1: &b.conv1,
        conv2: &b.conv2,
        fc: &b.fc_grid,
        slope: 0.01,
    };
    let out_k = deepfoids_learn::kernels::ops::encode_with(
        &[layers],
        &Grids::Dense(x_k.clone()),
        Some(sparse_below),
    )
    .expect("the encoder kernel runs on Flex with autodiff");
    let out_r = b.encode_reference(x_r.clone());
    assert_eq!(out_k.dims(), [n, 128]);
    assert_close("output", &to_vec(out_r.clone()), &to_vec(out_k.clone()));
    let g_k = fold(out_k, 7).backward();
    let g_r = fold(out_r, 7).backward();
    for ((name, r), (_, k)) in grads_of(&b, &g_r).into_iter().zip(grads_of(&b, &g_k)) {
        assert_close(name, &r, &k);
    }
    assert_close(
        "input",
        &to_vec(x_r.grad(&g_r).unwrap()),
        &to_vec(x_k.grad(&g_k).unwrap()),
    );
}

/// Two bodies on the same grids in one kernel call (conv 1 as one GEMM of 32
/// channels): each body's output and gradients equal its own Burn layers'.
/// Quantised (compact) grids give what the reference gives on their
/// dequantised floats.
#[test]
fn two_encoders_on_compact_grids_match_burn_layers() {
    for sparse_below in [0.0, 1.0] {
        two_encoders_case(sparse_below);
    }
}

fn two_encoders_case(sparse_below: f32) {
    let dev = Device::flex().autodiff();
    let (a, c) = (body(&dev, 0), body(&dev, 3));
    let n = 33;
    let compact = CompactGrids::from_dense(&sensor_like(n, 2));
    let dense = compact.to_dense();
    fn layers(m: &Body) -> deepfoids_learn::kernels::ops::EncoderLayers<'_> {
        deepfoids_learn::kernels::ops::EncoderLayers {
            conv1: &m.conv1,
            conv2: &m.conv2,
            fc: &m.fc_grid,
            slope: 0.01,
        }
    }
    let both = deepfoids_learn::kernels::ops::encode_with(
        &[layers(&a), layers(&c)],
        &Grids::Compact(Arc::new(compact)),
        Some(sparse_below),
    )
    .expect("the encoder kernel runs on Flex with autodiff");
    let outs = vec![
        both.clone().slice([0..n, 0..128]),
        both.slice([0..n, 128..256]),
    ];
    let x = tensor4(dense, n, &dev);
    let refs = [a.encode_reference(x.clone()), c.encode_reference(x)];
    let mut loss_k = None;
    let mut loss_r = None;
    for (i, (k, r)) in outs.into_iter().zip(refs).enumerate() {
        assert_close(
            &format!("output {i}"),
            &to_vec(r.clone()),
            &to_vec(k.clone()),
        );
        let (lk, lr) = (fold(k, 10 + i as u32), fold(r, 10 + i as u32));
        loss_k = Some(loss_k.map_or(lk.clone(), |l: Tensor<1>| l + lk));
        loss_r = Some(loss_r.map_or(lr.clone(), |l: Tensor<1>| l + lr));
    }
    let (g_k, g_r) = (loss_k.unwrap().backward(), loss_r.unwrap().backward());
    for m in [&a, &c] {
        for ((name, r), (_, k)) in grads_of(m, &g_r).into_iter().zip(grads_of(m, &g_k)) {
            assert_close(name, &r, &k);
        }
    }
}

/// The Swish trunk kernel against Linear → silu, with the input's gradient
/// (SAC's actor loss differentiates through a critic's trunk into the action).
#[test]
fn dense_swish_matches_burn_layers() {
    let dev = Device::flex().autodiff();
    let b = body(&dev, 3);
    let n = 130;
    let enc = tensor2(noise(n * 128, 3), n, 128, &dev).require_grad();
    let vec_k = tensor2(noise(n * (VECTOR_OBS + 3), 4), n, VECTOR_OBS + 3, &dev).require_grad();
    let vec_r = vec_k.clone().detach().require_grad();
    let x = Tensor::cat(vec![enc.clone(), vec_k.clone()], 1);
    assert!(deepfoids_learn::kernels::ops::dense_silu(x, &b.trunk[0]).is_some());
    let out_k = b.trunk_forward(enc.clone(), vec_k.clone());
    let out_r = b.trunk_reference(enc.clone(), vec_r.clone());
    assert_close("output", &to_vec(out_r.clone()), &to_vec(out_k.clone()));
    let g_k = fold(out_k, 5).backward();
    let g_r = fold(out_r, 5).backward();
    for (i, l) in b.trunk.iter().enumerate() {
        let w = |g| to_vec(l.weight.val().grad(g).unwrap());
        let bias = |g| to_vec(l.bias.as_ref().unwrap().val().grad(g).unwrap());
        assert_close(&format!("trunk.{i}.weight"), &w(&g_r), &w(&g_k));
        assert_close(&format!("trunk.{i}.bias"), &bias(&g_r), &bias(&g_k));
    }
    assert_close(
        "vector input",
        &to_vec(vec_r.grad(&g_r).unwrap()),
        &to_vec(vec_k.grad(&g_k).unwrap()),
    );
}

/// The fused forward without autodiff (two bodies, a head on each, extra
/// trunk inputs on the second) against Burn's layers; and the kernels on a
/// device without autodiff.
#[test]
fn fused_forward_matches_burn_layers() {
    let dev = Device::flex();
    let (a, c) = (body(&dev, 0), body(&dev, 3));
    let head_a = burn::nn::LinearConfig::new(128, 3).init(&dev);
    let head_c = burn::nn::LinearConfig::new(128, 1).init(&dev);
    let n = 100;
    let grid = sensor_like(n, 4);
    let vectors = noise(n * VECTOR_OBS, 5);
    let actions = noise(n * 3, 6);
    let net = infer_net(&[(&a, Some(&head_a)), (&c, Some(&head_c))]);
    let enc = net.encode(GridsRef::Dense(&grid));
    let none = TrunkInputs {
        vectors: &vectors,
        extra: &[],
        extra_width: 0,
    };
    let with_action = TrunkInputs {
        extra: &actions,
        extra_width: 3,
        ..none
    };
    let out_a = net.trunk(0, &enc, none);
    let out_c = net.trunk(1, &enc, with_action);
    let x = tensor4(grid.clone(), n, &dev);
    let v = tensor2(vectors.clone(), n, VECTOR_OBS, &dev);
    let va = Tensor::cat(vec![v.clone(), tensor2(actions, n, 3, &dev)], 1);
    let ref_a = head_a.forward(a.trunk_reference(a.encode_reference(x.clone()), v.clone()));
    let ref_c = head_c.forward(c.trunk_reference(c.encode_reference(x.clone()), va.clone()));
    assert_close("actor head", &to_vec(ref_a), &out_a);
    assert_close("critic head", &to_vec(ref_c.clone()), &out_c);
    // The Burn-facing ops on a plain Flex device (no autodiff).
    let k = head_c.forward(c.forward(&Grids::Dense(x), va));
    assert_close("ops without autodiff", &to_vec(ref_c), &to_vec(k));
}

/// Acting on the sensor's bytes (conv 1 read straight from them where the CPU
/// can, else on their non-zeros) against im2col + GEMM on the same frames as
/// floats: the encodings of one body and of two, for 150 samples (two full
/// tasks of 64 and a partial one, sub-chunks of 16 and a partial one).
#[test]
fn acting_on_bytes_matches_acting_on_their_floats() {
    let dev = Device::flex();
    let (a, c) = (body(&dev, 0), body(&dev, 3));
    let n = 150;
    let bytes = CompactGrids::from_dense(&sensor_like(n, 7));
    let floats = bytes.to_dense();
    for parts in [vec![(&a, None)], vec![(&a, None), (&c, None)]] {
        let net = infer_net(&parts);
        let on_bytes = net.encode(GridsRef::Compact(&bytes.bytes));
        let on_floats = net.encode(GridsRef::Dense(&floats));
        assert_close(
            &format!("encodings of {} bodies", parts.len()),
            &on_floats,
            &on_bytes,
        );
    }
}

/// The general convolution op (the fish detector's layers) against Burn's
/// `Conv2d` → `leaky_relu`: outputs, weight, bias and input gradients, for a
/// stride-2 layer, dilated layers with their padding and a 1 × 1 head
/// without activation, on odd sizes.
#[test]
fn conv2d_op_matches_burn_conv2d() {
    use burn::nn::PaddingConfig2d;
    use burn::nn::conv::Conv2dConfig;
    use burn::tensor::activation::leaky_relu;
    let dev = Device::flex().autodiff();
    for (c_in, c_out, k, stride, dilation, slope, (h, w)) in [
        (3, 8, 3, 2, 1, Some(0.1), (17, 24)),
        (8, 8, 3, 1, 2, Some(0.1), (9, 11)),
        (8, 16, 3, 1, 4, Some(0.1), (12, 10)),
        (16, 4, 1, 1, 1, None, (6, 7)),
    ] {
        let pad = if k == 1 { 0 } else { dilation };
        let conv = Conv2dConfig::new([c_in, c_out], [k, k])
            .with_stride([stride, stride])
            .with_dilation([dilation, dilation])
            .with_padding(if pad == 0 {
                PaddingConfig2d::Valid
            } else {
                PaddingConfig2d::Explicit(pad, pad, pad, pad)
            })
            .init(&dev);
        let n = 3;
        let data = noise(n * c_in * h * w, c_out as u32);
        let x_k =
            Tensor::<4>::from_data(TensorData::new(data, [n, c_in, h, w]), &dev).require_grad();
        let x_r = x_k.clone().detach().require_grad();
        let out_k = deepfoids_learn::kernels::ops::conv2d(x_k.clone(), &conv, slope)
            .expect("the conv op runs on Flex with autodiff");
        let z = conv.forward(x_r.clone());
        let out_r = match slope {
            Some(s) => leaky_relu(z, f64::from(s)),
            None => z,
        };
        assert_eq!(out_k.dims(), out_r.dims());
        let what = format!("conv {c_in}→{c_out} k{k} s{stride} d{dilation}");
        assert_close(&what, &to_vec(out_r.clone()), &to_vec(out_k.clone()));
        let dims = out_k.dims();
        let len = dims.iter().product();
        let gw = Tensor::<4>::from_data(TensorData::new(noise(len, 9), dims), &dev);
        let g_k = (out_k * gw.clone()).sum().backward();
        let g_r = (out_r * gw).sum().backward();
        let weight = |g| to_vec(conv.weight.val().grad(g).unwrap());
        let bias = |g| to_vec(conv.bias.as_ref().unwrap().val().grad(g).unwrap());
        assert_close(&format!("{what}: weight"), &weight(&g_r), &weight(&g_k));
        assert_close(&format!("{what}: bias"), &bias(&g_r), &bias(&g_k));
        assert_close(
            &format!("{what}: input"),
            &to_vec(x_r.grad(&g_r).unwrap()),
            &to_vec(x_k.grad(&g_k).unwrap()),
        );
    }
}
