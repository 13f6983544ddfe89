// The importance network (mlp::Mlp::forward, operation for operation), shared by the DKB
// importance pass and the batch prediction pass: 12 standardised inputs, ReLU, ReLU, and the
// sigmoid (mlp::squash: 0 where the sums overflowed both ways). Its weights sit in a uniform
// buffer at binding 1, in 32-bit words: h1, h2, unused, unused, mean[12], std[12] (f32), then
// each layer's units padded to a multiple of four (mlp::padded_units, p1 and p2):
// fc1.weight [12][p1], fc1.bias[p1], fc2.weight[p1][p2], fc2.bias[p2], out.weight[p2],
// out.bias and three zeros: f32 words, or with F16_WEIGHTS binary16 values two to a word
// (wgsl::mlp_uniform). Four units are computed at once from one vec4 (f32) or half a vec4
// (f16) of the uniform, so no inner loop indexes into a vector: the uniform is read at
// addresses every invocation shares, a broadcast on GPUs.

@group(0) @binding(1) var<uniform> weights: array<vec4<u32>, NET_VEC4S>;

// Standardised inputs are clamped to MAX_STANDARDISED, so no sum overflows; the pass holds a
// second hidden layer of at most MAX_H2 units (both from the prelude).

// The definitions a network pass composes in (wgsl::shaders::Pass::defines; gpu::Variant
// gives a variant's): F16_WEIGHTS, the weights' precision (mlp::Precision: true for binary16);
// SHARED_WEIGHTS, whether the DKB importance pass stages the first two layers' weights in
// workgroup memory, TILE_UNITS first-layer units at a time, shared by the workgroup's pixels
// (mlp_forward_shared), instead of reading them from the uniform (gpu::Gpu::shared_weights);
// NET_P1 and NET_P2, the padded sizes (p1, p2) where the pass is built for one network shape:
// loops of known length (0: read from the uniform); ACC2_VEC4S, the second layer's sums (p2
// floats where the shape is known, else the largest network's); NET_VEC4S, the weights
// uniform's vec4s, as large as the network's (mlp::uniform_bytes): the buffer bound is sized
// to it. The forward the pass calls, mlp_forward, is composed in too: the loops below
// (wgsl::shaders::MLP_LOOP), or one written out for the network's shape.
const TILE_UNITS: u32 = 16u;
// A tile: fc1's 12 x TILE_UNITS weights (input-major), TILE_UNITS biases, then TILE_UNITS rows
// of fc2 (p2 weights each), in vec4s.
const TILE_W1: u32 = 0u;
const TILE_B1: u32 = FEATURES * TILE_UNITS / 4u;
const TILE_W2: u32 = TILE_B1 + TILE_UNITS / 4u;
var<workgroup> tile: array<vec4<f32>, TILE_W2 + TILE_UNITS * MAX_H2 / 4u>;


// Four parameters from index `i` of the unpadded-header f32 layout (a multiple of four past
// MLP_W1_AT); at f16 unpacked exactly from binary16.
fn param4(i: u32) -> vec4<f32> {
    if (F16_WEIGHTS) {
        // Word MLP_W1_AT + (i - MLP_W1_AT) / 2: an even word, the first or second half of a vec4.
        let word = MLP_W1_AT + ((i - MLP_W1_AT) >> 1u);
        let v = weights[word >> 2u];
        let pair = select(v.xy, v.zw, (word & 2u) != 0u);
        return vec4<f32>(unpack2x16float(pair.x), unpack2x16float(pair.y));
    }
    return bitcast<vec4<f32>>(weights[i >> 2u]);
}

// Adds `a` times row `row` of fc2.weight (p2 values from `row`) to the second layer's sums.
fn add_row(acc2: ptr<function, array<vec4<f32>, ACC2_VEC4S>>, a: f32, row: u32, q2: u32) {
    if (a != 0.0) {
        for (var j = 0u; j < q2; j++) {
            (*acc2)[j] += a * param4(row + 4u * j);
        }
    }
}

