// What an application's fragment hands dhoit (gpu::ListOit::wgsl, gpu::KBufferOit::wgsl): its
// 64-bit capture key, as dhoit's own passes make it. The module that includes it declares
// `oit_opaque_depth`, the application's opaque depth (1 where nothing opaque covers a pixel).

// 8-bit unorm with rounding half up (common.wgsl's to_unorm8).
fn oit_unorm8(v: f32) -> u32 {
    return u32(floor(clamp(v, 0.0, 1.0) * 255.0 + 0.5));
}

// The key of the fragment at `frag_coord` (its @builtin(position)) with straight colour `color`:
// window depth bits high and RGBA8 low (common.wgsl's fragment_key), or 0 where dhoit keeps
// nothing of it: its opacity rounds to 0, or it lies at or behind the opaque depth. (A pipeline
// depth test would not do: a fragment shader that writes storage is depth-tested after it ran,
// unless forced early, which needs a feature.)
fn oit_fragment_key(frag_coord: vec4<f32>, color: vec4<f32>) -> u64 {
    let rgba8 = oit_unorm8(color.r) | (oit_unorm8(color.g) << 8u) | (oit_unorm8(color.b) << 16u)
        | (oit_unorm8(color.a) << 24u);
    if ((rgba8 >> 24u) == 0u) {
        return 0lu;
    }
    if (frag_coord.z >= textureLoad(oit_opaque_depth, vec2<u32>(frag_coord.xy), 0)) {
        return 0lu;
    }
    let d = select(0.0, frag_coord.z, frag_coord.z > 0.0);
    return (u64(bitcast<u32>(d)) << 32u) | u64(rgba8);
}

// The pixel at `frag_coord` in a frame `width` pixels wide.
fn oit_pixel(frag_coord: vec4<f32>, width: u32) -> u32 {
    return u32(frag_coord.y) * width + u32(frag_coord.x);
}

// The fragment with its triangle's facing `|n . v|`, which only VKB reads (gpu::AllocatedOit):
// every method's module has it, so one application shader serves them all.
fn oit_store_facing(frag_coord: vec4<f32>, color: vec4<f32>, facing: f32) {
    oit_store(frag_coord, color);
}
