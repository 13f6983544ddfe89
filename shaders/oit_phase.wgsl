// One of dhoit's own geometry passes, for an application's fragment shader
// (gpu::AllocatedOit::store_module, gpu::BlendedOit::store_module): wgsl.rs's
// application_pass and application_blend_pass prepend this to the pass's own
// source, its group 1 moved to the group the application chose (OIT_GROUP) and its fragment
// entry made the function `oit_phase`, so the application's fragment runs exactly the code
// dhoit's own pass runs on its fragments. What geometry.wgsl gives dhoit's passes (the frame's
// parameters, the opaque depth, the transparent fragment) comes from here instead: the
// parameters and the application's opaque depth at bindings 14 and 15 of that group, and the
// fragment's colour from the application.

@group(OIT_GROUP) @binding(14) var<uniform> params: Params;
// The application's opaque depth (1 where nothing opaque covers a pixel).
@group(OIT_GROUP) @binding(15) var oit_opaque_depth: texture_depth_2d;

// The colour the application handed `oit_store`, for `transparent_fragment`.
var<private> oit_color: vec4<f32>;

struct Transparent {
    visible: bool,
    rgba8: u32,
    // An application's fragments are untinted: CLEAR, their colour's exponent in the top byte.
    tint: u32,
};

// As geometry.wgsl's: in front of the opaque depth (LESS), its colour 8 bits a channel
// (clamped at white, or where the frame keeps colours above white, params.hdr, its RGB over
// 2^e, e its exponent: geometry.wgsl's transparent_fragment), and of non-zero 8-bit opacity.
fn transparent_fragment(in: VertexOut, front: bool) -> Transparent {
    var out: Transparent;
    out.visible = false;
    out.rgba8 = 0u;
    out.tint = CLEAR;
    let d = textureLoad(oit_opaque_depth, vec2<u32>(u32(in.clip.x), u32(in.clip.y)), 0);
    if (in.clip.z >= d) {
        return out;
    }
    let max_e = select(0u, HDR_MAX_EXPONENT, params.hdr != 0u);
    let top = vec3<f32>(f32(1u << max_e));
    let c = select(vec3<f32>(0.0), min(oit_color.rgb, top), oit_color.rgb > vec3<f32>(0.0));
    let e = hdr_exponent(c, max_e);
    let rgba8 = pack_rgba8(vec4<f32>(c / f32(1u << e), oit_color.a));
    out.visible = (rgba8 >> 24u) != 0u;
    out.rgba8 = rgba8;
    out.tint = CLEAR | (e << 24u);
    return out;
}
