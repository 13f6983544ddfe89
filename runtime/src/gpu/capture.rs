//! The k-buffer: k for every pixel (one for all, uploaded, or allocated on the device:
//! `allocate.rs`), the slot bases (`scan.wgsl`), then `capture.wgsl` (geometry: the two-mode
//! capture, append or Loop64 insertion; twin `composite::capture`) and `resolve.wgsl` (the
//! slots front to back over the tail's approximation; twin `composite::hybrid_sorted`).

use super::allocate::{AllocBuffers, Importance, Word};
use super::bindings;
use super::buffers::{FrameStatus, read_back, read_counts, read_u64s, u32s};
use super::passes::{Phase, Resolve, at, entries};
use super::scan::Scan;
use super::{Capture, Planned, Recording, Slots};
use crate::error::{Error, Result};
use crate::shared::count_bytes;

/// A frame's k: per pixel, its slot bases (`pixels + 1` entries: k is their difference, not
/// stored), the slots (or, pooled, the pool they and the tails share), and n(p) where the frame
/// counted it (the two-mode capture reads it; else an unused buffer).
pub(super) struct KBuffer {
    pub(super) base: wgpu::Buffer,
    /// The slots: FKB's and an uploaded k's (their number is the host's), or the pooled ones
    /// with their tails.
    pub(super) slots: SlotsAt,
    pub(super) counts: wgpu::Buffer,
    /// The per-pixel tail's buffers the capture's layout binds unused where the tails are
    /// pooled.
    pub(super) unused: Option<(wgpu::Buffer, wgpu::Buffer)>,
    /// Whether the host knows the frame keeps every fragment (k = n everywhere).
    pub(super) all_fit: bool,
}

/// Where a k-buffer's slots are.
pub(super) enum SlotsAt {
    /// `n` slots, the tails per pixel in buffers of their own.
    PerPixel(u64),
    /// A pool of the slots and the tails (`Params::pooled_tail`: the bases are the prefix sums
    /// of each pixel's span, `shared::span`), sized before the count.
    Pooled(wgpu::Buffer),
}

