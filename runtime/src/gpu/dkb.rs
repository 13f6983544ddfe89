//! The deep k-buffer's importance: the count (`abuffer_count.wgsl`), `totals.wgsl`, then
//! `features.wgsl` (geometry: nearest and two farthest keys, colour sums; twin
//! `importance::pixel_stats`), drawn only when the budget truncates (`totals.wgsl`'s
//! `features_draw` sets its indirect draw; or counting in the features pass, drawn always:
//! [`DkbGeometry`]), then `importance_dkb.wgsl` (the 12 features, never stored, through the
//! network of `mlp.wgsl`, built for the network's shape and precision by [`Variant`]; twin
//! `Mlp::dkb_importance`).

use super::*;

impl Recording<'_, '_> {
    /// DKB's features, totals and importance (the network's pass left pending where the frame
    /// is expected to fit); the features' buffers, once read, hold the tail and the image.
    pub(super) fn dkb_importance(&mut self, mlp: &Mlp, expect_fit: bool) -> Result<Importance> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let (fb, enc) = (&mut self.fb, &mut self.enc);
        let weights = fb.init(
            "mlp.weights",
            bytemuck::cast_slice(&mlp_uniform(mlp)),
            wgpu::BufferUsages::UNIFORM,
            true,
        );
        let counts = fb.storage("features.count", 4 * px, true)?;
        // The features pass's indirect draw: the frame's vertices, or none (below).
        let draw = fb.init(
            "features.draw",
            bytemuck::cast_slice(&[passes.vertices, 1, 0, 0]),
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
            true,
        );
        // The nearest key (8 bytes a pixel), then the tail's count; the two farthest keys (16),
        // then the tail's sums; the colour sums (16), then the image. No buffer above 16 bytes
        // a pixel, so a 4K frame fits 128 MiB bindings.
        let nearest = fb.storage("features.nearest", 8 * px, true)?;
        let farthest = fb.storage("features.farthest", 16 * px, true)?;
        let sums = fb.storage("features.color_sums", 16 * px, true)?;
        let totals = fb.storage("features.totals", 24, true)?;
        let importance = fb.storage("oit.importance", 4 * px, true)?;
        let count_first = match gpu.dkb_geometry {
            DkbGeometry::CountFirst => true,
            DkbGeometry::Counting => false,
            DkbGeometry::FollowLastFrame => !gpu
                .last_truncated
                .load(std::sync::atomic::Ordering::Relaxed),
        };
        if count_first {
            // Count, totals, and the features only where the budget truncates: when it holds
            // every fragment, k = n whatever the importance, and the draw has no vertex.
            passes.draw(enc, &p.count, &[&counts], "count");
            let sum = gpu.bind(
                &p.totals.get_bind_group_layout(0),
                &[passes.params(), &counts, &totals],
            );
            let args = gpu.bind_at(
                &p.features_draw.get_bind_group_layout(0),
                &[(0, passes.params()), (2, &totals), (3, &draw)],
            );
            passes.compute(enc, "totals", |pass| {
                pass.set_pipeline(&p.totals);
                pass.set_bind_group(0, &sum, &[]);
                let (gx, gy) = grid(px as u32, PIXEL_GROUP);
                pass.dispatch_workgroups(gx, gy, 1);
                pass.set_pipeline(&p.features_draw);
                pass.set_bind_group(0, &args, &[]);
                pass.dispatch_workgroups(1, 1, 1);
            });
            let features = if gpu.features_preload {
                &p.features
            } else {
                &p.features_no_preload
            };
            // The count is bound, not written (COUNT_FRAGMENTS is false).
            passes.draw_indirect(
                enc,
                features,
                &[&nearest, &farthest, &sums, &counts],
                "features",
                &draw,
            );
        } else {
            // One pass counts and gathers the features, drawn always: where the budget
            // truncates (as the last frame's did), one geometry pass fewer.
            passes.draw_indirect(
                enc,
                &p.features_counting,
                &[&nearest, &farthest, &sums, &counts],
                "features",
                &draw,
            );
            passes.dispatch(
                enc,
                &p.totals,
                &[passes.params(), &counts, &totals],
                "totals",
            );
        }
        // The pixels the network decides, listed in the allocation's marks buffer (dead until
        // the allocation), their count and the network's indirect dispatch.
        let list = fb.storage("alloc.flags", 4 * px, true)?;
        let list_len = fb.storage("importance.list_len", 16, true)?;
        let dispatch = fb.take(
            "importance.dispatch",
            16,
            wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::COPY_DST,
            true,
        );
        fb.allocated += 16;
        let entry = |entry| {
            gpu.network_pass(Variant {
                shared_weights: gpu.shared_weights,
                unrolled: gpu.unrolled_network,
                entry,
                ..Variant::for_network("importance_dkb", mlp, gpu.skip_forced)
            })
        };
        let (select, args, network) = (entry("select_pixels"), entry("args"), entry("network"));
        let bind = |dispatch_or_not: &wgpu::Buffer| {
            gpu.bind(
                &p.network_layout.group,
                &[
                    passes.params(),
                    &weights,
                    &counts,
                    &nearest,
                    &farthest,
                    &sums,
                    &totals,
                    &importance,
                    &list,
                    &list_len,
                    dispatch_or_not,
                ],
            )
        };
        // The network's dispatch reads `dispatch` as its arguments, so its group binds the
        // list's length (which that entry does not touch there) in its place.
        let (group, network_group) = (bind(&dispatch), bind(&list_len));
        let (gx, gy) = grid(px as u32, PIXEL_GROUP);
        let importance_pass = PendingPass {
            name: "importance",
            steps: vec![
                (select, group.clone(), Grid::Direct(gx, gy)),
                (args, group, Grid::Direct(1, 1)),
                (network, network_group, Grid::Indirect(dispatch)),
            ],
        };
        let pending = passes.record_unless(enc, importance_pass, expect_fit);
        // Copies for the frame's statistics (not counted), then the buffers serve the tail and
        // the image.
        if gpu.diagnostics {
            let mut copy = |b: &wgpu::Buffer, label: &str, bytes: u64| {
                let c = fb.storage(label, bytes * px, false)?;
                enc.copy_buffer_to_buffer(b, 0, &c, 0, bytes * px);
                Ok::<_, Error>(c)
            };
            self.out.stats_bufs = Some([
                copy(&nearest, "features.nearest.readback", 8)?,
                copy(&farthest, "features.farthest.readback", 16)?,
                copy(&sums, "features.color_sums.readback", 16)?,
            ]);
            self.out.features_draw_buf = Some(draw.clone());
        }
        Ok(Importance {
            counts,
            importance,
            totals,
            computed: true,
            kind: weight_kind(mlp.target),
            marks: Some(list),
            reuse: Some(Reuse {
                tail: farthest,
                tail_count: nearest,
                image: sums,
            }),
            pending,
        })
    }
}
