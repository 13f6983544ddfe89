// VKB count pass (geometry): per pixel the fragment count (two to a word, counts.wgsl) and the
// nearest fragment's 32-bit key (importance::vkb_nearest_key: the depth's bits above bit 6
// high, |n . v| in 8 bits low), kept complemented so a cleared buffer means "none yet", in
// the frame's shared word a pixel (oit.offsets, cleared before), where the importance pass
// reads it and writes the pixel's importance in its place.

@group(1) @binding(0) var<storage, read_write> count: array<atomic<u32>>;
@group(1) @binding(1) var<storage, read_write> nearest_inv: array<atomic<u32>>;

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    if (!transparent_fragment(in, front).visible) {
        return vec4<f32>(0.0);
    }
    let p = pixel_index(in.clip, params.width);
    let depth = select(0.0, min(in.clip.z, 1.0), in.clip.z > 0.0);
    let facing = u32(round(clamp(in.facing, 0.0, 1.0) * 255.0));
    let w = count_word(p);
    if (count_stopped(atomicAdd(&count[w], count_unit(p)), p)) {
        atomicSub(&count[w], count_unit(p));
    }
    atomicMax(&nearest_inv[p], ~(((bitcast<u32>(depth) >> 6u) << 8u) | facing));
    return vec4<f32>(0.0);
}
