//! glTF 2.0 loading (`.gltf` + `.bin` + images, and `.glb`) into a triangle soup.
//!
//! Every mesh primitive of the default scene (or of the first scene) is instanced through its
//! node's world transform. Vertex colour is `baseColorFactor x COLOR_0 x baseColorTexture`, the
//! texture being sampled once per vertex (nearest texel, sRGB decoded to linear, UV set of the
//! texture info, wrap-repeat): the OIT pipeline then needs no texture bindings and the CPU and GPU
//! shade identically. Alpha follows the material's `alphaMode` (OPAQUE -> 1, MASK -> 0 or 1 by
//! the cutoff, BLEND -> alpha); the scene's [`super::Opacity`] may override it afterwards.
//!
//! Every accessor is bounds-checked before it is read, so a truncated or inconsistent file is an
//! error naming the problem, never a panic.

use super::{Scene, SceneFault};
use crate::error::{Error, Result};
use glam::{Mat4, Vec3};
use gltf::mesh::Mode;
use std::collections::HashMap;
use std::path::Path;

pub fn load(path: &Path) -> Result<Scene> {
    let bytes = std::fs::read(path).map_err(|e| Error::read(path, e))?;
    from_slice(&bytes, path)
}

/// Loads a glTF or GLB file's bytes; `path` names it in errors, and external buffers and
/// images are looked up beside it.
pub fn from_slice(bytes: &[u8], path: &Path) -> Result<Scene> {
    let err = |m: String| Error::scene(path, m);
    precheck(bytes, path)?;
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| err(format!("not a valid glTF: {e}")))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let buffers = gltf::import_buffers(&gltf.document, Some(base), gltf.blob.clone())
        .map_err(|e| err(format!("cannot load buffers: {e}")))?;
    for (i, (buf, data)) in gltf.document.buffers().zip(&buffers).enumerate() {
        if data.len() < buf.length() {
            return Err(err(format!(
                "buffer {i} holds {} bytes but declares {}",
                data.len(),
                buf.length()
            )));
        }
    }
    let doc = &gltf.document;
    let gscene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| err("the file has no scene".into()))?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "gltf".into());
    let mut loader = Loader {
        path,
        base,
        buffers: &buffers,
        textures: HashMap::new(),
        scene: Scene {
            name,
            ..Scene::default()
        },
    };
    let mut stack: Vec<(gltf::Node, Mat4, usize)> =
        gscene.nodes().map(|n| (n, Mat4::IDENTITY, 0)).collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > 64 {
            return Err(err("node hierarchy deeper than 64 (a cycle?)".into()));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                loader.primitive(&prim, world)?;
            }
        }
        for child in node.children() {
            stack.push((child, world, depth + 1));
        }
    }
    Ok(loader.scene)
}

