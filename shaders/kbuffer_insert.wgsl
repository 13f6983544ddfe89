// The k-buffer's insertion, which dhoit's capture runs (capture.wgsl; an application's
// fragment shader runs the capture's own code, gpu::Oit::store_module): NVIDIA's lock-free Loop64 into the pixel's k slots, and the key it pushes
// out added to the tail's integer sums. The pass that includes it declares `oit_slots` (atomic
// u64, complemented keys: a cleared, zero slot is empty), `oit_tail` (atomic u64, two a pixel),
// `oit_tail_count` (atomic u32, one a pixel) and `oit_slot_at(base, i, p)`, where slot i of
// pixel p lies.

// Loop64 insertion of `key` (complemented) into the pixel's k slots from `base`; returns the
// key pushed out past the last slot, or 0 where the insertion ended in an empty slot. Two
// early tests skip the atomics that could not change a slot: the slots only ever grow and stay
// in decreasing order, so a key no greater than the last slot goes straight to the tail, and
// one no greater than the middle slot starts after it.
fn oit_insert(p: u32, base: u32, k: u32, key: u64) -> u64 {
    var cur = key;
    var i = 0u;
    if (k > 0u) {
        if (atomicLoad(&oit_slots[oit_slot_at(base, k - 1u, p)]) >= cur) {
            i = k;
        } else if (k > 2u) {
            let m = k / 2u;
            if (atomicLoad(&oit_slots[oit_slot_at(base, m, p)]) >= cur) {
                i = m + 1u;
            }
        }
    }
    for (; i < k; i++) {
        let old = atomicMax(&oit_slots[oit_slot_at(base, i, p)], cur);
        if (old == 0lu) {
            return 0lu;
        }
        cur = min(old, cur);
    }
    return cur;
}

// The key `out` (complemented) pushed out of pixel p's slots, into its tail: sum c8 a8 for r,
// g, b and sum a8, two to a 64-bit word (no low half carries into its high half up to
// raster::MAX_FRAGMENTS_PER_PIXEL fragments: 32,767 x 255^2 < 2^32), and the tail's count.
// Three atomics a fragment pushed out, not five.
fn oit_to_tail(p: u32, out: u64) {
    let w = oit_tail_words(out);
    atomicAdd(&oit_tail[2u * p], w.x);
    atomicAdd(&oit_tail[2u * p + 1u], w.y);
    atomicAdd(&oit_tail_count[p], 1u);
}

// What the key `out` (complemented) adds to a tail's two sum words: r and g, then b and a.
fn oit_tail_words(out: u64) -> vec2<u64> {
    let rgba = u32((~out) & 0xfffffffflu);
    let a = rgba >> 24u;
    let r = u64((rgba & 0xffu) * a);
    let g = u64(((rgba >> 8u) & 0xffu) * a);
    let b = u64(((rgba >> 16u) & 0xffu) * a);
    return vec2<u64>(r | (g << 32u), b | (u64(a) << 32u));
}
