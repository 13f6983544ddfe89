//! Scenes: triangle soups with per-vertex non-premultiplied RGBA and texture coordinates, a
//! material per triangle (glTF's: [`material`]), from glTF files or built-in procedural
//! generators, and the deterministic orbit cameras they are seen from.
//!
//! A scene is stored unindexed (three vertices per triangle, in submission order), which is what
//! both the CPU rasterizer and the GPU's vertex stage (pulling vertices by index) consume;
//! `shuffled` permutes whole triangles to test order independence.

pub mod gltf;
pub mod material;
pub mod procedural;

pub use material::{Coverage, Glass, Material, Texture, Wrap};

use crate::error::{Error, Result};
use crate::rng::Rng;
use glam::{Mat4, Vec3};
use std::path::Path;

/// Largest bounding radius a scene may have: beyond it a float keeps no depth precision.
pub const MAX_RADIUS: f32 = 1e18;

/// Why a scene cannot be rendered.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SceneFault {
    #[error("the scene has no triangles")]
    NoTriangles,
    #[error(
        "its camera cannot see: eye {eye:?}, forward {forward:?}, up {up:?}, vertical field of view {yfov} rad (finite, a direction and an up apart, the field of view in (0, pi))"
    )]
    BadViewpoint {
        eye: Vec3,
        forward: Vec3,
        up: Vec3,
        yfov: f32,
    },
    #[error("vertex {vertex} (triangle {}) has a position that is not finite: {position:?}", vertex / 3)]
    NonFinite { vertex: usize, position: Vec3 },
    #[error(
        "coordinates too large: the scene's bounding radius is {radius:e} (at most {MAX_RADIUS:e})"
    )]
    TooLarge { radius: f32 },
    #[error("every one of its {triangles} triangles is degenerate (zero area): nothing to draw")]
    Degenerate { triangles: usize },
    #[error("{positions} positions and {colors} colours do not make whole triangles")]
    Unpaired { positions: usize, colors: usize },
    #[error("{bytes} bytes exceed a GLB's 4 GiB")]
    TooBigForGlb { bytes: usize },
    #[error(
        "{triangles} triangles, {uvs} texture coordinates and {materials} triangle materials do not match"
    )]
    Unmatched {
        triangles: usize,
        uvs: usize,
        materials: usize,
    },
    #[error("triangle {triangle} names material {material} of {materials}")]
    NoSuchMaterial {
        triangle: usize,
        material: u32,
        materials: usize,
    },
    #[error("material {material} names texture {texture} of {textures}")]
    NoSuchTexture {
        material: usize,
        texture: u32,
        textures: usize,
    },
    #[error("texture {texture} is {width}x{height} with {texels} texels")]
    BadTexture {
        texture: usize,
        width: u32,
        height: u32,
        texels: usize,
    },
    #[error("vertex {vertex} has texture coordinates that are not finite: {uv:?}")]
    NonFiniteUv { vertex: usize, uv: [f32; 2] },
    #[error("material {material} has a value that is not finite or out of range: {what}")]
    BadMaterial { material: usize, what: String },
}

/// The opacity of the papers' protocol: every surface transparent with this one opacity.
pub const PAPER_OPACITY: f32 = 0.33;

/// How fragment opacity is decided.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Opacity {
    /// Every surface is transparent with this one opacity (the papers' protocol; the reference
    /// implementation uses [`PAPER_OPACITY`]).
    Uniform(f32),
    /// The materials decide ([`material`]): opaque, masked, blended and glass surfaces.
    Material,
    /// The scene's own: its materials for glTF files and the built-in material families, one
    /// opacity of [`PAPER_OPACITY`] for the papers' built-in families.
    #[default]
    Native,
}

/// A triangle soup: `positions.len() == colors.len() == uvs.len() == 3 * triangle_count()`,
/// `triangle_material.len() == triangle_count()`.
#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    pub positions: Vec<Vec3>,
    /// Non-premultiplied linear RGBA per vertex (glTF's COLOR_0).
    pub colors: Vec<[f32; 4]>,
    /// Texture coordinates per vertex, of the material's base colour texture (zero where the
    /// material has none).
    pub uvs: Vec<[f32; 2]>,
    /// Per triangle, its material's index in `materials`.
    pub triangle_material: Vec<u32>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    /// One opacity for every surface (the papers' protocol), or `None`: the materials decide.
    pub uniform_opacity: Option<f32>,
    /// How its glass transmits: one grey opacity, or filtering per channel.
    pub glass: Glass,
    /// The viewpoint the file gives (a glTF's first camera in its scene), where it gives one.
    pub viewpoint: Option<Viewpoint>,
}

