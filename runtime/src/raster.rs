//! CPU rasterizer: every fragment of every triangle, both faces, no depth test, into per-pixel
//! fragment lists (an A-buffer in CSR form).
//!
//! Conventions follow Vulkan (and so wgpu), so that the GPU renderer agrees pixel for pixel:
//! - window coordinates: x right, y down, origin at the top-left corner; NDC y = +1 is the top
//!   row; window depth `z_clip / w_clip` in [0, 1];
//! - vertices snapped to a 1/256-pixel grid ([`SUBPIXEL_BITS`] = 8), edge functions evaluated
//!   exactly in integers, so shared edges are watertight;
//! - a pixel is covered when its centre (x + 0.5, y + 0.5) lies inside the triangle, or on an
//!   edge that is a top edge (horizontal, interior below) or a left edge (interior to the right);
//! - depth interpolated linearly in screen space on the plane through the vertices' unsnapped
//!   window positions (as Mesa's lavapipe does; snapped positions put depth up to 9e-4 away
//!   from the GPU's on steep triangles);
//! - colour, texture coordinates and world position perspective-correctly, at weights from the
//!   triangle's clip-space vertices by 2-D homogeneous edge functions ([`homogeneous_weights`],
//!   which geometry.wgsl computes alike in the fragment stage rather than take the hardware's
//!   interpolation, whose rounding moved one texel in ten by an 8-bit step on lavapipe);
//! - triangles are clipped against the near and far planes in clip space;
//! - a single-sided material's back faces (clockwise in clip space) are culled, except under
//!   one uniform opacity (the papers' protocol draws both faces).
//!
//! Two passes, as renderers draw them: the opaque triangles first (OPAQUE and MASK materials,
//! [`crate::scene::material`]) with a depth buffer cleared to 1 (a fragment is kept where its
//! depth is less than the buffer's, so the first of equal depths in submission order stays),
//! giving each pixel its nearest opaque colour ([`FragmentLists::opaque`]); then the
//! transparent triangles, a fragment kept only where it lies in front of that depth (at or
//! behind it, it does not exist for any method) and its 8-bit opacity is not zero (it would
//! add nothing to any composite).
//!
//! Shading: a headlight Lambert term on the vertex colour,
//! `rgb = vertex_rgb * (AMBIENT + (1 - AMBIENT) |n . v|)` with `n` the triangle's geometric
//! normal and `v` the camera's forward direction, then the material per fragment
//! ([`crate::scene::material::shade`]: factor, texture, alpha mode, glass). Vertex colours are
//! interpolated perspective-correctly, except a channel the triangle's three vertices share,
//! which is kept exactly (the GPU alike): the interpolation's rounding would otherwise move a
//! value that sits on a half step, such as alpha 0.3 = 76.5 / 255, to one side on the CPU and
//! the other on the GPU. Fragment colours are rounded to 8 bits per
//! channel, the precision the capture key stores. Each fragment keeps
//! `|n . v|` (`facing`, for the Fresnel importance) and its triangle's submission index.
//!
//! Within a pixel, fragments are listed in submission order. Work is split into bands of rows
//! processed in parallel; the result does not depend on the number of threads.

use crate::error::{Error, Result};
use crate::fragment::{FragmentLists, pack_opaque, quantize_hdr};
use crate::scene::material::{self, Shaded};
use crate::scene::{Camera, Scene};
use glam::{Vec3, Vec4};
use rayon::prelude::*;

pub const SUBPIXEL_BITS: u32 = 8;
const SUB: i64 = 1 << SUBPIXEL_BITS;
pub use crate::shared::{AMBIENT, MAX_FRAGMENTS_PER_PIXEL};
const BAND_ROWS: u32 = 8;
/// Largest accepted width or height.
pub const MAX_DIM: u32 = 16384;

/// A frame size, given as `WIDTHxHEIGHT` on command lines (parsed by [`parse_resolution`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Resolution {
    pub width: u32,
    pub height: u32,
}

impl Resolution {
    /// (width, height), the size every function takes.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
}

impl std::str::FromStr for Resolution {
    type Err = Error;
    fn from_str(s: &str) -> Result<Resolution> {
        let (width, height) = parse_resolution(s)?;
        Ok(Resolution { width, height })
    }
}

