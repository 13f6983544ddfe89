//! Per-pixel allocations of fragment slots: error curves, the optimal allocation (the training
//! target and quality ceiling), the paper's backward greedy, and k(p) from an importance map.
//!
//! Every allocation gives covered pixels (n(p) > 0) `lo <= k(p) <= n(p)` and uncovered pixels 0,
//! with `sum k = min(F, sum n)` exactly. Normally `lo = 1`; when F is smaller than the number of
//! covered pixels, one slot each cannot be given, so `lo = 0`: pixels with k = 0 are composited
//! entirely as tail, and which pixels keep a slot is decided by the same rule as the rest
//! (importance, or error for the optimal allocation).
//!
//! # Error curves
//! For a pixel with fragments sorted front to back, `e(k) = |C_exact - C_hybrid(k)|^2` (summed
//! over RGB) for k = 0..=n, computed in O(n) after the sort: prefix sums give the core colour and
//! transmittance, suffix sums the tail's `sum C a`, `sum a` and count. Computed in f64, so
//! `e(n) = 0` exactly.
//!
//! # Optimal allocation
//! Minimise `sum_p e_p(k_p)` subject to `sum k_p = min(F, sum n)`, `lo <= k_p <= n_p`: a
//! multiple-choice knapsack. Each curve is replaced by its lower convex hull; hull segments of all
//! pixels are taken in order of decreasing gain per slot, which solves the relaxation exactly and
//! gives a lower bound on the true optimum (the one segment only partly taken is interpolated).
//! The integer answer takes whole segments while they fit, fills the remainder with later
//! segments that fit, then repairs the neighbourhood of the critical gain with an exact dynamic
//! program on the true curves. The paper's backward greedy (Algorithm 1, keyed by the new error
//! as printed, and keyed by the error increase) is run too, and the best of the three is
//! returned, so the result is never worse than either greedy; all totals and the certified gap
//! (total minus lower bound) are reported.

use crate::fragment::{CLEAR, Fragment, FragmentLists, unpack_tint};
use rayon::prelude::*;
use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;

/// Error curves of every pixel: pixel p's e(0..=n_p) is `values[start[p]..start[p + 1]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorCurves {
    pub start: Vec<usize>,
    pub values: Vec<f64>,
}

impl ErrorCurves {
    pub fn curve(&self, p: usize) -> &[f64] {
        &self.values[self.start[p]..self.start[p + 1]]
    }
    pub fn pixels(&self) -> usize {
        self.start.len() - 1
    }
    /// n(p) for every pixel.
    pub fn counts(&self) -> Vec<u32> {
        self.start
            .windows(2)
            .map(|w| (w[1] - w[0] - 1) as u32)
            .collect()
    }
    /// The curves of a k-buffer whose tails share its slots' pool (VKB, DKB): a pixel given k
    /// slots stores `shared::stored_k(k, n)`, all n where its tail would hold no more than a
    /// tail's words, so its error at k is e at that: 0 from `n - TAIL_WORDS` on. The optimum
    /// of these ([`optimal`]) is the least error such a k-buffer can reach with F slots.
    pub fn pooled(&self) -> ErrorCurves {
        let mut values = self.values.clone();
        for (p, n) in self.counts().into_iter().enumerate() {
            let c = &mut values[self.start[p]..self.start[p + 1]];
            for k in 0..=n {
                c[k as usize] = self.curve(p)[crate::shared::stored_k(k, n) as usize];
            }
        }
        ErrorCurves {
            start: self.start.clone(),
            values,
        }
    }
    /// Total error of an allocation.
    pub fn total(&self, k: &[u32]) -> f64 {
        (0..self.pixels())
            .map(|p| self.curve(p)[k[p] as usize])
            .sum()
    }
}

