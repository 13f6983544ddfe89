// A-buffer pass 3 (compute, one invocation a pixel): sort the pixel's capture keys front to back
// in place (sort.wgsl's insertion sort) and blend them exactly over what is behind the pixel
// (behind.wgsl), as composite::exact_sorted.

// Its bindings, the pixel's stored range and the image write are sort.wgsl's.

// The pixel's stored fragments, sorted in place, blended front to back over `bg`.
fn exact_color(list: Stored, bg: vec3<f32>) -> vec3<f32> {
    sort_keys(list.start, list.end, params.store_primitives != 0u);
    var c = vec3<f32>(0.0);
    var t = 1.0;
    for (var i = list.start; i < list.end; i++) {
        tick();
        let rgba = unpack_rgba8(u32(keys[i] & 0xfffffffflu));
        c += t * rgba.a * rgba.rgb;
        t *= 1.0 - rgba.a;
    }
    return c + t * bg;
}

@compute @workgroup_size(PIXEL_GROUP)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let list = stored(wid, nwg, lid);
    if (list.ok) {
        write_pixel(list.p, exact_color(list, behind(list.p)));
    }
}

// An application's frame (gpu::ExactOit::resolve): over its own image `under`, onto its target.
@group(0) @binding(8) var under: texture_2d<f32>;
@group(0) @binding(9) var onto_target: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(PIXEL_GROUP)
fn onto(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let list = stored(wid, nwg, lid);
    if (list.ok) {
        let xy = vec2<u32>(list.p % params.width, list.p / params.width);
        let c = exact_color(list, textureLoad(under, xy, 0).rgb);
        if (ticks > LOOP_BUDGET) {
            atomicMax(&status[0], 1lu);
        }
        textureStore(onto_target, xy, vec4<f32>(c, 1.0));
    }
}
