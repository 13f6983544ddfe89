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
/// The least bytes of any GPU buffer dhoit makes (an unused binding's, an empty pool's), as the
/// budget counts them.
pub const LEAST_BUFFER_BYTES: u64 = 16;
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
/// Words of a frame's totals (totals.wgsl): its fragments, covered pixels, largest count, deep
/// pixels (two fragments or more), DKB's records handed out, deeper pixels (more than
/// [`TAIL_WORDS`]), then the frame's plan (plan.wgsl): F as the allocation reads it, and its
/// flags.
pub const TOTALS_WORDS: u32 = 8;
/// The totals' words that totals.wgsl adds up (the plan, the allocation, the importance passes
/// and the host read them by these names): the frame's fragments, ...
pub const TOTAL_FRAGMENTS: u32 = 0;
/// ... its covered pixels, ...
pub const TOTAL_COVERED: u32 = 1;
/// ... the largest count of a pixel, ...
pub const TOTAL_MAX_COUNT: u32 = 2;
/// ... its deep pixels (two fragments or more), ...
pub const TOTAL_DEEP: u32 = 3;
/// ... DKB's records: the pixels its record marks mark (records.wgsl; this frame's deeper ones,
/// or where it gathers its statistics with its count the frame before's), ...
pub const TOTAL_RECORDS: u32 = 4;
/// ... and its deeper pixels (more than [`TAIL_WORDS`]).
pub const TOTAL_DEEPER: u32 = 5;
/// Words of DKB's batch buffer (its records gathered a batch at a time: totals.wgsl, plan.wgsl,
/// the features and importance passes), by name: the records the network listed in this
/// batch, ...
pub const BATCH_LISTED: u32 = 0;
/// ... the batch's first record, ...
pub const BATCH_LO: u32 = 1;
/// ... the records a batch holds (the frame's plan's), ...
pub const BATCH_SIZE: u32 = 2;
/// ... the rows the network ran in the batches before, ...
pub const BATCH_ROWS_BEFORE: u32 = 3;
/// ... and the sum of the requests the network gave the frame's first batch, in units of
/// 2^-[`REQUEST_SUM_BITS`] rounded to the nearest, a 64-bit sum in two words (low, high): a
/// pixel deeper than the frame before marked takes their mean (importance_dkb.wgsl's gather,
/// `Mlp::dkb_importance_recorded`).
pub const BATCH_REQUESTS: u32 = 4;
/// Words of the batch buffer.
pub const BATCH_WORDS: u32 = 6;
/// The fixed point the requests are summed in ([`BATCH_REQUESTS`]): a request is in (0, 1),
/// so each adds less than 2^20, and the sum of up to 2^44 of them fits 64 bits.
pub const REQUEST_SUM_BITS: u32 = 20;

/// A request as the sum of a batch's requests adds it ([`BATCH_REQUESTS`]).
pub fn request_units(v: f32) -> u32 {
    (v * (1u32 << REQUEST_SUM_BITS) as f32 + 0.5) as u32
}
/// Bytes of the frame's plan's parameters (`wgsl::PlanParams`, whose size a test holds to it).
pub const PLAN_PARAMS_BYTES: u64 = 64;
/// The totals' word holding the plan's F ([`crate::plan::Plan::words`]).
pub const PLAN_F_WORD: u32 = 6;
/// The totals' word holding the plan's flags: bit 0 exact, then [`crate::plan::SHORT_SLOTS`]
/// and the other short bits shifted up by one.
pub const PLAN_FLAGS_WORD: u32 = 7;
/// The resolves' status word 0 (gpu's `FrameStatus`): a pixel's loops came close to the
/// device's limit.
pub const STATUS_NEAR_LOOP: u32 = 1;
/// ... a pool sized before the frame's count held fewer of its fragments than it has (the
/// A-buffer's: the pixels past its end hold none).
pub const STATUS_POOL_SHORT: u32 = 2;
/// Pixels whose allocation marks one u32 holds: the allocation marks the pixels whose k rises
/// at the next level one bit each, and ranks a marked pixel by the marks before it.
pub const MARK_BITS: u64 = 32;
/// Words of the allocation's marks for a frame of `pixels` pixels (allocate.wgsl's `mark` and
/// `apply`): a word of bits for every [`MARK_BITS`] pixels, their popcounts' exclusive prefix
/// sums before them (one word each and the total), so a pixel's rank among the marked ones is
/// its word's prefix and the bits below its own: 1/8 byte a pixel and 4 bytes for every 32,
/// where a word a pixel scanned held 4.
pub const fn marks_words(pixels: u64) -> u64 {
    2 * mark_blocks(pixels) + 1
}

/// Words of the marks' bits for `pixels` pixels (common.wgsl's `mark_blocks`): one every
/// [`MARK_BITS`] pixels, each with its popcount's prefix sum.
pub const fn mark_blocks(pixels: u64) -> u64 {
    pixels.div_ceil(MARK_BITS)
}
/// The largest exponent of a fragment colour kept above white (fragment::hdr_exponent): a
/// colour is stored as RGB8 times `2^e`, `e` in the top byte of its tint word, so colours reach
/// `2^15 = 32768` (an `Rgba16Float` target holds up to 65504). A tail adds `c8 a8 2^e` for
/// each channel, at most `255^2 2^15`, which a 32-bit sum holds.
pub const HDR_MAX_EXPONENT: u32 = 15;
/// Ambient share of the headlight shading.
pub const AMBIENT: f32 = 0.3;
/// Most fragments one pixel may hold: a per-pixel count takes 16 bits (two to a word,
/// [`count_word`]) and stops one past this ([`COUNT_SATURATED`]); the tail's 32-bit integer
/// sums, which add up to 255^2 a fragment, hold twice as many.
pub const MAX_FRAGMENTS_PER_PIXEL: u32 = 32_767;

