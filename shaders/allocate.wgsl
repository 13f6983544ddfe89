// Allocation (compute): k(p) from importance, the twin of alloc::allocate, entirely on the GPU
// in one submission: every sum an integer atomic (exact, order-free), no invocation loops more
// than 16 times (lavapipe ends long loops silently), no host round trip.
//
// Each covered pixel's k is a monotone function of one integer t: water-filling weights w
// (alloc::water_fill: k = clamp(floor(t w / 2^24), lo, cap) below t = 2^40) or slot requests
// c (alloc::level_fill, level L = 2^24 - t: k = clamp(floor((c - L) / 256), lo, cap) below
// t = 2^26), cap the pixel's useful cap (all but its farthest fragment, or two for a pair);
// then every pixel at its cap, at all but its farthest fragment, at n, in three more tiers. The allocation is the largest t whose total fits min(F, sum n), plus one slot each
// for the first pixels (by index) whose k rises at t + 1, as many as are still missing.
//   setup:   F (the frame's plan's, plan.wgsl, in the totals), target, lo, the search
//            interval [a, a + 2^44), the three indirect dispatches' grids; when every fragment
//            fits, the state the rounds would end in, and no workgroup for the weights, the
//            rounds, the marks and their prefix sum (dispatches it empties): apply alone gives
//            k = n
//   weights: importance -> fixed-point weight in place (the kind of alloc::Target)
//   search:  the totals at 16 candidates (SEARCH_PIXELS pixels an invocation, then workgroup
//            sums, then one 64-bit add per candidate and workgroup, two 32-bit atomics where
//            the low word carries): in the first round a
//            bracket (bracket_at), then a + j span/16
//   choose:  the largest candidate whose total fits becomes a; after the bracket, span is the
//            smallest power of 16 that reaches the next candidate, then span /= 16 each round
//            until it is 1, when the remaining rounds' search dispatches no workgroup.
// The bracket's candidates are geometric, 8 apart, from 0 or around the last frame's answer of
// the same kind (kept in the state): an answer d from its centre takes 1 + log16(8 d) rounds or
// so instead of 11 (2 for the frame before's answer again; 4 for VKB's scale near 2^9 and 7
// for DKB's levels near 2^24 from 0). The answer itself does not depend on the bracket: it is
// the largest t whose total fits, and the totals grow with t.
//   mark:    a bit a pixel where k rises at a + 1, a word of them every MARK_BITS pixels, and
//            each word's popcount (then prefix-summed in place by the scan, over those words)
//   apply:   k = k(a) + 1 for the first (target - total(a)) marked pixels, in the weight's place
//            (its span, k and its tail's words, where the tails are pooled: params.pooled_tail)

