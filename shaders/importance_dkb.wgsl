// DKB importance (compute): the 12 features of importance::pixel_features from the features
// pass's records and the totals, computed here and never stored, standardised, through the MLP
// of mlp.wgsl (the same source `dhoit predict --device gpu` runs). Four entry points in one
// compute pass, sharing one explicit layout (gpu::Pipelines::network_layout):
//   select:  one invocation a record (a pixel of more than TAIL_WORDS fragments the record
//            marks mark: records.wgsl): a record the network decides is appended to a list
//            (its index), every other gets its importance here (0 with the pair mark where
//            forced);
//   args:    the list's length -> the workgroups of an indirect dispatch (a 2-D grid);
//   network: one invocation a listed record: its features again, the network, its importance;
//   gather:  one invocation a pixel: its record's importance into the shared word; a pixel
//            without one of more than TAIL_WORDS fragments (unmarked by the frame before, or
//            past the records the pool held) the mean request the network gave, a pixel of
//            fewer 0 (forced whatever its importance).
// Once for each batch of records (totals.wgsl), which are a batch's own indices here (`r`): the
// batch's first record is at the pool's start.
// A record's importance waits in its nearest words' place (read by then).
// So the network's invocations all run it (no forced record idles a SIMD lane), and a frame whose
// pixels are all forced never enters the network's code.

@group(0) @binding(0) var<uniform> params: Params;
// RECORD_WORDS words a record (features.wgsl): the two nearest words (complemented), the colour
// sums (n in bits 48-63 of the first), the opacity sums. Read_write: once a record's features
// are read, its importance takes its nearest words' place (set_importance).
// Each record word a 64-bit word's two halves (low x, high y: u64.wgsl's W).
@group(0) @binding(3) var<storage, read_write> records: array<W>;
// The records the network decides, and how many (BATCH_LISTED), lie in the same pool after a
// batch's records, a 32-bit word each (list_get, list_set): WebGPU binds a buffer writable once
// in a dispatch.
// The TOTAL_* words (totals.wgsl; a record for each of TOTAL_DEEPER's pixels), then the frame's
// plan (plan.wgsl): its F.
@group(0) @binding(6) var<storage, read> totals: array<u32>;

// F as the frame's plan found it (the budget's, within what its pool holds; at most n).
fn planned_f() -> u32 {
    return totals[PLAN_F_WORD];
}
// Per pixel, after `gather`: its importance (the frame's shared word).
@group(0) @binding(8) var<storage, read_write> shared_word: array<u32>;
// The marks that give each pixel its record (records.wgsl), and the counts, two to a word
// (counts.wgsl): `gather` reads them.
@group(0) @binding(4) var<storage, read> record_marks: array<u32>;
@group(0) @binding(5) var<storage, read> count: array<u32>;
// The batch (totals.wgsl, the BATCH_* words): the list's length, its first record lo, the
// records a batch holds (its records from the pool's start, `r` below a batch's own index), the
// rows before.
@group(0) @binding(9) var<storage, read_write> list_len: array<atomic<u32>, BATCH_WORDS>;
// The network entry's indirect dispatch: workgroups x, y, z.
@group(0) @binding(10) var<storage, read_write> dispatch: array<u32, DISPATCH_WORDS>;

// SKIP_FORCED (a definition the pass composes in): skip the network where k does not depend on it (Mlp::dkb_importance): a pixel whose useful
// cap is the frame's smallest k, lo (mlp::forced: n <= lo + 2, the pair mark on every pixel as
// the tails are pooled; lo is 1 where F covers every covered pixel, as at 2 fpp) gets
// importance 0 with its pair mark. The bench builds this pass once more with it false
// (Tuning::skip_forced off) to show the time saved. Every pixel of a frame whose budget holds all its fragments gets 0, unmarked,
// either way: its features pass drew nothing (features.wgsl), and k = n whatever it gets.

// Sum r, g, b of record r's fragments (features.wgsl's packing: r and g 24 bits each in the
// first colour-sum word, then n; b in the second's low half).
fn color_sums(at: u32) -> vec3<u32> {
    let w = records[at + 1u];
    return vec3<u32>(w.x & 0xffffffu, ((w.x >> 24u) | (w.y << 8u)) & 0xffffffu, records[at + 2u].x);
}

fn luma(c: vec3<f32>) -> f32 {
    return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
}

// A pixel's network inputs (importance::pixel_features), or, where the network is not run (an
// uncovered or forced pixel), its importance written here and `runs` false.
struct Net {
    x: array<f32, FEATURES>,
    mark: u32,
    runs: bool,
}

