//! The frame's plan: what an allocated k-buffer's frame (DKB, VKB, an uploaded importance)
//! decides from its own count, on the device, so that no frame waits for it. The twin of
//! `plan.wgsl` (one invocation, after the count's totals), written step for step like it.
//!
//! Every buffer of a frame is sized before the frame is counted, for an occupancy the frame's
//! client expects ([`Occupancy`]: this frame's own where it counted first, as `Gpu::render`
//! does for the memory tables; an earlier frame's, read back without waiting, in an
//! application's renderer). The slot pool is one such buffer: `pool_bytes`. From the frame's
//! own count the plan then takes:
//!
//! - F: the budget's (`FragmentBudget::of` its count, or the most slots a byte budget holds
//!   for its occupancy, [`Layout::fragment_budget_counted`]), lowered to the most the pool holds
//!   where the pool is smaller than that: [`largest_fitting`]. A frame that needs more than the
//!   pool therefore keeps fewer fragments in slots and more in the tails, never more than the
//!   pool holds (the plan says so: [`Plan::short`]).
//! - Whether the frame keeps every fragment (k = n, the exact image): where F holds them all,
//!   or, with `exact_when_cheaper`, where the pool holds them all (then the exact answer costs
//!   no memory the frame does not hold already).
//! - DKB's records: how many a batch holds in the pool ([`crate::budget::PoolState::batch`])
//!   and how many batches the frame's records need; the client records `batches` features
//!   passes, and records past them get no importance of their own (the allocation's least
//!   weight), which [`Plan::short`] reports.
//!
//! Where the host knows the frame's count (the CPU renderer, `Gpu::render`), what its budget
//! comes to is decided once, by [`counted`]: the bytes, F, and whether the frame renders the
//! exact A-buffer instead ([`Counted`]). An application's frame, sized before its count, makes
//! the pool [`ahead`] gives for the occupancy it expects: for that occupancy, the bytes and F
//! `counted` decides.

pub use crate::budget::PlanBudget;
use crate::budget::{self, Layout, Occupancy, SLOT_BYTES, Words};
use crate::error::Result;
use crate::method::{Method, exact_is_no_dearer};

/// What a k-buffer's budget comes to on a frame whose fragments are counted: decided by
/// [`counted`] for the CPU renderer (`frame::Renderer`, the equal-bytes budget included) and for
/// the GPU engine's frames that count first (`Gpu::render`). A frame sized before its count
/// (an application's) is decided on the device instead ([`plan`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Counted {
    /// M: a byte budget's bytes, or what the method reserves for F, with the words its frame
    /// stores beside the slots ([`Layout::with_tints`]).
    pub bytes: u64,
    /// F(M); the frame's fragments n where the budget holds them all.
    pub f: u64,
    /// Whether the budget holds every fragment: F of at least n, or bytes that hold the exact
    /// A-buffer (a budget is a cap, not a quantity to spend).
    pub holds_all: bool,
    /// Whether the exact A-buffer needs no more bytes than the method reserves at F
    /// ([`exact_is_no_dearer`]).
    pub no_dearer: bool,
}

impl Counted {
    /// Whether the frame renders the exact A-buffer (k = n): where its budget holds every
    /// fragment, and with `exact_when_cheaper` where the A-buffer is no dearer.
    pub fn exact(&self, exact_when_cheaper: bool) -> bool {
        self.holds_all || (exact_when_cheaper && self.no_dearer)
    }
}

