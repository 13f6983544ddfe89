//! glTF 2.0 loading (`.gltf` + `.bin` + images, and `.glb`) into a triangle soup.
//!
//! Every mesh primitive of the default scene (or of the first scene) is instanced through its
//! node's world transform; the scene's first perspective camera is its viewpoint. Each vertex keeps its `COLOR_0` and the texture coordinates its
//! material's textures read (`KHR_texture_transform` applied, an affine map, so it commutes with
//! perspective-correct interpolation); each triangle its material: base colour factor and
//! texture with its sampler's wrap modes and magnification filter, `alphaMode` and
//! `alphaCutoff`, `doubleSided`, `KHR_materials_transmission`'s factor and texture,
//! `emissiveFactor`, `emissiveTexture` and `KHR_materials_emissive_strength`,
//! `KHR_materials_volume`'s attenuation colour, distance and thickness factor, and
//! `KHR_materials_ior` (see [`super::material`] for what a fragment of each is). Images are
//! decoded to RGBA8 and box-filtered down to [`MAX_TEXTURE_SIDE`] a side. A primitive without a material takes glTF's
//! default material (white, OPAQUE, single-sided).
//!
//! Every accessor is bounds-checked before it is read, so a truncated or inconsistent file is an
//! error naming the problem, never a panic.

