//! Fragments and per-pixel fragment lists: what the rasterizers produce and every pass reads.
//!
//! A fragment is a window depth in [0, 1], a non-premultiplied RGBA colour stored at 8 bits a
//! channel (the precision of the GPU capture key), a tint and its triangle's submission index.
//! Where a frame's colours keep their range (light above white: emission, [`quantize_hdr`]),
//! RGB is stored as 8 bits times a shared power of two, its exponent in the top byte of the
//! fragment's tint word ([`tint_word`]); a colour within white has exponent 0 and is stored as
//! RGBA8 alone.
//! What it lets through of what lies behind it is its transmittance `(1 - a) g`, per channel
//! (`g` the tint, RGB8): white for every fragment but tinted glass
//! ([`crate::scene::Glass::Tinted`]), whose tint is its base colour, so a red pane passes red.
//! "Front to back" is the order of [`fragment_key`]: depth bits high, packed RGBA8 low, the key
//! the GPU capture sorts by, with the tint word, then the submission index breaking exact
//! ties. It is a total order, so every result is independent of the order fragments arrive in.

/// A channel in [0, 1] as an 8-bit unorm, rounding half up (`floor(v 255 + 0.5)`, which WGSL
/// computes identically; Rust's `round` and WGSL's `round` disagree on halves).
pub fn to_unorm8(v: f32) -> u32 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5).floor() as u32
}

/// A channel rounded to the nearest 8-bit value: fragment colours are stored as RGBA8, as the
/// capture key holds them, so every method sees the same colours on the CPU and the GPU.
pub fn quantize(v: f32) -> f32 {
    to_unorm8(v) as f32 / 255.0
}

/// Packs non-premultiplied RGBA in [0, 1] into RGBA8 (R in the low byte).
pub fn pack_rgba8(c: [f32; 4]) -> u32 {
    to_unorm8(c[0]) | to_unorm8(c[1]) << 8 | to_unorm8(c[2]) << 16 | to_unorm8(c[3]) << 24
}

pub fn unpack_rgba8(v: u32) -> [f32; 4] {
    [0, 8, 16, 24].map(|s| ((v >> s) & 0xff) as f32 / 255.0)
}

/// The exponent a colour is stored with: the smallest `e` in `0..=max` whose `2^e` is at least
/// its brightest channel (`max` where none is). Colours within white take 0 and are stored as
/// they always were; the frames whose colours keep their range take
/// [`crate::shared::HDR_MAX_EXPONENT`] as `max`, the others 0 (geometry.wgsl's `hdr_exponent`).
pub fn hdr_exponent(rgb: [f32; 3], max: u32) -> u32 {
    let m = rgb[0].max(rgb[1]).max(rgb[2]);
    let mut e = 0;
    while e < max && m > (1u32 << e) as f32 {
        e += 1;
    }
    e
}

/// A colour as a fragment stores it: RGB rounded to 8 bits of `rgb / 2^e` (a shared exponent,
/// [`hdr_exponent`]), alpha to 8 bits, each channel clamped to `[0, 2^e]` first. With `max` 0
/// this is [`quantize`] of each channel.
pub fn quantize_hdr(rgba: [f32; 4], max: u32) -> [f32; 4] {
    let top = (1u32 << max) as f32;
    let c = rgba.map(|v| if v > 0.0 { v.min(top) } else { 0.0 });
    let e = hdr_exponent([c[0], c[1], c[2]], max);
    let scale = (1u32 << e) as f32;
    let mut q = c.map(|v| to_unorm8(v / scale) as f32 / 255.0 * scale);
    q[3] = quantize(rgba[3]);
    q
}

/// The RGBA8 a stored colour keeps beside its exponent (R in the low byte): its RGB over `2^e`.
/// For colours within white it is [`pack_rgba8`].
pub fn mantissa_rgba8(rgba: [f32; 4]) -> u32 {
    mantissa_and_exponent(rgba).0
}

