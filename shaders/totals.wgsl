// Frame totals (compute, one invocation a pixel): sum of n, covered pixels, the largest n, the
// pixels of two fragments or more and, where the buffer has a sixth word, of more than
// TAIL_WORDS (budget::Occupancy's deep and deeper ones, which bound the pooled tails), with
// integer atomics (importance::totals).

@group(0) @binding(0) var<uniform> params: Params;
// Two counts to a word (counts.wgsl).
@group(0) @binding(1) var<storage, read> count: array<u32>;
// fragments, covered, max count, deep, the records handed out (assign_records), deeper
@group(0) @binding(2) var<storage, read_write> totals: array<atomic<u32>>;

// A workgroup's sums, added to the frame's totals by one invocation: three atomics on the
// frame's three words a workgroup, not three a covered pixel (lavapipe spent about 6 ms of a
// 640x480 frame on those). Workgroup memory starts zeroed.
var<workgroup> group_fragments: atomic<u32>;
var<workgroup> group_covered: atomic<u32>;
var<workgroup> group_max: atomic<u32>;
var<workgroup> group_deep: atomic<u32>;
var<workgroup> group_deeper: atomic<u32>;

@compute @workgroup_size(PIXEL_GROUP)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p < params.pixels) {
        add_pixel(count_in(count[count_word(p)], p));
    }
    add_group(lid);
}

fn add_pixel(c: u32) {
    if (c > 0u) {
        atomicAdd(&group_fragments, c);
        atomicAdd(&group_covered, 1u);
        atomicMax(&group_max, c);
        if (c >= 2u) {
            atomicAdd(&group_deep, 1u);
        }
        if (c > TAIL_WORDS) {
            atomicAdd(&group_deeper, 1u);
        }
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
            atomicAdd(&totals[3], atomicLoad(&group_deep));
            if (arrayLength(&totals) > 5u) {
                atomicAdd(&totals[5], atomicLoad(&group_deeper));
            }
        }
    }
}

// DKB's records (features.wgsl): one for each pixel of more than TAIL_WORDS fragments (any
// fewer are all kept whatever k: shared::stored_k), RECORD_WORDS words in the slot pool, its
// index in the frame's shared word (NO_RECORD for the others), n in its colour sums' first
// word (bits 48-63). Indices from one atomic a workgroup, in any
// order: a record is its pixel's alone, so the order changes no result.
@group(0) @binding(6) var<storage, read_write> record_of: array<u32>;
@group(0) @binding(7) var<storage, read_write> records: array<u64>;

var<workgroup> group_records: atomic<u32>;
var<workgroup> group_first: u32;

@compute @workgroup_size(PIXEL_GROUP)
fn assign_records(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    var n = 0u;
    if (p < params.pixels) {
        n = count_in(count[count_word(p)], p);
    }
    var local = 0u;
    if (n > TAIL_WORDS) {
        local = atomicAdd(&group_records, 1u);
    }
    workgroupBarrier();
    if (lid == 0u) {
        group_first = atomicAdd(&totals[4], atomicLoad(&group_records));
    }
    workgroupBarrier();
    if (p < params.pixels) {
        if (n > TAIL_WORDS) {
            let r = group_first + local;
            record_of[p] = r;
            records[RECORD_WORDS * r + 1u] = u64(n) << 48u;
        } else {
            record_of[p] = NO_RECORD;
        }
    }
}
