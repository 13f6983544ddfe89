//! Compositing per-pixel fragment lists: exact (A-buffer), hybrid (k core fragments plus an
//! approximated tail) and multi-layer alpha blending (MLAB).
//!
//! Colours are non-premultiplied; fragments of a pixel sorted front to back have colours `C_i`
//! and opacities `a_i`.
//! - Exact: `sum_i C_i a_i prod_{j<i}(1 - a_j) + prod_i(1 - a_i) C_bg`.
//! - Hybrid, k core and t = n - k tail fragments: `C_core = sum_{i<=k} C_i a_i T_i`, core
//!   transmittance `T_core = prod_{i<=k}(1 - a_i)`; tail `C_tail = sum C_i a_i / sum a_i`,
//!   `a_avg = sum a_i / t`, `a_tail = 1 - (1 - a_avg)^t`; result
//!   `C_core + T_core (a_tail C_tail + (1 - a_tail) C_bg)`. The paper prints the tail term without
//!   the `a_tail` factor; with it a pixel whose fragments share one colour and one opacity
//!   composites exactly for every k. An empty tail, or one of zero opacity, adds nothing.
//! - MLAB (Salvi and Vaidyanathan, listing 1): m rows of premultiplied colour, transmittance and
//!   depth; each fragment, in submission order, is inserted by one bubble pass into m + 1 rows,
//!   then the last two rows are merged.
//! - WBOIT (McGuire and Bavoil 2013): no order at all; each fragment weighted by
//!   `w(z, a) = a max(10^-2, 3 10^3 (1 - z)^3)` (their eq. 10, z the window depth),
//!   `C = (sum C_i a_i w_i / sum a_i w_i) (1 - R) + R C_bg`, revealage `R = prod_i (1 - a_i)`;
//!   the accumulation clamped to [10^-4, 5 10^4] as theirs. Exact for one fragment; wrong
//!   where opacity is high and surfaces lie close in depth (their weights barely differ, so a
//!   near opaque surface does not hide the one just behind it).
//! - MBOIT (Munstermann, Krumpen, Klein and Peters 2018), four power moments in 32 bits: each
//!   fragment's absorbance `A_i = -ln(1 - a_i)` (at most 10) at depth `z_i = 2 d_i - 1` adds to
//!   `b_0 = sum A_i` and `b_j = sum A_i z_i^j`, j = 1..4 (the first additive pass); a
//!   fragment's transmittance `T(z)` is reconstructed from `b_j / b_0`, biased towards
//!   `(0, 0.375, 0, 0.375)` by `beta` (5e-7), as the three-point distribution those moments
//!   admit with one point at `z` weighted by `overestimation` (0.25) ([`mboit_transmittance`]);
//!   the second pass sums `L = sum T(z_i) a_i C_i` and `W = sum T(z_i) a_i`, and
//!   `C = (1 - e^{-b_0}) L / W + e^{-b_0} C_bg`.
//!   Six and eight power moments (b_1..b_6 or b_1..b_8, biased towards the paper's vectors by
//!   5e-6 or 5e-5) place four or five points, the other roots of a cubic or a quartic
//!   ([`mboit_transmittance_n`]). Exact for one fragment; bounded memory whatever
//!   the depth; smooth where surfaces lie close in depth, too soft where one opaque surface
//!   should hide another.
//!
//! "Front to back" is the order of [`crate::fragment::fragment_key`] (see [`crate::fragment`]).

use crate::fragment::{Fragment, FragmentLists, fragment_key, sort_front_to_back, to_unorm8};
use rayon::prelude::*;

/// A linear RGB image, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub data: Vec<[f32; 3]>,
}

impl Image {
    /// A black image of `size` (width, height), the size convention of every function here.
    pub fn new(size: (u32, u32)) -> Self {
        let (width, height) = size;
        Image {
            width,
            height,
            data: vec![[0.0; 3]; (width * height) as usize],
        }
    }

    /// (width, height).
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Mean over pixels and channels of the squared difference.
    pub fn mse(&self, other: &Image) -> f64 {
        assert_eq!(self.data.len(), other.data.len(), "images differ in size");
        let sum: f64 = self
            .data
            .iter()
            .zip(&other.data)
            .map(|(a, b)| (0..3).map(|i| ((a[i] - b[i]) as f64).powi(2)).sum::<f64>())
            .sum();
        sum / (3 * self.data.len().max(1)) as f64
    }

    /// Largest absolute channel difference.
    pub fn max_abs_diff(&self, other: &Image) -> f32 {
        self.data
            .iter()
            .zip(&other.data)
            .flat_map(|(a, b)| (0..3).map(move |i| (a[i] - b[i]).abs()))
            .fold(0.0, f32::max)
    }
}

/// Exact compositing of fragments already sorted front to back: each adds its premultiplied
/// colour through what the ones in front let through, and lets through its transmittance
/// `(1 - a) g` per channel ([`Fragment::transmittance`]).
pub fn exact_sorted(frags: &[Fragment], bg: [f32; 3]) -> [f32; 3] {
    let (c, t) = over_sorted(frags);
    std::array::from_fn(|i| c[i] + t[i] * bg[i])
}

/// Fragments sorted front to back blended into a premultiplied colour and what they let
/// through of what is behind them, per channel.
fn over_sorted(frags: &[Fragment]) -> ([f32; 3], [f32; 3]) {
    let mut c = [0.0f32; 3];
    let mut t = [1.0f32; 3];
    for f in frags {
        let a = f.rgba[3];
        let through = f.transmittance();
        for i in 0..3 {
            c[i] += t[i] * a * f.rgba[i];
            t[i] *= through[i];
        }
    }
    (c, t)
}

/// Exact compositing of fragments in any order.
pub fn exact_pixel(frags: &[Fragment], bg: [f32; 3]) -> [f32; 3] {
    let mut v = frags.to_vec();
    sort_front_to_back(&mut v);
    exact_sorted(&v, bg)
}

/// WBOIT's weight functions, as McGuire and Bavoil (2013) give them: eqs. 7-9 of the
/// fragment's view-space distance |z| (in the scene's units, tuned by the paper for 0.1 to 500),
/// eq. 10 of its window depth alone. Each multiplies the fragment's opacity by a depth factor
/// clamped to [10^-2, 3 10^3].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WboitWeight {
    /// `10 / (10^-5 + (|z|/5)^2 + (|z|/200)^6)`: falls from near surfaces.
    Eq7,
    /// `10 / (10^-5 + (|z|/10)^3 + (|z|/200)^6)`.
    Eq8,
    /// `0.03 / (10^-5 + (|z|/200)^4)`: flat until far away.
    Eq9,
    /// `3 10^3 (1 - d)^3`, d the window depth: needs no depth range (the default).
    #[default]
    Eq10,
}

