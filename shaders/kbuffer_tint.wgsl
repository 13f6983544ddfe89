// The k-buffer's tint pass (where the frame stores tint words: tinted glass, colours above
// white; common.wgsl's stores_tints), as kbuffer_insert.wgsl's functions: after the capture
// (either insertion) has left each pixel's slots holding its k smallest keys, a third geometry
// pass over the same fragments puts each fragment's tint word (its tint, its colour's exponent
// in the top byte) beside its key, so the slots hold the k smallest (key, word) pairs in order
// and the tail the others, as composite::capture and fragment::sort_front_to_back order them.
// A word carried past its run is a fragment in the tail: besides its absorption, where its
// colour is above white (exponent e), it adds the (2^e - 1) c8 a8 the capture's sums lack,
// saturating:
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
// - where the glass is grey (the words hold colours' exponents alone, params.tinted 0), no
//   sums: a word for each slot, or each word of the pool (budget::Words::Exponents).
//
// The slots' words are read as the portable capture's 32-bit pairs (colour low, depth high),
// which is how a 64-bit slot's bytes lie too.

alias SlotWord = atomic<u32>;

// The tint pass writes no key.
const OIT_APPENDS: bool = false;

@group(1) @binding(5) var<storage, read_write> oit_tints: array<atomic<u32>>;

// The RGBA8 of the fragment oit_insert placed, for its tail.
var<private> tint_rgba8: u32 = 0u;

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
    tint_rgba8 = slot_rgba8(colour_word);
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
    if (!filters(tint)) {
        return;
    }
    let through = 255u - (tint_rgba8 >> 24u);
    for (var c = 0u; c < 3u; c++) {
        let taken = through * (255u - ((tint >> (8u * c)) & 0xffu));
        if (taken != 0u) {
            atomicAdd(&oit_tints[at + c], taken);
        }
    }
}

// What a pushed-out fragment above white adds to its tail's colour sums beyond what the
// capture added: the tail takes c8 a8 2^e (composite::Tail::add), the capture added c8 a8.
fn hdr_extra(out: u32) -> vec3<u32> {
    return tail_sums_of(tint_rgba8).xyz * ((1u << ((~out) >> 24u)) - 1u);
}

// 2^32 - 1: where a colour sum stops (composite::Tail::add saturates). An add that wraps
// raises its word back to it, and any add after that wraps again and does the same, so the
// sum ends there whatever the order.
const SUM_MAX: u32 = 0xffffffffu;

fn oit_to_tail(p: u32, out: u32) {
    oit_tint_to_tail(tail_tint_word(p, NO_TAIL), out);
    let extra = hdr_extra(out);
    for (var c = 0u; c < 3u; c++) {
        let x = extra[c];
        if (x != 0u && atomicAdd(&oit_tail[4u * p + c], x) > SUM_MAX - x) {
            atomicMax(&oit_tail[4u * p + c], SUM_MAX);
        }
    }
}

fn pooled_to_tail(t: u32, out: u32) {
    oit_tint_to_tail(tail_tint_word(0u, t), out);
    let extra = hdr_extra(out);
    for (var c = 0u; c < 3u; c++) {
        let x = extra[c];
        if (x != 0u && atomicAdd(&oit_slots[2u * t + c], x) > SUM_MAX - x) {
            atomicMax(&oit_slots[2u * t + c], SUM_MAX);
        }
    }
}
