//! ONNX export of trained policies (Unity ML-Agents' interface) and an ONNX
//! policy that drives scenes through tract.

pub mod export;
pub mod proto;
pub mod runtime;

pub use export::{Head, Metadata, export_actor, export_policy};
pub use runtime::{OnnxPolicy, check_species};