/// What the gltf crate's validation reads before checking it: its POSITION check indexes the
/// accessor list with the attribute's index unchecked (gltf-json 1.4.1, mesh.rs), so a file
/// whose POSITION names an accessor that does not exist panicked (found by tests/fuzz.rs).
/// Anything this cannot parse is left to the crate, which reports it.
fn precheck(bytes: &[u8], path: &Path) -> Result<()> {
    let json: std::borrow::Cow<[u8]> = if bytes.starts_with(b"glTF") {
        match gltf::Glb::from_slice(bytes) {
            Ok(glb) => glb.json,
            Err(_) => return Ok(()),
        }
    } else {
        bytes.into()
    };
    let Ok(root) = serde_json::from_slice::<gltf::json::Root>(&json) else {
        return Ok(());
    };
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for index in prim.attributes.values() {
                if index.value() >= root.accessors.len() {
                    return Err(Error::scene(
                        path,
                        format!(
                            "not a valid glTF: mesh {m} primitive {p} names accessor {} of {}",
                            index.value(),
                            root.accessors.len()
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// A decoded base colour texture: linear RGBA.
struct Texture {
    width: u32,
    height: u32,
    texels: Vec<[f32; 4]>,
}

impl Texture {
    fn sample(&self, uv: [f32; 2]) -> [f32; 4] {
        let u = uv[0] - uv[0].floor();
        let v = uv[1] - uv[1].floor();
        let x = ((u * self.width as f32) as u32).min(self.width - 1);
        let y = ((v * self.height as f32) as u32).min(self.height - 1);
        self.texels[(y * self.width + x) as usize]
    }
}

struct Loader<'a> {
    path: &'a Path,
    base: &'a Path,
    buffers: &'a [gltf::buffer::Data],
    textures: HashMap<usize, Texture>,
    scene: Scene,
}

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl Loader<'_> {
    fn err(&self, m: impl Into<String>) -> Error {
        Error::scene(self.path, m)
    }

    /// Checks the component types and dimensions of the attributes read, which the gltf
    /// crate's readers assume valid (they reach `unreachable!()` otherwise: found by
    /// tests/fuzz.rs): POSITION f32 VEC3, COLOR_0 u8/u16/f32 VEC3/VEC4, TEXCOORD u8/u16/f32
    /// VEC2, indices u8/u16/u32 SCALAR.
    fn check_types(&self, prim: &gltf::Primitive) -> Result<()> {
        use gltf::accessor::{DataType as T, Dimensions as D};
        let check = |what: String, acc: gltf::Accessor, ok: &dyn Fn(T, D) -> bool| {
            if ok(acc.data_type(), acc.dimensions()) {
                Ok(())
            } else {
                Err(self.err(format!(
                    "{what} is {:?} {:?}, which glTF does not allow there",
                    acc.data_type(),
                    acc.dimensions()
                )))
            }
        };
        for (sem, acc) in prim.attributes() {
            match sem {
                gltf::Semantic::Positions => {
                    check("POSITION".into(), acc, &|t, d| t == T::F32 && d == D::Vec3)?
                }
                gltf::Semantic::Colors(i) => check(format!("COLOR_{i}"), acc, &|t, d| {
                    matches!(t, T::U8 | T::U16 | T::F32) && matches!(d, D::Vec3 | D::Vec4)
                })?,
                gltf::Semantic::TexCoords(i) => check(format!("TEXCOORD_{i}"), acc, &|t, d| {
                    matches!(t, T::U8 | T::U16 | T::F32) && d == D::Vec2
                })?,
                _ => {}
            }
        }
        if let Some(acc) = prim.indices() {
            check("the indices".into(), acc, &|t, d| {
                matches!(t, T::U8 | T::U16 | T::U32) && d == D::Scalar
            })?;
        }
        Ok(())
    }

    /// Checks that an accessor's elements all lie inside its buffer view and buffer.
    fn check_accessor(&self, acc: &gltf::Accessor) -> Result<()> {
        let Some(view) = acc.view() else {
            return Err(self.err(format!(
                "accessor {} has no buffer view (sparse-only accessors are not supported)",
                acc.index()
            )));
        };
        let data = &self.buffers[view.buffer().index()];
        if view.offset() + view.length() > data.len() {
            return Err(self.err(format!(
                "buffer view {} ends at byte {} but its buffer has {} bytes",
                view.index(),
                view.offset() + view.length(),
                data.len()
            )));
        }
        let elem = acc.size();
        let stride = view.stride().unwrap_or(elem);
        if acc.count() > 0 && acc.offset() + stride * (acc.count() - 1) + elem > view.length() {
            return Err(self.err(format!(
                "accessor {} ({} elements) overruns buffer view {}",
                acc.index(),
                acc.count(),
                view.index()
            )));
        }
        Ok(())
    }

    fn texture(&mut self, tex: &gltf::Texture) -> Result<&Texture> {
        let idx = tex.source().index();
        if !self.textures.contains_key(&idx) {
            let data = gltf::image::Data::from_source(
                tex.source().source(),
                Some(self.base),
                self.buffers,
            )
            .map_err(|e| self.err(format!("cannot decode image {idx}: {e}")))?;
            let texels = to_rgba(&data).ok_or_else(|| {
                self.err(format!(
                    "image {idx} has an unsupported pixel format {:?}",
                    data.format
                ))
            })?;
            if data.width == 0 || data.height == 0 {
                return Err(self.err(format!("image {idx} is empty")));
            }
            self.textures.insert(
                idx,
                Texture {
                    width: data.width,
                    height: data.height,
                    texels,
                },
            );
        }
        Ok(&self.textures[&idx])
    }

    fn primitive(&mut self, prim: &gltf::Primitive, world: Mat4) -> Result<()> {
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            return Ok(()); // points and lines produce no surfaces
        }
        let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else {
            return Err(self.err("a mesh primitive has no POSITION attribute"));
        };
        self.check_accessor(&pos_acc)?;
        for (_, acc) in prim.attributes() {
            self.check_accessor(&acc)?;
        }
        if let Some(acc) = prim.indices() {
            self.check_accessor(&acc)?;
        }
        self.check_types(prim)?;
        let buffers = self.buffers;
        let reader = prim.reader(|b| Some(&buffers[b.index()].0[..]));
        let positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| self.err("cannot read POSITION"))?
            .map(|p| world.transform_point3(Vec3::from(p)))
            .collect();
        let n = positions.len();
        let mut colors: Vec<[f32; 4]> = match reader.read_colors(0) {
            Some(c) => c.into_rgba_f32().collect(),
            None => vec![[1.0; 4]; n],
        };
        if colors.len() != n {
            return Err(self.err("COLOR_0 and POSITION have different counts"));
        }
        let material = prim.material();
        let pbr = material.pbr_metallic_roughness();
        let factor = pbr.base_color_factor();
        let tex_info = pbr.base_color_texture();
        let uvs: Option<Vec<[f32; 2]>> = tex_info
            .as_ref()
            .and_then(|t| reader.read_tex_coords(t.tex_coord()))
            .map(|t| t.into_f32().collect());
        if let (Some(info), Some(uvs)) = (tex_info, uvs) {
            if uvs.len() != n {
                return Err(self.err("TEXCOORD and POSITION have different counts"));
            }
            let tex = self.texture(&info.texture())?;
            for (c, uv) in colors.iter_mut().zip(&uvs) {
                let t = tex.sample(*uv);
                for i in 0..4 {
                    c[i] *= t[i];
                }
            }
        }
        let (mode_alpha, cutoff) = match material.alpha_mode() {
            gltf::material::AlphaMode::Opaque => (Some(1.0), None),
            gltf::material::AlphaMode::Mask => (None, Some(material.alpha_cutoff().unwrap_or(0.5))),
            gltf::material::AlphaMode::Blend => (None, None),
        };
        for c in &mut colors {
            for i in 0..4 {
                c[i] *= factor[i];
            }
            if let Some(a) = mode_alpha {
                c[3] = a;
            }
            if let Some(cut) = cutoff {
                c[3] = if c[3] >= cut { 1.0 } else { 0.0 };
            }
        }
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..n as u32).collect(),
        };
        if let Some(bad) = indices.iter().find(|&&i| i as usize >= n) {
            return Err(self.err(format!(
                "index {bad} is out of range: the primitive has {n} vertices"
            )));
        }
        let tri = |a: u32, b: u32, c: u32| [a as usize, b as usize, c as usize];
        let tris: Vec<[usize; 3]> = match mode {
            Mode::Triangles => indices
                .chunks_exact(3)
                .map(|t| tri(t[0], t[1], t[2]))
                .collect(),
            Mode::TriangleStrip => (2..indices.len())
                .map(|i| {
                    if i % 2 == 0 {
                        tri(indices[i - 2], indices[i - 1], indices[i])
                    } else {
                        tri(indices[i - 1], indices[i - 2], indices[i])
                    }
                })
                .collect(),
            _ => (2..indices.len())
                .map(|i| tri(indices[0], indices[i - 1], indices[i]))
                .collect(),
        };
        for t in tris {
            self.scene.push_triangle(
                [positions[t[0]], positions[t[1]], positions[t[2]]],
                [colors[t[0]], colors[t[1]], colors[t[2]]],
            );
        }
        Ok(())
    }
}