impl std::fmt::Display for Resolution {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.width, self.height)
    }
}

/// Parses `WxH` and checks it is a possible resolution.
pub fn parse_resolution(s: &str) -> Result<(u32, u32)> {
    let bad = |m: &str| Error::Resolution(s.to_string(), m.to_string());
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| bad("expected WIDTHxHEIGHT, such as 640x480"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| bad("width is not a whole number"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| bad("height is not a whole number"))?;
    check_resolution((w, h))?;
    Ok((w, h))
}

pub fn check_resolution(size: (u32, u32)) -> Result<()> {
    let (w, h) = size;
    if w == 0 || h == 0 || w > MAX_DIM || h > MAX_DIM {
        return Err(Error::Resolution(
            format!("{w}x{h}"),
            format!("width and height must be between 1 and {MAX_DIM}"),
        ));
    }
    Ok(())
}

/// A triangle after clipping and the viewport transform.
#[derive(Clone, Copy)]
struct ScreenTri {
    /// Fixed-point window x, y (1/256 pixel).
    xy: [[i64; 2]; 3],
    /// Window x, y before snapping (the plane depth is interpolated on).
    xyf: [[f32; 2]; 3],
    z: [f32; 3],
    /// The triangle's own vertices (before clipping, in submission order): clip-space x, y, w,
    /// their shaded colours, texture coordinates and world positions.
    hclip: [[f32; 3]; 3],
    rgba: [Vec4; 3],
    uv: [[f32; 2]; 3],
    world: [Vec3; 3],
    /// The geometric unit normal.
    normal: Vec3,
    facing: f32,
    prim: u32,
    material: u32,
    /// Drawn in the opaque pass.
    opaque: bool,
    y_range: (u32, u32),
}

/// A clipped vertex in window space.
#[derive(Clone, Copy)]
struct ScreenVertex {
    /// Snapped to 1/256 pixel (coverage).
    xy: [i64; 2],
    z: f32,
    /// Unsnapped (the depth plane).
    xyf: [f32; 2],
}

#[derive(Clone, Copy)]
struct ClipVertex {
    pos: Vec4,
}

fn lerp_vertex(a: &ClipVertex, b: &ClipVertex, t: f32) -> ClipVertex {
    ClipVertex {
        pos: a.pos + (b.pos - a.pos) * t,
    }
}

/// Perspective-correct barycentric weights of the pixel whose centre is at NDC (`px`, `py`),
/// from the triangle's clip-space vertices `v` (x, y, w): the 2-D homogeneous edge functions
/// `e_i = (v_j x v_k) . (px, py, 1)` normalised to sum to one (Olano and Greer 1997). Valid for
/// a triangle crossing the near plane as well, so no clipped vertex is needed. geometry.wgsl's
/// `homogeneous_weights` computes the same, operation for operation.
pub fn homogeneous_weights(v: [[f32; 3]; 3], px: f32, py: f32) -> [f32; 3] {
    let edge = |b: [f32; 3], c: [f32; 3]| {
        (b[1] * c[2] - b[2] * c[1]) * px
            + (b[2] * c[0] - b[0] * c[2]) * py
            + (b[0] * c[1] - b[1] * c[0])
    };
    let e = [edge(v[1], v[2]), edge(v[2], v[0]), edge(v[0], v[1])];
    let inv = 1.0 / (e[0] + e[1] + e[2]);
    [e[0] * inv, e[1] * inv, e[2] * inv]
}

/// NDC of pixel (x, y)'s centre in a frame of `size` (width, height; x right, y up).
pub fn pixel_ndc(x: u32, y: u32, size: (u32, u32)) -> (f32, f32) {
    let (w, h) = size;
    (
        ((x as f32 + 0.5) / w as f32) * 2.0 - 1.0,
        1.0 - ((y as f32 + 0.5) / h as f32) * 2.0,
    )
}

/// Sutherland-Hodgman against `z >= 0` and `z <= w`.
fn clip_polygon(poly: Vec<ClipVertex>) -> Vec<ClipVertex> {
    let planes: [fn(&Vec4) -> f32; 2] = [|p| p.z, |p| p.w - p.z];
    let mut poly = poly;
    for dist in planes {
        if poly.iter().all(|v| dist(&v.pos) >= 0.0) {
            continue;
        }
        let mut out = Vec::with_capacity(poly.len() + 1);
        for i in 0..poly.len() {
            let a = &poly[i];
            let b = &poly[(i + 1) % poly.len()];
            let (da, db) = (dist(&a.pos), dist(&b.pos));
            if da >= 0.0 {
                out.push(*a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                out.push(lerp_vertex(a, b, da / (da - db)));
            }
        }
        poly = out;
        if poly.len() < 3 {
            return Vec::new();
        }
    }
    poly
}

fn orient(a: [i64; 2], b: [i64; 2], c: [i64; 2]) -> i64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether a pixel centre exactly on edge a -> b (of a positively oriented triangle) is covered.
fn top_left(a: [i64; 2], b: [i64; 2]) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    dy < 0 || (dy == 0 && dx > 0)
}

fn setup(scene: &Scene, cam: &Camera, size: (u32, u32)) -> Vec<ScreenTri> {
    let (width, height) = size;
    let (w, h) = (width as f32, height as f32);
    let limit = (1i64 << 24) * SUB;
    (0..scene.triangle_count())
        .into_par_iter()
        .flat_map_iter(|t| {
            let p = &scene.positions[3 * t..3 * t + 3];
            let n = face_normal(p);
            let facing = n.dot(cam.forward).abs();
            let shade = AMBIENT + (1.0 - AMBIENT) * facing;
            let opaque = !scene.transparent(t);
            // Single-sided surfaces show their front faces only (not under one opacity).
            let cull = scene.uniform_opacity.is_none() && !scene.material_of(t).double_sided;
            let verts: Vec<ClipVertex> = (0..3)
                .map(|i| ClipVertex {
                    pos: cam.view_proj * p[i].extend(1.0),
                })
                .collect();
            let hclip = [0, 1, 2].map(|i| [verts[i].pos.x, verts[i].pos.y, verts[i].pos.w]);
            let rgba = [0, 1, 2].map(|i| {
                let c = scene.colors[3 * t + i];
                Vec4::new(c[0] * shade, c[1] * shade, c[2] * shade, c[3])
            });
            let poly = clip_polygon(verts);
            let screen: Vec<ScreenVertex> = poly
                .iter()
                .map(|v| {
                    let inv_w = 1.0 / v.pos.w;
                    let xw = (v.pos.x * inv_w + 1.0) * 0.5 * w;
                    let yw = (1.0 - v.pos.y * inv_w) * 0.5 * h;
                    let fx = ((xw as f64) * SUB as f64).round() as i64;
                    let fy = ((yw as f64) * SUB as f64).round() as i64;
                    let z = (v.pos.z * inv_w).clamp(0.0, 1.0);
                    ScreenVertex {
                        xy: [fx.clamp(-limit, limit), fy.clamp(-limit, limit)],
                        z,
                        xyf: [xw, yw],
                    }
                })
                .collect();
            let mut out = Vec::new();
            for i in 2..screen.len() {
                let v = [screen[0], screen[i - 1], screen[i]];
                let area = orient(v[0].xy, v[1].xy, v[2].xy);
                if area == 0 {
                    continue;
                }
                // Clockwise in clip space (y up) is counter-clockwise here (y down): a back
                // face.
                if cull && area > 0 {
                    continue;
                }
                // Both faces: make every triangle positively oriented.
                let v = if area < 0 { [v[0], v[2], v[1]] } else { v };
                let ymin = v.iter().map(|q| q.xy[1]).min().unwrap();
                let ymax = v.iter().map(|q| q.xy[1]).max().unwrap();
                // Rows whose centre (y + 0.5) lies in [ymin, ymax].
                let r0 = ((ymin - SUB / 2 + SUB - 1).div_euclid(SUB)).max(0);
                let r1 = ((ymax - SUB / 2).div_euclid(SUB)).min(height as i64 - 1);
                if r0 > r1 {
                    continue;
                }
                out.push(ScreenTri {
                    xy: v.map(|q| q.xy),
                    xyf: v.map(|q| q.xyf),
                    z: v.map(|q| q.z),
                    hclip,
                    rgba,
                    uv: [0, 1, 2].map(|i| scene.uvs[3 * t + i]),
                    world: [p[0], p[1], p[2]],
                    normal: n,
                    facing,
                    prim: t as u32,
                    material: scene.triangle_material[t],
                    opaque,
                    y_range: (r0 as u32, r1 as u32),
                });
            }
            out
        })
        .collect()
}

struct BandOut {
    counts: Vec<u32>,
    depth: Vec<f32>,
    rgba: Vec<[f32; 4]>,
    tint: Vec<u32>,
    primitive: Vec<u32>,
    facing: Vec<f32>,
    /// The nearest opaque fragment's colour ([`crate::fragment::pack_opaque`]) and depth, per
    /// pixel of the band.
    opaque: Vec<u32>,
    opaque_depth: Vec<f32>,
}

struct Frag {
    pixel: u32,
    depth: f32,
    rgba: [f32; 4],
    tint: u32,
    prim: u32,
    facing: f32,
}

/// What shading a fragment needs beside its triangle.
struct Shading<'a> {
    scene: &'a Scene,
    eye: Vec3,
    table: [f32; 256],
    /// The largest exponent a colour is stored with ([`Scene::max_exponent`]).
    max_exponent: u32,
}

