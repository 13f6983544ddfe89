// The k-buffer's insertion with 32-bit atomics alone (the portable capture, for devices
// without 64-bit atomics: WebGPU, Metal, most phones), as kbuffer_insert.wgsl's functions, in
// two geometry passes over the same fragments (nvpro's Loop32 idea, made exact):
//
// - the depth pass (CAPTURE_COLOURS false) inserts each fragment's depth word into the high
//   words of the pixel's k slots as Loop64 inserts keys (atomicMax, the farther carried on),
//   and appends whole keys where capture.wgsl's mode appends. After it, the slots' depth words
//   are the k nearest depths, with their multiplicity.
// - the colour pass (CAPTURE_COLOURS true) finds the run of slots holding the fragment's depth
//   (a binary search: the depth words are in decreasing order) and inserts its colour word
//   into their low words the same way. A colour carried past the last slot, or a depth not
//   among the kept ones, is the fragment pushed out: into the tail.
//
// Equal depths are ordered by colour word, as the 64-bit key orders them (depth high, colour
// low): the slots end holding the k smallest keys, sorted, and the tail the others, whatever
// the order the fragments arrive in; both words of every slot are what the wide capture
// leaves, bit for bit. Each slot is two 32-bit words (colour low, depth high: a 64-bit slot's
// bytes), each tail four. The pass that includes this declares CAPTURE_COLOURS.

alias SlotWord = atomic<u32>;

// The depth pass appends whole keys; the colour pass leaves appended pixels alone.
const OIT_APPENDS: bool = !CAPTURE_COLOURS;

// The word of slot i's depth (the high one).
fn oit_depth_at(base: u32, i: u32, p: u32) -> u32 {
    return 2u * oit_slot_at(base, i, p) + 1u;
}

// The depth pass's insertion of `depth_word` into the k slots' depth words, with Loop64's
// early tests; what it pushes out is dropped (the colour pass sends it to the tail).
fn oit_insert_depth(p: u32, base: u32, k: u32, depth_word: u32) {
    var cur = depth_word;
    var i = 0u;
    if (k > 0u) {
        if (atomicLoad(&oit_slots[oit_depth_at(base, k - 1u, p)]) >= cur) {
            i = k;
        } else if (k > 2u) {
            let m = k / 2u;
            if (atomicLoad(&oit_slots[oit_depth_at(base, m, p)]) >= cur) {
                i = m + 1u;
            }
        }
    }
    for (; i < k; i++) {
        let old = atomicMax(&oit_slots[oit_depth_at(base, i, p)], cur);
        if (old == 0u) {
            return;
        }
        cur = min(old, cur);
    }
}

// The colour pass: the colour word pushed out of the k slots (0 where none was), as
// kbuffer_insert.wgsl's oit_insert returns it.
fn oit_insert_colour(p: u32, base: u32, k: u32, depth_word: u32, colour_word: u32) -> u32 {
    // The first slot whose depth word is at most the fragment's (they decrease).
    var lo = 0u;
    var hi = k;
    while (lo < hi) {
        let mid = (lo + hi) / 2u;
        if (atomicLoad(&oit_slots[oit_depth_at(base, mid, p)]) > depth_word) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    var cur = colour_word;
    for (var i = lo; i < k; i++) {
        if (atomicLoad(&oit_slots[oit_depth_at(base, i, p)]) != depth_word) {
            // Past the run (or no run): the depth pass kept no more of this depth.
            break;
        }
        let old = atomicMax(&oit_slots[2u * oit_slot_at(base, i, p)], cur);
        if (old == 0u) {
            return 0u;
        }
        cur = min(old, cur);
    }
    return cur;
}

fn oit_insert(p: u32, base: u32, k: u32, depth_word: u32, colour_word: u32) -> u32 {
    if (CAPTURE_COLOURS) {
        return oit_insert_colour(p, base, k, depth_word, colour_word);
    }
    oit_insert_depth(p, base, k, depth_word);
    return 0u;
}

// The colour pass leaves an appended pixel alone: its depth pass appended whole keys.
fn oit_appended(p: u32, base: u32, k: u32, depth_word: u32, colour_word: u32) {
}

// Slot `at` set to the fragment's key (the append mode, in the depth pass).
fn oit_store_slot(at: u32, depth_word: u32, colour_word: u32) {
    atomicStore(&oit_slots[2u * at], colour_word);
    atomicStore(&oit_slots[2u * at + 1u], depth_word);
}

// The key of colour word `out` pushed out of pixel p's slots, into its tail's four sums (the
// wide capture's two 64-bit words' halves) and the tail's count.
fn oit_to_tail(p: u32, out: u32) {
    let s = tail_sums(out);
    atomicAdd(&oit_tail[4u * p], s.x);
    atomicAdd(&oit_tail[4u * p + 1u], s.y);
    atomicAdd(&oit_tail[4u * p + 2u], s.z);
    atomicAdd(&oit_tail[4u * p + 3u], s.w);
    atomicAdd(&oit_tail_count[p], 1u);
}

// The key of colour word `out` pushed out into a pooled tail at pool slot t.
fn pooled_to_tail(t: u32, out: u32) {
    let s = tail_sums(out);
    atomicAdd(&oit_slots[2u * t], s.x);
    atomicAdd(&oit_slots[2u * t + 1u], s.y);
    atomicAdd(&oit_slots[2u * t + 2u], s.z);
    atomicAdd(&oit_slots[2u * t + 3u], s.w);
}
