// WBOIT from the A-buffer (compute, one invocation a pixel): the pixel's stored capture keys are
// sorted front to back (sort.wgsl's insertion sort: a fixed order for the float sums, so the
// image does not depend on submission), then weighted and summed as McGuire and Bavoil's
// accumulation and revealage targets would hold them, and resolved over what is behind the
// pixel (behind.wgsl), as composite::wboit_sorted.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> offsets: array<u32>;
@group(0) @binding(2) var<storage, read_write> keys: array<u64>;
// Submission indices, where the store kept them (params.store_primitives): sorted alongside.
@group(0) @binding(5) var<storage, read_write> primitives: array<u32>;
@group(0) @binding(3) var<storage, read_write> image: array<vec4<f32>>;
// Set to 1 when a pixel's sort came close to lavapipe's loop limit; the deepest pixel over
// MAX_FRAGMENTS_PER_PIXEL (common.wgsl's deepest_word).
@group(0) @binding(4) var<storage, read_write> status: array<atomic<u64>, 2>;

// Their eq. 10: a max(10^-2, 3 10^3 (1 - z)^3), z the window depth (composite::wboit_weight).
fn weight(z: f32, a: f32) -> f32 {
    let d = 1.0 - z;
    return a * max(3e3 * d * d * d, 1e-2);
}

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
    let start = offsets[p];
    let end = offsets[p + 1u];
    if (end - start > MAX_FRAGMENTS_PER_PIXEL) {
        // The frame is refused: no sort of that length.
        atomicMax(&status[1], deepest_word(end - start, p));
        return;
    }
    if (end == start) {
        image[p] = vec4<f32>(behind(p), 1.0);
        return;
    }
    sort_keys(start, end, params.store_primitives != 0u);
    var acc = vec3<f32>(0.0);
    var acc_a = 0.0;
    var reveal = 1.0;
    for (var i = start; i < end; i++) {
        tick();
        let key = keys[i];
        let rgba = unpack_rgba8(u32(key & 0xfffffffflu));
        let w = weight(bitcast<f32>(u32(key >> 32u)), rgba.a);
        acc += rgba.rgb * rgba.a * w;
        acc_a += rgba.a * w;
        reveal *= 1.0 - rgba.a;
    }
    if (ticks > LOOP_BUDGET) {
        atomicMax(&status[0], 1lu);
    }
    let inv = 1.0 / clamp(acc_a, 1e-4, 5e4);
    image[p] = vec4<f32>(acc * inv * (1.0 - reveal) + reveal * behind(p), 1.0);
}
