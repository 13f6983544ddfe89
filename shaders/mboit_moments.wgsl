// MBOIT's first pass (geometry), as Munstermann et al. lay it out: each visible transparent
// fragment adds its absorbance to an R32F target (b_0) and its absorbance times z, z^2, z^3,
// z^4 to an RGBA32F one (blend one, one), z the window depth mapped to [-1, 1]. The sums are in
// float, in the order the device runs the fragments (composite::mboit_sorted's first loop sums
// the same terms front to back).

// The absorbance of each 8-bit opacity (composite::mboit_absorbance_table), four to a vec4, so
// both sides add the same floats.
@group(1) @binding(0) var<uniform> absorbance_table: array<vec4<f32>, 64>;

struct Targets {
    @location(0) b0: vec4<f32>,
    @location(1) moments: vec4<f32>,
};

// The fragment, shaded once for all the pass's targets; discarded where it is not visible.
fn visible_fragment(in: VertexOut, front: bool) -> Transparent {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        discard;
    }
    return f;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> Targets {
    return moments4(in, visible_fragment(in, front));
}

fn moments4(in: VertexOut, f: Transparent) -> Targets {
    let alpha8 = f.rgba8 >> 24u;
    let a = absorbance_table[alpha8 >> 2u][alpha8 & 3u];
    let z = mboit_depth(in.clip.z);
    let z2 = z * z;
    var out: Targets;
    out.b0 = vec4<f32>(a, 0.0, 0.0, 0.0);
    out.moments = vec4<f32>(a * z, a * z2, a * z2 * z, a * z2 * z2);
    return out;
}

// Where the frame's glass is tinted: the product of the transmittances (1 - a) g per channel
// multiplies into an RGBA8 target, last (blend zero, one minus source: RGB's source 1 - (1 - a)
// g), and its A, cleared to 1, becomes 0 where a tinted fragment is drawn (source 1): the
// pixels the composite filters per channel (composite::mboit_blended's).
fn through(f: Transparent) -> vec4<f32> {
    let tinted = select(0.0, 1.0, filters(f.tint));
    return vec4<f32>(1.0 - tint_transmittance(unpack_rgba8(f.rgba8), f.tint), tinted);
}

struct TintedTargets {
    @location(0) b0: vec4<f32>,
    @location(1) moments: vec4<f32>,
    @location(2) through: vec4<f32>,
};

@fragment
fn fs_tinted(in: VertexOut, @builtin(front_facing) front: bool) -> TintedTargets {
    let f = visible_fragment(in, front);
    let m = moments4(in, f);
    return TintedTargets(m.b0, m.moments, through(f));
}

// Six and eight power moments: b_1..b_4 in the RGBA32F target, b_5, b_6 (and b_7, b_8) in a
// third, RG32F (RGBA32F) one, the terms as composite::mboit_terms computes them.
struct Targets8 {
    @location(0) b0: vec4<f32>,
    @location(1) moments: vec4<f32>,
    @location(2) extra: vec4<f32>,
};

// Both six and eight moments' pass: the third target's format (RG32F or RGBA32F) keeps what
// it holds.
@fragment
fn fs_extra(in: VertexOut, @builtin(front_facing) front: bool) -> Targets8 {
    return moments_extra(in, visible_fragment(in, front));
}

fn moments_extra(in: VertexOut, f: Transparent) -> Targets8 {
    var out: Targets8;
    let alpha8 = f.rgba8 >> 24u;
    let a = absorbance_table[alpha8 >> 2u][alpha8 & 3u];
    let z = mboit_depth(in.clip.z);
    let z2 = z * z;
    let z4 = z2 * z2;
    let z6 = z4 * z2;
    out.b0 = vec4<f32>(a, 0.0, 0.0, 0.0);
    out.moments = vec4<f32>(a * z, a * z2, a * z2 * z, a * z2 * z2);
    out.extra = vec4<f32>(a * z4 * z, a * z4 * z2, a * z6 * z, a * z4 * z4);
    return out;
}

struct TintedTargets8 {
    @location(0) b0: vec4<f32>,
    @location(1) moments: vec4<f32>,
    @location(2) extra: vec4<f32>,
    @location(3) through: vec4<f32>,
};

@fragment
fn fs_extra_tinted(in: VertexOut, @builtin(front_facing) front: bool) -> TintedTargets8 {
    let f = visible_fragment(in, front);
    let m = moments_extra(in, f);
    return TintedTargets8(m.b0, m.moments, m.extra, through(f));
}
