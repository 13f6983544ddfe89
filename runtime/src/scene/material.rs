//! Materials as glTF defines them, evaluated per fragment: the CPU twin of geometry.wgsl's
//! `shade`, `sample_texture` and `glass_opacity`, written so the two read side by side.
//!
//! - Base colour: `baseColorFactor x COLOR_0 x baseColorTexture(uv)`, alpha the same product;
//!   the texture sampled per fragment at perspective-correct UVs with the sampler's wrap modes
//!   (REPEAT, MIRRORED_REPEAT, CLAMP_TO_EDGE) and its magnification filter (NEAREST, else
//!   bilinear), texels sRGB-decoded through a 256-entry table before filtering (the GPU reads
//!   the same table, so the decode is identical). No mipmaps: a texture larger than
//!   [`MAX_TEXTURE_SIDE`] a side is box-filtered down to it when loaded.
//! - `alphaMode`: OPAQUE and MASK surfaces are opaque (MASK after its test, alpha `>=
//!   alphaCutoff` kept), drawn first with a depth buffer; BLEND surfaces are transparent.
//! - Glass (`KHR_materials_transmission`, whatever the alpha mode): transparent, with the
//!   opacity of what it does not transmit, `1 - T (1 - F)`, `F` Schlick's Fresnel reflectance
//!   `F0 + (1 - F0)(1 - cos)^5` of `F0 = ((ior - 1) / (ior + 1))^2` (`KHR_materials_ior`,
//!   default 1.5: 0.04 face-on, 1 at grazing angles), `cos` the angle between the triangle's
//!   geometric normal and the direction from the eye to the fragment; times the base alpha
//!   where the mode is BLEND, after the cutoff test where it is MASK. Its colour is the base
//!   colour (a tint). `T` is the transmission factor times its texture's R channel, read as
//!   data (8-bit value / 255, no sRGB decode) where the material has one, so the parts a
//!   stained-glass texture marks as not transmitting (lead, paint) are opaque with their base
//!   colour. The IOR texture is not read (its factor is).
//! - Emission: `emissiveFactor x emissiveTexture(uv) x KHR_materials_emissive_strength` (the
//!   texture sRGB-decoded as base colour is) adds to the fragment's RGB after the headlight's
//!   shade, which does not dim it: an emissive label on a black base shows its texture. It adds
//!   to the straight colour, so a transparent fragment of opacity `a` contributes `a` times it;
//!   stored as RGBA8, it clamps at white.
//! - A material's textures are read at the vertices' one set of texture coordinates: its base
//!   colour texture's (with its transform), else its transmission texture's, else its
//!   emissive texture's. A second texture reading another set or transform is read at those.
//! - Double-sidedness: a single-sided surface shows only its front face (counter-clockwise in
//!   clip space, as glTF says), except under one uniform opacity (the papers' protocol draws
//!   both faces).
//!
//! Under one uniform opacity ([`super::Opacity::Uniform`]) every surface is transparent with
//! that opacity: alpha modes, transmission and the alpha of factors and textures are ignored;
//! colours still come from the factor, the vertex colour and the texture.

/// A texture's largest side once loaded (larger images are box-filtered down, halving).
pub const MAX_TEXTURE_SIDE: u32 = 1024;

/// Index of refraction where a material gives none (`KHR_materials_ior`'s default).
pub const DEFAULT_IOR: f32 = 1.5;

/// How a material's alpha decides what a fragment is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Coverage {
    /// Opaque (glTF `OPAQUE`).
    Opaque,
    /// Opaque where alpha reaches the cutoff, absent elsewhere (glTF `MASK`).
    Mask(f32),
    /// Transparent with the fragment's alpha (glTF `BLEND`).
    Blend,
}

/// A sampler's wrap mode along one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

impl Wrap {
    /// The mode's code in the GPU's material record (geometry.wgsl's `wrap`).
    pub fn code(self) -> u32 {
        match self {
            Wrap::Repeat => 0,
            Wrap::MirroredRepeat => 1,
            Wrap::ClampToEdge => 2,
        }
    }
}

/// Texel `i` of an axis of `n` texels as the wrap mode places it (geometry.wgsl's `wrap`).
pub fn wrap(i: i32, n: i32, mode: Wrap) -> i32 {
    match mode {
        Wrap::Repeat => ((i % n) + n) % n,
        Wrap::MirroredRepeat => {
            let j = ((i % (2 * n)) + 2 * n) % (2 * n);
            if j < n { j } else { 2 * n - 1 - j }
        }
        Wrap::ClampToEdge => i.clamp(0, n - 1),
    }
}

/// The largest texel coordinate a sample takes before its floor (so the integer conversion
/// cannot overflow): UVs millions of repeats out still wrap, beyond they stay put.
pub const TEXEL_LIMIT: f32 = 16_777_216.0;

