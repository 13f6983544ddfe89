// A-buffer pass 1 (geometry): count the visible transparent fragments of every pixel, two
// counts to a word (counts.wgsl).

@group(1) @binding(0) var<storage, read_write> counts: array<atomic<u32>>;

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    if (!transparent_fragment(in, front).visible) {
        return vec4<f32>(0.0);
    }
    let p = pixel_index(in.clip, params.width);
    let w = count_word(p);
    if (count_stopped(atomicAdd(&counts[w], count_unit(p)), p)) {
        atomicSub(&counts[w], count_unit(p));
    }
    return vec4<f32>(0.0);
}
