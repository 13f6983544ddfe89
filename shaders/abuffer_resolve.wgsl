// A-buffer pass 3 (compute, one invocation a pixel): sort the pixel's capture keys front to back
// in place (sort.wgsl's insertion sort) and blend them exactly over what is behind the pixel
// (behind.wgsl), as composite::exact_sorted.

// Its bindings, the pixel's stored range, the image write and its entries (`main`, and `onto`
// for an application's frame) are sort.wgsl's.

// The pixel's stored fragments, sorted in place, blended front to back over `bg`.
fn list_color(list: Stored, bg: vec3<f32>) -> vec3<f32> {
    sort_keys(list.start, list.end, params.store_primitives != 0u);
    var c = vec3<f32>(0.0);
    var t = vec3<f32>(1.0);
    for (var i = list.start; i < list.end; i++) {
        tick();
        let word = tint_at(i);
        let rgba = stored_colour(keys[i].x, word);
        c += t * rgba.a * rgba.rgb;
        t *= tint_transmittance(rgba, word);
    }
    return c + t * bg;
}
