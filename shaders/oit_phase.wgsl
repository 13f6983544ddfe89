// One of dhoit's own geometry passes, for an application's fragment shader
// (gpu::DeepOit::store_module): wgsl.rs's application_pass prepends this to the pass's own
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
};

// As geometry.wgsl's: in front of the opaque depth (LESS), its colour clamped to 8 bits a
// channel, and of non-zero 8-bit opacity.
fn transparent_fragment(in: VertexOut, front: bool) -> Transparent {
    var out: Transparent;
    out.visible = false;
    out.rgba8 = 0u;
    let d = textureLoad(oit_opaque_depth, vec2<u32>(u32(in.clip.x), u32(in.clip.y)), 0);
    if (in.clip.z >= d) {
        return out;
    }
    let rgba8 = pack_rgba8(clamp(oit_color, vec4<f32>(0.0), vec4<f32>(1.0)));
    out.visible = (rgba8 >> 24u) != 0u;
    out.rgba8 = rgba8;
    return out;
}

// Hands the fragment at `frag_coord` (the fragment's @builtin(position)) with straight colour
// `color` to the pass this module was built for, its triangle's facing `|n . v|` (n its
// geometric normal, v the camera's forward direction) for VKB's importance.
fn oit_store_facing(frag_coord: vec4<f32>, color: vec4<f32>, facing: f32) {
    var v: VertexOut;
    v.clip = frag_coord;
    v.facing = facing;
    oit_color = color;
    _ = oit_phase(v, true);
}

// oit_store_facing, face-on (all a method but VKB reads).
fn oit_store(frag_coord: vec4<f32>, color: vec4<f32>) {
    oit_store_facing(frag_coord, color, 1.0);
}
