// DKB features pass (geometry): per pixel of more than TAIL_WORDS fragments (its record:
// records.wgsl, the marks of totals.wgsl's mark_records), with 32-bit integer atomics only (so
// any order gives the same result, on any device, in one pass), the statistics
// importance::pixel_stats gathers beside the count: the nearest fragment's two nearest words
// (importance::near_words: its 16-bit depth above two of its channels, its opacity what its
// tint lets through: filtered_rgba8), and the sums of the fragments' 8-bit R, G, B and of
// r^2 + g^2 + b^2. A pixel of fewer has no record: it keeps all its fragments whatever its k
// (shared::stored_k), its k is forced (mlp::forced), so nothing is gathered for it. The nearest
// words are kept complemented so a cleared (zero) word means "none yet" and atomicMax finds the
// minimum. RECORD_WORDS (4) 64-bit words a record, in the slot pool, which the capture clears
// and fills once the importance pass has read them.
//
// Built twice. As a pass of its own (with features_batch.wgsl: gpu::Phase::Features), after the
// frame's count, for the records its own count marks (a frame's first, one after a cut, a frame
// whose records take batches). And as the count (with features_count.wgsl: gpu::Phase::
// CountFeatures, every DKB frame's count pass), for the records the frame before marked: a frame of a
// stream of frames gathers its statistics there and draws no features pass (its geometry is drawn
// twice, the count and the capture, and three times with the portable capture). A pixel the
// frame before did not mark has no statistics then, and the network does not decide it
// (importance_dkb.wgsl's gather: the least weight).
//
// Two atomicMax a fragment, each only where it can change its word (a word the stored one
// already beats is skipped after a plain atomic load, as Loop64's early test does), and three
// 64-bit sums, each added as two 32-bit halves, the low half's carry into the high half, as a
// 64-bit add would. The colour sums' first word holds sum r (bits 0-23), sum g (24-47) and n
// (48-63, written by totals.wgsl's record_counts): exact up to raster::MAX_FRAGMENTS_PER_PIXEL
// fragments (255 x 32,767 < 2^24), past which the resolve refuses the frame (resolve.wgsl's
// too_deep). The second holds sum b (low half, at most 255 n) and sum (r^2 + g^2 + b^2) (high
// half, wrapping as a 32-bit sum does). The last holds the opacity statistics: the sum of the
// fragments' optical depths from importance::optical_depth_table (low half) and of their 8-bit
// opacities (high), each opacity its tint's too (filtered_alpha8).

// The marks that give each pixel its record (records.wgsl's record_index: RECORD_WORDS words in
// the slot pool for each pixel of more than TAIL_WORDS fragments, in pixel order).
@group(1) @binding(0) var<storage, read> record_marks: array<u32>;
// RECORD_WORDS 64-bit words a record (importance::pixel_stats of its pixel), each two 32-bit
// words (low, high), in the slot pool until the capture: the two nearest words (complemented),
// the colour sums (sum r, sum g and n, which totals.wgsl's record_counts writes; sum b and sum
// (r^2 + g^2 + b^2)) and the opacity sums.
@group(1) @binding(1) var<storage, read_write> records: array<atomic<u32>>;
// A fragment's optical depth by its 8-bit opacity (importance::optical_depth_table), four to a
// vec4.
@group(1) @binding(2) var<uniform> optical_depth: array<vec4<u32>, 64>;
// PRELOAD_NEAREST (a definition the pass composes in): whether each nearest word is loaded first, and atomicMax issued only where it can change it
// (gpu::Gpu::features_preload): fewer atomics, but the load waits for its value, where a GPU
// issues an atomicMax whose result is unused without waiting.

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        return vec4<f32>(0.0);
    }
    let p = pixel_index(in.clip, params.width);
    // The fragment counted and its pixel's record where this is the count (features_count.wgsl),
    // its pixel's record of the batch where it is a features pass (features_batch.wgsl).
    let r = fragment_record(p);
    if (r == NO_RECORD) {
        return vec4<f32>(0.0);
    }
    let depth = select(0.0, in.clip.z, in.clip.z > 0.0);
    record_fragment(RECORD_WORDS * r, depth, f.rgba8, f.tint);
    return vec4<f32>(0.0);
}

