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
// (common.wgsl's stored_rgba8), and of non-zero 8-bit opacity.
fn transparent_fragment(in: VertexOut, front: bool) -> Transparent {
    var out: Transparent;
    out.visible = false;
    out.rgba8 = 0u;
    out.tint = CLEAR;
    let d = textureLoad(oit_opaque_depth, vec2<u32>(u32(in.clip.x), u32(in.clip.y)), 0);
    if (in.clip.z >= d) {
        return out;
    }
    let stored = stored_rgba8(oit_color);
    out.visible = (stored.x >> 24u) != 0u;
    out.rgba8 = stored.x;
    out.tint = CLEAR | (stored.y << 24u);
    return out;
}
