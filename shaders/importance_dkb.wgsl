// DKB importance (compute, one invocation a pixel): the 12 features of
// importance::pixel_features from the features pass's statistics and the totals, computed here
// and never stored, standardised, through the
// MLP (ReLU, ReLU, sigmoid) whose weights sit in a uniform buffer, as mlp::Mlp::forward.
// Layout of the weights (floats): h1, h2, unused, unused, mean[12], std[12], fc1.weight
// [12][h1], fc1.bias[h1], fc2.weight[h1][h2], fc2.bias[h2], out.weight[h2], out.bias.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> weights: array<vec4<f32>, 2504>;
@group(0) @binding(2) var<storage, read> count: array<u32>;
// Per pixel: the nearest key (complemented), the two farthest keys (features.wgsl).
@group(0) @binding(3) var<storage, read> keys: array<u64>;
@group(0) @binding(4) var<storage, read> sums: array<u32>;
@group(0) @binding(5) var<storage, read> totals: array<u32>;
@group(0) @binding(6) var<storage, read_write> importance: array<f32>;

// importance::OCCUPIED.
const OCCUPIED: u64 = 0x8000000000000000lu;

// importance::LOG_FLOOR.
const LOG_FLOOR: f32 = 1e-6;

fn luma(c: vec3<f32>) -> f32 {
    return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
}

// Largest second hidden layer the pass holds (mlp::MAX_H2).
const MAX_H2: u32 = 128u;

fn w(i: u32) -> f32 {
    return weights[i >> 2u][i & 3u];
}

@compute @workgroup_size(64)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, 64u);
    if (p >= params.pixels) {
        return;
    }
    let c = count[p];
    if (c == 0u) {
        importance[p] = 0.0;
        return;
    }
    // importance::pixel_features, operation for operation.
    let total = f32(max(totals[0], 1u));
    let covered = f32(max(totals[1], 1u));
    let nf = f32(c);
    let key = ~keys[3u * p];
    let near8 = u32(key & 0xfffffffflu);
    let near = unpack_rgba8(near8).rgb;
    let sum = vec3<u32>(sums[4u * p], sums[4u * p + 1u], sums[4u * p + 2u]);
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
    var x = array<f32, 12>(
        log2(nf),
        nf / (total / covered),
        f32(budget_of(totals[0])) / total,
        log2(f32(max(budget_of(totals[0]), 1lu)) / covered),
        bitcast<f32>(u32(key >> 32u)),
        near_luma - mean_luma,
        log2(variance + LOG_FLOOR),
        log2(dev + LOG_FLOOR),
        sqrt(variance),
        mean_luma,
        near_luma,
        sqrt(dev),
    );
    let h1 = u32(w(0u));
    let h2 = u32(w(1u));
    for (var i = 0u; i < 12u; i++) {
        x[i] = (x[i] - w(4u + i)) / w(16u + i);
    }
    let w1 = 28u;
    let b1 = w1 + 12u * h1;
    let w2 = b1 + h1;
    let b2 = w2 + h1 * h2;
    let w3 = b2 + h2;
    let b3 = w3 + h2;
    // One hidden unit of the first layer at a time, accumulated straight into the second
    // layer's sums: a private array of h2 floats instead of h1 (the order of the sums per
    // output unit is the same as the CPU twin's).
    var acc2: array<f32, MAX_H2>;
    for (var j = 0u; j < h2; j++) {
        acc2[j] = w(b2 + j);
    }
    for (var i = 0u; i < h1; i++) {
        var acc = w(b1 + i);
        for (var f = 0u; f < 12u; f++) {
            acc += x[f] * w(w1 + f * h1 + i);
        }
        let a = max(acc, 0.0);
        if (a != 0.0) {
            for (var j = 0u; j < h2; j++) {
                acc2[j] += a * w(w2 + i * h2 + j);
            }
        }
    }
    var out = w(b3);
    for (var j = 0u; j < h2; j++) {
        out += max(acc2[j], 0.0) * w(w3 + j);
    }
    // The sign bit marks a pixel whose two farthest fragments share one colour
    // (importance::tail_pair, alloc::mark_pair): the allocation lets it use a slot fewer.
    let f0 = keys[3u * p + 1u];
    let f1 = keys[3u * p + 2u];
    let pair = (f1 & OCCUPIED) != 0lu && u32(f0 & 0xfffffffflu) == u32(f1 & 0xfffffffflu);
    // mlp::squash: 0 where the sums overflowed both ways.
    let s = 1.0 / (1.0 + exp(-out));
    let i = select(0.0, s, s == s);
    importance[p] = bitcast<f32>(bitcast<u32>(i) | select(0u, 0x80000000u, pair));
}
