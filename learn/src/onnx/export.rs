//! The actor of SPEC §8 as an ONNX graph with Unity ML-Agents' (2.x) interface.
//!
//! Inputs: `obs_0` — the stacked grid `[batch, 18, 20, 34]`; `obs_1` — the vector
//! observation `[batch, 6]`; `batch` is a dynamic axis. Outputs:
//! * `version_number` `[1]` = 3, `memory_size` `[1]` = 0,
//!   `continuous_action_output_shape` `[1]` = 3 — float constants (initializers,
//!   passed through Identity nodes), as ML-Agents' exporter writes them;
//! * `continuous_actions` `[batch, 3]` — sampled: `clip(μ + σ·ε, −1, 1)` (PPO)
//!   or `tanh(μ + σ(s)·ε)` (SAC), ε from `RandomNormalLike`;
//! * `deterministic_continuous_actions` `[batch, 3]` — `clip(μ, −1, 1)` (PPO)
//!   or `tanh(μ)` (SAC).
//!
//! Opset 9: what ML-Agents exports and Unity's Barracuda loads (Sentis reads
//! opsets 7–15). Swish is `x · sigmoid(x)`; Burn's `Linear` weights are
//! `[in, out]`, so `Gemm` takes them untransposed; convolution weights are
//! `[out, in, kh, kw]` in both. The first convolution pads the azimuth axis
//! with one zero column on each side (`pads` `[0, 1, 0, 1]`): the network's
//! blind sector behind, as in Burn (see `crate::kernels::geometry`); the
//! input stays `[batch, 18, 20, 34]`. Metadata: species, scene, algorithm,
//! training step, behaviour and the observation and action layouts.

use super::build::{float, int, ints, node, tensor, value_info};
use super::proto::*;
use crate::body::{ACTIONS, Body};
use crate::kernels::geometry::{AZ_PAD, K1, K2, S1, S2};
use burn::nn::Linear;
use burn::nn::conv::Conv2d;
use burn::prelude::*;
use deepfoids_sensors::{AZ_CELLS, EL_CELLS, STACKED_CHANNELS};

/// The ONNX operator set the graph uses.
pub const OPSET: i64 = 9;
/// IR version matching opset 9 (ONNX 1.4).
pub const IR_VERSION: i64 = 4;
/// ML-Agents' `MODEL_EXPORT_VERSION`.
pub const MODEL_EXPORT_VERSION: f32 = 3.0;

/// What the file says about the policy.
#[derive(Clone, Debug, Default)]
pub struct Metadata {
    pub species: String,
    pub behaviour: String,
    pub scene: String,
    pub algorithm: String,
    pub training_step: u64,
    pub run: String,
    /// The reward profile the run trained under (recorded as
    /// `reward_profile` when known): its `heading_of` and action timing
    /// complete the layouts.
    pub reward_profile: Option<String>,
}

/// The observation layout recorded in the file.
pub const OBSERVATION_LAYOUT: &str = "obs_0: [batch, 18, 20, 34] (C, H, W): 3 stacked frames, oldest first, of 6 channels [proximity = 1 - distance/d_sense, fish, net, water surface, obstacle, chase partner] over 20 elevation rows (+90° to -90°, 9° each) x 34 azimuth columns (-170° to +170°, 10° each, positive to the fish's right); obs_1: [batch, 6] = [u_x, u_y, u_z (own forward minus a neighbour's forward, local frame: +x left, +y up, +z forward; the nearest neighbour in front, or what the reward profile's heading_of names: the closing neighbour, or the mean heading of the neighbours r_ND pays for), depth / cage height, aggressor, target]";
/// The action layout recorded in the file.
pub const ACTION_LAYOUT: &str = "[batch, 3] in [-1, 1]: [speed change, pitch change (positive: nose down), yaw change (positive: towards local +x, the fish's left)]; under the reward profile's per_step action timing (SPEC §4, the default) held at every physics step of the decision: speed by a x the species' max_delta_speed_bl BL/s per second (coho 4.1), pitch and yaw by a x timing.turn_step_deg (1°) per step; under per_decision timing, speed by a x max_delta_speed_bl BL/s and turns by a x physics.max_turn_deg (20°) per decision";

