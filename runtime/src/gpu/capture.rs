//! The k-buffer: k for every pixel (one for all, uploaded, or allocated on the device:
//! `allocate.rs`), the slot bases (`scan.wgsl`), then `capture.wgsl` (geometry: the two-mode
//! capture, append or Loop64 insertion; twin `composite::capture`) and `resolve.wgsl` (the
//! slots front to back over the tail's approximation; twin `composite::hybrid_sorted`).

use super::allocate::{AllocBuffers, Importance, Reuse, Word};
use super::buffers::{
    FrameBuffers, FrameStatus, read_back, read_counts, read_u64s, read_words, u32s,
};
use super::scan::Scan;
use super::{Recording, Slots};
use crate::budget::FragmentBudget;
use crate::error::{Error, Result};
use crate::shared::count_bytes;

/// A frame's k: per pixel, its slot bases (`pixels + 1` entries: k is their difference, not
/// stored) and how many slots in all, and n(p) where the frame counted it (the two-mode capture
/// reads it; else an unused buffer).
pub(super) struct KBuffer {
    pub(super) base: wgpu::Buffer,
    pub(super) slots: u64,
    pub(super) counts: wgpu::Buffer,
    pub(super) reuse: Option<Reuse>,
    /// Whether the budget holds every fragment the frame counted (then k = n everywhere).
    pub(super) all_fit: bool,
    /// Whether the tails live in the slot pool (`Params::pooled_tail`: the bases are the
    /// prefix sums of each pixel's span, `shared::span`, and `slots` counts the tails' words).
    pub(super) pooled: bool,
}