/// One pixel's error curve e(0..=n) from fragments sorted front to back, in O(n).
pub fn error_curve_sorted(frags: &[Fragment], bg: [f32; 3], out: &mut [f64]) {
    let n = frags.len();
    debug_assert_eq!(out.len(), n + 1);
    let bg = bg.map(f64::from);
    // Suffix sums of the tail: for k, fragments k..n (0-based) form the tail.
    // Tinted fragments (composite::Tail) filter per channel: the tail by its mean
    // transmittance to the power of its count where one of them is tinted.
    let mut sca = [0.0f64; 3];
    let mut sa = 0.0f64;
    let mut st = [0.0f64; 3];
    let mut tinted = false;
    let mut behind = vec![[0.0f64; 3]; n + 1];
    behind[n] = bg;
    for k in (0..n).rev() {
        let f = &frags[k];
        let a = f.rgba[3] as f64;
        for (s, ch) in sca.iter_mut().zip(f.rgba) {
            *s += ch as f64 * a;
        }
        for (s, g) in st.iter_mut().zip(unpack_tint(f.tint)) {
            *s += (1.0 - a) * g as f64;
        }
        tinted |= f.tint != CLEAR;
        sa += a;
        let t = (n - k) as i32;
        behind[k] = if sa <= 0.0 && !tinted {
            bg
        } else {
            let a_tail = 1.0 - (1.0 - (sa / t as f64).min(1.0)).powi(t);
            // a_tail sum(C a), then over sum(a): the rounding the committed weights' training
            // targets were computed with (`make train` reproduces them bit for bit).
            let colour = |i: usize| if sa > 0.0 { a_tail * sca[i] / sa } else { 0.0 };
            let through = |i: usize| match tinted {
                false => 1.0 - a_tail,
                true => (st[i] / t as f64).min(1.0).powi(t),
            };
            std::array::from_fn(|i| colour(i) + through(i) * bg[i])
        };
    }
    // Prefix: core colour and transmittance after k fragments, per channel.
    let mut core = [0.0f64; 3];
    let mut tr = [1.0f64; 3];
    let mut hybrid = vec![[0.0f64; 3]; n + 1];
    for k in 0..=n {
        hybrid[k] = std::array::from_fn(|i| core[i] + tr[i] * behind[k][i]);
        if k < n {
            let f = &frags[k];
            let a = f.rgba[3] as f64;
            let g = unpack_tint(f.tint);
            for i in 0..3 {
                core[i] += tr[i] * a * f.rgba[i] as f64;
                tr[i] *= (1.0 - a) * g[i] as f64;
            }
        }
    }
    let exact = hybrid[n];
    for k in 0..=n {
        out[k] = (0..3).map(|i| (exact[i] - hybrid[k][i]).powi(2)).sum();
    }
}

/// Error curves of every pixel of a frame, over what is behind each pixel
/// ([`FragmentLists::behind`]: its opaque surface, else the background `bg`).
pub fn error_curves(fl: &FragmentLists, bg: [f32; 3]) -> ErrorCurves {
    let pixels = fl.pixel_count();
    let start: Vec<usize> = (0..=pixels).map(|p| fl.offsets[p] as usize + p).collect();
    let mut values = vec![0.0f64; start[pixels]];
    // Split the output into per-row slices so rows run in parallel.
    let w = fl.width as usize;
    let mut rows: Vec<(usize, &mut [f64])> = Vec::with_capacity(fl.height as usize);
    let mut rest: &mut [f64] = &mut values;
    for y in 0..fl.height as usize {
        let len = start[(y + 1) * w] - start[y * w];
        let (head, tail) = rest.split_at_mut(len);
        rows.push((y, head));
        rest = tail;
    }
    rows.into_par_iter()
        .for_each_init(Vec::new, |scratch: &mut Vec<Fragment>, (y, row)| {
            let base = start[y * w];
            for p in y * w..(y + 1) * w {
                fl.sorted_into(p, scratch);
                let bg = fl.behind(p, bg);
                error_curve_sorted(scratch, bg, &mut row[start[p] - base..start[p + 1] - base]);
            }
        });
    ErrorCurves { start, values }
}

/// The smallest k a covered pixel may get for F slots: 1 when every covered pixel can have one.
pub fn min_k(counts: &[u32], f: u64) -> u32 {
    let covered = counts.iter().filter(|&&n| n > 0).count() as u64;
    u32::from(f >= covered)
}

/// `min(F, sum n)`: the slots an allocation hands out.
pub fn slots_to_allocate(counts: &[u32], f: u64) -> u64 {
    f.min(counts.iter().map(|&n| n as u64).sum())
}

/// Totals of the optimal allocation and of the greedies, side by side.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct OptimalReport {
    /// Total error of the returned allocation.
    pub total: f64,
    /// Lower bound from the convex-hull relaxation.
    pub lower_bound: f64,
    /// Total of the hull allocation after fill and repair (before taking the best).
    pub hull_total: f64,
    /// Paper's Algorithm 1 as printed (heap keyed by the new error).
    pub greedy_paper_total: f64,
    /// Algorithm 1 with the heap keyed by the error increase.
    pub greedy_increase_total: f64,
    /// Which one was returned: "hull", "greedy-paper" or "greedy-increase".
    pub chosen: &'static str,
    /// The Lagrange multiplier of the budget: the error one slot saves at the margin (the gain
    /// per slot of the first convex-hull segment that did not fit; 0 when everything fits).
    pub critical_gain: f64,
}

impl OptimalReport {
    /// Certified gap: the returned total minus the lower bound (>= 0 up to rounding).
    pub fn gap(&self) -> f64 {
        self.total - self.lower_bound
    }
}

/// Which heap key the backward greedy uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GreedyKey {
    /// The pixel's error after removing its farthest fragment (Algorithm 1 as printed).
    NewError,
    /// The increase in the pixel's error that removal causes.
    Increase,
}

