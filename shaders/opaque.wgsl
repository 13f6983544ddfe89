// The opaque pass (geometry, first in every frame): the OPAQUE and MASK triangles (MASK after
// its cutoff test), both of their faces where the material is double-sided, with a depth
// attachment (LESS, written) and each pixel's nearest colour into an R32 target as
// fragment::pack_opaque stores it (RGB8 over 2^e low, 255 - e high; 0 where none): what every
// transparent pass tests its depth against and every resolve composites over. Twin: raster.rs's
// opaque pass.

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) u32 {
    let s = shade(in, front);
    if (s.kind != SHADED_OPAQUE) {
        discard;
    }
    // Every frame keeps an opaque colour's range: the word has room for its exponent.
    let stored = stored_rgba8_up_to(vec4<f32>(s.color.rgb, 0.0), HDR_MAX_EXPONENT);
    return (stored.x & CLEAR) | ((255u - stored.y) << 24u);
}