/// A base colour texture with its sampler: RGBA8 texels, row-major from the top-left (UV
/// (0, 0)), colour sRGB-encoded and alpha linear, as glTF images store them.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    /// R in the low byte.
    pub texels: Vec<u32>,
    /// Along U (S) and V (T).
    pub wrap: [Wrap; 2],
    /// Magnification filter NEAREST (else bilinear).
    pub nearest: bool,
}

/// `sRGB -> linear` for an 8-bit value, as glTF decodes base colour texels.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// `linear -> sRGB` (encoding textures the project writes).
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// The decode table the GPU reads too (a uniform of 256 floats): entry i is
/// `srgb_to_linear(i / 255)`.
pub fn srgb_table() -> [f32; 256] {
    std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0))
}

/// A texel's 8-bit alpha times this is its opacity (a product, which every device rounds
/// alike, where a quotient may be computed through an approximate reciprocal).
pub const ALPHA_SCALE: f32 = 1.0 / 255.0;

/// The decode table of a data texture (a transmission texture: no sRGB): entry i is
/// `i x ALPHA_SCALE`, as geometry.wgsl decodes one.
pub fn data_table() -> [f32; 256] {
    std::array::from_fn(|i| i as f32 * ALPHA_SCALE)
}

impl Texture {
    /// A texel decoded: colour through the sRGB table, alpha times [`ALPHA_SCALE`].
    fn texel(&self, table: &[f32; 256], x: i32, y: i32) -> [f32; 4] {
        let v = self.texels[(y as u32 * self.width + x as u32) as usize];
        [
            table[(v & 0xff) as usize],
            table[(v >> 8 & 0xff) as usize],
            table[(v >> 16 & 0xff) as usize],
            (v >> 24) as f32 * ALPHA_SCALE,
        ]
    }

    /// The texture at `uv` (geometry.wgsl's `sample_texture`): nearest, or bilinear between
    /// the four texels around `uv * size - 0.5`, each axis wrapped by its mode.
    pub fn sample(&self, table: &[f32; 256], uv: [f32; 2]) -> [f32; 4] {
        let (w, h) = (self.width as i32, self.height as i32);
        let at = |c: f32, n: i32, half: f32| (c * n as f32 - half).clamp(-TEXEL_LIMIT, TEXEL_LIMIT);
        if self.nearest {
            let x = at(uv[0], w, 0.0).floor() as i32;
            let y = at(uv[1], h, 0.0).floor() as i32;
            return self.texel(table, wrap(x, w, self.wrap[0]), wrap(y, h, self.wrap[1]));
        }
        let (x, y) = (at(uv[0], w, 0.5), at(uv[1], h, 0.5));
        let (xf, yf) = (x.floor(), y.floor());
        let (fx, fy) = (x - xf, y - yf);
        let (x0, y0) = (xf as i32, yf as i32);
        let xs = [wrap(x0, w, self.wrap[0]), wrap(x0 + 1, w, self.wrap[0])];
        let ys = [wrap(y0, h, self.wrap[1]), wrap(y0 + 1, h, self.wrap[1])];
        let t00 = self.texel(table, xs[0], ys[0]);
        let t10 = self.texel(table, xs[1], ys[0]);
        let t01 = self.texel(table, xs[0], ys[1]);
        let t11 = self.texel(table, xs[1], ys[1]);
        std::array::from_fn(|i| {
            let top = t00[i] * (1.0 - fx) + t10[i] * fx;
            let bottom = t01[i] * (1.0 - fx) + t11[i] * fx;
            top * (1.0 - fy) + bottom * fy
        })
    }

    /// The texture box-filtered down (halving each side over `limit`, averaging in linear
    /// colour) until both sides are at most `limit`.
    pub fn limited(mut self, limit: u32) -> Texture {
        let table = srgb_table();
        while self.width > limit || self.height > limit {
            let (w2, h2) = (self.width.div_ceil(2), self.height.div_ceil(2));
            let mut out = Vec::with_capacity((w2 * h2) as usize);
            for y in 0..h2 {
                for x in 0..w2 {
                    let mut sum = [0.0f32; 4];
                    let mut n = 0.0;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (sx, sy) = (2 * x + dx, 2 * y + dy);
                        if sx < self.width && sy < self.height {
                            let t = self.texel(&table, sx as i32, sy as i32);
                            for i in 0..4 {
                                sum[i] += t[i];
                            }
                            n += 1.0;
                        }
                    }
                    out.push(pack_texel(sum.map(|s| s / n)));
                }
            }
            self.width = w2;
            self.height = h2;
            self.texels = out;
        }
        self
    }
}