#[derive(PartialEq)]
struct HeapItem(f64, u32);
impl Eq for HeapItem {}
impl PartialOrd for HeapItem {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for HeapItem {
    fn cmp(&self, o: &Self) -> Ordering {
        self.0.total_cmp(&o.0).then(self.1.cmp(&o.1))
    }
}

fn greedy_key(curves: &ErrorCurves, key: GreedyKey, p: usize, kp: u32) -> f64 {
    let c = curves.curve(p);
    match key {
        GreedyKey::NewError => c[kp as usize - 1],
        GreedyKey::Increase => c[kp as usize - 1] - c[kp as usize],
    }
}

/// The paper's backward greedy (Algorithm 1) with a min-heap, as written: start from k = n and
/// repeatedly remove the fragment whose removal has the smallest key (ties: lower pixel index),
/// until `sum k = min(F, sum n)`. [`greedy`] gives the same answer faster.
pub fn greedy_heap(curves: &ErrorCurves, f: u64, key: GreedyKey) -> Vec<u32> {
    let counts = curves.counts();
    let lo = min_k(&counts, f);
    let mut k = counts.clone();
    let total: u64 = counts.iter().map(|&n| n as u64).sum();
    let mut to_remove = total - slots_to_allocate(&counts, f);
    let mut heap: BinaryHeap<Reverse<HeapItem>> = (0..counts.len())
        .filter(|&p| counts[p] > lo)
        .map(|p| Reverse(HeapItem(greedy_key(curves, key, p, counts[p]), p as u32)))
        .collect();
    while to_remove > 0 {
        let Some(Reverse(HeapItem(_, p))) = heap.pop() else {
            break;
        };
        let p = p as usize;
        k[p] -= 1;
        to_remove -= 1;
        if k[p] > lo {
            heap.push(Reverse(HeapItem(
                greedy_key(curves, key, p, k[p]),
                p as u32,
            )));
        }
    }
    k
}

/// The backward greedy without the heap. A pixel's removals become available one after another,
/// so the heap pops removal j of pixel p exactly in the order of (the running maximum of the
/// pixel's keys up to j, p, j): a removal whose key is below that maximum is popped right after
/// its predecessor. Selecting the first `sum n - min(F, sum n)` removals in that order (linear
/// time) gives the heap's allocation.
pub fn greedy(curves: &ErrorCurves, f: u64, key: GreedyKey) -> Vec<u32> {
    let counts = curves.counts();
    let lo = min_k(&counts, f);
    let total: u64 = counts.iter().map(|&n| n as u64).sum();
    let to_remove = (total - slots_to_allocate(&counts, f)) as usize;
    let mut k = counts.clone();
    if to_remove == 0 {
        return k;
    }
    #[derive(Clone, Copy)]
    struct Removal {
        order: f64,
        pixel: u32,
        j: u32,
    }
    let mut removals: Vec<Removal> = (0..counts.len())
        .into_par_iter()
        .fold(Vec::new, |mut v, p| {
            let mut running = f64::NEG_INFINITY;
            for (j, kp) in (lo + 1..=counts[p]).rev().enumerate() {
                let key = greedy_key(curves, key, p, kp);
                if key.total_cmp(&running) == Ordering::Greater {
                    running = key;
                }
                v.push(Removal {
                    order: running,
                    pixel: p as u32,
                    j: j as u32,
                });
            }
            v
        })
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });
    let cmp = |a: &Removal, b: &Removal| {
        a.order
            .total_cmp(&b.order)
            .then(a.pixel.cmp(&b.pixel))
            .then(a.j.cmp(&b.j))
    };
    if to_remove < removals.len() {
        removals.select_nth_unstable_by(to_remove - 1, cmp);
    }
    for r in &removals[..to_remove] {
        k[r.pixel as usize] -= 1;
    }
    k
}

/// A lower-hull segment of one pixel's curve: from k to k + len, gain per slot.
#[derive(Clone, Copy, Debug)]
struct Segment {
    gain: f64,
    pixel: u32,
    k: u32,
    len: u32,
}

/// Lower convex hull of (k, e(k)) for k in lo..=n, as segments in increasing k.
fn hull_segments(curve: &[f64], lo: usize, pixel: u32, out: &mut Vec<Segment>) {
    let n = curve.len() - 1;
    if n <= lo {
        return;
    }
    let mut hull: Vec<usize> = Vec::with_capacity(8);
    for k in lo..=n {
        while hull.len() >= 2 {
            let (a, b) = (hull[hull.len() - 2], hull[hull.len() - 1]);
            // Drop b if it is not strictly below the line from a to k.
            let cross =
                (curve[b] - curve[a]) * (k - a) as f64 - (curve[k] - curve[a]) * (b - a) as f64;
            if cross >= 0.0 {
                hull.pop();
            } else {
                break;
            }
        }
        hull.push(k);
    }
    for w in hull.windows(2) {
        let len = (w[1] - w[0]) as u32;
        out.push(Segment {
            gain: (curve[w[0]] - curve[w[1]]) / len as f64,
            pixel,
            k: w[0] as u32,
            len,
        });
    }
}

