// MBOIT's reconstruction, shared by its passes: the depth its moments are taken of, and the
// transmittance in front of a depth that four power moments admit (composite::mboit_*).

// A fragment's window depth as its capture key holds it (fragment_key), mapped to [-1, 1]
// (composite::mboit_sorted's 2 z - 1).
fn mboit_depth(clip_z: f32) -> f32 {
    return 2.0 * select(0.0, clip_z, clip_z > 0.0) - 1.0;
}

// composite::mboit_transmittance and mboit_share, operation for operation: the share of the
// absorbance in front of z that the biased moments m admit, with one point of their three-point
// distribution at z; the overestimation where 32-bit floats cannot separate the points (no
// infinity or NaN is ever formed).
fn share(b: vec4<f32>, z: f32) -> f32 {
    let beta = params.mboit_bias;
    let m = b * (1.0 - beta) + vec4<f32>(0.0, 0.375, 0.0, 0.375) * beta;
    let one_depth = params.mboit_overestimation;
    let d2 = m.y - m.x * m.x;
    if (d2 <= 0.0) {
        return one_depth;
    }
    let l32 = (m.z - m.x * m.y) / d2;
    let d3 = m.w - m.y * m.y - l32 * l32 * d2;
    if (d3 <= 0.0) {
        return one_depth;
    }
    let y2 = (z - m.x) / d2;
    let y3 = (z * z - m.y - l32 * (z - m.x)) / d3;
    let c2 = y3;
    let c1 = y2 - l32 * c2;
    let c0 = 1.0 - m.x * c1 - m.y * c2;
    if (c2 == 0.0) {
        return one_depth;
    }
    let half = -0.5 * c1 / c2;
    let disc = half * half - c0 / c2;
    var r = 0.0;
    if (disc > 0.0) {
        r = sqrt(disc);
    }
    let z1 = half - r;
    let z2 = half + r;
    if (z1 == z || z2 == z1 || z2 == z) {
        return one_depth;
    }
    let f0 = params.mboit_overestimation;
    let f1 = select(0.0, 1.0, z1 < z);
    let f2 = select(0.0, 1.0, z2 < z);
    let f01 = (f1 - f0) / (z1 - z);
    let f12 = (f2 - f1) / (z2 - z1);
    let f012 = (f12 - f01) / (z2 - z);
    let a2 = f012;
    let a1 = f01 - f012 * (z + z1);
    let a0 = f0 - f01 * z + f012 * z * z1;
    return a0 + a1 * m.x + a2 * m.y;
}

fn transmittance(b0: f32, b: vec4<f32>, z: f32) -> f32 {
    return clamp(exp(-b0 * share(b, z)), 0.0, 1.0);
}
