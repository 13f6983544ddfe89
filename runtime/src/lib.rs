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
//! let size = (160, 120); // (width, height), as every size in dhoit
//! let cam = scene::Camera::orbit(&s, 1, scene::DEFAULT_VIEWS, size);
//! let fragments = raster::rasterize(&s, &cam, size)?;
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
pub mod method;
pub mod mlp;
pub mod plan;
pub mod raster;
pub mod rng;
pub mod scene;
pub mod shared;
pub mod tensors;
pub mod wgsl;

pub use error::{Error, GpuError, Result};

#[cfg(test)]
mod tests {
    use std::path::Path;

    /// The parameters of every `fn` in `source`, by function name.
    fn parameters(source: &str) -> Vec<(String, Vec<String>)> {
        let mut out = Vec::new();
        for (at, _) in source.match_indices("fn ") {
            let rest = &source[at + 3..];
            let Some(open) = rest.find('(') else { continue };
            let name = &rest[..open];
            if name.is_empty()
                || !name
                    .chars()
                    .all(|c| c.is_alphanumeric() || "_<>, '".contains(c))
            {
                continue;
            }
            let (mut depth, mut params, mut start) = (0, Vec::new(), open + 1);
            for (i, c) in rest.char_indices().skip(open + 1) {
                match c {
                    '(' | '[' | '<' => depth += 1,
                    ')' | ']' | '>' if depth > 0 => depth -= 1,
                    ')' => {
                        params.push(rest[start..i].trim().to_string());
                        break;
                    }
                    ',' if depth == 0 => {
                        params.push(rest[start..i].trim().to_string());
                        start = i + 1;
                    }
                    _ => {}
                }
            }
            out.push((name.to_string(), params));
        }
        out
    }

    fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                sources(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }

    /// A frame's, an image's or a texture's size travels as one `size: (u32, u32)` (width,
    /// height) through the library and the CLI, as [`crate::raster::rasterize`],
    /// [`crate::composite::Image::new`] and the application types take it: no function takes
    /// the two as separate parameters.
    #[test]
    fn every_size_is_one_width_height_pair() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut files = Vec::new();
        sources(&root.join("src"), &mut files);
        sources(&root.join("../src"), &mut files);
        assert!(files.len() > 30, "found {} sources", files.len());
        let (mut functions, mut split) = (0, Vec::new());
        for file in &files {
            let source = std::fs::read_to_string(file).unwrap();
            for (name, params) in parameters(&source) {
                functions += 1;
                let pair = |p: &str, q: &str| {
                    (p == "width: u32" && q == "height: u32") || (p == "w: u32" && q == "h: u32")
                };
                if params.windows(2).any(|w| pair(&w[0], &w[1])) {
                    split.push(format!("{}: fn {name}", file.display()));
                }
            }
        }
        assert!(functions > 800, "read {functions} functions");
        assert!(split.is_empty(), "take `size: (u32, u32)`: {split:#?}");
    }

    #[test]
    fn the_parameter_reader_splits_at_the_top_level() {
        // Built apart, so the test above does not read it as a function of this file.
        let read = parameters(concat!(
            "fn a(x: (u32, u32), f: impl Fn(u8, u8) -> u8,",
            " w: u32, h: u32) {}"
        ));
        assert_eq!(read[0].0, "a");
        assert_eq!(
            read[0].1,
            [
                "x: (u32, u32)",
                "f: impl Fn(u8, u8) -> u8",
                "w: u32",
                "h: u32"
            ]
        );
    }
}
