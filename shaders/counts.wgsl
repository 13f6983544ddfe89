// Per-pixel fragment counts, two to a 32-bit word (shared::count_word): pixel p's count is the
// low half of word p / 2 for an even p, the high half for an odd one, 2 bytes a pixel. Every
// pass that counts, reads or takes a count down goes through these (an application's count
// phase too: it runs dhoit's own count pass).
//
// A count stops at COUNT_SATURATED (shared::MAX_FRAGMENTS_PER_PIXEL + 1): an add that finds it
// there takes itself back (each count pass spells out the add, count_stopped and the take-back,
// as WGSL passes no storage pointer to a function), so a half never carries into its neighbour
// however deep a pixel is (only the adds in flight at once pass it, never by 2^15), and a pixel
// that reads more than MAX_FRAGMENTS_PER_PIXEL refuses the frame (resolve.wgsl's too_deep).

const COUNT_SATURATED: u32 = 32768u;

// The word pixel p's count is in.
fn count_word(p: u32) -> u32 {
    return p >> 1u;
}

// One fragment of pixel p, in its word.
fn count_unit(p: u32) -> u32 {
    return 1u << ((p & 1u) << 4u);
}

// Pixel p's count in `word`, its word's value.
fn count_in(word: u32, p: u32) -> u32 {
    return (word >> ((p & 1u) << 4u)) & 0xffffu;
}

// Whether an add that found `old` (its word's value before it) to pixel p's count must take
// itself back: the count had stopped.
fn count_stopped(old: u32, p: u32) -> bool {
    return count_in(old, p) >= COUNT_SATURATED;
}
