//! Memory budgets: what each method's GPU pipeline allocates, and the fragment budget F(M).
//!
//! `F(M) = floor((M - |P| S_p - S_i) / S_f)`: S_f is the bytes of one fragment slot, S_p the
//! bytes every pixel costs whatever its k, S_i the fixed cost. Each method has its own
//! [`Layout`], listing every buffer it creates by the label the GPU pipeline gives it, so the
//! accounting is one table, not a constant to keep in step by hand: the bytes allocated for
//! budget M never exceed M.
//!
//! A budget is given in bytes (`20MB`, `40MiB`, `1048576`), in average slots per pixel (`2fpp`),
//! or relative to the frame (`25%`: F is that share of the frame's own fragment total, what the
//! exact A-buffer would store, known from the count pass before any slot is allocated). The
//! last two fix F directly and the bytes follow from each method's layout. A share is held in
//! parts per million, so `F = floor(total * ppm / 10^6)` is the same integer on the CPU and the
//! GPU.

use crate::error::{Error, Result};
pub use crate::fragment::Words;

/// Bytes of one fragment slot: a 64-bit key, window depth bits high and RGBA8 low.
pub const SLOT_BYTES: u64 = 8;

/// Bytes the A-buffer stores beside each fragment's key where the frame stores tint words
/// (`abuf.tints`: its RGB8 tint and its colour's exponent, `fragment::tint_word`).
pub const TINT_BYTES: u64 = 4;

/// Words of the tint pass a pool word (pooled tails) or a slot, and a pixel (per-pixel
/// tails: its tail's sums).
fn per_slot_and_pixel(words: Words, pooled: bool) -> (u64, u64) {
    match (words, pooled) {
        (Words::None, _) => (0, 0),
        (Words::Exponents, _) => (1, 0),
        (Words::Tints, true) => (2, 0),
        (Words::Tints, false) => (1, 3),
    }
}

/// Words the k-buffers' tint pass keeps (kbuffer_tint.wgsl) for `slot_words` words of slots,
/// each [`TINT_BYTES`]: a word a slot, where `words` are [`Words::Exponents`] (with pooled
/// tails, a word for each word of the pool); for [`Words::Tints`], where the tails are
/// `pooled`, two for each word of the pool (a slot's tint; a tail's three sums of what its
/// tints take away, in its two words' four), else three a pixel (its tail's sums) and one a
/// slot.
pub fn kbuffer_tint_words(pixels: u64, slot_words: u64, pooled: bool, words: Words) -> u64 {
    let (slot, pixel) = per_slot_and_pixel(words, pooled);
    slot * slot_words + pixel * pixels
}

/// Bytes a pixel WBOIT adds where the frame's glass is tinted: an RGBA8 transmittance target in
/// its R8 revealage's place (`wboit.transmittance`).
pub const WBOIT_TINT_BYTES: u64 = 3;
/// Bytes a pixel MBOIT adds where the frame's glass is tinted: an RGBA8 target of the
/// transmittances' product (`mboit.transmittance`).
pub const MBOIT_TINT_BYTES: u64 = 4;

/// The exact A-buffer's bytes for `fragments` on `pixels`, with their tints where `tinted`.
pub fn abuffer_bytes(pixels: u64, fragments: u64, tinted: bool) -> u64 {
    ABUFFER.allocated_bytes(pixels, fragments) + tinted as u64 * TINT_BYTES * fragments
}

/// Bytes of the largest network's weights uniform (the default 12-128-64 network at f32,
/// `mlp::uniform_bytes`): what [`DKB`] counts; a network's own layout counts its own
/// ([`Layout::for_network`]).
pub const MLP_UNIFORM_BYTES: u64 =
    crate::mlp::uniform_bytes(crate::mlp::H1, crate::mlp::H2, crate::mlp::Precision::F32);
pub use crate::shared::{LEAST_BUFFER_BYTES, PARAMS_BYTES, PPM, SCAN_BLOCK, SCAN_GROUP};

/// The buffers one method allocates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    pub method: &'static str,
    /// Bytes of one fragment slot (the A-buffer stores whole fragments).
    pub slot_bytes: u64,
    /// Per-pixel buffers: (label, bytes per pixel).
    pub per_pixel: &'static [(&'static str, u64)],
    /// Fixed buffers: (label, bytes).
    pub fixed: &'static [(&'static str, u64)],
    /// Whether a prefix sum over pixels is part of the pipeline (it keeps one u32 of block
    /// totals per [`SCAN_BLOCK`] pixels).
    pub scan: bool,
    /// Bytes of the network's weights (the uniform `mlp.weights`), DKB's alone: sized to the
    /// network and its precision ([`Layout::for_network`]); [`DKB`] counts the default network
    /// at f32.
    pub weights: u64,
    /// Bytes of one pooled tail ([`POOLED_TAIL`]: in the slot pool, after the slots of each
    /// pixel [`crate::shared::has_tail`] names), for the allocated k-buffers (DKB, VKB); 0
    /// where the tails are per pixel (in [`Layout::per_pixel`]) or there are none.
    pub tail_bytes: u64,
    /// What the layout keeps in its slot pool before the slots (DKB), or None: the pool is
    /// the slots and tails alone, made for what the allocation hands out.
    pub pool_state: Option<PoolState>,
    /// A buffer of marks of its own (a bit a pixel and their prefix counts, [`marks_bytes`]), by
    /// its label, or None: VKB's allocation's marks; DKB's record marks, which a frame leaves
    /// for the frame after (its allocation's marks are in its pool).
    pub marks: Option<&'static str>,
}

/// State a layout keeps in the slot pool before the capture fills it (DKB's): the pool is made
/// for the frame's budget and occupancy before the first pass that writes it, as large as the
/// most it holds at once ([`Layout::pool_bytes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PoolState {
    /// Bytes of a deeper pixel's record (features.wgsl: one for each pixel of more than
    /// [`crate::shared::TAIL_WORDS`] fragments; in the pool until the importance is gathered).
    pub record_bytes: u64,
    /// Bytes a record takes in the pool after all the records while the importance is computed
    /// (importance_dkb.wgsl: the list of the records the network decides, an index each).
    pub list_bytes: u64,
    /// The most batches the records are gathered in ([`PoolState::batch`]): where they would
    /// take more of the pool than the slots and tails do, the features pass draws once for each
    /// batch of records, each batch's importance gathered into the shared word before the next
    /// batch reuses the pool. 3 is enough that the records take no more of a truncated frame's
    /// pool than its tails may: every pixel with a record may keep a tail of two words (16
    /// bytes) there, and a third of 36 is 12.
    pub batches: u64,
}

