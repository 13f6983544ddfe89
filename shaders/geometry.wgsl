// Vertex stage of every geometry pass, and the material per fragment (the twin of
// scene::material::shade and raster.rs's Shading). Positions, colours and texture coordinates
// come from storage buffers indexed by vertex_index (three vertices per triangle, in submission
// order; an index buffer lists the transparent triangles' vertices, then the opaque ones'), so
// the stage can read its triangle's other vertices for the face normal of the headlight
// shading, and hand the fragment stage all three in clip space: it interpolates colour,
// texture coordinates and world position at weights it computes as raster.rs does
// (homogeneous_weights), not at the hardware's, so the CPU and the GPU shade alike. Every transparent pass tests its fragments against the opaque pass's depth (LESS, as
// a depth attachment would; read in the shader, so the test comes before the pass's atomics on
// every device) and drops those of zero 8-bit opacity.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> colors: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> uvs: array<vec2<f32>>;
// Per triangle, its material.
@group(0) @binding(4) var<storage, read> triangle_material: array<u32>;
@group(0) @binding(5) var<storage, read> materials: array<Material>;
// Every texture's RGBA8 texels (colour sRGB-encoded), one after another.
@group(0) @binding(6) var<storage, read> texels: array<u32>;
// sRGB -> linear for the 256 8-bit values, four to a vec4 (material::srgb_table).
@group(0) @binding(7) var<uniform> srgb: array<vec4<f32>, 64>;

@vertex
fn vs_main(@builtin(vertex_index) vid: u32) -> VertexOut {
    let tri = vid / 3u;
    let p0 = positions[3u * tri].xyz;
    let p1 = positions[3u * tri + 1u].xyz;
    let p2 = positions[3u * tri + 2u].xyz;
    let n = normalize(cross(p1 - p0, p2 - p0));
    let facing = abs(dot(n, params.forward.xyz));
    let q0 = params.view_proj * vec4<f32>(p0, 1.0);
    let q1 = params.view_proj * vec4<f32>(p1, 1.0);
    let q2 = params.view_proj * vec4<f32>(p2, 1.0);
    var out: VertexOut;
    let corner = vid - 3u * tri;
    out.clip = select(select(q2, q1, corner == 1u), q0, corner == 0u);
    out.v0 = q0.xyw;
    out.v1 = q1.xyw;
    out.v2 = q2.xyw;
    out.primitive = tri;
    out.facing = facing;
    out.normal = n;
    out.material = triangle_material[tri];
    out.w0 = p0;
    out.w1 = p1;
    out.w2 = p2;
    out.c0 = colors[3u * tri];
    out.c1 = colors[3u * tri + 1u];
    out.c2 = colors[3u * tri + 2u];
    return out;
}

// Perspective-correct barycentric weights of the pixel at NDC p from the triangle's clip-space
// vertices (x, y, w): 2-D homogeneous edge functions, normalised (raster::homogeneous_weights).
fn homogeneous_weights(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, p: vec2<f32>) -> vec3<f32> {
    let e0 = (b.y * c.z - b.z * c.y) * p.x + (b.z * c.x - b.x * c.z) * p.y + (b.x * c.y - b.y * c.x);
    let e1 = (c.y * a.z - c.z * a.y) * p.x + (c.z * a.x - c.x * a.z) * p.y + (c.x * a.y - c.y * a.x);
    let e2 = (a.y * b.z - a.z * b.y) * p.x + (a.z * b.x - a.x * b.z) * p.y + (a.x * b.y - a.y * b.x);
    let inv = 1.0 / (e0 + e1 + e2);
    return vec3<f32>(e0 * inv, e1 * inv, e2 * inv);
}

// A fragment's interpolated attributes (raster.rs's Shading::shade).
struct Attributes {
    color: vec4<f32>,
    uv: vec2<f32>,
    world: vec3<f32>,
};

fn attributes(in: VertexOut) -> Attributes {
    let p = vec2<f32>(
        (in.clip.x / f32(params.width)) * 2.0 - 1.0,
        1.0 - (in.clip.y / f32(params.height)) * 2.0,
    );
    let l = homogeneous_weights(in.v0, in.v1, in.v2, p);
    let t = 3u * in.primitive;
    let shade = AMBIENT + (1.0 - AMBIENT) * in.facing;
    var out: Attributes;
    let c0 = in.c0;
    let c1 = in.c1;
    let c2 = in.c2;
    let s0 = vec4<f32>(c0.rgb * shade, c0.a);
    let s1 = vec4<f32>(c1.rgb * shade, c1.a);
    let s2 = vec4<f32>(c2.rgb * shade, c2.a);
    // A channel the three vertices share is taken as is, not interpolated: no rounding of the
    // weights moves it across an 8-bit step (alpha 0.3 is 76.5 / 255).
    let same = (s0 == s1) & (s1 == s2);
    out.color = select((s0 * l.x + s1 * l.y) + s2 * l.z, s0, same);
    out.uv = (uvs[t] * l.x + uvs[t + 1u] * l.y) + uvs[t + 2u] * l.z;
    out.world = (in.w0 * l.x + in.w1 * l.y) + in.w2 * l.z;
    return out;
}

