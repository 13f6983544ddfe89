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
    let top = vec3<f32>(f32(1u << HDR_MAX_EXPONENT));
    let c = select(vec3<f32>(0.0), min(s.color.rgb, top), s.color.rgb > vec3<f32>(0.0));
    let e = hdr_exponent(c, HDR_MAX_EXPONENT);
    return (pack_rgba8(vec4<f32>(c / f32(1u << e), 0.0)) & CLEAR) | ((255u - e) << 24u);
}