/// What `budget` comes to for the k-buffer `method` in `layout` on a frame of `pixels` and
/// occupancy `occ` that stores `words` beside its fragments: a byte budget that holds the exact
/// A-buffer keeps every fragment; other bytes hold the most slots their layout leaves after
/// the words ([`Layout::tinted_fragment_budget`]); F (slots or a share) reserves what the
/// layout takes for it ([`Layout::reserved_bytes`]) and its words.
pub fn counted(
    method: Method,
    layout: &Layout,
    budget: PlanBudget,
    pixels: u64,
    occ: &Occupancy,
    words: Words,
) -> Result<Counted> {
    let n = occ.fragments;
    if let PlanBudget::Bytes(m) = budget
        && m >= budget::abuffer_bytes(pixels, n, words.any())
    {
        return Ok(Counted {
            bytes: m,
            f: n,
            holds_all: true,
            no_dearer: true,
        });
    }
    let (bytes, f) = match budget {
        PlanBudget::Bytes(m) => (m, layout.tinted_fragment_budget(m, pixels, occ, words)?),
        PlanBudget::Fragments(b) => {
            let f = b.of(n);
            (
                layout.with_tints(layout.bytes_for(pixels, f, occ), pixels, words),
                f,
            )
        }
    };
    Ok(Counted {
        bytes,
        f,
        holds_all: f >= n,
        no_dearer: exact_is_no_dearer(method, layout, pixels, f, occ),
    })
}

/// The slot pool an application's frame is sized with before its count ([`ahead`]), and the
/// features passes DKB records for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ahead {
    pub pool_bytes: u64,
    pub batches: u64,
}

/// The pool a DKB or VKB frame sized before its count makes (an application's, read back
/// without waiting) for the occupancy `occ` its client expects: F's pool in the layout
/// ([`Layout::pool_for`], what [`counted`] reserves for F beyond the fixed bytes and words), or
/// what a byte budget's bytes leave beside the fixed bytes and the words (a fixed pool,
/// whatever the count). With `exact_when_cheaper` it is never more than the exact A-buffer of
/// that occupancy takes, so a frame that fits keeps every fragment ([`plan`]). DKB records the
/// batches of records that pool holds, up to its [`crate::budget::PoolState::batches`].
pub fn ahead(
    layout: &Layout,
    budget: PlanBudget,
    pixels: u64,
    occ: &Occupancy,
    words: Words,
    exact_when_cheaper: bool,
) -> Ahead {
    let pool = match budget {
        PlanBudget::Bytes(m) => layout
            .tinted_budget(m, pixels, words)
            .saturating_sub(layout.fixed_bytes(pixels)),
        PlanBudget::Fragments(b) => layout.pool_for(pixels, b.of(occ.fragments), occ),
    };
    let pool = match exact_when_cheaper {
        true => pool.min((SLOT_BYTES * occ.fragments).max(layout.pool_least(pixels, occ.deeper))),
        false => pool,
    };
    let pool_bytes = pool.max(crate::shared::LEAST_BUFFER_BYTES);
    Ahead {
        pool_bytes,
        batches: layout.pool_state.map_or(1, |ps| {
            let most = ps.batches.max(budget::MOST_RECORD_BATCHES);
            ps.batch(pool_bytes, occ.deeper).1.min(most)
        }),
    }
}

/// What a frame's plan is given before the frame is counted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlanInput {
    /// The method's layout (with pooled tails: DKB's, VKB's).
    pub layout: Layout,
    pub pixels: u64,
    pub budget: PlanBudget,
    /// Bytes of the frame's slot pool: its records and marks first (DKB), then its slots and
    /// pooled tails.
    pub pool_bytes: u64,
    /// DKB's features passes the frame records (one a batch of records; 1 for the others).
    pub batches: u64,
    /// Whether the frame keeps every fragment where its pool holds them all.
    pub exact_when_cheaper: bool,
}

/// What the plan found short: the pool held fewer slots than the budget's F.
pub const SHORT_SLOTS: u32 = 1;
/// The pool held fewer of DKB's records than the frame has, in the batches recorded.
pub const SHORT_RECORDS: u32 = 2;
/// A byte budget leaves this frame's occupancy no slot.
pub const NO_SLOT: u32 = 4;

/// A frame's plan.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Plan {
    /// F as the allocation takes it: at most the frame's fragments n; n where the frame keeps
    /// every fragment.
    pub f: u64,
    /// Whether the frame keeps every fragment (k = n everywhere).
    pub exact: bool,
    /// DKB's records a batch holds (0 where the frame gathers none: it keeps every fragment),
    /// and the batches its records need.
    pub per_batch: u64,
    pub batches: u64,
    /// [`SHORT_SLOTS`], [`SHORT_RECORDS`], [`NO_SLOT`].
    pub short: u32,
}