// Record r's importance, in its nearest words' place: only r's own invocation reads them, and
// it has read them by now.
fn set_importance(r: u32, v: f32) {
    records[RECORD_WORDS * r] = W(bitcast<u32>(v), 0u);
}

fn network_inputs(r: u32) -> Net {
    var net: Net;
    let at = RECORD_WORDS * r;
    let c = records[at + 1u].y >> 16u;
    // Every fragment kept (k = n whatever the importance), or a pixel the frame before marked
    // that has no more than TAIL_WORDS now (it keeps them all: 0 unmarked, as a pixel without
    // a record).
    if (planned_f() >= totals[TOTAL_FRAGMENTS] || c <= TAIL_WORDS) {
        set_importance(r, 0.0);
        return net;
    }
    // The sign bit marks a pixel whose two farthest fragments composite exactly without their
    // slots (alloc::mark_pair): the allocation lets it use a slot fewer. With the tails pooled
    // (DKB's always are) every pixel is so: one that would leave out no more than a tail's
    // TAIL_WORDS fragments keeps them all (shared::stored_k).
    let pair = true;
    let mark = select(0u, PAIR_BIT, pair);
    // alloc::min_k, as the allocation's setup finds it.
    let lo = select(0u, 1u, planned_f() >= totals[TOTAL_COVERED]);
    if (SKIP_FORCED && c <= lo + 1u + select(0u, 1u, pair)) {
        set_importance(r, bitcast<f32>(mark));
        return net;
    }
    // importance::pixel_features, operation for operation.
    let total = f32(max(totals[TOTAL_FRAGMENTS], 1u));
    let covered = f32(max(totals[TOTAL_COVERED], 1u));
    let nf = f32(c);
    // importance::near_rgba8 and near_depth of the two nearest words.
    let near_words = ~records[at];
    let near8 = (near_words.x & 0xffu) | (((near_words.y >> 8u) & 0xffu) << 8u)
        | ((near_words.y & 0xffu) << 16u) | (((near_words.x >> 8u) & 0xffu) << 24u);
    let near = unpack_rgba8(near8).rgb;
    let sum = color_sums(at);
    let mean = vec3<f32>(f32(sum.r) / 255.0 / nf, f32(sum.g) / 255.0 / nf, f32(sum.b) / 255.0 / nf);
    // n^2 var and n^2 dev in 8-bit units, exact integers (below 2^49) in 64-bit words: n times
    // the squares' sum less the sums' squares (0 where that is negative), and the sum of the
    // squared differences of n times the nearest colour and the sums.
    var sq = W(0u, 0u);
    var dev_num = W(0u, 0u);
    for (var ch = 0u; ch < 3u; ch++) {
        let s = sum[ch];
        sq = w_add(sq, w_mul(s, s));
        let cn = c * ((near8 >> (8u * ch)) & 0xffu);
        let d = select(s - cn, cn - s, cn >= s);
        dev_num = w_add(dev_num, w_mul(d, d));
    }
    let all_sq = w_mul(c, records[at + 2u].y);
    let var_num = select(W(0u, 0u), w_sub(all_sq, sq), w_le(sq, all_sq));
    let scale = nf * nf * 65025.0;
    let variance = w_to_f32(var_num) / scale;
    let dev = w_to_f32(dev_num) / scale;
    let mean_luma = luma(mean);
    let near_luma = luma(near);
    let tau = f32(records[at + 3u].x) * OPTICAL_DEPTH_UNIT;
    net.x = array<f32, FEATURES>(
        log2(nf),
        nf / (total / covered),
        f32(planned_f()) / total,
        log2(f32(max(planned_f(), 1u)) / covered),
        f32(near_words.x >> 16u) * (1.0 / 65536.0),
        f32(near8 >> 24u) / 255.0,
        log2(variance + LOG_FLOOR),
        log2(dev + LOG_FLOOR),
        f32(records[at + 3u].y) / 255.0 / nf,
        mean_luma,
        near_luma,
        log2(tau + OPTICAL_DEPTH_UNIT),
    );
    net.runs = true;
    net.mark = mark;
    return net;
}

// The list's entry i: the pool's 32-bit word i after a batch's records (RECORD_WORDS 64-bit
// words each; budget::PoolState::list_bytes), the low or high half of a W.
fn list_word(i: u32) -> u32 {
    return RECORD_WORDS * atomicLoad(&list_len[BATCH_SIZE]) + i / 2u;
}
fn list_get(i: u32) -> u32 {
    let w = records[list_word(i)];
    return select(w.x, w.y, (i & 1u) == 1u);
}
fn list_set(i: u32, r: u32) {
    if ((i & 1u) == 0u) {
        records[list_word(i)].x = r;
    } else {
        records[list_word(i)].y = r;
    }
}