impl Shading<'_> {
    /// The material's fragment of `t` at perspective-correct weights `l`
    /// ([`homogeneous_weights`]), each attribute `(a0 l0 + a1 l1) + a2 l2` as the GPU sums it.
    fn shade(&self, t: &ScreenTri, l: [f32; 3]) -> Shaded {
        // A channel the three vertices share is taken as is (geometry.wgsl alike).
        let lerp = (t.rgba[0] * l[0] + t.rgba[1] * l[1]) + t.rgba[2] * l[2];
        let vertex = Vec4::from_array(std::array::from_fn(|i| {
            let c = t.rgba.map(|v| v[i]);
            if c[0] == c[1] && c[1] == c[2] {
                c[0]
            } else {
                lerp[i]
            }
        }));
        let uv =
            std::array::from_fn(|i| (t.uv[0][i] * l[0] + t.uv[1][i] * l[1]) + t.uv[2][i] * l[2]);
        let world = (t.world[0] * l[0] + t.world[1] * l[1]) + t.world[2] * l[2];
        let m = &self.scene.materials[t.material as usize];
        // Only glass reads the view angle.
        let cos = if m.transmission > 0.0 {
            let v = world - self.eye;
            t.normal.dot(v).abs() / v.length()
        } else {
            0.0
        };
        material::shade(
            m,
            &self.scene.textures,
            &self.table,
            vertex.to_array(),
            uv,
            cos,
            material::ShadeMode {
                uniform: self.scene.uniform_opacity,
                glass: self.scene.glass,
            },
        )
    }
}

