//! The detector formats through tract: a YOLOv8-style output decoded from a
//! tiny ONNX the test writes itself, clear errors for files that are not
//! detectors, and our exported network against Burn's forward (parity).

use burn::prelude::*;
use deepfoids_count::count::{CountConfig, Counter};
use deepfoids_count::detector::{Detector, DetectorFormat, to_chw};
use deepfoids_count::export::export_detector;
use deepfoids_count::model::{DetectorNet, DetectorNetConfig, NORM_EPS, NORM_KERNEL};
use deepfoids_count::{CountError, InputCamera};
use deepfoids_learn::onnx::build::{self, ints, tensor, value_info};
use deepfoids_learn::onnx::proto::*;
use std::path::PathBuf;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("deepfoids-count-onnx-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn info(name: &str, dims: &[i64]) -> ValueInfoProto {
    let dims: Vec<Result<i64, &str>> = dims.iter().map(|&d| Ok(d)).collect();
    value_info(name, &dims)
}

/// Node `op` named after its output.
fn node(op: &str, inputs: &[&str], output: &str, attribute: Vec<AttributeProto>) -> NodeProto {
    build::node(op, output, inputs, output, attribute)
}

/// A YOLOv8-shaped model: `images` [1, 3, 32, 32] → Conv (zero weights,
/// 32 × 8 kernel and stride) [1, 5, 1, 4] → Squeeze axis 2 → [1, 5, 4] →
/// plus the constant `table` (4 box rows + 1 class row, 4 anchors).
fn yolo_like(table: &[f32], out_dims: &[i64]) -> Vec<u8> {
    let graph = GraphProto {
        node: vec![
            node(
                "Conv",
                &["images", "w"],
                "conv",
                vec![ints("kernel_shape", &[32, 8]), ints("strides", &[32, 8])],
            ),
            node("Squeeze", &["conv"], "squeezed", vec![ints("axes", &[2])]),
            node("Add", &["squeezed", "table"], "output0", vec![]),
        ],
        name: "yolo_like".into(),
        initializer: vec![
            tensor("w", &[5, 3, 32, 8], &vec![0.0; 5 * 3 * 32 * 8]),
            tensor("table", &[1, 5, 4], table),
        ],
        doc_string: String::new(),
        input: vec![info("images", &[1, 3, 32, 32])],
        output: vec![info("output0", out_dims)],
    };
    ModelProto {
        ir_version: 7,
        producer_name: "test".into(),
        graph: Some(graph),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: 11,
        }],
        ..Default::default()
    }
    .to_bytes()
}

/// Anchors: (8, 8, 6 × 4, 0.9), (9, 8, 6 × 4, 0.7) overlapping the first by
/// IoU 5/7 (NMS drops it), (24, 20, 8 × 8, 0.6), (4, 28, 2 × 2, 0.3 < 0.5).
#[rustfmt::skip]
const TABLE: [f32; 20] = [
    8.0, 9.0, 24.0, 4.0,  // cx
    8.0, 8.0, 20.0, 28.0, // cy
    6.0, 6.0, 8.0, 2.0,   // w
    4.0, 4.0, 8.0, 2.0,   // h
    0.9, 0.7, 0.6, 0.3,   // fish
];

fn pinhole(window: u32) -> CountConfig {
    CountConfig {
        camera: InputCamera::Pinhole,
        median: 1,
        window,
        step: window / 2,
        view_size: 32,
        ..CountConfig::default()
    }
}

#[test]
fn yolov8_output_is_decoded_through_tract() {
    let p = tmp("yolo.onnx");
    std::fs::write(&p, yolo_like(&TABLE, &[1, 5, 4])).unwrap();
    let det = Detector::load(&p, 416).unwrap();
    assert_eq!(det.format, DetectorFormat::YoloV8 { classes: 1 });
    assert_eq!(
        det.input, 32,
        "the model's fixed input wins over the window"
    );
    let raw = det.run_raw(&vec![0.5; 3 * 32 * 32]).unwrap();
    assert_eq!(raw[0], TABLE.to_vec());
    // One 32-px window: boxes as the table says, after NMS and the 0.5 cut.
    let mut c = Counter::new(pinhole(32), det).unwrap();
    let r = c.frame(&image::RgbImage::new(32, 32)).unwrap();
    let got: Vec<[f32; 5]> = r
        .detections
        .iter()
        .map(|d| [d.x0, d.y0, d.x1, d.y1, d.score])
        .collect();
    assert_eq!(
        got,
        vec![[5.0, 6.0, 11.0, 10.0, 0.9], [20.0, 16.0, 28.0, 24.0, 0.6]]
    );
    // A 64-px window is resized to the model's 32: boxes come back doubled.
    let det = Detector::load(&p, 416).unwrap();
    let mut c = Counter::new(pinhole(64), det).unwrap();
    let r = c.frame(&image::RgbImage::new(64, 64)).unwrap();
    assert_eq!(
        [r.detections[0].x0, r.detections[0].y1, r.detections[1].x1],
        [10.0, 20.0, 56.0]
    );
}

