// Exclusive prefix sum over pixels, in three dispatches so no invocation loops long (Mesa's
// lavapipe stops a shader's loops after 65,535 iterations, silently):
//   scan_blocks: each workgroup scans its SCAN_BLOCK counts into offsets and writes the block total;
//   scan_sums:   one workgroup scans the block totals in place, SCAN_BLOCK at a time;
//   scan_add:    each value gets its block's offset; the last entry gets the total.
// offsets[p] = sum of values[q] for q < p, offsets[pixels] = the total (where offsets holds
// pixels + 1 entries). Built with SCAN_OF_MARKS, it scans the allocation's marks' popcounts in
// place instead: one a MARK_BITS pixels, and their total after them.
//
// scan_blocks_in_place reads the values from offsets itself, in place (a workgroup reads its
// whole block before it writes any of it): the k-buffer's per-pixel word holds the importance,
// the allocation's weights and k in turn, and then k's prefix sums, the slot bases, so k is
// never stored beside them (a pixel's k is its bases' difference).
//
// A workgroup's SCAN_GROUP invocations take SCAN_ITEMS consecutive values each: a running sum
// over its own values, then a Hillis-Steele scan over the invocations' sums, so a block of
// SCAN_BLOCK values costs the workgroup barriers of SCAN_GROUP (each barrier costs a CPU
// device such as lavapipe a switch of every invocation). Values move between the device's
// memory and the workgroup's in strides of SCAN_GROUP (neighbouring invocations, neighbouring
// words), and the workgroup's copy is padded one word every 32 so an invocation's run of
// SCAN_ITEMS does not fall in one memory bank with its neighbours'.

@group(0) @binding(0) var<uniform> params: Params;
// scan_blocks's values: the per-pixel counts, two to a word (counts.wgsl).
@group(0) @binding(1) var<storage, read> values: array<u32>;
@group(0) @binding(2) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(3) var<storage, read_write> blocks: array<u32>;

const SCAN_ITEMS: u32 = SCAN_BLOCK / SCAN_GROUP;

// SCAN_OF_MARKS (a definition the pass composes in): whether this build scans the allocation's
// marks (the popcounts of their words, one a MARK_BITS pixels: gpu::scan's Scan::Marks) rather
// than a value a pixel.

// The values scanned: one a pixel, or a word of marks' popcount every MARK_BITS pixels.
fn scan_length() -> u32 {
    if (SCAN_OF_MARKS) {
        return mark_blocks(params.pixels);
    }
    return params.pixels;
}

var<workgroup> items: array<u32, SCAN_BLOCK + SCAN_BLOCK / 32u>;
var<workgroup> sums: array<u32, SCAN_GROUP>;
var<workgroup> carry: u32;

// Where value i of the block lies in `items`.
fn at(i: u32) -> u32 {
    return i + (i >> 5u);
}

// Exclusive scan of the block in `items`, in place; returns the block's total. Every
// invocation of the workgroup calls it, after the block is stored and a barrier.
fn scan_items(lid: u32) -> u32 {
    let first = lid * SCAN_ITEMS;
    var own = 0u;
    for (var j = 0u; j < SCAN_ITEMS; j++) {
        let v = items[at(first + j)];
        items[at(first + j)] = own;
        own += v;
    }
    sums[lid] = own;
    workgroupBarrier();
    // Inclusive Hillis-Steele scan of the invocations' sums.
    for (var s = 1u; s < SCAN_GROUP; s = s << 1u) {
        var add = 0u;
        if (lid >= s) {
            add = sums[lid - s];
        }
        workgroupBarrier();
        sums[lid] = sums[lid] + add;
        workgroupBarrier();
    }
    let before = sums[lid] - own;
    for (var j = 0u; j < SCAN_ITEMS; j++) {
        items[at(first + j)] += before;
    }
    let total = sums[SCAN_GROUP - 1u];
    workgroupBarrier();
    return total;
}

// The block's scan from `items`, stored into offsets, and its total into `blocks`.
fn store_block(b: u32, first: u32, lid: u32) {
    workgroupBarrier();
    let total = scan_items(lid);
    for (var j = 0u; j < SCAN_ITEMS; j++) {
        let i = first + j * SCAN_GROUP + lid;
        if (i < scan_length()) {
            offsets[i] = items[at(j * SCAN_GROUP + lid)];
        }
    }
    if (lid == 0u && b < (scan_length() + SCAN_BLOCK - 1u) / SCAN_BLOCK) {
        blocks[b] = total;
    }
}

@compute @workgroup_size(SCAN_GROUP)
fn scan_blocks(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let b = wid.y * nwg.x + wid.x;
    let first = b * SCAN_BLOCK;
    for (var j = 0u; j < SCAN_ITEMS; j++) {
        let i = first + j * SCAN_GROUP + lid;
        var v = 0u;
        if (i < scan_length()) {
            v = count_in(values[count_word(i)], i);
        }
        items[at(j * SCAN_GROUP + lid)] = v;
    }
    store_block(b, first, lid);
}

@compute @workgroup_size(SCAN_GROUP)
fn scan_blocks_in_place(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let b = wid.y * nwg.x + wid.x;
    let first = b * SCAN_BLOCK;
    for (var j = 0u; j < SCAN_ITEMS; j++) {
        let i = first + j * SCAN_GROUP + lid;
        var v = 0u;
        if (i < scan_length()) {
            v = offsets[i];
        }
        items[at(j * SCAN_GROUP + lid)] = v;
    }
    store_block(b, first, lid);
}

@compute @workgroup_size(SCAN_GROUP)
fn scan_sums(@builtin(local_invocation_index) lid: u32) {
    let n = (scan_length() + SCAN_BLOCK - 1u) / SCAN_BLOCK;
    if (lid == 0u) {
        carry = 0u;
    }
    workgroupBarrier();
    for (var base = 0u; base < n; base += SCAN_BLOCK) {
        for (var j = 0u; j < SCAN_ITEMS; j++) {
            let i = base + j * SCAN_GROUP + lid;
            var v = 0u;
            if (i < n) {
                v = blocks[i];
            }
            items[at(j * SCAN_GROUP + lid)] = v;
        }
        workgroupBarrier();
        let total = scan_items(lid);
        let c = carry;
        for (var j = 0u; j < SCAN_ITEMS; j++) {
            let i = base + j * SCAN_GROUP + lid;
            if (i < n) {
                blocks[i] = c + items[at(j * SCAN_GROUP + lid)];
            }
        }
        workgroupBarrier();
        if (lid == 0u) {
            carry = c + total;
        }
        workgroupBarrier();
    }
    if (lid == 0u && scan_length() < arrayLength(&offsets)) {
        offsets[scan_length()] = carry;
    }
}

@compute @workgroup_size(SCAN_GROUP)
fn scan_add(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let b = wid.y * nwg.x + wid.x;
    let first = b * SCAN_BLOCK;
    let add = blocks[min(b, arrayLength(&blocks) - 1u)];
    for (var j = 0u; j < SCAN_ITEMS; j++) {
        let i = first + j * SCAN_GROUP + lid;
        if (i < scan_length()) {
            offsets[i] = offsets[i] + add;
        }
    }
}
