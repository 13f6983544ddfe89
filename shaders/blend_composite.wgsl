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

// MBOIT where the frame's glass is tinted: the product of the transmittances per channel
// (RGBA8), what the background is seen through.
@group(0) @binding(4) var third_target: texture_2d<f32>;

fn texel(t: texture_2d<f32>, p: u32) -> vec4<f32> {
    return textureLoad(t, vec2<u32>(p % params.width, p / params.width), 0);
}

// WBOIT's pixel p over `under`.
fn wboit_pixel(p: u32, under: vec3<f32>) -> vec3<f32> {
    let acc = texel(first_target, p);
    let second = texel(second_target, p);
    var reveal = second.r;
    var through = vec3<f32>(reveal);
    // Tinted glass: the revealage in A, what the fragments let through per channel in RGB.
    if (params.tinted != 0u) {
        reveal = second.a;
        through = second.rgb;
    }
    let inv = 1.0 / clamp(acc.a, 1e-4, 5e4);
    return acc.rgb * inv * (1.0 - reveal) + through * under;
}

// MBOIT's pixel p over `under`.
fn mboit_pixel(p: u32, under: vec3<f32>) -> vec3<f32> {
    let b0 = texel(second_target, p).r;
    // A pixel of a tinted fragment (its A 0): the product per channel.
    var tinted = false;
    var through = vec3<f32>(1.0);
    if (params.tinted != 0u) {
        let t = texel(third_target, p);
        tinted = t.a == 0.0;
        through = select(vec3<f32>(1.0), t.rgb, tinted);
    }
    if (b0 < MBOIT_MIN_B0) {
        return through * under;
    }
    let acc = texel(first_target, p);
    let total = exp(-b0);
    if (!tinted) {
        through = vec3<f32>(total);
    }
    let inv = select(0.0, 1.0 / acc.a, acc.a > 0.0);
    return (1.0 - total) * acc.rgb * inv + through * under;
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
    image[p] = vec4<f32>(wboit_pixel(p, behind(p)), 1.0);
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
    image[p] = vec4<f32>(mboit_pixel(p, behind(p)), 1.0);
}

// An application's frame (gpu::BlendedOit::resolve): over its own image `under`, onto its
// target. Its targets are cleared by its next frame's first pass (their load operation).
@group(0) @binding(8) var under: texture_2d<f32>;
@group(0) @binding(9) var onto_target: OntoTexture;

@compute @workgroup_size(PIXEL_GROUP)
fn wboit_onto(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let xy = vec2<u32>(p % params.width, p / params.width);
    textureStore(onto_target, xy, vec4<f32>(wboit_pixel(p, textureLoad(under, xy, 0).rgb), 1.0));
}

@compute @workgroup_size(PIXEL_GROUP)
fn mboit_onto(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let xy = vec2<u32>(p % params.width, p / params.width);
    textureStore(onto_target, xy, vec4<f32>(mboit_pixel(p, textureLoad(under, xy, 0).rgb), 1.0));
}
