//! The variable k-buffer's importance (paper 002): `vkb_count.wgsl` (geometry: the count and
//! the nearest fragment's depth and facing; twin `importance::nearest_facing`), `totals.wgsl`,
//! then `importance_vkb.wgsl` (twin `importance::vkb_importance_from`).

use super::*;

impl Recording<'_, '_> {
    /// VKB's count, totals and importance (left pending where the frame is expected to fit);
    /// its nearest keys, once read, hold the allocation's marks.
    pub(super) fn vkb_importance(&mut self, expect_fit: bool) -> Result<Importance> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let (fb, enc) = (&mut self.fb, &mut self.enc);
        let counts = fb.storage("vkb.count", 4 * px, true)?;
        let nearest = fb.storage("vkb.nearest", 8 * px, true)?;
        let totals = fb.storage("vkb.totals", 16, true)?;
        let importance = fb.storage("oit.importance", 4 * px, true)?;
        passes.draw(enc, &p.vkb_count, &[&counts, &nearest], "count");
        passes.dispatch(
            enc,
            &p.totals,
            &[passes.params(), &counts, &totals],
            "totals",
        );
        let group = gpu.bind(
            &p.importance_vkb.get_bind_group_layout(0),
            &[passes.params(), &counts, &nearest, &totals, &importance],
        );
        let (gx, gy) = grid(px as u32, PIXEL_GROUP);
        let importance_pass = PendingPass {
            name: "importance",
            steps: vec![(p.importance_vkb.clone(), group, Grid::Direct(gx, gy))],
        };
        let pending = passes.record_unless(enc, importance_pass, expect_fit);
        // The nearest keys are read: a copy for the frame's statistics (not counted), then the
        // buffer holds the allocation's marks.
        if gpu.diagnostics {
            let copy = fb.storage("vkb.nearest.readback", 8 * px, false)?;
            enc.copy_buffer_to_buffer(&nearest, 0, &copy, 0, 8 * px);
            self.out.vkb_nearest_buf = Some(copy);
        }
        Ok(Importance {
            counts,
            importance,
            totals,
            computed: true,
            kind: weight_kind(Target::RelativeK),
            marks: Some(nearest),
            reuse: None,
            pending,
        })
    }
}
