//! A method's frames one after another, as a renderer draws them: each recorded into its
//! client's encoder with no wait, its buffers sized before its count from the counts of the
//! frames before (their reports, read back without waiting), its report mapped when its
//! submission has run. What an application's methods (`app.rs`) and dhoit's own streamed
//! scenes ([`SceneStream`](super::SceneStream)) share.

use super::buffers::FrameStatus;
use super::passes::{Geometry, Phase};
use super::timer::Timer;
use super::{Capture, FrameOptions, FrameSpec, Gpu, Sizing, Slots};
use crate::budget::{self, Budget, Layout, Occupancy};
use crate::composite::{MboitParams, WboitParams};
use crate::error::{Error, GpuError, Result};
use crate::importance::VkbParams;
use crate::mlp::Mlp;
use crate::plan::{Plan, PlanBudget};
use crate::wgsl::{MLAB_MAX_ROWS, Params};

/// What a frame did, read back once it has run (`Oit::finished`,
/// [`SceneStream::finished`](super::SceneStream::finished)).
#[derive(Debug)]
pub struct FrameReport {
    /// The frame's number: 0 for the first the renderer recorded.
    pub frame: u64,
    /// GPU time of each pass, in ms, in the order recorded (none where the device has no
    /// timestamps).
    pub pass_ms: Vec<(&'static str, f64)>,
    /// Every pass the frame recorded, in order, on any device (DKB's features pass only in a
    /// frame that marked its own records: its first, one after a cut).
    pub passes: Vec<&'static str>,
    /// The frame's fragments, where it counted them (the A-buffer, MLAB, DKB, VKB).
    pub fragments: Option<u64>,
    /// DKB and VKB: the frame's occupancy and the plan it made from it on the device.
    pub occupancy: Option<Occupancy>,
    pub plan: Option<Plan>,
    /// Whether the frame kept every fragment (the exact image): the A-buffer and MLAB where
    /// their pool held them, DKB and VKB where their plan said so.
    pub exact: bool,
    /// Bytes of the buffers the frame held.
    pub allocated_bytes: u64,
    /// Whether a pool sized before the frame's count held fewer of its fragments than it
    /// needed: the A-buffer's and MLAB's drop the pixels past its end, DKB's and VKB's keep
    /// fewer fragments in slots and more in the tails ([`crate::plan::Plan::short`]).
    pub pool_short: bool,
    /// Whether its buffers were sized before any count of the scene: a page's first frame (which
    /// cannot wait for one) of a method whose memory follows the count. One that fits may hold
    /// more bytes than the frames after it, sized from its count.
    pub guessed: bool,
    /// What made the frame wrong, where something did: a pixel too deep for any method, or a
    /// device that cut a pass's loops short.
    pub error: Option<Error>,
}

/// The method a [`Stream`] runs, with what it needs.
#[derive(Clone, Debug)]
pub(super) enum AppMethod {
    List { nodes: u64, sorted: u32 },
    Fkb { k: u32 },
    Abuffer,
    Mlab { rows: u32 },
    Dkb(Box<Mlp>),
    Vkb(VkbParams),
    Wboit(WboitParams),
    Mboit(MboitParams),
}

impl AppMethod {
    pub(super) fn name(&self) -> &'static str {
        match self {
            AppMethod::List { .. } => "linked-list",
            AppMethod::Fkb { .. } => "fkb",
            AppMethod::Abuffer => "abuffer",
            AppMethod::Mlab { .. } => "mlab",
            AppMethod::Dkb(_) => "dkb",
            AppMethod::Vkb(_) => "vkb",
            AppMethod::Wboit(_) => "wboit",
            AppMethod::Mboit(_) => "mboit",
        }
    }