/// A linear RGBA colour as an RGBA8 texel (colour sRGB-encoded, alpha linear).
pub fn pack_texel(c: [f32; 4]) -> u32 {
    let q = |v: f32| crate::fragment::to_unorm8(v);
    q(linear_to_srgb(c[0].clamp(0.0, 1.0)))
        | q(linear_to_srgb(c[1].clamp(0.0, 1.0))) << 8
        | q(linear_to_srgb(c[2].clamp(0.0, 1.0))) << 16
        | q(c[3]) << 24
}

/// A surface's material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// `baseColorFactor`, linear.
    pub base_color: [f32; 4],
    /// Index of the base colour texture in the scene's textures.
    pub texture: Option<u32>,
    pub coverage: Coverage,
    /// `KHR_materials_transmission`'s factor (0: none).
    pub transmission: f32,
    /// Index of its transmission texture in the scene's textures (R times the factor).
    pub transmission_texture: Option<u32>,
    /// `emissiveFactor` times `KHR_materials_emissive_strength`, linear (0: none).
    pub emissive: [f32; 3],
    /// Index of its emissive texture in the scene's textures (sRGB, times `emissive`).
    pub emissive_texture: Option<u32>,
    /// What `KHR_materials_volume` lets through one crossing of a surface, per channel:
    /// `attenuationColor^(thicknessFactor / (2 attenuationDistance))`, half the thickness at
    /// each of a closed volume's two surfaces a ray crosses (the thickness texture is not read).
    /// White where the material has no volume; tinted glass ([`Glass::Tinted`]) multiplies its
    /// tint by it.
    pub attenuation: [f32; 3],
    pub ior: f32,
    pub double_sided: bool,
}

impl Default for Material {
    /// White, untextured, transparent with its vertex alpha, both faces: the built-in scenes'.
    fn default() -> Self {
        Material {
            base_color: [1.0; 4],
            texture: None,
            coverage: Coverage::Blend,
            transmission: 0.0,
            transmission_texture: None,
            emissive: [0.0; 3],
            emissive_texture: None,
            attenuation: [1.0; 3],
            ior: DEFAULT_IOR,
            double_sided: true,
        }
    }
}

impl Material {
    /// Whether its surfaces are transparent (BLEND or glass), else drawn in the opaque pass.
    pub fn transparent(&self) -> bool {
        self.coverage == Coverage::Blend || self.transmission > 0.0
    }

    /// Schlick's reflectance at normal incidence, `((ior - 1) / (ior + 1))^2`.
    pub fn f0(&self) -> f32 {
        let r = (self.ior - 1.0) / (self.ior + 1.0);
        r * r
    }

    /// The alpha cutoff where the mode is MASK.
    pub fn cutoff(&self) -> Option<f32> {
        match self.coverage {
            Coverage::Mask(c) => Some(c),
            _ => None,
        }
    }
}

/// The opacity of glass at view cosine `cos` (geometry.wgsl's `glass_opacity`): what it does
/// not transmit, `1 - T (1 - F)` with Schlick's `F = F0 + (1 - F0)(1 - cos)^5`.
pub fn glass_opacity(transmission: f32, f0: f32, cos: f32) -> f32 {
    1.0 - transmission * (1.0 - fresnel(f0, cos))
}

/// How glass lets through what lies behind it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Glass {
    /// A grey opacity `1 - T (1 - F)`, the base colour its colour: clear glass of any colour
    /// passes every colour alike.
    #[default]
    Grey,
    /// Filtering per channel (McGuire and Mara 2017's coloured transmission): the same opacity,
    /// but a transmittance of `T (1 - F)` times the base colour (the material's factor and
    /// texture; vertex colours carry the headlight's shade and tint nothing), so a red pane
    /// passes red; its colour the Fresnel reflection of the light (`F` of the lit vertex colour,
    /// untinted) and, where `T < 1`, the diffuse base colour of what it does not transmit.
    Tinted,
}

impl Glass {
    pub fn name(self) -> &'static str {
        match self {
            Glass::Grey => "grey",
            Glass::Tinted => "tinted",
        }
    }
}

/// The scene-wide switches a fragment's shade reads: its one opacity where it has one
/// ([`super::Scene::uniform_opacity`]) and how its glass transmits ([`super::Scene::glass`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShadeMode {
    pub uniform: Option<f32>,
    pub glass: Glass,
}

impl From<Option<f32>> for ShadeMode {
    fn from(uniform: Option<f32>) -> ShadeMode {
        ShadeMode {
            uniform,
            glass: Glass::Grey,
        }
    }
}

/// What a fragment of a material is, once shaded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shaded {
    /// Drawn in the opaque pass with this colour (alpha unused).
    Opaque([f32; 4]),
    /// A transparent fragment of this non-premultiplied colour and opacity (not yet clamped),
    /// and its tint (`[1; 3]` but for tinted glass: [`Glass::Tinted`]).
    Transparent([f32; 4], [f32; 3]),
    /// No fragment: a MASK test failed.
    None,
}

