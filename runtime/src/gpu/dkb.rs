//! The deep k-buffer's importance: the count (`abuffer_count.wgsl`), `totals.wgsl`, then
//! `features.wgsl` (geometry: nearest and two farthest keys, colour sums; twin
//! `importance::pixel_stats`), drawn only when the budget truncates (`totals.wgsl`'s
//! `features_draw` sets its indirect draw; or counting in the features pass, drawn always:
//! [`DkbGeometry`], its count packed in the colour sums and written out by `totals.wgsl`'s
//! `from_sums`), then `importance_dkb.wgsl` (the 12 features, never stored, through the
//! network of `mlp.wgsl`, built for the network's shape and precision by [`Variant`]; twin
//! `Mlp::dkb_importance`). A frame expected to fit ([`FrameOptions::predict_fit`]) records the count
//! alone and leaves the rest to [`Recording::allocated`], which records it only where the
//! budget truncates.

use super::allocate::{Importance, Reuse, Word, pending, record_unless};
use super::pipelines::Variant;
use super::{DkbGeometry, Recording, weight_kind};
use crate::error::{Error, Result};
use crate::mlp::Mlp;
use crate::wgsl::{DISPATCH_WORDS, PIXEL_GROUP, grid, mlp_uniform};

/// DKB's per-frame buffers.
#[derive(Clone)]
struct DkbBuffers {
    weights: wgpu::Buffer,
    counts: wgpu::Buffer,
    /// The features pass's indirect draw.
    draw: wgpu::Buffer,
    nearest: wgpu::Buffer,
    farthest: wgpu::Buffer,
    sums: wgpu::Buffer,
    /// The optical depth of each 8-bit opacity (importance::optical_depth_table).
    optical_depth: wgpu::Buffer,
    /// Per pixel the sums of optical depth and opacity.
    opacity: wgpu::Buffer,
    totals: wgpu::Buffer,
    importance: wgpu::Buffer,
    list_len: wgpu::Buffer,
    dispatch: wgpu::Buffer,
}

