// What a resolve composites a pixel's fragments over: the opaque pass's colour where an opaque
// surface covers the pixel (fragment::pack_opaque's word: RGB8 over 2^e low, 255 - e high; 0
// where none), else the background, as fragment::FragmentLists::behind.

@group(0) @binding(15) var opaque_color: texture_2d<u32>;

fn behind(p: u32) -> vec3<f32> {
    let c = textureLoad(opaque_color, vec2<u32>(p % params.width, p / params.width), 0).r;
    if ((c >> 24u) != 0u) {
        return unpack_rgba8(c).rgb * f32(1u << min(255u - (c >> 24u), 31u));
    }
    return params.background.rgb;
}