/// A camera a scene file gives: where it stands, where it looks, its up, its vertical field of
/// view (radians). [`Camera::asset`] sees through it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Viewpoint {
    pub eye: Vec3,
    pub forward: Vec3,
    pub up: Vec3,
    pub yfov: f32,
}

impl Default for Scene {
    /// No triangles, one default material ([`Material::default`]), the materials deciding.
    fn default() -> Self {
        Scene {
            name: String::new(),
            positions: Vec::new(),
            colors: Vec::new(),
            uvs: Vec::new(),
            triangle_material: Vec::new(),
            materials: vec![Material::default()],
            textures: Vec::new(),
            uniform_opacity: None,
            glass: Glass::Grey,
            viewpoint: None,
        }
    }
}

impl Scene {
    /// Whether any of its fragments can be tinted: glass that filters per channel
    /// ([`Glass::Tinted`]) in a scene whose materials decide opacity.
    pub fn tints(&self) -> bool {
        self.glass == Glass::Tinted
            && self.uniform_opacity.is_none()
            && self.materials.iter().any(|m| m.transmission > 0.0)
    }

    /// Whether any of its transparent fragments can be brighter than white (a material's
    /// emission added to its base colour exceeds 1 in a channel, or a vertex colour does): its
    /// frames keep colours above white ([`crate::fragment::quantize_hdr`]), each fragment's
    /// exponent in its tint word, which the methods that store fragments then store
    /// ([`Scene::tint_words`]).
    pub fn hdr(&self) -> bool {
        let emits = self.materials.iter().any(|m| {
            (self.uniform_opacity.is_some() || m.transparent())
                && (0..3).any(|i| m.base_color[i] + m.emissive[i] > 1.0)
        });
        emits
            || self
                .colors
                .iter()
                .any(|c| c[0] > 1.0 || c[1] > 1.0 || c[2] > 1.0)
    }

    /// Whether its frames store a word beside each fragment's key: its tint ([`Scene::tints`])
    /// and the exponent of its colour ([`Scene::hdr`]).
    pub fn tint_words(&self) -> bool {
        self.tints() || self.hdr()
    }

    /// What its frames store beside each fragment's key ([`crate::fragment::Words`]).
    pub fn words(&self) -> crate::fragment::Words {
        crate::fragment::Words::of(self.tints(), self.tint_words())
    }

