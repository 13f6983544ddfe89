//! dhoit runtime: scenes, the CPU reference of every pass, compositing and budgets.
//!
//! The CPU path is the reference the GPU renderer is held to: [`raster`] turns a [`scene`] into
//! per-pixel fragment lists, [`frame`] allocates slots under a [`budget`] and composites with
//! [`composite`]; [`dump`] writes the fragment dump contract.
//!
//! One frame, every step on the CPU: a built-in scene, its fragments, DKB with the shipped
//! weights at a quarter of the frame's fragments, beside the exact A-buffer. Where the exact
//! A-buffer needs no more bytes than DKB would, DKB renders it ([`frame::Options`]'s
//! `exact_when_cheaper`); `always_approximate` renders the network's allocation whatever it
//! costs.
//!
//! ```
//! use dhoit_runtime::budget::Budget;
//! use dhoit_runtime::frame::{Method, Options, Renderer};
//! use dhoit_runtime::{mlp::Mlp, raster, scene};
//!
//! let s = scene::load("particles", scene::Opacity::default())?;
//! let (w, h) = (160, 120);
//! let cam = scene::Camera::orbit(&s, 1, scene::DEFAULT_VIEWS, w, h);
//! let fragments = raster::rasterize(&s, &cam, w, h)?;
//! let weights = Mlp::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/weights.safetensors").as_ref())?;
//! let options = Options {
//!     weights: Some(&weights),
//!     ..Options::new(Budget::parse("25%")?, [1.0; 3])
//! };
//! let frame = Renderer::new(&fragments, options).render(Method::Dkb)?;
//! let exact = Renderer::new(&fragments, options).render(Method::Abuffer)?;
//! // Never more memory than the exact answer.
//! assert!(frame.allocated_bytes <= exact.allocated_bytes);
//! // The network's own allocation: a quarter of the fragments in slots (and, where a pixel's
//! // tail would hold no more than two, those too, in the tail's words), an error above zero.
//! let own = Renderer::new(&fragments, options.always_approximate()).render(Method::Dkb)?;
//! let quarter = fragments.fragment_count() as u64 / 4;
//! assert_eq!(own.budget_fragments, quarter);
//! assert!(own.fragments_captured >= quarter);
//! assert!(own.image.mse(&exact.image) > 0.0);
//! # Ok::<(), dhoit_runtime::Error>(())
//! ```

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
pub mod plan;
pub mod raster;
pub mod rng;
pub mod scene;
pub mod shared;
pub mod tensors;
pub mod wgsl;

pub use error::{Error, GpuError, Result};
