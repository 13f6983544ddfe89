// MBOIT's second pass (geometry): each visible transparent fragment adds its colour and
// opacity, weighted by the transmittance the first pass's moments admit in front of it
// (mboit.wgsl's `transmittance`), to an RGBA16F target (blend one, one), as
// composite::mboit_sorted's second loop sums them. A pixel whose b_0 is below MBOIT_MIN_B0 adds
// nothing (the composite shows what is behind it).

@group(1) @binding(0) var b0_target: texture_2d<f32>;
@group(1) @binding(1) var moments_target: texture_2d<f32>;

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        discard;
    }
    let xy = vec2<u32>(u32(in.clip.x), u32(in.clip.y));
    let b0 = textureLoad(b0_target, xy, 0).r;
    if (b0 < MBOIT_MIN_B0) {
        discard;
    }
    let m = textureLoad(moments_target, xy, 0) / b0;
    let rgba = stored_colour(f.rgba8, f.tint);
    let t = transmittance(b0, m, mboit_depth(in.clip.z)) * rgba.a;
    return vec4<f32>(t * rgba.rgb, t);
}

// Six and eight power moments: b_5.. in a third target.
@group(1) @binding(2) var extra_target: texture_2d<f32>;

fn accumulate_n(in: VertexOut, front: bool, moments: u32) -> vec4<f32> {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        discard;
    }
    let xy = vec2<u32>(u32(in.clip.x), u32(in.clip.y));
    let b0 = textureLoad(b0_target, xy, 0).r;
    if (b0 < MBOIT_MIN_B0) {
        discard;
    }
    let lo = textureLoad(moments_target, xy, 0) / b0;
    let hi = textureLoad(extra_target, xy, 0) / b0;
    let m = array<f32, 8>(lo.x, lo.y, lo.z, lo.w, hi.x, hi.y, hi.z, hi.w);
    let rgba = stored_colour(f.rgba8, f.tint);
    let t = transmittance_n(b0, m, mboit_depth(in.clip.z), moments) * rgba.a;
    return vec4<f32>(t * rgba.rgb, t);
}

@fragment
fn fs_main6(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    return accumulate_n(in, front, 6u);
}

@fragment
fn fs_main8(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    return accumulate_n(in, front, 8u);
}
