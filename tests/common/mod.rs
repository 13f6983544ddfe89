//! Helpers shared by the `dhoit` crate's integration tests.
#![allow(dead_code)] // each test binary uses its own subset

use dhoit_runtime::gpu::Gpu;
use std::path::Path;
use std::process::{Command, Output};

/// The workspace root (committed data, weights, golden files).
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[path = "../../runtime/tests/common/temp.rs"]
mod temp;
#[allow(unused_imports)] // each test binary uses its own subset
pub use temp::{TempDir, temp_dir};

/// Runs the `dhoit` binary.
pub fn dhoit(args: &[&str]) -> Output {
    dhoit_with_env(args, &[])
}

/// Runs the `dhoit` binary with environment variables set for it.
pub fn dhoit_with_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dhoit"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("run dhoit")
}

/// Whether DHOIT_SKIP_GPU=1 asks to skip the GPU tests explicitly; says so for `what`.
pub fn skip_gpu(what: &str) -> bool {
    let skip = std::env::var("DHOIT_SKIP_GPU").as_deref() == Ok("1");
    if skip {
        eprintln!("SKIPPED (DHOIT_SKIP_GPU=1): {what}");
    }
    skip
}

/// The GPU the tests of one binary share. Without an adapter the test fails, unless
/// DHOIT_SKIP_GPU=1 says to skip (None, and it says so).
pub fn gpu() -> Option<&'static Gpu> {
    static GPU: std::sync::OnceLock<Option<Gpu>> = std::sync::OnceLock::new();
    GPU.get_or_init(|| match Gpu::new() {
        Ok(g) => Some(g),
        Err(e) if skip_gpu(&format!("the GPU tests ({e})")) => None,
        Err(e) => panic!("{e} (set DHOIT_SKIP_GPU=1 to skip the GPU tests explicitly)"),
    })
    .as_ref()
}

/// Largest absolute difference of two equally long slices.
pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}