// Texel (x, y) of texture `t`, decoded: colour through the sRGB table, alpha times
// ALPHA_SCALE (material::Texture::texel); a data texture's (`srgb` false) every channel times
// ALPHA_SCALE (material::data_table).
fn texel(t: TextureRef, x: i32, y: i32, srgb_colour: bool) -> vec4<f32> {
    let v = texels[t.texels + u32(y) * t.width + u32(x)];
    let r = v & 0xffu;
    let g = (v >> 8u) & 0xffu;
    let b = (v >> 16u) & 0xffu;
    let a = f32(v >> 24u) * ALPHA_SCALE;
    if (!srgb_colour) {
        return vec4<f32>(f32(r) * ALPHA_SCALE, f32(g) * ALPHA_SCALE, f32(b) * ALPHA_SCALE, a);
    }
    return vec4<f32>(srgb[r >> 2u][r & 3u], srgb[g >> 2u][g & 3u], srgb[b >> 2u][b & 3u], a);
}

// Texel i of an axis of n as the wrap mode places it (material::wrap): 0 repeat, 1 mirrored
// repeat, 2 clamp to edge.
fn wrap(i: i32, n: i32, mode: u32) -> i32 {
    if (mode == 0u) {
        return ((i % n) + n) % n;
    }
    if (mode == 1u) {
        let j = ((i % (2 * n)) + 2 * n) % (2 * n);
        return select(2 * n - 1 - j, j, j < n);
    }
    return clamp(i, 0, n - 1);
}

// Texture `t` at `uv` (material::Texture::sample): nearest, or bilinear between the four texels
// around uv * size - 0.5, each axis wrapped by its mode; arithmetic written out, not the
// hardware filter, so the CPU computes the same. `srgb_colour` false for a data texture.
fn sample_texture(t: TextureRef, uv: vec2<f32>, srgb_colour: bool) -> vec4<f32> {
    let w = i32(t.width);
    let h = i32(t.height);
    let wrap_s = t.sampler & 3u;
    let wrap_t = (t.sampler >> 2u) & 3u;
    if ((t.sampler & TEXTURE_NEAREST) != 0u) {
        let x = i32(floor(clamp(uv.x * f32(w), -TEXEL_LIMIT, TEXEL_LIMIT)));
        let y = i32(floor(clamp(uv.y * f32(h), -TEXEL_LIMIT, TEXEL_LIMIT)));
        return texel(t, wrap(x, w, wrap_s), wrap(y, h, wrap_t), srgb_colour);
    }
    let x = clamp(uv.x * f32(w) - 0.5, -TEXEL_LIMIT, TEXEL_LIMIT);
    let y = clamp(uv.y * f32(h) - 0.5, -TEXEL_LIMIT, TEXEL_LIMIT);
    let xf = floor(x);
    let yf = floor(y);
    let fx = x - xf;
    let fy = y - yf;
    let x0 = i32(xf);
    let y0 = i32(yf);
    let xa = wrap(x0, w, wrap_s);
    let xb = wrap(x0 + 1, w, wrap_s);
    let ya = wrap(y0, h, wrap_t);
    let yb = wrap(y0 + 1, h, wrap_t);
    let top = texel(t, xa, ya, srgb_colour) * (1.0 - fx) + texel(t, xb, ya, srgb_colour) * fx;
    let bottom = texel(t, xa, yb, srgb_colour) * (1.0 - fx) + texel(t, xb, yb, srgb_colour) * fx;
    return top * (1.0 - fy) + bottom * fy;
}

// Schlick's reflectance at view cosine `c` (material::fresnel).
fn fresnel(f0: f32, c: f32) -> f32 {
    let m = 1.0 - clamp(c, 0.0, 1.0);
    let m2 = m * m;
    return f0 + (1.0 - f0) * (m2 * m2 * m);
}

// The opacity of glass at view cosine `c` (material::glass_opacity).
fn glass_opacity(transmission: f32, f0: f32, c: f32) -> f32 {
    return 1.0 - transmission * (1.0 - fresnel(f0, c));
}

// What a fragment is once shaded (material::Shaded): kind SHADED_OPAQUE, SHADED_TRANSPARENT or
// SHADED_NONE (a MASK test failed, or a back face of a single-sided material), and its colour
// (not yet clamped).
struct Shaded {
    kind: u32,
    color: vec4<f32>,
    // (1, 1, 1) but for tinted glass (material::tinted_glass).
    tint: vec3<f32>,
};

