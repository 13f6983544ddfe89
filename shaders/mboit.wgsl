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

// Six and eight power moments (composite::mboit_transmittance_n and its helpers, operation for
// operation): b holds b_1..b_8 over b_0 (six read the first six). Each returns whether floats
// could form the distribution; where they cannot, the first four moments' `share` stands in.

// The paper's bias vectors.
const MBOIT_PULL6 = array<f32, 6>(0.0, 0.48, 0.0, 0.451, 0.0, 0.45);
const MBOIT_PULL8 = array<f32, 8>(0.0, 0.75, 0.0, 0.6766667, 0.0, 0.63, 0.0, 0.60030303);

struct Maybe {
    ok: bool,
    value: f32,
};

// Whether v is a finite float (no infinity or NaN: its exponent is not all ones).
fn finite(v: f32) -> bool {
    return (bitcast<u32>(v) & 0x7f800000u) != 0x7f800000u;
}

// The weight of point z_i (i > 0) that counts as in front of z: 1 nearer, 0 farther.
fn in_front(zi: f32, z: f32) -> f32 {
    return select(0.0, 1.0, zi < z);
}

struct Roots3 {
    ok: bool,
    r: vec3<f32>,
};

// composite::mboit_cubic_roots: the three real roots of c0 + c1 x + c2 x^2 + c3 x^3.
fn cubic_roots(c: vec4<f32>) -> Roots3 {
    var out: Roots3;
    out.ok = false;
    if (c.w == 0.0) {
        return out;
    }
    let c0 = c.x / c.w;
    let c1 = c.y / c.w / 3.0;
    let c2 = c.z / c.w / 3.0;
    let delta = vec3<f32>(c1 - c2 * c2, c0 - c1 * c2, c2 * c0 - c1 * c1);
    let discriminant = 4.0 * delta.x * delta.z - delta.y * delta.y;
    let depressed = vec2<f32>(delta.y - 2.0 * c2 * delta.x, delta.x);
    if (!(discriminant >= 0.0 && depressed.y <= 0.0)) {
        return out;
    }
    let theta = atan2(sqrt(discriminant), -depressed.x) / 3.0;
    let s = sin(theta);
    let k = cos(theta);
    let half_sqrt3 = 0.5 * sqrt(3.0);
    let scale = 2.0 * sqrt(-depressed.y);
    out.r = vec3<f32>(
        scale * k - c2,
        scale * (-0.5 * k - half_sqrt3 * s) - c2,
        scale * (-0.5 * k + half_sqrt3 * s) - c2,
    );
    out.ok = finite(out.r.x) && finite(out.r.y) && finite(out.r.z);
    return out;
}

// composite::cubic_smallest_root: the smallest root of c0 + c1 x + c2 x^2 + x^3.
fn cubic_smallest_root(c: vec3<f32>) -> Maybe {
    var out: Maybe;
    out.ok = false;
    out.value = 0.0;
    let c0 = c.x;
    let c1 = c.y / 3.0;
    let c2 = c.z / 3.0;
    let delta = vec3<f32>(c1 - c2 * c2, c0 - c2 * c1, c2 * c0 - c1 * c1);
    let discriminant = 4.0 * delta.x * delta.z - delta.y * delta.y;
    let depressed = vec2<f32>(delta.z, -c0 * delta.y + 2.0 * c1 * delta.z);
    if (!(discriminant >= 0.0 && depressed.x <= 0.0)) {
        return out;
    }
    let theta = abs(atan2(c0 * sqrt(discriminant), -depressed.y)) / 3.0;
    let s = sin(theta);
    let k = cos(theta);
    let t = 2.0 * sqrt(-depressed.x);
    let x = vec2<f32>(t * k, t * (-0.5 * k - 0.5 * sqrt(3.0) * s));
    var d = x.y + c1;
    if (x.x + x.y < 2.0 * c1) {
        d = x.x + c1;
    }
    out.value = -c0 / d;
    out.ok = finite(out.value);
    return out;
}

struct Roots2 {
    ok: bool,
    r: vec2<f32>,
};

// composite::quadratic_roots: the roots of x^2 + b x + c.
fn quadratic_roots(b: f32, c: f32) -> Roots2 {
    var out: Roots2;
    out.ok = false;
    let half = 0.5 * b;
    let disc = half * half - c;
    if (!(disc >= 0.0)) {
        return out;
    }
    let r = sqrt(disc);
    if (half >= 0.0) {
        out.r = vec2<f32>(-c / (half + r), -half - r);
    } else {
        out.r = vec2<f32>(-half + r, c / (-half + r));
    }
    out.ok = finite(out.r.x) && finite(out.r.y);
    return out;
}

struct Roots4 {
    ok: bool,
    r: vec4<f32>,
};