fn raster_band(
    tris: &[ScreenTri],
    ids: &[u32],
    shading: &Shading,
    (width, height): (u32, u32),
    y0: u32,
    y1: u32,
) -> BandOut {
    let npix = ((y1 - y0) * width) as usize;
    let mut opaque = vec![0u32; npix];
    let mut opaque_depth = vec![1.0f32; npix];
    let mut frags: Vec<Frag> = Vec::new();
    // The opaque pass, then the transparent one (ids are in submission order).
    for pass_opaque in [true, false] {
        for &id in ids {
            let t = &tris[id as usize];
            if t.opaque != pass_opaque {
                continue;
            }
            let [a, b, c] = t.xy;
            let xmin = a[0].min(b[0]).min(c[0]);
            let xmax = a[0].max(b[0]).max(c[0]);
            let c0 = ((xmin - SUB / 2 + SUB - 1).div_euclid(SUB)).max(0);
            let c1 = ((xmax - SUB / 2).div_euclid(SUB)).min(width as i64 - 1);
            if c0 > c1 {
                continue;
            }
            let bias = [top_left(b, c), top_left(c, a), top_left(a, b)];
            let ry0 = t.y_range.0.max(y0);
            let ry1 = t.y_range.1.min(y1 - 1);
            for y in ry0..=ry1 {
                let py = y as i64 * SUB + SUB / 2;
                for x in c0..=c1 {
                    let p = [x * SUB + SUB / 2, py];
                    let w = [orient(b, c, p), orient(c, a, p), orient(a, b, p)];
                    let inside = (0..3).all(|i| w[i] > 0 || (w[i] == 0 && bias[i]));
                    if !inside {
                        continue;
                    }
                    let pixel = ((y - y0) * width + x as u32) as usize;
                    let depth = plane_depth(t, x as f32 + 0.5, y as f32 + 0.5);
                    // The depth test against the opaque pass (LESS, as the GPU's).
                    if depth >= opaque_depth[pixel] {
                        continue;
                    }
                    let (px, py) = pixel_ndc(x as u32, y, (width, height));
                    let l = homogeneous_weights(t.hclip, px, py);
                    match shading.shade(t, l) {
                        Shaded::Opaque(c) => {
                            opaque_depth[pixel] = depth;
                            opaque[pixel] = pack_opaque([c[0], c[1], c[2]]);
                        }
                        Shaded::Transparent(c, tint) => {
                            let rgba = quantize_hdr(c, shading.max_exponent);
                            // Zero opacity adds nothing to any composite: no fragment.
                            if rgba[3] == 0.0 {
                                continue;
                            }
                            frags.push(Frag {
                                pixel: pixel as u32,
                                depth,
                                rgba,
                                tint: crate::fragment::pack_tint(tint),
                                prim: t.prim,
                                facing: t.facing,
                            });
                        }
                        Shaded::None => {}
                    }
                }
            }
        }
    }
    // Stable counting sort by pixel keeps submission order within each pixel.
    let mut counts = vec![0u32; npix];
    for f in &frags {
        counts[f.pixel as usize] += 1;
    }
    let mut start = vec![0usize; npix];
    let mut acc = 0;
    for p in 0..npix {
        start[p] = acc;
        acc += counts[p] as usize;
    }
    let n = frags.len();
    let mut out = BandOut {
        counts,
        depth: vec![0.0; n],
        rgba: vec![[0.0; 4]; n],
        tint: vec![0; n],
        primitive: vec![0; n],
        facing: vec![0.0; n],
        opaque,
        opaque_depth,
    };
    for f in frags {
        let i = start[f.pixel as usize];
        start[f.pixel as usize] += 1;
        out.depth[i] = f.depth;
        out.rgba[i] = f.rgba;
        out.tint[i] = f.tint;
        out.primitive[i] = f.prim;
        out.facing[i] = f.facing;
    }
    out
}