/// Where a per-pixel count stops (counts.wgsl): one past [`MAX_FRAGMENTS_PER_PIXEL`], the top
/// bit of its 16, so an add that finds it there can take itself back before any half carries
/// into its neighbour, whatever other adds are in flight.
pub const COUNT_SATURATED: u32 = MAX_FRAGMENTS_PER_PIXEL + 1;
const _: () = assert!(COUNT_SATURATED == 1 << 15);

/// The 32-bit word pixel `p`'s count is in, and its shift there: two counts to a word, the
/// even pixel's in the low half (counts.wgsl).
pub const fn count_word(p: u64) -> (u64, u32) {
    (p / 2, 16 * (p % 2) as u32)
}

/// Bytes of the counts of `pixels` pixels: two to a 32-bit word, 2 bytes a pixel (rounded to
/// a whole word).
pub const fn count_bytes(pixels: u64) -> u64 {
    4 * pixels.div_ceil(2)
}

/// The counts of `pixels` pixels from their words as the GPU packs them ([`count_word`]).
pub fn unpack_counts(words: &[u32], pixels: u64) -> Vec<u32> {
    (0..pixels)
        .map(|p| {
            let (w, shift) = count_word(p);
            (words[w as usize] >> shift) & 0xffff
        })
        .collect()
}

/// The words the GPU holds `counts` in ([`count_word`]; each below 2^16).
pub fn pack_counts(counts: &[u32]) -> Vec<u32> {
    let mut words = vec![0u32; counts.len().div_ceil(2)];
    for (p, &n) in counts.iter().enumerate() {
        let (w, shift) = count_word(p as u64);
        words[w as usize] |= (n & 0xffff) << shift;
    }
    words
}

/// 64-bit words of a pooled tail (the allocated k-buffers, `Params::pooled_tail`): sum c8 a8
/// for r and g, for b and sum a8 (two to a word, as the per-pixel tail). Its count is n - k
/// (every fragment a pixel does not keep in its k slots is in its tail), so it is not stored.
/// A pixel that keeps one holds it right after its k slots, so the slot pool holds the tails
/// too: no per-pixel tail buffer.
pub const TAIL_WORDS: u32 = 2;

/// Whether a pixel of `k` slots and `n` fragments keeps a pooled tail: where it truncates by
/// more than [`TAIL_WORDS`] fragments. A tail takes TAIL_WORDS words of the pool, as many as
/// that many fragments' keys, so a pixel that would leave out no more than that keeps them all
/// instead ([`stored_k`]): exact, in no more memory than the tail.
pub const fn has_tail(k: u32, n: u32) -> bool {
    n > k.saturating_add(TAIL_WORDS)
}

/// The slots a pooled pixel keeps for an allocation's `k` of its `n` fragments: k where it
/// keeps a tail ([`has_tail`]), else all n (a tail would take as many words as what it left
/// out). Never fewer than k's fragments, never more words ([`span`]) than k slots and a tail.
pub const fn stored_k(k: u32, n: u32) -> u32 {
    if has_tail(k, n) { k } else { n }
}

/// [`stored_k`] of every pixel: the k a pooled k-buffer's frame stores for an allocation `k`
/// of a frame of `counts`.
pub fn stored(k: &[u32], counts: &[u32]) -> Vec<u32> {
    k.iter()
        .zip(counts)
        .map(|(&k, &n)| stored_k(k, n))
        .collect()
}

/// The pool words a pixel takes: its k slots and its tail where it keeps one ([`has_tail`]),
/// else its n fragments: `min(n, k + TAIL_WORDS)`. The slot bases are the spans' prefix sums.
pub const fn span(k: u32, n: u32) -> u32 {
    if has_tail(k, n) { k + TAIL_WORDS } else { n }
}

/// The k a pixel of `n` fragments stores, from its span (the inverse of [`span`] on every
/// (k, n) it takes): a span below n holds a tail after its slots.
pub const fn k_of_span(span: u32, n: u32) -> u32 {
    if span < n {
        span.saturating_sub(TAIL_WORDS)
    } else {
        span
    }
}

/// 64-bit words of DKB's per-pixel record (features.wgsl): the two 32-bit nearest words
/// (`importance::near_words`), two of colour sums, one of opacity sums. Only a pixel of more
/// than [`TAIL_WORDS`] fragments has one (any fewer are all kept whatever k: [`stored_k`]), in
/// the slot pool until the capture, in pixel order (records.wgsl, `importance::record_index`).
pub const RECORD_WORDS: u32 = 4;

/// A pixel without a record (records.wgsl).
pub const NO_RECORD: u32 = u32::MAX;

#[cfg(test)]
mod tests {
    use super::*;

    /// By hand: the even pixel low, the odd one high, an odd frame's last word half empty; and
    /// back, for every count a pixel may hold beside every other in one word.
    #[test]
    fn counts_pack_two_to_a_word_and_unpack_to_themselves() {
        assert_eq!(pack_counts(&[1, 2, 3]), vec![0x0002_0001, 0x0000_0003]);
        assert_eq!(count_bytes(3), 8);
        assert_eq!(count_bytes(4), 8);
        assert_eq!(unpack_counts(&[0x8000_7fff], 2), vec![32_767, 32_768]);
        for n in (0..=COUNT_SATURATED).step_by(97).chain([COUNT_SATURATED]) {
            let counts = [n, COUNT_SATURATED - n, 0, n];
            assert_eq!(unpack_counts(&pack_counts(&counts), 4), counts);
        }
    }
}
