// DKB features pass (geometry): per pixel, with integer atomics only (so any order gives the
// same result), the statistics importance::pixel_stats gathers: the fragment count, the nearest
// fragment's capture key, and the sums of the fragments' 8-bit R, G, B and of r^2 + g^2 + b^2.
// The nearest key is kept complemented so a cleared (zero) buffer means "none yet" and
// atomicMax finds the minimum. The two largest keys (the farthest fragments) are kept by a
// two-slot insertion with atomicMax, each key marked with bit 63 (importance::OCCUPIED) so a
// slot is never mistaken for empty. 44 bytes a pixel, which the tail and the image reuse.

@group(1) @binding(0) var<storage, read_write> count: array<atomic<u32>>;
// Per pixel: the nearest key (complemented), then the two largest keys, farthest first. The
// frame reuses this buffer for the tail's sums once the importance pass has read it.
@group(1) @binding(1) var<storage, read_write> keys: array<atomic<u64>>;
// Per pixel: sum r, sum g, sum b, sum (r^2 + g^2 + b^2), 8-bit units (wrapping). Reused for
// the image.
@group(1) @binding(2) var<storage, read_write> sums: array<atomic<u32>>;


@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let p = pixel_index(in.clip, params.width);
    let rgba8 = fragment_rgba8(in);
    let depth = select(0.0, in.clip.z, in.clip.z > 0.0);
    atomicAdd(&count[p], 1u);
    let key = fragment_key(depth, rgba8);
    atomicMax(&keys[3u * p], ~key);
    // Insertion into two slots kept in decreasing order: the larger key stays, the smaller
    // moves on; a key that finds an empty slot stops there.
    var carry = key | OCCUPIED;
    for (var i = 0u; i < 2u; i++) {
        let old = atomicMax(&keys[3u * p + 1u + i], carry);
        if (old == 0lu) {
            break;
        }
        carry = min(old, carry);
    }
    let r = rgba8 & 0xffu;
    let g = (rgba8 >> 8u) & 0xffu;
    let b = (rgba8 >> 16u) & 0xffu;
    atomicAdd(&sums[4u * p], r);
    atomicAdd(&sums[4u * p + 1u], g);
    atomicAdd(&sums[4u * p + 2u], b);
    atomicAdd(&sums[4u * p + 3u], r * r + g * g + b * b);
    return vec4<f32>(0.0);
}
