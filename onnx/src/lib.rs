//! Running exported policies: an ONNX policy that drives scenes through tract
//! (pure-Rust ONNX runtime). The exporter itself lives in
//! `deepfoids_learn::onnx` (re-exported here).

pub mod runtime;

pub use deepfoids_learn::onnx::{Head, Metadata, OPSET, export, export_policy, proto};
pub use runtime::{OnnxPolicy, check_species};
