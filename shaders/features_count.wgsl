// DKB's count with its statistics (features.wgsl built with this: gpu::Phase::CountFeatures):
// each fragment counted, as abuffer_count.wgsl counts it, two to a word (counts.wgsl); then its
// pixel's record, where it is among the first params.dkb_records (the marks the frame before
// left: none where the frame draws a features pass after its count).

@group(1) @binding(4) var<storage, read_write> counts: array<atomic<u32>>;

// The fragment of pixel p counted; its pixel's record, or NO_RECORD.
fn fragment_record(p: u32) -> u32 {
    let w = count_word(p);
    if (count_stopped(atomicAdd(&counts[w], count_unit(p)), p)) {
        atomicSub(&counts[w], count_unit(p));
    }
    if (params.dkb_records == 0u) {
        return NO_RECORD;
    }
    return batch_record(record_index(p), 0u, params.dkb_records);
}
