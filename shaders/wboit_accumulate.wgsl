// WBOIT's accumulation pass (geometry), as McGuire and Bavoil lay it out: each visible
// transparent fragment adds its weighted premultiplied colour and weight to an RGBA16F target
// (blend one, one) and multiplies an R8 revealage target, cleared to 1, by 1 - alpha (blend
// zero, one minus source). No slot, no order: the device adds in whatever order it runs the
// fragments, at the targets' precision (composite::wboit_sorted, summed front to back in f32,
// is the twin within that rounding).

// The view-space distance of window depth d (composite::WboitParams::view_distance).
fn view_distance(d: f32) -> f32 {
    let n = params.wboit_near;
    let f = params.wboit_far;
    return n * f / (f - d * (f - n));
}

// Their eqs. 7-10 (composite::wboit_weight): a times a depth factor clamped to
// [10^-2, 3 10^3], of the view-space distance (7-9) or the window depth d (10).
fn weight(d: f32, a: f32) -> f32 {
    switch params.wboit_weight {
        case 0u: {
            let u = view_distance(d) / 5.0;
            let v = view_distance(d) / 200.0;
            let v3 = v * v * v;
            return a * clamp(10.0 / (1e-5 + u * u + v3 * v3), 1e-2, 3e3);
        }
        case 1u: {
            let u = view_distance(d) / 10.0;
            let v = view_distance(d) / 200.0;
            let v3 = v * v * v;
            return a * clamp(10.0 / (1e-5 + u * u * u + v3 * v3), 1e-2, 3e3);
        }
        case 2u: {
            let v = view_distance(d) / 200.0;
            let v2 = v * v;
            return a * clamp(0.03 / (1e-5 + v2 * v2), 1e-2, 3e3);
        }
        default: {
            let e = 1.0 - d;
            return a * max(3e3 * e * e * e, 1e-2);
        }
    }
}

struct Targets {
    @location(0) accumulation: vec4<f32>,
    @location(1) revealage: vec4<f32>,
};

fn accumulate(in: VertexOut, front: bool, tinted: bool) -> Targets {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        discard;
    }
    let rgba = stored_colour(f.rgba8, f.tint);
    // The depth a capture key holds (fragment_key): what the twin weighs.
    let w = weight(select(0.0, in.clip.z, in.clip.z > 0.0), rgba.a);
    var out: Targets;
    out.accumulation = vec4<f32>(rgba.rgb * rgba.a * w, rgba.a * w);
    out.revealage = vec4<f32>(rgba.a);
    if (tinted) {
        // RGB multiplies by the transmittance (1 - a) g, A by 1 - a (the revealage).
        out.revealage = vec4<f32>(1.0 - tint_transmittance(rgba, f.tint), rgba.a);
    }
    return out;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> Targets {
    return accumulate(in, front, false);
}

// Where the frame's glass is tinted: the revealage target is RGBA8, its RGB the product of the
// transmittances per channel (McGuire and Bavoil's coloured transmission).
@fragment
fn fs_tinted(in: VertexOut, @builtin(front_facing) front: bool) -> Targets {
    return accumulate(in, front, true);
}
