// k-buffer capture (geometry), in two modes chosen per pixel, so every fragment ends in a slot
// or in the tail exactly once, in any submission order, and the slots end sorted front to back
// (the append mode's once the resolve has sorted them):
//
// - append (the allocated k-buffers, params.append 1, whose tails are pooled: a pixel that
//   keeps all its n fragments, shared::stored_k, and no more than APPEND_MAX; composite::appends):
//   no insertion is needed; each fragment takes the next of the pixel's n places from a cursor,
//   its count taken down to 0 (the resolve sorts the slots and puts n back).
// - insertion (every other pixel, and every pixel of FKB or an uploaded k): NVIDIA's lock-free
//   Loop64 (kbuffer_insert.wgsl, which an application's shader runs too). Slots hold the
//   bitwise complement of the slot key (common.wgsl's slot_depth_word and slot_colour_word: a
//   cleared, zero slot is empty and atomicMax keeps the nearest): for each slot, old =
//   atomicMax(slot, cur); an empty old ends the insertion, otherwise the farther of the two is
//   carried on. A key still carried after the last slot is the one this insertion pushed out;
//   it goes to the tail's integer sums.
//
// The pass is built with one of two insertions: kbuffer_insert.wgsl's 64-bit atomics (one
// pass), or kbuffer_portable.wgsl's 32-bit ones (the portable capture: a depth pass, then a
// colour pass over the same fragments, CAPTURE_COLOURS), which leave the same slots and tails.
// Where the frame stores tint words (tinted glass, colours above white: common.wgsl's
// stores_tints), a third build runs after either, kbuffer_tint.wgsl's tint pass: each
// fragment's tint word beside its key, the pushed-out words' absorption and light into the tail.
//
// Built a second time with EVERY_FRAGMENT_FITS for the frames whose budget holds every fragment
// (the pixels' modes then follow from the slot bases alone; see below).

// Per pixel (pixels + 1 entries): its slot bases, the exclusive prefix sums of k, so a pixel's
// k is its bases' difference (k is not stored beside them); with the tails pooled
// (params.pooled_tail), of its span: k slots, then TAIL_WORDS words of its tail where it keeps
// one (common.wgsl's has_tail), the per-pixel tail buffers then unused.
@group(1) @binding(0) var<storage, read> slot_base: array<u32>;
@group(1) @binding(1) var<storage, read_write> oit_slots: array<SlotWord>;
// Per pixel: sum c8 a8 for r, g, b, sum a8 (four 32-bit words, as resolve.wgsl reads them;
// the wide capture adds them two to a 64-bit word), and the tail's count. Both unused where the
// tails are pooled.
@group(1) @binding(2) var<storage, read_write> oit_tail: array<SlotWord>;
@group(1) @binding(3) var<storage, read_write> oit_tail_count: array<atomic<u32>>;
// n(p), two to a word (counts.wgsl), read where the tails are pooled (a pixel's span says
// whether it keeps a tail only beside n; an unused buffer otherwise); a pixel that appends
// takes its places from it, down to 0 (resolve.wgsl restores it). A pixel that appends never
// has a tail and one with a tail never appends, so a load of it sees n wherever n decides. (A
// pixel's count is taken down once for each of its n fragments, so it never borrows from the
// word's other half: a pixel too deep for any method has a tail, so never appends.)
@group(1) @binding(4) var<storage, read_write> count: array<atomic<u32>>;

// Whether the frame's budget holds every fragment, so k(p) = n(p) for every pixel (a pipeline
// of its own, defined true (wgsl::shaders::Pass::defines), for the allocated k-buffers alone: their tails
// pooled, such a frame keeps none): each pixel's k is its slot bases' difference, and a pixel
// of at most APPEND_MAX fragments appends with no other load; the deeper ones insert as above
// (nothing is pushed out). EVERY_FRAGMENT_FITS is a definition the pass composes in.

// Where slot i of pixel p lies (kbuffer_insert.wgsl's oit_insert and oit_to_tail run here).
fn oit_slot_at(base: u32, i: u32, p: u32) -> u32 {
    return slot_at(base, i, p);
}

// No pooled tail (a pixel that holds all its n fragments: common.wgsl's has_tail).
const NO_TAIL: u32 = 0xffffffffu;

// The fragment's tint word (its tint, RGB8, and its colour's exponent), for the tint pass
// (kbuffer_tint.wgsl).
var<private> oit_tint: u32 = CLEAR;

// A pooled pixel of n = k fragments (no tail) that appends: the next of its k places, from its
// count taken down (n - 1 first). The passes after the one that appended whole keys (the
// portable capture's colour pass, the tint pass) hand it to their oit_appended.
fn pooled_append(p: u32, base: u32, k: u32, depth_word: u32, colour_word: u32) {
    if (!OIT_APPENDS) {
        oit_appended(p, base, k, depth_word, colour_word);
        return;
    }
    let i = count_in(atomicSub(&count[count_word(p)], count_unit(p)), p) - 1u;
    if (i < k) {
        oit_store_slot(base + i, depth_word, colour_word);
    }
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        return vec4<f32>(0.0);
    }
    let p = pixel_index(in.clip, params.width);
    let depth_word = slot_depth_word(in.clip.z);
    let colour_word = slot_colour_word(f.rgba8);
    oit_tint = f.tint;
    if (EVERY_FRAGMENT_FITS) {
        // The bases hold spans of k = n: no tail.
        let base = slot_base[p];
        let n = slot_base[p + 1u] - base;
        if (n > APPEND_MAX) {
            oit_insert(p, base, n, depth_word, colour_word);
        } else {
            pooled_append(p, base, n, depth_word, colour_word);
        }
        return vec4<f32>(0.0);
    }
    var k = params.k_uniform;
    var base = p * params.k_uniform;
    var tail = NO_TAIL;
    let pooled = params.pooled_tail != 0u;
    if (k == 0u) {
        base = slot_base[p];
        k = slot_base[p + 1u] - base;
        if (pooled) {
            let span = k;
            let n = count_in(atomicLoad(&count[count_word(p)]), p);
            k = k_of_span(span, n);
            if (span < n) {
                tail = base + k;
            } else if (params.append != 0u && k <= APPEND_MAX) {
                pooled_append(p, base, k, depth_word, colour_word);
                return vec4<f32>(0.0);
            }
        }
    }
    // Where a pixel keeps no pooled tail, its k = n slots hold all it has: nothing is pushed
    // out.
    let out = oit_insert(p, base, k, depth_word, colour_word);
    if (out == 0u) {
        return vec4<f32>(0.0);
    }
    if (!pooled) {
        oit_to_tail(p, out);
    } else if (tail != NO_TAIL) {
        pooled_to_tail(tail, out);
    }
    return vec4<f32>(0.0);
}
