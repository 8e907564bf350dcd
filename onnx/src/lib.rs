//! ONNX export of trained policies (Unity ML-Agents' interface) and an ONNX
//! policy that drives scenes through tract.
//!
//! The exporter needs Burn and sits behind the default `export` feature; the
//! runtime alone (`default-features = false`) is what the Python wheel uses.

#[cfg(feature = "export")]
pub mod export;
pub mod proto;
pub mod runtime;

#[cfg(feature = "export")]
pub use export::{Head, Metadata, export_actor, export_policy};
pub use runtime::{OnnxPolicy, check_species};
