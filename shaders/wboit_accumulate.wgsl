// WBOIT's accumulation pass (geometry), as McGuire and Bavoil lay it out: each visible
// transparent fragment adds its weighted premultiplied colour and weight to an RGBA16F target
// (blend one, one) and multiplies an R8 revealage target, cleared to 1, by 1 - alpha (blend
// zero, one minus source). No slot, no order: the device adds in whatever order it runs the
// fragments, at the targets' precision (composite::wboit_sorted, summed front to back in f32,
// is the twin within that rounding).

// Their eq. 10: a max(10^-2, 3 10^3 (1 - z)^3), z the window depth (composite::wboit_weight).
fn weight(z: f32, a: f32) -> f32 {
    let d = 1.0 - z;
    return a * max(3e3 * d * d * d, 1e-2);
}

struct Targets {
    @location(0) accumulation: vec4<f32>,
    @location(1) revealage: vec4<f32>,
};

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> Targets {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        discard;
    }
    let rgba = unpack_rgba8(f.rgba8);
    // The depth a capture key holds (fragment_key): what the twin weighs.
    let w = weight(select(0.0, in.clip.z, in.clip.z > 0.0), rgba.a);
    var out: Targets;
    out.accumulation = vec4<f32>(rgba.rgb * rgba.a * w, rgba.a * w);
    out.revealage = vec4<f32>(rgba.a);
    return out;
}
