// What the A-buffer's list resolves share (the exact sort and blend, MLAB's rows, WBOIT's sums;
// prepended to each): their bindings, a pixel's stored range, the per-pixel insertion sort and
// the image write. The sort runs in place over `keys[start..end)` (each the 64-bit capture key,
// depth bits high and RGBA8 low), front to back by key for the exact blend and WBOIT (equal keys
// are equal fragments: any order blends alike, as fragment::sort_front_to_back), submission order
// for MLAB (the `primitives` sorted alongside, each fragment's submission index, which the
// A-buffer stores only for MLAB and the tests' readback). Every step ticks the loop counter
// (lavapipe's limit, see common.wgsl).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> offsets: array<u32>;
@group(0) @binding(2) var<storage, read_write> keys: array<vec2<u32>>;
// Submission indices, where the store kept them (params.store_primitives): sorted alongside.
@group(0) @binding(5) var<storage, read_write> primitives: array<u32>;
// Tint words (common.wgsl's stores_tints: the tint RGB8, the colour's exponent in the top
// byte), where the store kept them: sorted alongside, breaking ties between equal keys before
// the submission index.
@group(0) @binding(6) var<storage, read_write> tints: array<u32>;

// Fragment i's tint word (CLEAR where the frame stores none).
fn tint_at(i: u32) -> u32 {
    if (stores_tints()) {
        return tints[i];
    }
    return CLEAR;
}

@group(0) @binding(3) var<storage, read_write> image: array<vec4<f32>>;
// STATUS_NEAR_LOOP where a pixel's sort came close to lavapipe's loop limit, STATUS_POOL_SHORT
// where the pool held fewer fragments than the frame; the pixels over MAX_FRAGMENTS_PER_PIXEL
// (common.wgsl's STATUS_WORDS).
@group(0) @binding(4) var<storage, read_write> status: array<atomic<u32>, STATUS_WORDS>;

// Pixel p's stored fragments, keys[start..end).
struct Stored {
    p: u32,
    start: u32,
    end: u32,
    // False past the frame's last pixel, and where the pixel holds more than
    // MAX_FRAGMENTS_PER_PIXEL: the frame is refused (its depth is reported), and no sort of that
    // length runs.
    ok: bool,
}

// The pixel of an invocation of a resolve (dispatched as wgsl::grid's 2-D grid) and its stored
// range.
fn stored(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> Stored {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return Stored(p, 0u, 0u, false);
    }
    let start = offsets[p];
    let end = offsets[p + 1u];
    // A pool sized before the count (an application's frame, from an earlier frame's) that
    // holds fewer fragments than the frame has: the pixels past its end stored none
    // (abuffer_store.wgsl), so they hold none here, and the frame says so.
    if (end > arrayLength(&keys)) {
        atomicOr(&status[0], STATUS_POOL_SHORT);
        return Stored(p, start, start, true);
    }
    if (end - start > MAX_FRAGMENTS_PER_PIXEL) {
        atomicMax(&status[STATUS_DEEPEST_PIXEL], p);
        atomicMax(&status[STATUS_DEEPEST_COUNT], end - start);
        return Stored(p, start, end, false);
    }
    return Stored(p, start, end, true);
}

// Whether the pixel's loops came close to the device's limit.
fn report_loops() {
    if (ticks > LOOP_BUDGET) {
        atomicOr(&status[0], STATUS_NEAR_LOOP);
    }
}

// The pixel's colour into the image, and whether its loops came close to the device's limit.
fn write_pixel(p: u32, c: vec3<f32>) {
    report_loops();
    image[p] = vec4<f32>(c, 1.0);
}

// An application's frame (gpu::ExactOit::resolve, the `onto` entries): over its own image
// `under`, onto its target.
@group(0) @binding(8) var under: texture_2d<f32>;
@group(0) @binding(9) var onto_target: OntoTexture;

// What the application's image holds at pixel p.
fn under_pixel(p: u32) -> vec3<f32> {
    return textureLoad(under, vec2<u32>(p % params.width, p / params.width), 0).rgb;
}

// The pixel's colour onto the application's target.
fn write_onto(p: u32, c: vec3<f32>) {
    report_loops();
    textureStore(onto_target, vec2<u32>(p % params.width, p / params.width), vec4<f32>(c, 1.0));
}

// Front to back by key, then tint; with `with_primitives` the submission indices move
// alongside and break the remaining ties, as fragment::sort_front_to_back (the tests read them
// back). The tints move alongside where the frame stores them.
fn sort_keys(start: u32, end: u32, with_primitives: bool) {
    let with_tints = stores_tints();
    for (var i = start + 1u; i < end; i++) {
        tick();
        let k = keys[i];
        let g = tint_at(i);
        var q = 0u;
        if (with_primitives) {
            q = primitives[i];
        }
        var j = i;
        loop {
            if (j <= start) {
                break;
            }
            let before = keys[j - 1u];
            var after = key_less(k, before);
            if (all(k == before)) {
                let gb = tint_at(j - 1u);
                after = g < gb || (g == gb && with_primitives && q < primitives[j - 1u]);
            }
            if (!after) {
                break;
            }
            tick();
            keys[j] = before;
            if (with_primitives) {
                primitives[j] = primitives[j - 1u];
            }
            if (with_tints) {
                tints[j] = tints[j - 1u];
            }
            j--;
        }
        keys[j] = k;
        if (with_primitives) {
            primitives[j] = q;
        }
        if (with_tints) {
            tints[j] = g;
        }
    }
}

fn sort_by_submission(start: u32, end: u32) {
    for (var i = start + 1u; i < end; i++) {
        tick();
        let k = keys[i];
        let q = primitives[i];
        let g = tint_at(i);
        var j = i;
        while (j > start && q < primitives[j - 1u]) {
            tick();
            keys[j] = keys[j - 1u];
            primitives[j] = primitives[j - 1u];
            if (stores_tints()) {
                tints[j] = tints[j - 1u];
            }
            j--;
        }
        keys[j] = k;
        primitives[j] = q;
        if (stores_tints()) {
            tints[j] = g;
        }
    }
}

// The resolve's two entries, over each pixel's stored fragments: dhoit's own frame (over what
// is behind the pixel, into the image) and an application's (over its image `under`, onto its
// target). `list_color(list, bg)`, the pixel's colour over bg, is the pass's own.
@compute @workgroup_size(PIXEL_GROUP)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let list = stored(wid, nwg, lid);
    if (list.ok) {
        write_pixel(list.p, list_color(list, behind(list.p)));
    }
}

@compute @workgroup_size(PIXEL_GROUP)
fn onto(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let list = stored(wid, nwg, lid);
    if (list.ok) {
        write_onto(list.p, list_color(list, under_pixel(list.p)));
    }
}