struct Builder {
    nodes: Vec<NodeProto>,
    init: Vec<TensorProto>,
}

fn values<const D: usize>(t: Tensor<D>) -> (Vec<i64>, Vec<f32>) {
    let dims = t.dims().iter().map(|&d| d as i64).collect();
    (
        dims,
        t.into_data().try_into_vec::<f32>().expect("f32 parameters"),
    )
}

impl Builder {
    fn node(
        &mut self,
        op: &str,
        name: &str,
        inputs: &[&str],
        output: &str,
        attrs: Vec<AttributeProto>,
    ) -> String {
        self.nodes.push(node(op, name, inputs, output, attrs));
        output.to_string()
    }

    fn constant<const D: usize>(&mut self, name: &str, t: Tensor<D>) -> String {
        let (dims, v) = values(t);
        self.init.push(tensor(name, &dims, &v));
        name.to_string()
    }

    fn conv(
        &mut self,
        prefix: &str,
        conv: &Conv2d,
        input: &str,
        kernel: usize,
        stride: usize,
        pad_w: usize,
    ) -> String {
        let w = self.constant(&format!("{prefix}.weight"), conv.weight.val());
        let mut inputs = vec![input.to_string(), w];
        if let Some(b) = &conv.bias {
            inputs.push(self.constant(&format!("{prefix}.bias"), b.val()));
        }
        let refs: Vec<&str> = inputs.iter().map(String::as_str).collect();
        let (k, s, p) = (kernel as i64, stride as i64, pad_w as i64);
        // pads: [top, left, bottom, right]
        let attrs = vec![
            ints("kernel_shape", &[k, k]),
            ints("strides", &[s, s]),
            ints("pads", &[0, p, 0, p]),
            int("group", 1),
        ];
        self.node("Conv", prefix, &refs, &format!("{prefix}.out"), attrs)
    }

    fn gemm(&mut self, prefix: &str, linear: &Linear, input: &str) -> String {
        let w = self.constant(&format!("{prefix}.weight"), linear.weight.val());
        let b = match &linear.bias {
            Some(b) => self.constant(&format!("{prefix}.bias"), b.val()),
            None => {
                let [_, out] = linear.weight.val().dims();
                self.init.push(tensor(
                    &format!("{prefix}.bias"),
                    &[out as i64],
                    &vec![0.0; out],
                ));
                format!("{prefix}.bias")
            }
        };
        let attrs = vec![float("alpha", 1.0), float("beta", 1.0)];
        self.node(
            "Gemm",
            prefix,
            &[input, &w, &b],
            &format!("{prefix}.out"),
            attrs,
        )
    }

    /// `mean + std · ε`, ε ~ N(0, 1) of `mean`'s shape.
    fn sample(&mut self, mean: &str, std: &str) -> String {
        // tract picks the distribution from the node's name: it must start with
        // "RandomNormal" and end with "Like".
        let eps = self.node(
            "RandomNormalLike",
            "RandomNormalLike",
            &[mean],
            "epsilon",
            vec![float("mean", 0.0), float("scale", 1.0)],
        );
        let noise = self.node("Mul", "noise", &[&eps, std], "noise.out", vec![]);
        self.node("Add", "sample", &[mean, &noise], "sample.out", vec![])
    }

    fn leaky(&mut self, prefix: &str, input: &str, alpha: f32) -> String {
        self.node(
            "LeakyRelu",
            prefix,
            &[input],
            &format!("{prefix}.out"),
            vec![float("alpha", alpha)],
        )
    }
}

/// The action head of an actor.
pub enum Head<'a> {
    /// PPO: a Gaussian with a state-independent log-std; actions are clipped
    /// to [−1, 1]: deterministic `clip(μ)`, sampled `clip(μ + σ·ε)`.
    Gaussian {
        mean: &'a Linear,
        log_std: &'a Tensor<1>,
    },
    /// SAC: a tanh-squashed Gaussian whose log-std is a head of its own,
    /// `lo + (hi − lo)·(tanh(x) + 1)/2`: deterministic `tanh(μ)`, sampled
    /// `tanh(μ + σ·ε)`.
    Squashed {
        mean: &'a Linear,
        log_std: &'a Linear,
        bounds: [f32; 2],
    },
}