    /// The largest colour exponent its fragments are stored with
    /// ([`crate::fragment::quantize_hdr`]): [`crate::shared::HDR_MAX_EXPONENT`] where it keeps
    /// colours above white, else 0.
    pub fn max_exponent(&self) -> u32 {
        match self.hdr() {
            true => crate::shared::HDR_MAX_EXPONENT,
            false => 0,
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.positions.len() / 3
    }

    /// A triangle of the first material, untextured.
    pub fn push_triangle(&mut self, p: [Vec3; 3], c: [[f32; 4]; 3]) {
        self.push_textured(p, c, [[0.0; 2]; 3], 0);
    }

    /// A triangle with texture coordinates and a material.
    pub fn push_textured(&mut self, p: [Vec3; 3], c: [[f32; 4]; 3], uv: [[f32; 2]; 3], m: u32) {
        self.positions.extend_from_slice(&p);
        self.colors.extend_from_slice(&c);
        self.uvs.extend_from_slice(&uv);
        self.triangle_material.push(m);
    }

    /// Adds a material, returning its index.
    pub fn add_material(&mut self, m: Material) -> u32 {
        self.materials.push(m);
        (self.materials.len() - 1) as u32
    }

    /// Adds a texture, returning its index.
    pub fn add_texture(&mut self, t: Texture) -> u32 {
        self.textures.push(t);
        (self.textures.len() - 1) as u32
    }

    /// Whether triangle `t` is transparent (the materials', or every triangle under one
    /// uniform opacity); the others are drawn in the opaque pass.
    pub fn transparent(&self, t: usize) -> bool {
        self.uniform_opacity.is_some()
            || self.materials[self.triangle_material[t] as usize].transparent()
    }

    /// Whether any triangle is opaque (then the frame has an opaque pass).
    pub fn has_opaque(&self) -> bool {
        (0..self.triangle_count()).any(|t| !self.transparent(t))
    }

    /// Triangle `t`'s material.
    pub fn material_of(&self, t: usize) -> &Material {
        &self.materials[self.triangle_material[t] as usize]
    }

    /// Whether the materials, textures and texture coordinates are consistent and finite.
    pub(crate) fn check_materials(&self) -> std::result::Result<(), SceneFault> {
        let n = self.triangle_count();
        if self.uvs.len() != 3 * n || self.triangle_material.len() != n {
            return Err(SceneFault::Unmatched {
                triangles: n,
                uvs: self.uvs.len(),
                materials: self.triangle_material.len(),
            });
        }
        if let Some(t) = self
            .triangle_material
            .iter()
            .position(|&m| m as usize >= self.materials.len())
        {
            return Err(SceneFault::NoSuchMaterial {
                triangle: t,
                material: self.triangle_material[t],
                materials: self.materials.len(),
            });
        }
        if let Some(vertex) = self
            .uvs
            .iter()
            .position(|uv| !uv.iter().all(|c| c.is_finite()))
        {
            return Err(SceneFault::NonFiniteUv {
                vertex,
                uv: self.uvs[vertex],
            });
        }
        for (i, m) in self.materials.iter().enumerate() {
            let bad = |what: &str| SceneFault::BadMaterial {
                material: i,
                what: what.into(),
            };
            if !m.base_color.iter().all(|c| c.is_finite() && *c >= 0.0) {
                return Err(bad(&format!("base colour {:?}", m.base_color)));
            }
            if !(0.0..=1.0).contains(&m.transmission) {
                return Err(bad(&format!("transmission {}", m.transmission)));
            }
            if !(m.ior.is_finite() && m.ior >= 1.0) {
                return Err(bad(&format!("index of refraction {}", m.ior)));
            }
            if let Coverage::Mask(c) = m.coverage
                && !c.is_finite()
            {
                return Err(bad(&format!("alpha cutoff {c}")));
            }
            if !m.emissive.iter().all(|c| c.is_finite() && *c >= 0.0) {
                return Err(bad(&format!("emissive colour {:?}", m.emissive)));
            }
            if !m.attenuation.iter().all(|c| (0.0..=1.0).contains(c)) {
                return Err(bad(&format!("volume attenuation {:?}", m.attenuation)));
            }
            for t in [m.texture, m.transmission_texture, m.emissive_texture]
                .into_iter()
                .flatten()
            {
                if t as usize >= self.textures.len() {
                    return Err(SceneFault::NoSuchTexture {
                        material: i,
                        texture: t,
                        textures: self.textures.len(),
                    });
                }
            }
        }
        for (i, t) in self.textures.iter().enumerate() {
            if t.width == 0 || t.height == 0 || t.texels.len() != (t.width * t.height) as usize {
                return Err(SceneFault::BadTexture {
                    texture: i,
                    width: t.width,
                    height: t.height,
                    texels: t.texels.len(),
                });
            }
        }
        Ok(())
    }

    /// Whether the scene can be rendered: some triangles, every position finite, a bounding
    /// sphere a float can hold (positions far beyond 1e18 leave no depth precision), and at
    /// least one triangle with an area.
    pub fn check(&self) -> std::result::Result<(), SceneFault> {
        if self.triangle_count() == 0 {
            return Err(SceneFault::NoTriangles);
        }
        if let Some(v) = self.viewpoint {
            let seeing = v.eye.is_finite()
                && v.forward.is_finite()
                && v.up.is_finite()
                && v.forward.length() > 0.5
                && v.forward.cross(v.up).length() > 1e-3
                && v.yfov > 0.0
                && v.yfov < std::f32::consts::PI;
            if !seeing {
                return Err(SceneFault::BadViewpoint {
                    eye: v.eye,
                    forward: v.forward,
                    up: v.up,
                    yfov: v.yfov,
                });
            }
        }
        if let Some(vertex) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(SceneFault::NonFinite {
                vertex,
                position: self.positions[vertex],
            });
        }
        let (_, radius) = self.bounding_sphere();
        if !(radius.is_finite() && radius <= MAX_RADIUS) {
            return Err(SceneFault::TooLarge { radius });
        }
        let area = |t: &[Vec3]| (t[1] - t[0]).cross(t[2] - t[0]).length_squared() > 0.0;
        if !self.positions.chunks_exact(3).any(area) {
            return Err(SceneFault::Degenerate {
                triangles: self.triangle_count(),
            });
        }
        self.check_materials()
    }

    /// Applies an opacity mode: `Uniform(a)` makes every surface transparent with opacity `a`
    /// (and writes it into every vertex alpha, as an exported file keeps it), `Material` lets
    /// the materials decide, `Native` keeps what the scene came with.
    pub fn with_opacity(mut self, opacity: Opacity) -> Result<Self> {
        match opacity {
            Opacity::Uniform(a) => {
                if !(a.is_finite() && (0.0..=1.0).contains(&a)) {
                    return Err(Error::Invalid(format!("opacity {a} is not in [0, 1]")));
                }
                for c in &mut self.colors {
                    c[3] = a;
                }
                self.uniform_opacity = Some(a);
            }
            Opacity::Material => self.uniform_opacity = None,
            Opacity::Native => {}
        }
        Ok(self)
    }

