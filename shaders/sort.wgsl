// The A-buffer's per-pixel insertion sort, in place over `fragments[start..end)` (each
// vec4<u32>: depth bits, RGBA8, submission index, unused), prepended to the passes that sort a
// pixel's stored fragments and declare `fragments`: front to back (capture key, then
// submission index, as fragment::sort_front_to_back) for the exact blend, submission order for
// MLAB. Every step ticks the loop counter (lavapipe's limit, see common.wgsl).

fn sorts_before(a: vec4<u32>, b: vec4<u32>, by_submission: bool) -> bool {
    if (by_submission) {
        return a.z < b.z;
    }
    let ka = fragment_key(bitcast<f32>(a.x), a.y);
    let kb = fragment_key(bitcast<f32>(b.x), b.y);
    return ka < kb || (ka == kb && a.z < b.z);
}

fn sort_pixel(start: u32, end: u32, by_submission: bool) {
    for (var i = start + 1u; i < end; i++) {
        tick();
        let f = fragments[i];
        var j = i;
        while (j > start && sorts_before(f, fragments[j - 1u], by_submission)) {
            tick();
            fragments[j] = fragments[j - 1u];
            j--;
        }
        fragments[j] = f;
    }
}
