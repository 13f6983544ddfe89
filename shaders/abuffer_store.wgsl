// A-buffer pass 2 (geometry): store every fragment in its pixel's slice of the fragment pool as
// its 64-bit capture key (window depth bits high, RGBA8 low: the k-buffer's slot, 8 bytes a
// fragment), where params.store_primitives is 1 (MLAB, which blends in submission order, and
// the tests' readback) its submission index beside it, and where the frame stores them
// (common.wgsl's stores_tints) its tint word.

@group(1) @binding(0) var<storage, read> offsets: array<u32>;
// The count pass's buffer, cleared after the prefix sum read it: each pixel's next place (two
// to a word, as the counts: counts.wgsl). A cursor that stopped, in a pixel too deep for any
// method (which the resolve refuses), stores nothing more.
@group(1) @binding(1) var<storage, read_write> cursor: array<atomic<u32>>;
@group(1) @binding(2) var<storage, read_write> keys: array<vec2<u32>>;
@group(1) @binding(3) var<storage, read_write> primitives: array<u32>;
@group(1) @binding(4) var<storage, read_write> tints: array<u32>;

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        return vec4<f32>(0.0);
    }
    let p = pixel_index(in.clip, params.width);
    let w = count_word(p);
    let old = atomicAdd(&cursor[w], count_unit(p));
    if (count_stopped(old, p)) {
        atomicSub(&cursor[w], count_unit(p));
        return vec4<f32>(0.0);
    }
    // A pixel whose fragments the pool does not hold whole (sized before the count, from an
    // earlier frame's) stores none: sort.wgsl's `stored` reports it.
    if (offsets[p + 1u] > arrayLength(&keys)) {
        return vec4<f32>(0.0);
    }
    let i = offsets[p] + count_in(old, p);
    keys[i] = key_of(in.clip.z, f.rgba8);
    if (params.store_primitives != 0u) {
        primitives[i] = in.primitive;
    }
    if (stores_tints()) {
        tints[i] = f.tint;
    }
    return vec4<f32>(0.0);
}