/// Window depth at a pixel centre: the plane through the three vertices at their unsnapped
/// window positions, `z0 + dz/dx (x - x0) + dz/dy (y - y0)`, in f32 (how Mesa's lavapipe
/// interpolates it).
fn plane_depth(t: &ScreenTri, px: f32, py: f32) -> f32 {
    let [a, b, c] = t.xyf;
    let (x10, y10) = (b[0] - a[0], b[1] - a[1]);
    let (x20, y20) = (c[0] - a[0], c[1] - a[1]);
    let (z10, z20) = (t.z[1] - t.z[0], t.z[2] - t.z[0]);
    let det = x10 * y20 - x20 * y10;
    let dzdx = (z10 * y20 - z20 * y10) / det;
    let dzdy = (x10 * z20 - x20 * z10) / det;
    (t.z[0] + dzdx * (px - a[0]) + dzdy * (py - a[1])).clamp(0.0, 1.0)
}

/// Bytes the rasterizer holds a fragment at its peak: the bands' lists and the frame's (depth,
/// RGBA, primitive and facing, 28 bytes), while the one is copied into the other.
pub const PEAK_BYTES_PER_FRAGMENT: u64 = 2 * 28;
/// ... and a pixel: the bands' counts and the frame's offsets.
pub const PEAK_BYTES_PER_PIXEL: u64 = 8;
/// The environment variable that caps the memory a frame's rasterization may plan for (bytes
/// as budgets take them: `8GiB`), in place of what the machine reports available.
pub const MAX_MEMORY_VAR: &str = "DHOIT_MAX_MEMORY";