// Four inputs' terms for four first-layer units, in the twin's order: the units' weights for
// input f are at `at + f p1` (fc1.weight is input-major).
fn add_inputs(acc: vec4<f32>, x: vec4<f32>, at: u32, p1: u32) -> vec4<f32> {
    var s = acc;
    s += x.x * param4(at);
    s += x.y * param4(at + p1);
    s += x.z * param4(at + 2u * p1);
    s += x.w * param4(at + 3u * p1);
    return s;
}

fn standardised(x: vec4<f32>, at: u32) -> vec4<f32> {
    let mean = bitcast<vec4<f32>>(weights[(MLP_MEAN_AT >> 2u) + at]);
    let spread = bitcast<vec4<f32>>(weights[(MLP_STD_AT >> 2u) + at]);
    return clamp((x - mean) / spread, vec4<f32>(-MAX_STANDARDISED), vec4<f32>(MAX_STANDARDISED));
}

// The network's padded sizes.
fn net_shape() -> vec2<u32> {
    var p1 = NET_P1;
    var p2 = NET_P2;
    if (NET_P1 == 0u) {
        let shape = weights[0];
        p1 = (u32(bitcast<f32>(shape.x)) + 3u) & ~3u;
        p2 = (u32(bitcast<f32>(shape.y)) + 3u) & ~3u;
    }
    return vec2<u32>(p1, p2);
}

// mlp_forward with the first two layers' weights staged in workgroup memory a tile of
// TILE_UNITS first-layer units at a time: every invocation of the workgroup calls it (its
// barriers need them all), `runs` the ones whose output counts. The same sums in the same
// order as mlp_forward.
fn mlp_forward_shared(f: array<f32, FEATURES>, runs: bool, lid: u32) -> f32 {
    let shape = net_shape();
    let p1 = shape.x;
    let p2 = shape.y;
    let q2 = p2 / 4u;
    let x0 = standardised(vec4<f32>(f[0], f[1], f[2], f[3]), 0u);
    let x1 = standardised(vec4<f32>(f[4], f[5], f[6], f[7]), 1u);
    let x2 = standardised(vec4<f32>(f[8], f[9], f[10], f[11]), 2u);
    let w1 = MLP_W1_AT;
    let b1 = w1 + FEATURES * p1;
    let w2 = b1 + p1;
    let b2 = w2 + p1 * p2;
    let w3 = b2 + p2;
    var acc2: array<vec4<f32>, ACC2_VEC4S>;
    for (var j = 0u; j < q2; j++) {
        acc2[j] = param4(b2 + 4u * j);
    }
    let staged = TILE_W2 + TILE_UNITS * q2;
    for (var t = 0u; t < p1; t += TILE_UNITS) {
        // Stage the tile (units past p1: zeros, so they add nothing).
        for (var v = lid; v < staged; v += PIXEL_GROUP) {
            var value = vec4<f32>(0.0);
            if (v < TILE_B1) {
                let unit = t + 4u * (v % (TILE_UNITS / 4u));
                if (unit < p1) {
                    value = param4(w1 + (v / (TILE_UNITS / 4u)) * p1 + unit);
                }
            } else if (v < TILE_W2) {
                let unit = t + 4u * (v - TILE_B1);
                if (unit < p1) {
                    value = param4(b1 + unit);
                }
            } else {
                let r = v - TILE_W2;
                let unit = t + r / q2;
                if (unit < p1) {
                    value = param4(w2 + unit * p2 + 4u * (r % q2));
                }
            }
            tile[v] = value;
        }
        workgroupBarrier();
        if (runs) {
            for (var g = 0u; g < TILE_UNITS / 4u; g++) {
                var acc = tile[TILE_B1 + g];
                let c = TILE_W1 + g;
                let s = TILE_UNITS / 4u;
                acc += x0.x * tile[c];
                acc += x0.y * tile[c + s];
                acc += x0.z * tile[c + 2u * s];
                acc += x0.w * tile[c + 3u * s];
                acc += x1.x * tile[c + 4u * s];
                acc += x1.y * tile[c + 5u * s];
                acc += x1.z * tile[c + 6u * s];
                acc += x1.w * tile[c + 7u * s];
                acc += x2.x * tile[c + 8u * s];
                acc += x2.y * tile[c + 9u * s];
                acc += x2.z * tile[c + 10u * s];
                acc += x2.w * tile[c + 11u * s];
                let a = max(acc, vec4<f32>(0.0));
                let row = TILE_W2 + 4u * g * q2;
                add_tile_row(&acc2, a.x, row, q2);
                add_tile_row(&acc2, a.y, row + q2, q2);
                add_tile_row(&acc2, a.z, row + 2u * q2, q2);
                add_tile_row(&acc2, a.w, row + 3u * q2, q2);
            }
        }
        workgroupBarrier();
    }
    return network_output(&acc2, w3, q2);
}

