// MLAB from the A-buffer (compute, one invocation a pixel): the pixel's stored fragments are
// sorted into submission order (insertion sort by submission index), then inserted one by one
// into m blending rows of premultiplied colour, transmittance and depth key (a bubble pass into
// m + 1 rows, then the last two merged), and the rows blended over what is behind the pixel
// (behind.wgsl), as composite::mlab_pixel.

// Its bindings, the pixel's stored range, the image write and its entries (`main`, and `onto`
// for an application's frame) are sort.wgsl's.

struct Row {
    a: vec3<f32>,
    // Transmittance, per channel.
    t: vec3<f32>,
    z: vec2<u32>,
};

// The pixel's stored fragments, sorted into submission order, through m rows, over `bg`.
fn list_color(list: Stored, bg: vec3<f32>) -> vec3<f32> {
    let start = list.start;
    let end = list.end;
    sort_by_submission(start, end);
    let m = clamp(params.k_uniform, 1u, MLAB_MAX_ROWS);
    var rows: array<Row, MLAB_MAX_ROWS + 1u>;
    for (var r = 0u; r <= m; r++) {
        tick();
        rows[r] = Row(vec3<f32>(0.0), vec3<f32>(1.0), vec2<u32>(0xffffffffu));
    }
    for (var i = start; i < end; i++) {
        tick();
        let key = keys[i];
        let word = tint_at(i);
        let rgba = stored_colour(key.x, word);
        var cur = Row(rgba.rgb * rgba.a, tint_transmittance(rgba, word), key);
        for (var r = 0u; r < m; r++) {
            tick();
            if (!key_less(rows[r].z, cur.z)) {
                let tmp = rows[r];
                rows[r] = cur;
                cur = tmp;
            }
        }
        rows[m] = cur;
        let front = rows[m - 1u];
        let back = rows[m];
        rows[m - 1u] = Row(front.a + back.a * front.t, front.t * back.t, front.z);
        rows[m] = Row(vec3<f32>(0.0), vec3<f32>(1.0), vec2<u32>(0xffffffffu));
    }
    var c = vec3<f32>(0.0);
    var t = vec3<f32>(1.0);
    for (var r = 0u; r < m; r++) {
        tick();
        c += t * rows[r].a;
        t *= rows[r].t;
    }
    return c + t * bg;
}
