//! The exported file computes what the Burn actor computes: tract's
//! `deterministic_continuous_actions` equal the Burn actor's clipped mean on 64
//! random observations, at batch 1 and batch 64 (max abs difference ≤ 1e−4).
//! The observations, the expected actions and the file are also left in
//! `target/onnx-check/` for `.ci/check_onnx.py` (onnx checker and onnxruntime).

use burn::prelude::*;
use deepfoids_env::{GridsRef, VECTOR_OBS};
use deepfoids_learn::policy::Actor;
use deepfoids_learn::{BodyConfig, Grids};
use deepfoids_onnx::{Metadata, OnnxPolicy};
use deepfoids_ppo::PpoActor;
use deepfoids_ppo::model::ActorCriticConfig;
use deepfoids_sensors::STACKED_LEN;
use std::path::PathBuf;

fn observations(n: usize, seed: u64) -> (Vec<f32>, Vec<f32>) {
    let mut s = deepfoids_env::rng::Stream::new(seed, deepfoids_env::rng::Purpose::Policy, 0, 0);
    // Grid values like the sensor's: mostly zeros, proximities in [0, 1), one-hot types.
    let grids: Vec<f32> = (0..n * STACKED_LEN)
        .map(|_| if s.uniform() < 0.3 { s.uniform() } else { 0.0 })
        .collect();
    let vectors: Vec<f32> = (0..n * VECTOR_OBS).map(|_| s.range(-1.5, 1.5)).collect();
    (grids, vectors)
}

/// `n` observations from `seed` as flat buffers and as the actor's tensors.
fn observation_tensors(
    n: usize,
    seed: u64,
    dev: &Device,
) -> (Vec<f32>, Vec<f32>, Tensor<4>, Tensor<2>) {
    let (grids, vectors) = observations(n, seed);
    let g = Tensor::<4>::from_data(TensorData::new(grids.clone(), [n, 18, 20, 34]), dev);
    let v = Tensor::<2>::from_data(TensorData::new(vectors.clone(), [n, VECTOR_OBS]), dev);
    (grids, vectors, g, v)
}

/// Scale a head's weights so that the largest `|μ|` over a batch, now
/// `biggest`, becomes 0.8: the body's initial features differ between draws
/// (tests seeding the shared device run in parallel) and small ones made the
/// actions near zero, which these tests cannot check.
fn rescale(weight: &mut burn::module::Param<Tensor<2>>, biggest: f32) {
    assert!(biggest > 0.0, "a body with no output");
    *weight = burn::module::Param::from_tensor(weight.val() * (0.8 / biggest));
}

fn largest(t: Tensor<2>) -> f32 {
    t.abs().max().into_scalar()
}

/// Head weights `[128, 3]` uniform in ±`lim`.
fn uniform(lim: f64, dev: &Device) -> burn::module::Param<Tensor<2>> {
    burn::module::Param::from_tensor(Tensor::<2>::random(
        [128, 3],
        burn::tensor::Distribution::Uniform(-lim, lim),
        dev,
    ))
}

/// The largest |a − b| over two action vectors.
fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max)
}

/// The metadata of a seabream test policy trained by `algorithm`.
fn seabream_meta(algorithm: &str, training_step: u64) -> Metadata {
    Metadata {
        species: "seabream".into(),
        behaviour: "seabream_regular".into(),
        scene: "seabream_default".into(),
        algorithm: algorithm.into(),
        training_step,
        run: "test".into(),
        reward_profile: Some("thesis".into()),
    }
}