/// A fragment of `m` (geometry.wgsl's `shade`): `vertex` the interpolated vertex colour with
/// the headlight's shade on its RGB, `uv` its texture coordinates, `cos` the view cosine
/// (glass), `mode` the scene's one opacity where it has one and how its glass transmits.
pub fn shade(
    m: &Material,
    textures: &[Texture],
    table: &[f32; 256],
    vertex: [f32; 4],
    uv: [f32; 2],
    cos: f32,
    mode: impl Into<ShadeMode>,
) -> Shaded {
    let mode = mode.into();
    let mut c: [f32; 4] = std::array::from_fn(|i| vertex[i] * m.base_color[i]);
    // The base colour without the vertex's, and the volume's attenuation (the tint of tinted
    // glass).
    let mut base: [f32; 3] = std::array::from_fn(|i| m.base_color[i] * m.attenuation[i]);
    if let Some(t) = m.texture {
        let s = textures[t as usize].sample(table, uv);
        c = std::array::from_fn(|i| c[i] * s[i]);
        base = std::array::from_fn(|i| base[i] * s[i]);
    }
    let mut emitted = [0.0; 3];
    // Emission, after the headlight's shade (in `vertex`), which does not dim it.
    if m.emissive != [0.0; 3] {
        let e = match m.emissive_texture {
            Some(t) => {
                let s = textures[t as usize].sample(table, uv);
                std::array::from_fn(|i| m.emissive[i] * s[i])
            }
            None => m.emissive,
        };
        emitted = e;
    }
    let lit = c;
    for (c, e) in c.iter_mut().zip(emitted) {
        *c += e;
    }
    if let Some(a) = mode.uniform {
        c[3] = a;
        return Shaded::Transparent(c, [1.0; 3]);
    }
    if let Coverage::Mask(cut) = m.coverage
        && c[3] < cut
    {
        return Shaded::None;
    }
    if !m.transparent() {
        return Shaded::Opaque(c);
    }
    let coverage = if m.coverage == Coverage::Blend {
        c[3]
    } else {
        1.0
    };
    if m.transmission == 0.0 {
        c[3] = coverage;
        return Shaded::Transparent(c, [1.0; 3]);
    }
    let t = match m.transmission_texture {
        Some(t) => m.transmission * textures[t as usize].sample(&data_table(), uv)[0],
        None => m.transmission,
    };
    let opacity = glass_opacity(t, m.f0(), cos);
    c[3] = coverage * opacity;
    if mode.glass == Glass::Grey || opacity <= 0.0 {
        return Shaded::Transparent(c, [1.0; 3]);
    }
    let (colour, tint) = tinted_glass(t, fresnel(m.f0(), cos), coverage, vertex, lit, base);
    let colour: [f32; 3] = std::array::from_fn(|i| colour[i] + emitted[i]);
    Shaded::Transparent([colour[0], colour[1], colour[2], c[3]], tint)
}

/// Schlick's reflectance at view cosine `cos`, `F0 + (1 - F0)(1 - cos)^5`.
pub fn fresnel(f0: f32, cos: f32) -> f32 {
    let m = 1.0 - cos.clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (1.0 - f0) * (m2 * m2 * m)
}

/// Tinted glass of transmission `t`, reflectance `f` and coverage `cov` (the base alpha where
/// BLEND, else 1) over what it covers: its straight colour (the Fresnel reflection of the lit
/// vertex colour `vertex`, and the diffuse colour `lit` of what it neither reflects nor
/// transmits, over its opacity `1 - t (1 - f)`) and its tint `g`, so that `(1 - a) g` is the
/// transmittance `(1 - cov) + cov t (1 - f) base` per channel.
pub fn tinted_glass(
    t: f32,
    f: f32,
    cov: f32,
    vertex: [f32; 4],
    lit: [f32; 4],
    base: [f32; 3],
) -> ([f32; 3], [f32; 3]) {
    let opacity = 1.0 - t * (1.0 - f);
    let diffuse = (1.0 - t) * (1.0 - f);
    let colour = std::array::from_fn(|i| (f * vertex[i] + diffuse * lit[i]) / opacity);
    let through = t * (1.0 - f);
    let grey = (1.0 - cov) + cov * through;
    // Wholly covered, the base colour itself (no division to round: the GPU's is the same).
    let tint = std::array::from_fn(|i| match (cov >= 1.0, grey > 0.0) {
        (true, _) => base[i].clamp(0.0, 1.0),
        (false, true) => ((1.0 - cov) + cov * through * base[i].clamp(0.0, 1.0)) / grey,
        (false, false) => 1.0,
    });
    (colour, tint)
}
