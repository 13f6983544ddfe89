// DKB features pass (geometry): per pixel, with atomics only (so any order gives the same
// result), the statistics importance::pixel_stats gathers: fragment count, nearest and farthest
// window depth, the nearest fragment's capture key, and fixed-point sums of RGB, luminance and
// squared luminance. Nearest depth and key are kept complemented so a cleared (zero) buffer
// means "none yet" and atomicMax finds the minimum.

@group(1) @binding(0) var<storage, read_write> count: array<atomic<u32>>;
@group(1) @binding(1) var<storage, read_write> near_inv: array<atomic<u32>>;
@group(1) @binding(2) var<storage, read_write> far: array<atomic<u32>>;
@group(1) @binding(3) var<storage, read_write> nearest_inv: array<atomic<u64>>;
// Per pixel: r, g, b, luminance, squared luminance (fixed point, 12 fractional bits).
@group(1) @binding(4) var<storage, read_write> sums: array<atomic<u32>>;

fn to_fixed(v: f32) -> u32 {
    return u32(floor(clamp(v, 0.0, 1.0) * 4096.0 + 0.5));
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let p = pixel_index(in.clip, params.width);
    let rgba8 = fragment_rgba8(in.color);
    let c = unpack_rgba8(rgba8);
    let depth = select(0.0, in.clip.z, in.clip.z > 0.0);
    atomicAdd(&count[p], 1u);
    atomicMax(&near_inv[p], ~bitcast<u32>(depth));
    atomicMax(&far[p], bitcast<u32>(depth));
    atomicMax(&nearest_inv[p], ~fragment_key(depth, rgba8));
    let l = 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
    atomicAdd(&sums[5u * p], to_fixed(c.r));
    atomicAdd(&sums[5u * p + 1u], to_fixed(c.g));
    atomicAdd(&sums[5u * p + 2u], to_fixed(c.b));
    atomicAdd(&sums[5u * p + 3u], to_fixed(l));
    atomicAdd(&sums[5u * p + 4u], to_fixed(l * l));
    return vec4<f32>(0.0);
}
