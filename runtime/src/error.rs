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
    /// The file's fault is displayed inline, and is not the error's `source` (which anyhow's
    /// `{:#}` would print a second time): thiserror takes a field named `source` as one.
    #[error("fragment dump {path}: {fault}")]
    Dump { path: PathBuf, fault: FormatError },
    #[error("weights {path}: {fault}")]
    Weights { path: PathBuf, fault: FormatError },
    /// (Displayed whole, not as a source, so the message is not repeated.)
    #[error("GPU: {0}")]
    Gpu(GpuError),
    #[error("image {path}: {message}")]
    Image { path: PathBuf, message: String },
}

pub type Result<T> = std::result::Result<T, Error>;

impl From<GpuError> for Error {
    fn from(e: GpuError) -> Self {
        Error::Gpu(e)
    }
}

/// What can go wrong on the GPU, so a caller can tell a missing device from a frame too large
/// for it.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found: dhoit needs a Vulkan, Metal or DX12 device (on Debian, \
         `apt-get install mesa-vulkan-drivers` provides lavapipe, a Vulkan device on the CPU)"
    )]
    NoAdapter,
    /// Every adapter lacks something the passes need; `lacking` says what, per adapter.
    #[error(
        "no adapter has the features asked for (for DKB, 64-bit integers and 64-bit atomics: \
         Vulkan with shaderInt64 and VK_KHR_shader_atomic_int64, DX12 with shader model 6.6; \
         wgpu's Metal backend and WebGPU have none, and run every other method): {lacking}"
    )]
    MissingFeatures { lacking: String },
    /// The application's device was opened without a feature or a limit the passes need.
    #[error(
        "the device on {adapter} was opened without what this needs: {missing} (request \
         gpu::required_features(), 64-bit integers and their atomics, and \
         gpu::required_limits() when opening it)"
    )]
    DeviceLacks { adapter: String, missing: String },
    /// A texture an application hands a frame is not the one the method was made for.
    #[error("the frame's {texture} is {got}; this {method} renders {expected}")]
    FrameTexture {
        method: &'static str,
        texture: &'static str,
        expected: String,
        got: String,
    },
    /// The network was deployed at f16-math on a device without half-precision shaders.
    #[error(
        "{adapter} lacks SHADER_F16 (half-precision arithmetic in shaders), which the \
         importance pass needs at precision f16-math: use f16 (binary16 weights, f32 \
         arithmetic) or f32"
    )]
    NoHalfMath { adapter: String },
    #[error("cannot open {adapter}: {message}")]
    Open { adapter: String, message: String },
    #[error("the device rejected a shader or pipeline: {0}")]
    Pipeline(String),
    /// A buffer larger than the device binds, found before anything is allocated.
    #[error(
        "{label} needs {need} bytes in one buffer, but this device binds at most {max}: lower \
         the resolution or the budget"
    )]
    BufferTooLarge { label: String, need: u64, max: u64 },
    #[error("a {width}x{height} frame exceeds this device's largest render target ({max} a side)")]
    FrameTooLarge { width: u32, height: u32, max: u32 },
    /// A pass stopped its loops early (lavapipe ends a shader's loops after 65,535 iterations);
    /// the frame is refused, not returned wrong.
    #[error(
        "{adapter} stopped a pass's loops early: too many fragments in one pixel for this device \
         (Mesa's lavapipe ends a shader's loops after 65,535 iterations, and the A-buffer sorts \
         each pixel's fragments in place)"
    )]
    LoopLimit { adapter: String },
    #[error("out of device memory: {0}")]
    OutOfMemory(String),
    #[error("the device rejected a command: {0}")]
    Validation(String),
    /// The device was lost, or waiting for or reading back a submission failed.
    #[error("the device failed while {doing}: {message}")]
    Lost {
        doing: &'static str,
        message: String,
    },
}

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

/// What is wrong with the contents of a safetensors file (weights, features, dumps, dataset
/// shards): the loaders wrap it with the file's path.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FormatError {
    #[error("not a safetensors file: {0}")]
    NotSafetensors(String),
    #[error("missing tensor '{0}'")]
    MissingTensor(String),
    #[error("tensor '{name}' is {found}, expected {expected}")]
    Dtype {
        name: String,
        found: String,
        expected: String,
    },
    #[error("tensor '{name}' has shape {found:?}, expected {expected}")]
    Shape {
        name: String,
        found: Vec<usize>,
        expected: String,
    },
    #[error("tensor '{name}' has a non-finite value at {index}")]
    NonFinite { name: String, index: usize },
    #[error("metadata has no '{0}'")]
    MissingMetadata(String),
    #[error("metadata '{key}': {message}")]
    Metadata { key: String, message: String },
    /// Well-formed, but beyond what this build holds (such as a hidden layer wider than the GPU
    /// pass's arrays).
    #[error("{0}")]
    Unsupported(String),
    /// Any other rule of the file's contract (values out of range, inconsistent tensors).
    #[error("{0}")]
    Contract(String),
}