impl PoolState {
    /// Records a batch holds in a pool of `pool` bytes and the batches `records` take: one
    /// batch where the pool holds them all (as large as it is made: [`Layout::pool_bytes`], so
    /// never more than [`PoolState::batches`]), and one where there is none (its pass writes
    /// every pixel's shared word: the importance of a pixel without a record).
    pub fn batch(&self, pool: u64, records: u64) -> (u64, u64) {
        let per_batch = (pool / (self.record_bytes + self.list_bytes)).clamp(1, records.max(1));
        (per_batch, records.div_ceil(per_batch).max(1))
    }
}

/// The most batches DKB gathers its records in ([`PoolState::batches`]): one, so its pool holds
/// every record at once and a frame gathers its statistics with its count
/// (`gpu::Tuning::two_pass_dkb`), at the cost of a larger pool where the records outweigh the
/// slots and tails (a small budget on a deep frame). Up to three take a third of the records'
/// bytes and a features pass a batch.
pub const RECORD_BATCHES: u64 = 1;

/// How a k-buffer frame's budget is decided, the one option set the CPU's frame
/// (`frame::Options::decision`), the GPU's (`gpu::FrameOptions::decision`) and an
/// application's renderer share, so the bytes each counts are the same.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Decision {
    /// Render the exact A-buffer wherever it needs no more bytes than the k-buffer method
    /// would for its budget (`method::exact_is_no_dearer`), or its budget holds every
    /// fragment: on by default. Off, DKB and VKB render their approximation whatever it costs
    /// (the papers' equal-F protocol, what measures the approximation itself). FKB's and
    /// uploaded k's frames render as asked either way.
    pub exact_when_cheaper: bool,
    /// The most batches DKB gathers its network's records in ([`PoolState::batches`],
    /// [`RECORD_BATCHES`] by default; 1 to [`MOST_RECORD_BATCHES`]): fewer take more memory
    /// where the records outweigh the slots, and fewer features passes.
    pub record_batches: u64,
}

impl Default for Decision {
    fn default() -> Self {
        Decision {
            exact_when_cheaper: true,
            record_batches: RECORD_BATCHES,
        }
    }
}

impl Decision {
    /// This decision with the approximation rendered at any budget
    /// ([`Decision::exact_when_cheaper`] off).
    pub fn always_approximate(self) -> Decision {
        Decision {
            exact_when_cheaper: false,
            ..self
        }
    }

    /// DKB's buffers for `m` as this decision's frames create them: the network's own bytes
    /// ([`Layout::for_network`]) and its records in at most [`Decision::record_batches`]
    /// batches.
    pub fn dkb_layout(&self, m: &crate::mlp::Mlp) -> Layout {
        DKB.for_network(m).with_record_batches(self.record_batches)
    }
}

/// The most batches DKB may be given to gather its records in: past three the tails already
/// take more of a truncated frame's pool than a batch of records ([`PoolState::batches`]).
pub const MOST_RECORD_BATCHES: u64 = 3;

/// Bytes of a tail in the slot pool: [`crate::shared::TAIL_WORDS`] words.
pub const POOLED_TAIL: u64 = 8 * crate::shared::TAIL_WORDS as u64;

/// Bytes of the allocation's marks for a frame of `pixels` pixels ([`crate::shared::marks_words`]:
/// a bit a pixel and its word's prefix count, 0.25 bytes a pixel), at least 16 as every buffer.
pub fn marks_bytes(pixels: u64) -> u64 {
    (4 * crate::shared::marks_words(pixels)).max(LEAST_BUFFER_BYTES)
}

/// What a frame's count says about its pixels, which the pooled tails are bounded by: its
/// fragments, the pixels holding one or more, two or more, and more than a tail's
/// [`crate::shared::TAIL_WORDS`] (three or more).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Occupancy {
    pub fragments: u64,
    pub covered: u64,
    pub deep: u64,
    pub deeper: u64,
}

// Occupancy::extra_words_at counts a pixel's words past its k slots by these thresholds.
const _: () = assert!(crate::shared::TAIL_WORDS == 2);

impl Occupancy {
    /// The occupancy of a frame whose pixels hold `counts` fragments.
    pub fn of(counts: &[u32]) -> Occupancy {
        counts.iter().fold(Occupancy::default(), |o, &n| Occupancy {
            fragments: o.fragments + n as u64,
            covered: o.covered + (n >= 1) as u64,
            deep: o.deep + (n >= 2) as u64,
            deeper: o.deeper + (n > crate::shared::TAIL_WORDS) as u64,
        })
    }

    /// The occupancy a frame's totals hold (totals.wgsl's words, read back: at least
    /// [`crate::shared::TOTAL_DEEPER`] + 1 of them).
    pub fn from_totals(totals: &[u32]) -> Occupancy {
        use crate::shared::{TOTAL_COVERED, TOTAL_DEEP, TOTAL_DEEPER, TOTAL_FRAGMENTS};
        let word = |i: u32| totals[i as usize] as u64;
        Occupancy {
            fragments: word(TOTAL_FRAGMENTS),
            covered: word(TOTAL_COVERED),
            deep: word(TOTAL_DEEP),
            deeper: word(TOTAL_DEEPER),
        }
    }

    /// Each count times `by`, rounded up, the pixel counts at most `pixels` (an occupancy
    /// expected of a frame of `pixels` pixels).
    pub fn scaled(&self, by: f64, pixels: u64) -> Occupancy {
        let up = |v: u64| ((v as f64 * by).ceil() as u64).min(u64::MAX / 2);
        Occupancy {
            fragments: up(self.fragments),
            covered: up(self.covered).min(pixels),
            deep: up(self.deep).min(pixels),
            deeper: up(self.deeper).min(pixels),
        }
    }

    /// The most a frame of `pixels` pixels can hold as the tails see it: every pixel deep.
    pub fn most(pixels: u64) -> Occupancy {
        Occupancy {
            fragments: u64::MAX,
            covered: pixels,
            deep: pixels,
            deeper: pixels,
        }
    }

