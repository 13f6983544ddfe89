//! The deep k-buffer's importance: the count with the network's statistics
//! (`features.wgsl` with `features_count.wgsl`), `totals.wgsl` and the frame's plan
//! (`plan.wgsl`: F within its pool, whether it keeps every fragment, the records a batch), the
//! records' counts (`totals.wgsl`'s `record_counts`), then `importance_dkb.wgsl` (the 12
//! features, never stored, through the network of `mlp.wgsl`, built for the network's shape and
//! precision by [`Variant`]; twin `Mlp::dkb_importance`). Where the frame keeps every fragment
//! none of the records, features or network does anything (k = n whatever the importance);
//! where its client counted first and knows it, none of them is recorded.
//!
//! A record (RECORD_WORDS words in the slot pool) is each pixel of more than
//! `shared::TAIL_WORDS` fragments that its record marks mark (`totals.wgsl`'s `mark_records`,
//! `records.wgsl`; a pixel of fewer keeps them all whatever its k). Two ways to a frame's
//! statistics:
//!
//! - **With the count** (two geometry passes, the count and the capture): where the frame's
//!   client carried valid marks from the frame before ([`super::Carried`]), the count gathers the
//!   statistics of the pixels they mark, as many as the pool holds
//!   ([`super::Tuning::two_pass_dkb`]); a pixel they leave out (deeper now than then, or past
//!   the pool) gets the least weight. The frame then marks its own pixels for the frame after.
//! - **In a features pass** (three geometry passes: a frame's first, one after a cut, one whose
//!   records take batches): the frame marks its own pixels after its count and draws
//!   `features.wgsl` for them, once a batch of records.
//!
//! DKB's per-pixel state is the count, the shared word (`oit.offsets`: a pixel's importance, the
//! allocation's weights, k and the slot bases in turn) and the record marks (a bit a pixel);
//! what only some pixels need lives in the slot pool before the slots do: the records and the
//! network's list until the importance is gathered, the allocation's marks until k is known,
//! then the slots and the pooled tails. The pool is sized before the frame's count
//! ([`crate::budget::Layout::pool_bytes`] for the occupancy its client expects), and the plan
//! fits the frame into it.

use super::allocate::{Importance, Reuse, Word};
use super::bindings::{
    features, features_batch, features_count, importance_dkb, mlp, scan, totals,
};
use super::passes::Phase;
use super::pipelines;
use super::pipelines::Variant;
use super::{Planned, Recording, weight_kind};
use crate::error::Result;
use crate::mlp::Mlp;
use crate::shared::{BATCH_WORDS, TOTAL_RECORDS, TOTALS_WORDS, count_bytes, mark_blocks};
use crate::wgsl::{DISPATCH_WORDS, PIXEL_GROUP, grid, mlp_uniform};

/// DKB's per-frame buffers.
#[derive(Clone)]
struct DkbBuffers {
    weights: wgpu::Buffer,
    counts: wgpu::Buffer,
    /// The records, the marks, then the slots and tails.
    pool: wgpu::Buffer,
    /// The optical depth of each 8-bit opacity (importance::optical_depth_table).
    optical_depth: wgpu::Buffer,
    /// fragments, covered, max count, deep, records marked, deeper, the plan's F and flags
    /// (totals.wgsl, plan.wgsl).
    totals: wgpu::Buffer,
    /// The shared word: importance, weights, k, slot bases.
    importance: wgpu::Buffer,
    /// Which pixel has which record (records.wgsl): the frame before's or this frame's.
    marks: wgpu::Buffer,
    /// The length of the list of the records the network decides (in the pool, after the
    /// records: one word a record), the batch's first record, the records a batch holds (the
    /// plan's) and the rows the batches before ran (totals.wgsl's `batch`).
    list_len: wgpu::Buffer,
    /// The network's dispatch.
    dispatch: wgpu::Buffer,
}

