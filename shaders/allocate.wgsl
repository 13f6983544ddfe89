// Allocation (compute, one workgroup of 256): k(p) from importance, the twin of
// alloc::from_importance. Importance becomes fixed point in place (q), then
// k = clamp(floor(F q / S), lo, n), then rounds hand out (or take back) slots until
// sum k = min(F, sum n): all pixels with room (or spare slots) at once while they are no more
// than what is missing (extra), else the most (least) important by a bisection over q, ties to
// the lower pixel index. Every sum is an integer, so the result is exact and order-free.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> counts: array<u32>;
@group(0) @binding(2) var<storage, read_write> importance: array<u32>;
@group(0) @binding(3) var<storage, read_write> k: array<u32>;
// Set to 1 when the pass came close to lavapipe's loop limit (see common.wgsl).
@group(0) @binding(4) var<storage, read_write> status: array<atomic<u32>>;

const SCALE: f32 = 1048576.0;

var<workgroup> red: array<u64, 256>;
var<workgroup> result: u64;

fn sum64(lid: u32, v: u64) -> u64 {
    red[lid] = v;
    workgroupBarrier();
    for (var s = 128u; s > 0u; s = s >> 1u) {
        tick();
        if (lid < s) {
            red[lid] = red[lid] + red[lid + s];
        }
        workgroupBarrier();
    }
    if (lid == 0u) {
        result = red[0];
    }
    return workgroupUniformLoad(&result);
}

// mode 0: has room (k < n); mode 1: has a spare slot (k > lo).
fn eligible(p: u32, mode: u32, lo: u32) -> bool {
    let n = counts[p];
    if (n == 0u) {
        return false;
    }
    if (mode == 0u) {
        return k[p] < n;
    }
    return k[p] > lo;
}

// Larger ranks are chosen first: importance when giving, its complement when taking.
fn rank(p: u32, mode: u32) -> u32 {
    let q = importance[p];
    return select(~q, q, mode == 0u);
}

// Changes k by +1 (mode 0) or -1 (mode 1) for the `count` eligible pixels of highest rank,
// ties to the lower index.
fn select_and_apply(lid: u32, count: u64, mode: u32, lo: u32) {
    let n = params.pixels;
    var lo_t = 0lu;
    var hi_t = 4294967296lu;
    for (var it = 0u; it < 33u; it++) {
        tick();
        if (hi_t - lo_t <= 1lu) {
            break;
        }
        let mid = (lo_t + hi_t) / 2lu;
        var c = 0lu;
        for (var p = lid; p < n; p += 256u) {
            tick();
            if (eligible(p, mode, lo) && u64(rank(p, mode)) >= mid) {
                c += 1lu;
            }
        }
        if (sum64(lid, c) >= count) {
            lo_t = mid;
        } else {
            hi_t = mid;
        }
    }
    let t = u32(lo_t);
    // How many are strictly above the threshold; the rest come from the threshold in order.
    var above = 0lu;
    for (var p = lid; p < n; p += 256u) {
        tick();
        if (eligible(p, mode, lo) && rank(p, mode) > t) {
            above += 1lu;
        }
    }
    let left = count - sum64(lid, above);
    // Mark the threshold pixels to change, block by block in index order, before changing
    // anything (a change can alter eligibility).
    var taken = 0lu;
    for (var base = 0u; base < n; base += 256u) {
        tick();
        let p = base + lid;
        var flag = 0lu;
        if (p < n && eligible(p, mode, lo) && rank(p, mode) == t) {
            flag = 1lu;
        }
        // Exclusive prefix of the flags within the block.
        red[lid] = flag;
        workgroupBarrier();
        for (var s = 1u; s < 256u; s = s << 1u) {
            tick();
            var add = 0lu;
            if (lid >= s) {
                add = red[lid - s];
            }
            workgroupBarrier();
            red[lid] = red[lid] + add;
            workgroupBarrier();
        }
        let before = taken + red[lid] - flag;
        let block_total = workgroupUniformLoad(&red[255]);
        workgroupBarrier();
        if (flag == 1lu && before < left) {
            k[p] = k[p] + 0x80000000u; // marked; applied below
        }
        taken += block_total;
    }
    storageBarrier();
    workgroupBarrier();
    for (var p = lid; p < n; p += 256u) {
        tick();
        var kp = k[p];
        var marked = false;
        if (kp >= 0x80000000u) {
            kp = kp - 0x80000000u;
            marked = true;
        }
        if (marked || (eligible_value(p, kp, mode, lo) && rank(p, mode) > t)) {
            if (mode == 0u) {
                kp += 1u;
            } else {
                kp -= 1u;
            }
        }
        k[p] = kp;
    }
    storageBarrier();
    workgroupBarrier();
}