/// An actor (body and head) as an ONNX model (protobuf bytes): the encoder
/// and trunk, the head's two action outputs, ML-Agents' constants, then the
/// graph's inputs and outputs and the model's metadata.
pub fn export_policy(body: &Body, head: Head<'_>, meta: &Metadata) -> Vec<u8> {
    let mut b = Builder {
        nodes: vec![],
        init: vec![],
    };
    let x = b.body(body);
    match head {
        Head::Gaussian { mean, log_std } => b.gaussian_head(&x, mean, log_std),
        Head::Squashed {
            mean,
            log_std,
            bounds,
        } => b.squashed_head(&x, mean, log_std, bounds),
    }
    b.ml_agents_constants();
    model(graph(b, meta), meta).to_bytes()
}

fn clip(lo: f32, hi: f32) -> Vec<AttributeProto> {
    vec![float("min", lo), float("max", hi)]
}

impl Builder {
    /// The encoder (two convolutions, the azimuth padded in the first), the
    /// grid's dense layer, the vector observation concatenated, and the
    /// Swish trunk; returns the trunk's output.
    fn body(&mut self, body: &Body) -> String {
        let b = self;
        let slope = body.slope() as f32;
        let x = b.conv("conv1", &body.conv1, "obs_0", K1, S1, AZ_PAD);
        let x = b.leaky("conv1.act", &x, slope);
        let x = b.conv("conv2", &body.conv2, &x, K2, S2, 0);
        let x = b.leaky("conv2.act", &x, slope);
        let x = b.node(
            "Flatten",
            "flatten",
            &[&x],
            "flatten.out",
            vec![int("axis", 1)],
        );
        let x = b.gemm("fc_grid", &body.fc_grid, &x);
        let x = b.leaky("fc_grid.act", &x, slope);
        let mut x = b.node(
            "Concat",
            "concat",
            &[&x, "obs_1"],
            "concat.out",
            vec![int("axis", 1)],
        );
        for (k, layer) in body.trunk.iter().enumerate() {
            let z = b.gemm(&format!("trunk.{k}"), layer, &x);
            let s = b.node(
                "Sigmoid",
                &format!("trunk.{k}.sigmoid"),
                &[&z],
                &format!("trunk.{k}.sigmoid.out"),
                vec![],
            );
            x = b.node(
                "Mul",
                &format!("trunk.{k}.swish"),
                &[&z, &s],
                &format!("trunk.{k}.swish.out"),
                vec![],
            );
        }
        x
    }

    /// PPO's head: `clip(μ)` and `clip(μ + σ·ε)`, σ from a state-independent log-std.
    fn gaussian_head(&mut self, x: &str, mean: &Linear, log_std: &Tensor<1>) {
        let b = self;
        let mean = b.gemm("actor_mean", mean, x);
        b.node(
            "Clip",
            "deterministic",
            &[&mean],
            "deterministic_continuous_actions",
            clip(-1.0, 1.0),
        );
        let log_std = b.constant("log_std", log_std.clone());
        let std = b.node("Exp", "std", &[&log_std], "std.out", vec![]);
        let sample = b.sample(&mean, &std);
        b.node(
            "Clip",
            "sampled",
            &[&sample],
            "continuous_actions",
            clip(-1.0, 1.0),
        );
    }

