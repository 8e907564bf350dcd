//! ONNX export of trained policies (Unity ML-Agents' interface) and an ONNX
//! policy that drives scenes through tract.

pub mod export;
pub mod proto;
pub mod runtime;

pub use export::{Metadata, export_actor};
pub use runtime::{OnnxPolicy, check_species};
