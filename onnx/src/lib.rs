//! Running exported policies: an ONNX policy that drives scenes through tract
//! (pure-Rust ONNX runtime). The exporter itself lives in
//! `deepfoids_learn::onnx`, re-exported here behind the default `export`
//! feature; the runtime alone (`default-features = false`) is what the
//! Python wheel uses, without Burn.

pub mod runtime;

#[cfg(feature = "export")]
pub use deepfoids_learn::onnx::{Head, Metadata, OPSET, export, export_policy, proto};
pub use runtime::{OnnxError, OnnxPolicy, check_species};
