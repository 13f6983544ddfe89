//! Recording a pass: a geometry pass over every triangle or a per-pixel compute dispatch, with
//! the frame's shared bindings and timestamps.

use super::allocated::AppGeometry;
use super::timer::Timer;
use super::{FrameInputs, FrameOptions, Gpu};
use crate::wgsl::{PIXEL_GROUP, grid};

/// The frame's shared bindings and the pass timer: every pass is one call.
pub(super) struct Passes<'a> {
    pub(super) gpu: &'a Gpu,
    /// How the frame lays out its passes and what it reads back.
    pub(super) opts: FrameOptions,
    pub(super) timer: &'a Timer<'a>,
    pub(super) inputs: &'a FrameInputs,
    /// The opaque pass's depth, as the transparent passes read it; its colour, as the
    /// resolves do; its depth and colour as its attachments.
    opaque_depth: wgpu::TextureView,
    opaque_color: wgpu::TextureView,
    /// The indices of the transparent triangles (the vertices every transparent pass draws).
    pub(super) vertices: u32,
    pub(super) pixels: u32,
    /// An application's frame ([`super::AllocatedOit`]): its draws in place of dhoit's geometry
    /// passes, and its target in place of the image.
    app: Option<&'a dyn AppGeometry>,
}

impl<'a> Passes<'a> {
    pub(super) fn new(
        gpu: &'a Gpu,
        timer: &'a Timer<'a>,
        inputs: &'a FrameInputs,
        opts: FrameOptions,
        app: Option<&'a dyn AppGeometry>,
    ) -> Self {
        Passes {
            gpu,
            opts,
            timer,
            inputs,
            opaque_depth: inputs.opaque_depth.create_view(&Default::default()),
            opaque_color: inputs.opaque_color.create_view(&Default::default()),
            vertices: inputs.transparent,
            pixels: inputs.pixels,
            app,
        }
    }