impl WboitWeight {
    pub const ALL: [WboitWeight; 4] = [
        WboitWeight::Eq7,
        WboitWeight::Eq8,
        WboitWeight::Eq9,
        WboitWeight::Eq10,
    ];

    /// Its name on the command line (`eq7` .. `eq10`).
    pub fn name(self) -> &'static str {
        match self {
            WboitWeight::Eq7 => "eq7",
            WboitWeight::Eq8 => "eq8",
            WboitWeight::Eq9 => "eq9",
            WboitWeight::Eq10 => "eq10",
        }
    }

    /// The weight function named `s`, or an error listing them.
    pub fn parse(s: &str) -> crate::error::Result<WboitWeight> {
        WboitWeight::ALL
            .into_iter()
            .find(|w| w.name() == s.trim().to_ascii_lowercase())
            .ok_or_else(|| {
                crate::error::Error::Invalid(format!(
                    "'{s}' is not a WBOIT weight function: eq7, eq8, eq9 (of the view-space \
                     distance) or eq10 (of the window depth; the default)"
                ))
            })
    }

    /// Its code in the frame's parameters (`Params::wboit_weight`, wboit_accumulate.wgsl).
    pub fn code(self) -> u32 {
        self as u32
    }

    /// Whether it reads the view-space distance (eqs. 7-9), which needs the camera's planes.
    pub fn needs_depth_range(self) -> bool {
        self != WboitWeight::Eq10
    }
}

/// WBOIT's parameters: its weight function and, for eqs. 7-9, the camera's near and far planes,
/// from which a fragment's window depth d gives its view-space distance
/// `near far / (far - d (far - near))` (the inverse of `scene::perspective_rh`'s depth).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WboitParams {
    pub weight: WboitWeight,
    pub near: f32,
    pub far: f32,
}

impl WboitParams {
    /// `weight` with `cam`'s planes.
    pub fn for_camera(weight: WboitWeight, cam: &crate::scene::Camera) -> WboitParams {
        WboitParams {
            weight,
            near: cam.near,
            far: cam.far,
        }
    }

    /// Refuses a weight function of the view-space distance without a depth range
    /// (`0 < near < far`, finite).
    pub fn check(&self) -> crate::error::Result<()> {
        let (n, f) = (self.near, self.far);
        if self.weight.needs_depth_range() && !(n > 0.0 && n < f && f.is_finite()) {
            return Err(crate::error::Error::Invalid(format!(
                "WBOIT's weight {} reads the view-space distance: it needs the camera's near \
                 and far planes, 0 < near < far (given {n} and {f})",
                self.weight.name()
            )));
        }
        Ok(())
    }

    /// The view-space distance of window depth `d` (wboit_accumulate.wgsl's `view_distance`).
    pub fn view_distance(&self, d: f32) -> f32 {
        self.near * self.far / (self.far - d * (self.far - self.near))
    }
}

/// WBOIT's weight of a fragment at window depth `d` with opacity `a` (McGuire and Bavoil 2013,
/// the function `p` names; wboit_accumulate.wgsl's `weight`).
pub fn wboit_weight(p: &WboitParams, d: f32, a: f32) -> f32 {
    let clamp = |w: f32| w.clamp(1e-2, 3e3);
    let z = || p.view_distance(d);
    match p.weight {
        WboitWeight::Eq7 => {
            let (u, v) = (z() / 5.0, z() / 200.0);
            let v3 = v * v * v;
            a * clamp(10.0 / (1e-5 + u * u + v3 * v3))
        }
        WboitWeight::Eq8 => {
            let (u, v) = (z() / 10.0, z() / 200.0);
            let v3 = v * v * v;
            a * clamp(10.0 / (1e-5 + u * u * u + v3 * v3))
        }
        WboitWeight::Eq9 => {
            let v = z() / 200.0;
            let v2 = v * v;
            a * clamp(0.03 / (1e-5 + v2 * v2))
        }
        WboitWeight::Eq10 => {
            let e = 1.0 - d;
            a * (3e3 * e * e * e).max(1e-2)
        }
    }
}

/// Weighted blended OIT of a pixel's fragments in exact targets, summed front to back in f32:
/// the paper's formula, which [`wboit_blended`] computes at the precision of the targets
/// engines give it.
pub fn wboit_sorted(frags: &[Fragment], bg: [f32; 3], p: &WboitParams) -> [f32; 3] {
    wboit_sums(frags, bg, Sums::Exact, p)
}

/// How the blended methods' sums are held: exactly (f32), or as engines' targets hold them
/// (binary16 colour sums rounded after each add; WBOIT's revealage in 8 bits).
#[derive(Clone, Copy, PartialEq)]
enum Sums {
    Exact,
    Targets,
}

impl Sums {
    fn add(self, sum: f32, v: f32) -> f32 {
        match self {
            Sums::Exact => sum + v,
            Sums::Targets => to_binary16(sum + v),
        }
    }
}

/// WBOIT over `frags` in their order, summed as `sums` says.
fn wboit_sums(frags: &[Fragment], bg: [f32; 3], sums: Sums, p: &WboitParams) -> [f32; 3] {
    let mut acc = [0.0f32; 4];
    let mut reveal = 1.0f32;
    let mut reveal8 = 255u32;
    for f in frags {
        let a = f.rgba[3];
        let w = wboit_weight(p, f.depth, a);
        let src = [
            f.rgba[0] * a * w,
            f.rgba[1] * a * w,
            f.rgba[2] * a * w,
            a * w,
        ];
        for (s, v) in acc.iter_mut().zip(src) {
            *s = sums.add(*s, v);
        }
        reveal *= 1.0 - a;
        reveal8 = (reveal8 * (255 - to_unorm8(a)) + 127) / 255;
    }
    if sums == Sums::Targets {
        reveal = reveal8 as f32 / 255.0;
    }
    // Per channel, what the fragments let through (McGuire and Bavoil's coloured transmission)
    // where one is tinted, else the revealage.
    let through = tinted_through(frags, sums).unwrap_or([reveal; 3]);
    let inv = 1.0 / acc[3].clamp(1e-4, 5e4);
    std::array::from_fn(|i| acc[i] * inv * (1.0 - reveal) + through[i] * bg[i])
}

