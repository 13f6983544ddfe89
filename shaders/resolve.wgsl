// k-buffer resolve (compute, one invocation a pixel): the core slots blended front to back,
// then the tail approximated over the background, as composite::hybrid_sorted with
// composite::Tail.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> k_of: array<u32>;
@group(0) @binding(2) var<storage, read> slot_base: array<u32>;
@group(0) @binding(3) var<storage, read> slots: array<u64>;
@group(0) @binding(4) var<storage, read> tail: array<u32>;
@group(0) @binding(5) var<storage, read_write> image: array<vec4<f32>>;

@compute @workgroup_size(PIXEL_GROUP)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    var k = params.k_uniform;
    var base = p * params.k_uniform;
    if (k == 0u) {
        k = k_of[p];
        base = slot_base[p];
    }
    // The tail over the background.
    let bg = params.background.rgb;
    var behind = bg;
    let count = tail[5u * p + 4u];
    let sum_a = tail[5u * p + 3u];
    if (count > 0u && sum_a > 0u) {
        let a_avg = min(f32(sum_a) / (255.0 * f32(count)), 1.0);
        let a_tail = 1.0 - pow(1.0 - a_avg, f32(count));
        let inv = 1.0 / (255.0 * f32(sum_a));
        let c_tail = vec3<f32>(f32(tail[5u * p]), f32(tail[5u * p + 1u]), f32(tail[5u * p + 2u])) * inv;
        behind = a_tail * c_tail + (1.0 - a_tail) * bg;
    }
    var c = vec3<f32>(0.0);
    var t = 1.0;
    for (var i = 0u; i < k; i++) {
        let s = slots[base + i];
        if (s == 0lu) {
            break;
        }
        let rgba = unpack_rgba8(u32((~s) & 0xfffffffflu));
        c += t * rgba.a * rgba.rgb;
        t *= 1.0 - rgba.a;
    }
    image[p] = vec4<f32>(c + t * behind, 1.0);
}
