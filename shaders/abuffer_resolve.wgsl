// A-buffer pass 3 (compute, one invocation a pixel): sort the pixel's capture keys front to back
// in place (sort.wgsl's insertion sort) and blend them exactly over what is behind the pixel
// (behind.wgsl), as composite::exact_sorted.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> offsets: array<u32>;
@group(0) @binding(2) var<storage, read_write> keys: array<u64>;
// Submission indices, where the store kept them (params.store_primitives): sorted alongside.
@group(0) @binding(5) var<storage, read_write> primitives: array<u32>;
@group(0) @binding(3) var<storage, read_write> image: array<vec4<f32>>;
// Set to 1 when a pixel's sort came close to lavapipe's loop limit; the deepest pixel over
// MAX_FRAGMENTS_PER_PIXEL (common.wgsl's deepest_word).
@group(0) @binding(4) var<storage, read_write> status: array<atomic<u64>, 2>;

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
    sort_keys(start, end, params.store_primitives != 0u);
    var c = vec3<f32>(0.0);
    var t = 1.0;
    for (var i = start; i < end; i++) {
        tick();
        let rgba = unpack_rgba8(u32(keys[i] & 0xfffffffflu));
        c += t * rgba.a * rgba.rgb;
        t *= 1.0 - rgba.a;
    }
    if (ticks > LOOP_BUDGET) {
        atomicMax(&status[0], 1lu);
    }
    image[p] = vec4<f32>(c + t * behind(p), 1.0);
}