// The fragment's material (material::shade).
fn shade(in: VertexOut, front: bool) -> Shaded {
    let m = materials[in.material];
    var out: Shaded;
    out.kind = SHADED_NONE;
    out.tint = vec3<f32>(1.0);
    let uniform = params.uniform_alpha >= 0.0;
    if (!uniform && (m.flags & MATERIAL_DOUBLE_SIDED) == 0u && !front) {
        return out;
    }
    let at = attributes(in);
    var c = at.color * m.factor;
    // The base colour without the vertex's, and the volume's attenuation (tinted glass's tint).
    var base = m.factor.rgb * m.attenuation;
    if (m.base.texels != NO_TEXTURE) {
        let s = sample_texture(m.base, at.uv, true);
        c = c * s;
        base = base * s.rgb;
    }
    let lit = c.rgb;
    // Emission, after the headlight's shade (in at.color), which does not dim it.
    var e = vec3<f32>(0.0);
    if (any(m.emissive != vec3<f32>(0.0))) {
        e = m.emissive;
        if (m.emissive_texture.texels != NO_TEXTURE) {
            e = e * sample_texture(m.emissive_texture, at.uv, true).rgb;
        }
        c = vec4<f32>(c.rgb + e, c.a);
    }
    out.color = c;
    if (uniform) {
        out.color.a = params.uniform_alpha;
        out.kind = SHADED_TRANSPARENT;
        return out;
    }
    let coverage = (m.flags >> 4u) & 3u;
    if (coverage == COVERAGE_MASK && c.a < m.cutoff) {
        return out;
    }
    let glass = m.transmission > 0.0;
    if (coverage != COVERAGE_BLEND && !glass) {
        out.kind = SHADED_OPAQUE;
        return out;
    }
    let a = select(1.0, c.a, coverage == COVERAGE_BLEND);
    if (glass) {
        let v = at.world - params.eye.xyz;
        let cosine = abs(dot(in.normal, v)) / length(v);
        var t = m.transmission;
        if (m.transmission_texture.texels != NO_TEXTURE) {
            t = t * sample_texture(m.transmission_texture, at.uv, false).r;
        }
        let opacity = glass_opacity(t, m.f0, cosine);
        out.color.a = a * opacity;
        if (params.tinted != 0u && opacity > 0.0) {
            // material::tinted_glass: the Fresnel reflection of the lit vertex colour and the
            // diffuse colour of what is neither reflected nor transmitted, over the opacity;
            // the tint such that (1 - a) g is (1 - cov) + cov t (1 - f) base.
            let f = fresnel(m.f0, cosine);
            let diffuse = (1.0 - t) * (1.0 - f);
            let colour = (f * at.color.rgb + diffuse * lit) / opacity;
            out.color = vec4<f32>(colour + e, out.color.a);
            let through = t * (1.0 - f);
            let grey = (1.0 - a) + a * through;
            let b = clamp(base, vec3<f32>(0.0), vec3<f32>(1.0));
            if (a >= 1.0) {
                out.tint = b;
            } else if (grey > 0.0) {
                out.tint = ((1.0 - a) + a * through * b) / grey;
            }
        }
    } else {
        out.color.a = a;
    }
    out.kind = SHADED_TRANSPARENT;
    return out;
}

// The nearest opaque surface's depth (the opaque pass's depth attachment; 1 where none).
@group(0) @binding(8) var opaque_depth: texture_depth_2d;

// A transparent pass's fragment: its RGBA8, or none (0 after `visible` says false).
struct Transparent {
    visible: bool,
    // Its RGB over 2^e (e its exponent, 0 within white) and alpha, 8 bits each.
    rgba8: u32,
    // Its tint word: the tint, RGB8 (CLEAR but for tinted glass), and e in the top byte.
    tint: u32,
};

// The fragment as a transparent pass stores it: in front of the opaque depth, transparent,
// and of non-zero 8-bit opacity (raster.rs's transparent pass); its colour 8 bits a channel
// (common.wgsl's stored_rgba8: clamped at white, or where the frame keeps colours above white,
// its RGB over 2^e).
fn transparent_fragment(in: VertexOut, front: bool) -> Transparent {
    var out: Transparent;
    out.visible = false;
    out.rgba8 = 0u;
    out.tint = CLEAR;
    let d = textureLoad(opaque_depth, vec2<u32>(u32(in.clip.x), u32(in.clip.y)), 0);
    if (in.clip.z >= d) {
        return out;
    }
    let s = shade(in, front);
    if (s.kind != SHADED_TRANSPARENT) {
        return out;
    }
    let stored = stored_rgba8(s.color);
    out.visible = (stored.x >> 24u) != 0u;
    out.rgba8 = stored.x;
    out.tint = pack_rgba8(vec4<f32>(clamp(s.tint, vec3<f32>(0.0), vec3<f32>(1.0)), 0.0)) | (stored.y << 24u);
    return out;
}
