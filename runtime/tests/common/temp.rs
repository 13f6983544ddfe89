//! Tests' temporary folders (shared by the runtime's and the `dhoit` crate's tests).

use std::path::{Path, PathBuf};

/// A test's temporary folder: a path ([`std::ops::Deref`]), removed with what is in it when
/// the test drops it (at its end, or as it panics).
pub struct TempDir(tempfile::TempDir);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        self.0.path()
    }
}

impl TempDir {
    /// The folder, kept after the test (for what a test binary's tests share).
    pub fn keep(self) -> PathBuf {
        self.0.keep()
    }
}

/// A fresh, empty temporary folder for one test (`prefix` names it: `dhoit-{prefix}-…`).
pub fn temp_dir(prefix: &str) -> TempDir {
    tempfile::Builder::new()
        .prefix(&format!("dhoit-{prefix}-"))
        .tempdir()
        .map(TempDir)
        .unwrap_or_else(|e| panic!("a temporary folder for {prefix}: {e}"))
}