/// Exact DP over a few pixels: choose k_q in ranges[q] with sum = budget minimising the true
/// error. Returns None when no choice fits.
fn repair_dp(
    curves: &ErrorCurves,
    pixels: &[usize],
    ranges: &[(u32, u32)],
    budget: u64,
) -> Option<Vec<u32>> {
    let base: u64 = ranges.iter().map(|r| r.0 as u64).sum();
    if budget < base {
        return None;
    }
    let cap = (budget - base) as usize;
    let inf = f64::INFINITY;
    // best[j][c]: minimal error of the first j pixels using c extra slots.
    let mut best = vec![inf; cap + 1];
    best[0] = 0.0;
    let mut choice: Vec<Vec<u32>> = Vec::with_capacity(pixels.len());
    for (q, &p) in pixels.iter().enumerate() {
        let (lo, hi) = ranges[q];
        let curve = curves.curve(p);
        let mut next = vec![inf; cap + 1];
        let mut pick = vec![0u32; cap + 1];
        for (c, &bc) in best.iter().enumerate() {
            if bc == inf {
                continue;
            }
            for extra in 0..=(hi - lo) as usize {
                let c2 = c + extra;
                if c2 > cap {
                    break;
                }
                let v = bc + curve[lo as usize + extra];
                if v < next[c2] {
                    next[c2] = v;
                    pick[c2] = extra as u32;
                }
            }
        }
        best = next;
        choice.push(pick);
    }
    if best[cap] == inf {
        return None;
    }
    let mut out = vec![0u32; pixels.len()];
    let mut c = cap;
    for q in (0..pixels.len()).rev() {
        let e = choice[q][c];
        out[q] = ranges[q].0 + e;
        c -= e as usize;
    }
    Some(out)
}

/// The convex-hull allocation with fill and repair, its lower bound and the critical gain (the
/// gain per slot of the first hull segment that did not fit whole; 0 when every one fits).
fn hull_allocation(curves: &ErrorCurves, f: u64) -> (Vec<u32>, f64, f64) {
    let counts = curves.counts();
    let lo = min_k(&counts, f);
    let mut k: Vec<u32> = counts.iter().map(|&n| if n > 0 { lo } else { 0 }).collect();
    let base: u64 = k.iter().map(|&x| x as u64).sum();
    let mut rem = slots_to_allocate(&counts, f) - base;
    let start_total: f64 = curves.total(&k);
    let mut segs: Vec<Segment> = (0..counts.len())
        .into_par_iter()
        .fold(Vec::new, |mut v, p| {
            if counts[p] > 0 {
                hull_segments(curves.curve(p), lo as usize, p as u32, &mut v);
            }
            v
        })
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });
    segs.par_sort_unstable_by(|a, b| {
        b.gain
            .total_cmp(&a.gain)
            .then(a.pixel.cmp(&b.pixel))
            .then(a.k.cmp(&b.k))
    });
    // Whole segments while they fit; the first that does not is the critical one.
    let mut bound_gain = 0.0f64;
    let mut critical = segs.len();
    for (i, s) in segs.iter().enumerate() {
        if s.len as u64 <= rem {
            k[s.pixel as usize] += s.len;
            rem -= s.len as u64;
            bound_gain += s.gain * s.len as f64;
        } else {
            critical = i;
            bound_gain += s.gain * rem as f64;
            break;
        }
    }
    let lower_bound = (start_total - bound_gain).max(0.0);
    let critical_gain = segs.get(critical).map_or(0.0, |s| s.gain.max(0.0));
    if rem == 0 || critical == segs.len() {
        return (k, lower_bound, critical_gain);
    }
    // Fill: later segments that fit, in gain order, each only when its pixel's earlier
    // segments are taken (k equals the segment's start).
    let mut filled = Vec::new();
    for (i, s) in segs.iter().enumerate().skip(critical) {
        if rem == 0 {
            break;
        }
        if s.len as u64 <= rem && k[s.pixel as usize] == s.k {
            k[s.pixel as usize] += s.len;
            rem -= s.len as u64;
            filled.push(i);
        }
    }
    // Repair: exact DP over the pixels whose segments are nearest the critical gain.
    const WINDOW: usize = 24;
    let lo_i = critical.saturating_sub(WINDOW);
    let hi_i = (critical + WINDOW).min(segs.len());
    let mut pixels: Vec<usize> = segs[lo_i..hi_i].iter().map(|s| s.pixel as usize).collect();
    pixels.sort_unstable();
    pixels.dedup();
    let ranges: Vec<(u32, u32)> = pixels
        .iter()
        .map(|&p| {
            // Anything between the pixel's k before its window segments and after them.
            let mut a = k[p];
            let mut b = k[p];
            for s in segs[lo_i..hi_i].iter().filter(|s| s.pixel as usize == p) {
                a = a.min(s.k);
                b = b.max(s.k + s.len);
            }
            (a.max(if counts[p] > 0 { lo } else { 0 }), b.min(counts[p]))
        })
        .collect();
    let budget: u64 = pixels.iter().map(|&p| k[p] as u64).sum::<u64>() + rem;
    let span: u64 = ranges.iter().map(|r| (r.1 - r.0) as u64).sum();
    // The DP costs about pixels x span^2; skip it where that is too much (rare, long segments).
    if span > 0
        && span * span * pixels.len() as u64 <= 50_000_000
        && let Some(best) = repair_dp(curves, &pixels, &ranges, budget)
    {
        let before: f64 = pixels.iter().map(|&p| curves.curve(p)[k[p] as usize]).sum();
        let after: f64 = pixels
            .iter()
            .zip(&best)
            .map(|(&p, &kp)| curves.curve(p)[kp as usize])
            .sum();
        if after <= before || rem > 0 {
            for (&p, &kp) in pixels.iter().zip(&best) {
                k[p] = kp;
            }
            rem = 0;
        }
    }
    // Whatever is still left (no repair possible) goes one slot at a time to the pixels where
    // it lowers the true error most.
    while rem > 0 {
        let mut best: Option<(f64, usize)> = None;
        for p in 0..counts.len() {
            if k[p] < counts[p] {
                let c = curves.curve(p);
                let gain = c[k[p] as usize] - c[k[p] as usize + 1];
                if best.is_none_or(|b| gain > b.0) {
                    best = Some((gain, p));
                }
            }
        }
        let Some((_, p)) = best else { break };
        k[p] += 1;
        rem -= 1;
    }
    (k, lower_bound, critical_gain)
}

