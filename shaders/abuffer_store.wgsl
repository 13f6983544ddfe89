// A-buffer pass 2 (geometry): store every fragment in its pixel's slice of the fragment pool.
// A stored fragment is (depth bits, RGBA8, submission index, unused).

@group(1) @binding(0) var<storage, read> offsets: array<u32>;
@group(1) @binding(1) var<storage, read_write> cursor: array<atomic<u32>>;
@group(1) @binding(2) var<storage, read_write> fragments: array<vec4<u32>>;

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        return vec4<f32>(0.0);
    }
    let p = pixel_index(in.clip, params.width);
    let i = offsets[p] + atomicAdd(&cursor[p], 1u);
    fragments[i] = vec4<u32>(bitcast<u32>(in.clip.z), f.rgba8, in.primitive, 0u);
    return vec4<f32>(0.0);
}
