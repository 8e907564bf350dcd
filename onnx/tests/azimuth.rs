//! Issue 11 item 2, in the exported file: the ONNX actor's first convolution
//! pads the azimuth axis as the network does, and a fish in the rightmost
//! azimuth column — the one the stock encoder never saw — changes the actions
//! tract computes from the file.

use burn::prelude::*;
use deepfoids_env::VECTOR_OBS;
use deepfoids_learn::kernels::geometry::AZ_PAD;
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

#[test]
fn the_onnx_actor_pads_the_azimuth_and_sees_the_rightmost_column() {
    let dev = Device::flex();
    let mut model = ActorCriticConfig::new().init(&dev);
    // The mean head starts near zero (× 0.01): give it weight so changes show.
    model.actor_mean.weight = burn::module::Param::from_tensor(Tensor::random(
        [128, 3],
        burn::tensor::Distribution::Uniform(-0.5, 0.5),
        &dev,
    ));
    let bytes = PpoActor::new(model).onnx(&Metadata {
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
    let diff = empty
        .iter()
        .zip(&right)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    // A column outside every receptive field leaves the output bit-for-bit
    // unchanged; f32 rounding alone moves it by ~1e−8.
    assert!(
        diff > 1e-6,
        "column {}: the exported actor is blind ({empty:?} vs {right:?})",
        AZ_CELLS - 1
    );
}
