// Unsigned 64-bit integers as two 32-bit words, for the passes that run where WGSL has no u64
// (WebGPU, most of Metal): a W is vec2<u32>(low, high), a u64's bytes. Exact, wrapping where
// a u64 would (the callers keep within range, as with u64).

alias W = vec2<u32>;

fn w_of(v: u32) -> W {
    return W(v, 0u);
}

fn w_add(a: W, b: W) -> W {
    let lo = a.x + b.x;
    return W(lo, a.y + b.y + select(0u, 1u, lo < a.x));
}

fn w_sub(a: W, b: W) -> W {
    return W(a.x - b.x, a.y - b.y - select(0u, 1u, a.x < b.x));
}

fn w_lt(a: W, b: W) -> bool {
    return a.y < b.y || (a.y == b.y && a.x < b.x);
}

fn w_le(a: W, b: W) -> bool {
    return !w_lt(b, a);
}

fn w_min(a: W, b: W) -> W {
    return select(b, a, w_lt(a, b));
}

fn w_max(a: W, b: W) -> W {
    return select(a, b, w_lt(a, b));
}

// The whole product of two u32s.
fn w_mul(a: u32, b: u32) -> W {
    let al = a & 0xffffu;
    let ah = a >> 16u;
    let bl = b & 0xffffu;
    let bh = b >> 16u;
    let ll = al * bl;
    let mid = al * bh;
    let mid2 = ah * bl;
    let m = mid + mid2;
    let carry_mid = select(0u, 0x10000u, m < mid);
    let lo = ll + (m << 16u);
    let carry_lo = select(0u, 1u, lo < ll);
    return W(lo, ah * bh + (m >> 16u) + carry_mid + carry_lo);
}

// a * b, wrapping at 2^64.
fn w_mul_u32(a: W, b: u32) -> W {
    let p = w_mul(a.x, b);
    return W(p.x, p.y + a.y * b);
}

// floor(a / d) for d > 0, by long division (64 steps).
fn w_div_u32(a: W, d: u32) -> W {
    var r = 0u;
    var q = W(0u, 0u);
    for (var i = 63i; i >= 0i; i--) {
        let top = r >> 31u;
        let word = select(a.x, a.y, i >= 32i);
        let bit = (word >> (u32(i) & 31u)) & 1u;
        r = (r << 1u) | bit;
        // With the top bit shifted out, r is at least 2^32 > d: the wrapping subtraction is
        // the true remainder.
        if (top != 0u || r >= d) {
            r -= d;
            if (i >= 32i) {
                q.y |= 1u << (u32(i) - 32u);
            } else {
                q.x |= 1u << u32(i);
            }
        }
    }
    return q;
}

// a as a u32, where it fits (else u32's largest).
fn w_u32_sat(a: W) -> u32 {
    return select(a.x, 0xffffffffu, a.y != 0u);
}

fn w_is_zero(a: W) -> bool {
    return a.x == 0u && a.y == 0u;
}

// 2^e, for e < 64.
fn w_pow2(e: u32) -> W {
    return select(W(1u << e, 0u), W(0u, 1u << (e - 32u)), e >= 32u);
}

// a >> s, for s < 64.
fn w_shr(a: W, s: u32) -> W {
    if (s == 0u) {
        return a;
    }
    if (s >= 32u) {
        return W(a.y >> (s - 32u), 0u);
    }
    return W((a.x >> s) | (a.y << (32u - s)), a.y >> s);
}

// a << s, for s < 64 (wrapping).
fn w_shl(a: W, s: u32) -> W {
    if (s == 0u) {
        return a;
    }
    if (s >= 32u) {
        return W(0u, a.x << (s - 32u));
    }
    return W(a.x << s, (a.y << s) | (a.x >> (32u - s)));
}

// a as the nearest f32 (ties to even), as Rust's `as f32` and a u64's conversion round.
fn w_to_f32(a: W) -> f32 {
    if (a.y == 0u) {
        return f32(a.x);
    }
    // 33 to 64 significant bits: keep the top 24, round on the `drop` below them.
    let drop = 40u - countLeadingZeros(a.y);
    var m = w_shr(a, drop).x;
    let rem = w_sub(a, w_shl(w_of(m), drop));
    let half = w_pow2(drop - 1u);
    if (w_lt(half, rem) || (all(rem == half) && (m & 1u) == 1u)) {
        m += 1u;
    }
    return f32(m) * exp2(f32(drop));
}
