//! The learning core of DeepFoids, shared by the PPO and SAC crates: the
//! network body of SPEC §8 and its hand-written kernels, tensor helpers, the
//! backend choice, compact frame storage, checkpoints with a typed algorithm,
//! the logs (TensorBoard and CSV), episode statistics, progress reporting,
//! weight loading, the ONNX writer, and the one run driver that owns resume,
//! transfer (`--init-from`), the environment loop, budgets, checkpoints and
//! the outcome. An algorithm plugs in as a [`driver::Trainer`].

pub mod algorithm;
pub mod backend;
pub mod body;
pub mod budget;
pub mod checkpoint;
pub mod driver;
pub mod error;
pub mod frames;
pub mod kernels;
pub mod logger;
pub mod onnx;
pub mod plan;
pub mod policy;
pub mod progress;
pub mod stats;
pub mod tensor;
pub mod tfevents;

pub use algorithm::Algorithm;
pub use backend::Backend;
pub use body::{ACTIONS, Body, BodyConfig, ENCODER_LAYOUT};
pub use budget::Budget;
pub use driver::{
    BufferMemory, Learner, LearnerCtx, RunArgs, RunSettings, StepCtx, Timing, TrainOutcome, Trainer,
};
pub use error::{LearnError, Result};
pub use kernels::ops::Grids;
pub use progress::ProgressMode;
