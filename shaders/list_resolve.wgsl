// The budgeted linked list's resolve (compute, one invocation a pixel): the pixel's list is
// walked once; its nearest params.list_sorted keys are kept sorted in private memory (each
// arriving key inserted, the one it pushes past the last place, or itself, added to the tail's
// integer sums, as composite::Tail adds), then blended front to back over the tail's
// approximation over what is behind the pixel (behind.wgsl; an application's own image in
// `onto`): composite::hybrid_sorted of the kept fragments with k = list_sorted. Where the
// frame's glass is tinted (params.tinted), each node's tint moves with its key, breaks ties
// between equal keys (fragment::sort_front_to_back) and filters per channel, the tail by its
// integer sums of (255 - a8) g8 as composite::Tail adds them.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> heads: array<u32>;
@group(0) @binding(2) var<storage, read> next: array<u32>;
@group(0) @binding(3) var<storage, read> keys: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read_write> image: array<vec4<f32>>;
// Set to 1 when a pixel's walk came close to lavapipe's loop limit; the pixels over
// MAX_FRAGMENTS_PER_PIXEL (common.wgsl's STATUS_WORDS).
@group(0) @binding(5) var<storage, read_write> status: array<atomic<u32>, STATUS_WORDS>;
// Per node, its tint word where the frame stores them (common.wgsl's stores_tints).
@group(0) @binding(8) var<storage, read> tints: array<u32>;

// A node's key and tint.
struct Near {
    key: vec2<u32>,
    tint: u32,
};

// Whether a orders before b: by key, then tint.
fn near_less(a: Near, b: Near) -> bool {
    return key_less(a.key, b.key) || (all(a.key == b.key) && a.tint < b.tint);
}

// A pixel's colour over `bg`, or ok false where its list is deeper than any method takes (the
// frame is refused: status[1]).
struct Resolved {
    ok: bool,
    color: vec3<f32>,
}

fn list_color(p: u32, bg: vec3<f32>) -> Resolved {
    let s = params.list_sorted;
    var near: array<Near, LIST_MAX_SORTED>;
    var held = 0u;
    // Sum c8 a8 for r, g, b; sum a8; the count.
    var sums = vec4<u32>(0u);
    // Sum (255 - a8) g8 per channel, and whether a tinted fragment joined.
    var through = vec3<u32>(0u);
    var tinted = false;
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
        var carry = Near(keys[node - 1u], CLEAR);
        if (stores_tints()) {
            carry.tint = tints[node - 1u];
        }
        node = next[node - 1u];
        // Insertion into the sorted places: a key nearer than the last moves it on.
        if (held < s) {
            var j = held;
            while (j > 0u && near_less(carry, near[j - 1u])) {
                tick();
                near[j] = near[j - 1u];
                j--;
            }
            near[j] = carry;
            held++;
            continue;
        }
        if (near_less(carry, near[s - 1u])) {
            let out = near[s - 1u];
            var j = s - 1u;
            while (j > 0u && near_less(carry, near[j - 1u])) {
                tick();
                near[j] = near[j - 1u];
                j--;
            }
            near[j] = carry;
            carry = out;
        }
        sums = add_tail_sums(sums, carry.key.x, carry.tint);
        let g = vec3<u32>(carry.tint & 0xffu, (carry.tint >> 8u) & 0xffu, (carry.tint >> 16u) & 0xffu);
        through += (255u - (carry.key.x >> 24u)) * g;
        tinted = tinted || filters(carry.tint);
        tail_n++;
    }
    // composite::Tail::over, then the sorted places front to back.
    var over = bg;
    if (tail_n > 0u && (sums.w > 0u || tinted)) {
        let n = f32(tail_n);
        let a_avg = min(f32(sums.w) / (255.0 * n), 1.0);
        let a_tail = 1.0 - pow(1.0 - a_avg, n);
        var inv = 0.0;
        if (sums.w > 0u) {
            inv = 1.0 / (255.0 * f32(sums.w));
        }
        var seen = vec3<f32>(1.0 - a_tail);
        if (tinted) {
            seen = pow(min(vec3<f32>(through) / (255.0 * 255.0 * n), vec3<f32>(1.0)), vec3<f32>(n));
        }
        over = a_tail * (vec3<f32>(sums.xyz) * inv) + seen * bg;
    }
    var c = vec3<f32>(0.0);
    var t = vec3<f32>(1.0);
    for (var i = 0u; i < held; i++) {
        let rgba = stored_colour(near[i].key.x, near[i].tint);
        c += t * rgba.a * rgba.rgb;
        t *= tint_transmittance(rgba, near[i].tint);
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

// An application's frame (gpu::ListOit's resolve): over its own image `under`, onto its target.
@group(0) @binding(6) var under: texture_2d<f32>;
@group(0) @binding(7) var onto_target: OntoTexture;

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