    /// The geometry passes a frame draws, in order, with the k-buffers' capture `capture`, and
    /// where its fragments keep tint words (`tints`: colours above white) the k-buffers' tint
    /// pass after their capture.
    pub(super) fn phases(&self, capture: Capture, tints: bool) -> &'static [Phase] {
        use Phase::*;
        let portable = capture == super::Capture::Portable;
        // A k-buffer's passes, its tint pass last.
        let k_buffer: &'static [Phase] = match (self, portable) {
            (AppMethod::List { .. }, _) => return &[ListStore],
            (AppMethod::Abuffer | AppMethod::Mlab { .. }, _) => return &[Count, Store],
            (AppMethod::Wboit(_), _) => return &[WboitAccumulate],
            (AppMethod::Mboit(_), _) => return &[MboitMoments, MboitAccumulate],
            (AppMethod::Fkb { .. }, true) => &[CaptureDepths, CaptureColours, CaptureTints],
            (AppMethod::Fkb { .. }, false) => &[Capture, CaptureTints],
            // DKB's features pass is drawn where a frame marks its own records (its first,
            // one after a cut, batches); else the count gathers them.
            (AppMethod::Dkb(_), true) => &[
                CountFeatures,
                Features,
                CaptureDepths,
                CaptureColours,
                CaptureTints,
            ],
            (AppMethod::Dkb(_), false) => &[CountFeatures, Features, Capture, CaptureTints],
            (AppMethod::Vkb(_), true) => &[VkbCount, CaptureDepths, CaptureColours, CaptureTints],
            (AppMethod::Vkb(_), false) => &[VkbCount, Capture, CaptureTints],
        };
        match tints {
            true => k_buffer,
            false => &k_buffer[..k_buffer.len() - 1],
        }
    }

    /// The layout its memory follows ([`budget::Layout`]).
    /// Its buffers, DKB's records in `decision`'s batches.
    pub(super) fn layout(&self, decision: &budget::Decision) -> Layout {
        match self {
            AppMethod::List { .. } => budget::LINKED_LIST,
            AppMethod::Fkb { .. } => budget::FKB,
            AppMethod::Abuffer | AppMethod::Mlab { .. } => budget::ABUFFER,
            AppMethod::Dkb(m) => decision.dkb_layout(m),
            AppMethod::Vkb(_) => budget::VKB,
            AppMethod::Wboit(_) => budget::WBOIT,
            AppMethod::Mboit(m) => budget::mboit(m.moments),
        }
    }
}

/// What an application's frame for the method runs on, in dhoit's own terms.
fn slots_of(method: &AppMethod, budget: PlanBudget) -> Slots<'_> {
    match method {
        AppMethod::List { nodes, sorted } => Slots::LinkedList {
            nodes: *nodes,
            sorted: *sorted,
        },
        AppMethod::Fkb { k } => Slots::Uniform(*k),
        AppMethod::Abuffer => Slots::Exact,
        AppMethod::Mlab { rows } => Slots::Mlab(*rows),
        AppMethod::Dkb(m) => Slots::Dkb(m, budget),
        AppMethod::Vkb(v) => Slots::Vkb(*v, budget),
        AppMethod::Wboit(w) => Slots::Wboit(*w),
        AppMethod::Mboit(m) => Slots::Mboit(*m),
    }
}

/// The growth a pool sized from earlier frames' counts keeps over them.
const HEADROOM: f64 = 1.25;
/// The fragments a pixel an application's first frames are sized for, before any count.
const FIRST_FRAGMENTS_PER_PIXEL: u64 = 2;
/// Frames whose reports a renderer keeps waiting to be read at once (past them a new frame's
/// report takes the oldest's place).
const REPORTS_IN_FLIGHT: usize = 16;
/// Where a report's words lie in its staging buffer: the resolve's status first, then the
/// totals with the plan, ...
const REPORT_TOTALS_AT: u64 = FrameStatus::BYTES;
/// ... the A-buffer's fragments, ...
const REPORT_COUNTED_AT: u64 = REPORT_TOTALS_AT + 4 * crate::shared::TOTALS_WORDS as u64;
/// ... the frame's stamp, two words the frame's own commands copy there ([`stamp`]), ...
const REPORT_STAMP_AT: u64 = REPORT_COUNTED_AT + 4;
/// ... and from here (8-byte aligned), the timestamps: two u64 a timed pass.
const REPORT_WORDS: u64 = (REPORT_STAMP_AT + 8).next_multiple_of(8);
/// Values of the stamps' words: 1 to 256 (never 0, what a new staging buffer holds).
const STAMP_VALUES: u64 = 256;

/// Frame `frame`'s stamp: the words [`Stream::stamps`] holds at these indices, copied into
/// its report by its own commands, so a report whose staging buffer holds another stamp (its
/// encoder was never submitted, or its submission failed) is of a frame that never ran. 1 + the
/// frame's number's low and second bytes: two reports share a staging buffer's stamp only 65,536
/// frames apart.
fn stamp(frame: u64) -> [u32; 2] {
    [
        1 + (frame % STAMP_VALUES) as u32,
        1 + (frame / STAMP_VALUES % STAMP_VALUES) as u32,
    ]
}

