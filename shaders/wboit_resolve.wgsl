// WBOIT from the A-buffer (compute, one invocation a pixel): the pixel's stored capture keys are
// sorted front to back (sort.wgsl's insertion sort: a fixed order for the float sums, so the
// image does not depend on submission), then weighted and summed as McGuire and Bavoil's
// accumulation and revealage targets would hold them, and resolved over what is behind the
// pixel (behind.wgsl), as composite::wboit_sorted.

// Its bindings, the pixel's stored range and the image write are sort.wgsl's.

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
    let list = stored(wid, nwg, lid);
    if (!list.ok) {
        return;
    }
    let p = list.p;
    let start = list.start;
    let end = list.end;
    if (end == start) {
        write_pixel(p, behind(p));
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
    let inv = 1.0 / clamp(acc_a, 1e-4, 5e4);
    write_pixel(p, acc * inv * (1.0 - reveal) + reveal * behind(p));
}