/// [`mantissa_rgba8`] and the exponent `e` it is over ([`hdr_exponent`]).
pub fn mantissa_and_exponent(rgba: [f32; 4]) -> (u32, u32) {
    let e = hdr_exponent([rgba[0], rgba[1], rgba[2]], crate::shared::HDR_MAX_EXPONENT);
    let scale = (1u32 << e) as f32;
    let c8 = pack_rgba8([rgba[0] / scale, rgba[1] / scale, rgba[2] / scale, rgba[3]]);
    (c8, e)
}

/// An opaque surface's colour as the opaque pass stores it, one 32-bit word a pixel: RGB8 of
/// `rgb / 2^e` low ([`hdr_exponent`] up to [`crate::shared::HDR_MAX_EXPONENT`], whatever the
/// frame: the word has room for it), `255 - e` in the top byte, so the word is never 0 (0 marks
/// a pixel no opaque surface covers). Within white it is RGBA8 with A = 255 (opaque.wgsl).
pub fn pack_opaque(rgb: [f32; 3]) -> u32 {
    let top = (1u32 << crate::shared::HDR_MAX_EXPONENT) as f32;
    let c = rgb.map(|v| if v > 0.0 { v.min(top) } else { 0.0 });
    let (c8, e) = mantissa_and_exponent([c[0], c[1], c[2], 0.0]);
    (c8 & CLEAR) | (255 - e) << 24
}

/// The colour a [`pack_opaque`] word holds (behind.wgsl's `behind`).
pub fn unpack_opaque(word: u32) -> [f32; 3] {
    let e = (255 - (word >> 24)).min(31);
    let c = unpack_rgba8(word);
    let scale = (1u32 << e) as f32;
    [c[0] * scale, c[1] * scale, c[2] * scale]
}

/// A fragment's tint word as the GPU stores it beside its key: the tint (RGB8) low, the
/// exponent of its colour ([`hdr_exponent`]) in the top byte. It breaks ties between equal
/// keys ([`sort_front_to_back`]).
pub fn tint_word(rgba: [f32; 4], tint: u32) -> u32 {
    let e = hdr_exponent([rgba[0], rgba[1], rgba[2]], crate::shared::HDR_MAX_EXPONENT);
    (tint & CLEAR) | e << 24
}

/// A stored fragment's colour and tint from its key's RGBA8 and its tint word (common.wgsl's
/// `stored_colour`): RGB times `2^e`, `e` the word's top byte, and the tint its RGB8.
pub fn stored_fragment(rgba8: u32, word: u32) -> ([f32; 4], u32) {
    let scale = (1u32 << (word >> 24).min(31)) as f32;
    let c = unpack_rgba8(rgba8);
    (
        [c[0] * scale, c[1] * scale, c[2] * scale, c[3]],
        word & CLEAR,
    )
}

/// The 64-bit key fragments are ordered by: window depth bits high (non-negative floats order
/// like their bit patterns; -0 and NaN count as 0), the colour's RGBA8 low
/// ([`mantissa_rgba8`]: a colour above white keeps its exponent in its tint word).
pub fn fragment_key(depth: f32, rgba: [f32; 4]) -> u64 {
    let d = if depth > 0.0 { depth } else { 0.0 };
    ((d.to_bits() as u64) << 32) | mantissa_rgba8(rgba) as u64
}

/// The tint of a fragment that lets through every colour alike (RGB8, R in the low byte): its
/// transmittance is `1 - a` in each channel.
pub const CLEAR: u32 = 0x00ff_ffff;

/// Packs a tint in [0, 1] into RGB8 (R in the low byte), as [`pack_rgba8`] its RGB.
pub fn pack_tint(g: [f32; 3]) -> u32 {
    pack_rgba8([g[0], g[1], g[2], 0.0])
}

pub fn unpack_tint(v: u32) -> [f32; 3] {
    let c = unpack_rgba8(v);
    [c[0], c[1], c[2]]
}