/// An RGBA8 target's RGB, cleared to 1, multiplied by fragment `f`'s transmittance `(1 - a) g`
/// as a device's blending does (`dst (1 - src)`, src `1 - (1 - a) g`): each channel times the
/// transmittance in 8 bits, rounded to the nearest 1/255 (the revealage's rounding).
fn multiply8(t8: [u32; 3], f: &Fragment) -> [u32; 3] {
    let a8 = to_unorm8(f.rgba[3]);
    std::array::from_fn(|i| {
        let g8 = (f.tint >> (8 * i)) & 0xff;
        (t8[i] * (((255 - a8) * g8 + 127) / 255) + 127) / 255
    })
}

/// A value as a binary16 target stores it (round to nearest even): what a device's blend
/// unit writes into an RGBA16F target after each fragment.
fn to_binary16(v: f32) -> f32 {
    half::f16::from_f32(v).to_f32()
}

/// Fragments in submission order: the order a device blends one draw's fragments into a pixel
/// (primitive order), whatever order a list holds them in.
fn in_submission_order(frags: &[Fragment]) -> Vec<Fragment> {
    let mut v = frags.to_vec();
    v.sort_by_key(|f| f.primitive);
    v
}

/// WBOIT as engines ship it and the GPU renders it (`gpu::blend`): the fragments in submission
/// order, each adding its weighted colour and weight into a binary16 accumulation (rounded to
/// binary16 after each add, as the blend unit stores it) and multiplying an 8-bit revealage by
/// `1 - a` (rounded to the nearest 1/255). [`wboit_sorted`]'s formula at its targets'
/// precision: the rounding depends on the submission order, by at most a few binary16 steps of
/// the accumulation and a few 1/255 of the revealage.
pub fn wboit_blended(frags: &[Fragment], bg: [f32; 3], p: &WboitParams) -> [f32; 3] {
    wboit_sums(&in_submission_order(frags), bg, Sums::Targets, p)
}

/// MBOIT's parameters: the number of power moments (4, 6 or 8), the moment bias and the
/// overestimation; the paper's defaults for four power moments in 32 bits
/// ([`MboitParams::default`]), or for six and eight ([`MboitParams::with_moments`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MboitParams {
    /// Power moments b_1..b_n beside b_0: 4, 6 or 8 (the paper's; 32-bit float targets).
    pub moments: u32,
    /// How far the normalized moments are pulled towards `(0, 0.375, 0, 0.375)` before the
    /// reconstruction (the paper's 5e-7 for four power moments in 32 bits): what keeps the
    /// Hankel matrix of one or two fragments' moments invertible in float.
    pub bias: f32,
    /// The weight of the reconstruction's point at the fragment's own depth that counts as in
    /// front of it (0: none of the fragment's own absorbance, 1: all; the paper's 0.25).
    pub overestimation: f32,
}

impl Default for MboitParams {
    fn default() -> Self {
        MboitParams {
            moments: 4,
            bias: MBOIT_BIAS[0],
            overestimation: 0.25,
        }
    }
}

/// The paper's moment bias for 4, 6 and 8 power moments in 32-bit floats (Munstermann et al.
/// 2018, table 1: 5e-7, 5e-6, 5e-5).
pub const MBOIT_BIAS: [f32; 3] = [5e-7, 5e-6, 5e-5];

impl MboitParams {
    /// The paper's defaults for `moments` power moments (4, 6 or 8): its bias for them
    /// ([`MBOIT_BIAS`]) and the overestimation 0.25; another count is an error.
    pub fn with_moments(moments: u32) -> crate::error::Result<MboitParams> {
        let bias = match moments {
            4 => MBOIT_BIAS[0],
            6 => MBOIT_BIAS[1],
            8 => MBOIT_BIAS[2],
            n => {
                return Err(crate::error::Error::Invalid(format!(
                    "MBOIT takes 4, 6 or 8 power moments, not {n}"
                )));
            }
        };
        Ok(MboitParams {
            moments,
            bias,
            ..MboitParams::default()
        })
    }
}

/// MBOIT's largest absorbance of one fragment (opacity 1 - e^-10): a fragment of opacity 1
/// adds this, not infinity.
pub const MBOIT_MAX_ABSORBANCE: f32 = 10.0;

/// MBOIT's smallest `b_0` a pixel blends (the absorbance of opacity 0.001); below, the pixel
/// shows what is behind it.
pub const MBOIT_MIN_B0: f32 = 0.001_000_500_3;

/// MBOIT's absorbance `min(-ln(1 - a), 10)` of each 8-bit opacity, computed in f64: a table the
/// GPU reads too (a uniform), so both sides sum the same floats; the moments of surfaces close
/// in depth are ill-conditioned in 32 bits, and a logarithm rounded differently on the device
/// moves their reconstruction by 1e-4.
pub fn mboit_absorbance_table() -> [f32; 256] {
    std::array::from_fn(|a| {
        let a = a as f64 / 255.0;
        (-(1.0 - a).ln()).min(MBOIT_MAX_ABSORBANCE as f64) as f32
    })
}

/// MBOIT's absorbance of a fragment of opacity `a` (an 8-bit value, as every fragment's is):
/// [`mboit_absorbance_table`]'s entry.
pub fn mboit_absorbance(a: f32) -> f32 {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(mboit_absorbance_table)[to_unorm8(a) as usize]
}

/// The transmittance in front of depth `z` (in [-1, 1]) that four power moments admit: `b0`
/// and the moments `b = (b_1, .., b_4)` divided by `b0`. The moments, biased, form the 3x3
/// Hankel matrix `B = (b_{i+j})`, i, j = 0..2 (b_0 = 1); `B c = (1, z, z^2)` (solved by
/// `B = L D L^T`) gives the polynomial `c_0 + c_1 x + c_2 x^2` whose roots `z_1 <= z_2` are the
/// other two points of the distribution; the quadratic through `(z, overestimation)`,
/// `(z_1, [z_1 < z])`, `(z_2, [z_2 < z])`, integrated against the moments, is the share of the
/// absorbance in front of `z`. mboit.wgsl's `transmittance`, operation for operation.
pub fn mboit_transmittance(b0: f32, b: [f32; 4], z: f32, p: MboitParams) -> f32 {
    (-b0 * mboit_share(b, z, p)).exp().clamp(0.0, 1.0)
}