/// A frame's report, recorded and not yet read.
struct PendingReport {
    frame: u64,
    staging: wgpu::Buffer,
    /// The passes timed, in the order of their timestamps in `staging`.
    passes: Vec<&'static str>,
    /// Every pass recorded.
    ran: Vec<&'static str>,
    allocated: u64,
    /// Whether it holds totals (an allocated k-buffer's), an A-buffer's fragments.
    totals: bool,
    counted: bool,
    /// [`FrameReport::guessed`].
    guessed: bool,
    /// True once mapped (after the submission that ran the frame).
    mapped: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

/// A method's frames: its frame engine (a fork of its client's [`Gpu`]: the same passes,
/// buffers of its own), what it runs, and what sizes the buffers a frame makes before its count.
pub(super) struct Stream {
    pub(super) gpu: Gpu,
    pub(super) size: (u32, u32),
    pub(super) method: AppMethod,
    /// DKB's and VKB's budget (the others' is in their method).
    pub(super) budget: Option<Budget>,
    /// How its k-buffer frames' budget is decided ([`FrameOptions::decision`]).
    pub(super) decision: budget::Decision,
    /// How the k-buffers insert their fragments ([`FrameOptions::capture`]).
    pub(super) capture: Capture,
    /// What its frames store beside each fragment's key (dhoit's own scenes of tinted glass or
    /// colours above white, `SceneStream`: [`crate::scene::Scene::words`]): a byte budget
    /// then holds them too (`Layout::tinted_budget`). An application's fragments are untinted:
    /// its frames store the words where it asked for colours above white ([`Stream::hdr`]).
    pub(super) words: budget::Words,
    /// Whether its frames keep colours above white (`Params::hdr`): an application's, where it
    /// asked for it (`Oit::set_hdr`); a scene's, where its emission can pass white.
    pub(super) hdr: bool,
    /// The budget last given ([`Stream::set_budget`]), resolved again where what a fragment
    /// keeps changes.
    pub(super) asked: Option<Budget>,
    /// The occupancy the buffers made before a frame's count hold: the largest of the last
    /// frames', with [`HEADROOM`] (before any, [`FIRST_FRAGMENTS_PER_PIXEL`] a pixel).
    pub(super) expected: Occupancy,
    frames: u64,
    pub(super) last_bytes: u64,
    /// The frames' reports, copied and waiting to be read.
    reports: Reports,
    /// DKB's record marks from frame to frame ([`super::Carried`]): made with the first frame
    /// of a size, valid once a frame has left its own there, made invalid by a cut
    /// ([`Stream::cut`]), after which the next frame marks its own and draws a features pass.
    carried: Option<super::Carried>,
    /// Whether the frames' sizes follow a count (one read back, or the application's
    /// [`Stream::expect`]): until then the next frame counts first ([`Stream::count_first`]).
    counted: bool,
}

impl Stream {
    pub(super) fn new(
        gpu: &Gpu,
        size: (u32, u32),
        method: AppMethod,
        budget: Option<Budget>,
    ) -> Result<Stream> {
        check_size(gpu, size)?;
        if let AppMethod::Dkb(m) = &method {
            gpu.can_run(m)?;
        }
        check_fixed_buffers(gpu, size, &method)?;
        let mut f = Stream {
            gpu: gpu.fork(),
            size,
            method,
            budget: None,
            decision: budget::Decision::default(),
            capture: gpu.capture_for(Capture::Wide),
            words: budget::Words::None,
            hdr: false,
            asked: None,
            expected: first_occupancy(size),
            frames: 0,
            last_bytes: 0,
            reports: Reports::default(),
            carried: None,
            counted: false,
        };
        if let Some(b) = budget {
            f.set_budget(b)?;
        }
        Ok(f)
    }

    /// The k-buffers' capture from the next frame: `capture`, or the portable one on a device
    /// without 64-bit atomics ([`Gpu::capture_for`]).
    pub(super) fn set_capture(&mut self, capture: Capture) {
        self.capture = self.gpu.capture_for(capture);
    }

    /// The geometry passes a frame of the method draws, in order.
    pub(super) fn phases(&self) -> &'static [Phase] {
        self.method.phases(self.capture, self.words.any())
    }

    pub(super) fn pixels(&self) -> u64 {
        self.size.0 as u64 * self.size.1 as u64
    }