use super::material::{self, Coverage, MAX_TEXTURE_SIDE, Material, Texture, Wrap};
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
        materials: HashMap::new(),
        scene: Scene {
            name,
            materials: Vec::new(),
            ..Scene::default()
        },
    };
    // Every material in the file's order (so a scene written by `export` reads back with the
    // same indices), the default one (for primitives without one) after them where used.
    for m in doc.materials() {
        loader.material(&m)?;
    }
    let mut stack: Vec<(gltf::Node, Mat4, usize)> =
        gscene.nodes().map(|n| (n, Mat4::IDENTITY, 0)).collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > 64 {
            return Err(err("node hierarchy deeper than 64 (a cycle?)".into()));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(camera) = node.camera()
            && let gltf::camera::Projection::Perspective(p) = camera.projection()
            && loader.scene.viewpoint.is_none()
        {
            loader.scene.viewpoint = Some(super::Viewpoint {
                eye: world.transform_point3(Vec3::ZERO),
                forward: world.transform_vector3(Vec3::NEG_Z).normalize(),
                up: world.transform_vector3(Vec3::Y).normalize(),
                yfov: p.yfov(),
            });
        }
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

struct Loader<'a> {
    path: &'a Path,
    base: &'a Path,
    buffers: &'a [gltf::buffer::Data],
    /// glTF texture index -> the scene's.
    textures: HashMap<usize, u32>,
    /// glTF material index (None: the default material) -> the scene's.
    materials: HashMap<Option<usize>, u32>,
    scene: Scene,
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

    /// The scene's texture for a glTF texture (its image and sampler), decoded on first use.
    fn texture(&mut self, tex: &gltf::Texture) -> Result<u32> {
        if let Some(&t) = self.textures.get(&tex.index()) {
            return Ok(t);
        }
        let idx = tex.source().index();
        // The image's file, where it has one, named in the error.
        let name = match tex.source().source() {
            gltf::image::Source::Uri { uri, .. } => format!(" ({uri})"),
            gltf::image::Source::View { .. } => String::new(),
        };
        let data =
            gltf::image::Data::from_source(tex.source().source(), Some(self.base), self.buffers)
                .map_err(|e| self.err(format!("cannot decode image {idx}{name}: {e}")))?;
        if data.width == 0 || data.height == 0 {
            return Err(self.err(format!("image {idx} is empty")));
        }
        let texels = to_rgba8(&data).ok_or_else(|| {
            self.err(format!(
                "image {idx} has an unsupported pixel format {:?}",
                data.format
            ))
        })?;
        use gltf::texture::{MagFilter, WrappingMode};
        let sampler = tex.sampler();
        let wrap = |m: WrappingMode| match m {
            WrappingMode::Repeat => Wrap::Repeat,
            WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
            WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        };
        let texture = Texture {
            width: data.width,
            height: data.height,
            texels,
            wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
            nearest: sampler.mag_filter() == Some(MagFilter::Nearest),
        }
        .limited(MAX_TEXTURE_SIDE);
        let t = self.scene.add_texture(texture);
        self.textures.insert(tex.index(), t);
        Ok(t)
    }

    /// The scene's material for a primitive's, added on first use, and the texture
    /// coordinate set and transform its base colour texture reads.
    fn material(&mut self, m: &gltf::Material) -> Result<(u32, UvSet)> {
        let pbr = m.pbr_metallic_roughness();
        let info = pbr.base_color_texture();
        let transmission = m.transmission();
        let transmission_info = transmission.as_ref().and_then(|t| t.transmission_texture());
        let emissive_info = m.emissive_texture();
        // The vertices' one set: the base colour texture's, else the transmission texture's,
        // else the emissive texture's (material.rs).
        let uv = match info
            .as_ref()
            .or(transmission_info.as_ref())
            .or(emissive_info.as_ref())
        {
            Some(i) => {
                let t = i.texture_transform();
                UvSet {
                    set: t
                        .as_ref()
                        .and_then(|t| t.tex_coord())
                        .unwrap_or(i.tex_coord()),
                    transform: t.map(|t| (t.offset(), t.rotation(), t.scale())),
                }
            }
            None => UvSet::default(),
        };
        if let Some(&i) = self.materials.get(&m.index()) {
            return Ok((i, uv));
        }
        let texture = match &info {
            Some(i) => Some(self.texture(&i.texture())?),
            None => None,
        };
        let transmission_texture = match &transmission_info {
            Some(i) => Some(self.texture(&i.texture())?),
            None => None,
        };
        let emissive_texture = match &emissive_info {
            Some(i) => Some(self.texture(&i.texture())?),
            None => None,
        };
        let strength = m.emissive_strength().unwrap_or(1.0);
        let emissive = m.emissive_factor().map(|e| e * strength);
        let coverage = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => Coverage::Opaque,
            gltf::material::AlphaMode::Mask => Coverage::Mask(m.alpha_cutoff().unwrap_or(0.5)),
            gltf::material::AlphaMode::Blend => Coverage::Blend,
        };
        let mat = Material {
            base_color: pbr.base_color_factor(),
            texture,
            coverage,
            transmission: transmission.map_or(0.0, |t| t.transmission_factor()),
            transmission_texture,
            emissive,
            emissive_texture,
            attenuation: attenuation(m.volume()),
            ior: m.ior().unwrap_or(material::DEFAULT_IOR),
            double_sided: m.double_sided(),
        };
        let i = self.scene.add_material(mat);
        self.materials.insert(m.index(), i);
        Ok((i, uv))
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
        let colors: Vec<[f32; 4]> = match reader.read_colors(0) {
            Some(c) => c.into_rgba_f32().collect(),
            None => vec![[1.0; 4]; n],
        };
        if colors.len() != n {
            return Err(self.err("COLOR_0 and POSITION have different counts"));
        }
        let (material, uv_set) = self.material(&prim.material())?;
        // The set the base colour texture reads (else set 0), where the primitive has it.
        let uvs: Vec<[f32; 2]> = match reader.read_tex_coords(uv_set.set) {
            Some(t) => t.into_f32().map(|uv| uv_set.apply(uv)).collect(),
            None => vec![[0.0; 2]; n],
        };
        if uvs.len() != n {
            return Err(self.err(format!(
                "TEXCOORD_{} and POSITION have different counts",
                uv_set.set
            )));
        }
        if let Some(v) = uvs.iter().position(|uv| !uv.iter().all(|c| c.is_finite())) {
            return Err(self.err(format!(
                "vertex {v} has texture coordinates that are not finite: {:?}",
                uvs[v]
            )));
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
            self.scene.push_textured(
                t.map(|i| positions[i]),
                t.map(|i| colors[i]),
                t.map(|i| uvs[i]),
                material,
            );
        }
        Ok(())
    }
}

