// The features pass's additions with 32-bit atomics alone (features.wgsl), in two passes over
// the same fragments, which leave the bytes the one-pass 64-bit atomics leave:
//
// - the depth pass (FEATURES_COLOURS false; with the count, gpu::Phase::CountFeaturesDepths)
//   keeps the nearest depth: an atomicMax of its complement into the key's high word; and adds
//   each sum word's halves, the low half's carry into the high half, as a 64-bit add would;
// - the colour pass (FEATURES_COLOURS true) keeps, among the fragments at that depth, the
//   nearest key's colour (an atomicMax of its complement into the low word: the 64-bit key
//   orders equal depths by colour).
//
// Each record word is two 32-bit words (low, high). The pass that includes this declares
// FEATURES_COLOURS.

alias RecordWord = atomic<u32>;

// Word w of the record at `at` plus the 64-bit value v (low, high halves).
fn record_add(i: u32, v: vec2<u32>) {
    let old = atomicAdd(&records[2u * i], v.x);
    let carry = select(0u, 1u, old + v.x < old);
    if (v.y + carry != 0u) {
        atomicAdd(&records[2u * i + 1u], v.y + carry);
    }
}

fn record_fragment(at: u32, depth_bits: u32, rgba8: u32, tint: u32) {
    let near = ~depth_bits;
    if (FEATURES_COLOURS) {
        if (atomicLoad(&records[2u * at + 1u]) == near) {
            atomicMax(&records[2u * at], ~filtered_rgba8(rgba8, tint));
        }
        return;
    }
    if (!PRELOAD_NEAREST || atomicLoad(&records[2u * at + 1u]) < near) {
        atomicMax(&records[2u * at + 1u], near);
    }
    let sums = fragment_sums(rgba8, tint);
    for (var w = 0u; w < 3u; w++) {
        record_add(at + 1u + w, sums[w]);
    }
}
