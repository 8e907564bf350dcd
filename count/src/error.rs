//! Typed errors: each names the file or value that was wrong and what is allowed.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum CountError {
    /// The I/O error is part of the message, not a `source`: a chain says it once.
    #[error("{path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("{path} does not exist")]
    Missing { path: PathBuf },
    /// The file is no ONNX protobuf at all (a text file, say).
    #[error("{path} is not an ONNX model ({why})")]
    NotOnnxFile { path: PathBuf, why: String },
    #[error("{path} is not a loadable ONNX model: {message}")]
    NotOnnx { path: PathBuf, message: String },
    #[error(
        "{path}: unknown detector outputs {outputs}; allowed: ours (`heatmap` [1, 1, h, w] and `boxes` [1, 4, h, w]) or a YOLOv8 export ([1, 4 + classes, anchors])"
    )]
    WrongOutputs { path: PathBuf, outputs: String },
    #[error("tract cannot run {path}: {message}")]
    Runtime { path: PathBuf, message: String },
    #[error("cannot read image {path}: {message}")]
    Image { path: PathBuf, message: String },
    #[error("{path}: {message}")]
    Video { path: PathBuf, message: String },
    #[error("{path} holds no frames (PNG or JPEG files expected)")]
    NoFrames { path: PathBuf },
    #[error("{what} must be {allowed}, got {value}")]
    Value {
        what: &'static str,
        allowed: &'static str,
        value: String,
    },
    #[error("{path}: {message}")]
    Dataset { path: PathBuf, message: String },
    #[error("training failed: {0}")]
    Train(String),
}

impl CountError {
    pub fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> CountError + '_ {
        move |error| CountError::Io {
            path: path.to_path_buf(),
            error,
        }
    }
}

pub type Result<T, E = CountError> = std::result::Result<T, E>;
