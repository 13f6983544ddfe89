//! dhoit runtime: scenes, the CPU reference of every pass, compositing and budgets.
//!
//! The CPU path is the reference the GPU renderer is held to: [`raster`] turns a [`scene`] into
//! per-pixel fragment lists, [`frame`] allocates slots under a [`budget`] and composites with
//! [`composite`]; [`dump`] writes the fragment dump contract.

pub mod alloc;
pub mod budget;
pub mod composite;
pub mod dump;
pub mod error;
pub mod fragment;
pub mod frame;
/// The wgpu renderer (the `gpu` feature, on by default; the trainer builds without it).
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod image_io;
pub mod importance;
pub mod mlp;
pub mod raster;
pub mod rng;
pub mod scene;
pub mod tensors;
pub mod wgsl;

pub use error::{Error, GpuError, Result};