// composite::mboit_quartic_roots: Neumark's factorization, Herbison-Evans's choice.
fn quartic_roots(c: array<f32, 5>) -> Roots4 {
    var out: Roots4;
    out.ok = false;
    if (c[4] == 0.0) {
        return out;
    }
    let b = c[3] / c[4];
    let cc = c[2] / c[4];
    let d = c[1] / c[4];
    let e = c[0] / c[4];
    let p = -2.0 * cc;
    let q = cc * cc + b * d - 4.0 * e;
    let r = d * d + b * b * e - b * cc * d;
    let y = cubic_smallest_root(vec3<f32>(r, q, p));
    if (!y.ok) {
        return out;
    }
    let bb = b * b;
    let fy = 4.0 * y.value;
    let bb_fy = bb - fy;
    let zz0 = cc - y.value;
    let zz = zz0 * zz0;
    let fe = 4.0 * e;
    let zz_fe = zz - fe;
    var g1: f32;
    var g2: f32;
    var h1: f32;
    var h2: f32;
    if (y.value < 0.0 || (zz + fe) * bb_fy > zz_fe * (bb + fy)) {
        let t = sqrt(bb_fy);
        g1 = (b + t) * 0.5;
        g2 = (b - t) * 0.5;
        let u = (b * zz0 - 2.0 * d) / (2.0 * t);
        h1 = zz0 * 0.5 + u;
        h2 = zz0 * 0.5 - u;
    } else {
        let t = sqrt(zz_fe);
        h1 = (zz0 + t) * 0.5;
        h2 = (zz0 - t) * 0.5;
        let u = (b * zz0 - 2.0 * d) / (2.0 * t);
        g1 = b * 0.5 + u;
        g2 = b * 0.5 - u;
    }
    let first = quadratic_roots(g1, h1);
    let second = quadratic_roots(g2, h2);
    out.ok = first.ok && second.ok;
    out.r = vec4<f32>(first.r, second.r);
    return out;
}

// composite::newton_to_monomial for four points: the cubic through (zs_i, f_i), constant
// first (ok false where two points coincide or a coefficient is not finite).
struct Poly4 {
    ok: bool,
    a: vec4<f32>,
};

fn newton4(zs: vec4<f32>, f: vec4<f32>) -> Poly4 {
    var out: Poly4;
    out.ok = false;
    var d = array<f32, 4>(f.x, f.y, f.z, f.w);
    let z = array<f32, 4>(zs.x, zs.y, zs.z, zs.w);
    for (var level = 1u; level < 4u; level++) {
        for (var i = 3u; i >= level; i--) {
            let dz = z[i] - z[i - level];
            if (dz == 0.0) {
                return out;
            }
            d[i] = (d[i] - d[i - 1u]) / dz;
        }
    }
    var a = array<f32, 4>(d[3], 0.0, 0.0, 0.0);
    for (var i = 3u; i > 0u; i--) {
        let zi = z[i - 1u];
        for (var j = 3u; j > 0u; j--) {
            a[j] = a[j - 1u] - a[j] * zi;
        }
        a[0] = d[i - 1u] - a[0] * zi;
    }
    out.a = vec4<f32>(a[0], a[1], a[2], a[3]);
    out.ok = finite(a[0]) && finite(a[1]) && finite(a[2]) && finite(a[3]);
    return out;
}

// The same for five points (the quartic's), coefficients in a0 and a.
struct Poly5 {
    ok: bool,
    a0: f32,
    a: vec4<f32>,
};

fn newton5(zs: array<f32, 5>, f: array<f32, 5>) -> Poly5 {
    var out: Poly5;
    out.ok = false;
    var d = f;
    let z = zs;
    for (var level = 1u; level < 5u; level++) {
        for (var i = 4u; i >= level; i--) {
            let dz = z[i] - z[i - level];
            if (dz == 0.0) {
                return out;
            }
            d[i] = (d[i] - d[i - 1u]) / dz;
        }
    }
    var a = array<f32, 5>(d[4], 0.0, 0.0, 0.0, 0.0);
    for (var i = 4u; i > 0u; i--) {
        let zi = z[i - 1u];
        for (var j = 4u; j > 0u; j--) {
            a[j] = a[j - 1u] - a[j] * zi;
        }
        a[0] = d[i - 1u] - a[0] * zi;
    }
    out.a0 = a[0];
    out.a = vec4<f32>(a[1], a[2], a[3], a[4]);
    out.ok = finite(a[0]) && finite(a[1]) && finite(a[2]) && finite(a[3]) && finite(a[4]);
    return out;
}

