// dhoit's exact A-buffer, for an application's fragment shader (gpu::ExactOit::wgsl): its
// bindings at the group the application chose (OIT_GROUP), and `oit_store`, which its
// transparent fragment shader calls with the fragment's position and straight (not
// premultiplied) colour. The application draws its transparent geometry twice, as dhoit's own
// A-buffer does (abuffer_count.wgsl, abuffer_store.wgsl), with the group ExactOit gives for
// each: the count (oit_params.phase 0) adds one to the pixel's count; after it dhoit sums the
// counts into each pixel's offset and sizes the pool to the frame's fragments (exact memory),
// and the store (phase 1) writes the key at the pixel's next place (and for MLAB, its
// submission index beside it). The occluder is the
// application's opaque depth, tested as dhoit's own passes test theirs (oit_fragment.wgsl).
// Needs SHADER_INT64 in the module.

struct OitParams {
    width: u32,
    phase: u32,
    // 1 where the store keeps each fragment's submission index (MLAB's order).
    ordered: u32,
    _pad: u32,
};

// Per pixel: the count, then (cleared after the prefix sum read it) the store's cursor, two to a
// word (counts.wgsl, which the module includes).
@group(OIT_GROUP) @binding(0) var<storage, read_write> oit_counts: array<atomic<u32>>;
// Per pixel (pixels + 1 entries): the exclusive prefix sums of the counts.
@group(OIT_GROUP) @binding(1) var<storage, read_write> oit_offsets: array<u32>;
// The frame's fragments, by pixel: their capture keys.
@group(OIT_GROUP) @binding(2) var<storage, read_write> oit_keys: array<u64>;
// Beside each key, its fragment's submission index where the store is ordered (MLAB); else
// an empty binding.
@group(OIT_GROUP) @binding(3) var<storage, read_write> oit_orders: array<u32>;
@group(OIT_GROUP) @binding(4) var<uniform> oit_params: OitParams;
// The application's opaque depth (1 where nothing opaque covers a pixel).
@group(OIT_GROUP) @binding(5) var oit_opaque_depth: texture_depth_2d;

// Hands the fragment at `frag_coord` (the fragment's @builtin(position)) with straight colour
// `color` to dhoit, `order` its submission index (MLAB blends a pixel's fragments in that
// order: the index of its triangle in the application's submission, say; the exact blend reads
// it only to break ties of equal keys, which blend alike). A fragment whose opacity rounds to 0
// is not stored, as dhoit's own passes.
fn oit_store_ordered(frag_coord: vec4<f32>, color: vec4<f32>, order: u32) {
    let key = oit_fragment_key(frag_coord, color);
    if (key == 0lu) {
        return;
    }
    let p = oit_pixel(frag_coord, oit_params.width);
    let w = count_word(p);
    let old = atomicAdd(&oit_counts[w], count_unit(p));
    if (count_stopped(old, p)) {
        atomicSub(&oit_counts[w], count_unit(p));
        return;
    }
    if (oit_params.phase != 0u) {
        let i = oit_offsets[p] + count_in(old, p);
        oit_keys[i] = key;
        if (oit_params.ordered != 0u) {
            oit_orders[i] = order;
        }
    }
}

// oit_store_ordered without an order (the exact blend needs none; MLAB does).
fn oit_store(frag_coord: vec4<f32>, color: vec4<f32>) {
    oit_store_ordered(frag_coord, color, 0u);
}
