// DKB importance (compute): the 12 features of importance::pixel_features from the features
// pass's statistics and the totals, computed here and never stored, standardised, through the
// MLP of mlp.wgsl (the same source `dhoit predict --device gpu` runs). Four entry points in
// one compute pass, sharing one explicit layout (gpu::Pipelines::network_layout):
//   select:  one invocation a pixel: a pixel the network decides is appended to a list (its
//            index; the list lives in the frame's shared word, dead until then), every other
//            pixel gets its importance here (0, or its pair mark where forced);
//   args:    the list's length -> the workgroups of an indirect dispatch (a 2-D grid);
//   network: one invocation a listed pixel: its features again, the network, its importance;
//   gather:  one invocation a pixel: its importance into the shared word.
// A pixel's importance waits in its nearest key's place (read by then), so DKB needs no buffer
// of its own for the list or the importance.
// So the network's invocations all run it (no forced pixel idles a SIMD lane), and a frame whose
// pixels are all forced never enters the network's code.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> count: array<u32>;
// Per pixel: the nearest key (complemented); the two farthest keys (features.wgsl).
// The nearest keys are read_write: once a pixel's features are read, its importance takes its
// nearest key's place (set_importance), and `gather` moves it to the frame's shared word.
@group(0) @binding(3) var<storage, read_write> nearest: array<u64>;
@group(0) @binding(4) var<storage, read> farthest: array<u64>;
@group(0) @binding(5) var<storage, read> sums: array<u32>;
@group(0) @binding(6) var<storage, read> totals: array<u32>;
// The pixels the network decides (the frame's shared word, Recording::pixel_word, dead until
// then), and how many (list_len[0]); then, after `gather`, every pixel's importance.
@group(0) @binding(8) var<storage, read_write> list: array<u32>;
@group(0) @binding(9) var<storage, read_write> list_len: array<atomic<u32>, 4>;
// The network entry's indirect dispatch: workgroups x, y, z.
@group(0) @binding(10) var<storage, read_write> dispatch: array<u32, DISPATCH_WORDS>;
// Per pixel: the sums of optical depth and 8-bit opacity (features.wgsl).
@group(0) @binding(12) var<storage, read> opacity: array<u32>;

// Skip the network where k does not depend on it (Mlp::dkb_importance): a pixel whose useful
// cap is the frame's smallest k, lo (mlp::forced: n <= lo + 1, or lo + 2 where its two farthest
// fragments share one colour; lo is 1 where F covers every covered pixel, as at 2 fpp) gets
// importance 0 with its pair mark. The bench builds this pass once more with it false
// (Gpu::skip_forced) to show the time saved. Every pixel of a frame whose budget holds all its fragments gets 0, unmarked,
// either way: its features pass drew nothing (features.wgsl), and k = n whatever it gets.
const SKIP_FORCED: bool = true;

// Sum r, g, b of pixel p's fragments (features.wgsl's packing: r and g 24 bits each in the first
// 64-bit word, then n; b in the second's low half).
fn color_sums(p: u32) -> vec3<u32> {
    let lo = sums[4u * p];
    let hi = sums[4u * p + 1u];
    return vec3<u32>(lo & 0xffffffu, (lo >> 24u) | ((hi & 0xffffu) << 8u), sums[4u * p + 2u]);
}

fn luma(c: vec3<f32>) -> f32 {
    return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
}

// A pixel's network inputs (importance::pixel_features), or, where the network is not run (an
// uncovered or forced pixel), its importance written here and `runs` false.
struct Net {
    x: array<f32, FEATURES>,
    mark: u32,
    runs: bool,
}

// Pixel p's importance, in its nearest key's place: only p's own invocation reads that key, and
// it has read it by now.
fn set_importance(p: u32, v: f32) {
    nearest[p] = u64(bitcast<u32>(v));
}