/// What a fragment of straight colour `rgba` and tint `tint` lets through, per channel:
/// `(1 - a) g`. For [`CLEAR`] it is `1 - a` in each channel, bit for bit.
pub fn transmittance(rgba: [f32; 4], tint: u32) -> [f32; 3] {
    let g = unpack_tint(tint);
    std::array::from_fn(|i| (1.0 - rgba[3]) * g[i])
}

/// One fragment as compositing sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fragment {
    pub depth: f32,
    pub rgba: [f32; 4],
    /// Its tint, RGB8 ([`CLEAR`] but for tinted glass): it passes `(1 - a) g` of what is behind.
    pub tint: u32,
    /// Submission index: breaks ties between equal keys.
    pub primitive: u32,
}

impl Fragment {
    /// A fragment of no tint ([`CLEAR`]).
    pub fn new(depth: f32, rgba: [f32; 4], primitive: u32) -> Fragment {
        Fragment {
            depth,
            rgba,
            tint: CLEAR,
            primitive,
        }
    }
    /// What it lets through of what is behind it, per channel ([`transmittance`]).
    pub fn transmittance(&self) -> [f32; 3] {
        transmittance(self.rgba, self.tint)
    }
}

/// Sorts fragments front to back (by key, then tint word, then submission index).
pub fn sort_front_to_back(frags: &mut [Fragment]) {
    frags.sort_unstable_by_key(|f| {
        (
            fragment_key(f.depth, f.rgba),
            tint_word(f.rgba, f.tint),
            f.primitive,
        )
    });
}

/// Per-pixel fragment lists: pixel `p = y * width + x` owns `offsets[p]..offsets[p + 1]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FragmentLists {
    pub width: u32,
    pub height: u32,
    pub offsets: Vec<u32>,
    /// Window depth in [0, 1].
    pub depth: Vec<f32>,
    /// Non-premultiplied linear RGBA.
    pub rgba: Vec<[f32; 4]>,
    /// Each fragment's tint (RGB8), or empty: every fragment is [`CLEAR`]. The frames of scenes
    /// that store tint words ([`crate::scene::Scene::tint_words`]: tinted glass, colours above
    /// white) carry them, as the A-buffer stores them (the exponent of a colour above white is
    /// read from the colour itself, [`tint_word`]).
    pub tint: Vec<u32>,
    /// Whether its scene's glass is tinted, so that its k-buffers' tails keep what their tints
    /// take away ([`crate::budget::Words::Tints`]); with `tint` but not this, the words hold
    /// colours' exponents alone ([`crate::budget::Words::Exponents`]).
    pub tinted_glass: bool,
    /// Submission index of the fragment's triangle.
    pub primitive: Vec<u32>,
    /// `|n . v|` of the fragment's triangle.
    pub facing: Vec<f32>,
    /// Per pixel, the nearest opaque surface's colour as [`pack_opaque`] stores it (0 where
    /// none covers the pixel): what every method composites over instead of the background.
    /// Empty where the frame has no opaque surface.
    pub opaque: Vec<u32>,
    /// Per pixel, the nearest opaque surface's window depth (1 where none; empty with
    /// `opaque`): transparent fragments at or behind it are not in the lists.
    pub opaque_depth: Vec<f32>,
}

