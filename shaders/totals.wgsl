// Frame totals (compute, one invocation a pixel): sum of n, covered pixels and the largest n,
// with integer atomics (importance::totals).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> count: array<u32>;
// fragments, covered, max count, unused
@group(0) @binding(2) var<storage, read_write> totals: array<atomic<u32>>;

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
    add_pixel(count[p]);
}

fn add_pixel(c: u32) {
    if (c > 0u) {
        atomicAdd(&totals[0], c);
        atomicAdd(&totals[1], 1u);
        atomicMax(&totals[2], c);
    }
}

// DKB's features pass, where it counts, keeps n in bits 48-63 of its first colour-sum word
// (features.wgsl): this entry writes it out as the count the passes after it read, and adds it
// to the totals as main does.
@group(0) @binding(4) var<storage, read> sums: array<u32>;
@group(0) @binding(5) var<storage, read_write> count_out: array<u32>;

@compute @workgroup_size(PIXEL_GROUP)
fn from_sums(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let c = sums[4u * p + 1u] >> 16u;
    count_out[p] = c;
    add_pixel(c);
}

// DKB's features pass is drawn indirectly from these arguments (vertices, instances, first
// vertex, first instance; the host writes the frame's vertex count): with no vertex when the
// budget holds every fragment, since k = n then whatever the importance (allocate.wgsl's
// setup, mlp::Mlp::dkb_importance).
@group(0) @binding(3) var<storage, read_write> features_draw_args: array<u32, 4>;

@compute @workgroup_size(1)
fn features_draw() {
    if (holds_every_fragment(atomicLoad(&totals[0]))) {
        features_draw_args[0] = 0u;
    }
}