    /// What the buffers a frame makes before its count are sized for: for DKB and VKB, the
    /// pool their budget takes at the occupancy this stream expects ([`crate::plan::ahead`]).
    fn sizing(&self) -> Sizing {
        let occ = self.expected;
        let ahead = match (&self.method, self.budget) {
            (AppMethod::Dkb(_) | AppMethod::Vkb(_), Some(_)) => crate::plan::ahead(
                &self.method.layout(&self.decision),
                self.plan_budget(),
                self.pixels(),
                &occ,
                self.words,
                self.decision.exact_when_cheaper,
            ),
            _ => crate::plan::Ahead {
                pool_bytes: 0,
                batches: 1,
            },
        };
        Sizing::Ahead {
            fragments: occ.fragments,
            pool_bytes: ahead.pool_bytes,
            batches: ahead.batches,
        }
    }

    /// The budget DKB's and VKB's frames plan with: F (a share, or slots a pixel times the
    /// pixels), or bytes, which the plan resolves against each frame's own count. No budget
    /// (the other methods) is no slot.
    fn plan_budget(&self) -> PlanBudget {
        self.budget
            .map_or(0.into(), |b| PlanBudget::from_budget(b, self.pixels()))
    }

    pub(super) fn finished(&mut self, wait: bool) -> Result<Vec<FrameReport>> {
        match wait && !self.reports.pending.is_empty() {
            true => self.gpu.wait("reading a frame's report")?,
            false => {
                self.gpu
                    .device
                    .poll(wgpu::PollType::Poll)
                    .map_err(|e| GpuError::Lost {
                        doing: "reading a frame's report",
                        message: e.to_string(),
                    })?;
            }
        }
        let mapped = |p: &PendingReport| p.mapped.load(std::sync::atomic::Ordering::Acquire);
        let mut reports = Vec::new();
        while let Some(p) = self.reports.pending.first() {
            if !mapped(p) {
                // Submissions run in order: where a later frame's report is mapped (or, waited
                // for, every submitted one), this one's encoder was never submitted.
                let later = self.reports.pending[1..].iter().any(mapped);
                if later || wait {
                    self.reports.pending.remove(0);
                    continue;
                }
                break;
            }
            let p = self.reports.pending.remove(0);
            let report = self.read_report(&p)?;
            p.staging.unmap();
            self.reports.spare.push(p.staging);
            // Only the frames that ran report (and size the frames to come).
            if let Some(report) = report {
                self.learn(&report);
                reports.push(report);
            }
        }
        Ok(reports)
    }

    /// The report of the frame `p` staged, or None where it never ran: its staging buffer does
    /// not hold its [`stamp`] (its submission failed, and the buffer holds what it held).
    fn read_report(&self, p: &PendingReport) -> Result<Option<FrameReport>> {
        let data = p
            .staging
            .slice(..)
            .get_mapped_range()
            .map_err(|e| GpuError::Lost {
                doing: "reading a frame's report",
                message: e.to_string(),
            })?;
        let word = |at: usize| u32::from_le_bytes(data[at..at + 4].try_into().expect("4"));
        let at = REPORT_STAMP_AT as usize;
        if [word(at), word(at + 4)] != stamp(p.frame) {
            return Ok(None);
        }
        let status = FrameStatus::parse(&data[..REPORT_TOTALS_AT as usize]);
        let totals: Vec<u32> = (0..crate::shared::TOTALS_WORDS as usize)
            .map(|i| word(REPORT_TOTALS_AT as usize + 4 * i))
            .collect();
        let occupancy = p.totals.then(|| Occupancy::from_totals(&totals));
        let plan = p.totals.then(|| {
            let word = |i: u32| totals[i as usize];
            let (f, flags) = (crate::shared::PLAN_F_WORD, crate::shared::PLAN_FLAGS_WORD);
            Plan::from_words([word(f), word(flags), 0], 0)
        });
        let fragments = match (p.counted, occupancy) {
            (true, _) => Some(word(REPORT_COUNTED_AT as usize) as u64),
            (_, Some(o)) => Some(o.fragments),
            _ => None,
        };
        let period = self.gpu.timestamp_period as f64;
        let pass_ms = match self.gpu.timestamps {
            true => p
                .passes
                .iter()
                .enumerate()
                .map(|(i, &name)| {
                    let at = REPORT_WORDS as usize + 16 * i;
                    let tick = |k: usize| {
                        u64::from_le_bytes(data[at + 8 * k..at + 8 * k + 8].try_into().expect("8"))
                    };
                    (name, tick(1).saturating_sub(tick(0)) as f64 * period / 1e6)
                })
                .collect(),
            false => Vec::new(),
        };
        let plan_short = plan.is_some_and(|p| p.short != 0);
        let exact = match (&self.method, plan) {
            (_, Some(plan)) => plan.exact,
            (AppMethod::Abuffer | AppMethod::Mlab { .. }, None) => !status.pool_short,
            _ => false,
        };
        Ok(Some(FrameReport {
            frame: p.frame,
            pass_ms,
            passes: p.ran.clone(),
            fragments,
            occupancy,
            plan,
            exact,
            allocated_bytes: p.allocated,
            pool_short: status.pool_short || plan_short,
            guessed: p.guessed,
            error: status.check(&self.gpu, self.size.0).err(),
        }))
    }

