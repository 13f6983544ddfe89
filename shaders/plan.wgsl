// The frame's plan (compute, one invocation after the count's totals; twin plan::plan, written
// step for step like it): what an allocated k-buffer's frame decides from its own count, on the
// device, so that no frame waits for it. Every buffer was sized before the count, for the
// occupancy the frame's client expected; the slot pool holds `pool` bytes. From the count's
// totals it takes F (the budget's, lowered to what the pool holds), whether the frame keeps
// every fragment (F holds them all, or with exact_when_cheaper the pool does), and DKB's
// records a batch, and writes them where the passes after it read them: F and the flags into
// the totals (PLAN_F_WORD, PLAN_FLAGS_WORD; the allocation and the network read F there), the
// records a batch into the batch words (totals.wgsl's record_counts, importance_dkb.wgsl).

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
// The TOTAL_* words (totals.wgsl), then the plan's F and flags (PLAN_F_WORD, PLAN_FLAGS_WORD).
@group(0) @binding(2) var<storage, read_write> totals: array<u32>;
// DKB's BATCH_* words (totals.wgsl's `batch`); an unused buffer of BATCH_WORDS for the others.
@group(0) @binding(8) var<storage, read_write> batch: array<u32>;

// A value and whether there is one (u64.wgsl's W: 64 bits in two 32-bit words).
struct Maybe {
    value: W,
    some: bool,
};

fn some(v: W) -> Maybe {
    return Maybe(v, true);
}

fn none() -> Maybe {
    return Maybe(W(0u, 0u), false);
}

fn checked_sub(a: W, b: W) -> Maybe {
    if (w_lt(a, b)) {
        return none();
    }
    return some(w_sub(a, b));
}

fn ceil_div(a: W, b: u32) -> W {
    return w_div_u32(w_add(a, w_of(b - 1u)), b);
}

// plan::largest_fitting: the largest F at most `cap` whose slots and tails take at most
// `words` pool words.
fn largest_fitting(words: W, n: W, covered: W, deep: W, deeper: W, cap: W) -> Maybe {
    if (w_le(n, words)) {
        return some(cap);
    }
    if (w_le(covered, cap)) {
        let f1 = checked_sub(words, w_add(deep, deeper));
        if (f1.some && w_le(covered, f1.value)) {
            return some(w_min(cap, f1.value));
        }
    }
    let f0 = checked_sub(words, w_add(covered, deep));
    if (f0.some) {
        return some(w_min(cap, f0.value));
    }
    return none();
}

// budget::Layout::fragment_budget_counted for a layout with pooled tails, the fixed bytes
// already taken off (`pool`): with DKB's records in the layout's batches, else (no slot beside
// them) in up to MOST_RECORD_BATCHES.
fn budget_counted(pool: Maybe, covered: W, deep: W, deeper: W) -> Maybe {
    let f = slots_beside(pool, covered, deep, deeper, plan.layout_batches);
    if (f.some || plan.record_bytes == 0u || plan.layout_batches >= MOST_RECORD_BATCHES) {
        return f;
    }
    return slots_beside(pool, covered, deep, deeper, MOST_RECORD_BATCHES);
}

// budget::Layout::slots_beside: the most slots `pool` holds beside what it holds first whatever
// F (DKB's records in `batches` batches and the marks; 16 bytes at least, as every buffer) and
// the tails.
fn slots_beside(pool: Maybe, covered: W, deep: W, deeper: W, batches: u32) -> Maybe {
    var least = w_of(16u);
    if (plan.record_bytes > 0u) {
        let records = ceil_div(deeper, max(batches, 1u));
        let marks = W(plan.marks_lo, plan.marks_hi);
        least = w_max(w_max(w_mul_u32(records, plan.record_bytes), marks), w_of(16u));
    }
    if (!pool.some || w_lt(pool.value, least)) {
        return none();
    }
    let words = w_div_u32(pool.value, 8u);
    let f1 = checked_sub(words, w_add(deep, deeper));
    if (f1.some && w_le(covered, f1.value)) {
        return f1;
    }
    let f0 = checked_sub(words, w_add(covered, deep));
    if (f0.some && (f0.value.x != 0u || f0.value.y != 0u)) {
        return f0;
    }
    return none();
}

@compute @workgroup_size(1)
fn main() {
    let n = w_of(totals[TOTAL_FRAGMENTS]);
    let covered = w_of(totals[TOTAL_COVERED]);
    let deep = w_of(totals[TOTAL_DEEP]);
    let deeper = w_of(totals[TOTAL_DEEPER]);
    var short = 0u;
    // The budget's F.
    var budget_f = w_of(plan.budget);
    if (plan.kind == 1u) {
        budget_f = w_div_u32(w_mul(totals[TOTAL_FRAGMENTS], plan.budget), PPM);
    } else if (plan.kind == 2u) {
        var bytes = none();
        if (plan.bytes_lo != 0xffffffffu || plan.bytes_hi != 0xffffffffu) {
            bytes = some(W(plan.bytes_lo, plan.bytes_hi));
        }
        let counted = budget_counted(bytes, covered, deep, deeper);
        budget_f = counted.value;
        if (!counted.some) {
            short |= PLAN_NO_SLOT;
        }
    }
    // Within what the pool holds.
    let pool = W(plan.pool_lo, plan.pool_hi);
    let words = w_div_u32(pool, 8u);
    let fitting = largest_fitting(words, n, covered, deep, deeper, budget_f);
    var f = fitting.value;
    if (!fitting.some) {
        short |= PLAN_SHORT_SLOTS;
    }
    if (w_lt(f, budget_f)) {
        short |= PLAN_SHORT_SLOTS;
    }
    let exact = w_le(n, f) || (plan.exact_when_cheaper != 0u && w_le(n, words));
    // DKB's records, in batches of what the pool holds (budget::PoolState::batch): the pixels
    // the record marks mark (TOTAL_RECORDS: this frame's deeper ones, or the frame before's
    // where it gathers its statistics with its count).
    var per_batch = 0u;
    if (plan.record_bytes > 0u && !exact) {
        let marked = w_of(totals[TOTAL_RECORDS]);
        let records = w_max(marked, w_of(1u));
        // At most the records (a u32 count).
        per_batch = w_min(w_max(w_div_u32(pool, plan.record_bytes), w_of(1u)), records).x;
        let batches = w_max(ceil_div(marked, per_batch), w_of(1u));
        if (w_lt(w_of(max(plan.batches, 1u)), batches)) {
            short |= PLAN_SHORT_RECORDS;
        }
    }
    if (exact) {
        f = n;
    }
    totals[PLAN_F_WORD] = w_min(f, n).x;
    totals[PLAN_FLAGS_WORD] = select(0u, 1u, exact) | (short << 1u);
    batch[BATCH_SIZE] = per_batch;
}