impl Recording<'_, '_, '_> {
    /// DKB's count, totals and plan, then its records, features and importance in the batches
    /// the frame's client sized its pool for (none where it knows the frame keeps every
    /// fragment).
    pub(super) fn dkb_importance(&mut self, mlp: &Mlp, planned: &Planned) -> Result<Importance> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        gpu.can_run(mlp)?;
        let carried = self.carried.clone();
        let b = self.dkb_buffers(mlp, planned, carried.as_ref())?;
        let plan = self.fb.plan_params(&planned.input);
        // The records whose statistics the count gathers (the frame's parameters hold the
        // same: Gpu::record_frame), or none: the frame marks its own and draws a features pass.
        let with_count = planned.gathered_with_count(&passes.opts, carried.as_ref());
        self.dkb_count(&b);
        passes.totals(self.fb.enc, &b.counts, &b.totals);
        // Where the client knows the frame keeps every fragment, k = n: no record, feature or
        // importance (the shared word the allocation reads as weights is ignored then).
        let drawn = !planned.known_exact();
        if drawn && with_count == 0 {
            self.mark_records(&b)?;
        }
        // The records the marks mark, for the plan and the network.
        let total_at = 4 * mark_blocks(px);
        self.fb.enc.copy_buffer_to_buffer(
            &b.marks,
            total_at,
            &b.totals,
            4 * TOTAL_RECORDS as u64,
            4,
        );
        passes.plan(self.fb.enc, &b.totals, &plan, &b.list_len);
        self.out.features_drawn = planned.host.map(|_| drawn);
        if drawn {
            self.dkb_batches(&b, mlp, planned, with_count, carried.is_some())?;
        }
        let variant = if self.passes.opts.tuning.features_preload {
            "features: preload"
        } else {
            "features: no preload"
        };
        self.out.variants.push(variant);
        Ok(Importance {
            counts: b.counts,
            importance: b.importance,
            totals: b.totals,
            computed: drawn,
            kind: weight_kind(mlp.target),
            // The allocation's marks in the pool, the records gathered by then.
            marks: Some(b.pool.clone()),
            // The capture's shared layout binds a per-pixel tail, unused where the tails are
            // pooled: two small buffers dead by the capture.
            reuse: Some(Reuse {
                tail: b.list_len,
                tail_count: b.dispatch,
                pool: Some(b.pool),
            }),
        })
    }

    /// DKB's buffers for a frame: the count, totals, batch list and dispatch, the record marks
    /// (the client's `carried` from the frame before, or the frame's own: DKB's memory either
    /// way), the pool, the network's weights and the optical depths' table.
    fn dkb_buffers(
        &mut self,
        mlp: &Mlp,
        planned: &Planned,
        carried: Option<&super::Carried>,
    ) -> Result<DkbBuffers> {
        let px = self.px;
        let importance = self.pixel_word(Word::Written)?;
        let fb = &mut self.fb;
        let totals = fb.storage("features.totals", 4 * TOTALS_WORDS as u64, true)?;
        let counts = fb.storage("features.count", count_bytes(px), true)?;
        let list_len = fb.storage("importance.list_len", 4 * BATCH_WORDS as u64, true)?;
        // The record marks: the client's, carried from the frame before (and left for the frame
        // after), or the frame's own; DKB's memory either way.
        let marks_bytes = crate::budget::marks_bytes(px);
        let marks = match carried {
            Some(c) => {
                fb.allocated += marks_bytes;
                c.marks.clone()
            }
            None => fb.storage("dkb.record_marks", marks_bytes, true)?,
        };
        let pool = fb.storage("oit.slots", planned.input.pool_bytes, true)?;
        let args = 4 * DISPATCH_WORDS as u64;
        let dispatch = fb.take(
            "importance.dispatch",
            args,
            wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::COPY_DST,
            true,
        );
        fb.allocated += args;
        Ok(DkbBuffers {
            weights: fb.init(
                "mlp.weights",
                bytemuck::cast_slice(&mlp_uniform(mlp)),
                wgpu::BufferUsages::UNIFORM,
                true,
            ),
            counts,
            pool,
            optical_depth: fb.init(
                "features.optical_depth",
                bytemuck::cast_slice(&crate::importance::optical_depth_table()),
                wgpu::BufferUsages::UNIFORM,
                true,
            ),
            totals,
            importance,
            marks,
            list_len,
            dispatch,
        })
    }

    /// DKB's records, features and network, batch after batch (as many as the frame's pool
    /// needs), then the marks the frame after gathers with its count where this frame gathered
    /// `with_count` records with its own (`carried`: the client keeps its marks).
    fn dkb_batches(
        &mut self,
        b: &DkbBuffers,
        mlp: &Mlp,
        planned: &Planned,
        with_count: u64,
        carried: bool,
    ) -> Result<()> {
        let (gpu, px) = (self.passes.gpu, self.px);
        let variant = |entry| Variant {
            shared_weights: self.passes.opts.tuning.shared_weights,
            unrolled: self.passes.opts.tuning.unrolled_network,
            entry,
            ..Variant::for_network("importance_dkb", mlp, self.passes.opts.tuning.skip_forced)
        };
        self.out.variants.push(variant("network").form());
        self.out.variants.push(match with_count {
            0 => "dkb statistics: a features pass",
            _ => "dkb statistics: with the count",
        });
        let network =
            ["select_pixels", "args", "network", "gather"].map(|e| gpu.network_pass(variant(e)));
        let batches = planned.input.batches.max(1);
        // The records a batch holds: the plan's, where the host knows it; else the most the
        // pool can hold (the network's selection is dispatched over that many).
        let per_batch = planned
            .host
            .map_or(planned.records_held(px), |h| h.per_batch);
        for batch in 0..batches {
            self.dkb_records_and_features(b, (batch, per_batch, batches), with_count > 0)?;
            self.dkb_network(b, per_batch, &network)?;
        }
        // The marks the frame after gathers with its count: this frame's, where it gathered
        // with the frame before's.
        if with_count > 0 {
            self.mark_records(b)?;
        }
        self.marked = carried;
        self.out.record_batches = Some(batches);
        Ok(())
    }

    /// DKB's count pass: each pixel's fragments counted, and the statistics of the records the
    /// frame's parameters say (`Params::dkb_records`: those the frame before marked, or none).
    fn dkb_count(&mut self, b: &DkbBuffers) {
        let pipeline = &self.passes.gpu.pipelines.count_features;
        let phase = Phase::CountFeatures;
        let group = vec![
            super::passes::at(features::RECORD_MARKS, &b.marks),
            super::passes::at(features::RECORDS, &b.pool),
            super::passes::at(features::OPTICAL_DEPTH, &b.optical_depth),
            super::passes::at(features_count::COUNTS, &b.counts),
        ];
        self.passes
            .draw_group(self.fb.enc, phase, pipeline, group, "count");
    }

    /// The frame's record marks from its count ([`Gpu::mark_records`]), in a pass of its own.
    fn mark_records(&mut self, b: &DkbBuffers) -> Result<()> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let blocks = self.fb.scan_blocks(px)?;
        let params = passes.params();
        let record = gpu.mark_records(params, &b.counts, &b.marks, &blocks, px);
        passes.compute(self.fb.enc, "record marks", record);
        Ok(())
    }
}

