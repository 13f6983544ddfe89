// DKB features pass (geometry): per pixel, with integer atomics only (so any order gives the
// same result), the statistics importance::pixel_stats gathers beside the count: the nearest
// fragment's capture key, and the sums of the fragments' 8-bit R, G, B and of r^2 + g^2 + b^2.
// The nearest key is kept complemented so a cleared (zero) buffer means "none yet" and
// atomicMax finds the minimum. The two largest keys (the farthest fragments) are kept by a
// two-slot insertion with atomicMax, each key marked with bit 63 (importance::OCCUPIED) so a
// slot is never mistaken for empty. 40 bytes a pixel, which the tail and the image reuse.
//
// The frame counts its fragments first (abuffer_count.wgsl) and draws this pass indirectly
// (totals.wgsl's features_draw): with no vertex when the budget holds every fragment, since then
// k = n whatever the network says (gpu::DkbGeometry). Built with COUNT_FRAGMENTS,
// the pass counts too and runs always (no count pass first; the bench's comparison).
//
// Three atomic adds a fragment, and atomicMax only where it can change a key: the colour sums,
// the count and the opacity statistics go in three 64-bit adds, and the keys only grow, so a key that the stored one
// already beats is skipped after a plain atomic load, as Loop64's early test does. The first
// word holds sum r (bits 0-23), sum g (24-47) and, where this pass counts, n (48-63): exact up
// to raster::MAX_FRAGMENTS_PER_PIXEL fragments (255 x 65,535 < 2^24), past which the resolve
// refuses the frame whatever n the passes before it were given (resolve.wgsl's too_deep). The
// second holds sum b (low half, at most 255 n) and sum (r^2 + g^2 + b^2) (high half, wrapping
// as a 32-bit sum does). A word in a buffer of its own holds the opacity statistics: the sum
// of the fragments' optical depths from importance::optical_depth_table (low half) and of
// their 8-bit opacities (high). No buffer above 16 bytes a pixel, so a 4K frame fits 128 MiB
// bindings.

// Per pixel: the nearest key (complemented); the frame reuses this buffer for the tail's count
// once the importance pass has read it.
@group(1) @binding(0) var<storage, read_write> nearest: array<atomic<u64>>;
// Per pixel: the two largest keys, farthest first; reused for the tail's sums.
@group(1) @binding(1) var<storage, read_write> farthest: array<atomic<u64>>;
// Per pixel: sum r, sum g and n; sum b and sum (r^2 + g^2 + b^2); 8-bit units, as above
// (importance_dkb.wgsl's color_sums and totals.wgsl's from_sums read them as 32-bit words).
// Reused for the image.
@group(1) @binding(2) var<storage, read_write> sums: array<atomic<u64>>;
// A fragment's optical depth by its 8-bit opacity (importance::optical_depth_table), four to a
// vec4.
@group(1) @binding(3) var<uniform> optical_depth: array<vec4<u32>, 64>;
// Per pixel: the sum of optical depths (low half) and of 8-bit opacities (high half).
@group(1) @binding(4) var<storage, read_write> opacity: array<atomic<u64>>;


// Whether the nearest key is loaded first, and atomicMax issued only where it can change it
// (gpu::Gpu::features_preload): fewer atomics, but the load waits for its value, where a GPU
// issues an atomicMax whose result is unused without waiting.
const PRELOAD_NEAREST: bool = true;

// Whether this pass counts the fragments (no count pass before it): n in the first sums word,
// which totals.wgsl's from_sums writes out as the count.
const COUNT_FRAGMENTS: bool = false;

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        return vec4<f32>(0.0);
    }
    let p = pixel_index(in.clip, params.width);
    let rgba8 = f.rgba8;
    let depth = select(0.0, in.clip.z, in.clip.z > 0.0);
    let key = fragment_key(depth, rgba8);
    if (!PRELOAD_NEAREST || atomicLoad(&nearest[p]) < ~key) {
        atomicMax(&nearest[p], ~key);
    }
    // Insertion into two slots kept in decreasing order: the larger key stays, the smaller
    // moves on; a key that finds an empty slot stops there. A key no greater than the second
    // slot changes neither.
    var carry = key | OCCUPIED;
    if (atomicLoad(&farthest[2u * p + 1u]) < carry) {
        for (var i = 0u; i < 2u; i++) {
            let old = atomicMax(&farthest[2u * p + i], carry);
            if (old == 0lu) {
                break;
            }
            carry = min(old, carry);
        }
    }
    let r = rgba8 & 0xffu;
    let g = (rgba8 >> 8u) & 0xffu;
    let b = (rgba8 >> 16u) & 0xffu;
    let a = rgba8 >> 24u;
    let counted = select(0lu, 1lu << 48u, COUNT_FRAGMENTS);
    atomicAdd(&sums[2u * p], u64(r) | (u64(g) << 24u) | counted);
    atomicAdd(&sums[2u * p + 1u], u64(b) | (u64(r * r + g * g + b * b) << 32u));
    atomicAdd(&opacity[p], u64(optical_depth[a >> 2u][a & 3u]) | (u64(a) << 32u));
    return vec4<f32>(0.0);
}
