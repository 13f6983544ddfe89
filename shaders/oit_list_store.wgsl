// dhoit's budgeted linked list, for an application's fragment shader (gpu::ListOit::wgsl):
// its bindings at the group the application chose (OIT_GROUP), and `oit_store`, which its
// transparent fragment shader calls with the fragment's position and straight (not
// premultiplied) colour. The fragment takes the next node while the pool lasts and becomes its
// pixel's head, exactly as dhoit's own store pass (list_store.wgsl). The occluder is the
// application's opaque depth, bound here and tested in `oit_store` as dhoit's own passes test
// theirs (geometry.wgsl's transparent_fragment): a fragment at or behind it is not stored. (A
// pipeline depth test would not do: a fragment shader that writes storage is depth-tested
// after it ran, unless forced early, which needs a feature.) Needs SHADER_INT64 in the module.

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

// 8-bit unorm with rounding half up (common.wgsl's to_unorm8).
fn oit_unorm8(v: f32) -> u32 {
    return u32(floor(clamp(v, 0.0, 1.0) * 255.0 + 0.5));
}

// Hands the fragment at `frag_coord` (the fragment's @builtin(position)) with straight colour
// `color` to dhoit: its 64-bit key, window depth bits high and RGBA8 low (common.wgsl's
// fragment_key). A fragment whose opacity rounds to 0 is not stored, as dhoit's own passes.
fn oit_store(frag_coord: vec4<f32>, color: vec4<f32>) {
    let rgba8 = oit_unorm8(color.r) | (oit_unorm8(color.g) << 8u) | (oit_unorm8(color.b) << 16u)
        | (oit_unorm8(color.a) << 24u);
    if ((rgba8 >> 24u) == 0u) {
        return;
    }
    if (frag_coord.z >= textureLoad(oit_opaque_depth, vec2<u32>(frag_coord.xy), 0)) {
        return;
    }
    let node = atomicAdd(&oit_counter[0], 1u);
    if (node >= oit_params.nodes) {
        return;
    }
    let d = select(0.0, frag_coord.z, frag_coord.z > 0.0);
    let p = u32(frag_coord.y) * oit_params.width + u32(frag_coord.x);
    oit_keys[node] = (u64(bitcast<u32>(d)) << 32u) | u64(rgba8);
    oit_next[node] = atomicExchange(&oit_heads[p], node + 1u);
}
