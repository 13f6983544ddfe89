//! The deep k-buffer's importance: the count (`abuffer_count.wgsl`), `totals.wgsl` and the
//! frame's plan (`plan.wgsl`: F within its pool, whether it keeps every fragment, the records a
//! batch), then `totals.wgsl`'s `assign_records` (a record for each pixel of more than
//! `shared::TAIL_WORDS` fragments, in the slot pool: a pixel of fewer keeps them all whatever
//! its k), `features.wgsl` (geometry: each record's nearest key, colour and opacity sums; twin
//! `importance::pixel_stats`), then `importance_dkb.wgsl` (the 12 features, never stored,
//! through the network of `mlp.wgsl`, built for the network's shape and precision by
//! [`Variant`]; twin `Mlp::dkb_importance`). Where the frame keeps every fragment none of the
//! records, features or network does anything (k = n whatever the importance); where its
//! client counted first and knows it, none of them is recorded.
//!
//! DKB's per-pixel state is the count, the shared word (`oit.offsets`: a pixel's record index,
//! its importance, the allocation's weights, k and the slot bases in turn); what only some
//! pixels need lives in the slot pool before the slots do: the records and the network's list
//! until the importance is gathered, the allocation's marks until k is known, then the slots
//! and the pooled tails. The pool is sized before the frame's count
//! ([`crate::budget::Layout::pool_bytes`] for the occupancy its client expects), and the plan
//! fits the frame into it.

use super::allocate::{Importance, Reuse, Word};
use super::bindings::{importance_dkb, mlp, totals};
use super::passes::Phase;
use super::pipelines;
use super::pipelines::Variant;
use super::{Planned, Recording, weight_kind};
use crate::error::Result;
use crate::mlp::Mlp;
use crate::shared::{BATCH_WORDS, TOTALS_WORDS, count_bytes};
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
    /// fragments, covered, max count, deep, records handed out, deeper, the plan's F and
    /// flags (totals.wgsl, plan.wgsl).
    totals: wgpu::Buffer,
    /// The shared word: record index, importance, weights, k, slot bases.
    importance: wgpu::Buffer,
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
        let p = &gpu.pipelines;
        let importance = self.pixel_word(Word::Written)?;
        let fb = &mut self.fb;
        let totals = fb.storage("features.totals", 4 * TOTALS_WORDS as u64, true)?;
        let counts = fb.storage("features.count", count_bytes(px), true)?;
        let list_len = fb.storage("importance.list_len", 4 * BATCH_WORDS as u64, true)?;
        let plan = fb.plan_params(&planned.input);
        passes.draw(fb.enc, Phase::Count, &p.count, &[&counts], "count");
        passes.totals_and_plan(fb.enc, &counts, &totals, Some((&plan, &list_len)))?;
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
        let b = DkbBuffers {
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
            list_len,
            dispatch,
        };
        // Where the client knows the frame keeps every fragment, k = n: no record, feature or
        // importance (the shared word the allocation reads as weights is ignored then).
        let drawn = !planned.known_exact();
        self.out.features_drawn = planned.host.map(|_| drawn);
        if drawn {
            let variant = |entry| Variant {
                shared_weights: self.passes.opts.tuning.shared_weights,
                unrolled: self.passes.opts.tuning.unrolled_network,
                entry,
                ..Variant::for_network("importance_dkb", mlp, self.passes.opts.tuning.skip_forced)
            };
            self.out.variants.push(variant("network").form());
            let network = ["select_pixels", "args", "network", "gather"]
                .map(|e| gpu.network_pass(variant(e)));
            let batches = planned.input.batches.max(1);
            // The records a batch holds: the plan's, where the host knows it; else the most the
            // pool can hold (the network's selection is dispatched over that many).
            let ps = planned
                .input
                .layout
                .pool_state
                .expect("DKB keeps its records in its pool");
            let most = (planned.input.pool_bytes / (ps.record_bytes + ps.list_bytes)).clamp(1, px);
            let per_batch = planned.host.map_or(most, |h| h.per_batch);
            let records = match self.sizing {
                super::Sizing::Own(occ) => occ.deeper,
                super::Sizing::Ahead { .. } => 0,
            };
            for batch in 0..batches {
                self.dkb_records_and_features(&b, records, (batch, per_batch))?;
                self.dkb_network(&b, per_batch, &network)?;
            }
            self.out.record_batches = Some(batches);
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

    /// The records (a pool index for each of the `records` pixels of more than TAIL_WORDS
    /// fragments) of batch `batch` (`per_batch` records each: [`budget::PoolState::batch`];
    /// the first assigns them all, the others empty theirs) and the features pass, and with
    /// diagnostics the copies of its statistics (not counted).
    fn dkb_records_and_features(
        &mut self,
        b: &DkbBuffers,
        records: u64,
        (batch, per_batch): (u64, u64),
    ) -> Result<()> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let (gx, gy) = grid(px as u32, PIXEL_GROUP);
        // The first batch assigns every record; each after it empties its own and moves the
        // batch on (totals.wgsl).
        // The records' index a pixel in the importance buffer, the records in the pool, the
        // batch in the list's length.
        let mut bound = vec![
            (totals::PARAMS, passes.params()),
            (totals::COUNT, &b.counts),
            (totals::RECORD_OF, &b.importance),
            (totals::RECORDS, &b.pool),
            (totals::BATCH, &b.list_len),
        ];
        let steps = match batch {
            0 => {
                bound.push((totals::TOTALS, &b.totals));
                vec![(&p.assign_records, bound, (gx, gy))]
            }
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
        let bufs = [&b.importance, &b.pool, &b.optical_depth, &b.list_len];
        // With the portable capture, or on a device without 64-bit atomics, in two passes with
        // 32-bit atomics alone (the same records).
        match (
            &gpu.pipelines.wide,
            gpu.capture_for(self.passes.opts.capture),
        ) {
            (Some(w), super::Capture::Wide) => {
                let features = match self.passes.opts.tuning.features_preload {
                    true => &w.features,
                    false => gpu.extras().features_no_preload(),
                };
                passes.draw(fb.enc, Phase::Features, features, &bufs, "features");
            }
            _ => {
                let [depths, colours] = gpu.extras().portable_features();
                let (d, c) = (Phase::FeaturesDepths, Phase::FeaturesColours);
                passes.draw(fb.enc, d, depths, &bufs, "features depths");
                passes.draw(fb.enc, c, colours, &bufs, "features colours");
            }
        }
        if self.passes.opts.diagnostics {
            // Every batch's records into one copy, where they would lie unbatched; the record
            // indices before the first batch's gather.
            let record_bytes = 8 * crate::shared::RECORD_WORDS as u64;
            let first = batch * per_batch;
            let these = per_batch.min(records - first);
            if batch == 0 {
                let record_of = fb.storage("features.record_of.readback", 4 * px, false)?;
                fb.enc
                    .copy_buffer_to_buffer(&b.importance, 0, &record_of, 0, 4 * px);
                let bytes = (record_bytes * records).max(crate::shared::LEAST_BUFFER_BYTES);
                let all = fb.storage("features.records.readback", bytes, false)?;
                self.out.stats_bufs = Some([record_of, all]);
            }
            if let Some([_, all]) = &self.out.stats_bufs {
                fb.enc.copy_buffer_to_buffer(
                    &b.pool,
                    0,
                    all,
                    record_bytes * first,
                    record_bytes * these,
                );
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