/// The optimal allocation (see the module docs) with the report of every total.
pub fn optimal(curves: &ErrorCurves, f: u64) -> (Vec<u32>, OptimalReport) {
    let ((hull_k, lower_bound, critical_gain), (paper, increase)) = rayon::join(
        || hull_allocation(curves, f),
        || {
            rayon::join(
                || greedy(curves, f, GreedyKey::NewError),
                || greedy(curves, f, GreedyKey::Increase),
            )
        },
    );
    let totals = [
        (curves.total(&hull_k), "hull"),
        (curves.total(&paper), "greedy-paper"),
        (curves.total(&increase), "greedy-increase"),
    ];
    // Best total; ties prefer the hull answer, then the printed greedy.
    let (i, &(total, chosen)) = totals
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.0.total_cmp(&b.1.0).then(a.0.cmp(&b.0)))
        .expect("three totals");
    let k = match i {
        0 => hull_k,
        1 => paper,
        _ => increase,
    };
    let report = OptimalReport {
        total,
        lower_bound: lower_bound.min(total),
        hull_total: totals[0].0,
        greedy_paper_total: totals[1].0,
        greedy_increase_total: totals[2].0,
        chosen,
        critical_gain,
    };
    (k, report)
}

/// Fixed k-buffer: the same k = floor(F / |P|) for every pixel (its capacity, not capped by n).
pub fn fixed(pixels: usize, f: u64) -> Vec<u32> {
    let k = (f / pixels.max(1) as u64).min(u32::MAX as u64) as u32;
    vec![k; pixels]
}

/// Fixed-point scale of a proportional importance (20 fractional bits) in its water-filling
/// weight ([`importance_weight`]): integer sums are exact and the same in every order, on the
/// CPU and in the GPU's allocation pass.
pub const IMPORTANCE_SCALE: f32 = 1_048_576.0;
/// Largest proportional importance a weight tells apart (larger values count as this).
pub const MAX_IMPORTANCE: f32 = 15.0;

/// Fixed-point bits of the water-filling weights: `k_p(lambda) = clamp(floor(lambda w_p /
/// 2^WEIGHT_BITS), lo, n_p)`. Weights are below `2^WEIGHT_BITS`, so raising lambda by one raises
/// any k by at most one.
pub const WEIGHT_BITS: u32 = 24;
/// Largest weight.
pub const WEIGHT_MAX: u32 = (1 << WEIGHT_BITS) - 1;
/// Below `2^LAMBDA_BITS` the scale applies: near the top every covered pixel (weight >= 1)
/// reaches its cap, since n < 2^16 and `2^40 / 2^24 = 2^16`; `lambda w < 2^64` throughout.
pub const LAMBDA_BITS: u32 = 40;

/// A proportional importance (VKB's, or a network trained for `k / max k`) as a water-filling
/// weight: `clamp(floor(i 2^20 + 1/2), 1, WEIGHT_MAX)`; non-finite or negative values count as 0
/// (then 1, the smallest weight, so every covered pixel can still reach n).
pub fn importance_weight(i: f32) -> u32 {
    if i.is_finite() && i > 0.0 {
        ((i.min(MAX_IMPORTANCE) * IMPORTANCE_SCALE + 0.5).floor() as u32).clamp(1, WEIGHT_MAX)
    } else {
        1
    }
}

