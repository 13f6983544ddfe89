//! Small helpers over the `safetensors` crate: typed reads with shape checks, and atomic writes
//! (a temporary file renamed into place, so a failed write never leaves half a file).

use crate::error::{Error, IoOp, Result};
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use std::collections::HashMap;
use std::path::Path;

/// One tensor to write: name, dtype, shape, little-endian bytes.
pub struct Entry {
    pub name: String,
    pub dtype: Dtype,
    pub shape: Vec<usize>,
    pub bytes: Vec<u8>,
}

impl Entry {
    pub fn f32(name: &str, shape: Vec<usize>, v: &[f32]) -> Entry {
        Entry {
            name: name.into(),
            dtype: Dtype::F32,
            shape,
            bytes: v.iter().flat_map(|x| x.to_le_bytes()).collect(),
        }
    }
    pub fn u32(name: &str, shape: Vec<usize>, v: &[u32]) -> Entry {
        Entry {
            name: name.into(),
            dtype: Dtype::U32,
            shape,
            bytes: v.iter().flat_map(|x| x.to_le_bytes()).collect(),
        }
    }
}

/// Writes tensors and string metadata to `path` atomically.
pub fn write(path: &Path, entries: &[Entry], metadata: HashMap<String, String>) -> Result<()> {
    let views: Vec<(String, TensorView)> = entries
        .iter()
        .map(|e| {
            TensorView::new(e.dtype, e.shape.clone(), &e.bytes)
                .map(|v| (e.name.clone(), v))
                .map_err(|err| Error::Invalid(format!("tensor {}: {err}", e.name)))
        })
        .collect::<Result<_>>()?;
    let bytes = safetensors::serialize(views, Some(metadata))
        .map_err(|e| Error::Invalid(format!("cannot serialise {}: {e}", path.display())))?;
    write_atomic(path, &bytes)
}

/// Writes bytes to a sibling temporary file, then renames it over `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io_op(IoOp::CreateFolder, dir, e))?;
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(format!(".{}.tmp", std::process::id()));
    let tmp = std::path::PathBuf::from(tmp);
    // A failed write (a full disk, say) removes its temporary file and leaves `path` as it was.
    if let Err(e) = std::fs::write(&tmp, bytes) {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io_op(IoOp::Write, path, e));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io_op(IoOp::Rename, path, e)
    })
}

/// A parsed safetensors file with its metadata.
pub struct File<'a> {
    pub tensors: SafeTensors<'a>,
    pub metadata: HashMap<String, String>,
}

impl<'a> File<'a> {
    pub fn parse(bytes: &'a [u8]) -> std::result::Result<File<'a>, String> {
        let (_, meta) = SafeTensors::read_metadata(bytes)
            .map_err(|e| format!("not a safetensors file: {e}"))?;
        let tensors =
            SafeTensors::deserialize(bytes).map_err(|e| format!("not a safetensors file: {e}"))?;
        Ok(File {
            tensors,
            metadata: meta.metadata().clone().unwrap_or_default(),
        })
    }

    fn view(
        &self,
        name: &str,
        dtype: Dtype,
        shape: Option<&[usize]>,
    ) -> std::result::Result<TensorView<'a>, String> {
        let v = self
            .tensors
            .tensor(name)
            .map_err(|_| format!("missing tensor '{name}'"))?;
        if v.dtype() != dtype {
            return Err(format!(
                "tensor '{name}' is {:?}, expected {dtype:?}",
                v.dtype()
            ));
        }
        if let Some(s) = shape
            && v.shape() != s
        {
            return Err(format!(
                "tensor '{name}' has shape {:?}, expected {s:?}",
                v.shape()
            ));
        }
        Ok(v)
    }

    /// Reads an f32 tensor, checking its shape when one is given; returns (shape, values).
    pub fn f32(
        &self,
        name: &str,
        shape: Option<&[usize]>,
    ) -> std::result::Result<(Vec<usize>, Vec<f32>), String> {
        let v = self.view(name, Dtype::F32, shape)?;
        let data = v
            .data()
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]));
        Ok((v.shape().to_vec(), data.collect()))
    }

    pub fn u32(
        &self,
        name: &str,
        shape: Option<&[usize]>,
    ) -> std::result::Result<(Vec<usize>, Vec<u32>), String> {
        let v = self.view(name, Dtype::U32, shape)?;
        let data = v
            .data()
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
        Ok((v.shape().to_vec(), data.collect()))
    }

    pub fn meta(&self, key: &str) -> std::result::Result<&str, String> {
        self.metadata
            .get(key)
            .map(String::as_str)
            .ok_or_else(|| format!("metadata has no '{key}'"))
    }
}
