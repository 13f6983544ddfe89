// Frame totals (compute, one invocation a pixel): sum of n, covered pixels, the largest n, the
// pixels of two fragments or more and, where the buffer has a sixth word, of more than
// TAIL_WORDS (budget::Occupancy's deep and deeper ones, which bound the pooled tails), with
// integer atomics (importance::totals).

@group(0) @binding(0) var<uniform> params: Params;
// Two counts to a word (counts.wgsl).
@group(0) @binding(1) var<storage, read> count: array<u32>;
// The TOTAL_* words (shared.rs): fragments, covered, max count, deep, the records marked (the
// host copies the marks' total there), deeper; then the plan's (plan.wgsl).
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
// fewer are all kept whatever k: shared::stored_k), RECORD_WORDS words in the slot pool, in
// pixel order (records.wgsl's record_index), n in its colour sums' first word (bits 48-63).
// mark_records marks those pixels of a frame's count: for its own features pass (a frame's
// first, or one after a cut), or for the frame after, which gathers its statistics with its
// count (features_count.wgsl). A pixel's record is the same whatever the order of
// the fragments or the invocations.
//
// The records are gathered in batches where the pool holds fewer than all of them
// (budget::PoolState::batch): a batch is the records [lo, lo + per_batch), at the pool's start
// while the features pass fills them and the network reads them; its importance is gathered
// into the shared word before the next batch takes the pool (init_records, next_batch). One
// batch is the whole frame's records, and the one a frame that gathers with its count has.
// The marks (shared::marks_words): the exclusive prefix sums of their words' popcounts (scan.wgsl
// built for marks makes them from the popcounts mark_records writes) and their total, then the
// bits.
@group(0) @binding(6) var<storage, read_write> record_marks: array<u32>;
// Each record word a 64-bit word's two halves (low x, high y), as features.wgsl adds to them.
@group(0) @binding(7) var<storage, read_write> records: array<vec2<u32>>;
// The BATCH_* words: the network's list length, the batch's first record lo, the records a
// batch holds, and the rows the network ran on in the batches before (importance_dkb.wgsl's
// list_len).
@group(0) @binding(8) var<storage, read_write> batch: array<u32>;

// A workgroup's marks, a bit a pixel: PIXEL_GROUP consecutive pixels, whole words of them.
var<workgroup> record_bits: array<atomic<u32>, PIXEL_GROUP / MARK_BITS>;

// The pixels of more than TAIL_WORDS fragments marked: a bit a pixel, and each word's popcount
// where the marks' scan makes its prefix (as allocate.wgsl's mark).
@compute @workgroup_size(PIXEL_GROUP)
fn mark_records(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    let words = PIXEL_GROUP / MARK_BITS;
    if (lid < words) {
        atomicStore(&record_bits[lid], 0u);
    }
    workgroupBarrier();
    if (p < params.pixels && count_in(count[count_word(p)], p) > TAIL_WORDS) {
        atomicOr(&record_bits[lid / MARK_BITS], 1u << (lid % MARK_BITS));
    }
    workgroupBarrier();
    let blocks = mark_blocks(params.pixels);
    let word = (p - lid) / MARK_BITS + lid;
    if (lid < words && word < blocks) {
        let bits = atomicLoad(&record_bits[lid]);
        record_marks[blocks + 1u + word] = bits;
        record_marks[word] = countOneBits(bits);
    }
}

// n into the records of the first batch, in its colour sums' first word (bits 48-63), beside
// the sums there: none yet, where the frame draws a features pass after; the count's, where it
// gathered them with its count (features.wgsl's adds never carry past bit 47).
@compute @workgroup_size(PIXEL_GROUP)
fn record_counts(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let r = batch_record(record_index(p), 0u, batch[BATCH_SIZE]);
    if (r != NO_RECORD) {
        let at = RECORD_WORDS * r + 1u;
        let n = count_in(count[count_word(p)], p);
        records[at].y = (records[at].y & 0xffffu) | (n << 16u);
    }
}

// A batch after the first: its records emptied (the batch before them left its statistics and
// importance there), n written. The batch starts where the one before ends (next_batch moves
// lo there after this).
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
    let r = batch_record(record_index(p), batch[BATCH_LO] + batch[BATCH_SIZE], batch[BATCH_SIZE]);
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