    /// The most words a frame's pooled pixels take beyond its F slots when F = `f`: a pixel
    /// of n fragments and k slots takes `min(n, k + TAIL_WORDS)` words ([`crate::shared::span`]),
    /// `k + min(n - k, 2)`, and k is at least the allocation's smallest, 1 where F covers every
    /// covered pixel (then `min(n - 1, 2)` a pixel: one for each deep pixel and one for each
    /// deeper), else 0 (`min(n, 2)`: one for each covered pixel and one for each deep).
    pub fn extra_words_at(&self, f: u64) -> u64 {
        if f >= self.covered {
            self.deep + self.deeper
        } else {
            self.covered + self.deep
        }
    }

    /// The most words a frame's pooled slots and tails take at F = `f`: `min(F, n)` slots and
    /// [`Occupancy::extra_words_at`], and never more than its fragments (a pixel takes at most
    /// its n).
    pub fn pool_words_at(&self, f: u64) -> u64 {
        let n = self.fragments;
        n.min(f.min(n).saturating_add(self.extra_words_at(f)))
    }
}

/// The pooled tails a frame's allocation `k` (or its [`crate::shared::stored`] k) keeps, for
/// pixels of `counts` fragments.
pub fn tails_kept(k: &[u32], counts: &[u32]) -> u64 {
    k.iter()
        .zip(counts)
        .filter(|&(&k, &n)| crate::shared::has_tail(k, n))
        .count() as u64
}

/// The tail's integer sums: sum c8 a8 for r, g, b, sum a8 (four u32 a pixel), and its count.
const HYBRID_TAIL: (&str, u64) = ("oit.tail", 16);
const TAIL_COUNT: (&str, u64) = ("oit.tail_count", 4);
/// The allocation's parameters (F, share, weight kind) and its search state (25 u64: target,
/// interval, sums of 16 candidates, rounds, the last answers).
const ALLOC_PARAMS: (&str, u64) = ("alloc.params", 16);
const ALLOC_STATE: (&str, u64) = ("alloc.state", 8 * crate::shared::ALLOC_STATE_WORDS as u64);
/// The allocation's three indirect dispatches (empty when every fragment fits).
const ALLOC_DISPATCHES: (&str, u64) = (
    "alloc.dispatches",
    (4 * crate::shared::ALLOC_DISPATCHES * crate::shared::DISPATCH_WORDS) as u64,
);
/// Bytes of a pixel's fragment count: 16 bits, two to a word (`shared::count_bytes`; a frame of
/// an odd number of pixels rounds its buffer up to a whole word, as [`Layout::fixed_bytes`]
/// counts it). No other per-pixel buffer takes 2 bytes.
const COUNT_BYTES: u64 = 2;
/// A frame's totals and its plan's F and flags (totals.wgsl, plan.wgsl).
const TOTALS: u64 = 4 * crate::shared::TOTALS_WORDS as u64;
/// The frame's plan's parameters (plan.wgsl's uniform).
const PLAN_PARAMS: (&str, u64) = ("plan.params", crate::shared::PLAN_PARAMS_BYTES);
/// The prefix sums' final entry (offsets hold pixels + 1 values).
const OFFSETS_END: (&str, u64) = ("offsets.end", 4);
/// The resolve's status words: loops cut short, a pixel too deep (gpu's FrameStatus).
const STATUS: (&str, u64) = ("status", 16);

/// Deep k-buffer: the count and the shared word a pixel, and its record marks (a bit a pixel:
/// which pixels have a record, kept from one frame for the next, whose count gathers their
/// statistics); the rest in the slot pool before the slots fill it ([`PoolState`]): a record of
/// the network's statistics for each pixel of three fragments or more (32 bytes: the two
/// nearest words, the colour and opacity sums; a pixel of fewer keeps them all whatever its k,
/// `shared::stored_k`, so its k is forced) and, after the records, the network's list of those
/// it decides (4 bytes a record), then the allocation's marks ([`marks_bytes`]: a bit a pixel,
/// 0.25 bytes with their prefix counts), then the slots and the pooled tails (two words, where a
/// pixel leaves out more than two fragments). The shared word (`oit.offsets`) holds a pixel's
/// importance, the allocation's weights, k and the slot bases in turn.
pub const DKB: Layout = Layout {
    method: "dkb",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[("features.count", COUNT_BYTES), ("oit.offsets", 4)],
    fixed: &[
        ("params", PARAMS_BYTES),
        ("features.totals", TOTALS),
        PLAN_PARAMS,
        // importance::optical_depth_table, a uniform.
        ("features.optical_depth", 1024),
        // The network's list's length and indirect dispatch (then the capture's unused
        // per-pixel tail).
        ("importance.list_len", 4 * crate::shared::BATCH_WORDS as u64),
        (
            "importance.dispatch",
            4 * crate::shared::DISPATCH_WORDS as u64,
        ),
        OFFSETS_END,
        ALLOC_PARAMS,
        ALLOC_STATE,
        ALLOC_DISPATCHES,
        STATUS,
    ],
    scan: true,
    weights: MLP_UNIFORM_BYTES,
    tail_bytes: POOLED_TAIL,
    pool_state: Some(PoolState {
        record_bytes: 8 * crate::shared::RECORD_WORDS as u64,
        list_bytes: 4,
        batches: RECORD_BATCHES,
    }),
    marks: Some("dkb.record_marks"),
};

/// Optimal allocation uploaded as k: the same capture and resolve as DKB, no network (and no
/// counts: its capture inserts every fragment, and binds an unused counts buffer). k is
/// uploaded into the slot bases' buffer and scanned in place.
pub const OPT: Layout = Layout {
    method: "optimal",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[("oit.offsets", 4), HYBRID_TAIL, TAIL_COUNT],
    fixed: &[
        ("params", PARAMS_BYTES),
        OFFSETS_END,
        ("oit.unused_counts", LEAST_BUFFER_BYTES),
        STATUS,
    ],
    scan: true,
    weights: 0,
    tail_bytes: 0,
    pool_state: None,
    marks: None,
};

