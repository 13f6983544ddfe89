// DKB's records (features.wgsl), one for each pixel the bits of `record_marks` mark, in pixel
// order: totals.wgsl's mark_records marks the pixels of more than TAIL_WORDS fragments (any
// fewer are all kept whatever k: shared::stored_k), of this frame's count, or where the frame
// gathers its statistics with its count (gpu::Tuning::two_pass_dkb), of the frame before's.
// The marks are laid out as the allocation's (shared::marks_words): the exclusive prefix sums of
// their words' popcounts and their total, then the bits, so pixel p's record is the number of
// marked pixels before it: its word's prefix and the bits below its own (importance::record_index).
// The pass that includes this binds `record_marks`.

// Pixel p's record, or NO_RECORD where the marks leave it out.
fn record_index(p: u32) -> u32 {
    let word = p / MARK_BITS;
    let bits = record_marks[mark_blocks(params.pixels) + 1u + word];
    let bit = 1u << (p % MARK_BITS);
    if ((bits & bit) == 0u) {
        return NO_RECORD;
    }
    return record_marks[word] + countOneBits(bits & (bit - 1u));
}
