//! Our fish detector: a small fully-convolutional, one-class, CenterNet-style
//! network (Zhou et al. 2019, "Objects as Points"), trained from scratch.
//!
//! # Shapes
//! image `[B, 3, H, W]` (RGB in [0, 1]; H, W multiples of 8)
//! → local contrast, per channel: `(x − mean) / √(var + ε²)` over the
//!   `NORM_KERNEL`² square around each pixel (no learnt parameters)
//! → Conv 3→c, 3×3, stride 2, LeakyReLU(0.1)            `[B, c, H/2, W/2]`
//! → Conv c→2c, 3×3, stride 2, LeakyReLU                 `[B, 2c, H/4, W/4]`
//! → Conv 2c→2c, 3×3, LeakyReLU
//! → Conv 2c→4c, 3×3, stride 2, LeakyReLU                `[B, 4c, H/8, W/8]`
//! → Conv 4c→4c, 3×3, LeakyReLU; the same with dilation 2, then 4
//! → heads, 1×1: `heat` 4c→1 (logits; the ONNX graph applies the sigmoid)
//!   and `boxes` 4c→4 (offset x, offset y, ln(w/8), ln(h/8)).
//!
//! Receptive field 135 px (the dilated layers widen it at no cost in
//! resolution), so a fish up to about a hundred pixels is seen whole (`wide`:
//! one more 4c→4c layer with dilation 8, 263 px); with
//! `c = 16` it has 0.14 M parameters (0.6 MB) and costs ≈ 1 GFLOP per 416²
//! window. Padding is `dilation` on every side, so every size that is a
//! multiple of 8 maps to exactly a 1/8 grid.

use burn::module::Param;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{Initializer, PaddingConfig2d};
use burn::prelude::*;
use burn::tensor::activation::leaky_relu;
use burn::tensor::module::avg_pool2d;
use burn::tensor::ops::AvgPoolOptions;
use deepfoids_learn::kernels::ops::conv2d;

/// Output stride of the heads (pixels per cell) unless told otherwise.
pub const STRIDE: usize = 8;
/// The output strides a detector can have.
pub const STRIDES: [usize; 2] = [4, 8];
/// LeakyReLU's negative slope.
pub const SLOPE: f64 = 0.1;
/// Initial heatmap bias: sigmoid(−2.19) = 0.1, CenterNet's prior, so the
/// first steps are not swamped by the loss of the many empty cells.
pub const HEAT_PRIOR_BIAS: f32 = -2.19;

/// Side of the square of the input's local contrast normalisation (pixels):
/// wider than most fish in a 416-px window, narrower than the glow of the
/// Snell window and the water's fall-off towards the rim.
pub const NORM_KERNEL: usize = 31;
/// `ε` of the local contrast normalisation (in [0, 1] units, about 5 grey
/// levels): flat water is not amplified into noise.
pub const NORM_EPS: f32 = 0.02;

/// The input's local contrast: `(x − m) / √(v + ε²)` with `m` and `v` the mean
/// and variance of each channel over the `NORM_KERNEL`² square around the
/// pixel (the padding not counted). Randomised water changes the colour, the
/// brightness and the contrast of the fish across frames by far more than the
/// fish differ from their water within one; a first full run without this
/// (mAP50 0.001, docs/counting.md) learned to call everything water.
pub fn local_contrast(x: Tensor<4>) -> Tensor<4> {
    // The mean over the square's part inside the image is the mean over a
    // rectangle, so a column pass then a row pass give it (62 adds a pixel
    // instead of 961).
    let (k, p) = (NORM_KERNEL, NORM_KERNEL / 2);
    let pass = |t: Tensor<4>, kernel: [usize; 2], padding: [usize; 2]| {
        avg_pool2d(
            t,
            AvgPoolOptions::new(kernel)
                .with_stride([1, 1])
                .with_padding(padding)
                .with_count_include_pad(false),
        )
    };
    let pool = |t: Tensor<4>| pass(pass(t, [k, 1], [p, 0]), [1, k], [0, p]);
    let m = pool(x.clone());
    let v = (pool(x.clone() * x.clone()) - m.clone() * m.clone()).clamp_min(0.0);
    (x - m) / (v + NORM_EPS * NORM_EPS).sqrt()
}

/// He (Kaiming) normal initialisation, `std = √2 / √fan_in`: Burn's default
/// (`gain` 1/√3, uniform) shrinks the signal's variance about sixfold per
/// layer, so after seven layers the heads saw a constant and a first
/// 28-minute run learned nothing (mAP50 0; the heatmap only reacted to the
/// zero padding at window borders).
fn he() -> Initializer {
    Initializer::KaimingNormal {
        gain: std::f64::consts::SQRT_2,
        fan_out_only: false,
    }
}

/// `(out channels as a multiple of the base, stride, dilation)` per body
/// layer, output stride 8.
pub const LAYERS: [(usize, usize, usize); 7] = [
    (1, 2, 1),
    (2, 2, 1),
    (2, 1, 1),
    (4, 2, 1),
    (4, 1, 1),
    (4, 1, 2),
    (4, 1, 4),
];

/// The same for output stride 4, for schools whose fish lie closer than
/// 8 px: the fourth layer keeps the resolution, the deep layers have half
/// the channels (so about the same multiply-adds: 0.57 G per 416² window at
/// base 16 against 0.52 G) and twice the dilation (the same 135-px
/// receptive field).
pub const LAYERS_STRIDE_4: [(usize, usize, usize); 7] = [
    (1, 2, 1),
    (2, 2, 1),
    (2, 1, 1),
    (2, 1, 1),
    (2, 1, 2),
    (2, 1, 4),
    (2, 1, 8),
];