/// Converts decoded image data into linear RGBA (colour channels sRGB-decoded).
fn to_rgba(data: &gltf::image::Data) -> Option<Vec<[f32; 4]>> {
    use gltf::image::Format;
    let px = &data.pixels;
    let lin = |v: u8| srgb_to_linear(v as f32 / 255.0);
    let out: Vec<[f32; 4]> = match data.format {
        Format::R8 => px.iter().map(|&r| [lin(r), lin(r), lin(r), 1.0]).collect(),
        Format::R8G8 => px
            .chunks_exact(2)
            .map(|p| [lin(p[0]), lin(p[0]), lin(p[0]), p[1] as f32 / 255.0])
            .collect(),
        Format::R8G8B8 => px
            .chunks_exact(3)
            .map(|p| [lin(p[0]), lin(p[1]), lin(p[2]), 1.0])
            .collect(),
        Format::R8G8B8A8 => px
            .chunks_exact(4)
            .map(|p| [lin(p[0]), lin(p[1]), lin(p[2]), p[3] as f32 / 255.0])
            .collect(),
        _ => return None,
    };
    (out.len() == (data.width * data.height) as usize).then_some(out)
}

/// Writes a scene as a binary glTF 2.0 file (`.glb`): one node, one mesh, one primitive of
/// unindexed triangles in submission order with `POSITION` (f32 VEC3) and `COLOR_0` (f32 VEC4,
/// linear, non-premultiplied), and a white `BLEND` material, so [`load`] with the material's
/// alpha gives back the same triangles and colours bit for bit. Written to a temporary file and
/// renamed, so a failed export leaves no half-written file.
pub fn export(scene: &Scene, path: &Path) -> Result<()> {
    let bytes = to_glb(scene).map_err(|f| Error::scene(path, f.to_string()))?;
    crate::tensors::write_atomic(path, &bytes)
}

