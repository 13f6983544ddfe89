// VKB importance (compute, one invocation a pixel), as importance::vkb_importance:
// I = max(0, I_per I_f I_d + lambda (xi - 0.5)) with depth complexity, periphery, the Fresnel
// term of the nearest fragment and per-pixel hash noise.

@group(0) @binding(0) var<uniform> params: Params;
// Two counts to a word (counts.wgsl).
@group(0) @binding(1) var<storage, read> count: array<u32>;
// The frame's shared word a pixel (oit.offsets): the count pass's nearest key (complemented,
// vkb_count.wgsl), which each invocation reads and then overwrites with its pixel's importance.
@group(0) @binding(2) var<storage, read_write> word: array<u32>;
@group(0) @binding(3) var<storage, read> totals: array<u32>;

fn pcg_hash(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

@compute @workgroup_size(PIXEL_GROUP)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let c = count_in(count[count_word(p)], p);
    if (c == 0u) {
        word[p] = bitcast<u32>(0.0);
        return;
    }
    let limit = f32(max(totals[TOTAL_MAX_COUNT], 1u));
    let alpha = params.vkb_alpha;
    let i_d = alpha + (1.0 - alpha) * min(f32(c) / limit, 1.0);
    let w = f32(params.width);
    let h = f32(params.height);
    let half_diag = 0.5 * sqrt(w * w + h * h);
    let x = f32(p % params.width) + 0.5 - 0.5 * w;
    let y = f32(p / params.width) + 0.5 - 0.5 * h;
    let r = min(sqrt(x * x + y * y) / half_diag, 1.0);
    let i_per = 1.0 - pow(r, params.vkb_exponent);
    // importance::vkb_key_facing.
    let facing = f32((~word[p]) & 0xffu) / 255.0;
    let g = 1.0 - facing;
    let i_f = 1.0 - g * g * g * g * g * 0.5;
    let xi = f32(pcg_hash(p ^ pcg_hash(params.vkb_seed)) >> 8u) / 16777216.0;
    // abs: never the sign bit, which the allocation reads as the pair flag (VKB has none).
    word[p] = bitcast<u32>(abs(max(i_per * i_f * i_d + params.vkb_noise * (xi - 0.5), 0.0)));
}