@compute @workgroup_size(PIXEL_GROUP)
fn select_pixels(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    // The batch's records: a batch's worth, or what is left of the frame's (TOTAL_RECORDS, the
    // marks'; none in a batch past them, which a frame sized ahead of its count may record).
    let r = grid_index(wid, nwg, lid, PIXEL_GROUP);
    let lo = atomicLoad(&list_len[BATCH_LO]);
    let marked = totals[TOTAL_RECORDS];
    let left = select(0u, marked - lo, marked > lo);
    if (r >= min(atomicLoad(&list_len[BATCH_SIZE]), left)) {
        return;
    }
    if (network_inputs(r).runs) {
        list_set(atomicAdd(&list_len[BATCH_LISTED], 1u), r);
    }
}

@compute @workgroup_size(1)
fn args() {
    let groups = (atomicLoad(&list_len[BATCH_LISTED]) + PIXEL_GROUP - 1u) / PIXEL_GROUP;
    // Rows of at most 65,535 workgroups (wgsl::grid).
    let rows = max((groups + 65534u) / 65535u, 1u);
    dispatch[0] = (groups + rows - 1u) / rows;
    dispatch[1] = select(0u, rows, groups > 0u);
    dispatch[2] = 1u;
}

@compute @workgroup_size(PIXEL_GROUP)
fn network(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = grid_index(wid, nwg, lid, PIXEL_GROUP);
    let listed = i < atomicLoad(&list_len[BATCH_LISTED]);
    var r = 0u;
    var net: Net;
    if (listed) {
        r = list_get(i);
        net = network_inputs(r);
    }
    if (SHARED_WEIGHTS) {
        // Every invocation of the workgroup stages the weights, listed or not.
        let out = mlp_forward_shared(net.x, net.runs, lid);
        if (net.runs) {
            set_importance(r, bitcast<f32>(bitcast<u32>(out) | net.mark));
            add_request(out);
        }
    } else if (net.runs) {
        let out = mlp_forward(net.x);
        set_importance(r, bitcast<f32>(bitcast<u32>(out) | net.mark));
        add_request(out);
    }
}

// Every pixel's importance from its record's nearest words' place into the shared word, where
// the allocation reads it: the batch's pixels; and in the first batch every pixel of no
// other batch its fallback (a later batch's pixel gets its own in its batch). A pixel of more
// than TAIL_WORDS fragments without a record (the frame before did not mark it, or it is past
// the records the pool held) takes the mean request the network gave the first batch, with
// its pair mark; where the network decided none, and for every other pixel, the least weight:
// 0, with the pair mark where the pixel has more than TAIL_WORDS fragments and the frame
// truncates (Mlp::dkb_importance_recorded's twin).
@compute @workgroup_size(PIXEL_GROUP)
fn gather(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let p = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (p >= params.pixels) {
        return;
    }
    let lo = atomicLoad(&list_len[BATCH_LO]);
    let size = atomicLoad(&list_len[BATCH_SIZE]);
    let r = batch_record(record_index(p), lo, size);
    if (r != NO_RECORD) {
        shared_word[p] = records[RECORD_WORDS * r].x;
    } else if (lo == 0u) {
        // 0 unmarked where the frame keeps every fragment, as network_inputs gives a record.
        let kept = planned_f() >= totals[TOTAL_FRAGMENTS];
        let deeper = count_in(count[count_word(p)], p) > TAIL_WORDS;
        var word = select(0u, PAIR_BIT, deeper && !kept);
        let decided = atomicLoad(&list_len[BATCH_LISTED]);
        if (deeper && !kept && decided > 0u) {
            let sum = W(atomicLoad(&list_len[BATCH_REQUESTS]), atomicLoad(&list_len[BATCH_REQUESTS + 1u]));
            let mean = w_to_f32(sum) / f32(decided) / exp2(f32(REQUEST_SUM_BITS));
            word = bitcast<u32>(mean) | PAIR_BIT;
        }
        shared_word[p] = word;
    }
}

// A request the network gave, into the sum of the batch's (BATCH_REQUESTS: a 64-bit sum in
// units of 2^-REQUEST_SUM_BITS, the low word's carry into the high one; shared::request_units).
fn add_request(v: f32) {
    let q = u32(v * exp2(f32(REQUEST_SUM_BITS)) + 0.5);
    let old = atomicAdd(&list_len[BATCH_REQUESTS], q);
    if (old + q < old) {
        atomicAdd(&list_len[BATCH_REQUESTS + 1u], 1u);
    }
}
