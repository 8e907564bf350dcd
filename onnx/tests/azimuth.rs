//! Issue 11 item 2: the network sees the whole sensor. A fish placed in any
//! of the 34 azimuth columns changes the actor's output — on the kernels, on
//! Burn's layers and in the exported ONNX run by tract, whose first
//! convolution pads the azimuth axis as the network does; the stock encoder
//! (no azimuth padding) was blind to columns 28–33.

use burn::module::Param;
use burn::prelude::*;
use deepfoids_env::{GridsRef, VECTOR_OBS};
use deepfoids_learn::kernels::geometry::{AZ_PAD, K1, K2, S1, S2};
use deepfoids_learn::policy::Actor;
use deepfoids_onnx::proto::ModelProto;
use deepfoids_onnx::{Metadata, OnnxPolicy};
use deepfoids_ppo::PpoActor;
use deepfoids_ppo::model::ActorCriticConfig;
use deepfoids_sensors::{AZ_CELLS, CELLS, FRAME_LEN, STACK, STACKED_LEN};
use prost::Message;

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

/// A fresh PPO actor whose mean head has weight: it starts near zero
/// (× 0.01), where changes would not show.
fn actor_with_weight(dev: &Device) -> PpoActor {
    let mut model = ActorCriticConfig::new().init(dev);
    model.actor_mean.weight = Param::from_tensor(Tensor::random(
        [128, 3],
        burn::tensor::Distribution::Uniform(-0.5, 0.5),
        dev,
    ));
    PpoActor::new(model)
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
    let actor = actor_with_weight(&dev);
    let vectors = vec![0.1f32; VECTOR_OBS];
    let empty = grid_with_fish(None);
    let (base, base_ref) = (
        actor.deterministic(GridsRef::Dense(&empty), &vectors),
        actor.deterministic_reference(&empty, &vectors),
    );
    for col in 0..AZ_CELLS {
        let g = grid_with_fish(Some(col));
        let (k, r) = (
            actor.deterministic(GridsRef::Dense(&g), &vectors),
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

/// The input columns (of `AZ_CELLS`) that reach the encoder's output when
/// `pad` zero columns are added on each side, through conv 1 (`k1`, stride
/// `s1`) and conv 2 (`k2`, stride `s2`).
fn columns_seen(pad: usize, k1: usize, s1: usize, k2: usize, s2: usize) -> Vec<bool> {
    let width = AZ_CELLS + 2 * pad;
    let w1 = (width - k1) / s1 + 1;
    let w2 = (w1 - k2) / s2 + 1;
    let mut seen = vec![false; AZ_CELLS];
    for o2 in 0..w2 {
        for o1 in o2 * s2..o2 * s2 + k2 {
            for padded in o1 * s1..o1 * s1 + k1 {
                if let Some(col) = padded.checked_sub(pad).filter(|&c| c < AZ_CELLS) {
                    seen[col] = true;
                }
            }
        }
    }
    seen
}

/// The encoder's geometry (`deepfoids_learn::kernels::geometry`) covers every
/// azimuth column; without its padding (the stock encoder: Conv 8×8 stride 4
/// on 34 columns) columns 28–33 never reach the output — the bug the padding
/// fixes.
#[test]
fn the_encoder_geometry_covers_every_azimuth_column() {
    let ours = columns_seen(AZ_PAD, K1, S1, K2, S2);
    assert!(ours.iter().all(|&s| s), "blind columns: {ours:?}");
    let stock = columns_seen(0, K1, S1, K2, S2);
    assert!(stock[..28].iter().all(|&s| s), "{stock:?}");
    assert!(stock[28..].iter().all(|&s| !s), "{stock:?}");
}

#[test]
fn the_onnx_actor_pads_the_azimuth_and_sees_the_rightmost_column() {
    let dev = Device::flex();
    let bytes = actor_with_weight(&dev).onnx(&Metadata {
        species: "coho".into(),
        behaviour: "coho_regular".into(),
        algorithm: "ppo".into(),
        ..Default::default()
    });

    let graph = ModelProto::decode(bytes.as_slice())
        .expect("the export decodes")
        .graph
        .expect("a graph");
    let conv1 = graph
        .node
        .iter()
        .find(|n| n.op_type == "Conv")
        .expect("a Conv node");
    assert_eq!(conv1.input[0], "obs_0", "the first Conv reads the grid");
    let pads = conv1
        .attribute
        .iter()
        .find(|a| a.name == "pads")
        .expect("the first Conv has pads");
    let az = AZ_PAD as i64;
    // ONNX order: [elevation begin, azimuth begin, elevation end, azimuth end].
    assert_eq!(pads.ints, [0, az, 0, az]);

    let path = std::env::temp_dir().join(format!("deepfoids-azimuth-{}.onnx", std::process::id()));
    std::fs::write(&path, &bytes).unwrap();
    let policy = OnnxPolicy::load(&path, false).unwrap();
    std::fs::remove_file(&path).unwrap();
    let vectors = vec![0.1f32; VECTOR_OBS];
    let empty = policy.run(&grid_with_fish(None), &vectors, 1).unwrap();
    let right = policy
        .run(&grid_with_fish(Some(AZ_CELLS - 1)), &vectors, 1)
        .unwrap();
    let diff = max_diff(&empty, &right);
    // A column outside every receptive field leaves the output bit-for-bit
    // unchanged; f32 rounding alone moves it by ~1e−8.
    assert!(
        diff > 1e-6,
        "column {}: the exported actor is blind ({empty:?} vs {right:?})",
        AZ_CELLS - 1
    );
}