// A fragment of window depth `depth`, colour `rgba8` and tint word `tint` into the record at
// 64-bit word `at`.
fn record_fragment(at: u32, depth: f32, rgba8: u32, tint: u32) {
    let near = near_words(depth, filtered_rgba8(rgba8, tint));
    for (var w = 0u; w < 2u; w++) {
        let word = ~near[w];
        if (!PRELOAD_NEAREST || atomicLoad(&records[2u * at + w]) < word) {
            atomicMax(&records[2u * at + w], word);
        }
    }
    let sums = fragment_sums(rgba8, tint);
    for (var w = 0u; w < 3u; w++) {
        record_add(at + 1u + w, sums[w]);
    }
}

// The record's 64-bit word i plus the 64-bit value v (low, high halves).
fn record_add(i: u32, v: vec2<u32>) {
    let old = atomicAdd(&records[2u * i], v.x);
    let carry = select(0u, 1u, old + v.x < old);
    if (v.y + carry != 0u) {
        atomicAdd(&records[2u * i + 1u], v.y + carry);
    }
}

// importance::near_words: the fragment's 16-bit depth (`depth 65535` truncated) above its
// opacity and red, then above its green and blue.
fn near_words(depth: f32, rgba8: u32) -> vec2<u32> {
    let d = u32(depth * NEAR_DEPTH_STEPS) << 16u;
    let r = rgba8 & 0xffu;
    let g = (rgba8 >> 8u) & 0xffu;
    let b = (rgba8 >> 16u) & 0xffu;
    let a = rgba8 >> 24u;
    return vec2<u32>(d | (a << 8u) | r, d | (g << 8u) | b);
}

// The 8-bit opacity the features read for a fragment of 8-bit opacity `a8` and tint word `tint`
// (importance::filtered_alpha8): 255 minus what it lets through in its most transparent channel,
// `(255 - a8) max(g) / 255` rounded to the nearest; `a8` itself for a CLEAR tint.
fn filtered_alpha8(a8: u32, tint: u32) -> u32 {
    let most = max(tint & 0xffu, max((tint >> 8u) & 0xffu, (tint >> 16u) & 0xffu));
    return 255u - ((255u - a8) * most + 127u) / 255u;
}

// A fragment's RGBA8 with its opacity as the features read it (filtered_alpha8): what its
// nearest words hold of it (importance::filtered_rgba8).
fn filtered_rgba8(rgba8: u32, tint: u32) -> u32 {
    return (rgba8 & 0xffffffu) | (filtered_alpha8(rgba8 >> 24u, tint) << 24u);
}

// What a fragment of colour `rgba8` and tint word `tint` adds to its record's three sum words,
// each as two 32-bit halves (low, high): sum r (bits 0-23) and g (24-47), n above them
// untouched; sum b and r^2 + g^2 + b^2; its optical depth and 8-bit opacity, its tint included
// (filtered_alpha8).
fn fragment_sums(rgba8: u32, tint: u32) -> array<vec2<u32>, 3> {
    let cr = rgba8 & 0xffu;
    let cg = (rgba8 >> 8u) & 0xffu;
    let cb = (rgba8 >> 16u) & 0xffu;
    let a = filtered_alpha8(rgba8 >> 24u, tint);
    return array<vec2<u32>, 3>(
        vec2<u32>(cr | (cg << 24u), 0u),
        vec2<u32>(cb, cr * cr + cg * cg + cb * cb),
        vec2<u32>(optical_depth[a >> 2u][a & 3u], a),
    );
}
