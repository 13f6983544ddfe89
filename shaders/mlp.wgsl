// The importance network (mlp::Mlp::forward, operation for operation), shared by the DKB
// importance pass and the batch prediction pass: 12 standardised inputs, ReLU, ReLU, and the
// sigmoid (mlp::squash: 0 where the sums overflowed both ways). Its weights sit in a uniform
// buffer at binding 1, laid out in floats as: h1, h2, unused, unused, mean[12], std[12],
// fc1.weight [12][h1], fc1.bias[h1], fc2.weight[h1][h2], fc2.bias[h2], out.weight[h2],
// out.bias (wgsl::mlp_uniform).

@group(0) @binding(1) var<uniform> weights: array<vec4<f32>, MLP_VEC4S>;

// Standardised inputs are clamped to MAX_STANDARDISED, so no sum overflows; the pass holds a
// second hidden layer of at most MAX_H2 units (both from the prelude).

fn w(i: u32) -> f32 {
    return weights[i >> 2u][i & 3u];
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
    let s = 1.0 / (1.0 + exp(-out));
    return select(0.0, s, s == s);
}