/// Variable k-buffer with importance maps (paper 002). Its count and the shared word a pixel
/// (`oit.offsets`), which holds the count pass's nearest key (`importance::vkb_nearest_key`),
/// the importance, k and the slot bases in turn; the allocation's marks ([`marks_bytes`], a
/// buffer of their own); the tails in the slot pool ([`POOLED_TAIL`]).
pub const VKB: Layout = Layout {
    method: "vkb",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[("vkb.count", COUNT_BYTES), ("oit.offsets", 4)],
    fixed: &[
        ("params", PARAMS_BYTES),
        ("vkb.totals", TOTALS),
        PLAN_PARAMS,
        // Bound in the capture's per-pixel tail's place, unused (the tails are pooled).
        ("vkb.unused_tail", LEAST_BUFFER_BYTES),
        OFFSETS_END,
        ALLOC_PARAMS,
        ALLOC_STATE,
        ALLOC_DISPATCHES,
        STATUS,
    ],
    scan: true,
    weights: 0,
    tail_bytes: POOLED_TAIL,
    pool_state: None,
    marks: Some("vkb.marks"),
};

/// Fixed k-buffer: k slots for every pixel, tail. (The output image is the application's
/// target, counted for no method.)
pub const FKB: Layout = Layout {
    method: "fkb",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[HYBRID_TAIL, TAIL_COUNT],
    // The capture and resolve passes bind per-pixel slot bases and counts that FKB never reads.
    fixed: &[
        ("params", PARAMS_BYTES),
        ("fkb.unused_offsets", LEAST_BUFFER_BYTES),
        ("fkb.unused_counts", LEAST_BUFFER_BYTES),
        STATUS,
    ],
    scan: false,
    weights: 0,
    tail_bytes: 0,
    pool_state: None,
    marks: None,
};

/// MLAB: m rows of 8 bytes (RGB8 premultiplied, transmittance 8 bits, depth 32 bits).
pub const MLAB: Layout = Layout {
    method: "mlab",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[],
    fixed: &[("params", PARAMS_BYTES)],
    scan: false,
    weights: 0,
    tail_bytes: 0,
    pool_state: None,
    marks: None,
};

/// Weighted blended OIT, as McGuire and Bavoil lay it out: an RGBA16F accumulation target and an
/// R8 revealage target a pixel, no slot (the GPU's frame creates exactly these targets,
/// `gpu::blend`).
pub const WBOIT: Layout = Layout {
    method: "wboit",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[("wboit.accumulation", 8), ("wboit.revealage", 1)],
    fixed: &[("params", PARAMS_BYTES)],
    scan: false,
    weights: 0,
    tail_bytes: 0,
    pool_state: None,
    marks: None,
};

/// Moment-based OIT, four power moments in 32 bits, as Munstermann et al. lay it out: an R32F
/// target for b_0 and an RGBA32F one for b_1..b_4 (the first additive pass), an RGBA16F one for
/// the transmittance-weighted colour and its weight (the second), no slot (the GPU's frame
/// creates exactly these targets, `gpu::blend`).
pub const MBOIT: Layout = Layout {
    method: "mboit",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[
        ("mboit.b0", 4),
        ("mboit.moments", 16),
        ("mboit.accumulation", 8),
    ],
    // composite::mboit_absorbance_table, a uniform.
    fixed: &[("params", PARAMS_BYTES), ("mboit.absorbance", 1024)],
    scan: false,
    weights: 0,
    tail_bytes: 0,
    pool_state: None,
    marks: None,
};

/// MBOIT with six power moments: b_5 and b_6 in an RG32F target beside [`MBOIT`]'s.
pub const MBOIT6: Layout = Layout {
    per_pixel: &[
        ("mboit.b0", 4),
        ("mboit.moments", 16),
        ("mboit.extra", 8),
        ("mboit.accumulation", 8),
    ],
    ..MBOIT
};

/// MBOIT with eight power moments: b_5..b_8 in an RGBA32F target beside [`MBOIT`]'s.
pub const MBOIT8: Layout = Layout {
    per_pixel: &[
        ("mboit.b0", 4),
        ("mboit.moments", 16),
        ("mboit.extra", 16),
        ("mboit.accumulation", 8),
    ],
    ..MBOIT
};

/// MBOIT's layout for `moments` power moments ([`MBOIT`], [`MBOIT6`], [`MBOIT8`]; any other
/// count is refused where the parameters are made, `composite::MboitParams::with_moments`).
pub fn mboit(moments: u32) -> Layout {
    match moments {
        6 => MBOIT6,
        8 => MBOIT8,
        _ => MBOIT,
    }
}

/// The most power moments (8, 6 or 4) whose MBOIT targets fit `bytes` for a frame of `pixels`
/// pixels, or None where not even four do: what MBOIT takes at one memory for every method.
pub fn mboit_moments_within(pixels: u64, bytes: u64) -> Option<u32> {
    [8, 6, 4]
        .into_iter()
        .find(|&n| mboit(n).fixed_bytes(pixels) <= bytes)
}

/// The budgeted per-pixel linked list, as Bevy lays it out: a 4-byte head a pixel, 12 bytes a
/// node (the 8-byte capture key and the next node's index), the pool of F nodes allocated whole,
/// and the atomic counter that hands them out.
pub const LINKED_LIST: Layout = Layout {
    method: "linked-list",
    slot_bytes: 12,
    per_pixel: &[("list.heads", 4)],
    fixed: &[
        ("params", PARAMS_BYTES),
        ("list.counter", LEAST_BUFFER_BYTES),
        STATUS,
    ],
    scan: false,
    weights: 0,
    tail_bytes: 0,
    pool_state: None,
    marks: None,
};

/// A-buffer: counts (then the store's cursors), offsets, every fragment as the 8-byte capture
/// key a k-buffer slot holds (paper 004's exact memory). Not budgeted: exact memory. The output
/// image is the application's target, counted for no method.
pub const ABUFFER: Layout = Layout {
    method: "abuffer",
    slot_bytes: SLOT_BYTES,
    per_pixel: &[("abuf.count", COUNT_BYTES), ("abuf.offsets", 4)],
    fixed: &[
        ("params", PARAMS_BYTES),
        OFFSETS_END,
        STATUS,
        // The submission indices MLAB alone stores, bound empty.
        ("abuf.no_primitives", LEAST_BUFFER_BYTES),
    ],
    scan: true,
    weights: 0,
    tail_bytes: 0,
    pool_state: None,
    marks: None,
};

