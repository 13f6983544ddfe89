//! Recording a pass: a geometry pass over every triangle or a per-pixel compute dispatch, with
//! the frame's shared bindings and timestamps.

use super::*;

/// The frame's shared bindings and the pass timer: every pass is one call.
pub(super) struct Passes<'a> {
    pub(super) gpu: &'a Gpu,
    pub(super) timer: &'a Timer<'a>,
    /// params, positions, colours: group 0 of every geometry pass.
    pub(super) geometry: [&'a wgpu::Buffer; 3],
    pub(super) target: &'a wgpu::TextureView,
    pub(super) vertices: u32,
    pub(super) pixels: u32,
}

impl<'a> Passes<'a> {
    pub(super) fn new(gpu: &'a Gpu, timer: &'a Timer<'a>, inputs: &'a FrameInputs) -> Self {
        Passes {
            gpu,
            timer,
            geometry: [&inputs.params, &inputs.positions, &inputs.colors],
            target: &inputs.target,
            vertices: inputs.vertices,
            pixels: inputs.pixels,
        }
    }

    /// The frame's parameter uniform (binding 0 of every pass).
    pub(super) fn params(&self) -> &'a wgpu::Buffer {
        self.geometry[0]
    }

    /// A geometry pass over every triangle, `buffers` bound as group 1.
    pub(super) fn draw(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        buffers: &[&wgpu::Buffer],
        name: &'static str,
    ) {
        self.geometry_pass(enc, pipeline, buffers, name, None);
    }

    /// [`Passes::draw`] with its vertex count (all of the frame's, or none) read from `args`
    /// (four words: vertices, instances, first vertex, first instance) on the device.
    pub(super) fn draw_indirect(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        buffers: &[&wgpu::Buffer],
        name: &'static str,
        args: &wgpu::Buffer,
    ) {
        self.geometry_pass(enc, pipeline, buffers, name, Some(args));
    }

    fn geometry_pass(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        buffers: &[&wgpu::Buffer],
        name: &'static str,
        indirect: Option<&wgpu::Buffer>,
    ) {
        let g0 = self
            .gpu
            .bind(&pipeline.get_bind_group_layout(0), &self.geometry);
        let g1 = self.gpu.bind(&pipeline.get_bind_group_layout(1), buffers);
        let (b, e) = self.timer.next(name);
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(name),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: self.target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Discard,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: Some(wgpu::RenderPassTimestampWrites {
                query_set: self.timer.set(),
                beginning_of_pass_write_index: Some(b),
                end_of_pass_write_index: Some(e),
            }),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &g0, &[]);
        pass.set_bind_group(1, &g1, &[]);
        match indirect {
            Some(args) => pass.draw_indirect(args, 0),
            None => pass.draw(0..self.vertices, 0..1),
        }
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
        let (gx, gy) = grid(self.pixels, PIXEL_GROUP);
        let g = self.gpu.bind(&pipeline.get_bind_group_layout(0), buffers);
        self.compute(enc, name, |pass| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &g, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        });
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

    /// The totals pass from DKB's counting features pass (totals.wgsl's from_sums): the count
    /// packed in `sums` written out into `counts`, and the totals into `totals`.
    pub(super) fn totals_from_sums(
        &self,
        enc: &mut wgpu::CommandEncoder,
        sums: &wgpu::Buffer,
        counts: &wgpu::Buffer,
        totals: &wgpu::Buffer,
    ) {
        let pipeline = &self.gpu.pipelines.totals_from_sums;
        let group = self.gpu.bind_at(
            &pipeline.get_bind_group_layout(0),
            &[(0, self.params()), (2, totals), (4, sums), (5, counts)],
        );
        let (gx, gy) = grid(self.pixels, PIXEL_GROUP);
        self.compute(enc, "totals", |pass| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        });
    }
}
