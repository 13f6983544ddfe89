//! The exclusive prefix sum (`scan.wgsl`: per-block scans, the block totals' scan, the add),
//! for the A-buffer's offsets and the k-buffer's slot bases; the twin is a running sum
//! (`FragmentLists::offsets`, `alloc` tests).

use super::bindings::scan;
use super::buffers::FrameBuffers;
use super::passes::Passes;
use crate::budget;
use crate::error::Result;
use crate::wgsl::grid;

/// What a prefix sum reads and writes.
#[derive(Clone, Copy)]
pub(super) enum Scan<'b> {
    /// `values` into `offsets` (`pixels + 1` entries).
    From(&'b wgpu::Buffer, &'b wgpu::Buffer),
    /// The buffer's own values, in place (`scan_blocks_in_place`); its last entry gets the total
    /// where it holds `pixels + 1`.
    InPlace(&'b wgpu::Buffer),
    /// The allocation's marks (`shared::marks_words`): the popcounts of their words, one every
    /// `MARK_BITS` pixels, in place, and their total after them.
    Marks(&'b wgpu::Buffer),
}

impl<'a> Passes<'a> {
    /// Exclusive prefix sum of `values` into `offsets` (pixels + 1 entries): three dispatches
    /// with a block-total buffer of one u32 per [`budget::SCAN_BLOCK`] pixels.
    pub(super) fn prefix_sum(
        &self,
        fb: &mut FrameBuffers<'_, '_>,
        values: &wgpu::Buffer,
        offsets: &wgpu::Buffer,
    ) -> Result<()> {
        self.prefix_sum_of(fb, Scan::From(values, offsets), None)
    }

    /// The prefix sum `scan` says, with its per-block dispatches' grid read from `args` at an
    /// offset where given (the device may empty it: then only the block totals' scan runs, over
    /// stale totals, and the offsets are left undefined).
    pub(super) fn prefix_sum_of(
        &self,
        fb: &mut FrameBuffers<'_, '_>,
        scan: Scan,
        args: Option<(&wgpu::Buffer, u64)>,
    ) -> Result<()> {
        let p = &self.gpu.pipelines;
        let px = self.pixels;
        let blocks = fb.scan_blocks(px as u64)?;
        let params = self.params();
        let [marks_first, marks_sums, marks_add] = &p.scan_marks;
        let (values, offsets, [first, sums, add], len) = match scan {
            Scan::From(v, o) => (Some(v), o, [&p.scan_blocks, &p.scan_sums, &p.scan_add], px),
            Scan::InPlace(o) => (
                None,
                o,
                [&p.scan_blocks_in_place, &p.scan_sums, &p.scan_add],
                px,
            ),
            Scan::Marks(o) => (
                None,
                o,
                [marks_first, marks_sums, marks_add],
                crate::shared::mark_blocks(px as u64) as u32,
            ),
        };
        // Auto layouts keep only the bindings an entry point uses: `values` only the first
        // entry's, where it reads another buffer.
        let bind = |pl: &wgpu::ComputePipeline, first: bool| {
            let mut entries = vec![
                (scan::PARAMS, params),
                (scan::OFFSETS, offsets),
                (scan::BLOCKS, &blocks),
            ];
            if let (true, Some(v)) = (first, values) {
                entries.push((scan::VALUES, v));
            }
            self.gpu.bind_at(&pl.get_bind_group_layout(0), &entries)
        };
        let (gx, gy) = grid(len, budget::SCAN_BLOCK as u32);
        self.compute(fb.enc, "prefix sum", |pass| {
            // (pipeline, over every block, the first)
            for (pl, per_block, is_first) in [
                (first, true, true),
                (sums, false, false),
                (add, true, false),
            ] {
                let g = bind(pl, is_first);
                pass.set_pipeline(pl);
                pass.set_bind_group(0, &g, &[]);
                match (per_block, args) {
                    (true, Some((args, at))) => pass.dispatch_workgroups_indirect(args, at),
                    (true, None) => pass.dispatch_workgroups(gx, gy, 1),
                    (false, _) => pass.dispatch_workgroups(1, 1, 1),
                }
            }
        });
        Ok(())
    }
}