impl Layout {
    /// S_p: bytes every pixel costs whatever its k.
    pub fn per_pixel_bytes(&self) -> u64 {
        self.per_pixel.iter().map(|b| b.1).sum()
    }
    /// The layout with `m`'s weights in place of the default network's: DKB's memory for the
    /// network it runs, at the precision it is deployed at (a 16-8 network at f16 needs 832
    /// bytes where the default at f32 needs 40,064). Other layouts hold no weights.
    pub fn for_network(self, m: &crate::mlp::Mlp) -> Layout {
        Layout {
            weights: if self.weights > 0 {
                m.uniform_bytes()
            } else {
                0
            },
            ..self
        }
    }
    /// The layout with its records gathered in at most `batches` batches
    /// ([`PoolState::batches`]; 1: the pool holds them all at once, one features pass); a
    /// layout that pools no records is returned as it is.
    pub fn with_record_batches(self, batches: u64) -> Layout {
        Layout {
            pool_state: self.pool_state.map(|ps| PoolState {
                batches: batches.max(1),
                ..ps
            }),
            ..self
        }
    }
    /// Bytes that do not depend on the number of slots: `|P| S_p + S_i` (scan scratch and
    /// weights included; the counts in whole words: [`crate::shared::count_bytes`]).
    pub fn fixed_bytes(&self, pixels: u64) -> u64 {
        // The block totals; like every GPU buffer, at least 16 bytes.
        let scan = if self.scan {
            (4 * pixels.div_ceil(SCAN_BLOCK)).max(LEAST_BUFFER_BYTES)
        } else {
            0
        };
        let per_pixel = |b: u64| match b {
            COUNT_BYTES => crate::shared::count_bytes(pixels),
            b => pixels * b,
        };
        self.per_pixel.iter().map(|b| per_pixel(b.1)).sum::<u64>()
            + self.fixed.iter().map(|b| b.1).sum::<u64>()
            + scan
            + self.marks.map_or(0, |_| marks_bytes(pixels))
            + self.weights
    }
    /// Bytes allocated with `slots` fragment slots (and no pooled tail: see
    /// [`Layout::allocated_with_tails`]).
    pub fn allocated_bytes(&self, pixels: u64, slots: u64) -> u64 {
        self.fixed_bytes(pixels) + slots * self.slot_bytes
    }
    /// Bytes allocated with `slots` fragment slots and `tails` pooled tails (none where the
    /// layout pools no tail: [`Layout::tail_bytes`] 0).
    pub fn allocated_with_tails(&self, pixels: u64, slots: u64, tails: u64) -> u64 {
        self.allocated_bytes(pixels, slots) + tails * self.tail_bytes
    }
    /// The slot pool a frame of occupancy `occ` makes at F = `f` where the layout keeps state
    /// there ([`PoolState`]): the most it holds at once, the records, the marks, or the words
    /// its slots and tails may take ([`Occupancy::pool_words_at`]); at least 16 bytes.
    pub fn pool_bytes(&self, pixels: u64, f: u64, occ: &Occupancy) -> u64 {
        let slots = self.slot_bytes * occ.pool_words_at(f);
        slots.max(self.pool_least(pixels, occ.deeper))
    }
    /// The pool's least size whatever F: the state it holds first for `records` pixels with a
    /// record, a batch of the records and the network's list ([`PoolState::batches`] of them
    /// at most), then the marks; [`LEAST_BUFFER_BYTES`] at least, as every buffer (all of it
    /// where the layout's pool holds no state).
    pub fn pool_least(&self, pixels: u64, records: u64) -> u64 {
        self.pool_least_in(pixels, records, self.pool_state.map_or(1, |ps| ps.batches))
    }
    /// [`Layout::pool_least`] with the records in `batches` batches at most.
    fn pool_least_in(&self, pixels: u64, records: u64, batches: u64) -> u64 {
        self.pool_state
            .map_or(0, |ps| {
                ((ps.record_bytes + ps.list_bytes) * records.div_ceil(batches.max(1)))
                    .max(marks_bytes(pixels))
            })
            .max(LEAST_BUFFER_BYTES)
    }
    /// The most bytes a frame of occupancy `occ` can allocate at F = `f`: its fixed bytes,
    /// `min(F, n)` slots (the most an allocation hands out) and, pooled, the words its pixels'
    /// tails and whole pixels may take beyond them ([`Occupancy::pool_words_at`]); where the
    /// pool holds state first, the pool it makes ([`Layout::pool_bytes`]: what such a frame
    /// allocates whatever its k).
    pub fn reserved_bytes(&self, pixels: u64, f: u64, occ: &Occupancy) -> u64 {
        match self.pool_state.is_some() || self.tail_bytes > 0 {
            true => self.fixed_bytes(pixels) + self.pool_for(pixels, f, occ),
            false => self.allocated_bytes(pixels, f.min(occ.fragments)),
        }
    }
    /// The slot pool a layout with pooled tails (DKB's, VKB's) makes for F = `f` on a frame of
    /// occupancy `occ`: the pool that holds state first ([`Layout::pool_bytes`]), else its
    /// slots' and tails' words ([`Occupancy::pool_words_at`]; 16 bytes at least, as every
    /// buffer).
    pub fn pool_for(&self, pixels: u64, f: u64, occ: &Occupancy) -> u64 {
        match self.pool_state {
            Some(_) => self.pool_bytes(pixels, f, occ),
            None => (self.slot_bytes * occ.pool_words_at(f)).max(LEAST_BUFFER_BYTES),
        }
    }
    /// The bytes a budget of F slots comes to: what the layout reserves for them on a frame of
    /// occupancy `occ` where it keeps tails ([`Layout::reserved_bytes`]), else F slots.
    pub fn bytes_for(&self, pixels: u64, f: u64, occ: &Occupancy) -> u64 {
        match self.tail_bytes {
            0 => self.allocated_bytes(pixels, f),
            _ => self.reserved_bytes(pixels, f, occ),
        }
    }
    /// F(M) for a frame of occupancy `occ`: the most slots whose bytes, with the tails they
    /// may keep (and the state the pool holds first), stay within `bytes`
    /// ([`Layout::fragment_budget`] where the tails are not pooled). Where F covers every
    /// covered pixel only the deep ones keep a tail. Where the bytes leave no slot beside
    /// DKB's records in the batches its layout takes ([`PoolState::batches`]: one), they are
    /// held in up to [`MOST_RECORD_BATCHES`] (a features pass a batch).
    pub fn fragment_budget_counted(&self, bytes: u64, pixels: u64, occ: &Occupancy) -> Result<u64> {
        if self.tail_bytes == 0 {
            return self.slots_after_fixed(bytes, pixels);
        }
        let least = self.pool_least(pixels, occ.deeper);
        match (
            self.pool_state,
            self.slots_beside(bytes, pixels, occ, least),
        ) {
            (_, Some(f)) => Ok(f),
            (Some(ps), None) if ps.batches < MOST_RECORD_BATCHES => {
                let least = self.pool_least_in(pixels, occ.deeper, MOST_RECORD_BATCHES);
                self.slots_beside(bytes, pixels, occ, least)
                    .ok_or_else(|| self.no_slot(bytes, pixels, occ, least, MOST_RECORD_BATCHES))
            }
            (ps, None) => Err(self.no_slot(bytes, pixels, occ, least, ps.map_or(1, |p| p.batches))),
        }
    }
    /// The layout a frame of occupancy `occ` takes at a byte budget of `bytes` for its slots
    /// and tails (what the words it stores leave: [`Layout::tinted_budget`]): this one, or
    /// where those bytes leave no slot beside DKB's records all at once, this one with its
    /// records in up to [`MOST_RECORD_BATCHES`] batches, as
    /// [`Layout::fragment_budget_counted`] resolves it (its pool then the bytes', a batch of
    /// records at a time).
    pub fn for_bytes(self, bytes: u64, pixels: u64, occ: &Occupancy) -> Layout {
        match self.pool_state {
            Some(ps)
                if ps.batches < MOST_RECORD_BATCHES
                    && self.tail_bytes > 0
                    && self
                        .slots_beside(bytes, pixels, occ, self.pool_least(pixels, occ.deeper))
                        .is_none() =>
            {
                self.with_record_batches(MOST_RECORD_BATCHES)
            }
            _ => self,
        }
    }
    /// The most slots `bytes` hold beside the fixed bytes, a pool of at least `least` and the
    /// tails (None: none; [`Layout::fragment_budget_counted`]).
    fn slots_beside(&self, bytes: u64, pixels: u64, occ: &Occupancy, least: u64) -> Option<u64> {
        let fixed = self.fixed_bytes(pixels);
        let pool = bytes.checked_sub(fixed).filter(|&p| p >= least);
        // The slots left beside the words the pixels may take past them where k is at least
        // lo ([`Occupancy::extra_words_at`]): F at or above the covered pixels (lo 1), or
        // below (lo 0). Where the first is below the covered pixels, so is the second.
        let slots_after = |extra: u64| {
            pool.map(|p| p / self.slot_bytes)
                .and_then(|w| w.checked_sub(extra))
        };
        match (
            slots_after(occ.extra_words_at(occ.covered)),
            slots_after(occ.extra_words_at(0)),
        ) {
            (Some(f), _) if f >= occ.covered => Some(f),
            (_, Some(f)) if f > 0 => Some(f),
            _ => None,
        }
    }
    /// Why `bytes` hold no slot for a frame of occupancy `occ`, its pool at least `least`
    /// with its records in `batches` batches.
    fn no_slot(&self, bytes: u64, pixels: u64, occ: &Occupancy, least: u64, batches: u64) -> Error {
        let fixed = self.fixed_bytes(pixels);
        Error::Budget(
            format_bytes(bytes),
            format!(
                "{} needs {} for one slot in this frame: {} for {} pixels before any \
                     fragment slot ({} B per pixel + {} fixed{}), and {} B for the tail (or \
                     the fragments, where a tail would hold no more) of each of the frame's {} \
                     covered pixels",
                self.method,
                format_bytes(fixed + least.max(self.slot_bytes * occ.pool_words_at(1))),
                format_bytes(fixed + least),
                pixels,
                self.per_pixel_bytes(),
                format_bytes(fixed - pixels * self.per_pixel_bytes()),
                match self.pool_state {
                    Some(_) => format!(
                        ", a pool of {} for the {} pixels of three fragments or more \
                             in {} batches",
                        format_bytes(least),
                        occ.deeper,
                        batches
                    ),
                    None => String::new(),
                },
                self.tail_bytes,
                occ.covered
            ),
        )
    }
    /// The budget a frame's slots (and tails) are resolved against: all of `bytes`, or where
    /// the frame stores `words`, what they leave of it: the linked list's nodes share it with
    /// a word a node ([`TINT_BYTES`]); a k-buffer's tint pass ([`kbuffer_tint_words`]) takes a
    /// word a slot or pool word, and for [`Words::Tints`] half of what the fixed bytes leave
    /// where its tails are pooled (two words a pool word beside its [`SLOT_BYTES`]), else
    /// three words a pixel and one a slot.
    pub fn tinted_budget(&self, bytes: u64, pixels: u64, words: Words) -> u64 {
        if !words.any() {
            return bytes;
        }
        let fixed = self.fixed_bytes(pixels);
        let Some(rest) = bytes.checked_sub(fixed) else {
            return bytes;
        };
        // The list's nodes take a word each; a k-buffer's slots (or pool words) theirs, and
        // per-pixel tails their sums.
        let (per_slot, per_pixel) = match self.method {
            "linked-list" => (1, 0),
            _ => per_slot_and_pixel(words, self.tail_bytes > 0),
        };
        let slots = rest.saturating_sub(per_pixel * TINT_BYTES * pixels)
            / (self.slot_bytes + per_slot * TINT_BYTES);
        fixed + self.slot_bytes * slots
    }
    /// A k-buffer's `bytes` (its fixed bytes, slots and tails) with the tint pass's `words`
    /// ([`kbuffer_tint_words`]).
    pub fn with_tints(&self, bytes: u64, pixels: u64, words: Words) -> u64 {
        let slot_words = bytes.saturating_sub(self.fixed_bytes(pixels)) / self.slot_bytes;
        bytes + TINT_BYTES * kbuffer_tint_words(pixels, slot_words, self.tail_bytes > 0, words)
    }
    /// F(M) for a tinted frame of occupancy `occ` (a k-buffer's or the linked list's):
    /// [`Layout::fragment_budget_counted`] at
    /// [`Layout::tinted_budget`], its error naming `bytes` and what the tints take.
    pub fn tinted_fragment_budget(
        &self,
        bytes: u64,
        pixels: u64,
        occ: &Occupancy,
        words: Words,
    ) -> Result<u64> {
        let slots = self.tinted_budget(bytes, pixels, words);
        self.fragment_budget_counted(slots, pixels, occ)
            .map_err(|e| match e {
                Error::Budget(_, why) if slots < bytes => Error::Budget(
                    format_bytes(bytes),
                    format!(
                        "its fragments' tint words (tinted glass, colours above white) take {} of it, leaving {}: {why}",
                        format_bytes(bytes - slots),
                        format_bytes(slots)
                    ),
                ),
                e => e,
            })
    }
    /// F(M): the fragment slots a budget of `bytes` leaves, or an error saying what is needed.
    /// Before a frame is counted, a layout with pooled tails leaves room for one a pixel (the
    /// most a frame can keep); [`Layout::fragment_budget_counted`] knows the frame's.
    pub fn fragment_budget(&self, bytes: u64, pixels: u64) -> Result<u64> {
        self.fragment_budget_counted(bytes, pixels, &Occupancy::most(pixels))
    }
    fn slots_after_fixed(&self, bytes: u64, pixels: u64) -> Result<u64> {
        let fixed = self.fixed_bytes(pixels);
        if bytes < fixed + pixels.min(1) * self.slot_bytes {
            return Err(Error::Budget(
                format_bytes(bytes),
                format!(
                    "{} needs {} for {} pixels before any fragment slot ({} B per pixel + {} fixed); \
                     one slot per pixel takes {} in all",
                    self.method,
                    format_bytes(fixed),
                    pixels,
                    self.per_pixel_bytes(),
                    format_bytes(fixed - pixels * self.per_pixel_bytes()),
                    format_bytes(fixed + pixels * self.slot_bytes)
                ),
            ));
        }
        Ok((bytes - fixed) / self.slot_bytes)
    }
}

