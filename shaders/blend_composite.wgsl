// The composites of the blended methods (compute, one invocation a pixel): their targets, read
// as textures, over what is behind the pixel (behind.wgsl). `wboit`: the accumulation divided
// by its weight, over the revealage (composite::wboit_sorted's last line). `mboit`: the
// transmittance-weighted colour divided by its weight, over e^-b0 (composite::mboit_sorted's).
// No loop and no status: a pixel's cost does not depend on its depth.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> image: array<vec4<f32>>;
// WBOIT: the accumulation (RGBA16F) and the revealage (R8). MBOIT: the weighted colour
// (RGBA16F) and b_0 (R32F).
@group(0) @binding(2) var first_target: texture_2d<f32>;
@group(0) @binding(3) var second_target: texture_2d<f32>;

fn texel(t: texture_2d<f32>, p: u32) -> vec4<f32> {
    return textureLoad(t, vec2<u32>(p % params.width, p / params.width), 0);
}

@compute @workgroup_size(PIXEL_GROUP)
fn wboit(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let acc = texel(first_target, p);
    let reveal = texel(second_target, p).r;
    let inv = 1.0 / clamp(acc.a, 1e-4, 5e4);
    image[p] = vec4<f32>(acc.rgb * inv * (1.0 - reveal) + reveal * behind(p), 1.0);
}

@compute @workgroup_size(PIXEL_GROUP)
fn mboit(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let b0 = texel(second_target, p).r;
    if (b0 < MBOIT_MIN_B0) {
        image[p] = vec4<f32>(behind(p), 1.0);
        return;
    }
    let acc = texel(first_target, p);
    let total = exp(-b0);
    let inv = select(0.0, 1.0 / acc.a, acc.a > 0.0);
    image[p] = vec4<f32>((1.0 - total) * acc.rgb * inv + total * behind(p), 1.0);
}
