//! Our detector ([`crate::model`]) as an ONNX graph, written with the
//! project's own protobuf messages (`deepfoids_learn::onnx::proto`).
//!
//! Input `image` `[1, 3, height, width]` (height and width symbolic: the net
//! is fully convolutional); outputs `heatmap` = Sigmoid(heat head) and
//! `boxes`. Opset 13: Conv (with `dilations`), LeakyRelu, Sigmoid. Burn's
//! and ONNX's convolution weights are both `[out, in, kh, kw]`.
//! Metadata: `format` = `deepfoids-centernet`, `stride`, the training's
//! view (`view_fov_deg`, `view_size`, `window`) and whatever the caller adds
//! (data, budget, metrics).

use crate::model::{DetectorNet, LAYERS, SLOPE, STRIDE};
use burn::nn::conv::Conv2d;
use burn::prelude::*;
use deepfoids_learn::onnx::build::{ints, node, value_info};
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
    let mut x = "image".to_string();
    for (i, (conv, &(_, s, d))) in net.body.iter().zip(LAYERS.iter()).enumerate() {
        let name = format!("body.{i}");
        g.conv(&name, conv, &x, &format!("{name}.out"), s, d);
        let act = format!("{name}.act");
        g.nodes.push(node(
            "LeakyRelu",
            &act,
            &[&format!("{name}.out")],
            &act,
            vec![AttributeProto {
                name: "alpha".into(),
                f: Some(SLOPE as f32),
                r#type: attribute_type::FLOAT,
                ..Default::default()
            }],
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
        ("stride".to_string(), STRIDE.to_string()),
        ("classes".to_string(), "fish".to_string()),
    ];
    props.extend(metadata.iter().cloned());
    let (h, w) = (Err("height"), Err("width"));
    let (gh, gw) = (Err("grid_height"), Err("grid_width"));
    ModelProto {
        ir_version: IR_VERSION,
        producer_name: "deepfoids".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        domain: String::new(),
        model_version: 1,
        doc_string: "DeepFoids one-class fish detector (CenterNet-style heatmap and boxes, stride 8)".into(),
        graph: Some(GraphProto {
            node: g.nodes,
            name: "deepfoids_fish_detector".into(),
            initializer: g.init,
            doc_string: String::new(),
            input: vec![value_info("image", &[Ok(1), Ok(3), h, w])],
            output: vec![
                value_info("heatmap", &[Ok(1), Ok(1), gh, gw]),
                value_info("boxes", &[Ok(1), Ok(4), gh, gw]),
            ],
        }),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: OPSET,
        }],
        metadata_props: props
            .into_iter()
            .map(|(key, value)| StringStringEntryProto { key, value })
            .collect(),
    }
    .to_bytes()
}