struct Alloc {
    // Weights: 0 proportional importance, 1 share of the pixel's fragments (r n), 2 slot
    // request (an additive level fits them; the others a scale).
    kind: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> alloc: Alloc;
// Two counts to a word (counts.wgsl).
@group(0) @binding(2) var<storage, read> counts: array<u32>;

// Pixel p's count.
fn count_of(p: u32) -> u32 {
    return count_in(counts[count_word(p)], p);
}
// Importance (f32) in, the weights (u32) in place, then k in place (apply), which the scan then
// turns into the slot bases in place (scan.wgsl's scan_blocks_in_place): one word a pixel for
// the three, each read by the time the next is written.
@group(0) @binding(3) var<storage, read_write> w: array<u32>;
// 0 target, 1 a, 2 span, 3 lo, 4 total at a, 5 F, 6..21 the candidates' totals, 22 the rounds
// the search took, 23 and 24 the last answers of a level and of a scale (last_answer_word):
// 64-bit words, each two 32-bit ones (low, high: u64.wgsl's W), so no 64-bit integer is
// needed (st, st_set, st_add).
@group(0) @binding(5) var<storage, read_write> state: array<atomic<u32>, 2u * ALLOC_STATE_WORDS>;

// State word i.
fn st(i: u32) -> W {
    return W(atomicLoad(&state[2u * i]), atomicLoad(&state[2u * i + 1u]));
}

fn st_set(i: u32, v: W) {
    atomicStore(&state[2u * i], v.x);
    atomicStore(&state[2u * i + 1u], v.y);
}

// State word i plus v: the high word takes the low word's carry (exact once every add of the
// dispatch has run, in any order).
fn st_add(i: u32, v: u32) {
    let old = atomicAdd(&state[2u * i], v);
    if (old + v < old) {
        atomicAdd(&state[2u * i + 1u], 1u);
    }
}
// The marks (shared::marks_words): the popcounts of their words (mark), then those counts'
// exclusive prefix sums and their total (apply), and the words of bits after them.
@group(0) @binding(6) var<storage, read_write> flags: array<u32>;
// The TOTAL_* words (totals.wgsl) and the plan's F (plan.wgsl: PLAN_F_WORD).
@group(0) @binding(7) var<storage, read> totals: array<u32>;
// Three indirect dispatches (workgroups x, y, z, unused; setup writes the frame's grids, so a
// frame never reads what the one before left, however many share a submission): the per-pixel
// weights and marks, the search rounds, and the marks' prefix sum over its blocks. When every
// fragment fits, k = n whatever the weights and marks (apply places no slot past k(a)), so
// setup zeroes the three x and none of them runs a workgroup. Bound to the state in every
// dispatch but setup's and choose's (a buffer read as a dispatch's arguments is not bound
// writable in that dispatch).
@group(0) @binding(8) var<storage, read_write> dispatches: array<u32, ALLOC_DISPATCHES * DISPATCH_WORDS>;


// The workgroup's totals in SEARCH_COPIES copies (a definition the pass composes in): invocation lid adds to copy lid %
// SEARCH_COPIES, so with more than one, neighbouring invocations' atomics do not wait on one
// address (Tuning::spread_search builds it with 32; on lavapipe one is faster).
var<workgroup> partial: array<atomic<u32>, ALLOC_CANDIDATES * SEARCH_COPIES>;

// The span setup leaves for the first round: the bracket's candidates (bracket_at) instead of
// a + j span/16.
const BRACKET: W = W(0u, 0x80000000u);

// The state word holding the last answer of this frame's kind (a level, or a scale), 0 for none.
fn last_answer_word() -> u32 {
    return select(ALLOC_STATE_WORDS - 1u, ALLOC_STATE_WORDS - 2u, alloc.kind == 2u);
}

// Candidate j of the bracket, centred on `c` (0: none): first 0 (every covered pixel at lo: it
// always fits), last 2^44 (past the last tier: it never fits, unless every fragment does, which
// setup settles); between them, without a centre, 2^(3j) up to 2^42, and around one, c minus
// 2^21, 2^18, ..., 2^3, c, then c plus 2^3, ..., 2^18 (kept within [0, 2^44]). Non-decreasing.
fn bracket_at(j: u32, c: W) -> W {
    let top = w_pow2(4u * SEARCH_SPAN_DIGITS);
    if (j == 0u) {
        return W(0u, 0u);
    }
    if (j == ALLOC_CANDIDATES - 1u) {
        return top;
    }
    if (w_is_zero(c)) {
        return w_pow2(3u * j);
    }
    if (j < 8u) {
        let d = w_pow2(3u * (8u - j));
        return select(W(0u, 0u), w_sub(c, d), w_lt(d, c));
    }
    return w_min(w_add(c, select(W(0u, 0u), w_pow2(3u * (j - 8u)), j > 8u)), top);
}

fn pixel(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return grid_index(wid, nwg, lid, ALLOC_GROUP);
}

fn finite(v: f32) -> bool {
    return v == v && abs(v) <= MAX_F32;
}

// alloc::importance_weight, alloc::share_weight, alloc::slot_request.
fn weight(i: f32, n: u32) -> u32 {
    if (alloc.kind == 0u) {
        if (finite(i) && i > 0.0) {
            return clamp(u32(floor(min(i, MAX_IMPORTANCE) * IMPORTANCE_SCALE + 0.5)), 1u, WEIGHT_MAX);
        }
        return 1u;
    }
    let r = select(0.0, clamp(i, 0.0, 1.0), finite(i));
    if (alloc.kind == 1u) {
        return clamp(u32(floor(r * f32(n) * f32(1u << REQUEST_BITS) + 0.5)), 1u, WEIGHT_MAX);
    }
    return min(u32(floor(r * REQUEST_SLOTS * f32(1u << REQUEST_BITS) + 0.5)), WEIGHT_MAX);
}

// The most slots a covered pixel takes before every pixel has as many (alloc::useful_cap):
// all but its farthest fragment, or its two farthest when they share one colour (pair).
fn useful_cap(n: u32, lo: u32, pair: bool) -> u32 {
    let drop = select(1u, 2u, pair);
    return min(max(select(0u, n - drop, n >= drop), lo), n);
}

// k of a covered pixel at t (alloc::water_level_k, alloc::level_k), wp a weight with the pair
// flag in bit 31: the fill up to the pixel's useful cap, then in tiers of 2^40 (scale) or
// 2^26 (level) of t: every pixel at its cap, at all but its farthest fragment, at n.
fn k_at(t: W, wp: u32, n: u32, lo: u32) -> u32 {
    let bits = select(LAMBDA_BITS, LEVEL_BITS + 2u, alloc.kind == 2u);
    let tier = min(w_u32_sat(w_shr(t, bits)), 3u);
    let pair = (wp & PAIR_BIT) != 0u;
    let cap = useful_cap(n, lo, pair);
    if (tier == 1u) {
        return cap;
    }
    if (tier == 2u) {
        return useful_cap(n, lo, false);
    }
    if (tier == 3u) {
        return n;
    }
    let v = wp & WEIGHT_MAX;
    if (alloc.kind == 2u) {
        // Tier 0: t < 2^(LEVEL_BITS + 2), so k lies in 32 bits, signed.
        let k = i32(v) - (1i << LEVEL_BITS) + i32(t.x);
        return u32(clamp(k >> REQUEST_BITS, i32(lo), i32(cap)));
    }
    // Tier 0: t < 2^LAMBDA_BITS and v < 2^WEIGHT_BITS, so t v fits 64 bits.
    let k = w_shr(w_mul_u32(t, v), WEIGHT_BITS);
    return clamp(w_u32_sat(k), lo, cap);
}

@compute @workgroup_size(ALLOC_GROUP)
fn weights(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = pixel(wid, nwg, lid);
    if (p >= params.pixels) {
        return;
    }
    let n = count_of(p);
    // The importance's sign bit is the pair flag (alloc::pixel_weight), which every pixel has
    // where the tails are pooled (alloc::allocate_pooled: a pixel left out by no more than a
    // tail's TAIL_WORDS fragments keeps them all, shared::stored_k).
    let bits = w[p];
    let i = bitcast<f32>(bits & ~PAIR_BIT);
    let pair = (bits & PAIR_BIT) | select(0u, PAIR_BIT, params.pooled_tail != 0u);
    w[p] = select(0u, weight(i, n) | pair, n > 0u);
}

@compute @workgroup_size(1)
fn setup() {
    let f = totals[PLAN_F_WORD];
    let all = totals[TOTAL_FRAGMENTS];
    st_set(0u, w_of(min(f, all)));
    st_set(3u, w_of(select(0u, 1u, f >= totals[TOTAL_COVERED])));
    // The grids (wgsl::grid, as the host computes them): the per-pixel entry points, the
    // search's invocations of SEARCH_PIXELS pixels, the marks' blocks.
    let pixels = params.pixels;
    let grids = array<vec2<u32>, ALLOC_DISPATCHES>(
        grid_of(pixels, ALLOC_GROUP),
        grid_of((pixels + SEARCH_PIXELS - 1u) / SEARCH_PIXELS, ALLOC_GROUP),
        grid_of(mark_blocks(pixels), SCAN_BLOCK),
    );
    for (var d = 0u; d < ALLOC_DISPATCHES; d++) {
        let at = d * DISPATCH_WORDS;
        dispatches[at] = select(grids[d].x, 0u, f >= all);
        dispatches[at + 1u] = grids[d].y;
        dispatches[at + 2u] = 1u;
    }
    if (f >= all) {
        // Every fragment fits: k = n everywhere, the top tier. The search would pick its last
        // candidate in every round (every total fits) and end at a = 2^44 - 1 with span 1 and
        // the total there sum n; that state is set here, the weights, the rounds' search, the
        // marks and their prefix sum dispatch no workgroup (their x is zero), and the choice
        // returns at once.
        st_set(1u, w_sub(w_pow2(4u * SEARCH_SPAN_DIGITS), w_of(1u)));
        st_set(2u, w_of(1u));
        st_set(4u, w_of(all));
    } else {
        st_set(1u, W(0u, 0u));
        st_set(2u, BRACKET);
        st_set(4u, W(0u, 0u));
    }
    st_set(5u, w_of(f));
    st_set(ALLOC_ROUNDS_WORD, W(0u, 0u));
    for (var j = 0u; j < ALLOC_CANDIDATES; j++) {
        st_set(6u + j, W(0u, 0u));
    }
}

@compute @workgroup_size(ALLOC_GROUP)
fn search(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    // SEARCH_PIXELS pixels an invocation, ALLOC_GROUP apart (neighbouring invocations read
    // neighbouring pixels), summed privately before the workgroup's atomics.
    let span = st(2u);
    let bracket = all(span == BRACKET);
    let step = w_shr(span, 4u);
    // No pixel to visit once the search is over (setup found that every fragment fits, or the
    // rounds so far found the answer); the invocation still meets the barrier below.
    let visits = select(0u, SEARCH_PIXELS, !w_is_zero(step));
    let first = (wid.y * nwg.x + wid.x) * ALLOC_GROUP * SEARCH_PIXELS + lid;
    let a = st(1u);
    let lo = st(3u).x;
    let centre = st(last_answer_word());
    var sums: array<u32, ALLOC_CANDIDATES>;
    var any = false;
    for (var i = 0u; i < visits; i++) {
        let p = first + i * ALLOC_GROUP;
        if (p >= params.pixels) {
            continue;
        }
        let n = count_of(p);
        if (n > 0u) {
            any = true;
            let wp = w[p];
            if (bracket) {
                for (var j = 0u; j < ALLOC_CANDIDATES; j++) {
                    sums[j] += k_at(bracket_at(j, centre), wp, n, lo);
                }
            } else {
                for (var j = 0u; j < ALLOC_CANDIDATES; j++) {
                    sums[j] += k_at(w_add(a, w_mul_u32(step, j)), wp, n, lo);
                }
            }
        }
    }
    if (any) {
        let copy = (lid % SEARCH_COPIES) * ALLOC_CANDIDATES;
        for (var j = 0u; j < ALLOC_CANDIDATES; j++) {
            atomicAdd(&partial[copy + j], sums[j]);
        }
    }
    workgroupBarrier();
    if (lid < ALLOC_CANDIDATES) {
        var v = 0u;
        for (var c = 0u; c < SEARCH_COPIES; c++) {
            v += atomicLoad(&partial[c * ALLOC_CANDIDATES + lid]);
        }
        if (v > 0u) {
            st_add(6u + lid, v);
        }
    }
}

@compute @workgroup_size(1)
fn choose() {
    let goal = st(0u);
    let span = st(2u);
    let step = w_shr(span, 4u);
    if (w_is_zero(step)) {
        return;
    }
    // Candidate 0 (the current a) always fits; the totals grow with j.
    var best = 0u;
    for (var j = 1u; j < ALLOC_CANDIDATES; j++) {
        if (w_le(st(6u + j), goal)) {
            best = j;
        }
    }
    st_set(4u, st(6u + best));
    st_add(ALLOC_ROUNDS_WORD, 1u);
    var next_span = step;
    if (all(span == BRACKET)) {
        // The answer lies in [bracket_at(best), bracket_at(best + 1)) (the last candidate's
        // total never fits here): search the smallest power of 16 that covers it (candidates
        // past its end do not fit either). At most 2^44, so at most 11 rounds more.
        let centre = st(last_answer_word());
        let a = bracket_at(best, centre);
        let gap = w_sub(bracket_at(min(best + 1u, ALLOC_CANDIDATES - 1u), centre), a);
        next_span = w_of(1u);
        for (var d = 0u; d < SEARCH_SPAN_DIGITS && w_lt(next_span, gap); d++) {
            next_span = w_shl(next_span, 4u);
        }
        st_set(1u, a);
    } else {
        st_set(1u, w_add(st(1u), w_mul_u32(step, best)));
    }
    st_set(2u, next_span);
    if (all(next_span == w_of(1u))) {
        // Found: the remaining rounds' search dispatches no workgroup, and the next frame's
        // bracket centres on the answer.
        dispatches[DISPATCH_ROUNDS * DISPATCH_WORDS] = 0u;
        st_set(last_answer_word(), st(1u));
    }
    for (var j = 0u; j < ALLOC_CANDIDATES; j++) {
        st_set(6u + j, W(0u, 0u));
    }
}

// A workgroup's marks, a bit a pixel: ALLOC_GROUP consecutive pixels, whole words of them.
var<workgroup> mark_bits: array<atomic<u32>, ALLOC_GROUP / MARK_BITS>;

@compute @workgroup_size(ALLOC_GROUP)
fn mark(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = pixel(wid, nwg, lid);
    let words = ALLOC_GROUP / MARK_BITS;
    if (lid < words) {
        atomicStore(&mark_bits[lid], 0u);
    }
    workgroupBarrier();
    if (p < params.pixels) {
        let a = st(1u);
        let lo = st(3u).x;
        let n = count_of(p);
        if (n > 0u && k_at(w_add(a, w_of(1u)), w[p], n, lo) > k_at(a, w[p], n, lo)) {
            atomicOr(&mark_bits[lid / MARK_BITS], 1u << (lid % MARK_BITS));
        }
    }
    workgroupBarrier();
    // The workgroup's words: their bits after the prefix sums, and each word's popcount where
    // the scan (in place over the first mark_blocks words) makes its prefix.
    let blocks = mark_blocks(params.pixels);
    let word = (p - lid) / MARK_BITS + lid;
    if (lid < words && word < blocks) {
        let bits = atomicLoad(&mark_bits[lid]);
        flags[blocks + 1u + word] = bits;
        flags[word] = countOneBits(bits);
    }
}

@compute @workgroup_size(ALLOC_GROUP)
fn apply(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = pixel(wid, nwg, lid);
    if (p >= params.pixels) {
        return;
    }
    let n = count_of(p);
    if (n == 0u) {
        w[p] = 0u;
        return;
    }
    let a = st(1u);
    let lo = st(3u).x;
    let left = w_sub(st(0u), st(4u));
    let base = k_at(a, w[p], n, lo);
    let rises = k_at(w_add(a, w_of(1u)), w[p], n, lo) > base;
    // `flags` holds the marks' bits after their words' exclusive prefix sums: the marked
    // pixels before p are its word's prefix and its word's bits below its own. The weight
    // read, k takes its place, or with the tails pooled its span (common.wgsl's span_of).
    let word = p / MARK_BITS;
    let below = flags[mark_blocks(params.pixels) + 1u + word] & ((1u << (p % MARK_BITS)) - 1u);
    let rank = flags[word] + countOneBits(below);
    let k = base + select(0u, 1u, rises && w_lt(w_of(rank), left));
    w[p] = select(k, span_of(k, n), params.pooled_tail != 0u);
}
