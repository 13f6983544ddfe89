//! The variable k-buffer's importance (paper 002): `vkb_count.wgsl` (geometry: the count and
//! the nearest fragment's 32-bit key of depth and facing; twin `importance::nearest_facing`), `totals.wgsl`,
//! then `importance_vkb.wgsl` (twin `importance::vkb_importance_from`).

use super::allocate::{Importance, Reuse, Word, pending, record_unless};
use super::{Recording, weight_kind};
use crate::alloc::Target;
use crate::budget::FragmentBudget;
use crate::error::Result;
use crate::shared::count_bytes;

impl Recording<'_, '_> {
    /// VKB's budget: `budget`, or with [`super::FrameOptions::counted_bytes`] the most slots
    /// those bytes hold for the frame's own occupancy, which it counts first where it has not
    /// (exact_when_cheaper counts first).
    pub(super) fn vkb_budget(&mut self, budget: FragmentBudget) -> Result<FragmentBudget> {
        if self.passes.opts.counted_bytes.is_none() {
            return Ok(budget);
        }
        if self.counted.is_none() {
            self.counted = Some(self.count(true)?);
        }
        let occ = self
            .counted
            .as_ref()
            .and_then(|c| c.occupancy.as_ref())
            .expect("counted with its occupancy")
            .0;
        self.counted_budget(&crate::budget::VKB, budget, &occ)
    }

    /// VKB's count, then totals and importance (left pending where the frame is expected to fit).
    /// Its nearest keys (`importance::vkb_nearest_key`) live in the frame's shared word a
    /// pixel, cleared before the count, until the importance pass reads each and writes the
    /// pixel's importance in its place; the allocation's marks (a quarter byte a pixel) have a
    /// buffer of their own, dead by the capture. The tails live in the slot pool
    /// (`Params::pooled_tail`), where the capture's layout binds the marks and a 16-byte buffer
    /// in the per-pixel tail's place, unused.
    pub(super) fn vkb_importance(&mut self, expect_fit: bool) -> Result<Importance> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let importance = self.pixel_word(Word::Written)?;
        let (fb, enc) = (&mut self.fb, &mut self.enc);
        // The frame's count where it counted first, counted again here with the nearest
        // fragment (vkb_count.wgsl adds to it).
        let counts = match &self.counted {
            Some(c) => {
                enc.clear_buffer(&c.counts, 0, None);
                c.counts.clone()
            }
            None => fb.storage("vkb.count", count_bytes(px), true)?,
        };
        // "None yet" in every pixel's word (the count's prefix sums where it counted first,
        // read by now).
        enc.clear_buffer(&importance, 0, None);
        let tail_count = fb.storage("vkb.marks", crate::budget::marks_bytes(px), true)?;
        let unused_tail = fb.storage("vkb.unused_tail", 16, true)?;
        // The application's target where it gives one: counted for no method.
        let image = fb.storage("application.image", 16 * px, false)?;
        let totals = fb.storage("vkb.totals", 16, true)?;
        passes.draw(enc, &p.vkb_count, &[&counts, &importance], "count");
        let [c, t, i] = [&counts, &totals, &importance].map(|b| b.clone());
        let rest = pending(move |rec| {
            let (passes, p, enc) = (rec.passes, &rec.passes.gpu.pipelines, &mut rec.enc);
            passes.totals(enc, &c, &t);
            let bufs = [passes.params(), &c, &i, &t];
            passes.dispatch(enc, &p.importance_vkb, &bufs, "importance");
            Ok(())
        });
        // A copy of the nearest keys for the frame's statistics (not counted), before the
        // importance takes their place.
        if self.passes.opts.diagnostics {
            let copy = fb.storage("vkb.nearest.readback", 4 * px, false)?;
            enc.copy_buffer_to_buffer(&importance, 0, &copy, 0, 4 * px);
            self.out.vkb_nearest_buf = Some(copy);
        }
        let pending = record_unless(self, rest, expect_fit)?;
        Ok(Importance {
            counts,
            importance,
            totals,
            computed: true,
            kind: weight_kind(Target::RelativeK),
            marks: Some(tail_count.clone()),
            reuse: Some(Reuse {
                tail: unused_tail,
                tail_count,
                image,
                pool: None,
            }),
            pending,
            fits: false,
        })
    }
}
