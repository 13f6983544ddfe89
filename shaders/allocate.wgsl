// Allocation: k(p) from importance, the twin of alloc::from_importance, as small per-pixel
// steps the host sequences (every sum an integer atomic, so each step is exact and order-free,
// and no invocation loops: lavapipe ends long loops). The host reads `acc` after each step:
//   init:        importance -> fixed point q in place; acc = covered, fragments, sum q
//   uniform_q:   q = 1 for covered pixels (when every q is 0)
//   base:        k = clamp(F q / S, lo, n); acc[0] = sum k, acc[1] = pixels with room
//   count:       acc[0] = eligible pixels (mode 0: k < n, mode 1: k > lo)
//   step:        eligible pixels change by min(d, room); acc[0] = total change, acc[1] =
//                pixels still eligible
//   histogram:   hist[digit] counts eligible pixels by the 8-bit digit of their rank at bit d,
//                among those whose higher digits equal t (rank: q giving, ~q taking); four
//                of these find the threshold rank
//   flags:       flags[p] = eligible and rank == t (then prefix-summed by the scan)
//   apply:       eligible and (rank > t, or rank == t and before[p] < left) change by one

struct Alloc {
    f: u32,
    s_lo: u32,
    s_hi: u32,
    lo: u32,
    mode: u32,
    d: u32,
    t: u32,
    left: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> alloc: Alloc;
@group(0) @binding(2) var<storage, read> counts: array<u32>;
@group(0) @binding(3) var<storage, read_write> q: array<u32>;
@group(0) @binding(4) var<storage, read_write> k: array<u32>;
@group(0) @binding(5) var<storage, read_write> acc: array<atomic<u64>, 4>;
@group(0) @binding(6) var<storage, read_write> flags: array<u32>;
// 256-bin histogram of one 8-bit digit of the rank (radix selection of the threshold).
@group(0) @binding(7) var<storage, read_write> hist: array<atomic<u32>, 256>;

const SCALE: f32 = 1048576.0;

fn eligible(p: u32) -> bool {
    let n = counts[p];
    if (n == 0u) {
        return false;
    }
    if (alloc.mode == 0u) {
        return k[p] < n;
    }
    return k[p] > alloc.lo;
}

fn rank(p: u32) -> u32 {
    return select(~q[p], q[p], alloc.mode == 0u);
}

@compute @workgroup_size(64)
fn init(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if (p >= params.pixels) {
        return;
    }
    let c = counts[p];
    var v = 0u;
    if (c > 0u) {
        let i = bitcast<f32>(q[p]);
        if (i > 0.0 && i <= 3.4028235e38) {
            v = u32(floor(min(i, 2047.0) * SCALE + 0.5));
        }
        atomicAdd(&acc[0], 1lu);
        atomicAdd(&acc[1], u64(c));
    }
    q[p] = v;
    atomicAdd(&acc[2], u64(v));
}

@compute @workgroup_size(64)
fn uniform_q(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if (p >= params.pixels) {
        return;
    }
    q[p] = select(0u, 1u, counts[p] > 0u);
}

@compute @workgroup_size(64)
fn base(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if (p >= params.pixels) {
        return;
    }
    let c = counts[p];
    var kp = 0u;
    if (c > 0u && alloc.lo == 1u) {
        let s = max((u64(alloc.s_hi) << 32u) | u64(alloc.s_lo), 1lu);
        kp = u32(clamp((u64(alloc.f) * u64(q[p])) / s, 1lu, u64(c)));
    }
    k[p] = kp;
    atomicAdd(&acc[0], u64(kp));
    if (c > 0u && kp < c) {
        atomicAdd(&acc[1], 1lu); // still has room: eligible for the first round
    }
}

@compute @workgroup_size(64)
fn count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if (p < params.pixels && eligible(p)) {
        atomicAdd(&acc[0], 1lu);
    }
}

@compute @workgroup_size(64)
fn step(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if (p >= params.pixels || !eligible(p)) {
        return;
    }
    if (alloc.mode == 0u) {
        let add = min(alloc.d, counts[p] - k[p]);
        k[p] = k[p] + add;
        atomicAdd(&acc[0], u64(add));
    } else {
        let take = min(alloc.d, k[p] - alloc.lo);
        k[p] = k[p] - take;
        atomicAdd(&acc[0], u64(take));
    }
    if (eligible(p)) {
        atomicAdd(&acc[1], 1lu); // eligible for the next round: saves a count step
    }
}

@compute @workgroup_size(64)
fn histogram(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if (p >= params.pixels || !eligible(p)) {
        return;
    }
    let r = rank(p);
    let shift = alloc.d;
    if (shift < 24u && (r >> (shift + 8u)) != alloc.t) {
        return;
    }
    atomicAdd(&hist[(r >> shift) & 255u], 1u);
}

@compute @workgroup_size(64)
fn mark(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if (p >= params.pixels) {
        return;
    }
    flags[p] = select(0u, 1u, eligible(p) && rank(p) == alloc.t);
}

@compute @workgroup_size(64)
fn apply(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if (p >= params.pixels || !eligible(p)) {
        return;
    }
    let r = rank(p);
    // `flags` holds the exclusive prefix of the marks here: threshold pixels before p.
    if (r > alloc.t || (r == alloc.t && flags[p] < alloc.left)) {
        if (alloc.mode == 0u) {
            k[p] = k[p] + 1u;
        } else {
            k[p] = k[p] - 1u;
        }
    }
}