    /// Whether the next frame's buffers wait for a count of it ([`Stream::count_first`]): a
    /// method whose memory follows the frame's count, no count read or expected since it was
    /// made or resized, on a device it may wait for (not a page's).
    pub(super) fn uncounted(&self) -> bool {
        self.guesses() && !cfg!(target_arch = "wasm32")
    }

    /// Whether the next frame's buffers are sized before any count of it: a method whose memory
    /// follows the frame's count, no count read or expected since it was made or resized.
    fn guesses(&self) -> bool {
        let follows = matches!(
            self.method,
            AppMethod::Abuffer | AppMethod::Mlab { .. } | AppMethod::Dkb(_) | AppMethod::Vkb(_)
        );
        follows && !self.counted
    }

    /// The next frame's fragments counted first (the method's first frame, the first after a
    /// resize, where the application expected no occupancy): its count phase drawn by
    /// `geometry` in a submission of its own, after what `before` records (the opaque pass, or
    /// an occluder cleared to the far plane: then every fragment in view counts, the most the
    /// frame can have), which it waits for; the totals read back size the frames to come (with
    /// [`HEADROOM`]), so the frame holds every fragment its budget asks for.
    pub(super) fn count_first(
        &mut self,
        geometry: &dyn Geometry,
        before: &dyn Fn(&Gpu, &mut wgpu::CommandEncoder),
        params: Params,
    ) -> Result<()> {
        use super::bindings::{features, features_count, vkb_count};
        use super::buffers::FrameBuffers;
        use super::passes::{GeometryPass, at};
        let gpu = &self.gpu;
        let px = self.pixels();
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        let mut fb = FrameBuffers::new(gpu, &mut enc);
        let uniform = fb.init(
            "count first.params",
            bytemuck::bytes_of(&Params {
                dkb_records: 0,
                ..params
            }),
            wgpu::BufferUsages::UNIFORM,
            false,
        );
        let counts = fb.storage("count first.count", crate::shared::count_bytes(px), false)?;
        let totals = fb.storage(
            "count first.totals",
            4 * crate::shared::TOTALS_WORDS as u64,
            false,
        )?;
        let p = &gpu.pipelines;
        // The method's own count phase (the one its frames draw first), its group's other
        // buffers unread (DKB gathers no record: Params::dkb_records 0) or written and dropped.
        let (phase, pipeline, extra) = match &self.method {
            AppMethod::Dkb(_) => {
                let marks = fb.storage("count first.marks", budget::marks_bytes(px), false)?;
                let none = fb.storage("count first.records", 16, false)?;
                let depths = fb.init(
                    "count first.optical_depth",
                    bytemuck::cast_slice(&crate::importance::optical_depth_table()),
                    wgpu::BufferUsages::UNIFORM,
                    false,
                );
                let (phase, pipeline) = (Phase::CountFeatures, &p.count_features);
                let bound = vec![
                    (features::RECORD_MARKS, marks),
                    (features::RECORDS, none),
                    (features::OPTICAL_DEPTH, depths),
                    (features_count::COUNTS, counts.clone()),
                ];
                (phase, pipeline, bound)
            }
            AppMethod::Vkb(_) => {
                let nearest = fb.storage("count first.nearest", 4 * px, false)?;
                let bound = vec![
                    (vkb_count::COUNT, counts.clone()),
                    (vkb_count::NEAREST_INV, nearest),
                ];
                (Phase::VkbCount, &p.vkb_count, bound)
            }
            _ => (Phase::Count, &p.count, vec![(0, counts.clone())]),
        };
        let held = fb.into_taken();
        before(gpu, &mut enc);
        let pass = GeometryPass {
            phase,
            pipeline,
            group: extra.iter().map(|(i, b)| at(*i, b)).collect(),
            targets: &[],
            name: "count first",
        };
        geometry.draw(gpu, &mut enc, pass, &uniform, None);
        let g = gpu.bind(
            &p.totals.get_bind_group_layout(0),
            &[&uniform, &counts, &totals],
        );
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            let (gx, gy) = crate::wgsl::grid(px as u32, crate::wgsl::PIXEL_GROUP);
            pass.set_pipeline(&p.totals);
            pass.set_bind_group(0, &g, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        gpu.submit(enc.finish());
        let words = (0..=crate::shared::TOTAL_DEEPER).map(|i| (&totals, 4 * i as u64));
        let w = super::buffers::read_words(gpu, &words.collect::<Vec<_>>())?;
        drop(held);
        self.expected = Occupancy::from_totals(&w).scaled(HEADROOM, px);
        self.counted = true;
        Ok(())
    }

    /// A frame's count, for the frames to come: the pool follows the largest recent count with
    /// some headroom, made again where a frame needed more, or less than half.
    fn learn(&mut self, r: &FrameReport) {
        let px = self.pixels();
        let seen = match (r.occupancy, r.fragments) {
            (Some(o), _) => o,
            (None, Some(n)) => Occupancy {
                fragments: n,
                ..self.expected
            },
            _ => return,
        };
        let next = seen.scaled(HEADROOM, px);
        self.counted = true;
        let e = self.expected;
        let needs_more = seen.fragments > e.fragments
            || seen.covered > e.covered
            || seen.deep > e.deep
            || seen.deeper > e.deeper;
        let far_less = 2 * next.fragments < e.fragments;
        if needs_more || far_less {
            self.expected = next;
        }
    }

    /// The buffers of the frames to come sized for frames of `occupancy`, as given (no first
    /// count: [`Stream::counted`]).
    pub(super) fn expect(&mut self, occupancy: Occupancy) {
        self.expected = occupancy;
        self.counted = true;
    }

    pub(super) fn set_budget(&mut self, budget: Budget) -> Result<()> {
        let px = self.pixels();
        let name = self.method.name();
        let refuse = |why: &str| Err(Error::Budget(budget.to_string(), format!("{name} {why}")));
        let words = self.words;
        self.asked = Some(budget);
        match &mut self.method {
            AppMethod::Dkb(_) | AppMethod::Vkb(_) => {
                let layout = self.method.layout(&self.decision);
                // Refused now where no frame can hold a slot: bytes below the fixed bytes and
                // the marks, or no fragment budget for the layout.
                match budget {
                    Budget::Bytes(m) => {
                        layout.fragment_budget_counted(m, px, &Occupancy::default())?;
                    }
                    _ => {
                        budget.fragment_budget(&layout, px)?;
                    }
                }
                self.budget = Some(budget);
            }
            AppMethod::Fkb { k } => {
                let f = match budget {
                    Budget::Share(_) => {
                        return refuse(
                            "allocates its k slots a pixel before any count: give slots a pixel or bytes",
                        );
                    }
                    Budget::Bytes(m) => {
                        let m = budget::FKB.tinted_budget(m, px, words);
                        Budget::Bytes(m).resolve(&budget::FKB, px, 0)?.1
                    }
                    b => b.resolve(&budget::FKB, px, 0)?.1,
                };
                *k = (f / px.max(1)).clamp(1, u32::MAX as u64) as u32;
            }
            AppMethod::List { nodes, .. } => {
                *nodes = match budget {
                    Budget::Share(_) => {
                        return refuse(
                            "allocates its pool before any count: give fragments a pixel or bytes",
                        );
                    }
                    Budget::Bytes(m) => {
                        let m = budget::LINKED_LIST.tinted_budget(m, px, words);
                        Budget::Bytes(m).resolve(&budget::LINKED_LIST, px, 0)?.1
                    }
                    b => b.resolve(&budget::LINKED_LIST, px, 0)?.1,
                };
            }
            AppMethod::Mlab { rows } => match budget {
                Budget::SlotsPerPixel(f) if f >= 1.0 && f <= MLAB_MAX_ROWS as f64 => {
                    *rows = f.floor() as u32;
                }
                _ => {
                    return refuse(&format!(
                        "takes its rows as slots a pixel, 1 to {MLAB_MAX_ROWS}"
                    ));
                }
            },
            AppMethod::Abuffer | AppMethod::Wboit(_) | AppMethod::Mboit(_) => {
                return refuse("takes no budget");
            }
        }
        check_fixed_buffers(&self.gpu, self.size, &self.method)
    }

    /// The next frame starts a new shot (the camera jumped, the scene changed): DKB's frame
    /// marks its own records and draws a features pass rather than gather its statistics with
    /// its count for the pixels the frame before marked.
    pub(super) fn cut(&mut self) {
        if let Some(c) = &mut self.carried {
            c.valid = false;
        }
    }

    pub(super) fn resize(&mut self, size: (u32, u32)) -> Result<()> {
        check_size(&self.gpu, size)?;
        let old = self.pixels();
        self.size = size;
        // The marks are of the old size: a cut; and the first frame of the size counts first.
        self.carried = None;
        self.counted = false;
        // The counts so far, for a frame as many times larger.
        let px = self.pixels();
        self.expected = self.expected.scaled(px as f64 / old.max(1) as f64, px);
        // A budget in slots or bytes may not fit the new size.
        if let Some(b) = self.budget {
            self.set_budget(b)?;
        }
        Ok(())
    }

    /// One frame of the method recorded into `enc`, its geometry drawn by `geometry`, with the
    /// frame's parameters `params` (the client's camera where it has one), and its report
    /// copied where [`Stream::finished`] reads it once the encoder's submission has run.
    pub(super) fn record(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        geometry: &dyn Geometry,
        params: Params,
    ) -> Result<()> {
        if matches!(self.method, AppMethod::Dkb(_) | AppMethod::Vkb(_)) && self.budget.is_none() {
            return Err(Error::Invalid(format!(
                "{} needs a budget (set_budget)",
                self.method.name()
            )));
        }
        let opts = FrameOptions {
            diagnostics: false,
            decision: self.decision,
            capture: self.capture,
            ..FrameOptions::default()
        };
        self.make_marks();
        let spec = FrameSpec {
            opts,
            size: self.size,
            params,
            slots: slots_of(&self.method, self.plan_budget()),
            sizing: self.sizing(),
            carried: self.carried.clone(),
        };
        let timer = Timer::new(&self.gpu);
        let recorded = match self.gpu.record_frame(enc, &timer, geometry, &spec) {
            Ok(r) => r,
            Err(e) => {
                // What the frame recorded of its marks is not to be read.
                if let Some(c) = &mut self.carried {
                    c.valid = false;
                }
                return Err(e);
            }
        };
        if let Some(c) = &mut self.carried {
            c.valid = recorded.marked;
        }
        let numbered = (self.frames, self.guesses());
        self.reports
            .copy(&self.gpu, enc, numbered, &timer, &recorded);
        self.frames += 1;
        self.last_bytes = recorded.allocated;
        Ok(())
    }

    /// DKB's record marks, made with its first frame of a size (the frame before's marks are
    /// what a frame that gathers its statistics with its count reads).
    fn make_marks(&mut self) {
        if matches!(self.method, AppMethod::Dkb(_)) && self.carried.is_none() {
            let bytes = budget::marks_bytes(self.pixels());
            self.carried = Some(super::Carried {
                marks: self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("dkb.record_marks"),
                    size: bytes,
                    usage: wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_SRC
                        | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                }),
                valid: false,
            });
        }
    }
}

