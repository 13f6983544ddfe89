// The k-buffer's tint pass (tinted glass, params.tinted), as kbuffer_insert.wgsl's functions:
// after the capture (either insertion) has left each pixel's slots holding its k smallest keys,
// a third geometry pass over the same fragments puts each fragment's tint beside its key, so
// the slots hold the k smallest (key, tint) pairs in order and the tail the others, as
// composite::capture and fragment::sort_front_to_back order them:
//
// - where a pixel inserted (its slots sorted, nearest first), the run of slots holding the
//   fragment's key (a binary search over the keys, which decrease) takes its tint the way the
//   insertion takes keys: the complemented tint, atomicMax, the greater carried on, so a run
//   ends with its keys' smallest tints in order. A tint carried past the run is the fragment
//   pushed out with that key: its absorption goes to the pixel's tail.
// - where a pixel appended (at most APPEND_MAX fragments, its slots unsorted: capture.wgsl's
//   pooled_append), every slot of the fragment's key takes part in that carry, and the resolve
//   sorts the tints with the keys. Nothing is pushed out of such a pixel.
//
// A slot's tint is stored complemented (0: not yet written). A tail holds three sums of what
// its tints take away, `sum (255 - a8) (255 - g8)` for r, g, b (composite::Tail::absorbed: only
// tinted fragments add). The tints buffer (common.wgsl's tint_word, tail_tint_word):
//
// - where the tails are per pixel (FKB, an uploaded k), those three sums a pixel, then a word
//   for each slot;
// - where they are pooled (VKB, DKB), two words for each word of the pool, so that a tail's
//   two pool words have four: slot s's tint at 2 s, the sums of the tail at pool word t at
//   2 t, 2 t + 1, 2 t + 2. No pixel pays for a tail it does not keep.
//
// The slots' words are read as the portable capture's 32-bit pairs (colour low, depth high),
// which is how a 64-bit slot's bytes lie too.

alias SlotWord = atomic<u32>;

// The tint pass writes no key.
const OIT_APPENDS: bool = false;

@group(1) @binding(5) var<storage, read_write> oit_tints: array<atomic<u32>>;

// The alpha of the fragment oit_insert placed, for its tail.
var<private> tint_alpha: u32 = 0u;

// Slot s's key as two words (colour, depth), as common.wgsl's key_of lays them out.
fn oit_slot_key(s: u32) -> vec2<u32> {
    return vec2<u32>(atomicLoad(&oit_slots[2u * s]), atomicLoad(&oit_slots[2u * s + 1u]));
}

// The complemented tint `cur` into the tint words of the slots [first, k) that hold `key`,
// carried as the insertion carries keys; returns the tint carried past them, or 0 where it
// ended in an empty word. With `run` the slots from `first` on hold the key until the first
// that does not (a sorted pixel); else any may (an appended one).
fn oit_carry_tint(p: u32, base: u32, first: u32, k: u32, key: vec2<u32>, run: bool) -> u32 {
    var cur = ~oit_tint;
    for (var i = first; i < k; i++) {
        let s = oit_slot_at(base, i, p);
        if (any(oit_slot_key(s) != key)) {
            if (run) {
                break;
            }
            continue;
        }
        let old = atomicMax(&oit_tints[tint_word(s)], cur);
        if (old == 0u) {
            return 0u;
        }
        cur = min(old, cur);
    }
    return cur;
}

// The fragment's tint into the run of its key in pixel p's sorted slots: the complemented tint
// pushed out (never 0: a complemented RGB8's high byte is 0xff), or 0.
fn oit_insert(p: u32, base: u32, k: u32, depth_word: u32, colour_word: u32) -> u32 {
    tint_alpha = slot_rgba8(colour_word) >> 24u;
    let key = vec2<u32>(colour_word, depth_word);
    // The first slot whose key is at most the fragment's (the keys decrease).
    var lo = 0u;
    var hi = k;
    while (lo < hi) {
        let mid = (lo + hi) / 2u;
        if (key_less(key, oit_slot_key(oit_slot_at(base, mid, p)))) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return oit_carry_tint(p, base, lo, k, key, true);
}

// An appended pixel's fragment: its tint into the slots of its key, wherever they are.
fn oit_appended(p: u32, base: u32, k: u32, depth_word: u32, colour_word: u32) {
    oit_carry_tint(p, base, 0u, k, vec2<u32>(colour_word, depth_word), false);
}

// Never called: the tint pass appends nothing (OIT_APPENDS).
fn oit_store_slot(at: u32, depth_word: u32, colour_word: u32) {
}

// A pushed-out tint's absorption into the tail whose first sum is at `at` (a clear one takes
// nothing away).
fn oit_tint_to_tail(at: u32, out: u32) {
    let tint = ~out;
    if (tint == CLEAR) {
        return;
    }
    let through = 255u - tint_alpha;
    for (var c = 0u; c < 3u; c++) {
        let taken = through * (255u - ((tint >> (8u * c)) & 0xffu));
        if (taken != 0u) {
            atomicAdd(&oit_tints[at + c], taken);
        }
    }
}

fn oit_to_tail(p: u32, out: u32) {
    oit_tint_to_tail(tail_tint_word(p, NO_TAIL), out);
}

fn pooled_to_tail(t: u32, out: u32) {
    oit_tint_to_tail(tail_tint_word(0u, t), out);
}