impl Recording<'_, '_, '_> {
    /// k as `s` gives it: FKB's uniform k, an uploaded k, or the allocation of the importance
    /// the frame computes (DKB, VKB) or is given, as its plan has it.
    pub(super) fn k_for(&mut self, s: Slots, planned: Planned) -> Result<KBuffer> {
        let (passes, px) = (self.passes, self.px);
        match s {
            Slots::Uniform(k) => {
                // FKB reads none of these, but the shared capture layout binds them.
                let fb = &mut self.fb;
                Ok(KBuffer {
                    base: fb.storage(
                        "fkb.unused_offsets",
                        crate::shared::LEAST_BUFFER_BYTES,
                        true,
                    )?,
                    slots: SlotsAt::PerPixel(k.max(1) as u64 * px),
                    counts: fb.storage(
                        "fkb.unused_counts",
                        crate::shared::LEAST_BUFFER_BYTES,
                        true,
                    )?,
                    unused: None,
                    all_fit: false,
                })
            }
            Slots::PerPixel(k) => {
                if k.len() as u64 != px {
                    return Err(Error::Invalid(format!(
                        "{} k values for {px} pixels",
                        k.len()
                    )));
                }
                // k uploaded into the bases' buffer, then their prefix sums in place.
                let base = self.pixel_word(Word::Holding(k))?;
                let fb = &mut self.fb;
                passes.prefix_sum_of(fb, Scan::InPlace(&base), None)?;
                Ok(KBuffer {
                    base,
                    slots: SlotsAt::PerPixel(k.iter().map(|&x| x as u64).sum()),
                    counts: fb.storage(
                        "oit.unused_counts",
                        crate::shared::LEAST_BUFFER_BYTES,
                        true,
                    )?,
                    unused: None,
                    all_fit: false,
                })
            }
            Slots::Importance(imp, target, _) => {
                let i = self.uploaded_importance(imp, target, &planned)?;
                self.allocated(i, &planned)
            }
            Slots::Vkb(..) => {
                let i = self.vkb_importance(&planned)?;
                self.allocated(i, &planned)
            }
            Slots::Dkb(mlp, _) => {
                let i = self.dkb_importance(mlp, &planned)?;
                self.allocated(i, &planned)
            }
            Slots::Exact
            | Slots::Mlab(_)
            | Slots::Wboit(_)
            | Slots::Mboit(_)
            | Slots::LinkedList { .. } => {
                unreachable!(
                    "the A-buffer, MLAB, WBOIT, MBOIT and the linked list have passes of their own"
                )
            }
        }
    }

    /// The allocation of `i` at its plan's F (allocate.wgsl reads it in the totals; where the
    /// frame keeps every fragment, apply alone gives k = n) and its slot bases, in the pool the
    /// frame was sized for.
    pub(super) fn allocated(&mut self, i: Importance, planned: &Planned) -> Result<KBuffer> {
        let (passes, px) = (self.passes, self.px);
        // The importance's word becomes k, then the slot bases.
        let base = i.importance.clone();
        let fb = &mut self.fb;
        let al = passes.allocation(
            fb,
            AllocBuffers {
                counts: &i.counts,
                weights: &base,
                totals: &i.totals,
                flags: i.marks.as_ref(),
            },
            i.kind,
        )?;
        // A readback copy of the importance (not counted, like the staging buffers), taken
        // before the allocation overwrites it with its fixed point; where no pass computed it
        // (k = n), zeros.
        if passes.opts.diagnostics && (i.computed || planned.host.is_some()) {
            let copy = fb.storage("importance.readback", 4 * px, false)?;
            if i.computed {
                fb.enc
                    .copy_buffer_to_buffer(&i.importance, 0, &copy, 0, 4 * px);
            } else {
                fb.enc.clear_buffer(&copy, 0, None);
            }
            self.out.importance_buf = Some(copy);
        }
        self.out.counts_buf = Some(i.counts.clone());
        let search = passes.allocate(fb, &al)?;
        self.out.variants.push(search);
        passes.prefix_sum_of(fb, Scan::InPlace(&base), None)?;
        let pool = match i.reuse.as_ref().and_then(|r| r.pool.clone()) {
            Some(pool) => pool,
            None => fb.storage("oit.slots", planned.input.pool_bytes, true)?,
        };
        // The plan's F and flags in the totals, its records a batch in the batch words (DKB's;
        // the others' plan writes 0 into the unused buffer it binds in their place).
        let batch = i.reuse.as_ref().map(|r| r.tail.clone());
        self.out.plan_buf = batch.map(|b| (i.totals.clone(), b));
        Ok(KBuffer {
            base,
            slots: SlotsAt::Pooled(pool),
            counts: i.counts,
            unused: i.reuse.map(|r| (r.tail, r.tail_count)),
            all_fit: planned.known_exact(),
        })
    }

    /// The capture and resolve into `kb`'s slots. With diagnostics, the slots, their bases and
    /// the tails are read back after the frame (five words a pixel, as `composite::capture`
    /// gives them).
    pub(super) fn capture_and_resolve(&mut self, s: Slots, kb: KBuffer) -> Result<()> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let b = self.slot_buffers(&kb)?;
        let fb = &mut self.fb;
        let status = fb.storage("status", FrameStatus::BYTES, true)?;
        // One pass with 64-bit atomics, or on a device without them (or asked for it) the
        // portable capture's two with 32-bit ones: the same slots and tails.
        let wide = (gpu.capture_for(passes.opts.capture) == Capture::Wide)
            .then_some(p.wide.as_ref())
            .flatten();
        // Where the host knows k = n everywhere, the pipelines built for it (the same slots,
        // tail and image).
        let fits = passes.opts.tuning.two_mode_capture
            && passes.opts.tuning.fits_pipelines
            && kb.all_fit
            && wide.is_some();
        let group = [&kb.base, &b.slots, &b.tail, &b.tail_count, &kb.counts];
        match wide {
            Some(w) => {
                let (phase, capture, variant) = match fits {
                    true => (
                        Phase::CaptureFits,
                        &w.capture_fits,
                        "capture: built for frames that fit",
                    ),
                    false => (Phase::Capture, &w.capture, "capture: general"),
                };
                self.out.variants.push(variant);
                passes.draw(fb.enc, phase, capture, &group, "capture");
            }
            None => {
                self.out.variants.push("capture: portable");
                let [depths, colours] = gpu.extras().portable_capture();
                let (d, c) = (Phase::CaptureDepths, Phase::CaptureColours);
                passes.draw(fb.enc, d, depths, &group, "capture depths");
                passes.draw(fb.enc, c, colours, &group, "capture colours");
            }
        }
        if b.tinted {
            // Its group: the bases, the slots (and the pooled tails), the per-pixel tails'
            // sums (for colours above white), the counts and the tints.
            let mut group = entries(&[&kb.base, &b.slots, &b.tail]);
            group.extend([
                at(bindings::capture::COUNT, &kb.counts),
                at(bindings::kbuffer_tint::OIT_TINTS, &b.tints),
            ]);
            let tint = gpu.extras().capture_tints(fits);
            passes.draw_group(fb.enc, Phase::CaptureTints, tint, group, "capture tints");
        }
        let (resolve, own) = (
            Resolve::KBuffer { fits },
            if fits { &p.resolve_fits } else { &p.resolve },
        );
        // With diagnostics, the cursors as the capture left them, before the resolve sorts
        // what the append mode spilled ([`super::GpuFrame::capture_counts`]): per pixel, the
        // tail counts (n where a pixel appended, what insertion pushed out where it inserted),
        // or with the tails pooled the counts (0 where a pixel appended, its cursor having
        // taken them down; n where it inserted).
        let pooled = matches!(kb.slots, SlotsAt::Pooled(_));
        let captured = match (passes.opts.diagnostics, pooled) {
            (false, _) => None,
            (true, true) => {
                let copy = fb.storage("oit.count.captured", count_bytes(px), false)?;
                fb.enc
                    .copy_buffer_to_buffer(&kb.counts, 0, &copy, 0, count_bytes(px));
                Some(copy)
            }
            (true, false) => {
                let copy = fb.storage("oit.tail_count.captured", 4 * px, false)?;
                fb.enc
                    .copy_buffer_to_buffer(&b.tail_count, 0, &copy, 0, 4 * px);
                Some(copy)
            }
        };
        let mut group = entries(&[passes.params(), &kb.base, &b.slots, &b.tail, &b.tail_count]);
        group.extend([
            at(bindings::resolve::COUNT, &kb.counts),
            at(bindings::resolve::STATUS, &status),
            at(bindings::resolve::TINTS, &b.tints),
        ]);
        passes.resolve(fb.enc, resolve, own, group, "resolve");
        self.out.status = Some(status);
        if passes.opts.diagnostics {
            self.read_slots_later(s, &kb, b, captured);
        }
        Ok(())
    }

    /// The buffers `kb`'s capture fills beside its bases and counts: the slots and the tail (sum
    /// c8 a8 for r, g, b and sum a8, 16 bytes a pixel, and its count) in buffers of their own,
    /// or pooled, the tails in the slots (cleared with them) and the tail buffers the shared
    /// layout binds unused; and where the frame stores tint words, the tint pass's words
    /// (kbuffer_tint.wgsl).
    fn slot_buffers(&mut self, kb: &KBuffer) -> Result<SlotBuffers> {
        let (px, fb) = (self.px, &mut self.fb);
        let (slots, tail, tail_count) = match (&kb.slots, &kb.unused) {
            (SlotsAt::Pooled(pool), Some((tail, tail_count))) => {
                // The pool made before (and used for other state until now), cleared.
                fb.enc.clear_buffer(pool, 0, None);
                (pool.clone(), tail.clone(), tail_count.clone())
            }
            (SlotsAt::Pooled(pool), None) => {
                fb.enc.clear_buffer(pool, 0, None);
                (
                    pool.clone(),
                    fb.storage("oit.unused_tail", crate::shared::LEAST_BUFFER_BYTES, true)?,
                    fb.storage(
                        "oit.unused_tail_count",
                        crate::shared::LEAST_BUFFER_BYTES,
                        true,
                    )?,
                )
            }
            (SlotsAt::PerPixel(n), _) => (
                fb.storage("oit.slots", 8 * n, true)?,
                fb.storage("oit.tail", 16 * px, true)?,
                fb.storage("oit.tail_count", 4 * px, true)?,
            ),
        };
        let (slot_words, pooled) = match &kb.slots {
            SlotsAt::Pooled(pool) => (pool.size() / crate::budget::SLOT_BYTES, true),
            SlotsAt::PerPixel(n) => (*n, false),
        };
        let words = crate::budget::kbuffer_tint_words(px, slot_words, pooled, self.words);
        let (tints, tinted) = fb.tints("oit", words, self.words.any())?;
        Ok(SlotBuffers {
            slots,
            tail,
            tail_count,
            tints,
            tinted,
        })
    }

    /// After the frame, `kb`'s slots, bases and tails read back as `composite::capture` gives
    /// them ([`super::GpuFrame::slots`]), and the cursors `captured` copied.
    fn read_slots_later(
        &mut self,
        s: Slots,
        kb: &KBuffer,
        b: SlotBuffers,
        captured: Option<wgpu::Buffer>,
    ) {
        let px = self.px;
        let base = kb.base.clone();
        let counts = kb.counts.clone();
        let layer_major = self.passes.opts.tuning.layer_major_fkb;
        let uniform = match s {
            Slots::Uniform(k) => Some(k.max(1)),
            _ => None,
        };
        let per_pixel = match kb.slots {
            SlotsAt::PerPixel(n) => Some(n),
            SlotsAt::Pooled(_) => None,
        };
        let SlotBuffers {
            slots,
            tail,
            tail_count,
            ..
        } = b;
        self.out.deferred.push(Box::new(move |gpu, out| {
            let Some(n) = per_pixel else {
                // Each pixel's k slots and its tail out of the pool, as composite::capture
                // gives them.
                let spans = u32s(&read_back(gpu, &base, 4 * (px + 1))?);
                let words = spans.last().map_or(0, |&w| w as u64);
                let pool = read_u64s(gpu, &slots, words)?;
                // n, as the resolve put it back.
                let counts = read_counts(gpu, &counts, px)?;
                if let Some(c) = &captured {
                    out.capture_counts = Some(read_counts(gpu, c, px)?);
                }
                out.slots = Some(unpool(&spans, &counts, &pool));
                return Ok(());
            };
            let bases = match uniform {
                Some(k) => (0..=px as u32).map(|q| q * k).collect(),
                None => u32s(&read_back(gpu, &base, 4 * (px + 1))?),
            };
            let sums = u32s(&read_back(gpu, &tail, 16 * px)?);
            let tail_counts = u32s(&read_back(gpu, &tail_count, 4 * px)?);
            let tails = sums
                .chunks_exact(4)
                .zip(tail_counts)
                .flat_map(|(s, c)| [s[0], s[1], s[2], s[3], c])
                .collect();
            let mut keys: Vec<u64> = read_u64s(gpu, &slots, n)?
                .into_iter()
                .map(slot_key)
                .collect();
            if let (Some(k), true) = (uniform, layer_major) {
                // Pixel-major, as composite::capture gives them.
                let (k, n) = (k as usize, px as usize);
                keys = (0..n * k).map(|q| keys[(q % k) * n + q / k]).collect();
            }
            out.slots = Some((keys, bases, tails));
            if let Some(c) = &captured {
                out.capture_counts = Some(u32s(&read_back(gpu, c, 4 * px)?));
            }
            Ok(())
        }));
    }
}