    /// The same triangles in a seeded random submission order.
    pub fn shuffled(&self, seed: u64) -> Scene {
        let perm = Rng::new(seed).permutation(self.triangle_count());
        let mut out = Scene {
            name: self.name.clone(),
            positions: Vec::with_capacity(self.positions.len()),
            colors: Vec::with_capacity(self.colors.len()),
            uvs: Vec::with_capacity(self.uvs.len()),
            triangle_material: Vec::with_capacity(self.triangle_material.len()),
            materials: self.materials.clone(),
            textures: self.textures.clone(),
            uniform_opacity: self.uniform_opacity,
            glass: self.glass,
            viewpoint: self.viewpoint,
        };
        for t in perm {
            out.positions
                .extend_from_slice(&self.positions[3 * t..3 * t + 3]);
            out.colors.extend_from_slice(&self.colors[3 * t..3 * t + 3]);
            out.uvs.extend_from_slice(&self.uvs[3 * t..3 * t + 3]);
            out.triangle_material.push(self.triangle_material[t]);
        }
        out
    }

    /// The least and greatest corners of the box enclosing every vertex (infinite, inside out,
    /// where there is none).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        )
    }

    /// Centre and radius of a sphere enclosing every vertex (the bounding box's centre).
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        if self.positions.is_empty() {
            return (Vec3::ZERO, 1.0);
        }
        let (lo, hi) = self.bounds();
        let c = 0.5 * (lo + hi);
        let r = self
            .positions
            .iter()
            .map(|p| p.distance(c))
            .fold(0.0f32, f32::max);
        (c, r.max(1e-6))
    }
}

/// A file-name-safe label for a scene name or path (its file stem for paths).
pub fn file_label(name: &str) -> String {
    let stem = Path::new(name)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| name.to_string());
    stem.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Loads a scene by built-in name or by path to a `.gltf` / `.glb` file.
pub fn load(name_or_path: &str, opacity: Opacity) -> Result<Scene> {
    let scene = if let Some(s) = procedural::build(name_or_path) {
        s
    } else {
        let path = Path::new(name_or_path);
        let is_gltf = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"));
        if !is_gltf && !path.exists() {
            return Err(Error::UnknownScene(name_or_path.to_string()));
        }
        gltf::load(path)?
    };
    scene
        .check()
        .map_err(|f| Error::scene(name_or_path, f.to_string()))?;
    // The scene's own opacity first (the papers' families: one opacity in every vertex too).
    let native = scene
        .uniform_opacity
        .map_or(Opacity::Material, Opacity::Uniform);
    scene.with_opacity(native)?.with_opacity(opacity)
}

/// A perspective camera on an orbit around the scene's bounding sphere.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    pub view_proj: Mat4,
    /// Unit vector from the eye towards the scene centre (the headlight direction).
    pub forward: Vec3,
    pub eye: Vec3,
    /// The projection's near and far planes (distances along the view direction; 0 where the
    /// camera is no perspective one): what WBOIT's weights of the view-space distance read
    /// (`composite::WboitParams::for_camera`).
    pub near: f32,
    pub far: f32,
}

/// Number of orbit views a scene is seen from by default.
pub const DEFAULT_VIEWS: usize = 8;

/// That `view` is one of an orbit of `views` ([`Camera::orbit`]): [`Error::Invalid`] otherwise.
pub fn check_view(view: usize, views: usize) -> Result<()> {
    if views == 0 {
        return Err(Error::Invalid("an orbit needs at least one view".into()));
    }
    if view >= views {
        return Err(Error::Invalid(format!(
            "view {view} does not exist: there are {views} views (0..{views})"
        )));
    }
    Ok(())
}

impl Camera {
    /// View `view` of `views` evenly spaced around the bounding sphere, alternating between
    /// looking down (25 degrees) and up (-15 degrees), framing the whole sphere with a 45 degree
    /// vertical field of view. Near and far planes hug the sphere, so no geometry is clipped.
    pub fn orbit(scene: &Scene, view: usize, views: usize, size: (u32, u32)) -> Camera {
        let views = views.max(1);
        let azimuth = std::f32::consts::TAU * (view % views) as f32 / views as f32 + 0.5;
        let elevation = if view.is_multiple_of(2) {
            25f32
        } else {
            -15f32
        }
        .to_radians();
        Camera::orbit_at(scene, azimuth, elevation, size)
    }