/// [`mboit_transmittance`] from `p.moments` power moments `b` (b_1..b_n over b_0; the rest
/// unread): four (or any count but six and eight) as there; six and eight as the paper reconstructs them (the 4x4 or 5x5 Hankel
/// matrix's Cholesky factorization, the cubic or quartic whose roots are the distribution's
/// other points, the interpolation polynomial through them). mboit.wgsl's
/// `transmittance_n`, operation for operation. Where 32-bit floats cannot form that
/// distribution (a pivot or a root difference of zero, a root that is not a finite real), the
/// first four moments' reconstruction stands in, so no infinity or NaN is ever formed.
pub fn mboit_transmittance_n(b0: f32, b: [f32; 8], z: f32, p: MboitParams) -> f32 {
    let four = [b[0], b[1], b[2], b[3]];
    let share = match p.moments {
        6 => mboit_share6(b, z, p),
        8 => mboit_share8(b, z, p),
        _ => None,
    };
    let share = share.unwrap_or_else(|| mboit_share(four, z, p));
    (-b0 * share).exp().clamp(0.0, 1.0)
}

/// The paper's bias vectors for six and eight power moments (what the moments are pulled
/// towards).
const MBOIT_PULL6: [f32; 6] = [0.0, 0.48, 0.0, 0.451, 0.0, 0.45];
const MBOIT_PULL8: [f32; 8] = [0.0, 0.75, 0.0, 0.676_666_7, 0.0, 0.63, 0.0, 0.600_303_03];