    /// SAC's head: `tanh(μ)` and `tanh(μ + σ(s)·ε)`, the log-std squashed
    /// into `bounds`.
    fn squashed_head(&mut self, x: &str, mean: &Linear, log_std: &Linear, [lo, hi]: [f32; 2]) {
        let b = self;
        let mean = b.gemm("actor_mean", mean, x);
        b.node(
            "Tanh",
            "deterministic",
            &[&mean],
            "deterministic_continuous_actions",
            vec![],
        );
        let raw = b.gemm("actor_log_std", log_std, x);
        let t = b.node("Tanh", "log_std.tanh", &[&raw], "log_std.tanh.out", vec![]);
        let mut scalar = |name: &str, v: f32| {
            b.init.push(tensor(name, &[1], &[v]));
            name.to_string()
        };
        let (one, half_range, low) = (
            scalar("log_std.one", 1.0),
            scalar("log_std.half_range", 0.5 * (hi - lo)),
            scalar("log_std.low", lo),
        );
        let t1 = b.node(
            "Add",
            "log_std.shift",
            &[&t, &one],
            "log_std.shift.out",
            vec![],
        );
        let t2 = b.node(
            "Mul",
            "log_std.scale",
            &[&t1, &half_range],
            "log_std.scale.out",
            vec![],
        );
        let log_std = b.node("Add", "log_std", &[&t2, &low], "log_std.out", vec![]);
        let std = b.node("Exp", "std", &[&log_std], "std.out", vec![]);
        let sample = b.sample(&mean, &std);
        b.node("Tanh", "sampled", &[&sample], "continuous_actions", vec![]);
    }

    /// ML-Agents' constant outputs: float initializers passed through
    /// Identity nodes.
    fn ml_agents_constants(&mut self) {
        let b = self;
        for (name, value) in [
            ("version_number", MODEL_EXPORT_VERSION),
            ("memory_size", 0.0),
            ("continuous_action_output_shape", ACTIONS as f32),
        ] {
            b.init
                .push(tensor(&format!("{name}.value"), &[1], &[value]));
            b.node("Identity", name, &[&format!("{name}.value")], name, vec![]);
        }
    }
}

/// The graph: the builder's nodes and initializers, the inputs (`batch` a
/// dynamic axis) and ML-Agents' outputs.
fn graph(b: Builder, meta: &Metadata) -> GraphProto {
    let batch = Err("batch");
    GraphProto {
        node: b.nodes,
        name: format!("deepfoids_{}", meta.behaviour),
        initializer: b.init,
        doc_string:
            "DeepFoids actor (SPEC §8): simple visual encoder (azimuth padded by one zero column each side), 4 x 128 Swish, Gaussian head (PPO) or tanh-squashed Gaussian head (SAC)".into(),
        input: vec![
            value_info(
                "obs_0",
                &[
                    batch,
                    Ok(STACKED_CHANNELS as i64),
                    Ok(EL_CELLS as i64),
                    Ok(AZ_CELLS as i64),
                ],
            ),
            value_info("obs_1", &[batch, Ok(deepfoids_env::VECTOR_OBS as i64)]),
        ],
        output: vec![
            value_info("version_number", &[Ok(1)]),
            value_info("memory_size", &[Ok(1)]),
            value_info("continuous_actions", &[batch, Ok(ACTIONS as i64)]),
            value_info("continuous_action_output_shape", &[Ok(1)]),
            value_info(
                "deterministic_continuous_actions",
                &[batch, Ok(ACTIONS as i64)],
            ),
        ],
    }
}

/// The model: producer, opset and the metadata (layouts included).
fn model(graph: GraphProto, meta: &Metadata) -> ModelProto {
    let props = [
        ("species", meta.species.clone()),
        ("behaviour", meta.behaviour.clone()),
        ("scene", meta.scene.clone()),
        ("algorithm", meta.algorithm.clone()),
        ("training_step", meta.training_step.to_string()),
        ("run", meta.run.clone()),
        ("observation_layout", OBSERVATION_LAYOUT.to_string()),
        ("action_layout", ACTION_LAYOUT.to_string()),
    ];
    let profile = meta
        .reward_profile
        .as_ref()
        .map(|p| ("reward_profile", p.clone()));
    super::build::model(
        graph,
        IR_VERSION,
        OPSET,
        format!(
            "{} policy for {} ({}), step {}",
            meta.algorithm, meta.behaviour, meta.scene, meta.training_step
        ),
        props
            .into_iter()
            .chain(profile)
            .map(|(k, v)| (k.to_string(), v))
            .collect(),
    )
}
