//! The runtime's one error type.

use std::path::PathBuf;

/// Everything that can go wrong in the runtime, each variant naming the thing at fault.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("cannot read {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("scene {path}: {message}")]
    Scene { path: PathBuf, message: String },
    #[error(
        "unknown scene '{0}': give a built-in name (see `dhoit scenes`) or a path to a .gltf/.glb file"
    )]
    UnknownScene(String),
    #[error("invalid resolution {0}: {1}")]
    Resolution(String, String),
    #[error("invalid budget '{0}': {1}")]
    Budget(String, String),
    #[error("invalid argument: {0}")]
    Invalid(String),
    #[error("fragment dump {path}: {message}")]
    Dump { path: PathBuf, message: String },
    #[error("weights {path}: {message}")]
    Weights { path: PathBuf, message: String },
    #[error("GPU: {0}")]
    Gpu(String),
    #[error("image {path}: {message}")]
    Image { path: PathBuf, message: String },
}

pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
    pub fn scene(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Scene {
            path: path.into(),
            message: message.into(),
        }
    }
}