/// Whether every value is finite.
fn finite(v: &[f32]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// The share of the absorbance in front of `z` that six power moments admit (four points: `z`
/// and the roots of a cubic), or None where floats cannot form it.
fn mboit_share6(b: [f32; 8], z: f32, p: MboitParams) -> Option<f32> {
    let beta = p.bias;
    let b: [f32; 6] = std::array::from_fn(|i| b[i] * (1.0 - beta) + MBOIT_PULL6[i] * beta);
    // The Hankel matrix's L D L^T, its non-trivial entries.
    let d11 = b[1] - b[0] * b[0];
    let l21d11 = b[2] - b[0] * b[1];
    let l21 = l21d11 / d11;
    let d22 = (b[3] - b[1] * b[1]) - l21d11 * l21;
    let l31d11 = b[3] - b[0] * b[2];
    let l31 = l31d11 / d11;
    let l32d22 = (b[4] - b[1] * b[2]) - l21d11 * l31;
    let l32 = l32d22 / d22;
    let d33 = (b[5] - b[2] * b[2]) - (l31d11 * l31 + l32d22 * l32);
    if !(d11 > 0.0 && d22 > 0.0 && d33 > 0.0) {
        return None;
    }
    // B c = (1, z, z^2, z^3): forward, scale, backward.
    let mut c = [1.0, z, z * z, z * z * z];
    c[1] -= b[0];
    c[2] -= b[1] + l21 * c[1];
    c[3] -= b[2] + (l31 * c[1] + l32 * c[2]);
    c[1] /= d11;
    c[2] /= d22;
    c[3] /= d33;
    c[2] -= l32 * c[3];
    c[1] -= l21 * c[2] + l31 * c[3];
    c[0] -= b[0] * c[1] + b[1] * c[2] + b[2] * c[3];
    let r = mboit_cubic_roots(c)?;
    let zs = [z, r[0], r[1], r[2]];
    let f = weights_in_front(&zs, p.overestimation);
    let a = newton_to_monomial(&zs, &f)?;
    let share = a[0] + a[1] * b[0] + a[2] * b[1] + a[3] * b[2];
    share.is_finite().then_some(share)
}

/// The share in front of `z` that eight power moments admit (five points: `z` and the roots of
/// a quartic), or None where floats cannot form it.
fn mboit_share8(b: [f32; 8], z: f32, p: MboitParams) -> Option<f32> {
    let beta = p.bias;
    let b: [f32; 8] = std::array::from_fn(|i| b[i] * (1.0 - beta) + MBOIT_PULL8[i] * beta);
    let d22 = b[1] - b[0] * b[0];
    let l32d22 = b[2] - b[1] * b[0];
    let l32 = l32d22 / d22;
    let l42d22 = b[3] - b[2] * b[0];
    let l42 = l42d22 / d22;
    let l52d22 = b[4] - b[3] * b[0];
    let l52 = l52d22 / d22;
    let d33 = (b[3] - b[1] * b[1]) - l32 * l32d22;
    let l43d33 = (b[4] - b[2] * b[1]) - l42 * l32d22;
    let l43 = l43d33 / d33;
    let l53d33 = (b[5] - b[3] * b[1]) - l52 * l32d22;
    let l53 = l53d33 / d33;
    let d44 = (b[5] - b[2] * b[2]) - (l42 * l42d22 + l43 * l43d33);
    let l54d44 = (b[6] - b[3] * b[2]) - (l52 * l42d22 + l53 * l43d33);
    let l54 = l54d44 / d44;
    let d55 = (b[7] - b[3] * b[3]) - (l52 * l52d22 + l53 * l53d33 + l54 * l54d44);
    if !(d22 > 0.0 && d33 > 0.0 && d44 > 0.0 && d55 > 0.0) {
        return None;
    }
    let mut c = [1.0, z, z * z, z * z * z, z * z * z * z];
    c[1] -= b[0];
    c[2] -= b[1] + l32 * c[1];
    c[3] -= b[2] + (l42 * c[1] + l43 * c[2]);
    c[4] -= b[3] + (l52 * c[1] + l53 * c[2] + l54 * c[3]);
    c[1] /= d22;
    c[2] /= d33;
    c[3] /= d44;
    c[4] /= d55;
    c[3] -= l54 * c[4];
    c[2] -= l53 * c[4] + l43 * c[3];
    c[1] -= l52 * c[4] + l42 * c[3] + l32 * c[2];
    c[0] -= b[3] * c[4] + b[2] * c[3] + b[1] * c[2] + b[0] * c[1];
    let r = mboit_quartic_roots(c)?;
    let zs = [z, r[0], r[1], r[2], r[3]];
    let f = weights_in_front(&zs, p.overestimation);
    let a = newton_to_monomial(&zs, &f)?;
    let share = a[0] + a[1] * b[0] + a[2] * b[1] + a[3] * b[2] + a[4] * b[3];
    share.is_finite().then_some(share)
}

/// The weight of each point of the distribution that counts as in front of `zs[0]`: the
/// overestimation for itself, 1 for a point nearer, 0 for one farther.
fn weights_in_front<const N: usize>(zs: &[f32; N], overestimation: f32) -> [f32; N] {
    std::array::from_fn(|i| match i {
        0 => overestimation,
        _ if zs[i] < zs[0] => 1.0,
        _ => 0.0,
    })
}

/// The coefficients (constant first) of the polynomial through (zs[i], f[i]): Newton's divided
/// differences, expanded. None where two points coincide in float.
fn newton_to_monomial<const N: usize>(zs: &[f32; N], f: &[f32; N]) -> Option<[f32; N]> {
    // d[i] = f[z_0 .. z_i] after the loop.
    let mut d = *f;
    for level in 1..N {
        for i in (level..N).rev() {
            let dz = zs[i] - zs[i - level];
            if dz == 0.0 {
                return None;
            }
            d[i] = (d[i] - d[i - 1]) / dz;
        }
    }
    // Horner from the last difference: p = d[N-1]; p = p (x - z_i) + d[i].
    let mut a = [0.0f32; N];
    a[0] = d[N - 1];
    for i in (0..N - 1).rev() {
        // a <- a (x - z_i) + d[i]
        for j in (1..N).rev() {
            a[j] = a[j - 1] - a[j] * zs[i];
        }
        a[0] = d[i] - a[0] * zs[i];
    }
    finite(&a).then_some(a)
}

/// The three real roots of `c[0] + c[1] x + c[2] x^2 + c[3] x^3` (Peters' trigonometric
/// solution, as the paper's code), or None where they are not finite reals.
fn mboit_cubic_roots(c: [f32; 4]) -> Option<[f32; 3]> {
    if c[3] == 0.0 {
        return None;
    }
    let (c0, c1, c2) = (c[0] / c[3], c[1] / c[3] / 3.0, c[2] / c[3] / 3.0);
    let delta = [c1 - c2 * c2, c0 - c1 * c2, c2 * c0 - c1 * c1];
    let discriminant = 4.0 * delta[0] * delta[2] - delta[1] * delta[1];
    let depressed = [delta[1] - 2.0 * c2 * delta[0], delta[0]];
    if !(discriminant >= 0.0 && depressed[1] <= 0.0) {
        return None;
    }
    let theta = discriminant.sqrt().atan2(-depressed[0]) / 3.0;
    let (sin, cos) = (theta.sin(), theta.cos());
    let half_sqrt3 = 0.5 * 3.0f32.sqrt();
    let scale = 2.0 * (-depressed[1]).sqrt();
    let roots = [
        scale * cos - c2,
        scale * (-0.5 * cos - half_sqrt3 * sin) - c2,
        scale * (-0.5 * cos + half_sqrt3 * sin) - c2,
    ];
    finite(&roots).then_some(roots)
}

/// The smallest root of the cubic `c[0] + c[1] x + c[2] x^2 + x^3` with three real roots
/// (Blinn's), for the quartic's resolvent.
fn cubic_smallest_root(c: [f32; 3]) -> Option<f32> {
    let (c0, c1, c2) = (c[0], c[1] / 3.0, c[2] / 3.0);
    let delta = [c1 - c2 * c2, c0 - c2 * c1, c2 * c0 - c1 * c1];
    let discriminant = 4.0 * delta[0] * delta[2] - delta[1] * delta[1];
    let depressed = [delta[2], -c0 * delta[1] + 2.0 * c1 * delta[2]];
    if !(discriminant >= 0.0 && depressed[0] <= 0.0) {
        return None;
    }
    let theta = (c0 * discriminant.sqrt()).atan2(-depressed[1]).abs() / 3.0;
    let (sin, cos) = (theta.sin(), theta.cos());
    let t = 2.0 * (-depressed[0]).sqrt();
    let x = [t * cos, t * (-0.5 * cos - 0.5 * 3.0f32.sqrt() * sin)];
    let s = if x[0] + x[1] < 2.0 * c1 {
        [-c0, x[0] + c1]
    } else {
        [-c0, x[1] + c1]
    };
    let root = s[0] / s[1];
    root.is_finite().then_some(root)
}

/// The two roots of `x^2 + b x + c` (numerically stable), or None where they are not real.
fn quadratic_roots(b: f32, c: f32) -> Option<[f32; 2]> {
    let half = 0.5 * b;
    let disc = half * half - c;
    // Not real (or NaN: the comparison is false).
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let r = disc.sqrt();
    let roots = if half >= 0.0 {
        [-c / (half + r), -half - r]
    } else {
        [-half + r, c / (-half + r)]
    };
    finite(&roots).then_some(roots)
}

/// The four real roots of `c[0] + .. + c[4] x^4` (Neumark's factorization into two
/// quadratics, chosen as Herbison-Evans proposes, as the paper's code), or None where they are
/// not finite reals.
fn mboit_quartic_roots(c: [f32; 5]) -> Option<[f32; 4]> {
    if c[4] == 0.0 {
        return None;
    }
    let (b, cc, d, e) = (c[3] / c[4], c[2] / c[4], c[1] / c[4], c[0] / c[4]);
    // The cubic resolvent's smallest root.
    let p = -2.0 * cc;
    let q = cc * cc + b * d - 4.0 * e;
    let r = d * d + b * b * e - b * cc * d;
    let y = cubic_smallest_root([r, q, p])?;
    let bb = b * b;
    let fy = 4.0 * y;
    let bb_fy = bb - fy;
    let zz0 = cc - y;
    let zz = zz0 * zz0;
    let fe = 4.0 * e;
    let zz_fe = zz - fe;
    let (g1, g2, h1, h2);
    if y < 0.0 || (zz + fe) * bb_fy > zz_fe * (bb + fy) {
        let t = bb_fy.sqrt();
        g1 = (b + t) * 0.5;
        g2 = (b - t) * 0.5;
        let t = (b * zz0 - 2.0 * d) / (2.0 * t);
        h1 = zz0 * 0.5 + t;
        h2 = zz0 * 0.5 - t;
    } else {
        let t = zz_fe.sqrt();
        h1 = (zz0 + t) * 0.5;
        h2 = (zz0 - t) * 0.5;
        let t = (b * zz0 - 2.0 * d) / (2.0 * t);
        g1 = b * 0.5 + t;
        g2 = b * 0.5 - t;
    }
    let [r0, r1] = quadratic_roots(g1, h1)?;
    let [r2, r3] = quadratic_roots(g2, h2)?;
    Some([r0, r1, r2, r3])
}

/// The share of a pixel's absorbance in front of `z` ([`mboit_transmittance`]). Where 32-bit
/// floats cannot separate the points (surfaces at one depth, whose Hankel matrix the bias keeps
/// invertible only in exact arithmetic), every fragment counts as at `z`: the share is the
/// overestimation, as it is for one surface. So no infinity or NaN is ever formed (which WGSL
/// lets a device assume away).
fn mboit_share(b: [f32; 4], z: f32, p: MboitParams) -> f32 {
    let beta = p.bias;
    let pull = [0.0, 0.375, 0.0, 0.375];
    let m: [f32; 4] = std::array::from_fn(|i| b[i] * (1.0 - beta) + pull[i] * beta);
    let one_depth = p.overestimation;
    // B = L D L^T: D = (1, d2, d3), L's lower entries b1, b2 and l32.
    let d2 = m[1] - m[0] * m[0];
    if d2 <= 0.0 {
        return one_depth;
    }
    let l32 = (m[2] - m[0] * m[1]) / d2;
    let d3 = m[3] - m[1] * m[1] - l32 * l32 * d2;
    if d3 <= 0.0 {
        return one_depth;
    }
    // L y = (1, z, z^2), then D, then L^T c = y.
    let y2 = (z - m[0]) / d2;
    let y3 = (z * z - m[1] - l32 * (z - m[0])) / d3;
    let c2 = y3;
    let c1 = y2 - l32 * c2;
    let c0 = 1.0 - m[0] * c1 - m[1] * c2;
    if c2 == 0.0 {
        return one_depth;
    }
    // The other two points: c_2 x^2 + c_1 x + c_0 = 0.
    let half = -0.5 * c1 / c2;
    let disc = half * half - c0 / c2;
    let r = if disc > 0.0 { disc.sqrt() } else { 0.0 };
    let (z1, z2) = (half - r, half + r);
    if z1 == z || z2 == z1 || z2 == z {
        return one_depth;
    }
    // Newton's divided differences of the weights at z, z1, z2, expanded to a_0 + a_1 x + a_2 x^2.
    let f0 = p.overestimation;
    let f1 = if z1 < z { 1.0 } else { 0.0 };
    let f2 = if z2 < z { 1.0 } else { 0.0 };
    let f01 = (f1 - f0) / (z1 - z);
    let f12 = (f2 - f1) / (z2 - z1);
    let f012 = (f12 - f01) / (z2 - z);
    let a2 = f012;
    let a1 = f01 - f012 * (z + z1);
    let a0 = f0 - f01 * z + f012 * z * z1;
    a0 + a1 * m[0] + a2 * m[1]
}

/// A fragment's terms `a z^j`, j = 1..8, as the moments pass computes them
/// (mboit_moments.wgsl), products left to right: a z, a z2, a z2 z, a z2 z2, then with
/// z4 = z2 z2 and z6 = z4 z2: a z4 z, a z4 z2, a z6 z, a z4 z4.
pub fn mboit_terms(a: f32, z: f32) -> [f32; 8] {
    let z2 = z * z;
    let z4 = z2 * z2;
    let z6 = z4 * z2;
    [
        a * z,
        a * z2,
        a * z2 * z,
        a * z2 * z2,
        a * z4 * z,
        a * z4 * z2,
        a * z6 * z,
        a * z4 * z4,
    ]
}

/// Moment-based OIT of a pixel's fragments, both passes summed front to back in f32: the
/// paper's passes in exact order, which [`mboit_blended`] computes in submission order with its
/// colour target in binary16.
pub fn mboit_sorted(frags: &[Fragment], bg: [f32; 3], p: MboitParams) -> [f32; 3] {
    mboit_passes(frags, bg, p, Sums::Exact)
}

/// MBOIT as Munstermann et al. lay it out and the GPU renders it (`gpu::blend`): the fragments
/// in submission order, b_0 and the moments added in f32 (their targets' precision), then each
/// fragment's transmittance-weighted colour added into a binary16 target (rounded after each
/// add). [`mboit_sorted`]'s passes at their targets' precision and order.
pub fn mboit_blended(frags: &[Fragment], bg: [f32; 3], p: MboitParams) -> [f32; 3] {
    mboit_passes(&in_submission_order(frags), bg, p, Sums::Targets)
}

/// Where a fragment is tinted, what the background is seen through per channel: the product
/// of the fragments' transmittances, in f32 (`Sums::Exact`), or in an RGBA8 target as the GPU
/// multiplies it (`Sums::Targets`, [`multiply8`]). WBOIT's and MBOIT's colours keep their grey
/// share; only the background is filtered per channel.
fn tinted_through(frags: &[Fragment], sums: Sums) -> Option<[f32; 3]> {
    if !frags.iter().any(|f| f.tint != crate::fragment::CLEAR) {
        return None;
    }
    Some(match sums {
        Sums::Exact => frags.iter().fold([1.0; 3], |t, f| {
            let ft = f.transmittance();
            std::array::from_fn(|i| t[i] * ft[i])
        }),
        Sums::Targets => frags
            .iter()
            .fold([255; 3], multiply8)
            .map(|t| t as f32 / 255.0),
    })
}

/// MBOIT's two passes over `frags` in their order, the colour summed as `sums` says.
fn mboit_passes(frags: &[Fragment], bg: [f32; 3], p: MboitParams, sums: Sums) -> [f32; 3] {
    let mut b0 = 0.0f32;
    let mut b = [0.0f32; 8];
    for f in frags {
        let a = mboit_absorbance(f.rgba[3]);
        b0 += a;
        for (j, v) in mboit_terms(a, 2.0 * f.depth - 1.0).iter().enumerate() {
            b[j] += v;
        }
    }
    if b0 < MBOIT_MIN_B0 {
        let t = tinted_through(frags, sums).unwrap_or([1.0; 3]);
        return std::array::from_fn(|i| t[i] * bg[i]);
    }
    let m = b.map(|x| x / b0);
    let mut acc = [0.0f32; 4];
    for f in frags {
        let z = 2.0 * f.depth - 1.0;
        let t = mboit_transmittance_n(b0, m, z, p) * f.rgba[3];
        let src = [t * f.rgba[0], t * f.rgba[1], t * f.rgba[2], t];
        for (s, v) in acc.iter_mut().zip(src) {
            *s = sums.add(*s, v);
        }
    }
    let total = (-b0).exp();
    let through = tinted_through(frags, sums).unwrap_or([total; 3]);
    let inv = if acc[3] > 0.0 { 1.0 / acc[3] } else { 0.0 };
    std::array::from_fn(|i| (1.0 - total) * acc[i] * inv + through[i] * bg[i])
}

/// The budgeted per-pixel linked list (as Bevy ships it) keeps fragments first come, first
/// served, until the frame's `capacity` of nodes is spent; what arrives after is dropped. The
/// order of arrival is the order of submission (triangle by triangle; within a triangle, pixel
/// by pixel in rows, as the CPU rasterizer walks it): one flag a fragment of `fl`, in list
/// order, saying whether it was kept. A GPU appends in the order its atomics happen to run, so
/// where the capacity truncates, which fragments it keeps differs from run to run.
pub fn linked_list_kept(fl: &FragmentLists, capacity: u64) -> Vec<bool> {
    let n = fl.fragment_count();
    let mut keep = vec![false; n];
    if capacity >= n as u64 {
        keep.fill(true);
        return keep;
    }
    let mut arrival: Vec<(u32, u32, u32)> = Vec::with_capacity(n);
    for p in 0..fl.pixel_count() {
        for i in fl.range(p) {
            arrival.push((fl.primitive[i], p as u32, i as u32));
        }
    }
    arrival.sort_unstable();
    for &(_, _, i) in &arrival[..capacity as usize] {
        keep[i as usize] = true;
    }
    keep
}

/// The linked list's nearest fragments a pixel sorted and blended at resolve (the rest as a
/// hybrid tail): Bevy's default.
pub const LIST_SORTED: u32 = 8;

/// The most a pixel's sorted fragments may be ([`LIST_SORTED`] is the default): the resolve
/// keeps them in a private array of this size.
pub const LIST_MAX_SORTED: u32 = 16;

/// Refuses a linked list's sorted count outside 1 to [`LIST_MAX_SORTED`], with the range.
pub fn check_list_sorted(sorted: u32) -> crate::error::Result<()> {
    if (1..=LIST_MAX_SORTED).contains(&sorted) {
        return Ok(());
    }
    Err(crate::error::Error::Invalid(format!(
        "the linked list sorts 1 to {LIST_MAX_SORTED} fragments a pixel, not {sorted}"
    )))
}

/// Running sums of a hybrid tail in integers, exactly as the GPU's atomics add them: with
/// 8-bit colour `c8`, alpha `a8` and tint `g8`, `sum c8 a8` (units of 1/255^2), `sum a8`
/// (units of 1/255), the fragment count, and where a tinted fragment joined, `sum (255 - a8)
/// g8` per channel (units of 1/255^2). Integer sums are exact and the same in every order; they
/// hold up to [`crate::raster::MAX_FRAGMENTS_PER_PIXEL`] fragments.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tail {
    pub sum_ca: [u32; 3],
    pub sum_a: u32,
    pub count: u32,
    /// `sum (255 - a8) g8` per channel: what the tail's fragments let through, summed.
    pub sum_t: [u32; 3],
}