    /// The camera a scene's file gives ([`Scene::viewpoint`], its aspect the frame's), else
    /// the front view: looking along -Z, level, from where the bounding box's front face just
    /// fills a 45 degree vertical field of view (where glTF viewers start). Near and far hug
    /// the bounding sphere, or the box.
    pub fn asset(scene: &Scene, size: (u32, u32)) -> Camera {
        let (width, height) = size;
        let aspect = width as f32 / height as f32;
        let Some(v) = scene.viewpoint else {
            let (lo, hi) = scene.bounds();
            let (centre, half) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
            let fovy = 45f32.to_radians();
            let tan_v = (fovy * 0.5).tan();
            let d = (half.x / (aspect * tan_v)).max(half.y / tan_v).max(1e-6) * 1.05;
            let eye = Vec3::new(centre.x, centre.y, hi.z + d);
            let far = d + 2.0 * half.z * 1.01 + d * 1e-3;
            let near = (d * 0.98).max(far * 1e-5);
            let view_m = look_at_rh(eye, Vec3::new(centre.x, centre.y, lo.z), Vec3::Y);
            return Camera {
                view_proj: perspective_rh(fovy, aspect, near, far) * view_m,
                forward: Vec3::NEG_Z,
                eye,
                near,
                far,
            };
        };
        let (centre, radius) = scene.bounding_sphere();
        let forward = v.forward.normalize();
        // The sphere's extent along the view, from the eye.
        let along = (centre - v.eye).dot(forward);
        let far = (along + radius * 1.01).max(1e-3);
        let near = (along - radius * 1.01).max(far * 1e-4);
        let view_m = look_at_rh(v.eye, v.eye + forward, v.up);
        let proj = perspective_rh(v.yfov, aspect, near, far);
        Camera {
            view_proj: proj * view_m,
            forward,
            eye: v.eye,
            near,
            far,
        }
    }

    /// The camera on the bounding sphere's orbit at `azimuth` and `elevation` (radians), framed
    /// as [`Camera::orbit`] frames its views (which are this at their angles): what an
    /// interactive viewer turns with the mouse.
    pub fn orbit_at(scene: &Scene, azimuth: f32, elevation: f32, size: (u32, u32)) -> Camera {
        let (width, height) = size;
        let (centre, radius) = scene.bounding_sphere();
        let dir = Vec3::new(
            elevation.cos() * azimuth.cos(),
            elevation.sin(),
            elevation.cos() * azimuth.sin(),
        );
        let fovy = 45f32.to_radians();
        let aspect = width as f32 / height as f32;
        // Distance at which the sphere fits both the vertical and horizontal field of view.
        let half = (fovy * 0.5)
            .tan()
            .atan()
            .min((aspect * (fovy * 0.5).tan()).atan());
        let distance = radius / half.sin() * 1.02;
        let eye = centre + dir * distance;
        let near = (distance - radius * 1.01).max(distance * 1e-3);
        let far = distance + radius * 1.01;
        let view_m = look_at_rh(eye, centre, Vec3::Y);
        let proj = perspective_rh(fovy, aspect, near, far);
        Camera {
            view_proj: proj * view_m,
            forward: (centre - eye).normalize(),
            eye,
            near,
            far,
        }
    }
}

/// Right-handed view matrix looking from `eye` at `target`.
pub fn look_at_rh(eye: Vec3, target: Vec3, up: Vec3) -> Mat4 {
    let f = (target - eye).normalize();
    let s = f.cross(up).normalize();
    let u = s.cross(f);
    Mat4::from_cols(
        glam::Vec4::new(s.x, u.x, -f.x, 0.0),
        glam::Vec4::new(s.y, u.y, -f.y, 0.0),
        glam::Vec4::new(s.z, u.z, -f.z, 0.0),
        glam::Vec4::new(-s.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
    )
}

/// Right-handed perspective projection to Vulkan/wgpu clip space (depth 0 at near, 1 at far).
pub fn perspective_rh(fovy: f32, aspect: f32, near: f32, far: f32) -> Mat4 {
    let f = 1.0 / (0.5 * fovy).tan();
    let r = far / (near - far);
    Mat4::from_cols(
        glam::Vec4::new(f / aspect, 0.0, 0.0, 0.0),
        glam::Vec4::new(0.0, f, 0.0, 0.0),
        glam::Vec4::new(0.0, 0.0, r, -1.0),
        glam::Vec4::new(0.0, 0.0, r * near, 0.0),
    )
}
