//! Per-pixel inputs of the allocations: the 12 network features and the variable k-buffer's
//! heuristic importance (paper 002). Written pass by pass as the GPU computes them, so the two
//! can be compared line by line.

use crate::fragment::{CLEAR, FragmentLists, fragment_key, unpack_rgba8};

/// Names of the network's inputs, in order (see [`pixel_features`]).
pub const FEATURE_NAMES: [&str; 12] = [
    "log2_count",
    "count_rel",
    "budget_share",
    "log2_budget_per_pixel",
    "near_depth",
    "near_alpha",
    "log2_color_var",
    "log2_near_dev",
    "mean_alpha",
    "mean_luma",
    "near_luma",
    "log2_optical_depth",
];
pub const FEATURES: usize = 12;

/// What the log-scaled colour statistics add before the logarithm: below the smallest non-zero
/// variance of 8-bit colours in any pixel of up to 128 fragments, so "every fragment has the
/// same colour" (a pixel whose tails are all exact) stays apart from "nearly the same".
pub const LOG_FLOOR: f32 = 1e-6;

/// The largest pixel depth whose sum of squared 8-bit colours fits the features pass's 32-bit
/// atomic (`n 3 255^2 < 2^32`). Deeper pixels wrap the sum, which the CPU twin does alike; their
/// colour variance is then meaningless (such pixels are far beyond any real scene's).
pub const MAX_EXACT_COUNT: u32 = (u32::MAX as u64 / (3 * 255 * 255)) as u32;

/// Units a fragment's optical depth is summed in by the features pass (1/256).
pub const OPTICAL_DEPTH_UNIT: f32 = 1.0 / 256.0;

/// A fragment's optical depth `-ln(1 - a)` for its 8-bit opacity, in [`OPTICAL_DEPTH_UNIT`]s
/// rounded to the nearest (an opaque fragment counts as opacity 254.5 / 255): a table the GPU
/// reads too, so the sums are the same integers. Its largest entry (about 1,600) times
/// [`crate::raster::MAX_FRAGMENTS_PER_PIXEL`] fits 32 bits.
pub fn optical_depth_table() -> [u32; 256] {
    std::array::from_fn(|a| {
        let a = (a as f64).min(254.5) / 255.0;
        (-(1.0 - a).ln() / OPTICAL_DEPTH_UNIT as f64).round() as u32
    })
}

/// The 8-bit opacity the features read for a fragment of 8-bit opacity `a8` and tint `tint`
/// (RGB8, R in the low byte; higher bits ignored): 255 minus what it lets through in its most
/// transparent channel, `(255 - a8) max(g) / 255` rounded to the nearest, so a red pane counts
/// as transparent as it is to red light. An exact integer, as the features pass computes it;
/// `a8` itself for a [`CLEAR`] fragment.
pub fn filtered_alpha8(a8: u32, tint: u32) -> u32 {
    let g = tint & CLEAR;
    let most = (g & 0xff).max(g >> 8 & 0xff).max(g >> 16 & 0xff);
    255 - ((255 - a8) * most + 127) / 255
}

/// A fragment's RGBA8 with its opacity as the features read it ([`filtered_alpha8`] of its
/// tint): what the nearest words hold of it ([`near_words`]; features.wgsl's twin).
pub fn filtered_rgba8(rgba8: u32, tint: u32) -> u32 {
    rgba8 & 0x00ff_ffff | filtered_alpha8(rgba8 >> 24, tint) << 24
}

/// Steps of the window depth [0, 1] in the nearest words' 16 bits ([`near_depth16`]).
pub const NEAR_DEPTH_STEPS: f32 = 65535.0;

/// A window depth in [0, 1] as the nearest words order it: `depth 65535` truncated, a step of
/// 1.5e-5 everywhere (as fine as the f32's own spacing just below 1, where a perspective puts
/// most depths).
pub fn near_depth16(depth: f32) -> u32 {
    (depth.max(0.0) * NEAR_DEPTH_STEPS) as u32
}

