// The k-buffer's insertion with 64-bit atomics (the wide capture), which dhoit's capture runs
// (capture.wgsl; an application's fragment shader runs the capture's own code,
// gpu::Oit::store_module): NVIDIA's lock-free Loop64 into the pixel's k slots, and the key it
// pushes out added to the tail's integer sums. capture.wgsl declares `oit_slots` (of
// `SlotWord`s: here one 64-bit slot each, its depth word high and colour word low,
// common.wgsl's slot_depth_word), `oit_tail` (two words a pixel), `oit_tail_count` (one a
// pixel) and `oit_slot_at(base, i, p)`, where slot i of pixel p lies. The portable capture
// (kbuffer_portable.wgsl) gives the same functions with 32-bit atomics.

alias SlotWord = atomic<u64>;

// The wide capture is one pass: it appends where capture.wgsl's mode says so.
const OIT_APPENDS: bool = true;

fn oit_key(depth_word: u32, colour_word: u32) -> u64 {
    return (u64(depth_word) << 32u) | u64(colour_word);
}

// Loop64 insertion of the fragment's key into the pixel's k slots from `base`; returns the
// colour word of the key pushed out past the last slot, or 0 where the insertion ended in an
// empty slot. Two early tests skip the atomics that could not change a slot: the slots only
// ever grow and stay in decreasing order, so a key no greater than the last slot goes straight
// to the tail, and one no greater than the middle slot starts after it.
fn oit_insert(p: u32, base: u32, k: u32, depth_word: u32, colour_word: u32) -> u32 {
    var cur = oit_key(depth_word, colour_word);
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
            return 0u;
        }
        cur = min(old, cur);
    }
    return u32(cur & 0xfffffffflu);
}

// Never called: this capture appends (OIT_APPENDS).
fn oit_appended(p: u32, base: u32, k: u32, depth_word: u32, colour_word: u32) {
}

// Slot `at` set to the fragment's key (the append mode: nobody else writes it).
fn oit_store_slot(at: u32, depth_word: u32, colour_word: u32) {
    atomicStore(&oit_slots[at], oit_key(depth_word, colour_word));
}

// What a colour word adds to a tail's two 64-bit sum words: r and g, then b and a. No low half
// carries into its high half up to raster::MAX_FRAGMENTS_PER_PIXEL fragments (32,767 x 255^2
// < 2^32), so the words are the four 32-bit sums, as resolve.wgsl reads them.
fn oit_tail_words(colour_word: u32) -> vec2<u64> {
    let s = tail_sums(colour_word);
    return vec2<u64>(u64(s.x) | (u64(s.y) << 32u), u64(s.z) | (u64(s.w) << 32u));
}

// The key of colour word `out` pushed out of pixel p's slots, into its tail and the tail's
// count. Three atomics a fragment pushed out, not five.
fn oit_to_tail(p: u32, out: u32) {
    let w = oit_tail_words(out);
    atomicAdd(&oit_tail[2u * p], w.x);
    atomicAdd(&oit_tail[2u * p + 1u], w.y);
    atomicAdd(&oit_tail_count[p], 1u);
}

// The key of colour word `out` pushed out into a pooled tail at pool slot t (its count is
// n - k).
fn pooled_to_tail(t: u32, out: u32) {
    let w = oit_tail_words(out);
    atomicAdd(&oit_slots[t], w.x);
    atomicAdd(&oit_slots[t + 1u], w.y);
}
