//! Our detector ([`crate::model`]) as an ONNX graph, written with the
//! project's own protobuf messages (`deepfoids_learn::onnx::proto`).
//!
//! Input `image` `[1, 3, height, width]` (height and width symbolic: the net
//! is fully convolutional); outputs `heatmap` = Sigmoid(heat head) and
//! `boxes`. Opset 13: the local contrast of [`crate::model::local_contrast`]
//! (AveragePool, Mul, Sub, Relu, Add, Sqrt, Div), Conv (with `dilations`),
//! LeakyRelu, Sigmoid. Burn's
//! and ONNX's convolution weights are both `[out, in, kh, kw]`.
//! Metadata: `format` = `deepfoids-centernet`, `stride`, the training's
//! view (`view_fov_deg`, `view_size`, `window`) and whatever the caller adds
//! (data, budget, metrics).

use crate::model::{DetectorNet, NORM_EPS, NORM_KERNEL, SLOPE};
use burn::nn::conv::Conv2d;
use burn::prelude::*;
use deepfoids_learn::onnx::build::{float, int, ints, model, node, tensor, value_info};
use deepfoids_learn::onnx::proto::*;

pub const OPSET: i64 = 13;
pub const IR_VERSION: i64 = 7;
/// The `format` metadata of our detectors.
pub const FORMAT: &str = "deepfoids-centernet";

fn values<const D: usize>(t: Tensor<D>) -> (Vec<i64>, Vec<u8>) {
    let dims = t.dims().iter().map(|&d| d as i64).collect();
    let v = t.into_data().try_into_vec::<f32>().expect("f32 parameters");
    (dims, v.iter().flat_map(|x| x.to_le_bytes()).collect())
}

struct Graph {
    nodes: Vec<NodeProto>,
    init: Vec<TensorProto>,
}

impl Graph {
    fn constant<const D: usize>(&mut self, name: &str, t: Tensor<D>) -> String {
        let (dims, raw_data) = values(t);
        self.init.push(TensorProto {
            dims,
            data_type: data_type::FLOAT,
            name: name.into(),
            raw_data,
        });
        name.into()
    }

    fn op(&mut self, op: &str, inputs: &[&str], output: &str) {
        self.nodes.push(node(op, output, inputs, output, vec![]));
    }

    /// `(x − m) / √(v + ε²)` with the local mean `m` and variance `v`
    /// ([`crate::model::local_contrast`]); returns the output's name.
    fn local_contrast(&mut self, x: &str) -> String {
        let (k, p) = (NORM_KERNEL as i64, (NORM_KERNEL / 2) as i64);
        // A column pass, then a row pass (as the model does).
        let pool = |g: &mut Self, input: &str, output: &str| {
            let column = format!("{output}.columns");
            for (from, to, kernel, pads) in [
                (input, column.as_str(), [k, 1], [p, 0, p, 0]),
                (column.as_str(), output, [1, k], [0, p, 0, p]),
            ] {
                g.nodes.push(node(
                    "AveragePool",
                    to,
                    &[from],
                    to,
                    vec![
                        ints("kernel_shape", &kernel),
                        ints("strides", &[1, 1]),
                        ints("pads", &pads),
                        int("count_include_pad", 0),
                    ],
                ));
            }
        };
        pool(self, x, "norm.mean");
        self.op("Mul", &[x, x], "norm.square");
        pool(self, "norm.square", "norm.mean_square");
        self.op("Mul", &["norm.mean", "norm.mean"], "norm.mean2");
        self.op("Sub", &["norm.mean_square", "norm.mean2"], "norm.var_raw");
        self.op("Relu", &["norm.var_raw"], "norm.var");
        self.init
            .push(tensor("norm.eps2", &[], &[NORM_EPS * NORM_EPS]));
        self.op("Add", &["norm.var", "norm.eps2"], "norm.var_eps");
        self.op("Sqrt", &["norm.var_eps"], "norm.std");
        self.op("Sub", &[x, "norm.mean"], "norm.centred");
        self.op("Div", &["norm.centred", "norm.std"], "norm.out");
        "norm.out".into()
    }

    fn conv(
        &mut self,
        name: &str,
        conv: &Conv2d,
        input: &str,
        output: &str,
        stride: usize,
        dilation: usize,
    ) {
        let w = self.constant(&format!("{name}.weight"), conv.weight.val());
        let mut inputs = vec![input.to_string(), w];
        if let Some(b) = &conv.bias {
            inputs.push(self.constant(&format!("{name}.bias"), b.val()));
        }
        let [_, _, k, _] = conv.weight.dims();
        let pad = (dilation * (k / 2)) as i64;
        let refs: Vec<&str> = inputs.iter().map(String::as_str).collect();
        let (s, d, k) = (stride as i64, dilation as i64, k as i64);
        self.nodes.push(node(
            "Conv",
            name,
            &refs,
            output,
            vec![
                ints("kernel_shape", &[k, k]),
                ints("strides", &[s, s]),
                ints("dilations", &[d, d]),
                ints("pads", &[pad, pad, pad, pad]),
            ],
        ));
    }
}

/// The network as ONNX bytes, with `metadata` added to the file's properties.
pub fn export_detector(net: &DetectorNet, metadata: &[(String, String)]) -> Vec<u8> {
    let mut g = Graph {
        nodes: vec![],
        init: vec![],
    };
    let mut x = g.local_contrast("image");
    let stride = net.stride();
    for (i, conv) in net.body.iter().enumerate() {
        let name = format!("body.{i}");
        g.conv(
            &name,
            conv,
            &x,
            &format!("{name}.out"),
            conv.stride[0],
            conv.dilation[0],
        );
        let act = format!("{name}.act");
        g.nodes.push(node(
            "LeakyRelu",
            &act,
            &[&format!("{name}.out")],
            &act,
            vec![float("alpha", SLOPE as f32)],
        ));
        x = act;
    }
    g.conv("heat", &net.heat, &x, "heat.logits", 1, 1);
    g.nodes.push(node(
        "Sigmoid",
        "heat.sigmoid",
        &["heat.logits"],
        "heatmap",
        vec![],
    ));
    g.conv("boxes", &net.boxes, &x, "boxes", 1, 1);
    let mut props = vec![
        ("format".to_string(), FORMAT.to_string()),
        ("stride".to_string(), stride.to_string()),
        ("classes".to_string(), "fish".to_string()),
    ];
    props.extend(metadata.iter().cloned());
    let (h, w) = (Err("height"), Err("width"));
    let (gh, gw) = (Err("grid_height"), Err("grid_width"));
    model(
        GraphProto {
            node: g.nodes,
            name: "deepfoids_fish_detector".into(),
            initializer: g.init,
            doc_string: String::new(),
            input: vec![value_info("image", &[Ok(1), Ok(3), h, w])],
            output: vec![
                value_info("heatmap", &[Ok(1), Ok(1), gh, gw]),
                value_info("boxes", &[Ok(1), Ok(4), gh, gw]),
            ],
        },
        IR_VERSION,
        OPSET,
        format!(
            "DeepFoids one-class fish detector (CenterNet-style heatmap and boxes, stride {stride})"
        ),
        props,
    )
    .to_bytes()
}
