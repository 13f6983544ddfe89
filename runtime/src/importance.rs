//! Per-pixel inputs of the allocations: the 12 network features and the variable k-buffer's
//! heuristic importance (paper 002). Written pass by pass as the GPU computes them, so the two
//! can be compared line by line.

use crate::composite::{fragment_key, unpack_rgba8};
use crate::raster::FragmentLists;

/// Names of the network's inputs, in order.
pub const FEATURE_NAMES: [&str; 12] = [
    "count_rel",
    "near_depth",
    "far_depth",
    "near_r",
    "near_g",
    "near_b",
    "mean_r",
    "mean_g",
    "mean_b",
    "budget_share",
    "log2_count",
    "luma_std",
];
pub const FEATURES: usize = 12;

/// Fixed-point scale of the colour sums (the GPU adds them with u32 atomics, so the sum is the
/// same in every order): 12 fractional bits, room for a million fragments per pixel.
pub const COLOR_SUM_SCALE: f32 = 4096.0;

pub fn to_fixed(c: f32) -> u32 {
    (c.clamp(0.0, 1.0) * COLOR_SUM_SCALE + 0.5).floor() as u32
}

/// What the features pass accumulates per pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelStats {
    pub count: u32,
    /// Window depths of the nearest and farthest fragment.
    pub near: f32,
    pub far: f32,
    /// The smallest fragment key (depth bits high, RGBA8 low): the nearest fragment.
    pub nearest_key: u64,
    /// Submission index of the nearest fragment (ties: the lowest).
    pub nearest_primitive: u32,
    /// Sum of the fragments' RGB in fixed point.
    pub color_sum: [u32; 3],
    /// Sums of the fragments' luminance and squared luminance in fixed point.
    pub luma_sum: u32,
    pub luma_sq_sum: u32,
}

/// Rec. 709 luminance of a linear colour.
pub fn luma(c: [f32; 4]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The features pass: per-pixel statistics (CPU twin of the geometry pass with atomics).
pub fn pixel_stats(fl: &FragmentLists) -> Vec<PixelStats> {
    (0..fl.pixel_count())
        .map(|p| {
            let mut s = PixelStats {
                near: f32::INFINITY,
                far: 0.0,
                nearest_key: u64::MAX,
                nearest_primitive: u32::MAX,
                ..Default::default()
            };
            for i in fl.range(p) {
                s.count += 1;
                s.near = s.near.min(fl.depth[i]);
                s.far = s.far.max(fl.depth[i]);
                let key = fragment_key(fl.depth[i], fl.rgba[i]);
                if (key, fl.primitive[i]) < (s.nearest_key, s.nearest_primitive) {
                    s.nearest_key = key;
                    s.nearest_primitive = fl.primitive[i];
                }
                for c in 0..3 {
                    s.color_sum[c] = s.color_sum[c].wrapping_add(to_fixed(fl.rgba[i][c]));
                }
                let l = luma(fl.rgba[i]);
                s.luma_sum = s.luma_sum.wrapping_add(to_fixed(l));
                s.luma_sq_sum = s.luma_sq_sum.wrapping_add(to_fixed(l * l));
            }
            if s.count == 0 {
                s.near = 0.0;
            }
            s
        })
        .collect()
}

/// Frame totals (the reduction pass): sum of n, covered pixels and max n.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Totals {
    pub fragments: u64,
    pub covered: u64,
    pub max_count: u32,
}

pub fn totals(stats: &[PixelStats]) -> Totals {
    let mut t = Totals {
        fragments: 0,
        covered: 0,
        max_count: 0,
    };
    for s in stats.iter().filter(|s| s.count > 0) {
        t.fragments += s.count as u64;
        t.covered += 1;
        t.max_count = t.max_count.max(s.count);
    }
    t
}

/// The 12 features of one covered pixel, in order:
/// 0 `n / mean n` over covered pixels (relative depth complexity, the same at every
/// resolution); 1, 2 nearest and farthest window depth; 3-5 the nearest fragment's RGB (RGBA8,
/// as the capture key stores it); 6-8 the mean fragment RGB; 9 `F / sum n` (the budget's
/// share of the frame's fragments); 10 `log2 n`; 11 the standard deviation of the fragments'
/// luminance.
///
/// The paper's list has `n / sum n` first and the frame's min and max depth last. `n / sum n`
/// shrinks with resolution and, with the frame depth range, tells the network nothing about
/// the absolute depth complexity or how much the fragments differ, which decide how many of
/// them a pixel needs (the hybrid error of fragments that share one colour is zero); the
/// replacements carry that, and measured better (see the README).
pub fn pixel_features(s: &PixelStats, t: &Totals, budget_fragments: u64) -> [f32; FEATURES] {
    let total = t.fragments.max(1) as f32;
    let near = unpack_rgba8(s.nearest_key as u32);
    let n = s.count.max(1) as f32;
    let mean = s.color_sum.map(|c| c as f32 / COLOR_SUM_SCALE / n);
    let mean_n = total / t.covered.max(1) as f32;
    let luma_mean = s.luma_sum as f32 / COLOR_SUM_SCALE / n;
    let luma_var = (s.luma_sq_sum as f32 / COLOR_SUM_SCALE / n - luma_mean * luma_mean).max(0.0);
    [
        s.count as f32 / mean_n,
        s.near,
        s.far,
        near[0],
        near[1],
        near[2],
        mean[0],
        mean[1],
        mean[2],
        budget_fragments as f32 / total,
        n.log2(),
        luma_var.sqrt(),
    ]
}

