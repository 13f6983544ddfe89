// VKB count pass (geometry): per pixel the fragment count (two to a word, counts.wgsl) and the
// nearest fragment, as (depth bits, |n . v| bits) kept complemented so a cleared buffer means
// "none yet".

@group(1) @binding(0) var<storage, read_write> count: array<atomic<u32>>;
@group(1) @binding(1) var<storage, read_write> nearest_inv: array<atomic<u64>>;

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    if (!transparent_fragment(in, front).visible) {
        return vec4<f32>(0.0);
    }
    let p = pixel_index(in.clip, params.width);
    let depth = select(0.0, in.clip.z, in.clip.z > 0.0);
    let w = count_word(p);
    if (count_stopped(atomicAdd(&count[w], count_unit(p)), p)) {
        atomicSub(&count[w], count_unit(p));
    }
    atomicMax(&nearest_inv[p], ~((u64(bitcast<u32>(depth)) << 32u) | u64(bitcast<u32>(in.facing))));
    return vec4<f32>(0.0);
}
