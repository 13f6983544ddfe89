// Shared by every pass (prepended to each pass's source): frame parameters, the geometry
// vertex stage and fragment helpers. Mirrors runtime/src/raster.rs and composite.rs.

struct Params {
    view_proj: mat4x4<f32>,
    // xyz: unit vector from the eye towards the scene (the headlight); w unused.
    forward: vec4<f32>,
    // rgb: linear background colour; a unused.
    background: vec4<f32>,
    // xyz: the eye's world position (glass's view angle); w unused.
    eye: vec4<f32>,
    width: u32,
    height: u32,
    // FKB: slots per pixel; 0 when k comes from the per-pixel buffer.
    k_uniform: u32,
    pixels: u32,
    // F(M), saturated to 32 bits.
    budget_fragments: u32,
    // Variable k-buffer parameters (importance::VkbParams).
    vkb_alpha: f32,
    vkb_exponent: f32,
    vkb_noise: f32,
    vkb_seed: u32,
    // A relative budget in parts per million of the frame's fragments (0: F is
    // budget_fragments).
    budget_ppm: u32,
    // 1 when the k-buffer passes have n(p) bound and capture in two modes (capture.wgsl).
    append: u32,
    // 1 when FKB's slots are laid out layer-major (slot_at).
    layer_major: u32,
    // The scene's one opacity for every surface, or -1: the materials decide.
    uniform_alpha: f32,
    // 1 when the A-buffer's store keeps each fragment's submission index (abuffer_store.wgsl).
    store_primitives: u32,
    // MBOIT's moment bias and overestimation (composite::MboitParams).
    mboit_bias: f32,
    mboit_overestimation: f32,
    // The linked list's fragments a pixel sorted at resolve (list_resolve.wgsl).
    list_sorted: u32,
    // 1 when the k-buffer's tails live in its slot pool after each pixel's k slots (wgsl::Params).
    pooled_tail: u32,
    // WBOIT's weight function (composite::WboitWeight::code: 0-2 eqs. 7-9 of the view-space
    // distance, 3 eq. 10 of the window depth) and the camera's planes the first three read.
    wboit_weight: u32,
    wboit_near: f32,
    wboit_far: f32,
    // 1 when glass filters per channel (scene::Glass::Tinted): each fragment's tint is stored
    // beside its key (the A-buffer's `tints`).
    tinted: u32,
    // 1 when the frame's colours keep their range above white (scene::Scene::hdr): a
    // transparent fragment's RGB is stored over 2^e, e in the top byte of its tint word.
    hdr: u32,
    // DKB's records whose statistics its count pass gathers (features_count.wgsl;
    // wgsl::Params::dkb_records); 0 where the frame draws a features pass of its own.
    dkb_records: u32,
};

// Whether the methods that store fragments store each one's tint word beside its key: its
// tint (tinted glass) and its colour's exponent (colours above white).
fn stores_tints() -> bool {
    return params.tinted != 0u || params.hdr != 0u;
}

// One of a material's textures (wgsl::GpuTexture): where its texels start in the texel buffer
// (NO_TEXTURE: none), its size, its sampler (bits 0-1 and 2-3 the wrap modes along U and V,
// TEXTURE_NEAREST).
struct TextureRef {
    texels: u32,
    width: u32,
    height: u32,
    sampler: u32,
};

