// The opaque pass (geometry, first in every frame): the OPAQUE and MASK triangles (MASK after
// its cutoff test), both of their faces where the material is double-sided, with a depth
// attachment (LESS, written) and each pixel's nearest colour as RGBA8 with A = 255 into an R32
// target (0 where none): what every transparent pass tests its depth against and every resolve
// composites over. Twin: raster.rs's opaque pass.

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) u32 {
    let s = shade(in, front);
    if (s.kind != SHADED_OPAQUE) {
        discard;
    }
    let c = clamp(s.color, vec4<f32>(0.0), vec4<f32>(1.0));
    return pack_rgba8(vec4<f32>(c.rgb, 1.0));
}
