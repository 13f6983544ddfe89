// Frame totals (compute, one invocation a pixel): sum of n, covered pixels and the largest n,
// with integer atomics (importance::totals).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> count: array<u32>;
// fragments, covered, max count, unused
@group(0) @binding(2) var<storage, read_write> totals: array<atomic<u32>>;

// A workgroup's sums, added to the frame's totals by one invocation: three atomics on the
// frame's three words a workgroup, not three a covered pixel (lavapipe spent about 6 ms of a
// 640x480 frame on those). Workgroup memory starts zeroed.
var<workgroup> group_fragments: atomic<u32>;
var<workgroup> group_covered: atomic<u32>;
var<workgroup> group_max: atomic<u32>;

@compute @workgroup_size(PIXEL_GROUP)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p < params.pixels) {
        add_pixel(count[p]);
    }
    add_group(lid);
}

fn add_pixel(c: u32) {
    if (c > 0u) {
        atomicAdd(&group_fragments, c);
        atomicAdd(&group_covered, 1u);
        atomicMax(&group_max, c);
    }
}

// After every invocation of the workgroup has added its pixel (the barrier is reached by all:
// uniform control flow).
fn add_group(lid: u32) {
    workgroupBarrier();
    if (lid == 0u) {
        let covered = atomicLoad(&group_covered);
        if (covered > 0u) {
            atomicAdd(&totals[0], atomicLoad(&group_fragments));
            atomicAdd(&totals[1], covered);
            atomicMax(&totals[2], atomicLoad(&group_max));
        }
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
    if (p < params.pixels) {
        let c = sums[4u * p + 1u] >> 16u;
        count_out[p] = c;
        add_pixel(c);
    }
    add_group(lid);
}

// DKB's features pass is drawn indirectly from these arguments (an indexed draw: indices,
// instances, first index, base vertex, first instance; the host writes the frame's
// transparent indices): with none when the budget holds every fragment, since k = n then
// whatever the importance (allocate.wgsl's setup, mlp::Mlp::dkb_importance).
@group(0) @binding(3) var<storage, read_write> features_draw_args: array<u32, 5>;

@compute @workgroup_size(1)
fn features_draw() {
    if (holds_every_fragment(atomicLoad(&totals[0]))) {
        features_draw_args[0] = 0u;
    }
}