fn eligible_value(p: u32, kp: u32, mode: u32, lo: u32) -> bool {
    let n = counts[p];
    if (n == 0u) {
        return false;
    }
    if (mode == 0u) {
        return kp < n;
    }
    return kp > lo;
}

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) lid: u32) {
    let n = params.pixels;
    let f = u64(params.budget_fragments);
    var covered = 0lu;
    var frags = 0lu;
    var qsum = 0lu;
    for (var p = lid; p < n; p += 256u) {
        tick();
        let c = counts[p];
        var q = 0u;
        if (c > 0u) {
            let i = bitcast<f32>(importance[p]);
            if (i > 0.0 && i <= 3.4028235e38) {
                q = u32(floor(min(i, 2047.0) * SCALE + 0.5));
            }
            covered += 1lu;
            frags += u64(c);
        }
        importance[p] = q;
        qsum += u64(q);
    }
    let c_all = sum64(lid, covered);
    let total = sum64(lid, frags);
    var s = sum64(lid, qsum);
    if (s == 0lu) {
        for (var p = lid; p < n; p += 256u) {
            tick();
            importance[p] = select(0u, 1u, counts[p] > 0u);
        }
        s = c_all;
    }
    storageBarrier();
    workgroupBarrier();
    let target_k = min(f, total);
    let lo = select(0u, 1u, f >= c_all);
    var g = 0lu;
    for (var p = lid; p < n; p += 256u) {
        tick();
        var kp = 0u;
        let c = counts[p];
        if (c > 0u && lo == 1u) {
            kp = u32(clamp((f * u64(importance[p])) / max(s, 1lu), 1lu, u64(c)));
        }
        k[p] = kp;
        g += u64(kp);
    }
    var sum_k = sum64(lid, g);
    storageBarrier();
    // Hand out what is missing.
    for (var round = 0u; round < 100000u; round++) {
        tick();
        if (sum_k >= target_k) {
            break;
        }
        let missing = target_k - sum_k;
        var open = 0lu;
        for (var p = lid; p < n; p += 256u) {
            tick();
            if (eligible(p, 0u, lo)) {
                open += 1lu;
            }
        }
        let n_open = sum64(lid, open);
        if (n_open <= missing) {
            let d = u32(max(missing / max(n_open, 1lu), 1lu));
            var added = 0lu;
            for (var p = lid; p < n; p += 256u) {
                tick();
                if (eligible(p, 0u, lo)) {
                    let add = min(d, counts[p] - k[p]);
                    k[p] = k[p] + add;
                    added += u64(add);
                }
            }
            sum_k = sum_k + sum64(lid, added);
            storageBarrier();
        } else {
            select_and_apply(lid, missing, 0u, lo);
            sum_k = target_k;
        }
    }
    // Take back what is extra.
    for (var round = 0u; round < 100000u; round++) {
        tick();
        if (sum_k <= target_k) {
            break;
        }
        let extra = sum_k - target_k;
        var spare = 0lu;
        for (var p = lid; p < n; p += 256u) {
            tick();
            if (eligible(p, 1u, lo)) {
                spare += 1lu;
            }
        }
        let n_spare = sum64(lid, spare);
        if (n_spare <= extra) {
            let d = u32(max(extra / max(n_spare, 1lu), 1lu));
            var taken = 0lu;
            for (var p = lid; p < n; p += 256u) {
                tick();
                if (eligible(p, 1u, lo)) {
                    let take = min(d, k[p] - lo);
                    k[p] = k[p] - take;
                    taken += u64(take);
                }
            }
            sum_k = sum_k - sum64(lid, taken);
            storageBarrier();
        } else {
            select_and_apply(lid, extra, 1u, lo);
            sum_k = target_k;
        }
    }
    if (ticks > LOOP_BUDGET) {
        atomicMax(&status[0], 1u);
    }
}