impl FragmentLists {
    /// (width, height).
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    pub fn pixel_count(&self) -> usize {
        (self.width * self.height) as usize
    }
    pub fn fragment_count(&self) -> usize {
        self.depth.len()
    }
    pub fn range(&self, p: usize) -> std::ops::Range<usize> {
        self.offsets[p] as usize..self.offsets[p + 1] as usize
    }
    /// n(p): the depth complexity of pixel p.
    pub fn count(&self, p: usize) -> u32 {
        self.offsets[p + 1] - self.offsets[p]
    }
    pub fn counts(&self) -> Vec<u32> {
        self.offsets.windows(2).map(|w| w[1] - w[0]).collect()
    }
    pub fn max_depth_complexity(&self) -> u32 {
        self.offsets
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or(0)
    }
    /// Fragment i's tint ([`CLEAR`] where the lists carry none).
    #[inline]
    pub fn tint(&self, i: usize) -> u32 {
        self.tint.get(i).copied().unwrap_or(CLEAR)
    }
    /// Whether the lists carry tints (their scene stores tint words: [`crate::scene::Scene::tint_words`]).
    pub fn tinted(&self) -> bool {
        !self.tint.is_empty()
    }
    /// What its frames store beside each fragment's key (the k-buffers' tails' sums included).
    pub fn words(&self) -> Words {
        Words::of(self.tinted_glass, self.tinted())
    }
    pub fn covered_pixels(&self) -> usize {
        self.offsets.windows(2).filter(|w| w[1] > w[0]).count()
    }
    /// What pixel p's fragments are composited over: its opaque surface's colour where one
    /// covers it, else the background `bg`.
    #[inline]
    pub fn behind(&self, p: usize, bg: [f32; 3]) -> [f32; 3] {
        match self.opaque.get(p) {
            Some(&c) if c >> 24 != 0 => unpack_opaque(c),
            _ => bg,
        }
    }

    /// These lists with only the fragments `keep` marks (one flag a fragment, in list order):
    /// the same pixels, opaque surfaces and per-pixel order.
    pub fn retain(&self, keep: &[bool]) -> FragmentLists {
        let mut out = FragmentLists {
            width: self.width,
            height: self.height,
            offsets: Vec::with_capacity(self.offsets.len()),
            opaque: self.opaque.clone(),
            opaque_depth: self.opaque_depth.clone(),
            tinted_glass: self.tinted_glass,
            ..Default::default()
        };
        out.offsets.push(0);
        for p in 0..self.pixel_count() {
            for i in self.range(p).filter(|&i| keep[i]) {
                out.depth.push(self.depth[i]);
                out.rgba.push(self.rgba[i]);
                if let Some(&g) = self.tint.get(i) {
                    out.tint.push(g);
                }
                out.primitive.push(self.primitive[i]);
                if let Some(&f) = self.facing.get(i) {
                    out.facing.push(f);
                }
            }
            out.offsets.push(out.depth.len() as u32);
        }
        out
    }

    /// Pixel p's fragments in list (submission) order.
    pub fn fragments(&self, p: usize) -> impl ExactSizeIterator<Item = Fragment> + '_ {
        self.range(p).map(|i| Fragment {
            depth: self.depth[i],
            rgba: self.rgba[i],
            tint: self.tint(i),
            primitive: self.primitive[i],
        })
    }
    /// Pixel p's fragments sorted front to back into `out` (cleared first; reuse it across
    /// pixels to avoid allocating).
    pub fn sorted_into(&self, p: usize, out: &mut Vec<Fragment>) {
        out.clear();
        out.extend(self.fragments(p));
        sort_front_to_back(out);
    }
    /// Pixel p's fragments sorted front to back.
    pub fn sorted(&self, p: usize) -> Vec<Fragment> {
        let mut v = Vec::with_capacity(self.count(p) as usize);
        self.sorted_into(p, &mut v);
        v
    }
}

/// What a frame stores beside each fragment's key ([`crate::fragment::tint_word`]) and its
/// k-buffers beside their tails.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Words {
    /// Nothing: grey glass, colours within white.
    #[default]
    None,
    /// A word a fragment, node or slot, its tint clear: the exponents of colours above white.
    Exponents,
    /// A word a fragment, node or slot, and in each k-buffer tail three sums of what its tints
    /// take away: tinted glass (with or without colours above white).
    Tints,
}

impl Words {
    /// The words of a frame whose glass is `tinted` and which stores `words` at all.
    pub fn of(tinted: bool, words: bool) -> Words {
        match (words, tinted) {
            (false, _) => Words::None,
            (true, false) => Words::Exponents,
            (true, true) => Words::Tints,
        }
    }
    /// Whether the frame stores a word a fragment.
    pub fn any(self) -> bool {
        self != Words::None
    }
    /// Whether the words hold tints (the frame's glass is tinted), not exponents alone.
    pub fn tints(self) -> bool {
        self == Words::Tints
    }
}