// A material (wgsl::GpuMaterial; scene::material): base colour factor, its textures (base
// colour, transmission, emissive), the emissive colour, flags (bits 4-5 the coverage
// COVERAGE_*, MATERIAL_DOUBLE_SIDED), MASK's cutoff, glass's transmission and F0, and what its
// volume lets through a crossing (tinted glass multiplies its tint by it).
struct Material {
    factor: vec4<f32>,
    base: TextureRef,
    transmission_texture: TextureRef,
    emissive_texture: TextureRef,
    emissive: vec3<f32>,
    flags: u32,
    cutoff: f32,
    transmission: f32,
    f0: f32,
    attenuation: vec3<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // The triangle's three vertices in clip space (x, y, w): the fragment stage interpolates
    // its attributes itself (geometry.wgsl's homogeneous_weights), as the CPU does.
    @location(0) @interpolate(flat) v0: vec3<f32>,
    @location(1) @interpolate(flat) primitive: u32,
    // |n . v| of the triangle (for the Fresnel importance and the headlight).
    @location(2) @interpolate(flat) facing: f32,
    @location(3) @interpolate(flat) v1: vec3<f32>,
    @location(4) @interpolate(flat) v2: vec3<f32>,
    // The triangle's geometric normal and material.
    @location(5) @interpolate(flat) normal: vec3<f32>,
    @location(6) @interpolate(flat) material: u32,
    // The triangle's vertices' world positions and colours, read by the vertex stage (so the
    // fragment stage binds three storage buffers, and a pass's own five fit WebGPU's eight).
    @location(7) @interpolate(flat) w0: vec3<f32>,
    @location(8) @interpolate(flat) w1: vec3<f32>,
    @location(9) @interpolate(flat) w2: vec3<f32>,
    @location(10) @interpolate(flat) c0: vec4<f32>,
    @location(11) @interpolate(flat) c1: vec4<f32>,
    @location(12) @interpolate(flat) c2: vec4<f32>,
};

// 8-bit unorm with rounding half up, as fragment::to_unorm8.
fn to_unorm8(v: f32) -> u32 {
    return u32(floor(clamp(v, 0.0, 1.0) * 255.0 + 0.5));
}

fn pack_rgba8(c: vec4<f32>) -> u32 {
    return to_unorm8(c.r) | (to_unorm8(c.g) << 8u) | (to_unorm8(c.b) << 16u) | (to_unorm8(c.a) << 24u);
}

// The tint of a fragment that passes every colour alike (fragment::CLEAR): RGB8, R low.
const CLEAR: u32 = 0x00ffffffu;

// What a fragment of straight colour `rgba` and tint `tint` lets through, per channel
// (fragment::transmittance): (1 - a) g.
fn tint_transmittance(rgba: vec4<f32>, tint: u32) -> vec3<f32> {
    return (1.0 - rgba.a) * unpack_rgba8(tint).rgb;
}

fn unpack_rgba8(v: u32) -> vec4<f32> {
    return vec4<f32>(
        f32(v & 0xffu), f32((v >> 8u) & 0xffu), f32((v >> 16u) & 0xffu), f32(v >> 24u)
    ) / 255.0;
}

// The exponent a colour is stored with (fragment::hdr_exponent): the smallest e in [0, max]
// whose 2^e is at least its brightest channel.
fn hdr_exponent(rgb: vec3<f32>, max_e: u32) -> u32 {
    let m = max(max(rgb.r, rgb.g), rgb.b);
    var e = 0u;
    while (e < max_e && m > f32(1u << e)) {
        e++;
    }
    return e;
}

// A colour stored with exponents up to `max_e` (fragment::quantize_hdr): x its RGBA8, its RGB
// clamped to [0, 2^max_e] and over 2^e; y that exponent e (0 within white).
fn stored_rgba8_up_to(color: vec4<f32>, max_e: u32) -> vec2<u32> {
    let top = vec3<f32>(f32(1u << max_e));
    let c = select(vec3<f32>(0.0), min(color.rgb, top), color.rgb > vec3<f32>(0.0));
    let e = hdr_exponent(c, max_e);
    return vec2<u32>(pack_rgba8(vec4<f32>(c / f32(1u << e), color.a)), e);
}

// A transparent fragment's colour as it is stored: clamped at white, or where the frame keeps
// colours above white (params.hdr) up to 2^HDR_MAX_EXPONENT (stored_rgba8_up_to).
fn stored_rgba8(color: vec4<f32>) -> vec2<u32> {
    return stored_rgba8_up_to(color, select(0u, HDR_MAX_EXPONENT, params.hdr != 0u));
}

// A stored fragment's colour: its RGBA8 `rgba8`, RGB times 2^e, e the top byte of its tint
// word `word` (CLEAR, or any word of exponent 0, where the colour is within white), as
// fragment::quantize_hdr decodes it.
fn stored_colour(rgba8: u32, word: u32) -> vec4<f32> {
    let c = unpack_rgba8(rgba8);
    return vec4<f32>(c.rgb * f32(1u << (word >> 24u)), c.a);
}

