// What an application's fragment shader calls to hand its fragment to one of dhoit's own
// storing geometry passes (wgsl.rs's application_pass, after oit_phase.wgsl and the pass).

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

// oit_store with the fragment's submission index `order` (the index of its triangle in the
// application's submission, say), which MLAB merges a pixel's fragments in, whatever order
// they arrive in; the other methods ignore it.
fn oit_store_ordered(frag_coord: vec4<f32>, color: vec4<f32>, order: u32) {
    var v: VertexOut;
    v.clip = frag_coord;
    v.facing = 1.0;
    v.primitive = order;
    oit_color = color;
    _ = oit_phase(v, true);
}
