//! The variable k-buffer's importance (paper 002): `vkb_count.wgsl` (geometry: the count and
//! the nearest fragment's 32-bit key of depth and facing; twin `importance::nearest_facing`),
//! `totals.wgsl` and the frame's plan (`plan.wgsl`), then `importance_vkb.wgsl` (twin
//! `importance::vkb_importance_from`).

use super::allocate::{Importance, Reuse, Word};
use super::passes::Phase;
use super::{Planned, Recording, weight_kind};
use crate::alloc::Target;
use crate::error::Result;
use crate::shared::{TOTALS_WORDS, count_bytes};

impl Recording<'_, '_, '_> {
    /// VKB's count, totals, plan and importance (no importance where its client knows the
    /// frame keeps every fragment). Its nearest keys (`importance::vkb_nearest_key`) live in
    /// the frame's shared word a pixel, cleared before the count, until the importance pass
    /// reads each and writes the pixel's importance in its place; the allocation's marks (a
    /// quarter byte a pixel) have a buffer of their own, dead by the capture. The tails live
    /// in the slot pool (`Params::pooled_tail`), where the capture's layout binds the marks
    /// and a 16-byte buffer in the per-pixel tail's place, unused (the plan writes its batch
    /// words there, which VKB has none of).
    pub(super) fn vkb_importance(&mut self, planned: &Planned) -> Result<Importance> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let importance = self.pixel_word(Word::Written)?;
        let fb = &mut self.fb;
        let counts = fb.storage("vkb.count", count_bytes(px), true)?;
        // "None yet" in every pixel's word.
        fb.enc.clear_buffer(&importance, 0, None);
        let marks = fb.storage("vkb.marks", crate::budget::marks_bytes(px), true)?;
        let unused_tail = fb.storage("vkb.unused_tail", crate::shared::LEAST_BUFFER_BYTES, true)?;
        let totals = fb.storage("vkb.totals", 4 * TOTALS_WORDS as u64, true)?;
        let plan = fb.plan_params(&planned.input);
        passes.draw(
            fb.enc,
            Phase::VkbCount,
            &p.vkb_count,
            &[&counts, &importance],
            "count",
        );
        // A copy of the nearest keys for the frame's statistics (not counted), before the
        // importance takes their place.
        if passes.opts.diagnostics {
            let copy = fb.storage("vkb.nearest.readback", 4 * px, false)?;
            fb.enc
                .copy_buffer_to_buffer(&importance, 0, &copy, 0, 4 * px);
            self.out.vkb_nearest_buf = Some(copy);
        }
        passes.totals_and_plan(fb.enc, &counts, &totals, Some((&plan, &unused_tail)))?;
        let computed = !planned.known_exact();
        if computed {
            let bufs = [passes.params(), &counts, &importance, &totals];
            passes.dispatch(fb.enc, &p.importance_vkb, &bufs, "importance");
        }
        Ok(Importance {
            counts,
            importance,
            totals,
            computed,
            kind: weight_kind(Target::RelativeK),
            marks: Some(marks.clone()),
            reuse: Some(Reuse {
                tail: unused_tail,
                tail_count: marks,
                pool: None,
            }),
        })
    }
}
