//! Memory budgets: what each method's GPU pipeline allocates, and the fragment budget F(M).
//!
//! `F(M) = floor((M - |P| S_p - S_i) / S_f)`: S_f is the bytes of one fragment slot, S_p the
//! bytes every pixel costs whatever its k, S_i the fixed cost. Each method has its own
//! [`Layout`], listing every buffer it creates by the label the GPU pipeline gives it, so the
//! accounting is one table, not a constant to keep in step by hand: the bytes allocated for
//! budget M never exceed M.
//!
//! A budget is given either in bytes (`20MB`, `40MiB`, `1048576`) or in average slots per pixel
//! (`2fpp`); the latter fixes F directly and the bytes follow from each method's layout.

use crate::error::{Error, Result};

/// Bytes of one fragment slot: a 64-bit key, window depth bits high and RGBA8 low.
pub const SLOT_BYTES: u64 = 8;
/// Bytes of the MLP's uniform buffer: a 4-float header, 24 standardisation floats and the
/// default network's 9,985 weights, in vec4s (`importance_dkb.wgsl` declares 2,504).
pub const MLP_UNIFORM_BYTES: u64 = (4u64 + 24 + 9985).div_ceil(4) * 16;
/// Pixels per workgroup of the prefix sum; one u32 of block totals per block.
pub const SCAN_BLOCK: u64 = 256;
/// Bytes of the per-frame parameter uniform (resolution, budget, background, totals).
pub const PARAMS_BYTES: u64 = 256;

/// The buffers one method allocates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    pub method: &'static str,
    /// Bytes of one fragment slot (the A-buffer stores whole fragments).
    pub slot_bytes: u64,
    /// Per-pixel buffers: (label, bytes per pixel).
    pub per_pixel: &'static [(&'static str, u64)],
    /// Fixed buffers: (label, bytes).
    pub fixed: &'static [(&'static str, u64)],
    /// Whether a prefix sum over pixels is part of the pipeline (it keeps one u32 of block
    /// totals per [`SCAN_BLOCK`] pixels).
    pub scan: bool,
}

/// The tail's integer sums: sum c8 a8 for r, g, b, sum a8, count (five u32 a pixel).
const HYBRID_TAIL: (&str, u64) = ("oit.tail", 20);
/// The geometry passes' render target (R8, never written): rasterization needs one.
const RASTER_TARGET: (&str, u64) = ("raster.target", 1);
/// The allocation's step parameters and integer sums.
const ALLOC_PARAMS: (&str, u64) = ("alloc.params", 32);
const ALLOC_SUMS: (&str, u64) = ("alloc.sums", 32);
const ALLOC_HISTOGRAM: (&str, u64) = ("alloc.histogram", 1024);
/// The prefix sums' final entry (offsets hold pixels + 1 values).
const OFFSETS_END: (&str, u64) = ("offsets.end", 4);

/// Deep k-buffer: network features, importance, k, offsets, tail, output.
pub const DKB: Layout = Layout {
    method: "dkb",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[
        RASTER_TARGET,
        ("features.count", 4),
        ("features.near", 4),
        ("features.far", 4),
        ("features.nearest_color", 8),
        ("features.color_sum", 12),
        ("features.luma_sums", 8),
        ("oit.importance", 4),
        ("alloc.flags", 4),
        ("oit.k", 4),
        ("oit.offsets", 4),
        HYBRID_TAIL,
        ("oit.image", 16),
    ],
    fixed: &[
        ("mlp.weights", MLP_UNIFORM_BYTES),
        ("params", PARAMS_BYTES),
        ("features.totals", 24),
        OFFSETS_END,
        ALLOC_PARAMS,
        ALLOC_SUMS,
        ALLOC_HISTOGRAM,
    ],
    scan: true,
};

/// Optimal allocation uploaded as k: the same capture and resolve as DKB, no network.
pub const OPT: Layout = Layout {
    method: "optimal",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[
        RASTER_TARGET,
        ("oit.k", 4),
        ("oit.offsets", 4),
        HYBRID_TAIL,
        ("oit.image", 16),
    ],
    fixed: &[("params", PARAMS_BYTES), OFFSETS_END],
    scan: true,
};

/// Variable k-buffer with importance maps (paper 002).
pub const VKB: Layout = Layout {
    method: "vkb",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[
        RASTER_TARGET,
        ("vkb.count", 4),
        ("vkb.nearest", 8),
        ("oit.importance", 4),
        ("alloc.flags", 4),
        ("oit.k", 4),
        ("oit.offsets", 4),
        HYBRID_TAIL,
        ("oit.image", 16),
    ],
    fixed: &[
        ("params", PARAMS_BYTES),
        ("vkb.totals", 16),
        OFFSETS_END,
        ALLOC_PARAMS,
        ALLOC_SUMS,
        ALLOC_HISTOGRAM,
    ],
    scan: true,
};

/// Fixed k-buffer: k slots for every pixel, tail, output.
pub const FKB: Layout = Layout {
    method: "fkb",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[RASTER_TARGET, HYBRID_TAIL, ("oit.image", 16)],
    // The capture and resolve passes bind a per-pixel k and offsets that FKB never reads.
    fixed: &[
        ("params", PARAMS_BYTES),
        ("fkb.unused_k", 16),
        ("fkb.unused_offsets", 16),
    ],
    scan: false,
};

/// MLAB: m rows of 8 bytes (RGB8 premultiplied, transmittance 8 bits, depth 32 bits), output.
pub const MLAB: Layout = Layout {
    method: "mlab",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[RASTER_TARGET, ("oit.image", 16)],
    fixed: &[("params", PARAMS_BYTES)],
    scan: false,
};

