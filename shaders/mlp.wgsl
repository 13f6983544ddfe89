// The importance network (mlp::Mlp::forward, operation for operation), shared by the DKB
// importance pass and the batch prediction pass: 12 standardised inputs, ReLU, ReLU, and the
// sigmoid (mlp::squash: 0 where the sums overflowed both ways). Its weights sit in a uniform
// buffer at binding 1, in 32-bit words: h1, h2, unused, unused, mean[12], std[12] (f32), then
// fc1.weight [12][h1], fc1.bias[h1], fc2.weight[h1][h2], fc2.bias[h2], out.weight[h2],
// out.bias: f32 words, or with F16_WEIGHTS binary16 values two to a word (wgsl::mlp_uniform).

@group(0) @binding(1) var<uniform> weights: array<vec4<u32>, MLP_VEC4S>;

// Standardised inputs are clamped to MAX_STANDARDISED, so no sum overflows; the pass holds a
// second hidden layer of at most MAX_H2 units (both from the prelude).

// The weights' precision (mlp::Precision): the f16 variant of a pass is built with this true.
const F16_WEIGHTS: bool = false;

fn word(i: u32) -> u32 {
    return weights[i >> 2u][i & 3u];
}

// An f32 of the header (sizes, standardisation).
fn w(i: u32) -> f32 {
    return bitcast<f32>(word(i));
}

// A weight or bias, `i` its index in the f32 layout: unpacked exactly from binary16 at f16.
fn param(i: u32) -> f32 {
    if (F16_WEIGHTS) {
        let j = i - MLP_W1_AT;
        return unpack2x16float(word(MLP_W1_AT + (j >> 1u)))[j & 1u];
    }
    return w(i);
}

fn mlp_forward(features: array<f32, 12>) -> f32 {
    var x = features;
    let h1 = u32(w(0u));
    let h2 = u32(w(1u));
    for (var i = 0u; i < 12u; i++) {
        x[i] = clamp((x[i] - w(MLP_MEAN_AT + i)) / w(MLP_STD_AT + i), -MAX_STANDARDISED, MAX_STANDARDISED);
    }
    let w1 = MLP_W1_AT;
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
        acc2[j] = param(b2 + j);
    }
    for (var i = 0u; i < h1; i++) {
        var acc = param(b1 + i);
        for (var f = 0u; f < 12u; f++) {
            acc += x[f] * param(w1 + f * h1 + i);
        }
        let a = max(acc, 0.0);
        if (a != 0.0) {
            for (var j = 0u; j < h2; j++) {
                acc2[j] += a * param(w2 + i * h2 + j);
            }
        }
    }
    var out = param(b3);
    for (var j = 0u; j < h2; j++) {
        out += max(acc2[j], 0.0) * param(w3 + j);
    }
    let s = 1.0 / (1.0 + exp(-out));
    return select(0.0, s, s == s);
}