/// The body layers of a network of output stride `stride` (4 or 8); `wide`
/// appends one more layer like the last with twice its dilation, which
/// widens the receptive field from 135 to 263 px (for fish close to the
/// camera, longer than 135 px in the view) for one more layer's cost.
pub fn layers(stride: usize, wide: bool) -> Vec<(usize, usize, usize)> {
    let mut l = if stride == 4 {
        LAYERS_STRIDE_4.to_vec()
    } else {
        LAYERS.to_vec()
    };
    if wide {
        let (m, _, d) = l[l.len() - 1];
        l.push((m, 1, 2 * d));
    }
    l
}

#[derive(Config, Debug)]
pub struct DetectorNetConfig {
    /// Channels of the first layer (the others are 2× and 4× it); 16.
    #[config(default = 16)]
    pub base: usize,
    /// Output stride, one of [`STRIDES`]; 8.
    #[config(default = 8)]
    pub stride: usize,
    /// One more dilated layer ([`layers`]); false.
    #[config(default = false)]
    pub wide: bool,
}

#[derive(Module, Debug)]
pub struct DetectorNet {
    pub body: Vec<Conv2d>,
    pub heat: Conv2d,
    pub boxes: Conv2d,
}

impl DetectorNetConfig {
    pub fn init(&self, device: &Device) -> DetectorNet {
        let mut c_in = 3;
        let body = layers(self.stride, self.wide)
            .into_iter()
            .map(|(m, s, d)| {
                let c_out = m * self.base;
                let conv = Conv2dConfig::new([c_in, c_out], [3, 3])
                    .with_stride([s, s])
                    .with_dilation([d, d])
                    .with_padding(PaddingConfig2d::Explicit(d, d, d, d))
                    .with_initializer(he())
                    .init(device);
                c_in = c_out;
                conv
            })
            .collect();
        let mut heat = Conv2dConfig::new([c_in, 1], [1, 1]).init(device);
        heat.bias = Some(Param::from_tensor(Tensor::full(
            [1],
            HEAT_PRIOR_BIAS,
            device,
        )));
        DetectorNet {
            body,
            heat,
            boxes: Conv2dConfig::new([c_in, 4], [1, 1]).init(device),
        }
    }
}

impl DetectorNet {
    /// `(heat logits [B, 1, H/s, W/s], boxes [B, 4, H/s, W/s])`, `s` the stride.
    pub fn forward(&self, image: Tensor<4>) -> (Tensor<4>, Tensor<4>) {
        self.forward_normalised(local_contrast(image))
    }

    /// [`forward`](Self::forward) on an image already normalised to its
    /// local contrast (as `train-detector` computes it, with running sums
    /// and off the autodiff graph: it has no parameters).
    ///
    /// On the Flex backend every layer runs as `deepfoids-learn`'s
    /// convolution kernel (im2col + GEMM with a hand-written backward, held
    /// to Burn's `Conv2d` within 1e−4 by `learn/tests/parity.rs`); elsewhere
    /// as Burn's layers.
    pub fn forward_normalised(&self, mut x: Tensor<4>) -> (Tensor<4>, Tensor<4>) {
        let layer = |x: Tensor<4>, conv: &Conv2d, slope: Option<f32>| {
            conv2d(x.clone(), conv, slope).unwrap_or_else(|| {
                let z = conv.forward(x);
                match slope {
                    Some(s) => leaky_relu(z, f64::from(s)),
                    None => z,
                }
            })
        };
        for conv in &self.body {
            x = layer(x, conv, Some(SLOPE as f32));
        }
        (
            layer(x.clone(), &self.heat, None),
            layer(x, &self.boxes, None),
        )
    }

    /// Channels of the first layer.
    pub fn base(&self) -> usize {
        self.body[0].weight.dims()[0]
    }

    /// Output stride: the product of the body layers' strides.
    pub fn stride(&self) -> usize {
        self.body.iter().map(|c| c.stride[0]).product()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64 × 64 image black on the left half (x < 32) and white on the
    /// right, in all three channels. At x = 32 the 31-wide square (x 17..=47)
    /// holds 15 black and 16 white columns: m = 16/31, v = m(1 − m) =
    /// 0.249740, so (1 − m)/√(v + 0.02²) = 0.967472; at x = 48 (x 33..=63) and
    /// at x = 5 (x 0..=20, the padding not counted) the square is uniform: 0.
    /// Rows do not matter (every row is the same), the image's edge included.
    #[test]
    fn local_contrast_by_hand() {
        let device = Device::flex();
        let (w, h) = (64usize, 64usize);
        let v: Vec<f32> = (0..3 * h * w)
            .map(|i| if i % w >= 32 { 1.0 } else { 0.0 })
            .collect();
        let x = Tensor::<4>::from_data(TensorData::new(v, [1, 3, h, w]), &device);
        let out = local_contrast(x).into_data().try_to_vec::<f32>().unwrap();
        let at = |c: usize, y: usize, x: usize| out[(c * h + y) * w + x];
        for (c, y) in [(0, 0), (1, 31), (2, 63)] {
            assert!((at(c, y, 32) - 0.967472).abs() < 1e-4, "{}", at(c, y, 32));
            assert!(at(c, y, 48).abs() < 1e-4 && at(c, y, 5).abs() < 1e-4);
        }
    }
}
