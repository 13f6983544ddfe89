// k-buffer resolve (compute, one invocation a pixel): the core slots blended front to back,
// then the tail approximated over what is behind the pixel (behind.wgsl), as
// composite::hybrid_sorted with composite::Tail. A pixel the capture appended (composite::appends:
// it keeps all its fragments, its tails pooled) first has its slots sorted here and its count,
// the capture's cursor, put back: after this pass the slots and the tail are those of the
// insertion mode (composite::capture), whatever the mode.

@group(0) @binding(0) var<uniform> params: Params;
// The slot bases (pixels + 1 entries; k is their difference, capture.wgsl).
@group(0) @binding(1) var<storage, read> slot_base: array<u32>;
// Each slot two words, colour low (x) and depth high (y), as capture.wgsl leaves them.
@group(0) @binding(2) var<storage, read_write> slots: array<vec2<u32>>;
// Per pixel: sum c8 a8 for r, g, b, sum a8; and the tail's count (unused where the tails are
// pooled: then TAIL_WORDS words after a pixel's k slots, its count n - k, read_tail).
@group(0) @binding(3) var<storage, read_write> tail: array<u32>;
@group(0) @binding(4) var<storage, read_write> tail_count: array<u32>;
@group(0) @binding(5) var<storage, read_write> image: array<vec4<f32>>;
// n(p), two to a word (counts.wgsl), read where the tails are pooled; a pixel that appended took
// its count down to 0 as its cursor (capture.wgsl), and it is put back here (count_put: the
// word's other half is its neighbour's, put back by another invocation).
@group(0) @binding(6) var<storage, read_write> count: array<atomic<u32>>;

// Pixel p's count.
fn count_of(p: u32) -> u32 {
    return count_in(atomicLoad(&count[count_word(p)]), p);
}

// Pixel p's count made n (from c, what it holds now), its neighbour's half untouched: the
// difference added in u32, which wraps to a subtraction where n < c and never crosses a half.
fn count_put(p: u32, c: u32, n: u32) {
    if (c != n) {
        atomicAdd(&count[count_word(p)], (n - c) * count_unit(p));
    }
}
// The pixels over MAX_FRAGMENTS_PER_PIXEL (common.wgsl's STATUS_WORDS), from the fragments the
// capture saw (its cursor, or the slots filled and the tail's count), so it holds whatever n(p)
// the frame was given. The flags (loop limits) are not set here.
@group(0) @binding(7) var<storage, read_write> status: array<atomic<u32>, STATUS_WORDS>;

// Where the frame stores tint words (common.wgsl's stores_tints), the tint pass's words
// (kbuffer_tint.wgsl: each slot's complemented tint word, and three sums a tail of what its
// tints take away, common.wgsl's tint_word and tail_tint_word); else an unused buffer.
@group(0) @binding(10) var<storage, read_write> tints: array<u32>;

// Slot s's tint word (the tint RGB8, the colour's exponent above it; CLEAR where the frame
// stores none).
fn tint_of(s: u32) -> u32 {
    if (!stores_tints()) {
        return CLEAR;
    }
    return ~tints[tint_word(s)];
}

// The slots blend_slots found filled.
var<private> filled: u32 = 0u;

// Where the pixel's pooled tail starts in `slots` (params.pooled_tail), or NO_TAIL: it keeps
// none (k = n), or the tails are per pixel; and its count, n - k.
const NO_TAIL: u32 = 0xffffffffu;
var<private> pooled_at: u32 = NO_TAIL;
var<private> pooled_count: u32 = 0u;

// Pixel p's tail: sum c8 a8 for r, g, b, sum a8, and its count, from the tail's buffers or the
// pool.
struct Tail {
    sums: vec4<u32>,
    count: u32,
}

fn read_tail(p: u32) -> Tail {
    if (params.pooled_tail == 0u) {
        return Tail(vec4<u32>(tail[4u * p], tail[4u * p + 1u], tail[4u * p + 2u], tail[4u * p + 3u]), tail_count[p]);
    }
    let t = pooled_at;
    if (t == NO_TAIL) {
        return Tail(vec4<u32>(0u), 0u);
    }
    let rg = slots[t];
    let ba = slots[t + 1u];
    return Tail(vec4<u32>(rg.x, rg.y, ba.x, ba.y), pooled_count);
}

// Whether a pixel that saw `n` fragments is over MAX_FRAGMENTS_PER_PIXEL (then recorded).
fn too_deep(p: u32, n: u32) -> bool {
    if (n > MAX_FRAGMENTS_PER_PIXEL) {
        atomicMax(&status[STATUS_DEEPEST_PIXEL], p);
        atomicMax(&status[STATUS_DEEPEST_COUNT], n);
        return true;
    }
    return false;
}

// Whether the frame's budget holds every fragment, so k(p) = n(p) for every pixel (a pipeline
// of its own, defined true (wgsl::shaders::Pass::defines), beside capture.wgsl's, for the allocated k-buffers
// alone): k is the slot bases' difference, no pixel keeps a tail, and only the appended pixels
// (at most APPEND_MAX fragments) are sorted, their counts put back: EVERY_FRAGMENT_FITS, a
// definition the pass composes in.