/// Every budgeted layout, by method name.
pub fn layout(method: &str) -> Option<Layout> {
    [DKB, OPT, VKB, FKB, MLAB, WBOIT, MBOIT, LINKED_LIST, ABUFFER]
        .into_iter()
        .find(|l| l.method == method)
}

/// A budget as the user gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    Bytes(u64),
    /// Average fragment slots per pixel: F = floor(fpp |P|).
    SlotsPerPixel(f64),
    /// A share of the frame's fragments, in parts per million: F = floor(total ppm / 10^6).
    Share(u32),
}

/// F as a pass sees it before the frame's fragments are counted: a fixed number of slots, or a
/// share of what the count finds (the GPU computes `floor(total ppm / 10^6)` after its count
/// pass, the CPU the same integer).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FragmentBudget {
    Slots(u64),
    /// Parts per million of the frame's fragments.
    Share(u32),
}

impl FragmentBudget {
    /// F for a frame of `total` fragments.
    pub fn of(self, total: u64) -> u64 {
        match self {
            FragmentBudget::Slots(f) => f,
            FragmentBudget::Share(ppm) => share_of(total, ppm),
        }
    }

    /// Whether F holds every one of a frame's `total` fragments (k = n then, whatever the
    /// importance; common.wgsl's `holds_every_fragment`).
    pub fn holds(self, total: u64) -> bool {
        self.of(total) >= total
    }
}

