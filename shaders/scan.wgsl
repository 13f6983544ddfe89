// Exclusive prefix sum over pixels, in three dispatches so no invocation loops long (Mesa's
// lavapipe stops a shader's loops after 65,535 iterations, silently):
//   scan_blocks: each workgroup scans its SCAN_BLOCK values into offsets and writes the block total;
//   scan_sums:   one workgroup scans the block totals in place, SCAN_BLOCK at a time;
//   scan_add:    each value gets its block's offset; the last entry gets the total.
// offsets[p] = sum of values[q] for q < p, offsets[pixels] = the total.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> values: array<u32>;
@group(0) @binding(2) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(3) var<storage, read_write> blocks: array<u32>;

var<workgroup> block: array<u32, SCAN_BLOCK>;
var<workgroup> carry: u32;

// Inclusive Hillis-Steele scan of `block`; every invocation of the workgroup calls it.
fn scan_block(lid: u32) {
    for (var s = 1u; s < SCAN_BLOCK; s = s << 1u) {
        var add = 0u;
        if (lid >= s) {
            add = block[lid - s];
        }
        workgroupBarrier();
        block[lid] = block[lid] + add;
        workgroupBarrier();
    }
}

@compute @workgroup_size(SCAN_BLOCK)
fn scan_blocks(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let b = wid.y * nwg.x + wid.x;
    let i = grid_index(wid, nwg, lid, SCAN_BLOCK);
    var v = 0u;
    if (i < params.pixels) {
        v = values[i];
    }
    block[lid] = v;
    workgroupBarrier();
    scan_block(lid);
    if (i < params.pixels) {
        offsets[i] = block[lid] - v;
    }
    if (lid == SCAN_BLOCK - 1u && b < (params.pixels + SCAN_BLOCK - 1u) / SCAN_BLOCK) {
        blocks[b] = block[SCAN_BLOCK - 1u];
    }
}

@compute @workgroup_size(SCAN_BLOCK)
fn scan_sums(@builtin(local_invocation_index) lid: u32) {
    let n = (params.pixels + SCAN_BLOCK - 1u) / SCAN_BLOCK;
    if (lid == 0u) {
        carry = 0u;
    }
    workgroupBarrier();
    for (var base = 0u; base < n; base += SCAN_BLOCK) {
        let i = base + lid;
        var v = 0u;
        if (i < n) {
            v = blocks[i];
        }
        block[lid] = v;
        workgroupBarrier();
        scan_block(lid);
        let c = carry;
        if (i < n) {
            blocks[i] = c + block[lid] - v;
        }
        workgroupBarrier();
        if (lid == SCAN_BLOCK - 1u) {
            carry = c + block[SCAN_BLOCK - 1u];
        }
        workgroupBarrier();
    }
    if (lid == 0u) {
        offsets[params.pixels] = carry;
    }
}

@compute @workgroup_size(SCAN_BLOCK)
fn scan_add(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = grid_index(wid, nwg, lid, SCAN_BLOCK);
    if (i < params.pixels) {
        offsets[i] = offsets[i] + blocks[wid.y * nwg.x + wid.x];
    }
}