// The keys of slots [base, base + n) in decreasing order (nearest first), by insertion (at most
// APPEND_MAX (APPEND_MAX - 1) / 2 steps); where the frame stores tint words, those moved with
// them. The sort is stable, and the tint pass left the words of equal keys in their slots'
// order, smallest first (kbuffer_tint.wgsl's oit_appended): they stay in order.
fn sort_slots(base: u32, n: u32) {
    let tinted = stores_tints();
    for (var i = 1u; i < n; i++) {
        let key = slots[base + i];
        var g = 0u;
        if (tinted) {
            g = tints[tint_word(base + i)];
        }
        var j = i;
        while (j > 0u && key_less(slots[base + j - 1u], key)) {
            slots[base + j] = slots[base + j - 1u];
            if (tinted) {
                tints[tint_word(base + j)] = tints[tint_word(base + j - 1u)];
            }
            j--;
        }
        slots[base + j] = key;
        if (tinted) {
            tints[tint_word(base + j)] = g;
        }
    }
}

// The slots [base, base + k) front to back (up to the first empty one) over `under`.
fn blend_slots(p: u32, base: u32, k: u32, under: vec3<f32>) -> vec4<f32> {
    var c = vec3<f32>(0.0);
    var t = vec3<f32>(1.0);
    for (var i = 0u; i < k; i++) {
        let at = slot_at(base, i, p);
        let s = slots[at];
        if (all(s == vec2<u32>(0u))) {
            break;
        }
        filled += 1u;
        let word = tint_of(at);
        let rgba = stored_colour(slot_rgba8(s.x), word);
        c += t * rgba.a * rgba.rgb;
        // (1 - a) g: 1 - a exactly where the glass is grey (CLEAR's g is 1).
        t *= tint_transmittance(rgba, word);
    }
    return vec4<f32>(c + t * under, 1.0);
}

// A pixel's colour over `bg`, or ok false where it saw more fragments than any method takes
// (the frame is refused: status[1]).
struct Resolved {
    ok: bool,
    color: vec4<f32>,
}

fn resolve_pixel(p: u32, bg: vec3<f32>) -> Resolved {
    if (EVERY_FRAGMENT_FITS) {
        // The bases hold spans of k = n, no tail; the count the capture took down as its
        // cursor put back.
        let base = slot_base[p];
        let n = slot_base[p + 1u] - base;
        count_put(p, count_of(p), n);
        if (too_deep(p, n)) {
            return Resolved(false, vec4<f32>(0.0));
        }
        if (n <= APPEND_MAX) {
            sort_slots(base, n);
        }
        return Resolved(true, blend_slots(p, base, n, bg));
    }
    var k = params.k_uniform;
    var base = p * params.k_uniform;
    if (k == 0u) {
        base = slot_base[p];
        k = slot_base[p + 1u] - base;
        if (params.pooled_tail != 0u) {
            // A span below n holds a tail (its count n - k); else the pixel holds its n = span
            // fragments, and where it appended (k <= APPEND_MAX) the capture took its count
            // down to 0: put back, and its slots sorted.
            let span = k;
            let c = count_of(p);
            if (span < c) {
                k = k_of_span(span, c);
                pooled_at = base + k;
                pooled_count = c - k;
            } else {
                count_put(p, c, span);
                if (params.append != 0u && k <= APPEND_MAX) {
                    sort_slots(base, k);
                }
            }
            if (too_deep(p, max(c, span))) {
                return Resolved(false, vec4<f32>(0.0));
            }
        }
    }
    // The tail over what is behind the pixel.
    var over = bg;
    let tl = read_tail(p);
    let tail_n = tl.count;
    let sum_a = tl.sums.w;
    // What its tints take away per channel (composite::Tail::absorbed), where tinted.
    var absorbed = vec3<u32>(0u);
    if (params.tinted != 0u && tail_n > 0u) {
        let at = tail_tint_word(p, pooled_at);
        absorbed = vec3<u32>(tints[at], tints[at + 1u], tints[at + 2u]);
    }
    let tinted_tail = any(absorbed != vec3<u32>(0u));
    if (tail_n > 0u && (sum_a > 0u || tinted_tail)) {
        let n = f32(tail_n);
        let a_avg = min(f32(sum_a) / (255.0 * n), 1.0);
        let a_tail = 1.0 - pow(1.0 - a_avg, n);
        var inv = 0.0;
        if (sum_a > 0u) {
            inv = 1.0 / (255.0 * f32(sum_a));
        }
        let c_tail = vec3<f32>(f32(tl.sums.x), f32(tl.sums.y), f32(tl.sums.z)) * inv;
        // Per channel t_avg^n, t_avg the mean of (1 - a) g: the clear tints' sum
        // 255 (255 n - sum a8) less what the tints take away.
        var through = vec3<f32>(1.0 - a_tail);
        if (tinted_tail) {
            let sum_t = vec3<u32>(255u * (255u * tail_n - sum_a)) - absorbed;
            through = pow(min(vec3<f32>(sum_t) / (255.0 * 255.0 * n), vec3<f32>(1.0)), vec3<f32>(n));
        }
        over = a_tail * c_tail + through * bg;
    }
    let color = blend_slots(p, base, k, over);
    // Where the capture inserted: every fragment is in a slot or in the tail.
    too_deep(p, filled + tail_n);
    return Resolved(true, color);
}

@compute @workgroup_size(PIXEL_GROUP)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let r = resolve_pixel(p, behind(p));
    if (r.ok) {
        image[p] = r.color;
    }
}

// An application's frame (gpu::KBufferOit::resolve): over its own image `under`, onto its
// target; the slots and the tail are left as the capture filled them, and cleared by the
// application's next frame (KBufferOit::clear).
@group(0) @binding(8) var under: texture_2d<f32>;
@group(0) @binding(9) var onto_target: OntoTexture;

@compute @workgroup_size(PIXEL_GROUP)
fn onto(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let xy = vec2<u32>(p % params.width, p / params.width);
    let r = resolve_pixel(p, textureLoad(under, xy, 0).rgb);
    if (r.ok) {
        textureStore(onto_target, xy, r.color);
    }
}
