// The features pass's additions with 64-bit atomics (one pass; features.wgsl): the nearest
// key by a 64-bit atomicMax of its complement, each sum word by one 64-bit add.

alias RecordWord = atomic<u64>;

fn record_fragment(at: u32, depth_bits: u32, rgba8: u32, tint: u32) {
    let key = (u64(depth_bits) << 32u) | u64(filtered_rgba8(rgba8, tint));
    if (!PRELOAD_NEAREST || atomicLoad(&records[at]) < ~key) {
        atomicMax(&records[at], ~key);
    }
    let sums = fragment_sums(rgba8, tint);
    for (var w = 0u; w < 3u; w++) {
        atomicAdd(&records[at + 1u + w], u64(sums[w].x) | (u64(sums[w].y) << 32u));
    }
}