fn network_inputs(p: u32) -> Net {
    var net: Net;
    let c = count[p];
    if (c == 0u || holds_every_fragment(totals[0])) {
        set_importance(p, 0.0);
        return net;
    }
    // The sign bit marks a pixel whose two farthest fragments share one colour
    // (importance::tail_pair, alloc::mark_pair): the allocation lets it use a slot fewer.
    let f0 = farthest[2u * p];
    let f1 = farthest[2u * p + 1u];
    let pair = (f1 & OCCUPIED) != 0lu && u32(f0 & 0xfffffffflu) == u32(f1 & 0xfffffffflu);
    let mark = select(0u, PAIR_BIT, pair);
    // alloc::min_k, as the allocation's setup finds it.
    let lo = select(0u, 1u, budget_of(totals[0]) >= u64(totals[1]));
    if (SKIP_FORCED && c <= lo + 1u + select(0u, 1u, pair)) {
        set_importance(p, bitcast<f32>(mark));
        return net;
    }
    // importance::pixel_features, operation for operation.
    let total = f32(max(totals[0], 1u));
    let covered = f32(max(totals[1], 1u));
    let nf = f32(c);
    let key = ~nearest[p];
    let near8 = u32(key & 0xfffffffflu);
    let near = unpack_rgba8(near8).rgb;
    let sum = color_sums(p);
    let mean = vec3<f32>(f32(sum.r) / 255.0 / nf, f32(sum.g) / 255.0 / nf, f32(sum.b) / 255.0 / nf);
    // n^2 var and n^2 dev in 8-bit units, exact integers.
    var var_num = i64(c) * i64(sums[4u * p + 3u]);
    var dev_num = 0li;
    for (var ch = 0u; ch < 3u; ch++) {
        let s = i64(sum[ch]);
        var_num -= s * s;
        let d = i64(c) * i64((near8 >> (8u * ch)) & 0xffu) - s;
        dev_num += d * d;
    }
    let scale = nf * nf * 65025.0;
    let variance = f32(max(var_num, 0li)) / scale;
    let dev = f32(dev_num) / scale;
    let mean_luma = luma(mean);
    let near_luma = luma(near);
    let tau = f32(opacity[2u * p]) * OPTICAL_DEPTH_UNIT;
    net.x = array<f32, FEATURES>(
        log2(nf),
        nf / (total / covered),
        f32(budget_of(totals[0])) / total,
        log2(f32(max(budget_of(totals[0]), 1lu)) / covered),
        bitcast<f32>(u32(key >> 32u)),
        f32(near8 >> 24u) / 255.0,
        log2(variance + LOG_FLOOR),
        log2(dev + LOG_FLOOR),
        f32(opacity[2u * p + 1u]) / 255.0 / nf,
        mean_luma,
        near_luma,
        log2(tau + OPTICAL_DEPTH_UNIT),
    );
    net.runs = true;
    net.mark = mark;
    return net;
}

@compute @workgroup_size(PIXEL_GROUP)
fn select_pixels(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    if (network_inputs(p).runs) {
        list[atomicAdd(&list_len[0], 1u)] = p;
    }
}

@compute @workgroup_size(1)
fn args() {
    let groups = (atomicLoad(&list_len[0]) + PIXEL_GROUP - 1u) / PIXEL_GROUP;
    // Rows of at most 65,535 workgroups (gpu::grid).
    let rows = max((groups + 65534u) / 65535u, 1u);
    dispatch[0] = (groups + rows - 1u) / rows;
    dispatch[1] = select(0u, rows, groups > 0u);
    dispatch[2] = 1u;
}

@compute @workgroup_size(PIXEL_GROUP)
fn network(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = grid_index(wid, nwg, lid, PIXEL_GROUP);
    let listed = i < atomicLoad(&list_len[0]);
    var p = 0u;
    var net: Net;
    if (listed) {
        p = list[i];
        net = network_inputs(p);
    }
    if (SHARED_WEIGHTS) {
        // Every invocation of the workgroup stages the weights, listed or not.
        let out = mlp_forward_shared(net.x, net.runs, lid);
        if (net.runs) {
            set_importance(p, bitcast<f32>(bitcast<u32>(out) | net.mark));
        }
    } else if (net.runs) {
        set_importance(p, bitcast<f32>(bitcast<u32>(mlp_forward(net.x)) | net.mark));
    }
}

// Every pixel's importance from its nearest key's place into the shared word, where the
// allocation reads it (the list there is read by now).
@compute @workgroup_size(PIXEL_GROUP)
fn gather(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p < params.pixels) {
        list[p] = u32(nearest[p] & 0xfffffffflu);
    }
}