impl Plan {
    /// The plan as `plan.wgsl` writes it: F, then the flags (bit 0 exact, the short bits above
    /// it), then the records a batch holds.
    pub fn words(&self) -> [u32; 3] {
        let f = self.f.min(u32::MAX as u64) as u32;
        [
            f,
            self.exact as u32 | self.short << 1,
            self.per_batch.min(u32::MAX as u64) as u32,
        ]
    }

    /// The plan `plan.wgsl` wrote ([`Plan::words`]); `batches` are the host's to know.
    pub fn from_words([f, flags, per_batch]: [u32; 3], batches: u64) -> Plan {
        Plan {
            f: f as u64,
            exact: flags & 1 != 0,
            per_batch: per_batch as u64,
            batches,
            short: flags >> 1,
        }
    }
}

/// The largest F at most `cap` whose slots and tails take at most `words` pool words for a
/// frame of occupancy `occ` ([`Occupancy::pool_words_at`]), or None where even F = 0 takes
/// more. The words F takes are not monotone in F: below the covered pixels every covered pixel
/// may keep a tail (`covered + deep` words beside F), from there only the deep ones
/// (`deep + deeper`), so the fitting F lie in [0, f0] and [covered, f1].
pub fn largest_fitting(words: u64, occ: &Occupancy, cap: u64) -> Option<u64> {
    if words >= occ.fragments {
        // A pixel takes at most its n words: every F fits.
        return Some(cap);
    }
    if cap >= occ.covered
        && let Some(f1) = words.checked_sub(occ.deep + occ.deeper)
        && f1 >= occ.covered
    {
        return Some(cap.min(f1));
    }
    words
        .checked_sub(occ.covered + occ.deep)
        .map(|f0| cap.min(f0))
}

/// The frame's plan for its occupancy `occ` (plan.wgsl's `main`, step for step), its DKB
/// records its deeper pixels (a frame that marks its own records: [`plan_with_records`]).
pub fn plan(input: &PlanInput, occ: &Occupancy) -> Plan {
    plan_with_records(input, occ, occ.deeper)
}

