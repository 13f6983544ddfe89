//! The fragment dump (`render --dump DIR`): one safetensors file with the frame's fragment lists,
//! the method's per-pixel k and its image.
//!
//! Tensors: `offsets` u32 `[W*H+1]` (pixel p's fragments are `offsets[p]..offsets[p+1]`, row-major
//! from the top-left pixel), `depth` f32 `[F]`, `rgba` f32 `[F,4]` (non-premultiplied), `primitive`
//! u32 `[F]` (submission index), `k` u32 `[W*H]`, `image` f32 `[H,W,3]` (linear); where the frame has
//! opaque surfaces, `opaque` u32 `[W*H]` (each pixel's nearest opaque colour as
//! `fragment::pack_opaque` stores it; 0 where none) and `opaque_depth` f32 `[W*H]` (its depth; 1 where none); where a fragment is
//! tinted, `tint` u32 `[F]` (each fragment's RGB8 tint, `fragment::CLEAR` untinted). Metadata: `width`,
//! `height`, `method`, `budget_bytes`, `budget_fragments` (F(M)), `background` ("r,g,b"),
//! `format` ("dhoit-dump-1").

use crate::composite::Image;
use crate::error::{Error, Result};
use crate::fragment::FragmentLists;
use crate::tensors::{self, Entry, FormatError};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

pub const FORMAT: &str = "dhoit-dump-1";
pub const FILE_NAME: &str = "fragments.safetensors";

/// Everything a dump holds.
#[derive(Clone, Debug, PartialEq)]
pub struct Dump {
    pub fragments: FragmentLists,
    pub k: Vec<u32>,
    pub image: Image,
    pub method: String,
    pub budget_bytes: u64,
    pub budget_fragments: u64,
    pub background: [f32; 3],
}

/// Writes `DIR/fragments.safetensors`; returns its path.
pub fn write(dir: &Path, d: &Dump) -> Result<PathBuf> {
    let fl = &d.fragments;
    let (w, h) = (fl.width as usize, fl.height as usize);
    let f = fl.fragment_count();
    let rgba: Vec<f32> = fl.rgba.iter().flatten().copied().collect();
    let image: Vec<f32> = d.image.data.iter().flatten().copied().collect();
    let mut entries = vec![
        Entry::u32("offsets", vec![w * h + 1], &fl.offsets),
        Entry::f32("depth", vec![f], &fl.depth),
        Entry::f32("rgba", vec![f, 4], &rgba),
        Entry::u32("primitive", vec![f], &fl.primitive),
        Entry::u32("k", vec![w * h], &d.k),
        Entry::f32("image", vec![h, w, 3], &image),
    ];
    if !fl.opaque.is_empty() {
        entries.push(Entry::u32("opaque", vec![w * h], &fl.opaque));
        entries.push(Entry::f32("opaque_depth", vec![w * h], &fl.opaque_depth));
    }
    if !fl.tint.is_empty() {
        entries.push(Entry::u32("tint", vec![f], &fl.tint));
    }
    let bg = d.background;
    let meta: HashMap<String, String> = [
        ("format", FORMAT.to_string()),
        ("width", fl.width.to_string()),
        ("height", fl.height.to_string()),
        ("method", d.method.clone()),
        ("budget_bytes", d.budget_bytes.to_string()),
        ("budget_fragments", d.budget_fragments.to_string()),
        ("background", format!("{},{},{}", bg[0], bg[1], bg[2])),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let path = dir.join(FILE_NAME);
    tensors::write(&path, &entries, meta)?;
    Ok(path)
}

/// Reads a dump written by [`write()`] (a directory or the file itself), checking every shape.
pub fn read(path: &Path) -> Result<Dump> {
    let path = if path.is_dir() {
        path.join(FILE_NAME)
    } else {
        path.to_path_buf()
    };
    let bytes = std::fs::read(&path).map_err(|e| Error::read(&path, e))?;
    parse(&bytes, &path)
}

/// Parses a dump's bytes (`path` names it in errors), checking every shape.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Dump> {
    let path = path.to_path_buf();
    let err = |fault: FormatError| Error::Dump {
        path: path.clone(),
        fault,
    };
    let contract = |m: &str| err(FormatError::Contract(m.into()));
    let file = tensors::File::parse(bytes).map_err(err)?;
    let num = |k: &str| -> Result<u64> {
        file.meta(k).map_err(err)?.parse().map_err(|_| {
            err(FormatError::Metadata {
                key: k.into(),
                message: "not a number".into(),
            })
        })
    };
    let (width, height) = (num("width")? as u32, num("height")? as u32);
    let pixels = width as usize * height as usize;
    let (_, offsets) = file.u32("offsets", Some(&[pixels + 1])).map_err(err)?;
    let (dshape, depth) = file.f32("depth", None).map_err(err)?;
    let f = dshape.first().copied().unwrap_or(0);
    if dshape.len() != 1
        || offsets.first() != Some(&0)
        || offsets.last().map(|&o| o as usize) != Some(f)
    {
        return Err(contract(&format!("offsets do not span the {f} fragments")));
    }
    if offsets.windows(2).any(|w| w[1] < w[0]) {
        return Err(contract("offsets decrease"));
    }
    let (_, rgba) = file.f32("rgba", Some(&[f, 4])).map_err(err)?;
    let (_, primitive) = file.u32("primitive", Some(&[f])).map_err(err)?;
    let (_, k) = file.u32("k", Some(&[pixels])).map_err(err)?;
    // The opaque layer, where the frame has one: both tensors or neither.
    let (opaque, opaque_depth) = match file.tensor("opaque") {
        Ok(_) => (
            file.u32("opaque", Some(&[pixels])).map_err(err)?.1,
            file.f32("opaque_depth", Some(&[pixels])).map_err(err)?.1,
        ),
        Err(_) => (Vec::new(), Vec::new()),
    };
    let tint = match file.tensor("tint") {
        Ok(_) => file.u32("tint", Some(&[f])).map_err(err)?.1,
        Err(_) => Vec::new(),
    };
    let (_, image) = file
        .f32("image", Some(&[height as usize, width as usize, 3]))
        .map_err(err)?;
    let bg: Vec<f32> = file
        .meta("background")
        .map_err(err)?
        .split(',')
        .map(|v| v.parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f32>| v.len() == 3)
        .ok_or_else(|| {
            err(FormatError::Metadata {
                key: "background".into(),
                message: "not r,g,b".into(),
            })
        })?;
    Ok(Dump {
        fragments: FragmentLists {
            width,
            height,
            offsets,
            depth,
            rgba: rgba
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect(),
            // A dump does not say why its fragments carry tints: counted as tinted glass's,
            // the more bytes.
            tinted_glass: !tint.is_empty(),
            tint,
            primitive,
            facing: Vec::new(),
            opaque,
            opaque_depth,
        },
        k,
        image: Image {
            width,
            height,
            data: image.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        },
        method: file.meta("method").map_err(err)?.to_string(),
        budget_bytes: num("budget_bytes")?,
        budget_fragments: num("budget_fragments")?,
        background: [bg[0], bg[1], bg[2]],
    })
}