/// The texture coordinate set a base colour texture reads, and its `KHR_texture_transform`
/// (offset, rotation, scale).
#[derive(Clone, Copy, Debug, Default)]
struct UvSet {
    set: u32,
    transform: Option<([f32; 2], f32, [f32; 2])>,
}

impl UvSet {
    /// `offset + R(rotation) S(scale) uv`, as the extension defines it.
    fn apply(&self, uv: [f32; 2]) -> [f32; 2] {
        let Some((o, r, s)) = self.transform else {
            return uv;
        };
        let (sin, cos) = r.sin_cos();
        let (u, v) = (s[0] * uv[0], s[1] * uv[1]);
        [o[0] + cos * u + sin * v, o[1] - sin * u + cos * v]
    }
}

/// Decoded image data as RGBA8 texels (R in the low byte), as stored: colour sRGB-encoded.
fn to_rgba8(data: &gltf::image::Data) -> Option<Vec<u32>> {
    use gltf::image::Format;
    let px = &data.pixels;
    let word = |r: u8, g: u8, b: u8, a: u8| u32::from_le_bytes([r, g, b, a]);
    let out: Vec<u32> = match data.format {
        Format::R8 => px.iter().map(|&r| word(r, r, r, 255)).collect(),
        Format::R8G8 => px
            .chunks_exact(2)
            .map(|p| word(p[0], p[0], p[0], p[1]))
            .collect(),
        Format::R8G8B8 => px
            .chunks_exact(3)
            .map(|p| word(p[0], p[1], p[2], 255))
            .collect(),
        Format::R8G8B8A8 => px
            .chunks_exact(4)
            .map(|p| word(p[0], p[1], p[2], p[3]))
            .collect(),
        // 16-bit channels: each one's high byte (the decoder's bytes are little-endian).
        Format::R16 => px
            .chunks_exact(2)
            .map(|p| word(p[1], p[1], p[1], 255))
            .collect(),
        Format::R16G16 => px
            .chunks_exact(4)
            .map(|p| word(p[1], p[1], p[1], p[3]))
            .collect(),
        Format::R16G16B16 => px
            .chunks_exact(6)
            .map(|p| word(p[1], p[3], p[5], 255))
            .collect(),
        Format::R16G16B16A16 => px
            .chunks_exact(8)
            .map(|p| word(p[1], p[3], p[5], p[7]))
            .collect(),
        _ => return None,
    };
    (out.len() == (data.width * data.height) as usize).then_some(out)
}

/// Writes a scene as a binary glTF 2.0 file (`.glb`): one node and one mesh, a primitive for
/// each run of triangles of one material in submission order (unindexed, `POSITION` f32 VEC3,
/// `COLOR_0` f32 VEC4 linear non-premultiplied, `TEXCOORD_0` f32 VEC2), the materials (base
/// colour factor and texture, alpha mode and cutoff, double-sidedness, transmission and IOR)
/// and their textures as PNG images with their samplers, so [`load`] gives back the same
/// triangles, colours, coordinates, materials and texels bit for bit. A scene under one uniform
/// opacity keeps it in every vertex alpha. Written to a temporary file and renamed, so a failed
/// export leaves no half-written file.
pub fn export(scene: &Scene, path: &Path) -> Result<()> {
    let bytes = to_glb(scene).map_err(|f| Error::scene(path, f.to_string()))?;
    crate::tensors::write_atomic(path, &bytes)
}