#[test]
fn tract_matches_the_burn_actor() {
    for kernels in [true, false] {
        let dev = Device::flex();
        dev.seed(11);
        let cfg = ActorCriticConfig::new()
            .with_body(BodyConfig::new().with_kernels(kernels))
            .with_init_log_std(-0.7);
        let mut model = cfg.init(&dev);
        // Give the mean head real weight (it starts near zero) so the test exercises it.
        model.actor_mean.weight = uniform(0.5, &dev);
        let n = 64;
        let (grids, vectors, g, v) = observation_tensors(n, 3, &dev);
        let grid = Grids::Dense(g);
        let biggest = largest(model.actor(&grid, v.clone()).0);
        rescale(&mut model.actor_mean.weight, biggest);
        let meta = seabream_meta("ppo", 12345);
        let (mean, _) = model.actor(&grid, v);
        let actor = PpoActor::new(model);
        let bytes = actor.onnx(&meta);
        let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../target/onnx-check"));
        std::fs::create_dir_all(&dir).unwrap();
        // The case for the Python checker is the first model's (the other is a
        // different draw when tests seeding the device run in parallel).
        let path = if kernels {
            dir.join("policy.onnx")
        } else {
            std::env::temp_dir().join(format!("deepfoids-parity-{}.onnx", std::process::id()))
        };
        std::fs::write(&path, &bytes).unwrap();
        let policy = OnnxPolicy::load(&path, false).unwrap();
        assert_eq!(policy.metadata["species"], "seabream");
        assert_eq!(policy.metadata["training_step"], "12345");
        assert_eq!(policy.metadata["reward_profile"], "thesis");

        let expected: Vec<f32> = mean
            .clamp(-1.0, 1.0)
            .into_data()
            .try_into_vec::<f32>()
            .unwrap();
        assert!(
            expected.iter().any(|x| x.abs() > 0.05),
            "the test needs non-trivial actions"
        );
        // Batch 64 at once.
        let got = policy.run(&grids, &vectors, n).unwrap();
        let worst = max_abs_diff(&got, &expected);
        eprintln!("tract vs Burn (kernels: {kernels}): max abs difference {worst:.2e} at batch 64");
        // The fused forward (acting) gives the same actions.
        let fused = actor.deterministic(GridsRef::Dense(&grids), &vectors);
        let worst_fused = max_abs_diff(&fused, &expected);
        assert!(
            worst_fused <= 1e-4,
            "fused forward: max abs difference {worst_fused}"
        );
        assert!(worst <= 1e-4, "batch 64: max abs difference {worst}");
        // Batch 1, one observation at a time.
        for i in 0..n {
            let one = policy
                .run(
                    &grids[i * STACKED_LEN..(i + 1) * STACKED_LEN],
                    &vectors[i * VECTOR_OBS..(i + 1) * VECTOR_OBS],
                    1,
                )
                .unwrap();
            for k in 0..3 {
                assert!(
                    (one[k] - expected[i * 3 + k]).abs() <= 1e-4,
                    "batch 1, sample {i}: {one:?} vs {:?}",
                    &expected[i * 3..i * 3 + 3]
                );
            }
        }
        // The sampled output is within [−1, 1] and differs from the mean.
        let sampled = OnnxPolicy::load(&path, true)
            .unwrap()
            .run(&grids, &vectors, n)
            .unwrap();
        assert!(sampled.iter().all(|x| (-1.0..=1.0).contains(x)));
        assert!(sampled.iter().zip(&got).any(|(a, b)| (a - b).abs() > 1e-3));
        if kernels {
            // Leave the case for the Python checker.
            let bin = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
            std::fs::write(dir.join("obs_0.bin"), bin(&grids)).unwrap();
            std::fs::write(dir.join("obs_1.bin"), bin(&vectors)).unwrap();
            std::fs::write(dir.join("expected.bin"), bin(&expected)).unwrap();
            std::fs::write(dir.join("case.json"), format!("{{\"batch\": {n}}}")).unwrap();
        }
    }
}

/// The SAC actor's export: tract's deterministic actions equal Burn's `tanh(μ)`
/// (max abs difference ≤ 1e−4); sampled actions lie strictly inside (−1, 1) and
/// differ from them. The case is left in `target/onnx-check/sac/` for the Python checker.
#[test]
fn tract_matches_the_sac_actor() {
    use deepfoids_onnx::{Head, export_policy};
    use deepfoids_sac::model::SacNetConfig;
    let dev = Device::flex();
    dev.seed(12);
    let mut actor = SacNetConfig::new().init_actor(&dev);
    // Both heads start small; give them weight so the test exercises them.
    actor.mean.weight = uniform(0.5, &dev);
    actor.log_std.weight = uniform(0.5, &dev);
    let n = 32;
    let (grids, vectors, g, v) = observation_tensors(n, 5, &dev);
    let grid = Grids::Dense(g);
    let biggest = largest(actor.forward(&grid, v.clone()).0);
    rescale(&mut actor.mean.weight, biggest);
    let meta = seabream_meta("sac", 777);
    let bytes = export_policy(
        &actor.body,
        Head::Squashed {
            mean: &actor.mean,
            log_std: &actor.log_std,
            bounds: [-5.0, 2.0],
        },
        &meta,
    );
    let dir = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../target/onnx-check/sac"
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("policy.onnx");
    std::fs::write(&path, &bytes).unwrap();
    let (mean, _) = actor.forward(&grid, v);
    let expected: Vec<f32> = mean.tanh().into_data().try_into_vec::<f32>().unwrap();
    // The fused forward (acting) gives the same actions.
    let fused = deepfoids_sac::SacActor::new(actor.clone())
        .deterministic(GridsRef::Dense(&grids), &vectors);
    let worst_fused = max_abs_diff(&fused, &expected);
    assert!(
        worst_fused <= 1e-4,
        "fused forward: max abs difference {worst_fused}"
    );
    let biggest = expected.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    assert!(
        biggest > 0.05,
        "the test needs non-trivial actions, got at most {biggest}"
    );
    let got = OnnxPolicy::load(&path, false)
        .unwrap()
        .run(&grids, &vectors, n)
        .unwrap();
    let worst = max_abs_diff(&got, &expected);
    assert!(worst <= 1e-4, "max abs difference {worst}");
    let sampled = OnnxPolicy::load(&path, true)
        .unwrap()
        .run(&grids, &vectors, n)
        .unwrap();
    assert!(sampled.iter().all(|x| x.abs() < 1.0));
    assert!(sampled.iter().zip(&got).any(|(a, b)| (a - b).abs() > 1e-3));
    let bin = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    std::fs::write(dir.join("obs_0.bin"), bin(&grids)).unwrap();
    std::fs::write(dir.join("obs_1.bin"), bin(&vectors)).unwrap();
    std::fs::write(dir.join("expected.bin"), bin(&expected)).unwrap();
    std::fs::write(dir.join("case.json"), format!("{{\"batch\": {n}}}")).unwrap();
}
