// k-buffer capture (geometry): insert every fragment into its pixel's k slots without locks.
// Slots hold the bitwise complement of the capture key (so a cleared, zero slot is empty and
// atomicMax keeps the nearest): for each slot, old = atomicMax(slot, cur); an empty old ends the
// insertion, otherwise the farther of the two is carried on. A key still carried after the last
// slot is the one fragment this insertion pushed out; it goes to the tail's integer sums. Every
// fragment ends in a slot or in the tail exactly once, in any submission order, and the slots
// end sorted front to back.

@group(1) @binding(0) var<storage, read> k_of: array<u32>;
@group(1) @binding(1) var<storage, read> slot_base: array<u32>;
@group(1) @binding(2) var<storage, read_write> slots: array<atomic<u64>>;
// Per pixel: sum c8 a8 for r, g, b, sum a8, count.
@group(1) @binding(3) var<storage, read_write> tail: array<atomic<u32>>;

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let p = pixel_index(in.clip, params.width);
    var k = params.k_uniform;
    var base = p * params.k_uniform;
    if (k == 0u) {
        k = k_of[p];
        base = slot_base[p];
    }
    var cur = ~fragment_key(in.clip.z, fragment_rgba8(in));
    for (var i = 0u; i < k; i++) {
        let old = atomicMax(&slots[base + i], cur);
        if (old == 0lu) {
            return vec4<f32>(0.0);
        }
        cur = min(old, cur);
    }
    let c = (~cur) & 0xfffffffflu;
    let rgba = u32(c);
    let a = rgba >> 24u;
    atomicAdd(&tail[5u * p], (rgba & 0xffu) * a);
    atomicAdd(&tail[5u * p + 1u], ((rgba >> 8u) & 0xffu) * a);
    atomicAdd(&tail[5u * p + 2u], ((rgba >> 16u) & 0xffu) * a);
    atomicAdd(&tail[5u * p + 3u], a);
    atomicAdd(&tail[5u * p + 4u], 1u);
    return vec4<f32>(0.0);
}