impl Tail {
    /// Adds a fragment: `c8 a8 2^e` to each colour sum (`c8` its stored 8 bits, `e` its
    /// exponent: [`crate::fragment::mantissa_rgba8`]), saturating, so a tail of colours far above
    /// white stays the brightest a sum holds rather than wrapping (kbuffer_tint.wgsl adds
    /// `2^e - 1` more of each the same way); `a8` to the alpha sum.
    pub fn add(&mut self, rgba: [f32; 4], tint: u32) {
        let a = to_unorm8(rgba[3]);
        let (c8, e) = crate::fragment::mantissa_and_exponent(rgba);
        for (i, s) in self.sum_ca.iter_mut().enumerate() {
            *s = s.saturating_add((((c8 >> (8 * i)) & 0xff) * a) << e);
        }
        for (i, s) in self.sum_t.iter_mut().enumerate() {
            *s = s.wrapping_add((255 - a) * ((tint >> (8 * i)) & 0xff));
        }
        self.sum_a = self.sum_a.wrapping_add(a);
        self.count += 1;
    }

    /// What the tail's tints take away per channel: `sum (255 - a8) (255 - g8)`, the sums of
    /// clear tints less [`Tail::sum_t`] (0 where every tint is clear, or every tinted fragment
    /// is opaque). The GPU's k-buffers add these (resolve.wgsl), only for tinted fragments.
    pub fn absorbed(&self) -> [u32; 3] {
        let clear = 255 * (255 * self.count).wrapping_sub(self.sum_a);
        self.sum_t.map(|s| clear.wrapping_sub(s))
    }

