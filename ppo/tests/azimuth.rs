//! Issue 11 item 2: the network sees the whole sensor. A fish placed in any
//! of the 34 azimuth columns changes the actor's output — on the kernels, on
//! Burn's layers and in the exported ONNX's layout; the stock encoder (no
//! azimuth padding) was blind to columns 28–33.

use burn::module::Param;
use burn::nn::conv::Conv2dConfig;
use burn::prelude::*;
use deepfoids_env::VECTOR_OBS;
use deepfoids_learn::policy::Actor;
use deepfoids_learn::tensor::{tensor4, to_vec};
use deepfoids_ppo::PpoActor;
use deepfoids_ppo::model::ActorCriticConfig;
use deepfoids_sensors::{AZ_CELLS, CELLS, FRAME_LEN, STACK, STACKED_LEN};

/// A stacked grid with one fish (proximity 0.9, fish channel) filling rows
/// 8–11 of azimuth column `col` in all three frames; `None`: empty.
fn grid_with_fish(col: Option<usize>) -> Vec<f32> {
    let mut g = vec![0.0f32; STACKED_LEN];
    if let Some(col) = col {
        for f in 0..STACK {
            for row in 8..12 {
                let cell = row * AZ_CELLS + col;
                g[f * FRAME_LEN + cell] = 0.9;
                g[f * FRAME_LEN + CELLS + cell] = 1.0;
            }
        }
    }
    g
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn a_fish_in_every_azimuth_column_changes_the_actors_output() {
    let dev = Device::flex();
    let mut model = ActorCriticConfig::new().init(&dev);
    // The mean head starts near zero (× 0.01): give it weight so changes show.
    model.actor_mean.weight = Param::from_tensor(Tensor::random(
        [128, 3],
        burn::tensor::Distribution::Uniform(-0.5, 0.5),
        &dev,
    ));
    let actor = PpoActor::new(model);
    let vectors = vec![0.1f32; VECTOR_OBS];
    let empty = grid_with_fish(None);
    let (base, base_ref) = (
        actor.deterministic(&empty, &vectors),
        actor.deterministic_reference(&empty, &vectors),
    );
    for col in 0..AZ_CELLS {
        let g = grid_with_fish(Some(col));
        let (k, r) = (
            actor.deterministic(&g, &vectors),
            actor.deterministic_reference(&g, &vectors),
        );
        // A column outside every receptive field leaves the output bit-for-bit
        // unchanged; f32 rounding alone moves it by ~1e−8.
        assert!(
            max_diff(&k, &base) > 1e-6,
            "column {col}: kernels blind ({k:?} vs {base:?})"
        );
        assert!(
            max_diff(&r, &base_ref) > 1e-6,
            "column {col}: Burn layers blind"
        );
    }
}

/// The stock encoder (Conv 8×8 stride 4 on 34 columns, no padding): columns
/// 28–33 never reach the output — the bug the padding fixes.
#[test]
fn the_stock_encoder_was_blind_on_the_right() {
    let dev = Device::flex();
    let conv1 = Conv2dConfig::new([18, 16], [8, 8])
        .with_stride([4, 4])
        .init(&dev);
    let conv2 = Conv2dConfig::new([16, 32], [4, 4])
        .with_stride([2, 2])
        .init(&dev);
    let encode = |g: Vec<f32>| {
        let x = tensor4(g, 1, &dev);
        to_vec(conv2.forward(conv1.forward(x)))
    };
    let base = encode(grid_with_fish(None));
    let seen: Vec<bool> = (0..AZ_CELLS)
        .map(|col| max_diff(&encode(grid_with_fish(Some(col))), &base) > 0.0)
        .collect();
    assert!(seen[..28].iter().all(|&s| s));
    assert!(seen[28..].iter().all(|&s| !s), "{seen:?}");
}