impl From<u64> for FragmentBudget {
    fn from(f: u64) -> Self {
        FragmentBudget::Slots(f)
    }
}

/// F of a relative budget: `floor(total ppm / 10^6)` (the GPU computes the same integer).
pub fn share_of(total: u64, ppm: u32) -> u64 {
    ((total as u128 * ppm as u128) / PPM as u128) as u64
}

impl Budget {
    /// A budget as the command line takes it: bytes with a unit, slots per pixel, or a share of
    /// the frame's fragments; anything else is an error that says what is expected.
    ///
    /// ```
    /// use dhoit_runtime::budget::{Budget, DKB};
    /// assert_eq!(Budget::parse("20MB")?, Budget::Bytes(20_000_000));
    /// assert_eq!(Budget::parse("2fpp")?, Budget::SlotsPerPixel(2.0));
    /// assert_eq!(Budget::parse("25%")?, Budget::Share(250_000));
    /// assert!(Budget::parse("25 apples").is_err());
    /// // Bytes fix F through the method's layout: what is left after its fixed buffers, in slots.
    /// // Before a frame is counted, DKB leaves room for what every pixel could need beside its
    /// // slots: a pooled tail (two words, 16 bytes) each (its records and the network's list,
    /// // 36 bytes a pixel at most, come and go in the same pool before the slots, in up to
    /// // three batches where the pool holds fewer).
    /// let pixels = 640 * 480;
    /// let (m, f) = Budget::parse("40MiB")?.resolve(&DKB, pixels, 0)?;
    /// assert_eq!(m, 40 << 20);
    /// assert_eq!(f, (m - DKB.fixed_bytes(pixels) - 16 * pixels) / 8);
    /// # Ok::<(), dhoit_runtime::Error>(())
    /// ```
    pub fn parse(s: &str) -> Result<Budget> {
        let t = s.trim();
        let bad = |m: &str| Error::Budget(s.to_string(), m.to_string());
        let lower = t.to_ascii_lowercase();
        if let Some(n) = lower.strip_suffix('%') {
            let v: f64 = n
                .trim()
                .parse()
                .map_err(|_| bad("expected a number before '%', such as 25%"))?;
            if !v.is_finite() || v <= 0.0 || v > 100.0 {
                return Err(bad(
                    "a share of the frame's fragments must be above 0% and at most 100%",
                ));
            }
            let ppm = (v * 1e4).round();
            if ppm < 1.0 {
                return Err(bad("a share below 0.0001% leaves no fragment slot"));
            }
            return Ok(Budget::Share(ppm as u32));
        }
        if let Some(n) = lower.strip_suffix("fpp") {
            let v: f64 = n
                .trim()
                .parse()
                .map_err(|_| bad("expected a number before 'fpp'"))?;
            if !v.is_finite() || v <= 0.0 {
                return Err(bad("slots per pixel must be a positive number"));
            }
            return Ok(Budget::SlotsPerPixel(v));
        }
        let split = lower
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(lower.len());
        let (num, unit) = lower.split_at(split);
        let v: f64 = num.parse().map_err(|_| {
            bad(
                "expected bytes such as 20MB, 40MiB or 1048576, slots per pixel such as 2fpp, \
                 or a share of the frame's fragments such as 25%",
            )
        })?;
        let scale = match unit.trim() {
            "" | "b" => 1.0,
            "kb" => 1e3,
            "mb" => 1e6,
            "gb" => 1e9,
            "kib" => 1024.0,
            "mib" => 1024.0 * 1024.0,
            "gib" => 1024.0 * 1024.0 * 1024.0,
            u => {
                return Err(bad(&format!(
                    "unknown unit '{u}' (B, KB, MB, GB, KiB, MiB, GiB, fpp or %)"
                )));
            }
        };
        let bytes = v * scale;
        if !bytes.is_finite() || !(1.0..=1e15).contains(&bytes) {
            return Err(bad("the budget must be between 1 byte and 1 PB"));
        }
        Ok(Budget::Bytes(bytes as u64))
    }