/// [`plan`] of a DKB frame with `records` records (the pixels the frame before marked, where
/// the frame gathers its statistics with its count: the totals' `TOTAL_RECORDS`).
pub fn plan_with_records(input: &PlanInput, occ: &Occupancy, records: u64) -> Plan {
    let n = occ.fragments;
    let mut short = 0;
    // The budget's F.
    let budget_f = match input.budget {
        PlanBudget::Fragments(b) => b.of(n),
        PlanBudget::Bytes(m) => match input.layout.fragment_budget_counted(m, input.pixels, occ) {
            Ok(f) => f,
            Err(_) => {
                short |= NO_SLOT;
                0
            }
        },
    };
    // Within what the pool holds.
    let words = input.pool_bytes / SLOT_BYTES;
    let f = match largest_fitting(words, occ, budget_f) {
        Some(f) => f,
        None => {
            short |= SHORT_SLOTS;
            0
        }
    };
    if f < budget_f {
        short |= SHORT_SLOTS;
    }
    let exact = f >= n || (input.exact_when_cheaper && words >= n);
    // DKB's records, in batches of what the pool holds (none where every fragment is kept).
    let (per_batch, batches) = match input.layout.pool_state {
        Some(ps) if !exact => ps.batch(input.pool_bytes, records),
        _ => (0, 0),
    };
    if batches > input.batches.max(1) {
        short |= SHORT_RECORDS;
    }
    Plan {
        f: if exact { n } else { f.min(n) },
        exact,
        per_batch,
        batches,
        short,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::budget::{DKB, FragmentBudget, VKB};

    fn occ(fragments: u64, covered: u64, deep: u64, deeper: u64) -> Occupancy {
        Occupancy {
            fragments,
            covered,
            deep,
            deeper,
        }
    }

    /// A byte budget's F is the largest F whose reservation fits in it (DKB's records whole,
    /// or where that leaves no slot in up to three batches), found by trying every F (F = 0 is
    /// no slot: refused); bytes that hold the exact A-buffer keep every fragment;
    /// and the bytes a budget of F slots reserves hold those F again, with the frame's words
    /// or without.
    #[test]
    fn a_counted_budget_is_the_largest_f_its_bytes_hold() {
        let mut searched = 0;
        let px = 24;
        // Deep enough that bytes below the A-buffer's hold DKB's weights and some slots.
        for o in [
            occ(60_000, 24, 24, 24),
            occ(20_000, 16, 10, 8),
            occ(400, 24, 20, 18),
            occ(100, 24, 3, 2),
            occ(24, 24, 0, 0),
        ] {
            for (method, layout) in [(Method::Dkb, DKB), (Method::Vkb, VKB)] {
                let abuffer = budget::abuffer_bytes(px, o.fragments, false);
                let fixed = layout.fixed_bytes(px);
                let (lo, hi) = (fixed.saturating_sub(64), abuffer + 64);
                let step = (hi.saturating_sub(lo) / 400).max(1) as usize;
                for m in (lo..hi).step_by(step) {
                    let got = counted(method, &layout, PlanBudget::Bytes(m), px, &o, Words::None);
                    let label = format!("{} {o:?} {m} B", layout.method);
                    if m >= abuffer {
                        let c = got.unwrap();
                        assert!(
                            c.holds_all && c.exact(false) && c.f == o.fragments,
                            "{label}"
                        );
                        continue;
                    }
                    // The records whole where the bytes hold a slot beside them, else in up to
                    // three batches.
                    let search_in = |l: Layout| {
                        (0..=m / SLOT_BYTES)
                            .rev()
                            .find(|&f| l.reserved_bytes(px, f, &o) <= m)
                            .filter(|&f| f > 0)
                    };
                    let batched = layout.with_record_batches(budget::MOST_RECORD_BATCHES);
                    let search = search_in(layout).or_else(|| search_in(batched));
                    searched += 1;
                    match (got, search) {
                        (Ok(c), Some(f)) => assert_eq!(c.f, f, "{label}"),
                        (Err(_), None | Some(0)) => {}
                        (got, search) => panic!("{label}: {got:?}, the search {search:?}"),
                    }
                }
                let step = (o.fragments / 300).max(1) as usize;
                for f in (1..=o.fragments + 4).step_by(step) {
                    for words in [Words::None, Words::Exponents, Words::Tints] {
                        let by_f = counted(method, &layout, f.into(), px, &o, words).unwrap();
                        assert_eq!(by_f.holds_all, f >= o.fragments);
                        let by_bytes = counted(
                            method,
                            &layout,
                            PlanBudget::Bytes(by_f.bytes),
                            px,
                            &o,
                            words,
                        )
                        .unwrap();
                        assert!(
                            by_bytes.f >= f.min(o.fragments),
                            "{} {o:?} {words:?}: F {f} reserves {} B, which hold F {}",
                            layout.method,
                            by_f.bytes,
                            by_bytes.f
                        );
                    }
                }
            }
        }
        // Bytes below the A-buffer's were searched, not only refused or held exact.
        assert!(searched > 1000, "{searched} budgets searched");
    }

    /// Every F from 0 to n, its words counted by `pool_words_at`: the largest that fits is
    /// what the closed form gives, for every pool from empty to the frame's fragments.
    #[test]
    fn the_largest_fitting_f_is_the_exhaustive_searchs() {
        for o in [
            occ(40, 10, 6, 4),
            occ(12, 12, 0, 0),
            occ(30, 5, 5, 5),
            occ(0, 0, 0, 0),
            occ(9, 3, 2, 1),
        ] {
            for words in 0..=o.fragments + 3 {
                for cap in 0..=o.fragments + 2 {
                    let search = (0..=cap).rev().find(|&f| o.pool_words_at(f) <= words);
                    assert_eq!(
                        largest_fitting(words, &o, cap),
                        search,
                        "{o:?}, {words} words, cap {cap}"
                    );
                }
            }
        }
    }

    /// A frame counted first is sized for its own occupancy: its pool holds the budget's F,
    /// the plan is exactly the budget's, and where the exact A-buffer is no dearer than that
    /// reservation the pool holds every fragment only if the plan says exact.
    #[test]
    fn a_pool_sized_for_the_frame_holds_the_budgets_f() {
        let px = 400;
        for o in [
            occ(900, 300, 200, 120),
            occ(2000, 400, 400, 380),
            occ(350, 300, 40, 10),
        ] {
            for layout in [DKB, VKB] {
                for ppm in [50_000, 250_000, 500_000, 900_000, 1_000_000] {
                    let budget = FragmentBudget::Share(ppm);
                    let f = budget.of(o.fragments);
                    let Ahead {
                        pool_bytes,
                        batches,
                    } = ahead(&layout, budget.into(), px, &o, Words::None, false);
                    let input = PlanInput {
                        layout,
                        pixels: px,
                        budget: PlanBudget::Fragments(budget),
                        pool_bytes,
                        batches,
                        exact_when_cheaper: false,
                    };
                    let p = plan(&input, &o);
                    assert_eq!(p.short, 0, "{o:?} {ppm}");
                    assert_eq!(p.f, f.min(o.fragments), "{o:?} {ppm}");
                    assert_eq!(p.exact, f >= o.fragments);
                    if !p.exact && layout.pool_state.is_some() {
                        assert_eq!(p.batches, batches);
                    }
                }
            }
        }
    }

    /// An application's frame sized ahead ([`ahead`]) for the occupancy it then counts is
    /// what [`counted`] decides on that count: F's pool is what `counted` reserves beyond the
    /// fixed bytes, and the plan of a byte budget's pool takes `counted`'s F (the exhaustive
    /// search of `a_counted_budget_is_the_largest_f_its_bytes_hold`) within those bytes, over
    /// budgets from the fixed bytes to the A-buffer's, in both layouts, with and without tint
    /// words. With
    /// `exact_when_cheaper` the pool never holds more than the frame's fragments (or the state
    /// DKB's holds first), and a frame it fits keeps every fragment.
    #[test]
    fn a_pool_sized_ahead_is_what_the_count_decides() {
        let px = 400;
        let mut bytes_checked = 0;
        for o in [
            occ(900, 300, 200, 120),
            occ(2000, 400, 400, 380),
            occ(350, 300, 40, 10),
        ] {
            for (method, layout) in [(Method::Dkb, DKB), (Method::Vkb, VKB)] {
                for words in [Words::None, Words::Tints] {
                    let fixed = layout.fixed_bytes(px);
                    for ppm in [50_000, 250_000, 500_000, 900_000] {
                        let b = PlanBudget::Fragments(FragmentBudget::Share(ppm));
                        let a = ahead(&layout, b, px, &o, words, false);
                        let c = counted(method, &layout, b, px, &o, Words::None).unwrap();
                        assert_eq!(fixed + a.pool_bytes, c.bytes, "{o:?} {ppm}");
                    }
                    let abuffer = budget::abuffer_bytes(px, o.fragments, words.any());
                    for m in (fixed..abuffer).step_by(97) {
                        let b = PlanBudget::Bytes(m);
                        let Ok(c) = counted(method, &layout, b, px, &o, words) else {
                            continue;
                        };
                        let a = ahead(&layout, b, px, &o, words, false);
                        // The pool and the words beside it stay within the bytes.
                        let taken = layout.with_tints(fixed + a.pool_bytes, px, words);
                        assert!(taken <= m, "{method:?} {o:?} {words:?}: {taken} > {m} B");
                        let input = PlanInput {
                            layout,
                            pixels: px,
                            budget: PlanBudget::Bytes(layout.tinted_budget(m, px, words)),
                            pool_bytes: a.pool_bytes,
                            batches: a.batches,
                            exact_when_cheaper: false,
                        };
                        let p = plan(&input, &o);
                        assert_eq!(p.short & SHORT_SLOTS, 0, "{o:?} {m} B");
                        assert_eq!(p.f, c.f.min(o.fragments), "{method:?} {o:?} {m} B");
                        bytes_checked += 1;
                    }
                    let shares = [250_000, 900_000, 1_000_000]
                        .map(|ppm| PlanBudget::Fragments(FragmentBudget::Share(ppm)));
                    let bytes = [abuffer / 2, abuffer, 3 * abuffer].map(PlanBudget::Bytes);
                    for b in shares.into_iter().chain(bytes) {
                        let a = ahead(&layout, b, px, &o, words, true);
                        let least = layout.pool_least(px, o.deeper);
                        assert!(a.pool_bytes <= (SLOT_BYTES * o.fragments).max(least));
                        let input = PlanInput {
                            layout,
                            pixels: px,
                            budget: match b {
                                PlanBudget::Bytes(m) => {
                                    PlanBudget::Bytes(layout.tinted_budget(m, px, words))
                                }
                                b => b,
                            },
                            pool_bytes: a.pool_bytes,
                            batches: a.batches,
                            exact_when_cheaper: true,
                        };
                        let p = plan(&input, &o);
                        let fits = a.pool_bytes / SLOT_BYTES >= o.fragments;
                        assert_eq!(p.exact, fits || p.f >= o.fragments, "{b:?}");
                    }
                }
            }
        }
        assert!(bytes_checked > 100, "{bytes_checked} byte budgets");
    }

    /// Worked by hand: DKB at 25% of 900 fragments (F = 225) in a pool of 1,000 bytes (125
    /// words): every covered pixel (300) is more than F, so F may take 125 - 300 - 200 < 0
    /// words: none fits; a pool of 6,000 bytes (750 words) holds F = 225 with 500 words of
    /// tails; one of 4,000 bytes (500 words) holds at most 500 - 500 = 0 below the covered
    /// pixels, and 500 - 320 = 180 < 300 above: F = 0.
    #[test]
    fn a_small_pool_lowers_f_to_what_it_holds() {
        let o = occ(900, 300, 200, 120);
        let input = |pool_bytes| PlanInput {
            layout: VKB,
            pixels: 400,
            budget: PlanBudget::Fragments(FragmentBudget::Share(250_000)),
            pool_bytes,
            batches: 1,
            exact_when_cheaper: true,
        };
        let p = plan(&input(6_000), &o);
        assert_eq!((p.f, p.exact, p.short), (225, false, 0));
        let p = plan(&input(4_000), &o);
        assert_eq!((p.f, p.exact, p.short), (0, false, SHORT_SLOTS));
        let p = plan(&input(1_000), &o);
        assert_eq!((p.f, p.short), (0, SHORT_SLOTS));
        // 7,200 bytes are 900 words: the pool holds every fragment, exact where cheaper.
        let p = plan(&input(7_200), &o);
        assert_eq!((p.f, p.exact, p.short), (900, true, 0));
        let p = plan(
            &PlanInput {
                exact_when_cheaper: false,
                ..input(7_200)
            },
            &o,
        );
        assert_eq!((p.f, p.exact), (225, false));
    }

    /// DKB's records in the batches recorded: 120 records of 36 bytes in a pool of 2,000
    /// bytes are 55 a batch, three batches; one recorded is short of records.
    #[test]
    fn records_past_the_recorded_batches_are_reported() {
        let o = occ(900, 300, 200, 120);
        let input = PlanInput {
            layout: DKB,
            pixels: 400,
            budget: PlanBudget::Fragments(FragmentBudget::Slots(100)),
            pool_bytes: 2_000,
            batches: 3,
            exact_when_cheaper: false,
        };
        let p = plan(&input, &o);
        assert_eq!((p.per_batch, p.batches), (55, 3));
        assert_eq!(p.short & SHORT_RECORDS, 0);
        let p = plan(
            &PlanInput {
                batches: 1,
                ..input
            },
            &o,
        );
        assert_eq!(p.short & SHORT_RECORDS, SHORT_RECORDS);
        // A byte budget below this frame's fixed bytes leaves it no slot.
        let p = plan(
            &PlanInput {
                budget: PlanBudget::Bytes(1_000),
                ..input
            },
            &o,
        );
        assert_eq!(p.short & NO_SLOT, NO_SLOT);
        assert_eq!(Plan::from_words(p.words(), p.batches), p);
    }
}
