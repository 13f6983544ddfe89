// dhoit's fixed k-buffer (FKB), for an application's fragment shader (gpu::KBufferOit::wgsl):
// its bindings at the group the application chose (OIT_GROUP), and `oit_store`, which its
// transparent fragment shader calls with the fragment's position and straight (not
// premultiplied) colour. The fragment is inserted into its pixel's k slots, and the one pushed
// out goes to the pixel's tail, exactly as dhoit's own capture inserts (capture.wgsl, with the
// same kbuffer_insert.wgsl): any draw order gives the same slots and tail. The occluder is the
// application's opaque depth, bound here and tested as dhoit's own passes test theirs
// (oit_fragment.wgsl). Needs SHADER_INT64 in the module.

struct OitParams {
    width: u32,
    k: u32,
    _pad0: u32,
    _pad1: u32,
};

// k slots a pixel, pixel-major; per pixel, the tail's sums (two words) and its count.
@group(OIT_GROUP) @binding(0) var<storage, read_write> oit_slots: array<atomic<u64>>;
@group(OIT_GROUP) @binding(1) var<storage, read_write> oit_tail: array<atomic<u64>>;
@group(OIT_GROUP) @binding(2) var<storage, read_write> oit_tail_count: array<atomic<u32>>;
@group(OIT_GROUP) @binding(3) var<uniform> oit_params: OitParams;
// The application's opaque depth (1 where nothing opaque covers a pixel).
@group(OIT_GROUP) @binding(4) var oit_opaque_depth: texture_depth_2d;

fn oit_slot_at(base: u32, i: u32, p: u32) -> u32 {
    return base + i;
}

// Hands the fragment at `frag_coord` (the fragment's @builtin(position)) with straight colour
// `color` to dhoit. A fragment whose opacity rounds to 0 is not stored, as dhoit's own passes.
fn oit_store(frag_coord: vec4<f32>, color: vec4<f32>) {
    let key = oit_fragment_key(frag_coord, color);
    if (key == 0lu) {
        return;
    }
    let p = oit_pixel(frag_coord, oit_params.width);
    let k = oit_params.k;
    let out = oit_insert(p, p * k, k, ~key);
    if (out != 0lu) {
        oit_to_tail(p, out);
    }
}