/// A fragment's two nearest words, each its 16-bit depth ([`near_depth16`]) above two 8-bit
/// channels of its RGBA8 `rgba8` (as [`filtered_rgba8`] gives it): opacity and red, then green
/// and blue. The features pass keeps each word's minimum over the pixel's fragments with a
/// 32-bit atomic of its own, so on any device, in one pass and in any order, the nearest
/// fragment's colour; where fragments share the nearest 16-bit depth each word takes the least
/// of them (the opacity and red of one, the green and blue of another).
pub fn near_words(depth: f32, rgba8: u32) -> [u32; 2] {
    let d = near_depth16(depth) << 16;
    let c = |i: u32| rgba8 >> (8 * i) & 0xff;
    [d | c(3) << 8 | c(0), d | c(1) << 8 | c(2)]
}

/// The nearest fragment's RGBA8 the two nearest words hold ([`near_words`]).
pub fn near_rgba8(near: [u32; 2]) -> u32 {
    near[0] & 0xff
        | (near[1] >> 8 & 0xff) << 8
        | (near[1] & 0xff) << 16
        | (near[0] >> 8 & 0xff) << 24
}

/// The nearest fragment's window depth the nearest words hold, in steps of 2^-16 (exact in
/// f32 on the CPU and the GPU).
pub fn near_depth(near: [u32; 2]) -> f32 {
    (near[0] >> 16) as f32 * (1.0 / 65536.0)
}

/// Bit 63 of a key in [`PixelStats::farthest`]: the slot holds a fragment (window depths are
/// non-negative, so a key's own bit 63 is clear).
pub const OCCUPIED: u64 = 1 << 63;

/// What the features pass accumulates per pixel, with 32-bit integer atomics only, so any
/// submission order gives the same result on any device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PixelStats {
    pub count: u32,
    /// The least of each of the fragments' [`near_words`] (their opacities what their tints let
    /// through, [`filtered_rgba8`]): the nearest fragment's 16-bit depth and colour.
    pub nearest: [u32; 2],
    /// The two largest fragment keys, farthest first, each with [`OCCUPIED`] set (0: none), as
    /// the pass's two-slot insertion with `atomicMax` leaves them in any order.
    pub farthest: [u64; 2],
    /// Sums of the fragments' 8-bit R, G and B.
    pub color_sum: [u32; 3],
    /// Sum over fragments of `r^2 + g^2 + b^2` in 8-bit units (wrapping, see
    /// [`MAX_EXACT_COUNT`]).
    pub color_sq_sum: u32,
    /// Sum of the fragments' optical depths ([`optical_depth_table`] of [`filtered_alpha8`]):
    /// the pixel's transmittance in its most transparent channel is about
    /// `exp(-optical_depth OPTICAL_DEPTH_UNIT)`.
    pub optical_depth: u32,
    /// Sum of the fragments' 8-bit opacities ([`filtered_alpha8`]: their tints included, as the
    /// optical depths).
    pub alpha_sum: u32,
}