// The output unit on the second layer's sums (ReLU), in the twin's order, through the sigmoid
// (mlp::squash: 0 where the sums overflowed both ways); its weights at `w3`, its bias after.
fn network_output(acc2: ptr<function, array<vec4<f32>, ACC2_VEC4S>>, w3: u32, q2: u32) -> f32 {
    var out = param4(w3 + 4u * q2).x;
    for (var j = 0u; j < q2; j++) {
        let h = max((*acc2)[j], vec4<f32>(0.0));
        let wv = param4(w3 + 4u * j);
        out += h.x * wv.x;
        out += h.y * wv.y;
        out += h.z * wv.z;
        out += h.w * wv.w;
    }
    let s = 1.0 / (1.0 + exp(-out));
    return select(0.0, s, s == s);
}

// add_row from a staged tile's row (q2 vec4s from `row`).
fn add_tile_row(acc2: ptr<function, array<vec4<f32>, ACC2_VEC4S>>, a: f32, row: u32, q2: u32) {
    if (a != 0.0) {
        for (var j = 0u; j < q2; j++) {
            (*acc2)[j] += a * tile[row + j];
        }
    }
}

fn mlp_forward_loop(f: array<f32, FEATURES>) -> f32 {
    let shape = net_shape();
    let p1 = shape.x;
    let p2 = shape.y;
    let q2 = p2 / 4u;
    let x0 = standardised(vec4<f32>(f[0], f[1], f[2], f[3]), 0u);
    let x1 = standardised(vec4<f32>(f[4], f[5], f[6], f[7]), 1u);
    let x2 = standardised(vec4<f32>(f[8], f[9], f[10], f[11]), 2u);
    let w1 = MLP_W1_AT;
    let b1 = w1 + FEATURES * p1;
    let w2 = b1 + p1;
    let b2 = w2 + p1 * p2;
    let w3 = b2 + p2;
    // Four hidden units of the first layer at a time, accumulated straight into the second
    // layer's sums: a private array of p2 floats instead of p1 (the order of the sums per
    // output unit is the same as the CPU twin's).
    var acc2: array<vec4<f32>, ACC2_VEC4S>;
    for (var j = 0u; j < q2; j++) {
        acc2[j] = param4(b2 + 4u * j);
    }
    for (var i = 0u; i < p1; i += 4u) {
        var acc = param4(b1 + i);
        acc = add_inputs(acc, x0, w1 + i, p1);
        acc = add_inputs(acc, x1, w1 + 4u * p1 + i, p1);
        acc = add_inputs(acc, x2, w1 + 8u * p1 + i, p1);
        let a = max(acc, vec4<f32>(0.0));
        add_row(&acc2, a.x, w2 + i * p2, q2);
        add_row(&acc2, a.y, w2 + (i + 1u) * p2, q2);
        add_row(&acc2, a.z, w2 + (i + 2u) * p2, q2);
        add_row(&acc2, a.w, w2 + (i + 3u) * p2, q2);
    }
    return network_output(&acc2, w3, q2);
}