impl Recording<'_, '_, '_> {
    /// The records of batch `batch` of `batches` (`per_batch` records each:
    /// [`crate::budget::PoolState::batch`];
    /// the first's n written beside its statistics, the others emptied) and, unless the count
    /// gathered them (`with_count`), the features pass over them; with diagnostics the copies
    /// of the marks and the records (not counted).
    fn dkb_records_and_features(
        &mut self,
        b: &DkbBuffers,
        (batch, per_batch, batches): (u64, u64, u64),
        with_count: bool,
    ) -> Result<()> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let (gx, gy) = grid(px as u32, PIXEL_GROUP);
        let bound = vec![
            (totals::PARAMS, passes.params()),
            (totals::COUNT, &b.counts),
            (totals::RECORD_MARKS, &b.marks),
            (totals::RECORDS, &b.pool),
            (totals::BATCH, &b.list_len),
        ];
        // The first batch's counts beside its statistics; each batch after it empties its own
        // and moves the batch on.
        let steps = match batch {
            0 => vec![(&p.record_counts, bound, (gx, gy))],
            _ => vec![
                (&p.init_records, bound, (gx, gy)),
                (&p.next_batch, vec![(totals::BATCH, &b.list_len)], (1, 1)),
            ],
        };
        let steps: Vec<_> = steps
            .into_iter()
            .map(|(pipeline, bound, grid)| {
                let group = gpu.bind_at(&pipeline.get_bind_group_layout(0), &bound);
                (pipeline, group, grid)
            })
            .collect();
        passes.compute(self.fb.enc, "records", |pass| {
            for (pipeline, group, (x, y)) in &steps {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, group, &[]);
                pass.dispatch_workgroups(*x, *y, 1);
            }
        });
        let fb = &mut self.fb;
        if !with_count {
            let group = vec![
                super::passes::at(features::RECORD_MARKS, &b.marks),
                super::passes::at(features::RECORDS, &b.pool),
                super::passes::at(features::OPTICAL_DEPTH, &b.optical_depth),
                super::passes::at(features_batch::BATCH, &b.list_len),
            ];
            let features = match self.passes.opts.tuning.features_preload {
                true => &p.features,
                false => gpu.extras().features_no_preload(),
            };
            passes.draw_group(fb.enc, Phase::Features, features, group, "features");
        }
        if self.passes.opts.diagnostics {
            // Every batch's records into one copy, where they would lie unbatched; the marks
            // that place them, before the frame marks its own for the frame after.
            let record_bytes = 8 * crate::shared::RECORD_WORDS as u64;
            let first = batch * per_batch;
            if batch == 0 {
                let bytes = crate::budget::marks_bytes(px);
                let marks = fb.storage("features.record_marks.readback", bytes, false)?;
                fb.enc.copy_buffer_to_buffer(&b.marks, 0, &marks, 0, bytes);
                // As many records as its batches hold.
                let bytes = record_bytes * (per_batch * batches).min(px);
                let all = fb.storage("features.records.readback", bytes, false)?;
                self.out.stats_bufs = Some([marks, all]);
            }
            if let Some([_, all]) = &self.out.stats_bufs {
                let room = all.size() / record_bytes;
                let these = per_batch.min(room.saturating_sub(first));
                let bytes = (record_bytes * these).min(b.pool.size() / record_bytes * record_bytes);
                fb.enc
                    .copy_buffer_to_buffer(&b.pool, 0, all, record_bytes * first, bytes);
            }
        }
        Ok(())
    }

    /// The network's pass over a batch of `records` records, its importance gathered into the
    /// shared word.
    fn dkb_network(
        &mut self,
        b: &DkbBuffers,
        records: u64,
        [select, args, network, gather]: &[wgpu::ComputePipeline; 4],
    ) -> Result<()> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let (gx, gy) = grid(px as u32, PIXEL_GROUP);
        let (rx, ry) = grid(records.max(1) as u32, PIXEL_GROUP);
        let bind = |dispatch_or_not: &wgpu::Buffer| {
            gpu.bind_at(
                &p.network_layout.group,
                &[
                    (importance_dkb::PARAMS, passes.params()),
                    (mlp::WEIGHTS, &b.weights),
                    // The records, and the list after them.
                    (importance_dkb::RECORDS, &b.pool),
                    (importance_dkb::TOTALS, &b.totals),
                    (importance_dkb::SHARED_WORD, &b.importance),
                    (importance_dkb::RECORD_MARKS, &b.marks),
                    (importance_dkb::COUNT, &b.counts),
                    (importance_dkb::LIST_LEN, &b.list_len),
                    (importance_dkb::DISPATCH, dispatch_or_not),
                    (pipelines::WEIGHTS_H, &b.weights),
                ],
            )
        };
        // The network's dispatch reads `dispatch` as its arguments, so its group binds the
        // device's placeholder (which that entry does not touch) in its place.
        let (group, network_group) = (bind(&b.dispatch), bind(&p.placeholder));
        passes.compute(self.fb.enc, "importance", |pass| {
            pass.set_bind_group(0, &group, &[]);
            pass.set_pipeline(select);
            pass.dispatch_workgroups(rx, ry, 1);
            pass.set_pipeline(args);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(network);
            pass.set_bind_group(0, &network_group, &[]);
            pass.dispatch_workgroups_indirect(&b.dispatch, 0);
            pass.set_pipeline(gather);
            pass.dispatch_workgroups(gx, gy, 1);
        });
        if self.passes.opts.diagnostics {
            let fb = &mut self.fb;
            let bytes = 4 * BATCH_WORDS as u64;
            let copy = fb.storage("importance.list_len.readback", bytes, false)?;
            fb.enc
                .copy_buffer_to_buffer(&b.list_len, 0, &copy, 0, bytes);
            self.out.network_rows_buf = Some(copy);
        }
        Ok(())
    }
}

