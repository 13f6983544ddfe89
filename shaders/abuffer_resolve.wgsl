// A-buffer pass 3 (compute, one invocation a pixel): sort the pixel's capture keys front to back
// in place (sort.wgsl's insertion sort) and blend them exactly over what is behind the pixel
// (behind.wgsl), as composite::exact_sorted.

// Its bindings, the pixel's stored range and the image write are sort.wgsl's.

@compute @workgroup_size(PIXEL_GROUP)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let list = stored(wid, nwg, lid);
    if (!list.ok) {
        return;
    }
    let p = list.p;
    let start = list.start;
    let end = list.end;
    sort_keys(start, end, params.store_primitives != 0u);
    var c = vec3<f32>(0.0);
    var t = 1.0;
    for (var i = start; i < end; i++) {
        tick();
        let rgba = unpack_rgba8(u32(keys[i] & 0xfffffffflu));
        c += t * rgba.a * rgba.rgb;
        t *= 1.0 - rgba.a;
    }
    write_pixel(p, c + t * behind(p));
}