/// Features of every pixel (zeros for uncovered pixels, which the network never sees).
pub fn features(fl: &FragmentLists, budget_fragments: u64) -> Vec<[f32; FEATURES]> {
    let stats = pixel_stats(fl);
    let t = totals(&stats);
    stats
        .iter()
        .map(|s| {
            if s.count > 0 {
                pixel_features(s, &t, budget_fragments)
            } else {
                [0.0; FEATURES]
            }
        })
        .collect()
}

/// Variable k-buffer parameters (paper 002).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VkbParams {
    /// Range bias of the depth-complexity factor (the paper uses 0.25 to 0.5).
    pub alpha: f32,
    /// Periphery fall-off exponent (3 in the paper).
    pub periphery_exponent: f32,
    /// Noise level (0.1 in the paper).
    pub noise: f32,
    /// Seed of the per-pixel noise.
    pub seed: u32,
}

impl Default for VkbParams {
    fn default() -> Self {
        VkbParams {
            alpha: 0.35,
            periphery_exponent: 3.0,
            noise: 0.1,
            seed: 0,
        }
    }
}

/// PCG integer hash (Jarzynski and Olano 2020): the same bits in WGSL.
pub fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// Uniform noise in [0, 1) for a pixel.
pub fn pixel_noise(p: u32, seed: u32) -> f32 {
    (pcg_hash(p ^ pcg_hash(seed)) >> 8) as f32 / 16_777_216.0
}

/// VKB importance of every pixel:
/// `I = max(0, I_per I_f I_d + lambda (xi - 0.5))` with
/// - depth complexity `I_d = alpha + (1 - alpha) min(1, n / N_limit)`, N_limit the frame's
///   largest n (computed per frame so the fraction never saturates);
/// - periphery `I_per = 1 - (|p - o| / r)^d`, o the image centre and r half the diagonal (the
///   printed formula is garbled; this keeps I_per in [0, 1], 1 at the centre, 0 at the corners);
/// - Fresnel `I_f = 1 - (1 - |n . e|)^5 / 2` of the nearest fragment;
/// - xi per-pixel uniform noise from a hash of the pixel index.
///
/// Uncovered pixels get 0.
pub fn vkb_importance(fl: &FragmentLists, params: &VkbParams) -> Vec<f32> {
    let counts = fl.counts();
    let facing: Vec<f32> = (0..fl.pixel_count())
        .map(|p| nearest_facing(fl, p))
        .collect();
    vkb_importance_from(&counts, &facing, fl.width, fl.height, params)
}

/// VKB importance from per-pixel counts and nearest-fragment `|n . e|` (the twin of
/// `importance_vkb.wgsl`, which gets them from its count pass).
pub fn vkb_importance_from(
    counts: &[u32],
    facing: &[f32],
    width: u32,
    height: u32,
    params: &VkbParams,
) -> Vec<f32> {
    let (w, h) = (width as f32, height as f32);
    let half_diag = 0.5 * (w * w + h * h).sqrt();
    let limit = counts.iter().copied().max().unwrap_or(0).max(1) as f32;
    (0..counts.len())
        .map(|p| {
            if counts[p] == 0 {
                return 0.0;
            }
            let i_d = params.alpha + (1.0 - params.alpha) * (counts[p] as f32 / limit).min(1.0);
            let x = (p as u32 % width) as f32 + 0.5 - 0.5 * w;
            let y = (p as u32 / width) as f32 + 0.5 - 0.5 * h;
            let r = ((x * x + y * y).sqrt() / half_diag).min(1.0);
            let i_per = 1.0 - r.powf(params.periphery_exponent);
            let i_f = 1.0 - (1.0 - facing[p]).powi(5) * 0.5;
            let xi = pixel_noise(p as u32, params.seed);
            (i_per * i_f * i_d + params.noise * (xi - 0.5)).max(0.0)
        })
        .collect()
}

/// `|n . e|` of a pixel's nearest fragment: the one with the smallest (depth bits, facing
/// bits), as the GPU's 64-bit atomic keeps it (1 when the pixel has none or no facing).
pub fn nearest_facing(fl: &FragmentLists, p: usize) -> f32 {
    fl.range(p)
        .filter_map(|i| {
            let d = if fl.depth[i] > 0.0 { fl.depth[i] } else { 0.0 };
            fl.facing
                .get(i)
                .map(|&f| ((d.to_bits() as u64) << 32 | f.to_bits() as u64, f))
        })
        .min_by_key(|x| x.0)
        .map_or(1.0, |x| x.1)
}