/// A predicted share of the pixel's own fragments `r = k / n` as a water-filling weight: the
/// slots the pixel asks for, `r n`, with 8 fractional bits: `clamp(floor(r n 256 + 1/2), 1,
/// WEIGHT_MAX)` (r is clamped to [0, 1]; at lambda = 2^24 every pixel gets `floor(r n)`).
pub fn share_weight(r: f32, n: u32) -> u32 {
    let r = if r.is_finite() {
        r.clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((r * n as f32 * (1 << REQUEST_BITS) as f32 + 0.5).floor() as u32).clamp(1, WEIGHT_MAX)
}

/// The sign bit of an importance value ([`allocate`]) and bit 31 of a water-filling weight or
/// slot request: the pixel's two farthest fragments share one colour (and opacity), so a tail
/// of those two composites exactly too and the pixel can use one slot fewer (see
/// [`useful_cap`]). DKB's features pass knows it (`importance::tail_pair`); VKB sets it never.
pub const PAIR_BIT: u32 = 1 << 31;

/// The most slots a covered pixel gets before every covered pixel has as many: all but its
/// farthest fragment, `max(n - 1, lo)`, or all but its two farthest when they share one colour
/// (`pair`). A tail of one fragment composites exactly (its `a_tail` is its own opacity and its
/// colour its own), and so does a tail of fragments that share colour and opacity, so
/// `e(n - 1) = e(n)` (and `e(n - 2) = e(n)` for a pair): those slots save nothing, and are
/// handed out only once every pixel holds its cap (see [`water_level_k`]).
#[inline]
pub fn useful_cap(n: u32, lo: u32, pair: bool) -> u32 {
    n.saturating_sub(1 + u32::from(pair)).max(lo).min(n)
}

/// Lambda from which every covered pixel holds its [`useful_cap`] (the scale's top).
pub const LAMBDA_CAP: u64 = 1 << LAMBDA_BITS;
/// Lambda from which every covered pixel holds all but its farthest fragment.
pub const LAMBDA_ALL_BUT_ONE: u64 = 2 << LAMBDA_BITS;
/// Lambda from which every covered pixel holds all its fragments.
pub const LAMBDA_FULL: u64 = 3 << LAMBDA_BITS;

/// k of a covered pixel in the tiers above the fill: `tier` 1 its useful cap, 2 all but its
/// farthest fragment, 3 all; tier 0 clamps `k` between lo and the cap.
#[inline]
fn tier_k(tier: u32, k: i64, n: u32, lo: u32, pair: bool) -> u32 {
    let cap = useful_cap(n, lo, pair);
    match tier {
        0 => k.clamp(lo as i64, cap as i64) as u32,
        1 => cap,
        2 => useful_cap(n, lo, false),
        _ => n,
    }
}

/// k of one pixel at lambda (0 for uncovered pixels), `w` a weight with its [`PAIR_BIT`]:
/// `clamp(floor(lambda w / 2^24), lo, useful_cap)` below [`LAMBDA_CAP`], the cap up to
/// [`LAMBDA_ALL_BUT_ONE`], `max(n - 1, lo)` up to [`LAMBDA_FULL`], then n. Rises by at most one
/// when lambda rises by one.
#[inline]
pub fn water_level_k(lambda: u64, w: u32, n: u32, lo: u32) -> u32 {
    if n == 0 {
        return 0;
    }
    let tier = (lambda >> LAMBDA_BITS).min(3) as u32;
    let k = if tier == 0 {
        (lambda * (w & WEIGHT_MAX) as u64) >> WEIGHT_BITS
    } else {
        0
    };
    tier_k(tier, k as i64, n, lo, w & PAIR_BIT != 0)
}

/// Slots handed out at lambda.
fn water_level_sum(lambda: u64, w: &[u32], counts: &[u32], lo: u32) -> u64 {
    w.par_iter()
        .zip(counts)
        .map(|(&w, &n)| water_level_k(lambda, w, n, lo) as u64)
        .sum()
}

/// Water-filling allocation (CPU twin of the GPU allocation): with weights `w_p` (see
/// [`importance_weight`], [`share_weight`]), `k_p = clamp(floor(lambda w_p / 2^24), lo,
/// useful_cap_p)` (see [`water_level_k`]) where lambda is the largest integer in `[0,
/// LAMBDA_FULL]` whose total fits `min(F, sum n)`; the slots still missing go one each to the
/// first pixels, by index, whose k rises at lambda + 1 (there are more of those than slots
/// missing). A pixel whose weight asks for more than it can use is captured as good as whole
/// (all but its farthest fragment, which composites exactly as a tail of one), and what the cap
/// leaves over flows to the others: `sum k = min(F, sum n)`
/// exactly, covered pixels get `lo <= k <= n`, uncovered 0; lo is 1 unless F is below the
/// covered pixels. The result is unique (it does not depend on how lambda is searched).
pub fn water_fill(w: &[u32], counts: &[u32], f: u64) -> Vec<u32> {
    assert_eq!(w.len(), counts.len(), "one weight per pixel");
    let target = slots_to_allocate(counts, f);
    let lo = min_k(counts, f);
    let (mut a, mut b) = (0u64, LAMBDA_FULL);
    // Invariant: sum(a) <= target; sum(b) > target unless b is the top and fits.
    if water_level_sum(b, w, counts, lo) <= target {
        a = b;
    }
    while b - a > 1 {
        let mid = a + (b - a) / 2;
        if water_level_sum(mid, w, counts, lo) <= target {
            a = mid;
        } else {
            b = mid;
        }
    }
    let mut k: Vec<u32> = w
        .iter()
        .zip(counts)
        .map(|(&w, &n)| water_level_k(a, w, n, lo))
        .collect();
    let mut left = target - k.iter().map(|&x| x as u64).sum::<u64>();
    for p in 0..k.len() {
        if left == 0 {
            break;
        }
        if water_level_k(a + 1, w[p], counts[p], lo) > k[p] {
            k[p] += 1;
            left -= 1;
        }
    }
    debug_assert_eq!(
        left, 0,
        "more pixels rise at lambda + 1 than slots are missing"
    );
    k
}

/// Fractional bits of a slot request: requests are in 1/256 of a slot.
pub const REQUEST_BITS: u32 = 8;
/// The most slots a network output of 1 requests (before the level).
pub const REQUEST_SLOTS: f32 = 256.0;
/// The level is searched in `[LEVEL_FULL, 2^24]` (in 1/256 slot): at [`LEVEL_CAP`] every covered
/// pixel holds its [`useful_cap`] (requests are below 2^24 and n below 2^16), at
/// [`LEVEL_FULL`] all its fragments, at the top every pixel falls to lo.
pub const LEVEL_BITS: u32 = 24;

/// A network output `r` in [0, 1] as a slot request in 1/256 of a slot:
/// `floor(r REQUEST_SLOTS 256 + 1/2)`, below `2^24`.
pub fn slot_request(r: f32) -> u32 {
    let r = if r.is_finite() {
        r.clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((r * REQUEST_SLOTS * (1 << REQUEST_BITS) as f32 + 0.5).floor() as u32).min(WEIGHT_MAX)
}

/// Level at and below which every covered pixel holds its [`useful_cap`]: `2^24 - 2^26`.
pub const LEVEL_CAP: i64 = (1 << LEVEL_BITS) - (1 << (LEVEL_BITS + 2));
/// Level at and below which every covered pixel holds all but its farthest fragment.
pub const LEVEL_ALL_BUT_ONE: i64 = (1 << LEVEL_BITS) - (2 << (LEVEL_BITS + 2));
/// Level at and below which every covered pixel holds all its fragments (the search's bottom).
pub const LEVEL_FULL: i64 = (1 << LEVEL_BITS) - (3 << (LEVEL_BITS + 2));

/// k of one pixel at level L (0 for uncovered pixels), `c` a request with its [`PAIR_BIT`]:
/// `clamp(floor((c - L) / 256), lo, useful_cap)` above [`LEVEL_CAP`], the cap down to
/// [`LEVEL_ALL_BUT_ONE`], `max(n - 1, lo)` down to [`LEVEL_FULL`], then n.
#[inline]
pub fn level_k(level: i64, c: u32, n: u32, lo: u32) -> u32 {
    if n == 0 {
        return 0;
    }
    // The level as the GPU's t = 2^24 - L, in tiers of 2^26.
    let t = (1i64 << LEVEL_BITS) - level;
    let tier = if t <= 0 {
        0
    } else {
        (t >> (LEVEL_BITS + 2)).min(3) as u32
    };
    let k = ((c & WEIGHT_MAX) as i64 - level).div_euclid(1 << REQUEST_BITS);
    tier_k(tier, k, n, lo, c & PAIR_BIT != 0)
}

fn level_sum(level: i64, c: &[u32], counts: &[u32], lo: u32) -> u64 {
    c.par_iter()
        .zip(counts)
        .map(|(&c, &n)| level_k(level, c, n, lo) as u64)
        .sum()
}

/// Additive water level (CPU twin of the GPU allocation for slot requests): each covered pixel
/// asks for `c_p` slots (1/256 units, see [`slot_request`]) and gets `k_p = clamp(floor((c_p -
/// L) / 256), lo, useful_cap_p)` (see [`level_k`]), where L is the smallest integer level in
/// `[LEVEL_FULL, 2^24]` whose total fits `min(F, sum n)`; the slots still missing go one each to
/// the first pixels, by index, whose k rises at L - 1. Pixels whose request exceeds what they
/// can use are captured as good as whole (all but the farthest fragment, which composites
/// exactly as a tail of one) and the level hands what they leave to the others: `sum k =
/// min(F, sum n)` exactly, covered pixels get `lo <= k <= n`. A common error in every request
/// moves L, not the allocation.
pub fn level_fill(c: &[u32], counts: &[u32], f: u64) -> Vec<u32> {
    assert_eq!(c.len(), counts.len(), "one request per pixel");
    let target = slots_to_allocate(counts, f);
    let lo = min_k(counts, f);
    // Invariant: sum(b) <= target; sum(a) > target unless a is the bottom and fits.
    let (mut a, mut b) = (LEVEL_FULL, 1i64 << LEVEL_BITS);
    if level_sum(a, c, counts, lo) <= target {
        b = a;
    }
    while b - a > 1 {
        let mid = a + (b - a) / 2;
        if level_sum(mid, c, counts, lo) <= target {
            b = mid;
        } else {
            a = mid;
        }
    }
    let mut k: Vec<u32> = c
        .iter()
        .zip(counts)
        .map(|(&c, &n)| level_k(b, c, n, lo))
        .collect();
    let mut left = target - k.iter().map(|&x| x as u64).sum::<u64>();
    for p in 0..k.len() {
        if left == 0 {
            break;
        }
        if level_k(b - 1, c[p], counts[p], lo) > k[p] {
            k[p] += 1;
            left -= 1;
        }
    }
    debug_assert_eq!(left, 0, "more pixels rise at L - 1 than slots are missing");
    k
}

/// What the network's output (in (0, 1)) means, so the runtime turns it into slots the way it
/// was trained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Target {
    /// `r = k / n`: the share of the pixel's own fragments to keep. The allocation asks for `r n`
    /// slots per pixel and water-fills (see [`share_weight`]).
    #[default]
    ShareOfFragments,
    /// `k / max_q k(q)` (the paper's): proportional importance (see [`importance_weight`]).
    RelativeK,
    /// A slot request `256 r`: the allocation gives `k = clamp(256 r - L, lo, n)` with one level
    /// L for the frame (see [`level_fill`]).
    SlotRequest,
}

impl Target {
    pub fn name(self) -> &'static str {
        match self {
            Target::ShareOfFragments => "k_over_n",
            Target::RelativeK => "k_over_max_k",
            Target::SlotRequest => "slot_request",
        }
    }
    pub fn parse(s: &str) -> Option<Target> {
        [
            Target::ShareOfFragments,
            Target::RelativeK,
            Target::SlotRequest,
        ]
        .into_iter()
        .find(|t| t.name() == s)
    }
    /// The water-filling weight of one covered pixel with n fragments and network output `i`.
    pub fn weight(self, i: f32, n: u32) -> u32 {
        match self {
            Target::ShareOfFragments => share_weight(i, n),
            Target::RelativeK => importance_weight(i),
            Target::SlotRequest => slot_request(i),
        }
    }
    /// Whether the weights are slot requests fitted by an additive level (else water-filling
    /// weights fitted by a scale).
    pub fn additive(self) -> bool {
        self == Target::SlotRequest
    }
}

