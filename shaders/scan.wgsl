// Exclusive prefix sum over pixels: offsets[p] = sum of values[q] for q < p, and
// offsets[pixels] = the total. One workgroup walks the pixels in blocks of 256, carrying the
// running sum (A-buffer offsets from counts, k-buffer slot bases from k).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> values: array<u32>;
@group(0) @binding(2) var<storage, read_write> offsets: array<u32>;

var<workgroup> block: array<u32, 256>;
var<workgroup> carry: u32;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) lid: u32) {
    if (lid == 0u) {
        carry = 0u;
    }
    workgroupBarrier();
    let n = params.pixels;
    for (var base = 0u; base < n; base += 256u) {
        let i = base + lid;
        var v = 0u;
        if (i < n) {
            v = values[i];
        }
        block[lid] = v;
        workgroupBarrier();
        // Hillis-Steele inclusive scan of the block.
        for (var s = 1u; s < 256u; s = s << 1u) {
            var add = 0u;
            if (lid >= s) {
                add = block[lid - s];
            }
            workgroupBarrier();
            block[lid] = block[lid] + add;
            workgroupBarrier();
        }
        let c = carry;
        if (i < n) {
            offsets[i] = c + block[lid] - v;
        }
        workgroupBarrier();
        if (lid == 255u) {
            carry = c + block[255];
        }
        workgroupBarrier();
    }
    if (lid == 0u) {
        offsets[n] = carry;
    }
}
