// MBOIT from the A-buffer (compute, one invocation a pixel): the pixel's stored capture keys are
// sorted front to back (sort.wgsl's insertion sort: a fixed order for the float sums, so the
// image does not depend on submission), then summed as Munstermann et al.'s two additive passes
// would hold them: b_0 and four power moments of the absorbance, then each fragment's colour
// weighted by the transmittance the moments give in front of it; resolved over what is behind
// the pixel (behind.wgsl), as composite::mboit_sorted.

// Its bindings, the pixel's stored range and the image write are sort.wgsl's; beside them, the
// absorbance of each 8-bit opacity (composite::mboit_absorbance_table), four to a vec4, so the
// moments are the CPU's floats.
@group(0) @binding(6) var<uniform> absorbance_table: array<vec4<f32>, 64>;

// composite::mboit_absorbance, of the key's 8-bit opacity.
fn absorbance(rgba8: u32) -> f32 {
    let a = rgba8 >> 24u;
    return absorbance_table[a >> 2u][a & 3u];
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

@compute @workgroup_size(PIXEL_GROUP)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let list = stored(wid, nwg, lid);
    if (!list.ok) {
        return;
    }
    let p = list.p;
    let start = list.start;
    let end = list.end;
    sort_keys(start, end, params.store_primitives != 0u);
    // The first pass: b_0 and the moments.
    var b0 = 0.0;
    var b = vec4<f32>(0.0);
    for (var i = start; i < end; i++) {
        tick();
        let key = keys[i];
        let a = absorbance(u32(key & 0xfffffffflu));
        let z = 2.0 * bitcast<f32>(u32(key >> 32u)) - 1.0;
        let z2 = z * z;
        b0 += a;
        b += vec4<f32>(a * z, a * z2, a * z2 * z, a * z2 * z2);
    }
    if (b0 < MBOIT_MIN_B0) {
        write_pixel(p, behind(p));
        return;
    }
    let m = b / b0;
    // The second: colour weighted by the transmittance in front of each fragment.
    var l = vec3<f32>(0.0);
    var w = 0.0;
    for (var i = start; i < end; i++) {
        tick();
        let key = keys[i];
        let rgba = unpack_rgba8(u32(key & 0xfffffffflu));
        let t = transmittance(b0, m, 2.0 * bitcast<f32>(u32(key >> 32u)) - 1.0) * rgba.a;
        l += t * rgba.rgb;
        w += t;
    }
    let total = exp(-b0);
    let inv = select(0.0, 1.0 / w, w > 0.0);
    write_pixel(p, (1.0 - total) * l * inv + total * behind(p));
}