/// The `.glb` bytes of a scene (see [`export`]).
pub fn to_glb(scene: &Scene) -> std::result::Result<Vec<u8>, SceneFault> {
    use serde_json::{Value, json};
    check_exportable(scene)?;
    let n = scene.positions.len();
    let mut bin: Vec<u8> = Vec::with_capacity(n * 36);
    let mut views: Vec<Value> = Vec::new();
    let mut accessors: Vec<Value> = Vec::new();
    // A buffer view of `bytes`, 4-byte aligned; returns its index.
    let mut view = |bin: &mut Vec<u8>, bytes: &[u8]| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len()}));
        bin.extend_from_slice(bytes);
        views.len() - 1
    };
    let mut primitives = Vec::new();
    let tris = scene.triangle_count();
    let mut t0 = 0;
    while t0 < tris {
        let m = scene.triangle_material[t0];
        let t1 = (t0..tris)
            .find(|&t| scene.triangle_material[t] != m)
            .unwrap_or(tris);
        let (v0, v1) = (3 * t0, 3 * t1);
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for p in &scene.positions[v0..v1] {
            for (c, v) in p.to_array().into_iter().enumerate() {
                lo[c] = lo[c].min(v);
                hi[c] = hi[c].max(v);
            }
        }
        let pos: Vec<u8> = scene.positions[v0..v1]
            .iter()
            .flat_map(|p| p.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        let col: Vec<u8> = scene.colors[v0..v1]
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let uv: Vec<u8> = scene.uvs[v0..v1]
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let count = v1 - v0;
        let a = accessors.len();
        accessors.push(
            json!({"bufferView": view(&mut bin, &pos), "componentType": 5126,
            "count": count, "type": "VEC3", "min": lo, "max": hi}),
        );
        accessors.push(
            json!({"bufferView": view(&mut bin, &col), "componentType": 5126,
            "count": count, "type": "VEC4"}),
        );
        accessors.push(
            json!({"bufferView": view(&mut bin, &uv), "componentType": 5126,
            "count": count, "type": "VEC2"}),
        );
        primitives.push(json!({
            "attributes": {"POSITION": a, "COLOR_0": a + 1, "TEXCOORD_0": a + 2},
            "material": m,
            "mode": 4
        }));
        t0 = t1;
    }
    let mut images = Vec::new();
    let mut samplers = Vec::new();
    let mut textures = Vec::new();
    for (i, t) in scene.textures.iter().enumerate() {
        let png = png_bytes(t);
        images.push(json!({"bufferView": view(&mut bin, &png), "mimeType": "image/png"}));
        let wrap = |w: Wrap| match w {
            Wrap::Repeat => 10497,
            Wrap::MirroredRepeat => 33648,
            Wrap::ClampToEdge => 33071,
        };
        samplers.push(json!({
            "magFilter": if t.nearest { 9728 } else { 9729 },
            "wrapS": wrap(t.wrap[0]),
            "wrapT": wrap(t.wrap[1])
        }));
        textures.push(json!({"source": i, "sampler": i}));
    }
    let mut used = std::collections::BTreeSet::new();
    let materials: Vec<Value> = scene
        .materials
        .iter()
        .map(|m| material_json(m, &mut used))
        .collect();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let mut root = json!({
        "asset": {"version": "2.0", "generator": "dhoit export"},
        "scene": 0,
        "scenes": [{"name": scene.name, "nodes": [0]}],
        "nodes": [{"mesh": 0, "name": scene.name}],
        "meshes": [{"primitives": primitives}],
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}]
    });
    if !textures.is_empty() {
        root["images"] = json!(images);
        root["samplers"] = json!(samplers);
        root["textures"] = json!(textures);
    }
    if !used.is_empty() {
        root["extensionsUsed"] = json!(used);
    }
    let json = serde_json::to_vec(&root).expect("a serde_json::Value always serialises");
    glb_container(json, bin)
}

/// What a scene must be to be written as glTF: whole triangles with a colour a vertex, finite
/// positions, materials whose references hold.
fn check_exportable(scene: &Scene) -> std::result::Result<(), SceneFault> {
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
    scene.check_materials()
}