// composite::mboit_share6.
fn share6(m: array<f32, 8>, z: f32) -> Maybe {
    var out: Maybe;
    out.ok = false;
    out.value = 0.0;
    let beta = params.mboit_bias;
    var b: array<f32, 6>;
    for (var i = 0u; i < 6u; i++) {
        b[i] = m[i] * (1.0 - beta) + MBOIT_PULL6[i] * beta;
    }
    let d11 = b[1] - b[0] * b[0];
    let l21d11 = b[2] - b[0] * b[1];
    let l21 = l21d11 / d11;
    let d22 = (b[3] - b[1] * b[1]) - l21d11 * l21;
    let l31d11 = b[3] - b[0] * b[2];
    let l31 = l31d11 / d11;
    let l32d22 = (b[4] - b[1] * b[2]) - l21d11 * l31;
    let l32 = l32d22 / d22;
    let d33 = (b[5] - b[2] * b[2]) - (l31d11 * l31 + l32d22 * l32);
    if (!(d11 > 0.0 && d22 > 0.0 && d33 > 0.0)) {
        return out;
    }
    var c = array<f32, 4>(1.0, z, z * z, z * z * z);
    c[1] -= b[0];
    c[2] -= b[1] + l21 * c[1];
    c[3] -= b[2] + (l31 * c[1] + l32 * c[2]);
    c[1] /= d11;
    c[2] /= d22;
    c[3] /= d33;
    c[2] -= l32 * c[3];
    c[1] -= l21 * c[2] + l31 * c[3];
    c[0] -= b[0] * c[1] + b[1] * c[2] + b[2] * c[3];
    let r = cubic_roots(vec4<f32>(c[0], c[1], c[2], c[3]));
    if (!r.ok) {
        return out;
    }
    let zs = vec4<f32>(z, r.r);
    let f = vec4<f32>(params.mboit_overestimation, in_front(r.r.x, z), in_front(r.r.y, z),
        in_front(r.r.z, z));
    let p = newton4(zs, f);
    if (!p.ok) {
        return out;
    }
    out.value = p.a.x + p.a.y * b[0] + p.a.z * b[1] + p.a.w * b[2];
    out.ok = finite(out.value);
    return out;
}

// composite::mboit_share8.
fn share8(m: array<f32, 8>, z: f32) -> Maybe {
    var out: Maybe;
    out.ok = false;
    out.value = 0.0;
    let beta = params.mboit_bias;
    var b: array<f32, 8>;
    for (var i = 0u; i < 8u; i++) {
        b[i] = m[i] * (1.0 - beta) + MBOIT_PULL8[i] * beta;
    }
    let d22 = b[1] - b[0] * b[0];
    let l32d22 = b[2] - b[1] * b[0];
    let l32 = l32d22 / d22;
    let l42d22 = b[3] - b[2] * b[0];
    let l42 = l42d22 / d22;
    let l52d22 = b[4] - b[3] * b[0];
    let l52 = l52d22 / d22;
    let d33 = (b[3] - b[1] * b[1]) - l32 * l32d22;
    let l43d33 = (b[4] - b[2] * b[1]) - l42 * l32d22;
    let l43 = l43d33 / d33;
    let l53d33 = (b[5] - b[3] * b[1]) - l52 * l32d22;
    let l53 = l53d33 / d33;
    let d44 = (b[5] - b[2] * b[2]) - (l42 * l42d22 + l43 * l43d33);
    let l54d44 = (b[6] - b[3] * b[2]) - (l52 * l42d22 + l53 * l43d33);
    let l54 = l54d44 / d44;
    let d55 = (b[7] - b[3] * b[3]) - (l52 * l52d22 + l53 * l53d33 + l54 * l54d44);
    if (!(d22 > 0.0 && d33 > 0.0 && d44 > 0.0 && d55 > 0.0)) {
        return out;
    }
    var c = array<f32, 5>(1.0, z, z * z, z * z * z, z * z * z * z);
    c[1] -= b[0];
    c[2] -= b[1] + l32 * c[1];
    c[3] -= b[2] + (l42 * c[1] + l43 * c[2]);
    c[4] -= b[3] + (l52 * c[1] + l53 * c[2] + l54 * c[3]);
    c[1] /= d22;
    c[2] /= d33;
    c[3] /= d44;
    c[4] /= d55;
    c[3] -= l54 * c[4];
    c[2] -= l53 * c[4] + l43 * c[3];
    c[1] -= l52 * c[4] + l42 * c[3] + l32 * c[2];
    c[0] -= b[3] * c[4] + b[2] * c[3] + b[1] * c[2] + b[0] * c[1];
    let r = quartic_roots(c);
    if (!r.ok) {
        return out;
    }
    let zs = array<f32, 5>(z, r.r.x, r.r.y, r.r.z, r.r.w);
    let f = array<f32, 5>(params.mboit_overestimation, in_front(r.r.x, z), in_front(r.r.y, z),
        in_front(r.r.z, z), in_front(r.r.w, z));
    let p = newton5(zs, f);
    if (!p.ok) {
        return out;
    }
    out.value = p.a0 + p.a.x * b[0] + p.a.y * b[1] + p.a.z * b[2] + p.a.w * b[3];
    out.ok = finite(out.value);
    return out;
}

// composite::mboit_transmittance_n: `moments` (6 or 8) power moments, the first four's
// reconstruction where floats cannot form theirs.
fn transmittance_n(b0: f32, m: array<f32, 8>, z: f32, moments: u32) -> f32 {
    var s: Maybe;
    if (moments == 8u) {
        s = share8(m, z);
    } else {
        s = share6(m, z);
    }
    var v = s.value;
    if (!s.ok) {
        v = share(vec4<f32>(m[0], m[1], m[2], m[3]), z);
    }
    return clamp(exp(-b0 * v), 0.0, 1.0);
}