#[test]
fn files_that_are_not_detectors_are_named() {
    let p = tmp("not.onnx");
    std::fs::write(&p, b"this is not protobuf at all").unwrap();
    let e = Detector::load(&p, 416).err().unwrap();
    assert!(matches!(e, CountError::NotOnnxFile { .. }), "{e}");
    // Issue 25: once "… is not a loadable ONNX model: Reading proto model".
    assert!(
        e.to_string().ends_with(
            "not.onnx is not an ONNX model (it is a text file; an ONNX model is a binary protobuf)"
        ),
        "{e}"
    );
    let e = Detector::load(&tmp("missing.onnx"), 416).err().unwrap();
    assert!(e.to_string().contains("missing.onnx") && e.to_string().contains("does not exist"));
    // Rank 2 output: neither format.
    let p = tmp("wrong.onnx");
    let graph = GraphProto {
        node: vec![node("Flatten", &["images"], "flat", vec![])],
        name: "flat".into(),
        input: vec![info("images", &[1, 3, 32, 32])],
        output: vec![info("flat", &[1, 3072])],
        ..Default::default()
    };
    let model = ModelProto {
        ir_version: 7,
        graph: Some(graph),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: 11,
        }],
        ..Default::default()
    };
    std::fs::write(&p, model.to_bytes()).unwrap();
    let e = Detector::load(&p, 416).err().unwrap();
    assert!(matches!(e, CountError::WrongOutputs { .. }), "{e}");
    assert!(e.to_string().contains("[1, 3072]"), "{e}");
}

/// Our exported network through tract against Burn's forward: heatmap =
/// sigmoid(heat logits) and boxes within 1e-4 on a random 64 × 64 input,
/// with a guard that the outputs are not all zero. Both as exported (the
/// graph's own local contrast) and as `count` loads it (the graph's cut off,
/// the running-sum `local_contrast` fed instead).
#[test]
fn our_export_matches_burn() {
    for (stride, wide) in [(8, false), (4, false), (8, true)] {
        export_matches_burn(stride, wide);
    }
}

fn export_matches_burn(stride: usize, wide: bool) {
    let dev = Device::flex();
    let net = DetectorNetConfig::new()
        .with_base(4)
        .with_stride(stride)
        .with_wide(wide)
        .init(&dev);
    assert_eq!(net.body.len(), if wide { 8 } else { 7 });
    assert_eq!(net.stride(), stride);
    let p = tmp(&format!("ours-{stride}-{wide}.onnx"));
    std::fs::write(&p, export_detector(&net, &[])).unwrap();
    let img = image::RgbImage::from_fn(64, 64, |x, y| {
        image::Rgb([(x * 4) as u8, (y * 4) as u8, ((x * 7 + y * 13) % 256) as u8])
    });
    let chw = to_chw(&img);
    let whole = Detector::load_as_exported(&p, 64).unwrap();
    assert_eq!(
        whole.format,
        DetectorFormat::Ours {
            stride: stride as u32
        }
    );
    assert_eq!(whole.cuts_local_contrast, None);
    let cut = Detector::load(&p, 64).unwrap();
    assert_eq!(cut.cuts_local_contrast, Some((NORM_KERNEL, NORM_EPS)));
    let cut_input = cut.input_of(&img);
    assert!(cut_input != chw, "the cut graph takes the local contrast");
    for tract in [
        whole.run_raw(&chw).unwrap(),
        cut.run_raw(&cut_input).unwrap(),
    ] {
        check_against_burn(&net, &chw, &tract, stride);
    }
}

fn check_against_burn(net: &DetectorNet, chw: &[f32], tract: &[Vec<f32>], stride: usize) {
    let dev = Device::flex();
    let chw = chw.to_vec();
    let x = Tensor::<4>::from_data(TensorData::new(chw, [1, 3, 64, 64]), &dev);
    let (heat, boxes) = net.forward(x);
    let heat: Vec<f32> = burn::tensor::activation::sigmoid(heat)
        .into_data()
        .try_into_vec()
        .unwrap();
    let boxes: Vec<f32> = boxes.into_data().try_into_vec().unwrap();
    let cells = (64 / stride) * (64 / stride);
    assert_eq!((tract[0].len(), tract[1].len()), (cells, 4 * cells));
    let max_diff = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f32::max)
    };
    assert!(
        max_diff(&tract[0], &heat) <= 1e-4,
        "{}",
        max_diff(&tract[0], &heat)
    );
    assert!(
        max_diff(&tract[1], &boxes) <= 1e-4,
        "{}",
        max_diff(&tract[1], &boxes)
    );
    assert!(
        boxes.iter().any(|v| v.abs() > 1e-3),
        "all-zero outputs prove nothing"
    );
    let spread =
        heat.iter().fold(0f32, |m, v| m.max(*v)) - heat.iter().fold(1f32, |m, v| m.min(*v));
    assert!(spread > 1e-4, "a constant heatmap proves little");
}
