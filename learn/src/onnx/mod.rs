//! ONNX export of actors with Unity ML-Agents' interface ([`export`]), on
//! hand-declared protobuf messages ([`proto`]). Running ONNX files (tract) is
//! the `deepfoids-onnx` crate's business.

pub mod build;
pub mod export;
pub mod proto;

pub use export::{Head, Metadata, OPSET, export_policy};