impl super::Gpu {
    /// DKB's record marks of a frame of `px` pixels from its `counts` into `marks`
    /// (`budget::marks_bytes`): a bit for each pixel of more than TAIL_WORDS fragments
    /// (totals.wgsl's mark_records), then their words' prefix sums and total in place (scan.wgsl
    /// built for marks, `blocks` its block totals), as a compute pass's dispatches. The twin:
    /// `importance::record_marks`.
    pub(super) fn mark_records(
        &self,
        params: &wgpu::Buffer,
        counts: &wgpu::Buffer,
        marks: &wgpu::Buffer,
        blocks: &wgpu::Buffer,
        px: u64,
    ) -> impl FnOnce(&mut wgpu::ComputePass) + use<> {
        let p = &self.pipelines;
        let mark = self.bind_at(
            &p.mark_records.get_bind_group_layout(0),
            &[
                (totals::PARAMS, params),
                (totals::COUNT, counts),
                (totals::RECORD_MARKS, marks),
            ],
        );
        let scan = p.scan_marks.clone().map(|pl| {
            let g = self.bind_at(
                &pl.get_bind_group_layout(0),
                &[
                    (scan::PARAMS, params),
                    (scan::OFFSETS, marks),
                    (scan::BLOCKS, blocks),
                ],
            );
            (pl, g)
        });
        let mark_pipeline = p.mark_records.clone();
        let (gx, gy) = grid(px as u32, PIXEL_GROUP);
        let (bx, by) = grid(mark_blocks(px) as u32, crate::shared::SCAN_BLOCK as u32);
        move |pass| {
            pass.set_pipeline(&mark_pipeline);
            pass.set_bind_group(0, &mark, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
            // The marks' scan: each block, the blocks' totals, the add.
            for (i, (pl, g)) in scan.iter().enumerate() {
                pass.set_pipeline(pl);
                pass.set_bind_group(0, g, &[]);
                match i {
                    1 => pass.dispatch_workgroups(1, 1, 1),
                    _ => pass.dispatch_workgroups(bx, by, 1),
                }
            }
        }
    }
}
