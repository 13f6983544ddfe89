// dhoit's budgeted linked list, for an application's fragment shader (gpu::ListOit::wgsl):
// its bindings at the group the application chose (OIT_GROUP), and `oit_store`, which its
// transparent fragment shader calls with the fragment's position and straight (not
// premultiplied) colour. The fragment takes the next node while the pool lasts and becomes its
// pixel's head, exactly as dhoit's own store pass (list_store.wgsl). The occluder is the
// application's opaque depth, bound here and tested as dhoit's own passes test theirs
// (oit_fragment.wgsl). Needs SHADER_INT64 in the module.

struct OitParams {
    width: u32,
    nodes: u32,
    _pad0: u32,
    _pad1: u32,
};

@group(OIT_GROUP) @binding(0) var<storage, read_write> oit_heads: array<atomic<u32>>;
@group(OIT_GROUP) @binding(1) var<storage, read_write> oit_next: array<u32>;
@group(OIT_GROUP) @binding(2) var<storage, read_write> oit_keys: array<u64>;
@group(OIT_GROUP) @binding(3) var<storage, read_write> oit_counter: array<atomic<u32>, 4>;
@group(OIT_GROUP) @binding(4) var<uniform> oit_params: OitParams;
// The application's opaque depth (1 where nothing opaque covers a pixel).
@group(OIT_GROUP) @binding(5) var oit_opaque_depth: texture_depth_2d;

// Hands the fragment at `frag_coord` (the fragment's @builtin(position)) with straight colour
// `color` to dhoit. A fragment whose opacity rounds to 0 is not stored, as dhoit's own passes.
fn oit_store(frag_coord: vec4<f32>, color: vec4<f32>) {
    let key = oit_fragment_key(frag_coord, color);
    if (key == 0lu) {
        return;
    }
    let node = atomicAdd(&oit_counter[0], 1u);
    if (node >= oit_params.nodes) {
        return;
    }
    oit_keys[node] = key;
    oit_next[node] = atomicExchange(&oit_heads[oit_pixel(frag_coord, oit_params.width)], node + 1u);
}