/// The GLB container of a glTF document: its 12-byte header, the JSON chunk (padded with
/// spaces to 4 bytes) and the binary chunk (`bin`, already padded), refused past 4 GiB.
fn glb_container(mut json: Vec<u8>, bin: Vec<u8>) -> std::result::Result<Vec<u8>, SceneFault> {
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
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

/// A material as glTF writes it, and the extensions it uses into `used`: base colour factor and
/// texture, alpha mode and cutoff, double-sidedness, transmission (factor and texture),
/// emission (its factor at most 1, what is brighter its strength, and its texture), volume
/// attenuation and IOR.
fn material_json(m: &Material, used: &mut std::collections::BTreeSet<String>) -> serde_json::Value {
    use serde_json::{Value, json};
    let mut pbr = json!({"baseColorFactor": m.base_color});
    if let Some(t) = m.texture {
        pbr["baseColorTexture"] = json!({"index": t});
    }
    let mut mat = json!({"pbrMetallicRoughness": pbr, "doubleSided": m.double_sided});
    match m.coverage {
        Coverage::Opaque => mat["alphaMode"] = json!("OPAQUE"),
        Coverage::Mask(c) => {
            mat["alphaMode"] = json!("MASK");
            mat["alphaCutoff"] = json!(c);
        }
        Coverage::Blend => mat["alphaMode"] = json!("BLEND"),
    }
    let mut ext = serde_json::Map::new();
    if m.transmission > 0.0 {
        let mut t = json!({"transmissionFactor": m.transmission});
        if let Some(i) = m.transmission_texture {
            t["transmissionTexture"] = json!({"index": i});
        }
        ext.insert("KHR_materials_transmission".into(), t);
    }
    if m.emissive != [0.0; 3] {
        // emissiveFactor is at most 1: what is brighter is its strength.
        let strength = m.emissive.into_iter().fold(1.0f32, f32::max);
        mat["emissiveFactor"] = json!(m.emissive.map(|e| e / strength));
        if strength > 1.0 {
            ext.insert(
                "KHR_materials_emissive_strength".into(),
                json!({"emissiveStrength": strength}),
            );
        }
        if let Some(i) = m.emissive_texture {
            mat["emissiveTexture"] = json!({"index": i});
        }
    }
    if m.attenuation != [1.0; 3] {
        // One crossing's attenuation is the colour at a thickness of twice the
        // distance: attenuationColor^(thickness / (2 distance)) with 1 / (2 x 0.5).
        ext.insert(
            "KHR_materials_volume".into(),
            json!({"thicknessFactor": 1.0, "attenuationDistance": 0.5,
                   "attenuationColor": m.attenuation}),
        );
    }
    if m.ior != material::DEFAULT_IOR {
        ext.insert("KHR_materials_ior".into(), json!({"ior": m.ior}));
    }
    used.extend(ext.keys().cloned());
    if !ext.is_empty() {
        mat["extensions"] = Value::Object(ext);
    }
    mat
}

/// A texture's texels as PNG bytes (RGBA8, as stored).
fn png_bytes(t: &Texture) -> Vec<u8> {
    use image::ImageEncoder;
    let raw: Vec<u8> = t.texels.iter().flat_map(|v| v.to_le_bytes()).collect();
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&raw, t.width, t.height, image::ExtendedColorType::Rgba8)
        .expect("an RGBA8 image of its own size encodes to memory");
    out
}

/// What `KHR_materials_volume` lets through one crossing of a surface
/// ([`Material::attenuation`]): `attenuationColor^(thicknessFactor / (2 attenuationDistance))`,
/// white where there is no volume, no thickness or an infinite distance (its default).
fn attenuation(volume: Option<gltf::material::Volume>) -> [f32; 3] {
    let Some(v) = volume else {
        return [1.0; 3];
    };
    let (d, t) = (v.attenuation_distance(), v.thickness_factor());
    if !(d.is_finite() && d > 0.0 && t > 0.0) {
        return [1.0; 3];
    }
    v.attenuation_color()
        .map(|c| c.clamp(0.0, 1.0).powf(t / (2.0 * d)))
}
