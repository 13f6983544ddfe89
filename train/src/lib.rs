//! dhoit trainer: datasets from scenes, the importance MLP in burn on the CPU, export to the
//! weights contract the runtime reads.
//!
//! The network is 12-128-64-1 (ReLU, ReLU, sigmoid) on standardised features, trained with a
//! loss (the regret of the k it asks for, by default; the paper's MSE as an option), L1 on the
//! first hidden layer's weights, L2 on the second's, and SGD with momentum (paper 001). burn
//! runs on its Flex CPU backend: its modules and optimiser, and a training step whose backward
//! pass is written out ([`step`]), held in tests to burn's autodiff.

pub mod cli;
pub mod dataset;
pub mod generalise;
pub mod model;
pub mod plot;
pub mod score;
pub mod step;
pub mod trainer;

pub use dhoit_runtime::error::IoOp;
use dhoit_runtime::tensors::FormatError;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Runtime(#[from] dhoit_runtime::Error),
    #[error("dataset: {0}")]
    Dataset(String),
    #[error("{0}")]
    Config(String),
    #[error("training diverged at epoch {epoch} (loss {loss}); lower the learning rate")]
    Diverged { epoch: usize, loss: f64 },
    // The file's fault inline, not as the error's source (dhoit_runtime::Error::Weights).
    #[error("dataset shard {path}: {fault}")]
    Shard { path: PathBuf, fault: FormatError },
    #[error("features {path}: {fault}")]
    Features { path: PathBuf, fault: FormatError },
}

impl Error {
    /// A read that failed (the runtime's I/O error, which says what and where).
    pub fn read(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Runtime(dhoit_runtime::Error::read(path, source))
    }
    /// Any other I/O that failed.
    pub fn io_op(op: IoOp, path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Runtime(dhoit_runtime::Error::io_op(op, path, source))
    }
}

pub type Result<T> = std::result::Result<T, Error>;