impl Recording<'_, '_> {
    /// k as `s` gives it: FKB's uniform k, an uploaded k, or the allocation of the importance
    /// the frame computes (DKB, VKB) or is given.
    pub(super) fn k_for(&mut self, s: Slots, budget: FragmentBudget) -> Result<KBuffer> {
        let (passes, px) = (self.passes, self.px);
        match s {
            Slots::Uniform(k) => {
                // FKB reads none of these, but the shared capture layout binds them.
                let fb = &mut self.fb;
                Ok(KBuffer {
                    base: fb.storage("fkb.unused_offsets", 16, true)?,
                    slots: k.max(1) as u64 * px,
                    counts: fb.storage("fkb.unused_counts", 16, true)?,
                    reuse: None,
                    all_fit: false,
                    pooled: false,
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
                passes.prefix_sum_of(&mut self.enc, fb, Scan::InPlace(&base), None)?;
                Ok(KBuffer {
                    base,
                    slots: k.iter().map(|&x| x as u64).sum(),
                    counts: fb.storage("oit.unused_counts", 16, true)?,
                    reuse: None,
                    all_fit: false,
                    pooled: false,
                })
            }
            Slots::Importance(imp, target, _) => {
                let expect_fit = self.expect_fit();
                let i = self.uploaded_importance(imp, target, expect_fit)?;
                self.allocated(i, budget, expect_fit)
            }
            Slots::Vkb(..) => {
                let budget = self.vkb_budget(budget)?;
                let expect_fit = self.expect_fit();
                let i = self.vkb_importance(expect_fit)?;
                self.allocated(i, budget, expect_fit)
            }
            Slots::Dkb(mlp, _) => {
                // DKB reads its count back first (its pool is sized from it).
                let (i, budget) = self.dkb_importance(mlp, budget)?;
                let fits = i.fits;
                self.allocated(i, budget, fits)
            }
            Slots::Mlab(_) | Slots::Wboit(_) | Slots::Mboit(_) | Slots::LinkedList { .. } => {
                unreachable!("MLAB, WBOIT, MBOIT and the linked list have passes of their own")
            }
        }
    }

    /// Whether this frame is recorded as one whose budget holds every fragment
    /// ([`FrameOptions::predict_fit`]: as the renderer's last allocated frame's did).
    fn expect_fit(&self) -> bool {
        let gpu = self.passes.gpu;
        // A frame that counted first knows it truncates (else it rendered the A-buffer).
        self.counted.is_none()
            && self.passes.opts.predict_fit
            && !gpu
                .last_truncated
                .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// The allocation of `i` at `budget`, its slot bases, and the slot count read back (the
    /// slots buffer is sized from it). A frame expected to fit has recorded its count alone:
    /// k = n, so the bases are the count's prefix sum and its last entry says whether the
    /// budget holds every fragment. Where it does not (and in every other frame), the passes
    /// left pending, the allocation (the device empties its search where every fragment fits)
    /// and the prefix sum of k, in another submission.
    pub(super) fn allocated(
        &mut self,
        mut i: Importance,
        budget: FragmentBudget,
        expect_fit: bool,
    ) -> Result<KBuffer> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        // The importance's word becomes k, then the slot bases (the count's prefix sums'
        // buffer where the frame counted first: Recording::pixel_word).
        self.counted = None;
        let base = i.importance.clone();
        let al = passes.allocation(
            &mut self.fb,
            AllocBuffers {
                counts: &i.counts,
                weights: &base,
                totals: &i.totals,
                flags: i.marks.as_ref(),
            },
            budget,
            i.kind,
        )?;
        // A readback copy of the importance (not counted, like the staging buffers), taken
        // before the allocation overwrites it with its fixed point; where no pass computed it
        // (k = n), it stays zero.
        let copy_importance = |fb: &mut FrameBuffers, enc: &mut wgpu::CommandEncoder| {
            if !(self.passes.opts.diagnostics && i.computed) {
                return Ok::<_, Error>(None);
            }
            let copy = fb.storage("importance.readback", 4 * px, false)?;
            enc.copy_buffer_to_buffer(&i.importance, 0, &copy, 0, 4 * px);
            Ok(Some(copy))
        };
        self.out.counts_buf = Some(i.counts.clone());
        if expect_fit {
            let (fb, enc) = (&mut self.fb, &mut self.enc);
            // The frame's fragments, read back from its totals (a frame that knows it fits, DKB
            // having read its count back, holds them there already; the others total their
            // count now). Where the budget holds them, the count's prefix sum is the slot bases
            // (k = n everywhere: a pixel keeping all its fragments has no tail, its span is n),
            // ending in the pool's words, the frame's fragments. The sum waits for that check:
            // it takes the word that holds what the importance pass reads (VKB's nearest keys).
            if !i.fits {
                passes.totals(enc, &i.counts, &i.totals);
            }
            fb.submit(enc);
            let words = read_words(gpu, &[(&i.totals, 0)])?[0] as u64;
            if i.fits || budget.holds(words) {
                passes.prefix_sum(enc, fb, &i.counts, &base)?;
                // No pass computed the importance (k = n): it reads back as zeros.
                if self.passes.opts.diagnostics && i.computed {
                    self.out.importance_buf =
                        Some(fb.storage("importance.readback", 4 * px, false)?);
                }
                gpu.last_truncated
                    .store(false, std::sync::atomic::Ordering::Relaxed);
                return Ok(KBuffer {
                    base,
                    slots: words,
                    counts: i.counts,
                    reuse: i.reuse,
                    all_fit: true,
                    pooled: true,
                });
            }
            // Expected to fit, truncated: the rest after all, whose totals start from zero.
            enc.clear_buffer(&i.totals, 0, None);
        }
        if let Some(rest) = i.pending.take() {
            rest(self)?;
        }
        let (fb, enc) = (&mut self.fb, &mut self.enc);
        self.out.importance_buf = copy_importance(fb, enc)?;
        let search = passes.allocate(enc, fb, &al)?;
        self.out.variants.push(search);
        passes.prefix_sum_of(enc, fb, Scan::InPlace(&base), None)?;
        fb.submit(enc);
        // The pool's words (the bases' last entry: slots and tails) and the frame's fragments,
        // without reading back the bases.
        let words = read_words(gpu, &[(&base, 4 * px), (&i.totals, 0)])?;
        let (slots, fragments) = (words[0] as u64, words[1] as u64);
        let all_fit = budget.holds(fragments);
        gpu.last_truncated
            .store(!all_fit, std::sync::atomic::Ordering::Relaxed);
        Ok(KBuffer {
            base,
            slots,
            counts: i.counts,
            reuse: i.reuse,
            all_fit,
            pooled: true,
        })
    }

    /// The capture and resolve into `k`'s slots; returns the image buffer. With diagnostics,
    /// the slots, their bases and the tails are read back (five words a pixel, as
    /// `composite::capture` gives them).
    pub(super) fn capture_and_resolve(&mut self, s: Slots, kb: KBuffer) -> Result<wgpu::Buffer> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let (fb, enc) = (&mut self.fb, &mut self.enc);
        // The pool made before (and used for other state until now), cleared, or made here.
        let slots = match kb.reuse.as_ref().and_then(|r| r.pool.clone()) {
            Some(pool) => {
                enc.clear_buffer(&pool, 0, None);
                pool
            }
            None => fb.storage("oit.slots", 8 * kb.slots, true)?,
        };
        let status = fb.storage("status", FrameStatus::BYTES, true)?;
        // The tail: sum c8 a8 for r, g, b and sum a8 (16 bytes a pixel), and its count; and the
        // image: their own buffers, or DKB's features once read.
        // Pooled, the tails are in the slots (cleared with them), and the tail buffers the
        // shared layout binds are unused.
        let (tail, tail_count, image) = match (kb.reuse, kb.pooled) {
            (Some(r), true) => (r.tail, r.tail_count, r.image),
            (Some(r), false) => {
                // The tail starts from zero.
                enc.clear_buffer(&r.tail, 0, None);
                enc.clear_buffer(&r.tail_count, 0, None);
                (r.tail, r.tail_count, r.image)
            }
            (None, true) => (
                fb.storage("oit.unused_tail", 16, true)?,
                fb.storage("oit.unused_tail_count", 16, true)?,
                fb.storage("application.image", 16 * px, false)?,
            ),
            (None, false) => (
                fb.storage("oit.tail", 16 * px, true)?,
                fb.storage("oit.tail_count", 4 * px, true)?,
                fb.storage("application.image", 16 * px, false)?,
            ),
        };
        // Where k = n everywhere, the pipelines built for it (the same slots, tail and image).
        let (capture, resolve) =
            if self.passes.opts.two_mode_capture && self.passes.opts.fits_pipelines && kb.all_fit {
                self.out.variants.push("capture: built for frames that fit");
                (&p.capture_fits, &p.resolve_fits)
            } else {
                self.out.variants.push("capture: general");
                (&p.capture, &p.resolve)
            };
        passes.draw(
            enc,
            capture,
            &[&kb.base, &slots, &tail, &tail_count, &kb.counts],
            "capture",
        );
        // With diagnostics, the cursors as the capture left them, before the resolve sorts
        // what the append mode spilled ([`GpuFrame::capture_counts`]): per pixel, the tail
        // counts (n where a pixel appended, what insertion pushed out where it inserted), or
        // with the tails pooled the counts (0 where a pixel appended, its cursor having taken
        // them down; n where it inserted).
        let captured = match (self.passes.opts.diagnostics, kb.pooled) {
            (false, _) => None,
            (true, true) => {
                let copy = fb.storage("oit.count.captured", count_bytes(px), false)?;
                enc.copy_buffer_to_buffer(&kb.counts, 0, &copy, 0, count_bytes(px));
                Some(copy)
            }
            (true, false) => {
                let copy = fb.storage("oit.tail_count.captured", 4 * px, false)?;
                enc.copy_buffer_to_buffer(&tail_count, 0, &copy, 0, 4 * px);
                Some(copy)
            }
        };
        passes.resolve(
            enc,
            resolve,
            &[
                passes.params(),
                &kb.base,
                &slots,
                &tail,
                &tail_count,
                &image,
                &kb.counts,
                &status,
            ],
            5,
            "resolve",
        );
        fb.submit(enc);
        self.out.status = Some(status);
        if self.passes.opts.diagnostics && kb.pooled {
            // Each pixel's k slots and its tail out of the pool, as composite::capture gives them.
            let spans = u32s(&read_back(gpu, &kb.base, 4 * (px + 1))?);
            let pool = read_u64s(gpu, &slots, kb.slots, false)?;
            // n, as the resolve put it back.
            let counts = read_counts(gpu, &kb.counts, px)?;
            if let Some(c) = &captured {
                self.out.capture_counts = Some(read_counts(gpu, c, px)?);
            }
            self.out.slots = Some(unpool(&spans, &counts, &pool));
        } else if self.passes.opts.diagnostics {
            let bases = match s {
                Slots::Uniform(k) => (0..=px as u32).map(|q| q * k.max(1)).collect(),
                _ => u32s(&read_back(gpu, &kb.base, 4 * (px + 1))?),
            };
            let sums = u32s(&read_back(gpu, &tail, 16 * px)?);
            let counts = u32s(&read_back(gpu, &tail_count, 4 * px)?);
            let tails = sums
                .chunks_exact(4)
                .zip(counts)
                .flat_map(|(s, c)| [s[0], s[1], s[2], s[3], c])
                .collect();
            let mut keys = read_u64s(gpu, &slots, kb.slots, true)?;
            if let (Slots::Uniform(k), true) = (s, self.passes.opts.layer_major_fkb) {
                // Pixel-major, as composite::capture gives them.
                let (k, n) = (k.max(1) as usize, px as usize);
                keys = (0..n * k).map(|q| keys[(q % k) * n + q / k]).collect();
            }
            self.out.slots = Some((keys, bases, tails));
            if let Some(c) = &captured {
                self.out.capture_counts = Some(u32s(&read_back(gpu, c, 4 * px)?));
            }
        }
        Ok(image)
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
        // Slots hold complemented keys.
        keys.extend(pool[at..at + k].iter().map(|&v| !v));
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