    /// Whether its tints filter any channel ([`Tail::absorbed`] not all 0).
    pub fn tinted(&self) -> bool {
        self.absorbed() != [0; 3]
    }

    /// The tail seen over the background: `a_tail C_tail + t_tail C_bg` with
    /// `C_tail = sum C a / sum a`, `a_avg = sum a / n`, `a_tail = 1 - (1 - a_avg)^n` and, per
    /// channel, `t_tail = 1 - a_tail` where the tints filter nothing ([`Tail::tinted`]), else
    /// `t_avg^n`, `t_avg` the mean transmittance `sum (1 - a) g / n` (the same value where
    /// they filter nothing).
    pub fn over(&self, bg: [f32; 3]) -> [f32; 3] {
        let tinted = self.tinted();
        if self.count == 0 || (self.sum_a == 0 && !tinted) {
            return bg;
        }
        let n = self.count as f32;
        let a_avg = (self.sum_a as f32 / (255.0 * n)).min(1.0);
        let a_tail = 1.0 - (1.0 - a_avg).powf(n);
        let inv = match self.sum_a {
            0 => 0.0,
            s => 1.0 / (255.0 * s as f32),
        };
        let through: [f32; 3] = match tinted {
            false => [1.0 - a_tail; 3],
            true => self
                .sum_t
                .map(|s| (s as f32 / (255.0 * 255.0 * n)).min(1.0).powf(n)),
        };
        std::array::from_fn(|i| a_tail * (self.sum_ca[i] as f32 * inv) + through[i] * bg[i])
    }
}