/// A stream's frame reports: those copied and not yet read, the staging buffers of those read
/// (for the next), and the stamps they are numbered from.
#[derive(Default)]
struct Reports {
    pending: Vec<PendingReport>,
    /// Staging buffers of reports read, for the next.
    spare: Vec<wgpu::Buffer>,
    /// The words 0 to [`STAMP_VALUES`], each its index, that frames copy their [`stamp`] from.
    stamps: Option<wgpu::Buffer>,
}

impl Reports {
    /// The frame's report (its status, totals, count, pass times and stamps) copied into a
    /// staging buffer mapped once the encoder's submission has run, where
    /// [`Stream::finished`] reads it without waiting: frame number `frame`, sized from a guess
    /// where `guessed`.
    fn copy(
        &mut self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        (frame, guessed): (u64, bool),
        timer: &Timer,
        recorded: &super::Recorded,
    ) {
        let passes = timer.names();
        let timed = timer.resolved();
        let bytes = REPORT_WORDS + 16 * passes.len() as u64;
        // Reports never read (an application that never asks) make room for new ones.
        if self.pending.len() >= REPORTS_IN_FLIGHT {
            self.pending.remove(0);
        }
        let staging = match self.spare.iter().position(|b| b.size() >= bytes) {
            Some(i) => self.spare.swap_remove(i),
            None => gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("dhoit frame report"),
                size: (REPORT_WORDS + 16 * super::TIMED_PASSES as u64).max(bytes),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        };
        enc.clear_buffer(&staging, 0, Some(REPORT_WORDS));
        let stamps = self.stamps.get_or_insert_with(|| {
            let words: Vec<u32> = (0..=STAMP_VALUES as u32).collect();
            let b = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("dhoit frame stamps"),
                size: 4 * words.len() as u64,
                usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            // Written before the first submission's commands, never again.
            gpu.queue.write_buffer(&b, 0, bytemuck::cast_slice(&words));
            b
        });
        for (i, s) in stamp(frame).into_iter().enumerate() {
            let to = REPORT_STAMP_AT + 4 * i as u64;
            enc.copy_buffer_to_buffer(stamps, 4 * s as u64, &staging, to, 4);
        }
        let out = &recorded.out;
        if let Some(status) = &out.status {
            enc.copy_buffer_to_buffer(status, 0, &staging, 0, FrameStatus::BYTES);
        }
        if let Some((totals, _)) = &out.plan_buf {
            let bytes = 4 * crate::shared::TOTALS_WORDS as u64;
            enc.copy_buffer_to_buffer(totals, 0, &staging, REPORT_TOTALS_AT, bytes);
        }
        if let Some((offsets, at)) = &out.counted {
            enc.copy_buffer_to_buffer(offsets, *at, &staging, REPORT_COUNTED_AT, 4);
        }
        if let Some(resolved) = &timed {
            enc.copy_buffer_to_buffer(
                resolved,
                0,
                &staging,
                REPORT_WORDS,
                16 * passes.len() as u64,
            );
        }
        // Mapped once the application's submission of this encoder has run: never before
        // it is submitted, so reading reports cannot hold up or break a submission.
        let mapped = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let flag = mapped.clone();
        enc.map_buffer_on_submit(&staging, wgpu::MapMode::Read, .., move |r| {
            flag.store(r.is_ok(), std::sync::atomic::Ordering::Release)
        });
        self.pending.push(PendingReport {
            frame,
            staging,
            passes,
            ran: timer.ran(),
            allocated: recorded.allocated,
            totals: out.plan_buf.is_some(),
            counted: out.counted.is_some(),
            guessed,
            mapped,
        });
    }
}