/// The area of a triangle's part inside the window [0, w] x [0, h], in square pixels: close to
/// the number of pixel centres it covers, so summed over a view's triangles, to its fragments.
fn window_area(t: &ScreenTri, w: f64, h: f64) -> f64 {
    // Sutherland-Hodgman against the window's four edges: (axis, bound, keep the side above).
    let mut poly: Vec<[f64; 2]> = t.xyf.iter().map(|p| [p[0] as f64, p[1] as f64]).collect();
    for (axis, bound, above) in [(0, 0.0, true), (0, w, false), (1, 0.0, true), (1, h, false)] {
        let inside = |p: [f64; 2]| {
            if above {
                p[axis] >= bound
            } else {
                p[axis] <= bound
            }
        };
        let mut out = Vec::with_capacity(poly.len() + 1);
        for (i, &a) in poly.iter().enumerate() {
            let b = poly[(i + 1) % poly.len()];
            if inside(a) {
                out.push(a);
            }
            if inside(a) != inside(b) {
                let s = (bound - a[axis]) / (b[axis] - a[axis]);
                out.push([a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])]);
            }
        }
        poly = out;
        if poly.len() < 3 {
            return 0.0;
        }
    }
    let twice: f64 = (0..poly.len())
        .map(|i| {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            p[0] * q[1] - q[0] * p[1]
        })
        .sum();
    twice.abs() / 2.0
}

