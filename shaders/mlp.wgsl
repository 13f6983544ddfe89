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

@group(0) @binding(1) var<uniform> weights: array<vec4<u32>, MLP_VEC4S>;

// Standardised inputs are clamped to MAX_STANDARDISED, so no sum overflows; the pass holds a
// second hidden layer of at most MAX_H2 units (both from the prelude).

// The weights' precision (mlp::Precision): the f16 variant of a pass is built with this true.
const F16_WEIGHTS: bool = false;

// The padded sizes (p1, p2) when the pass is built for one network shape (gpu::Variant): loops
// of known length, and the second layer's sums in exactly p2 floats. 0: read from the uniform.
const NET_P1: u32 = 0u;
const NET_P2: u32 = 0u;
const ACC2_VEC4S: u32 = MAX_H2 / 4u;

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

fn mlp_forward(f: array<f32, 12>) -> f32 {
    var p1 = NET_P1;
    var p2 = NET_P2;
    if (NET_P1 == 0u) {
        let shape = weights[0];
        p1 = (u32(bitcast<f32>(shape.x)) + 3u) & ~3u;
        p2 = (u32(bitcast<f32>(shape.y)) + 3u) & ~3u;
    }
    let q2 = p2 / 4u;
    let x0 = standardised(vec4<f32>(f[0], f[1], f[2], f[3]), 0u);
    let x1 = standardised(vec4<f32>(f[4], f[5], f[6], f[7]), 1u);
    let x2 = standardised(vec4<f32>(f[8], f[9], f[10], f[11]), 2u);
    let w1 = MLP_W1_AT;
    let b1 = w1 + 12u * p1;
    let w2 = b1 + p1;
    let b2 = w2 + p1 * p2;
    let w3 = b2 + p2;
    let b3 = w3 + p2;
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
    var out = param4(b3).x;
    for (var j = 0u; j < q2; j++) {
        let h = max(acc2[j], vec4<f32>(0.0));
        let wv = param4(w3 + 4u * j);
        out += h.x * wv.x;
        out += h.y * wv.y;
        out += h.z * wv.z;
        out += h.w * wv.w;
    }
    let s = 1.0 / (1.0 + exp(-out));
    return select(0.0, s, s == s);
}