/// Refuses, before anything is made, FKB's slots and the list's nodes past the device's
/// bindings or 32-bit indices: the buffers their budget fixes.
fn check_fixed_buffers(gpu: &Gpu, (w, h): (u32, u32), method: &AppMethod) -> Result<()> {
    let px = w as u64 * h as u64;
    let limits = gpu.device.limits();
    let max = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    let (label, slots, bytes) = match method {
        AppMethod::Fkb { k } => ("oit.slots", *k as u64 * px, budget::SLOT_BYTES),
        AppMethod::List { nodes, .. } => ("list.keys", *nodes, 8),
        _ => return Ok(()),
    };
    if slots >= u32::MAX as u64 {
        return Err(Error::Invalid(format!(
            "{} takes {slots} slots, past its 32-bit indices",
            method.name()
        )));
    }
    if slots * bytes > max {
        return Err(GpuError::BufferTooLarge {
            label: label.to_string(),
            need: slots * bytes,
            max,
        }
        .into());
    }
    Ok(())
}

/// The frame's first occupancy before any count: every pixel covered and deep, with
/// [`FIRST_FRAGMENTS_PER_PIXEL`] fragments a pixel.
fn first_occupancy((w, h): (u32, u32)) -> Occupancy {
    let px = w as u64 * h as u64;
    Occupancy {
        fragments: FIRST_FRAGMENTS_PER_PIXEL * px,
        ..Occupancy::most(px)
    }
}

pub(super) fn check_size(gpu: &Gpu, (w, h): (u32, u32)) -> Result<()> {
    crate::raster::check_resolution((w, h))?;
    let max = gpu.device.limits().max_texture_dimension_2d;
    if w > max || h > max {
        return Err(GpuError::FrameTooLarge {
            width: w,
            height: h,
            max,
        }
        .into());
    }
    Ok(())
}