/// Hybrid compositing of fragments sorted front to back: the first `k` exactly, the rest as a
/// tail.
pub fn hybrid_sorted(frags: &[Fragment], k: usize, bg: [f32; 3]) -> [f32; 3] {
    let k = k.min(frags.len());
    let mut tail = Tail::default();
    for f in &frags[k..] {
        tail.add(f.rgba, f.tint);
    }
    let behind = tail.over(bg);
    let (c, t) = over_sorted(&frags[..k]);
    std::array::from_fn(|i| c[i] + t[i] * behind[i])
}

pub fn hybrid_pixel(frags: &[Fragment], k: usize, bg: [f32; 3]) -> [f32; 3] {
    let mut v = frags.to_vec();
    sort_front_to_back(&mut v);
    hybrid_sorted(&v, k, bg)
}

#[derive(Clone, Copy, Debug)]
struct MlabRow {
    /// Premultiplied colour.
    a: [f32; 3],
    /// Transmittance, per channel.
    t: [f32; 3],
    z: u64,
}

const MLAB_EMPTY: MlabRow = MlabRow {
    a: [0.0; 3],
    t: [1.0; 3],
    z: u64::MAX,
};

/// MLAB with `m >= 1` rows, fragments taken in the order given (submission order). Rows past
/// the pixel's fragment count are never merged into and blend as nothing, so `m` is taken as
/// at most that count: the same result bit for bit, and a budget of gigabytes (36 million
/// rows a pixel) loops over no row it cannot fill.
pub fn mlab_pixel(frags: &[Fragment], m: usize, bg: [f32; 3]) -> [f32; 3] {
    let m = m.clamp(1, frags.len().max(1));
    let mut rows = vec![MLAB_EMPTY; m + 1];
    for f in frags {
        let al = f.rgba[3];
        let mut cur = MlabRow {
            a: [f.rgba[0] * al, f.rgba[1] * al, f.rgba[2] * al],
            t: f.transmittance(),
            z: fragment_key(f.depth, f.rgba),
        };
        for row in rows.iter_mut().take(m) {
            if cur.z <= row.z {
                std::mem::swap(&mut cur, row);
            }
        }
        rows[m] = cur;
        let (front, back) = (rows[m - 1], rows[m]);
        rows[m - 1] = MlabRow {
            a: std::array::from_fn(|i| front.a[i] + back.a[i] * front.t[i]),
            t: std::array::from_fn(|i| front.t[i] * back.t[i]),
            z: front.z,
        };
        rows[m] = MLAB_EMPTY;
    }
    let mut c = [0.0f32; 3];
    let mut t = [1.0f32; 3];
    for r in &rows[..m] {
        for i in 0..3 {
            c[i] += t[i] * r.a[i];
            t[i] *= r.t[i];
        }
    }
    std::array::from_fn(|i| c[i] + t[i] * bg[i])
}

/// How a whole frame is composited.
#[derive(Clone, Copy, Debug)]
pub enum Method<'a> {
    Exact,
    /// Hybrid with a per-pixel k (one entry per pixel).
    Hybrid(&'a [u32]),
    /// MLAB with m rows per pixel.
    Mlab(usize),
    /// Weighted blended OIT with these parameters.
    Wboit(WboitParams),
    /// Moment-based OIT, four power moments.
    Mboit(MboitParams),
}

/// Composites every pixel of `fl` over what is behind it: its opaque surface where one covers
/// it, else the background `bg` ([`FragmentLists::behind`]).
pub fn composite(fl: &FragmentLists, method: Method, bg: [f32; 3]) -> Image {
    let (w, h) = fl.size();
    let mut img = Image::new((w, h));
    img.data
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each_init(Vec::new, |scratch, (y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let p = y * w as usize + x;
                let bg = fl.behind(p, bg);
                *out = match method {
                    Method::Exact => {
                        fl.sorted_into(p, scratch);
                        exact_sorted(scratch, bg)
                    }
                    Method::Hybrid(k) => {
                        fl.sorted_into(p, scratch);
                        hybrid_sorted(scratch, k[p] as usize, bg)
                    }
                    // MLAB takes fragments in submission order.
                    Method::Mlab(m) => {
                        scratch.clear();
                        scratch.extend(fl.fragments(p));
                        mlab_pixel(scratch, m, bg)
                    }
                    // The blended methods at their targets' precision, in submission order.
                    Method::Wboit(params) => {
                        scratch.clear();
                        scratch.extend(fl.fragments(p));
                        wboit_blended(scratch, bg, &params)
                    }
                    Method::Mboit(params) => {
                        scratch.clear();
                        scratch.extend(fl.fragments(p));
                        mboit_blended(scratch, bg, params)
                    }
                };
            }
        });
    img
}

/// The deepest pixel the GPU capture appends instead of inserting (see [`appends`]); its resolve
/// sorts at most this many keys in private memory.
pub const APPEND_MAX: u32 = 64;

/// Whether the GPU capture of an allocated k-buffer (its tails pooled, its count known: the
/// two-mode capture) appends a covered pixel of `k` slots (the allocation's, or the k it
/// stores) and `n` fragments rather than inserting each fragment through its slots: where it
/// keeps them all (no tail: `shared::stored_k`) and few enough to sort at resolve. Both modes
/// end in the slots and tail [`capture`] computes. FKB and an uploaded k always insert.
#[inline]
pub fn appends(k: u32, n: u32) -> bool {
    n > 0 && !crate::shared::has_tail(k, n) && n <= APPEND_MAX
}

/// The CPU twin of the GPU capture pass: per pixel the `k[p]` nearest capture keys in front-to-
/// back order (`u64::MAX` for an empty slot), and the tail's integer sums of the rest
/// (`sum c8 a8` for r, g, b, `sum a8`, count: five a pixel).
pub fn capture(fl: &FragmentLists, k: &[u32]) -> (Vec<u64>, Vec<u32>) {
    let mut keys = Vec::with_capacity(k.iter().map(|&x| x as usize).sum());
    let mut tails = Vec::with_capacity(5 * fl.pixel_count());
    let mut frags = Vec::new();
    for (p, &kp) in k.iter().enumerate().take(fl.pixel_count()) {
        fl.sorted_into(p, &mut frags);
        let kp = kp as usize;
        keys.extend((0..kp).map(|i| {
            frags
                .get(i)
                .map_or(u64::MAX, |f| fragment_key(f.depth, f.rgba))
        }));
        let mut t = Tail::default();
        for f in frags.iter().skip(kp) {
            t.add(f.rgba, f.tint);
        }
        tails.extend([t.sum_ca[0], t.sum_ca[1], t.sum_ca[2], t.sum_a, t.count]);
    }
    (keys, tails)
}