    /// The frame's parameter uniform (binding 0 of every pass).
    pub(super) fn params(&self) -> &'a wgpu::Buffer {
        &self.inputs.params
    }

    /// Group 0 of a geometry pass (geometry.wgsl): params, the scene's buffers, the sRGB
    /// table, and for a transparent pass the opaque depth.
    fn geometry_group(&self, layout: &wgpu::BindGroupLayout, transparent: bool) -> wgpu::BindGroup {
        let i = self.inputs;
        let buffers: Vec<&wgpu::Buffer> = std::iter::once(&i.params).chain(&i.scene).collect();
        let depth = wgpu::BindGroupEntry {
            binding: 8,
            resource: wgpu::BindingResource::TextureView(&self.opaque_depth),
        };
        let extra = if transparent { vec![depth] } else { Vec::new() };
        self.gpu.bind_with(layout, &buffers, extra)
    }

    /// The application's opaque pass (opaque.wgsl): its opaque triangles into the depth and
    /// colour targets, cleared first (to 1 and 0; where the scene has none, that is all).
    pub(super) fn opaque(&self, enc: &mut wgpu::CommandEncoder) {
        let pipeline = &self.gpu.pipelines.opaque;
        let g0 = self.geometry_group(&pipeline.get_bind_group_layout(0), false);
        let depth = self.inputs.opaque_depth.create_view(&Default::default());
        let color = self.inputs.opaque_color.create_view(&Default::default());
        let color_ops = wgpu::Operations {
            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
            store: wgpu::StoreOp::Store,
        };
        let depth = wgpu::RenderPassDepthStencilAttachment {
            view: &depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        };
        let mut pass = self.render_pass(enc, "opaque", &[(&color, color_ops)], Some(depth));
        let i = self.inputs;
        if i.opaque > 0 {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &g0, &[]);
            pass.set_index_buffer(i.index.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(i.transparent..i.transparent + i.opaque, 0, 0..1);
        }
    }

    /// A timed render pass of its colour attachments and, where given, a depth attachment.
    fn render_pass<'e>(
        &self,
        enc: &'e mut wgpu::CommandEncoder,
        name: &'static str,
        colors: &[(&wgpu::TextureView, wgpu::Operations<wgpu::Color>)],
        depth: Option<wgpu::RenderPassDepthStencilAttachment>,
    ) -> wgpu::RenderPass<'e> {
        let (b, e) = self.timer.next(name);
        let colors: Vec<Option<wgpu::RenderPassColorAttachment>> = colors
            .iter()
            .map(|&(view, ops)| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops,
                })
            })
            .collect();
        enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(name),
            color_attachments: &colors,
            depth_stencil_attachment: depth,
            timestamp_writes: Some(wgpu::RenderPassTimestampWrites {
                query_set: self.timer.set(),
                beginning_of_pass_write_index: Some(b),
                end_of_pass_write_index: Some(e),
            }),
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// A geometry pass over every triangle, `buffers` bound as group 1.
    pub(super) fn draw(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        buffers: &[&wgpu::Buffer],
        name: &'static str,
    ) {
        self.geometry_pass(enc, pipeline, buffers, name);
    }

    fn geometry_pass(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        buffers: &[&wgpu::Buffer],
        name: &'static str,
    ) {
        if let Some(app) = self.app {
            // The application draws (always: its draw counts are its own).
            let (b, e) = self.timer.next(name);
            let timestamps = wgpu::RenderPassTimestampWrites {
                query_set: self.timer.set(),
                beginning_of_pass_write_index: Some(b),
                end_of_pass_write_index: Some(e),
            };
            app.draw(self.gpu, enc, pipeline, buffers, self.params(), timestamps);
            return;
        }
        let g0 = self.geometry_group(&pipeline.get_bind_group_layout(0), true);
        let g1 = self.gpu.bind(&pipeline.get_bind_group_layout(1), buffers);
        // The opaque depth, read-only, is the pass's one attachment (no colour is written).
        let depth = wgpu::RenderPassDepthStencilAttachment {
            view: &self.opaque_depth,
            depth_ops: None,
            stencil_ops: None,
        };
        let mut pass = self.render_pass(enc, name, &[], Some(depth));
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &g0, &[]);
        pass.set_bind_group(1, &g1, &[]);
        pass.set_index_buffer(self.inputs.index.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.vertices, 0, 0..1);
    }

    /// A blended method's geometry pass (gpu::blend) over every transparent triangle: its
    /// targets cleared to the given colours and kept, `group` (where the pass has one) as
    /// group 1.
    pub(super) fn blend(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        group: Option<&wgpu::BindGroup>,
        targets: &[(&wgpu::TextureView, wgpu::Color)],
        name: &'static str,
    ) {
        let g0 = self.geometry_group(&pipeline.get_bind_group_layout(0), true);
        let colors: Vec<_> = targets
            .iter()
            .map(|&(view, clear)| {
                let ops = wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    store: wgpu::StoreOp::Store,
                };
                (view, ops)
            })
            .collect();
        let mut pass = self.render_pass(enc, name, &colors, None);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &g0, &[]);
        if let Some(g) = group {
            pass.set_bind_group(1, g, &[]);
        }
        pass.set_index_buffer(self.inputs.index.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.vertices, 0, 0..1);
    }

    /// A blended method's composite (blend_composite.wgsl): `targets` read at bindings 2 and 3,
    /// composited over the opaque pass's colour (binding 15) into `image` (binding 1).
    pub(super) fn composite(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        image: &wgpu::Buffer,
        targets: [&wgpu::TextureView; 2],
        name: &'static str,
    ) {
        let view = |binding, view| wgpu::BindGroupEntry {
            binding,
            resource: wgpu::BindingResource::TextureView(view),
        };
        let extra = vec![
            view(2, targets[0]),
            view(3, targets[1]),
            view(15, &self.opaque_color),
        ];
        let g = self.gpu.bind_with(
            &pipeline.get_bind_group_layout(0),
            &[self.params(), image],
            extra,
        );
        self.dispatch_group(enc, pipeline, &g, name);
    }

    /// A resolve (behind.wgsl): [`Passes::dispatch`] with the opaque pass's colour at binding
    /// 15, what the resolve composites over. In an application's frame, the resolve's `onto`
    /// entry over the application's image onto its target instead, without the image
    /// (`buffers[image_at]`).
    pub(super) fn resolve(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
        image_at: usize,
        name: &'static str,
    ) {
        if let Some(app) = self.app {
            let (gx, gy) = grid(self.pixels, PIXEL_GROUP);
            self.compute(enc, name, |pass| {
                app.resolve(self.gpu, pass, pipeline, buffers, image_at, (gx, gy))
            });
            return;
        }
        let opaque = wgpu::BindGroupEntry {
            binding: 15,
            resource: wgpu::BindingResource::TextureView(&self.opaque_color),
        };
        let g = self
            .gpu
            .bind_with(&pipeline.get_bind_group_layout(0), buffers, vec![opaque]);
        self.dispatch_group(enc, pipeline, &g, name);
    }

    /// A per-pixel compute pass with its group 0.
    fn dispatch_group(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        group: &wgpu::BindGroup,
        name: &'static str,
    ) {
        let (gx, gy) = grid(self.pixels, PIXEL_GROUP);
        self.compute(enc, name, |pass| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        });
    }

    /// A timed compute pass `record` fills (several dispatches, one timestamp pair).
    pub(super) fn compute(
        &self,
        enc: &mut wgpu::CommandEncoder,
        name: &'static str,
        record: impl FnOnce(&mut wgpu::ComputePass),
    ) {
        let (b, e) = self.timer.next(name);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(name),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: self.timer.set(),
                beginning_of_pass_write_index: Some(b),
                end_of_pass_write_index: Some(e),
            }),
        });
        record(&mut pass);
    }

    /// A compute pass, `buffers` bound as group 0 in binding order.
    pub(super) fn dispatch(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
        name: &'static str,
    ) {
        // Every dispatched pass is per pixel.
        let g = self.gpu.bind(&pipeline.get_bind_group_layout(0), buffers);
        self.dispatch_group(enc, pipeline, &g, name);
    }

    /// The totals pass (totals.wgsl): the frame's fragments, covered pixels and largest count
    /// from `counts` into `totals`.
    pub(super) fn totals(
        &self,
        enc: &mut wgpu::CommandEncoder,
        counts: &wgpu::Buffer,
        totals: &wgpu::Buffer,
    ) {
        let pipeline = &self.gpu.pipelines.totals;
        self.dispatch(enc, pipeline, &[self.params(), counts, totals], "totals");
    }
}
