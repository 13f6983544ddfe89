//! The constants the CPU reference, the budget's layouts and the WGSL passes must agree on,
//! below all three: `budget` sizes the GPU's buffers from them, `wgsl` declares them in every
//! pass's generated prelude, `raster` and the twins compute with them. Each is re-exported
//! where it is used ([`crate::budget::SCAN_BLOCK`], [`crate::wgsl::DISPATCH_WORDS`], ...), so
//! none of those modules imports another for a constant.

/// Pixels per workgroup of the prefix sum (its [`SCAN_GROUP`] invocations take
/// `SCAN_BLOCK / SCAN_GROUP` each); one u32 of block totals per block.
pub const SCAN_BLOCK: u64 = 2048;
/// Invocations per workgroup of the prefix sum.
pub const SCAN_GROUP: u64 = 256;
/// Bytes of the per-frame parameter uniform (resolution, budget, background, totals:
/// `wgsl::Params`, whose size a test holds to it).
pub const PARAMS_BYTES: u64 = 256;
/// Parts per million of a whole share.
pub const PPM: u64 = 1_000_000;
/// Candidates the allocation's search tries per round (a 16-way search).
pub const ALLOC_CANDIDATES: u32 = 16;
/// The allocation's search state in u64s: target, interval start, span, lo, total at the start,
/// F, the candidates' totals, the rounds the search took, and the last answers found for a
/// level and for a scale (kept from frame to frame: the next search's bracket centres on them).
pub const ALLOC_STATE_WORDS: u32 = 6 + ALLOC_CANDIDATES + 3;
/// The state word counting the search's rounds (those that narrowed the interval).
pub const ALLOC_ROUNDS_WORD: u32 = 6 + ALLOC_CANDIDATES;
/// Words of one indirect dispatch's arguments: workgroups x, y, z and one unused (16 bytes, as
/// the allocation's and the importance pass's argument buffers lay them out).
pub const DISPATCH_WORDS: u32 = 4;
/// The allocation's indirect dispatches, in its argument buffer's order: the per-pixel entry
/// points (weights, mark), the search rounds, the marks' prefix sum.
pub const DISPATCH_PER_PIXEL: u32 = 0;
pub const DISPATCH_ROUNDS: u32 = 1;
pub const DISPATCH_SCAN: u32 = 2;
pub const ALLOC_DISPATCHES: u32 = 3;
/// Ambient share of the headlight shading.
pub const AMBIENT: f32 = 0.3;
/// Most fragments one pixel may hold: the tail's 32-bit integer sums add up to 255^2 per
/// fragment.
pub const MAX_FRAGMENTS_PER_PIXEL: u32 = 65_535;