// Whether a tint word's tint filters anything (its RGB8 not CLEAR; the exponent aside).
fn filters(word: u32) -> bool {
    return (word & CLEAR) != CLEAR;
}


// A fragment's 64-bit capture key (fragment::fragment_key) as two 32-bit words, as a u64's
// bytes lie: the low word (x) its RGBA8, the high (y) its window depth's bits (non-negative
// floats order like their bits). Keys order by depth, then colour (key_less).
fn key_of(depth: f32, rgba8: u32) -> vec2<u32> {
    let d = select(0.0, depth, depth > 0.0);
    return vec2<u32>(rgba8, bitcast<u32>(d));
}

// Whether key a orders before key b (as u64s would).
fn key_less(a: vec2<u32>, b: vec2<u32>) -> bool {
    return a.y < b.y || (a.y == b.y && a.x < b.x);
}

// A k-buffer slot's key as two 32-bit words, each complemented so a cleared, zero slot is empty
// and atomicMax keeps the nearest: the depth word (fragment_key's high word) and the colour
// word, the fragment's RGBA8 less 2^24 (alpha is at least 1 in every fragment captured, so
// the colour word is never 0, even for opaque white, and it orders colours as RGBA8 does). A
// 64-bit slot holds the depth word high and the colour word low; the portable capture writes
// the same two words with 32-bit atomics (kbuffer_portable.wgsl), so both leave the same bytes.
// What the colour word takes off RGBA8: alpha 1, 2^24.
const SLOT_COLOUR_BIAS: u32 = 1u << 24u;

fn slot_depth_word(depth: f32) -> u32 {
    return ~key_of(depth, 0u).y;
}

fn slot_colour_word(rgba8: u32) -> u32 {
    return ~(rgba8 - SLOT_COLOUR_BIAS);
}

// The RGBA8 colour of a slot's colour word.
fn slot_rgba8(colour_word: u32) -> u32 {
    return (~colour_word) + SLOT_COLOUR_BIAS;
}

// What a fragment of colour `rgba8` adds to a tail's integer sums (composite::Tail): c8 a8 for
// r, g and b, and a8.
fn tail_sums_of(rgba8: u32) -> vec4<u32> {
    let a = rgba8 >> 24u;
    return vec4<u32>((rgba8 & 0xffu) * a, ((rgba8 >> 8u) & 0xffu) * a, ((rgba8 >> 16u) & 0xffu) * a, a);
}

// A tail's sums (c8 a8 for r, g, b, and a8) with a fragment of RGBA8 `rgba8` and tint word
// `word` added: c8 a8 2^e, e its colour's exponent, each colour sum saturating at 2^32 - 1
// rather than wrapping (composite::Tail::add).
fn add_tail_sums(sums: vec4<u32>, rgba8: u32, word: u32) -> vec4<u32> {
    let s = tail_sums_of(rgba8);
    let c = sums.xyz + (s.xyz << vec3<u32>(word >> 24u));
    return vec4<u32>(select(c, vec3<u32>(0xffffffffu), c < sums.xyz), sums.w + s.w);
}

// What a slot's colour word adds to its pixel's tail.
fn tail_sums(colour_word: u32) -> vec4<u32> {
    return tail_sums_of(slot_rgba8(colour_word));
}

// The index of an invocation of a pass dispatched as a 2-D grid of workgroups of `size`
// invocations (wgsl::grid): rows of at most 65,535 workgroups, so frames up to 8K fit.
fn grid_index(wid: vec3<u32>, nwg: vec3<u32>, lid: u32, size: u32) -> u32 {
    return (wid.y * nwg.x + wid.x) * size + lid;
}

// Workgroups of `size` invocations covering `n`, as a 2-D grid of rows of at most 65,535
// (wgsl::grid, which the host computes the same way).
fn grid_of(n: u32, size: u32) -> vec2<u32> {
    let groups = max((n + size - 1u) / size, 1u);
    let x = min(groups, 65535u);
    return vec2<u32>(x, (groups + x - 1u) / x);
}