/// What a k-buffer's capture fills beside its bases and counts ([`Recording::slot_buffers`]).
struct SlotBuffers {
    slots: wgpu::Buffer,
    tail: wgpu::Buffer,
    tail_count: wgpu::Buffer,
    /// The tint pass's words, or an unused binding where the frame stores none (`tinted`
    /// false: grey glass, colours within white).
    tints: wgpu::Buffer,
    tinted: bool,
}

/// A slot's key as [`crate::fragment::fragment_key`] gives it, from the slot as stored: the
/// complement of its depth word high and its colour word low, the fragment's RGBA8 less 2^24
/// (common.wgsl's slot_colour_word); an empty (zero) slot reads `u64::MAX`.
pub(super) fn slot_key(stored: u64) -> u64 {
    if stored == 0 {
        u64::MAX
    } else {
        (!stored) + (1 << 24)
    }
}

/// A pooled k-buffer's pool (as stored: keys complemented; `spans`: the bases of each pixel's
/// span, `pixels + 1` entries; `counts`: n) as per-pixel buffers: the slots' keys
/// (pixel-major), their bases (prefix sums of k) and the tails (five words a pixel: sum c8 a8
/// for r, g, b, sum a8, the count n - k; zeros where a pixel keeps none).
fn unpool(spans: &[u32], counts: &[u32], pool: &[u64]) -> (Vec<u64>, Vec<u32>, Vec<u32>) {
    let px = spans.len().saturating_sub(1);
    let (mut keys, mut bases, mut tails) = (
        Vec::with_capacity(pool.len()),
        Vec::with_capacity(px + 1),
        Vec::with_capacity(5 * px),
    );
    bases.push(0);
    for (w, &n) in spans.windows(2).zip(counts) {
        let (at, span) = (w[0] as usize, w[1] - w[0]);
        let k = crate::shared::k_of_span(span, n) as usize;
        keys.extend(pool[at..at + k].iter().map(|&v| slot_key(v)));
        bases.push(bases.last().copied().unwrap_or(0) + k as u32);
        let t = if span < n {
            let t = &pool[at + k..at + k + crate::shared::TAIL_WORDS as usize];
            let lo = |w: u64| (w & 0xffff_ffff) as u32;
            [
                lo(t[0]),
                (t[0] >> 32) as u32,
                lo(t[1]),
                (t[1] >> 32) as u32,
                n - k as u32,
            ]
        } else {
            [0; 5]
        };
        tails.extend_from_slice(&t);
    }
    (keys, bases, tails)
}