/// The memory a frame may plan for: [`MAX_MEMORY_VAR`] where set, else what Linux reports
/// available (`MemAvailable`, and within a cgroup with a memory limit, that limit less its
/// usage, if less); `None` where none of them is known.
pub fn available_memory() -> Result<Option<u64>> {
    if let Ok(v) = std::env::var(MAX_MEMORY_VAR) {
        return match crate::budget::Budget::parse(&v) {
            Ok(crate::budget::Budget::Bytes(b)) => Ok(Some(b)),
            _ => Err(Error::Invalid(format!(
                "{MAX_MEMORY_VAR}='{v}': expected bytes such as 8GiB or 500MB"
            ))),
        };
    }
    let read = |p: &str| std::fs::read_to_string(p).ok();
    let meminfo = read("/proc/meminfo").and_then(|m| {
        m.lines()
            .find_map(|l| l.strip_prefix("MemAvailable:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            .map(|kb| kb * 1024)
    });
    let number = |p: &str| read(p).and_then(|v| v.trim().parse::<u64>().ok());
    let cgroup = number("/sys/fs/cgroup/memory.max")
        .map(|max| max.saturating_sub(number("/sys/fs/cgroup/memory.current").unwrap_or(0)));
    Ok(match (meminfo, cgroup) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    })
}

/// Refuses work on a frame of `size` (width, height) that needs `need` bytes where less is available
/// ([`available_memory`]), where the allocation would fail or the system stop the process
/// without a word: `what` says what needs them; the error adds what is available.
pub fn check_fits(size: (u32, u32), need: u64, what: impl FnOnce(&str) -> String) -> Result<()> {
    let (width, height) = size;
    let Some(available) = available_memory()? else {
        return Ok(());
    };
    if need <= available {
        return Ok(());
    }
    let available = crate::budget::format_bytes(available);
    let source = if std::env::var_os(MAX_MEMORY_VAR).is_some() {
        format!("{MAX_MEMORY_VAR} allows {available}")
    } else {
        format!("this machine has {available} available")
    };
    Err(Error::Resolution(
        format!("{width}x{height}"),
        format!(
            "{}, and {source}: lower the resolution",
            what(&crate::budget::format_bytes(need))
        ),
    ))
}

/// Refuses a view whose fragments would not fit in memory, before rasterizing it.
fn check_memory(size: (u32, u32), fragments: f64) -> Result<()> {
    let (width, height) = size;
    let pixels = width as u64 * height as u64;
    let need = fragments * PEAK_BYTES_PER_FRAGMENT as f64;
    let need = need as u64 + pixels * PEAK_BYTES_PER_PIXEL;
    check_fits((width, height), need, |need| {
        format!(
            "the view covers about {:.0} fragments; rasterizing them on the CPU takes about \
             {need} at its peak ({PEAK_BYTES_PER_FRAGMENT} bytes a fragment, \
             {PEAK_BYTES_PER_PIXEL} a pixel)",
            fragments.round()
        )
    })
}

/// About how many fragments a view of `scene` at `size` (width, height) holds (the area of its
/// triangles inside the window), without rasterizing it.
pub fn estimate_fragments(scene: &Scene, cam: &Camera, size: (u32, u32)) -> Result<f64> {
    check_resolution(size)?;
    let tris = setup(scene, cam, size);
    Ok(covered_area(&tris, size))
}

fn covered_area(tris: &[ScreenTri], size: (u32, u32)) -> f64 {
    let (width, height) = size;
    tris.par_iter()
        .map(|t| window_area(t, width as f64, height as f64))
        .sum()
}

/// Rasterizes every triangle of `scene` seen by `cam` into per-pixel fragment lists, after
/// checking that they fit in memory ([`available_memory`]).
pub fn rasterize(scene: &Scene, cam: &Camera, size: (u32, u32)) -> Result<FragmentLists> {
    let (width, height) = size;
    check_resolution(size)?;
    let tris = setup(scene, cam, size);
    check_memory((width, height), covered_area(&tris, size))?;
    let bands = height.div_ceil(BAND_ROWS);
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); bands as usize];
    for (i, t) in tris.iter().enumerate() {
        for b in t.y_range.0 / BAND_ROWS..=t.y_range.1 / BAND_ROWS {
            bins[b as usize].push(i as u32);
        }
    }
    let shading = Shading {
        scene,
        eye: cam.eye,
        table: material::srgb_table(),
        max_exponent: scene.max_exponent(),
    };
    let outs: Vec<BandOut> = bins
        .par_iter()
        .enumerate()
        .map(|(b, ids)| {
            let y0 = b as u32 * BAND_ROWS;
            raster_band(
                &tris,
                ids,
                &shading,
                (width, height),
                y0,
                (y0 + BAND_ROWS).min(height),
            )
        })
        .collect();
    let total: usize = outs.iter().map(|o| o.depth.len()).sum();
    for (b, o) in outs.iter().enumerate() {
        if let Some(i) = o.counts.iter().position(|&c| c > MAX_FRAGMENTS_PER_PIXEL) {
            let (x, y) = (i as u32 % width, b as u32 * BAND_ROWS + i as u32 / width);
            return Err(Error::Invalid(format!(
                "pixel ({x}, {y}) has {} fragments; at most {MAX_FRAGMENTS_PER_PIXEL} fit one pixel",
                o.counts[i]
            )));
        }
    }
    if total > u32::MAX as usize {
        return Err(Error::Invalid(format!(
            "{total} fragments exceed the 2^32 a fragment list can index; lower the resolution"
        )));
    }
    let mut fl = FragmentLists {
        width,
        height,
        offsets: Vec::with_capacity((width * height) as usize + 1),
        depth: Vec::with_capacity(total),
        rgba: Vec::with_capacity(total),
        primitive: Vec::with_capacity(total),
        facing: Vec::with_capacity(total),
        ..Default::default()
    };
    let has_opaque = scene.has_opaque();
    // Tints where the scene's glass is tinted or its colours keep their exponent
    // (FragmentLists::tint), as the GPU stores them.
    let tinted = scene.tint_words();
    if tinted {
        fl.tint.reserve(total);
    }
    fl.tinted_glass = scene.tints();
    let mut acc = 0u32;
    fl.offsets.push(0);
    for o in outs {
        for c in o.counts {
            acc += c;
            fl.offsets.push(acc);
        }
        fl.depth.extend(o.depth);
        fl.rgba.extend(o.rgba);
        if tinted {
            fl.tint.extend(o.tint);
        }
        fl.primitive.extend(o.primitive);
        fl.facing.extend(o.facing);
        if has_opaque {
            fl.opaque.extend(o.opaque);
            fl.opaque_depth.extend(o.opaque_depth);
        }
    }
    Ok(fl)
}

/// The geometric unit normal of a triangle (zero when degenerate).
pub fn face_normal(p: &[Vec3]) -> Vec3 {
    (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero()
}
