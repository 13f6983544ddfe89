//! Scenes: triangle soups with per-vertex non-premultiplied RGBA, from glTF files or built-in
//! procedural generators, and the deterministic orbit cameras they are seen from.
//!
//! A scene is stored unindexed (three vertices per triangle, in submission order), which is what
//! both the CPU rasterizer and a non-indexed GPU draw consume; `shuffled` permutes whole
//! triangles to test order independence.

pub mod gltf;
pub mod procedural;

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
}

/// How fragment opacity is decided.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Opacity {
    /// Every surface is transparent with this one opacity (the reference implementation uses 0.33).
    Uniform(f32),
    /// Keep the material's alpha (base colour factor x vertex colour x texture alpha).
    Material,
}

impl Default for Opacity {
    fn default() -> Self {
        Opacity::Uniform(0.33)
    }
}

/// A triangle soup: `positions.len() == colors.len() == 3 * triangle_count()`.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub name: String,
    pub positions: Vec<Vec3>,
    /// Non-premultiplied linear RGBA per vertex.
    pub colors: Vec<[f32; 4]>,
}

impl Scene {
    pub fn triangle_count(&self) -> usize {
        self.positions.len() / 3
    }

    pub fn push_triangle(&mut self, p: [Vec3; 3], c: [[f32; 4]; 3]) {
        self.positions.extend_from_slice(&p);
        self.colors.extend_from_slice(&c);
    }

    /// Whether the scene can be rendered: some triangles, every position finite, a bounding
    /// sphere a float can hold (positions far beyond 1e18 leave no depth precision), and at
    /// least one triangle with an area.
    pub fn check(&self) -> std::result::Result<(), SceneFault> {
        if self.triangle_count() == 0 {
            return Err(SceneFault::NoTriangles);
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
        Ok(())
    }

    /// Applies an opacity mode: `Uniform(a)` overwrites every vertex alpha with `a`.
    pub fn with_opacity(mut self, opacity: Opacity) -> Result<Self> {
        if let Opacity::Uniform(a) = opacity {
            if !(a.is_finite() && (0.0..=1.0).contains(&a)) {
                return Err(Error::Invalid(format!("opacity {a} is not in [0, 1]")));
            }
            for c in &mut self.colors {
                c[3] = a;
            }
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
        };
        for t in perm {
            out.positions
                .extend_from_slice(&self.positions[3 * t..3 * t + 3]);
            out.colors.extend_from_slice(&self.colors[3 * t..3 * t + 3]);
        }
        out
    }

    /// Centre and radius of a sphere enclosing every vertex (the bounding box's centre).
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        if self.positions.is_empty() {
            return (Vec3::ZERO, 1.0);
        }
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for p in &self.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
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
    scene.with_opacity(opacity)
}

/// A perspective camera on an orbit around the scene's bounding sphere.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    pub view_proj: Mat4,
    /// Unit vector from the eye towards the scene centre (the headlight direction).
    pub forward: Vec3,
    pub eye: Vec3,
}

/// Number of orbit views a scene is seen from by default.
pub const DEFAULT_VIEWS: usize = 8;

/// Whether `view` is one of an orbit of `views` ([`Camera::orbit`]); otherwise the message,
/// for the caller's error.
pub fn check_view(view: usize, views: usize) -> std::result::Result<(), String> {
    if views == 0 {
        return Err("an orbit needs at least one view".into());
    }
    if view >= views {
        return Err(format!(
            "view {view} does not exist: there are {views} views (0..{views})"
        ));
    }
    Ok(())
}

impl Camera {
    /// View `view` of `views` evenly spaced around the bounding sphere, alternating between
    /// looking down (25 degrees) and up (-15 degrees), framing the whole sphere with a 45 degree
    /// vertical field of view. Near and far planes hug the sphere, so no geometry is clipped.
    pub fn orbit(scene: &Scene, view: usize, views: usize, width: u32, height: u32) -> Camera {
        let (centre, radius) = scene.bounding_sphere();
        let views = views.max(1);
        let azimuth = std::f32::consts::TAU * (view % views) as f32 / views as f32 + 0.5;
        let elevation = if view.is_multiple_of(2) {
            25f32
        } else {
            -15f32
        }
        .to_radians();
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