/// A-buffer: counts, offsets, store cursors, every fragment (depth, RGBA8, submission index,
/// padding: 16 bytes), output. Not budgeted: exact memory.
pub const ABUFFER: Layout = Layout {
    method: "abuffer",
    slot_bytes: 16,
    per_pixel: &[
        RASTER_TARGET,
        ("abuf.count", 4),
        ("abuf.offsets", 4),
        ("abuf.cursor", 4),
        ("oit.image", 16),
    ],
    fixed: &[("params", PARAMS_BYTES), OFFSETS_END, ("status", 16)],
    scan: true,
};

impl Layout {
    /// S_p: bytes every pixel costs whatever its k.
    pub fn per_pixel_bytes(&self) -> u64 {
        self.per_pixel.iter().map(|b| b.1).sum()
    }
    /// Bytes that do not depend on the number of slots: `|P| S_p + S_i` (scan scratch included).
    pub fn fixed_bytes(&self, pixels: u64) -> u64 {
        // The block totals; like every GPU buffer, at least 16 bytes.
        let scan = if self.scan {
            (4 * pixels.div_ceil(SCAN_BLOCK)).max(16)
        } else {
            0
        };
        pixels * self.per_pixel_bytes() + self.fixed.iter().map(|b| b.1).sum::<u64>() + scan
    }
    /// Bytes allocated with `slots` fragment slots.
    pub fn allocated_bytes(&self, pixels: u64, slots: u64) -> u64 {
        self.fixed_bytes(pixels) + slots * self.slot_bytes
    }
    /// F(M): the fragment slots a budget of `bytes` leaves, or an error saying what is needed.
    pub fn fragment_budget(&self, bytes: u64, pixels: u64) -> Result<u64> {
        let fixed = self.fixed_bytes(pixels);
        if bytes < fixed + pixels.min(1) * self.slot_bytes {
            return Err(Error::Budget(
                format_bytes(bytes),
                format!(
                    "{} needs {} for {} pixels before any fragment slot ({} B per pixel + {} fixed); \
                     one slot per pixel takes {} in all",
                    self.method,
                    format_bytes(fixed),
                    pixels,
                    self.per_pixel_bytes(),
                    format_bytes(fixed - pixels * self.per_pixel_bytes()),
                    format_bytes(fixed + pixels * self.slot_bytes)
                ),
            ));
        }
        Ok((bytes - fixed) / self.slot_bytes)
    }
}

/// Every budgeted layout, by method name.
pub fn layout(method: &str) -> Option<Layout> {
    [DKB, OPT, VKB, FKB, MLAB, ABUFFER]
        .into_iter()
        .find(|l| l.method == method)
}

/// A budget as the user gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    Bytes(u64),
    /// Average fragment slots per pixel: F = floor(fpp |P|).
    SlotsPerPixel(f64),
}

impl Budget {
    pub fn parse(s: &str) -> Result<Budget> {
        let t = s.trim();
        let bad = |m: &str| Error::Budget(s.to_string(), m.to_string());
        let lower = t.to_ascii_lowercase();
        if let Some(n) = lower.strip_suffix("fpp") {
            let v: f64 = n
                .trim()
                .parse()
                .map_err(|_| bad("expected a number before 'fpp'"))?;
            if !v.is_finite() || v <= 0.0 {
                return Err(bad("slots per pixel must be a positive number"));
            }
            return Ok(Budget::SlotsPerPixel(v));
        }
        let split = lower
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(lower.len());
        let (num, unit) = lower.split_at(split);
        let v: f64 = num.parse().map_err(|_| {
            bad("expected bytes such as 20MB, 40MiB or 1048576, or slots per pixel such as 2fpp")
        })?;
        let scale = match unit.trim() {
            "" | "b" => 1.0,
            "kb" => 1e3,
            "mb" => 1e6,
            "gb" => 1e9,
            "kib" => 1024.0,
            "mib" => 1024.0 * 1024.0,
            "gib" => 1024.0 * 1024.0 * 1024.0,
            u => {
                return Err(bad(&format!(
                    "unknown unit '{u}' (B, KB, MB, GB, KiB, MiB, GiB or fpp)"
                )));
            }
        };
        let bytes = v * scale;
        if !bytes.is_finite() || !(1.0..=1e15).contains(&bytes) {
            return Err(bad("the budget must be between 1 byte and 1 PB"));
        }
        Ok(Budget::Bytes(bytes as u64))
    }

    /// Resolves to (bytes M, fragment slots F(M)) for a layout and pixel count.
    pub fn resolve(&self, layout: &Layout, pixels: u64) -> Result<(u64, u64)> {
        match *self {
            Budget::Bytes(b) => Ok((b, layout.fragment_budget(b, pixels)?)),
            Budget::SlotsPerPixel(f) => {
                let slots = (f * pixels as f64).floor() as u64;
                if slots == 0 {
                    return Err(Error::Budget(
                        format!("{f}fpp"),
                        format!("leaves no fragment slot for {pixels} pixels"),
                    ));
                }
                Ok((layout.allocated_bytes(pixels, slots), slots))
            }
        }
    }
}

impl std::fmt::Display for Budget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Budget::Bytes(b) => write!(f, "{}", format_bytes(*b)),
            Budget::SlotsPerPixel(v) => write!(f, "{v}fpp"),
        }
    }
}

/// Human-readable bytes (binary units).
pub fn format_bytes(b: u64) -> String {
    const UNITS: [&str; 4] = ["B", "KiB", "MiB", "GiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u < UNITS.len() - 1 {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.2} {}", UNITS[u])
    }
}
