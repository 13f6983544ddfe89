// Frame totals (compute, one invocation a pixel): sum of n, covered pixels, the largest n, the
// pixels of two fragments or more and, where the buffer has a sixth word, of more than
// TAIL_WORDS (budget::Occupancy's deep and deeper ones, which bound the pooled tails), with
// integer atomics (importance::totals).

@group(0) @binding(0) var<uniform> params: Params;
// Two counts to a word (counts.wgsl).
@group(0) @binding(1) var<storage, read> count: array<u32>;
// The TOTAL_* words (shared.rs): fragments, covered, max count, deep, the records handed out
// (assign_records), deeper; then the plan's (plan.wgsl).
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
            atomicAdd(&totals[TOTAL_FRAGMENTS], atomicLoad(&group_fragments));
            atomicAdd(&totals[TOTAL_COVERED], covered);
            atomicMax(&totals[TOTAL_MAX_COUNT], atomicLoad(&group_max));
            atomicAdd(&totals[TOTAL_DEEP], atomicLoad(&group_deep));
            if (arrayLength(&totals) > TOTAL_DEEPER) {
                atomicAdd(&totals[TOTAL_DEEPER], atomicLoad(&group_deeper));
            }
        }
    }
}

// DKB's records (features.wgsl): one for each pixel of more than TAIL_WORDS fragments (any
// fewer are all kept whatever k: shared::stored_k), RECORD_WORDS words in the slot pool, its
// index in the frame's shared word (NO_RECORD for the others), n in its colour sums' first
// word (bits 48-63). Indices from one atomic a workgroup, in any
// order: a record is its pixel's alone, so the order changes no result.
//
// The records are gathered in batches where the pool holds fewer than all of them
// (budget::PoolState::batch): a batch is the records [lo, lo + per_batch), at the pool's start
// while the features pass fills them and the network reads them; its importance is gathered
// into the shared word before the next batch takes the pool (init_records, next_batch). One
// batch is the whole frame's records.
@group(0) @binding(6) var<storage, read_write> record_of: array<u32>;
// Each record word a 64-bit word's two halves (low x, high y), as features.wgsl adds to them.
@group(0) @binding(7) var<storage, read_write> records: array<vec2<u32>>;
// The BATCH_* words: the network's list length, the batch's first record lo, the records a
// batch holds, and the rows the network ran on in the batches before (importance_dkb.wgsl's
// list_len).
@group(0) @binding(8) var<storage, read_write> batch: array<u32>;

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
        group_first = atomicAdd(&totals[TOTAL_RECORDS], atomicLoad(&group_records));
    }
    workgroupBarrier();
    if (p < params.pixels) {
        if (n > TAIL_WORDS) {
            let r = group_first + local;
            record_of[p] = r;
            // The first batch's records (the pool is zero until then).
            if (r < batch[BATCH_SIZE]) {
                records[RECORD_WORDS * r + 1u] = vec2<u32>(0u, n << 16u);
            }
        } else {
            record_of[p] = NO_RECORD;
        }
    }
}

// A batch after the first: its records emptied (the batch before them left its statistics and
// importance there), n written. The batch starts where the one before ends (next_batch moves
// lo there after this). A pixel of an earlier batch holds its importance by now, and one
// without a record 0 (the first batch's gather wrote it): neither is a record of the batch
// (common.wgsl's batch_record).
@compute @workgroup_size(PIXEL_GROUP)
fn init_records(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let r = batch_record(record_of[p], batch[BATCH_LO] + batch[BATCH_SIZE], batch[BATCH_SIZE]);
    if (r != NO_RECORD) {
        let at = RECORD_WORDS * r;
        records[at] = vec2<u32>(0u);
        records[at + 1u] = vec2<u32>(0u, count_in(count[count_word(p)], p) << 16u);
        for (var w = 2u; w < RECORD_WORDS; w++) {
            records[at + w] = vec2<u32>(0u);
        }
    }
}

// The next batch: lo moves past the batch before, whose list's length is added to the rows run
// and emptied (one invocation, after init_records).
@compute @workgroup_size(1)
fn next_batch() {
    batch[BATCH_ROWS_BEFORE] += batch[BATCH_LISTED];
    batch[BATCH_LISTED] = 0u;
    batch[BATCH_LO] += batch[BATCH_SIZE];
}
