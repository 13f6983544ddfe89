//! The runtime's one error type.

use std::path::PathBuf;

/// Everything that can go wrong in the runtime, each variant naming the thing at fault.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file or folder that could not be read, written, created or renamed (the operating
    /// system's reason follows as the source).
    #[error("cannot {op} {path}")]
    Io {
        op: IoOp,
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

/// What an I/O error was doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IoOp {
    Read,
    Write,
    CreateFolder,
    Rename,
    Remove,
}

impl std::fmt::Display for IoOp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            IoOp::Read => "read",
            IoOp::Write => "write",
            IoOp::CreateFolder => "create the folder",
            IoOp::Rename => "rename a finished file to",
            IoOp::Remove => "remove",
        })
    }
}

impl Error {
    /// A read that failed.
    pub fn read(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            op: IoOp::Read,
            path: path.into(),
            source,
        }
    }
    /// Any other I/O that failed.
    pub fn io_op(op: IoOp, path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            op,
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
