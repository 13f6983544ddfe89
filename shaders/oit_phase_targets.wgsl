// What an application's fragment shader returns to one of dhoit's blended geometry passes
// (wgsl.rs's application_blend_pass, after oit_phase.wgsl and the pass): `OitTargets`, the
// pass's outputs at its locations, which the application's fragment entry returns into the
// targets dhoit hands its render pass (gpu::BlendedOit::color_attachments). wgsl.rs fills in
// the type (the pass entry's own, or a struct of its one location) and how a value of the
// entry's becomes one.

OIT_TARGETS_TYPE

// The fragment at `frag_coord` (the fragment's @builtin(position)) with straight colour
// `color`, as dhoit's pass writes it; discarded where dhoit's pass discards it (behind the
// opaque depth, or of zero 8-bit opacity).
fn oit_targets(frag_coord: vec4<f32>, color: vec4<f32>) -> OitTargets {
    var v: VertexOut;
    v.clip = frag_coord;
    v.facing = 1.0;
    oit_color = color;
    return OIT_TARGETS_OF(oit_phase(v, true));
}
