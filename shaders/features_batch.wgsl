// DKB's features pass of its own (features.wgsl built with this: gpu::Phase::Features): the
// records of the batch this draw gathers.

// The batch (totals.wgsl): BATCH_LO its first record, BATCH_SIZE how many a batch holds; its
// records lie from the pool's start.
@group(1) @binding(3) var<storage, read> batch: array<u32>;

// Pixel p's record where it is of the batch, else NO_RECORD: a pixel of at most TAIL_WORDS
// fragments (forced, whatever its statistics: mlp::forced), or one of another batch (an
// earlier one's, its importance gathered; a later one's).
fn fragment_record(p: u32) -> u32 {
    return batch_record(record_index(p), batch[BATCH_LO], batch[BATCH_SIZE]);
}
