// The budgeted linked list's resolve (compute, one invocation a pixel): the pixel's list is
// walked once; its nearest params.list_sorted keys are kept sorted in private memory (each
// arriving key inserted, the one it pushes past the last place, or itself, added to the tail's
// integer sums, as composite::Tail adds), then blended front to back over the tail's
// approximation over what is behind the pixel (behind.wgsl; an application's own image in
// `onto`): composite::hybrid_sorted of the kept fragments with k = list_sorted.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> heads: array<u32>;
@group(0) @binding(2) var<storage, read> next: array<u32>;
@group(0) @binding(3) var<storage, read> keys: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read_write> image: array<vec4<f32>>;
// Set to 1 when a pixel's walk came close to lavapipe's loop limit; the pixels over
// MAX_FRAGMENTS_PER_PIXEL (common.wgsl's STATUS_WORDS).
@group(0) @binding(5) var<storage, read_write> status: array<atomic<u32>, STATUS_WORDS>;

// A pixel's colour over `bg`, or ok false where its list is deeper than any method takes (the
// frame is refused: status[1]).
struct Resolved {
    ok: bool,
    color: vec3<f32>,
}

fn list_color(p: u32, bg: vec3<f32>) -> Resolved {
    let s = params.list_sorted;
    var near: array<vec2<u32>, LIST_MAX_SORTED>;
    var held = 0u;
    // Sum c8 a8 for r, g, b; sum a8; the count.
    var sums = vec4<u32>(0u);
    var tail_n = 0u;
    var node = heads[p];
    var n = 0u;
    loop {
        if (node == 0u) {
            break;
        }
        tick();
        n++;
        if (n > MAX_FRAGMENTS_PER_PIXEL) {
            atomicMax(&status[STATUS_DEEPEST_PIXEL], p);
            atomicMax(&status[STATUS_DEEPEST_COUNT], n);
            return Resolved(false, bg);
        }
        var carry = keys[node - 1u];
        node = next[node - 1u];
        // Insertion into the sorted places: a key nearer than the last moves it on.
        if (held < s) {
            var j = held;
            while (j > 0u && key_less(carry, near[j - 1u])) {
                tick();
                near[j] = near[j - 1u];
                j--;
            }
            near[j] = carry;
            held++;
            continue;
        }
        if (key_less(carry, near[s - 1u])) {
            let out = near[s - 1u];
            var j = s - 1u;
            while (j > 0u && key_less(carry, near[j - 1u])) {
                tick();
                near[j] = near[j - 1u];
                j--;
            }
            near[j] = carry;
            carry = out;
        }
        sums += tail_sums_of(carry.x);
        tail_n++;
    }
    // composite::Tail::over, then the sorted places front to back.
    var over = bg;
    if (tail_n > 0u && sums.w > 0u) {
        let a_avg = min(f32(sums.w) / (255.0 * f32(tail_n)), 1.0);
        let a_tail = 1.0 - pow(1.0 - a_avg, f32(tail_n));
        let inv = 1.0 / (255.0 * f32(sums.w));
        over = a_tail * (vec3<f32>(sums.xyz) * inv) + (1.0 - a_tail) * bg;
    }
    var c = vec3<f32>(0.0);
    var t = 1.0;
    for (var i = 0u; i < held; i++) {
        let rgba = unpack_rgba8(near[i].x);
        c += t * rgba.a * rgba.rgb;
        t *= 1.0 - rgba.a;
    }
    if (ticks > LOOP_BUDGET) {
        atomicOr(&status[0], STATUS_NEAR_LOOP);
    }
    return Resolved(true, c + t * over);
}

// dhoit's own frames: over what is behind the pixel, into the image buffer.
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
    let r = list_color(p, behind(p));
    if (r.ok) {
        image[p] = vec4<f32>(r.color, 1.0);
    }
}

// An application's frame (gpu::ListOit::resolve): over its own image `under`, onto its target.
@group(0) @binding(6) var under: texture_2d<f32>;
@group(0) @binding(7) var onto_target: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(PIXEL_GROUP)
fn onto(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let xy = vec2<u32>(p % params.width, p / params.width);
    let bg = textureLoad(under, xy, 0).rgb;
    let r = list_color(p, bg);
    if (r.ok) {
        textureStore(onto_target, xy, vec4<f32>(r.color, 1.0));
    }
}