/// Rec. 709 luminance of a linear colour.
pub fn luma(c: [f32; 4]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The features pass: per-pixel statistics (CPU twin of the geometry pass with atomics).
pub fn pixel_stats(fl: &FragmentLists) -> Vec<PixelStats> {
    let tau = optical_depth_table();
    (0..fl.pixel_count())
        .map(|p| {
            let mut s = PixelStats {
                nearest: [u32::MAX; 2],
                ..Default::default()
            };
            for i in fl.range(p) {
                // The colour as the key stores it: RGBA8, over its exponent where it is
                // brighter than white (fragment::mantissa_rgba8).
                let key = fragment_key(fl.depth[i], fl.rgba[i]);
                let rgba8 = key as u32;
                let tint = fl.tint(i);
                s.count += 1;
                // The nearest, its opacity what its tint lets through.
                let depth = f32::from_bits((key >> 32) as u32);
                let near = near_words(depth, filtered_rgba8(rgba8, tint));
                s.nearest = [s.nearest[0].min(near[0]), s.nearest[1].min(near[1])];
                // The two largest keys of the multiset, as the insertion keeps them.
                let key = key | OCCUPIED;
                if key > s.farthest[0] {
                    s.farthest = [key, s.farthest[0]];
                } else if key > s.farthest[1] {
                    s.farthest[1] = key;
                }
                for c in 0..3 {
                    let v = rgba8 >> (8 * c) & 0xff;
                    s.color_sum[c] = s.color_sum[c].wrapping_add(v);
                    s.color_sq_sum = s.color_sq_sum.wrapping_add(v * v);
                }
                // What the fragment hides of what is behind it, its tint included.
                let a8 = filtered_alpha8(rgba8 >> 24, tint);
                s.optical_depth += tau[a8 as usize];
                s.alpha_sum += a8;
            }
            if s.count == 0 {
                s.nearest = [0; 2];
            }
            s
        })
        .collect()
}

/// Whether a pixel's two farthest fragments share one colour and opacity (RGBA8): then a tail
/// of those two composites exactly and the pixel can use one slot fewer (`alloc::useful_cap`).
/// Closed surfaces seen through (a part's back and front face under the same light) are the
/// common case.
pub fn tail_pair(s: &PixelStats) -> bool {
    s.farthest[1] & OCCUPIED != 0 && s.farthest[0] as u32 == s.farthest[1] as u32
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

/// The 12 features of one covered pixel, in order ([`FEATURE_NAMES`]); colours in [0, 1],
/// `C_near` and `a_near` the nearest fragment's colour and opacity (what its tint lets through:
/// [`filtered_rgba8`]; [`near_words`]), `mean` and `var` the mean and the variance (summed over
/// R, G, B) of the pixel's fragment colours, `dev = |C_near - mean|^2`, `tau` the sum of the
/// fragments' optical depths `-ln(1 - a)`: 0 `log2 n`; 1 `n / mean n` over covered pixels;
/// 2 `F / sum n`, the budget's share of the frame's fragments; 3 `log2(F / covered pixels)`;
/// 4 the nearest window depth (in 2^-16 steps: [`near_depth`]); 5 `a_near`;
/// 6 `log2(var + LOG_FLOOR)`; 7 `log2(dev + LOG_FLOOR)`; 8 the mean opacity; 9 `luma(mean)`;
/// 10 `luma(C_near)`; 11 `log2(tau + OPTICAL_DEPTH_UNIT)`.
///
/// Why these: with opacity a, truncating a pixel after k fragments costs about
/// `(1 - a)^(2k)` times how far the tail's front fragments stray from the tail's mean, so the
/// slots a pixel deserves grow with the logarithm of its colour spread (a factor of 2.2 in
/// variance is one slot at a = 0.33), and a pixel whose fragments share one colour needs none.
/// With the materials' opacities a varies from fragment to fragment: how fast the
/// transmittance falls (the mean opacity, the optical depth) and whether the nearest fragment
/// already hides the rest (`a_near`) decide it. The variance and deviation are exact integers
/// before the last division, so one colour is exactly zero on the CPU and the GPU. The paper's
/// `n / sum n` and frame depth range say nothing about any of it and shrink with resolution
/// (see the README's ablation).
pub fn pixel_features(s: &PixelStats, t: &Totals, budget_fragments: u64) -> [f32; FEATURES] {
    let total = t.fragments.max(1) as f32;
    let covered = t.covered.max(1) as f32;
    let n = s.count.max(1);
    let nf = n as f32;
    let near8 = near_rgba8(s.nearest);
    let near = unpack_rgba8(near8);
    let mean: [f32; 3] = std::array::from_fn(|c| s.color_sum[c] as f32 / 255.0 / nf);
    // n^2 var and n^2 dev in 8-bit units, exact integers.
    let sq = n as i64 * s.color_sq_sum as i64;
    let mut var_num = sq;
    let mut dev_num = 0i64;
    for c in 0..3 {
        let sum = s.color_sum[c] as i64;
        var_num -= sum * sum;
        let d = n as i64 * (near8 >> (8 * c) & 0xff) as i64 - sum;
        dev_num += d * d;
    }
    let scale = nf * nf * 65025.0;
    let var = var_num.max(0) as f32 / scale;
    let dev = dev_num as f32 / scale;
    let mean_luma = luma([mean[0], mean[1], mean[2], 1.0]);
    let near_luma = luma(near);
    let tau = s.optical_depth as f32 * OPTICAL_DEPTH_UNIT;
    [
        nf.log2(),
        nf / (total / covered),
        budget_fragments as f32 / total,
        (budget_fragments.max(1) as f32 / covered).log2(),
        near_depth(s.nearest),
        near[3],
        (var + LOG_FLOOR).log2(),
        (dev + LOG_FLOOR).log2(),
        s.alpha_sum as f32 / 255.0 / nf,
        mean_luma,
        near_luma,
        (tau + OPTICAL_DEPTH_UNIT).log2(),
    ]
}

/// Features of every pixel (zeros for uncovered pixels, which the network never sees).
pub fn features(fl: &FragmentLists, budget_fragments: u64) -> Vec<[f32; FEATURES]> {
    features_and_pairs(fl, budget_fragments).0
}

/// Features of every pixel and whether its two farthest fragments share one colour
/// ([`tail_pair`]): what DKB's allocation reads from its features pass.
pub fn features_and_pairs(
    fl: &FragmentLists,
    budget_fragments: u64,
) -> (Vec<[f32; FEATURES]>, Vec<bool>) {
    let stats = pixel_stats(fl);
    let t = totals(&stats);
    let features = stats
        .iter()
        .map(|s| {
            if s.count > 0 {
                pixel_features(s, &t, budget_fragments)
            } else {
                [0.0; FEATURES]
            }
        })
        .collect();
    (features, stats.iter().map(tail_pair).collect())
}

/// DKB's record marks of a frame whose pixels hold `counts` fragments (totals.wgsl's
/// mark_records, then the marks' scan): a bit for each pixel of more than
/// [`crate::shared::TAIL_WORDS`] fragments, laid out as the allocation's marks
/// ([`crate::shared::marks_words`]): the exclusive prefix sums of their words' popcounts and
/// their total, then the words of bits. The frame that gathers its statistics with its count
/// reads the frame before's.
pub fn record_marks(counts: &[u32]) -> Vec<u32> {
    let bits = crate::shared::MARK_BITS as usize;
    let blocks = counts.len().div_ceil(bits);
    let mut marks = vec![0u32; 2 * blocks + 1];
    for (p, &n) in counts.iter().enumerate() {
        if n > crate::shared::TAIL_WORDS {
            marks[blocks + 1 + p / bits] |= 1 << (p % bits);
        }
    }
    let mut before = 0;
    for w in 0..blocks {
        marks[w] = before;
        before += marks[blocks + 1 + w].count_ones();
    }
    marks[blocks] = before;
    marks
}

/// Each of `pixels` pixels' record under `marks` ([`record_marks`]; records.wgsl's
/// record_index): the marked pixels before it, None where it is not marked.
pub fn record_indices(marks: &[u32], pixels: u64) -> Vec<Option<u32>> {
    let bits = crate::shared::MARK_BITS as usize;
    let blocks = crate::shared::mark_blocks(pixels) as usize;
    (0..pixels as usize)
        .map(|p| {
            let word = marks[blocks + 1 + p / bits];
            let bit = 1u32 << (p % bits);
            (word & bit != 0).then(|| marks[p / bits] + (word & (bit - 1)).count_ones())
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
    vkb_importance_from(&counts, &facing, fl.size(), params)
}

/// VKB importance from per-pixel counts and nearest-fragment `|n . e|` (the twin of
/// `importance_vkb.wgsl`, which gets them from its count pass).
pub fn vkb_importance_from(
    counts: &[u32],
    facing: &[f32],
    size: (u32, u32),
    params: &VkbParams,
) -> Vec<f32> {
    let (width, height) = size;
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
            // abs: never the sign bit, which the allocation reads as the pair flag.
            (i_per * i_f * i_d + params.noise * (xi - 0.5))
                .max(0.0)
                .abs()
        })
        .collect()
}

/// `|n . e|` of a pixel's nearest fragment, as VKB's count pass keeps it: the fragment of the
/// smallest [`vkb_nearest_key`], its facing in 8 bits ([`vkb_key_facing`]; 1 when the pixel has
/// none or no facing).
pub fn nearest_facing(fl: &FragmentLists, p: usize) -> f32 {
    fl.range(p)
        .filter_map(|i| fl.facing.get(i).map(|&f| vkb_nearest_key(fl.depth[i], f)))
        .min()
        .map_or(1.0, vkb_key_facing)
}

/// VKB's 32-bit nearest key (vkb_count.wgsl keeps its complement with `atomicMax`, in the
/// frame's shared word a pixel until the importance takes its place): the window
/// depth's bits, clamped to [0, 1], above bit 6 (17 of its 23 mantissa bits; depths 2^-17
/// apart, relatively, tie) in the high 24 bits, and `|n . e|` rounded to 8 bits in the low 8,
/// so a tie keeps the smaller facing. The importance reads only the facing, whose Fresnel term
/// `1 - (1 - f)^5 / 2` moves by at most 0.005 for the rounding.
pub fn vkb_nearest_key(depth: f32, facing: f32) -> u32 {
    // As the shader's select: a depth not above 0 (-0 and NaN too) is 0, so its bits stay
    // below 2^30 and keep their order once shifted.
    let d = if depth > 0.0 { depth.min(1.0) } else { 0.0 }.to_bits() >> 6;
    let f = (facing.clamp(0.0, 1.0) * 255.0).round_ties_even() as u32;
    (d << 8) | f
}

/// The facing a [`vkb_nearest_key`] holds.
pub fn vkb_key_facing(key: u32) -> f32 {
    (key & 0xff) as f32 / 255.0
}

#[cfg(test)]
mod tests {
    use super::{near_depth, near_rgba8, near_words, pixel_stats, vkb_key_facing, vkb_nearest_key};
    use crate::fragment::FragmentLists;

    #[test]
    fn the_nearest_words_hold_the_nearest_fragment_by_hand() {
        // Depth 0.5 is 32767 steps (0.5 x 65535 = 32767.5, truncated); RGBA8 0xAABBGGRR.
        let w = near_words(0.5, 0x8040_2010);
        assert_eq!(w, [0x7fff_8010, 0x7fff_2040]);
        assert_eq!(near_rgba8(w), 0x8040_2010);
        assert_eq!(near_depth(w), 32767.0 / 65536.0);
        assert_eq!(near_words(1.0, 0)[0] >> 16, 65535);
        // A pixel of three fragments: the nearest (depth 0.25) wins every channel, in any order;
        // two at one 16-bit depth (0.75 and the next f32 above) give each word's least, the
        // opacity and red of one and the green and blue of the other.
        let lists = |frags: &[(f32, [f32; 4])]| {
            let fl = FragmentLists {
                width: 1,
                height: 1,
                offsets: vec![0, frags.len() as u32],
                depth: frags.iter().map(|f| f.0).collect(),
                rgba: frags.iter().map(|f| f.1).collect(),
                primitive: vec![0; frags.len()],
                ..Default::default()
            };
            pixel_stats(&fl)[0]
        };
        let (a, b, c) = (
            (0.75, [1.0, 0.0, 1.0, 0.5]),
            (0.25, [0.0, 1.0, 0.0, 1.0]),
            (0.5, [0.2, 0.2, 0.2, 0.2]),
        );
        for order in [[a, b, c], [c, b, a], [b, a, c]] {
            let s = lists(&order);
            assert_eq!(near_rgba8(s.nearest), 0xff00_ff00);
            assert_eq!(near_depth(s.nearest), 16383.0 / 65536.0);
        }
        let next = f32::from_bits(0.75f32.to_bits() + 1);
        let s = lists(&[(0.75, [1.0, 1.0, 0.0, 0.0]), (next, [0.0, 0.0, 1.0, 1.0])]);
        assert_eq!(near_rgba8(s.nearest), 0x00ff_00ff);
    }

    #[test]
    fn vkb_s_nearest_key_orders_by_depth_then_facing_by_hand() {
        let key = vkb_nearest_key;
        // Depth decides first, whatever the facing.
        assert!(key(0.25, 1.0) < key(0.5, 0.0));
        assert!(key(0.5, 1.0) < key(0.5 + 2f32.powi(-16), 0.0));
        // 0.5 is 0x3f000000: the next float up (0x3f000001) and 63 more share its bits above
        // bit 6, so they tie and the smaller facing is the nearer; the 64th above does not.
        let up = |n: u32| f32::from_bits(0x3f00_0000 + n);
        assert!(key(up(1), 0.2) < key(0.5, 0.3));
        assert!(key(up(63), 0.2) < key(0.5, 0.3));
        assert!(key(up(64), 0.2) > key(0.5, 0.3));
        // Not above 0 (-0, negative, NaN) is 0; above 1 is 1.
        for d in [-0.0, -1.0, f32::NAN] {
            assert_eq!(key(d, 0.4), key(0.0, 0.4), "{d}");
        }
        assert_eq!(key(2.0, 0.4), key(1.0, 0.4));
        assert_eq!(key(1.0, 0.0) >> 8, 0x3f80_0000 >> 6);
        // The facing in 8 bits, rounded half to even: 0.5 x 255 = 127.5 -> 128, 0.25 x 255 =
        // 63.75 -> 64, 0.002 x 255 = 0.51 -> 1; clamped to [0, 1].
        for (f, q) in [
            (0.5, 128),
            (0.25, 64),
            (0.002, 1),
            (1.0, 255),
            (1.5, 255),
            (-0.2, 0),
        ] {
            assert_eq!(key(0.75, f) & 0xff, q, "{f}");
            assert_eq!(vkb_key_facing(key(0.75, f)), q as f32 / 255.0, "{f}");
        }
    }

    /// DKB's record marks by hand: pixels of three fragments or more marked, a word of 32 a
    /// block, each block's marked pixels before it, and their total; a pixel's record is the
    /// marked pixels before it, in pixel order (what records.wgsl's record_index reads).
    #[test]
    fn record_marks_number_the_pixels_of_more_than_two_fragments_in_order_by_hand() {
        use super::{record_indices, record_marks};
        // 40 pixels: two words. Marked: 1, 3, 31 in the first word, 32, 39 in the second.
        let mut counts = vec![0u32; 40];
        for (p, n) in [
            (0, 2),
            (1, 3),
            (2, 1),
            (3, 7),
            (31, 3),
            (32, 9),
            (38, 2),
            (39, 3),
        ] {
            counts[p] = n;
        }
        let marks = record_marks(&counts);
        let bits0 = 1 << 1 | 1 << 3 | 1 << 31;
        let bits1 = 1 << 0 | 1 << 7;
        assert_eq!(marks, vec![0, 3, 5, bits0, bits1]);
        let r = record_indices(&marks, 40);
        let recorded: Vec<(usize, u32)> = r
            .iter()
            .enumerate()
            .filter_map(|(p, i)| i.map(|i| (p, i)))
            .collect();
        assert_eq!(recorded, vec![(1, 0), (3, 1), (31, 2), (32, 3), (39, 4)]);
        // No pixel of two or fewer has one.
        assert!(r[0].is_none() && r[38].is_none() && r[2].is_none());
    }
}