impl Recording<'_, '_> {
    /// DKB's count (or the features pass counting), then its totals, features and importance,
    /// left pending where the frame is expected to fit (k = n needs none of them). The
    /// features' buffers, once read, hold the tail and the image.
    pub(super) fn dkb_importance(&mut self, mlp: &Mlp, expect_fit: bool) -> Result<Importance> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        gpu.can_run(mlp)?;
        let p = &gpu.pipelines;
        let importance = self.pixel_word(Word::Written)?;
        let fb = &mut self.fb;
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
            // The frame's count where it counted first.
            counts: match &self.counted {
                Some(c) => c.counts.clone(),
                None => fb.storage("features.count", 4 * px, true)?,
            },
            // The frame's transparent indices, or none (totals.wgsl's features_draw).
            draw: fb.init(
                "features.draw",
                bytemuck::cast_slice(&[passes.vertices, 1, 0, 0, 0]),
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
                true,
            ),
            // The nearest key (8 bytes a pixel), then the tail's count; the two farthest keys
            // (16), then the tail's sums; the colour sums (16), then the image; the opacity
            // sums (8). No buffer above 16 bytes a pixel, so a 4K frame fits 128 MiB bindings.
            nearest: fb.storage("features.nearest", 8 * px, true)?,
            farthest: fb.storage("features.farthest", 16 * px, true)?,
            sums: fb.storage("features.color_sums", 16 * px, true)?,
            opacity: fb.storage("features.opacity", 8 * px, true)?,
            optical_depth: fb.init(
                "features.optical_depth",
                bytemuck::cast_slice(&crate::importance::optical_depth_table()),
                wgpu::BufferUsages::UNIFORM,
                true,
            ),
            totals: fb.storage("features.totals", 24, true)?,
            importance,
            list_len: fb.storage("importance.list_len", 16, true)?,
            dispatch,
        };
        let counted = self.counted.is_some();
        let count_first = counted
            || match self.passes.opts.dkb_geometry {
                DkbGeometry::CountFirst => true,
                DkbGeometry::Counting => false,
                DkbGeometry::FollowLastFrame => !gpu
                    .last_truncated
                    .load(std::sync::atomic::Ordering::Relaxed),
            };
        let (features, variant) = if !count_first {
            (&p.features_counting, "features: counting")
        } else if self.passes.opts.features_preload {
            (&p.features, "features: preload")
        } else {
            (&p.features_no_preload, "features: no preload")
        };
        let features = features.clone();
        self.out.variants.push(variant);
        if count_first {
            if !counted {
                passes.draw(&mut self.enc, &p.count, &[&b.counts], "count");
            }
            // Drawn, if at all, with the rest (where the frame is not expected to fit); once
            // recorded, its draw's arguments say whether it drew.
            self.out.features_drawn = Some(false);
        } else {
            // One pass counts and gathers the features, drawn always: where the budget
            // truncates (as the last frame's did), one geometry pass fewer. Its count goes
            // out of the sums (and into the totals) at once, for a frame expected to fit.
            self.dkb_features(&b, &features)?;
            passes.totals_from_sums(&mut self.enc, &b.sums, &b.counts, &b.totals);
        }
        let variant = |entry| Variant {
            shared_weights: self.passes.opts.shared_weights,
            unrolled: self.passes.opts.unrolled_network,
            entry,
            ..Variant::for_network("importance_dkb", mlp, self.passes.opts.skip_forced)
        };
        self.out.variants.push(variant("network").form());
        let network =
            ["select_pixels", "args", "network", "gather"].map(|e| gpu.network_pass(variant(e)));
        let bufs = b.clone();
        let rest = pending(move |rec| rec.dkb_rest(&bufs, count_first, &features, &network));
        let pending = record_unless(self, rest, expect_fit)?;
        Ok(Importance {
            counts: b.counts,
            importance: b.importance,
            totals: b.totals,
            computed: true,
            kind: weight_kind(mlp.target),
            // The nearest keys, where the importance waited, are dead once gathered.
            marks: Some(b.nearest.clone()),
            reuse: Some(Reuse {
                tail: b.farthest,
                tail_count: b.nearest,
                image: b.sums,
            }),
            pending,
        })
    }

    /// The features pass (drawn indirectly), and with diagnostics the copies of its statistics
    /// (not counted; the buffers then serve the tail and the image).
    fn dkb_features(&mut self, b: &DkbBuffers, features: &wgpu::RenderPipeline) -> Result<()> {
        let (passes, px) = (self.passes, self.px);
        let (fb, enc) = (&mut self.fb, &mut self.enc);
        // Where the pass counts (COUNT_FRAGMENTS), n goes in the sums (totals.wgsl's from_sums).
        let bufs = [
            &b.nearest,
            &b.farthest,
            &b.sums,
            &b.optical_depth,
            &b.opacity,
        ];
        passes.draw_indirect(enc, features, &bufs, "features", &b.draw);
        if self.passes.opts.diagnostics {
            let mut copy = |b: &wgpu::Buffer, label: &str, bytes: u64| {
                let c = fb.storage(label, bytes * px, false)?;
                enc.copy_buffer_to_buffer(b, 0, &c, 0, bytes * px);
                Ok::<_, Error>(c)
            };
            self.out.stats_bufs = Some([
                copy(&b.nearest, "features.nearest.readback", 8)?,
                copy(&b.farthest, "features.farthest.readback", 16)?,
                copy(&b.sums, "features.color_sums.readback", 16)?,
                copy(&b.opacity, "features.opacity.readback", 8)?,
            ]);
            self.out.features_draw_buf = Some(b.draw.clone());
        }
        Ok(())
    }

    /// After DKB's count: where the count came first, the totals and the features (drawn only
    /// where the budget truncates: when it holds every fragment, k = n whatever the importance,
    /// and `features_draw` empties the draw); then the network's pass.
    fn dkb_rest(
        &mut self,
        b: &DkbBuffers,
        count_first: bool,
        features: &wgpu::RenderPipeline,
        [select, args, network, gather]: &[wgpu::ComputePipeline; 4],
    ) -> Result<()> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let (gx, gy) = grid(px as u32, PIXEL_GROUP);
        if count_first {
            let sum = gpu.bind(
                &p.totals.get_bind_group_layout(0),
                &[passes.params(), &b.counts, &b.totals],
            );
            let draw_args = gpu.bind_at(
                &p.features_draw.get_bind_group_layout(0),
                &[(0, passes.params()), (2, &b.totals), (3, &b.draw)],
            );
            passes.compute(&mut self.enc, "totals", |pass| {
                pass.set_pipeline(&p.totals);
                pass.set_bind_group(0, &sum, &[]);
                pass.dispatch_workgroups(gx, gy, 1);
                pass.set_pipeline(&p.features_draw);
                pass.set_bind_group(0, &draw_args, &[]);
                pass.dispatch_workgroups(1, 1, 1);
            });
            self.dkb_features(b, features)?;
        }
        // The list, then the importance, in the frame's shared word (binding 8).
        let bind = |dispatch_or_not: &wgpu::Buffer| {
            gpu.bind_at(
                &p.network_layout.group,
                &[
                    (0, passes.params()),
                    (1, &b.weights),
                    (2, &b.counts),
                    (3, &b.nearest),
                    (4, &b.farthest),
                    (5, &b.sums),
                    (6, &b.totals),
                    (8, &b.importance),
                    (9, &b.list_len),
                    (10, dispatch_or_not),
                    (11, &b.weights),
                    (12, &b.opacity),
                ],
            )
        };
        // The network's dispatch reads `dispatch` as its arguments, so its group binds the
        // list's length (which that entry does not touch there) in its place.
        let (group, network_group) = (bind(&b.dispatch), bind(&b.list_len));
        passes.compute(&mut self.enc, "importance", |pass| {
            pass.set_bind_group(0, &group, &[]);
            pass.set_pipeline(select);
            pass.dispatch_workgroups(gx, gy, 1);
            pass.set_pipeline(args);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(network);
            pass.set_bind_group(0, &network_group, &[]);
            pass.dispatch_workgroups_indirect(&b.dispatch, 0);
            pass.set_pipeline(gather);
            pass.dispatch_workgroups(gx, gy, 1);
        });
        if self.passes.opts.diagnostics {
            let copy = self.fb.storage("importance.list_len.readback", 16, false)?;
            self.enc.copy_buffer_to_buffer(&b.list_len, 0, &copy, 0, 16);
            self.out.network_rows_buf = Some(copy);
        }
        Ok(())
    }
}