/// The `.glb` bytes of a scene (see [`export`]).
pub fn to_glb(scene: &Scene) -> std::result::Result<Vec<u8>, SceneFault> {
    let n = scene.positions.len();
    if n == 0 || !n.is_multiple_of(3) || scene.colors.len() != n {
        return Err(SceneFault::Unpaired {
            positions: n,
            colors: scene.colors.len(),
        });
    }
    if let Some(vertex) = scene.positions.iter().position(|p| !p.is_finite()) {
        return Err(SceneFault::NonFinite {
            vertex,
            position: scene.positions[vertex],
        });
    }
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in &scene.positions {
        for (c, v) in p.to_array().into_iter().enumerate() {
            lo[c] = lo[c].min(v);
            hi[c] = hi[c].max(v);
        }
    }
    let mut bin: Vec<u8> = Vec::with_capacity(n * 28);
    bin.extend(
        scene
            .positions
            .iter()
            .flat_map(|p| p.to_array())
            .flat_map(f32::to_le_bytes),
    );
    let pos_len = bin.len();
    bin.extend(scene.colors.iter().flatten().flat_map(|c| c.to_le_bytes()));
    let col_len = bin.len() - pos_len;
    let json = serde_json::json!({
        "asset": {"version": "2.0", "generator": "dhoit export"},
        "scene": 0,
        "scenes": [{"name": scene.name, "nodes": [0]}],
        "nodes": [{"mesh": 0, "name": scene.name}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "COLOR_0": 1},
            "material": 0,
            "mode": 4
        }]}],
        "materials": [{
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0]},
            "alphaMode": "BLEND",
            "doubleSided": true
        }],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
             "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC4"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": pos_len},
            {"buffer": 0, "byteOffset": pos_len, "byteLength": col_len}
        ],
        "buffers": [{"byteLength": bin.len()}]
    });
    let mut json = serde_json::to_vec(&json).expect("a serde_json::Value always serialises");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let total = u32::try_from(total).map_err(|_| SceneFault::TooBigForGlb { bytes: total })?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend(total.to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    Ok(out)
}