// Record `index` as a record of the batch [lo, lo + size) of DKB's records (records.wgsl's
// record_index; totals.wgsl's record_counts, init_records): its place in the batch, or
// NO_RECORD where it is none of it (NO_RECORD itself; another batch's).
fn batch_record(index: u32, lo: u32, size: u32) -> u32 {
    if (index >= lo && index - lo < size) {
        return index - lo;
    }
    return NO_RECORD;
}

// Words of the allocation's marks' bits (one bit a pixel, MARK_BITS a word) for `pixels`
// pixels: the marks hold their popcounts' exclusive prefix sums (this many and the total), then
// the bits (shared::marks_words).
fn mark_blocks(pixels: u32) -> u32 {
    return (pixels + MARK_BITS - 1u) / MARK_BITS;
}

fn pixel_index(frag_coord: vec4<f32>, width: u32) -> u32 {
    return u32(frag_coord.y) * width + u32(frag_coord.x);
}

// Where slot i of pixel p lies, its slots starting at `base`: pixel-major (a pixel's slots
// together), or with FKB's layer-major layout (params.layer_major) slot i of every pixel
// together, so neighbouring pixels' fragments touch neighbouring words. Only FKB, which
// never appends, is laid out layer-major.
fn slot_at(base: u32, i: u32, p: u32) -> u32 {
    if (params.layer_major != 0u) {
        return i * params.pixels + p;
    }
    return base + i;
}

// The pooled tail (params.pooled_tail, shared::has_tail): a pixel keeps TAIL_WORDS words after
// its k slots where it truncates by more than TAIL_WORDS fragments, and else all its n
// fragments (shared::stored_k), so the slot bases are the prefix sums of its span,
// min(n, k + TAIL_WORDS). The tail's count is n - k.
fn has_tail(k: u32, n: u32) -> bool {
    return n > k + TAIL_WORDS;
}

fn span_of(k: u32, n: u32) -> u32 {
    return select(n, k + TAIL_WORDS, has_tail(k, n));
}

// k from a pixel's span and n: a span below n holds a tail (shared::k_of_span).
fn k_of_span(span: u32, n: u32) -> u32 {
    return select(span, span - TAIL_WORDS, span < n);
}

// Where the frame stores tint words, the k-buffers' (kbuffer_tint.wgsl, budget::Words): the
// word of slot s's tint word, and where the glass is tinted the first of the three sums of
// pixel p's tail (per-pixel tails: three sums a pixel, then a word a slot) or of the tail at
// word t of the pool (pooled: two words a pool word). Where the words hold exponents alone
// (colours above white, grey glass), one a slot or pool word and no sums.
fn tint_word(s: u32) -> u32 {
    if (params.tinted == 0u) {
        return s;
    }
    if (params.pooled_tail != 0u) {
        return 2u * s;
    }
    return 3u * params.pixels + s;
}

fn tail_tint_word(p: u32, t: u32) -> u32 {
    if (params.pooled_tail != 0u) {
        return 2u * t;
    }
    return 3u * p;
}

// Mesa's lavapipe ends a shader invocation's loops after 65,535 iterations in all, silently.
// Passes with long loops count theirs with tick() and report through a status word when they
// came close, so the host can refuse the frame instead of returning a wrong one.
const LOOP_BUDGET: u32 = 60000u;
var<private> ticks: u32 = 0u;

fn tick() {
    ticks += 1u;
}

// The resolves' status words (gpu::FrameStatus), 32-bit: word 0 the flags (STATUS_NEAR_LOOP
// where a pixel's loops came close to LOOP_BUDGET, STATUS_POOL_SHORT), word 1 unused; of the
// pixels over raster::MAX_FRAGMENTS_PER_PIXEL fragments (the per-pixel counts stop one past
// it, counts.wgsl), the largest index and the largest count, so the host refuses such a frame
// as the CPU rasterizer does. (Read as two 64-bit words, the second is (count << 32) | index.)
const STATUS_WORDS: u32 = 4u;
const STATUS_DEEPEST_PIXEL: u32 = 2u;
const STATUS_DEEPEST_COUNT: u32 = 3u;