/// k from any importance map as a network with that target would allocate it (VKB's importance
/// is `Target::RelativeK`): the weights of covered pixels, then [`water_fill`] or
/// [`level_fill`]. The sign bit of an importance value is the pixel's [`PAIR_BIT`] (DKB sets it
/// where the two farthest fragments share one colour); its magnitude is the importance. The CPU
/// twin of the GPU allocation pass.
pub fn allocate(importance: &[f32], counts: &[u32], target: Target, f: u64) -> Vec<u32> {
    assert_eq!(importance.len(), counts.len(), "one importance per pixel");
    let w: Vec<u32> = importance
        .iter()
        .zip(counts)
        .map(|(&i, &n)| if n > 0 { pixel_weight(target, i, n) } else { 0 })
        .collect();
    if target.additive() {
        level_fill(&w, counts, f)
    } else {
        water_fill(&w, counts, f)
    }
}

/// [`allocate`] for a k-buffer whose tails share its slots' pool (VKB, DKB, an allocated
/// importance on the GPU, where the allocation pass marks every pixel): every covered pixel
/// marked with the [`PAIR_BIT`], whatever its importance's sign. A pooled pixel left out by no
/// more than a tail's `shared::TAIL_WORDS` (two) fragments keeps them all (`shared::stored_k`),
/// so, as for a pair, its slots past all but its two farthest fragments save nothing.
pub fn allocate_pooled(importance: &[f32], counts: &[u32], target: Target, f: u64) -> Vec<u32> {
    let marked: Vec<f32> = importance.iter().map(|&i| mark_pair(i, true)).collect();
    allocate(&marked, counts, target, f)
}

/// A covered pixel's weight or request from its importance, with the [`PAIR_BIT`] the
/// importance's sign bit carries (the allocation pass's `weights` entry point).
pub fn pixel_weight(target: Target, i: f32, n: u32) -> u32 {
    let pair = i.is_sign_negative();
    target.weight(f32::from_bits(i.to_bits() & !PAIR_BIT), n) | if pair { PAIR_BIT } else { 0 }
}

/// An importance value marked as a pixel whose two farthest fragments share one colour (its
/// sign bit set, see [`allocate`]).
pub fn mark_pair(i: f32, pair: bool) -> f32 {
    f32::from_bits(i.to_bits() | if pair { PAIR_BIT } else { 0 })
}
