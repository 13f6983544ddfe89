//! Small helpers over the `safetensors` crate: typed reads with shape checks, and atomic writes
//! (a temporary file renamed into place, so a failed write never leaves half a file).

pub use crate::error::FormatError;
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

/// Writes tensors and string metadata to `path` atomically. The header's keys (tensors and
/// metadata) are written in sorted order, so the same tensors and metadata give the same bytes
/// every time (the crate writes them in a hash map's order, which changes from run to run).
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
    write_atomic(path, &sorted_header(bytes))
}

/// A serialised file with its JSON header's objects in sorted key order (serde_json's map is
/// ordered), padded with spaces to the header's length as before: the data offsets in it are
/// relative to the end of the header, so they stay valid.
fn sorted_header(mut bytes: Vec<u8>) -> Vec<u8> {
    let n = u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes")) as usize;
    let header: serde_json::Value =
        serde_json::from_slice(&bytes[8..8 + n]).expect("the crate writes a JSON header");
    let mut sorted = serde_json::to_vec(&header).expect("a JSON value serialises");
    if sorted.len() > n {
        // Not the same text reordered (never seen): the crate's own order, as it wrote it.
        return bytes;
    }
    sorted.resize(n, b' ');
    bytes[8..8 + n].copy_from_slice(&sorted);
    bytes
}

/// Creates `dir` and its parents (nothing for an empty path), the error naming it. Commands
/// call it for their outputs before their work, so a path that cannot be written is refused
/// before the work, not after it.
pub fn create_folder(dir: &Path) -> Result<()> {
    if !dir.as_os_str().is_empty() {
        std::fs::create_dir_all(dir).map_err(|e| Error::io_op(IoOp::CreateFolder, dir, e))?;
    }
    Ok(())
}

/// [`create_folder`] for the folder a file goes in.
pub fn create_parent(path: &Path) -> Result<()> {
    path.parent().map_or(Ok(()), create_folder)
}

/// Writes bytes to a sibling temporary file, then renames it over `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    create_parent(path)?;
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

type FormatResult<T> = std::result::Result<T, FormatError>;

/// A parsed safetensors file with its metadata.
pub struct File<'a> {
    pub tensors: SafeTensors<'a>,
    pub metadata: HashMap<String, String>,
}

impl<'a> File<'a> {
    pub fn parse(bytes: &'a [u8]) -> FormatResult<File<'a>> {
        let not = |e: safetensors::SafeTensorError| FormatError::NotSafetensors(e.to_string());
        let (_, meta) = SafeTensors::read_metadata(bytes).map_err(not)?;
        let tensors = SafeTensors::deserialize(bytes).map_err(not)?;
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
    ) -> FormatResult<TensorView<'a>> {
        let v = self.tensor(name)?;
        if v.dtype() != dtype {
            return Err(FormatError::Dtype {
                name: name.into(),
                found: format!("{:?}", v.dtype()),
                expected: format!("{dtype:?}"),
            });
        }
        if let Some(s) = shape
            && v.shape() != s
        {
            return Err(FormatError::Shape {
                name: name.into(),
                found: v.shape().to_vec(),
                expected: format!("{s:?}"),
            });
        }
        Ok(v)
    }

    /// Reads an f32 tensor, checking its shape when one is given; returns (shape, values).
    pub fn f32(&self, name: &str, shape: Option<&[usize]>) -> FormatResult<(Vec<usize>, Vec<f32>)> {
        let v = self.view(name, Dtype::F32, shape)?;
        let data = v
            .data()
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]));
        Ok((v.shape().to_vec(), data.collect()))
    }

    pub fn u32(&self, name: &str, shape: Option<&[usize]>) -> FormatResult<(Vec<usize>, Vec<u32>)> {
        let v = self.view(name, Dtype::U32, shape)?;
        let data = v
            .data()
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
        Ok((v.shape().to_vec(), data.collect()))
    }

    /// A tensor of any dtype and shape.
    pub fn tensor(&self, name: &str) -> FormatResult<TensorView<'a>> {
        self.tensors
            .tensor(name)
            .map_err(|_| FormatError::MissingTensor(name.into()))
    }

    pub fn meta(&self, key: &str) -> FormatResult<&str> {
        self.metadata
            .get(key)
            .map(String::as_str)
            .ok_or_else(|| FormatError::MissingMetadata(key.into()))
    }

    /// A metadata entry parsed as JSON.
    pub fn meta_json<T: serde::de::DeserializeOwned>(&self, key: &str) -> FormatResult<T> {
        serde_json::from_str(self.meta(key)?).map_err(|e| FormatError::Metadata {
            key: key.into(),
            message: e.to_string(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same tensors and metadata give the same bytes: the header is written in sorted
    /// order, not in the order of a hash map (which differs between two maps of the same
    /// entries), and the file still reads back.
    #[test]
    fn the_same_contents_give_the_same_bytes() {
        let dir = std::env::temp_dir().join(format!("dhoit-tensors-{}", std::process::id()));
        let entries = || {
            vec![
                Entry::f32("b", vec![2], &[1.0, 2.0]),
                Entry::u32("a", vec![3], &[1, 2, 3]),
            ]
        };
        let meta = || -> HashMap<String, String> {
            (0..32)
                .map(|i| (format!("key{i}"), format!("{i}")))
                .collect()
        };
        let (p, q) = (dir.join("p.safetensors"), dir.join("q.safetensors"));
        write(&p, &entries(), meta()).unwrap();
        write(&q, &entries(), meta()).unwrap();
        let (a, b) = (std::fs::read(&p).unwrap(), std::fs::read(&q).unwrap());
        assert!(a == b, "two writes of the same contents differ");
        let f = File::parse(&a).unwrap();
        assert_eq!(f.u32("a", Some(&[3])).unwrap().1, vec![1, 2, 3]);
        assert_eq!(f.meta("key7").unwrap(), "7");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