    /// F before the frame is counted: a share stays a share, slots per pixel and bytes resolve
    /// through the layout.
    pub fn fragment_budget(&self, layout: &Layout, pixels: u64) -> Result<FragmentBudget> {
        match *self {
            Budget::Share(ppm) => Ok(FragmentBudget::Share(ppm)),
            _ => Ok(FragmentBudget::Slots(self.resolve(layout, pixels, 0)?.1)),
        }
    }

    /// Resolves to (bytes M, fragment slots F(M)) for a layout, a pixel count and the frame's
    /// fragment total (which only a relative budget reads). A layout with pooled tails is held
    /// to a tail for every pixel; [`Budget::resolve_counted`] knows the frame's pixels.
    pub fn resolve(&self, layout: &Layout, pixels: u64, fragments: u64) -> Result<(u64, u64)> {
        // Only a share reads the fragments; the others hold as many slots as they fix.
        let occ = Occupancy {
            fragments: match self {
                Budget::Share(_) => fragments,
                _ => u64::MAX,
            },
            ..Occupancy::most(pixels)
        };
        self.resolve_counted(layout, pixels, &occ)
    }

    /// [`Budget::resolve`] for a counted frame: bytes leave room for the pooled tails its
    /// pixels may keep, and the bytes of a share or of slots per pixel are what the method
    /// reserves for it ([`Layout::reserved_bytes`]).
    pub fn resolve_counted(
        &self,
        layout: &Layout,
        pixels: u64,
        occ: &Occupancy,
    ) -> Result<(u64, u64)> {
        match PlanBudget::of(*self, pixels, occ.fragments)? {
            PlanBudget::Bytes(b) => Ok((b, layout.fragment_budget_counted(b, pixels, occ)?)),
            PlanBudget::Fragments(f) => {
                let slots = f.of(occ.fragments);
                Ok((layout.bytes_for(pixels, slots, occ), slots))
            }
        }
    }
}

impl std::str::FromStr for Budget {
    type Err = Error;
    fn from_str(s: &str) -> Result<Budget> {
        Budget::parse(s)
    }
}

impl std::fmt::Display for Budget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Budget::Bytes(b) => write!(f, "{}", format_bytes(*b)),
            Budget::SlotsPerPixel(v) => write!(f, "{v}fpp"),
            Budget::Share(ppm) => write!(f, "{}%", *ppm as f64 / 1e4),
        }
    }
}

/// Human-readable bytes (binary units).
pub fn format_bytes(b: u64) -> String {
    const UNITS: [&str; 4] = ["B", "KiB", "MiB", "GiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u < UNITS.len() - 1 {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.2} {}", UNITS[u])
    }
}

/// How a frame's F follows from its count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanBudget {
    /// F slots, or a share of the frame's fragments.
    Fragments(FragmentBudget),
    /// The most slots these bytes hold for the frame's own occupancy in the method's layout
    /// ([`Layout::fragment_budget_counted`]).
    Bytes(u64),
}

impl From<FragmentBudget> for PlanBudget {
    fn from(f: FragmentBudget) -> PlanBudget {
        PlanBudget::Fragments(f)
    }
}

/// F slots.
impl From<u64> for PlanBudget {
    fn from(f: u64) -> PlanBudget {
        PlanBudget::Fragments(f.into())
    }
}

impl PlanBudget {
    /// The fragment budget, where F does not wait for the frame's occupancy (None for bytes).
    pub fn fragments(self) -> Option<FragmentBudget> {
        match self {
            PlanBudget::Fragments(f) => Some(f),
            PlanBudget::Bytes(_) => None,
        }
    }

    /// A user's budget on a frame of `pixels`: bytes stay bytes, a share stays a share, slots
    /// per pixel become `floor(fpp pixels)` slots.
    pub fn from_budget(budget: Budget, pixels: u64) -> PlanBudget {
        match budget {
            Budget::Bytes(m) => PlanBudget::Bytes(m),
            Budget::Share(ppm) => FragmentBudget::Share(ppm).into(),
            Budget::SlotsPerPixel(f) => ((f * pixels as f64).floor() as u64).into(),
        }
    }

    /// [`PlanBudget::from_budget`] on a frame of `fragments`, refused where it leaves no slot
    /// (a share of a frame with fragments, or slots per pixel).
    pub fn of(budget: Budget, pixels: u64, fragments: u64) -> Result<PlanBudget> {
        let b = PlanBudget::from_budget(budget, pixels);
        match (budget, b) {
            // A frame with nothing transparent in view (all hidden, or none) needs no slot.
            (Budget::Share(_), PlanBudget::Fragments(f))
                if f.of(fragments) == 0 && fragments > 0 =>
            {
                Err(Error::Budget(
                    budget.to_string(),
                    format!("leaves no fragment slot of the frame's {fragments} fragments"),
                ))
            }
            (Budget::SlotsPerPixel(f), PlanBudget::Fragments(FragmentBudget::Slots(0))) => {
                Err(Error::Budget(
                    format!("{f}fpp"),
                    format!("leaves no fragment slot for {pixels} pixels"),
                ))
            }
            _ => Ok(b),
        }
    }
}
