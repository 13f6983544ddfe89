// The frame's plan (compute, one invocation after the count's totals; twin plan::plan, written
// step for step like it): what an allocated k-buffer's frame decides from its own count, on the
// device, so that no frame waits for it. Every buffer was sized before the count, for the
// occupancy the frame's client expected; the slot pool holds `pool` bytes. From the count's
// totals it takes F (the budget's, lowered to what the pool holds), whether the frame keeps
// every fragment (F holds them all, or with exact_when_cheaper the pool does), and DKB's
// records a batch, and writes them where the passes after it read them: F and the flags into
// the totals (PLAN_F_WORD, PLAN_FLAGS_WORD; the allocation and the network read F there), the
// records a batch into the batch words (totals.wgsl's assign_records, importance_dkb.wgsl).

struct PlanParams {
    // How F follows from the count: 0 F slots (`budget`), 1 a share in parts per million
    // (`budget`), 2 the most slots the bytes `bytes` leave beside the layout's fixed bytes hold
    // (budget::Layout::fragment_budget_counted; all ones: none, the bytes are below them).
    kind: u32,
    budget: u32,
    exact_when_cheaper: u32,
    // DKB's features passes recorded, one a batch of records.
    batches: u32,
    bytes_lo: u32,
    bytes_hi: u32,
    pool_lo: u32,
    pool_hi: u32,
    // A record's bytes and its entry in the network's list (0: the layout keeps none), the
    // most batches the layout gathers them in, and the allocation's marks' bytes (what the
    // pool holds first: budget::Layout::pool_least).
    record_bytes: u32,
    layout_batches: u32,
    marks_lo: u32,
    marks_hi: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    _pad3: u32,
};

// The frame's parameters (common.wgsl's helpers read them; the plan does not).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(9) var<uniform> plan: PlanParams;
// fragments, covered, max count, deep, records handed out, deeper, then the plan's F and flags
// (totals.wgsl).
@group(0) @binding(2) var<storage, read_write> totals: array<u32>;
// DKB's batch words: the network's list length, the batch's first record, the records a batch
// holds, the rows run (totals.wgsl's `batch`); an unused buffer of four words for the others.
@group(0) @binding(8) var<storage, read_write> batch: array<u32>;

fn wide(lo: u32, hi: u32) -> u64 {
    return (u64(hi) << 32u) | u64(lo);
}

// A value and whether there is one.
struct Maybe {
    value: u64,
    some: bool,
};

fn some(v: u64) -> Maybe {
    return Maybe(v, true);
}

fn none() -> Maybe {
    return Maybe(0lu, false);
}

fn checked_sub(a: u64, b: u64) -> Maybe {
    if (a < b) {
        return none();
    }
    return some(a - b);
}

fn ceil_div(a: u64, b: u64) -> u64 {
    return (a + b - 1lu) / b;
}

// plan::largest_fitting: the largest F at most `cap` whose slots and tails take at most
// `words` pool words.
fn largest_fitting(words: u64, n: u64, covered: u64, deep: u64, deeper: u64, cap: u64) -> Maybe {
    if (words >= n) {
        return some(cap);
    }
    if (cap >= covered) {
        let f1 = checked_sub(words, deep + deeper);
        if (f1.some && f1.value >= covered) {
            return some(min(cap, f1.value));
        }
    }
    let f0 = checked_sub(words, covered + deep);
    if (f0.some) {
        return some(min(cap, f0.value));
    }
    return none();
}

// budget::Layout::fragment_budget_counted for a layout with pooled tails, the fixed bytes
// already taken off (`pool`).
fn budget_counted(pool: Maybe, covered: u64, deep: u64, deeper: u64) -> Maybe {
    // What the pool holds first whatever F (DKB's records and marks), and 16 bytes at least,
    // as every buffer.
    var least = 16lu;
    if (plan.record_bytes > 0u) {
        let records = ceil_div(deeper, u64(plan.layout_batches));
        least = max(max(u64(plan.record_bytes) * records, wide(plan.marks_lo, plan.marks_hi)), 16lu);
    }
    if (!pool.some || pool.value < least) {
        return none();
    }
    let words = pool.value / 8lu;
    let f1 = checked_sub(words, deep + deeper);
    if (f1.some && f1.value >= covered) {
        return f1;
    }
    let f0 = checked_sub(words, covered + deep);
    if (f0.some && f0.value > 0lu) {
        return f0;
    }
    return none();
}

@compute @workgroup_size(1)
fn main() {
    let n = u64(totals[0]);
    let covered = u64(totals[1]);
    let deep = u64(totals[3]);
    let deeper = u64(totals[5]);
    var short = 0u;
    // The budget's F.
    var budget_f = u64(plan.budget);
    if (plan.kind == 1u) {
        budget_f = (n * u64(plan.budget)) / u64(PPM);
    } else if (plan.kind == 2u) {
        var bytes = none();
        if (plan.bytes_lo != 0xffffffffu || plan.bytes_hi != 0xffffffffu) {
            bytes = some(wide(plan.bytes_lo, plan.bytes_hi));
        }
        let counted = budget_counted(bytes, covered, deep, deeper);
        budget_f = counted.value;
        if (!counted.some) {
            short |= PLAN_NO_SLOT;
        }
    }
    // Within what the pool holds.
    let pool = wide(plan.pool_lo, plan.pool_hi);
    let words = pool / 8lu;
    let fitting = largest_fitting(words, n, covered, deep, deeper, budget_f);
    var f = fitting.value;
    if (!fitting.some) {
        short |= PLAN_SHORT_SLOTS;
    }
    if (f < budget_f) {
        short |= PLAN_SHORT_SLOTS;
    }
    let exact = f >= n || (plan.exact_when_cheaper != 0u && words >= n);
    // DKB's records, in batches of what the pool holds (budget::PoolState::batch).
    var per_batch = 0lu;
    if (plan.record_bytes > 0u && !exact) {
        let records = max(deeper, 1lu);
        per_batch = clamp(pool / u64(plan.record_bytes), 1lu, records);
        let batches = max(ceil_div(deeper, per_batch), 1lu);
        if (batches > u64(max(plan.batches, 1u))) {
            short |= PLAN_SHORT_RECORDS;
        }
    }
    if (exact) {
        f = n;
    }
    totals[PLAN_F_WORD] = u32(min(f, n));
    totals[PLAN_FLAGS_WORD] = select(0u, 1u, exact) | (short << 1u);
    batch[2] = u32(per_batch);
}
