//! Recording a pass: a geometry pass, which the frame's client draws ([`Geometry`]), or a
//! per-pixel compute dispatch, with the frame's parameters and timestamps. The frame engine
//! draws geometry only through [`Geometry`]: `Gpu::render` draws its scene there
//! (`scene.rs`), an application its own transparent geometry (`app.rs`).

use super::bindings;
use super::timer::Timer;
use super::{FrameOptions, Gpu};
use crate::wgsl::{PIXEL_GROUP, grid};

/// One of the geometry passes a frame records, each drawn by the frame's client with one
/// pipeline: dhoit's own pass code, which an application's fragment shader runs as the module
/// `store_module` gives it for the phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Phase {
    /// Each pixel's fragments counted (abuffer_count.wgsl).
    Count,
    /// The exact A-buffer's store (abuffer_store.wgsl).
    Store,
    /// DKB's network's statistics (features.wgsl), in a pass of their own: in a frame that
    /// marks its own records (its first, one after a cut), once a batch of them.
    Features,
    /// DKB's count (features.wgsl with features_count.wgsl): each pixel's fragments counted,
    /// as [`Phase::Count`] counts them, and the network's statistics of the pixels the frame
    /// before marked, gathered with them: a frame after the first draws no
    /// [`Phase::Features`].
    CountFeatures,
    /// VKB's count with each pixel's nearest fragment's depth and facing (vkb_count.wgsl).
    VkbCount,
    /// The k-buffer's capture into each pixel's slots and its tail (capture.wgsl).
    Capture,
    /// The capture built for frames whose budget holds every fragment (k = n).
    CaptureFits,
    /// The portable capture's first pass: each fragment's depth into the slots
    /// ([`super::Capture::Portable`]; capture.wgsl with kbuffer_portable.wgsl).
    CaptureDepths,
    /// The portable capture's second pass, over the same fragments: each one's colour into the
    /// slots holding its depth, or into the tail.
    CaptureColours,
    /// Where the frame stores tint words (tinted glass, colours above white), after either
    /// capture: each fragment's tint word beside its key (capture.wgsl with kbuffer_tint.wgsl).
    /// An application's frames draw it where it asked for colours above white (`Oit::set_hdr`).
    CaptureTints,
    /// The budgeted linked list's store (list_store.wgsl).
    ListStore,
    /// WBOIT's accumulation into its two targets (wboit_accumulate.wgsl).
    WboitAccumulate,
    /// MBOIT's moments into their targets (mboit_moments.wgsl).
    MboitMoments,
    /// MBOIT's transmittance-weighted colour (mboit_accumulate.wgsl).
    MboitAccumulate,
}

/// Which resolve a frame ends in: the client binds the image (dhoit's frame) or the
/// application's image and target (its `onto` entry) around the engine's buffers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Resolve {
    /// resolve.wgsl, built for frames that fit where `fits`.
    KBuffer { fits: bool },
    /// abuffer_resolve.wgsl: sort and blend.
    Abuffer,
    /// mlab_resolve.wgsl.
    Mlab,
    /// list_resolve.wgsl.
    List,
    /// blend_composite.wgsl's WBOIT composite.
    Wboit,
    /// blend_composite.wgsl's MBOIT composite.
    Mboit,
}

impl Resolve {
    /// The pass and entry that resolve onto an application's target, and the bindings there of
    /// the image under the transparent surfaces and of the target: each resolve's `onto` entry.
    pub(super) fn onto(self) -> (&'static str, &'static str, [u32; 2]) {
        use bindings::{blend_composite as blend, list_resolve as list, resolve, sort};
        match self {
            Resolve::KBuffer { .. } => ("resolve", "onto", [resolve::UNDER, resolve::ONTO_TARGET]),
            Resolve::Abuffer => ("abuffer_resolve", "onto", [sort::UNDER, sort::ONTO_TARGET]),
            Resolve::Mlab => ("mlab_resolve", "onto", [sort::UNDER, sort::ONTO_TARGET]),
            Resolve::List => ("list_resolve", "onto", [list::UNDER, list::ONTO_TARGET]),
            Resolve::Wboit => (
                "blend_composite",
                "wboit_onto",
                [blend::UNDER, blend::ONTO_TARGET],
            ),
            Resolve::Mboit => (
                "blend_composite",
                "mboit_onto",
                [blend::UNDER, blend::ONTO_TARGET],
            ),
        }
    }

    /// The binding of the image dhoit's own frame resolves into (`main`).
    pub(super) fn image_at(self) -> u32 {
        match self {
            Resolve::KBuffer { .. } => bindings::resolve::IMAGE,
            Resolve::Abuffer | Resolve::Mlab => bindings::sort::IMAGE,
            Resolve::List => bindings::list_resolve::IMAGE,
            Resolve::Wboit | Resolve::Mboit => bindings::blend_composite::IMAGE,
        }
    }

    /// Whether the resolve is built for frames whose budget holds every fragment.
    pub(super) fn fits(self) -> bool {
        matches!(self, Resolve::KBuffer { fits: true })
    }
}

/// One geometry pass as the engine hands it to the frame's client.
pub(super) struct GeometryPass<'p> {
    pub(super) phase: Phase,
    /// dhoit's own pipeline of the pass (what the scene client draws with).
    pub(super) pipeline: &'p wgpu::RenderPipeline,
    /// The pass's own group (dhoit's group 1, the application's group): its buffers and
    /// textures at their bindings.
    pub(super) group: Vec<wgpu::BindGroupEntry<'p>>,
    /// A blended method's targets, cleared to these colours first; none for a pass that stores
    /// its fragments.
    pub(super) targets: &'p [(&'p wgpu::TextureView, wgpu::Color)],
    pub(super) name: &'static str,
}

impl<'p> GeometryPass<'p> {
    /// The pass's colour attachments: its targets, cleared first (none for a storing pass).
    pub(super) fn color_attachments(&self) -> Vec<Option<wgpu::RenderPassColorAttachment<'p>>> {
        self.targets
            .iter()
            .map(|&(view, clear)| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(clear),
                        store: wgpu::StoreOp::Store,
                    },
                })
            })
            .collect()
    }
}

/// A frame's client, as the engine sees it: it draws the frame's transparent geometry into
/// each geometry pass and binds what the resolve composites over and into.
pub(super) trait Geometry {
    /// Draws the frame's transparent geometry in `pass`, a render pass it opens on `enc` with
    /// `timestamps`; `params` is the frame's parameter uniform.
    fn draw(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        pass: GeometryPass<'_>,
        params: &wgpu::Buffer,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    );

    /// Dispatches `resolve` on a grid over the frame's pixels in `cpass`: `own` is dhoit's
    /// pipeline of it, `group` its group 0 without the image, which goes at `image_at` (dhoit's
    /// frame), or whose `onto` entry writes the application's target instead.
    fn resolve(
        &self,
        gpu: &Gpu,
        cpass: &mut wgpu::ComputePass,
        resolve: Resolve,
        own: &wgpu::ComputePipeline,
        group: Vec<wgpu::BindGroupEntry<'_>>,
    );
}

/// The frame's shared bindings and the pass timer: every pass is one call.
pub(super) struct Passes<'a> {
    pub(super) gpu: &'a Gpu,
    /// How the frame lays out its passes and what it reads back.
    pub(super) opts: FrameOptions,
    pub(super) timer: &'a Timer<'a>,
    params: wgpu::Buffer,
    pub(super) pixels: u32,
    geometry: &'a dyn Geometry,
}

/// `buffers` at bindings 0, 1, ...
pub(super) fn entries<'b>(buffers: &[&'b wgpu::Buffer]) -> Vec<wgpu::BindGroupEntry<'b>> {
    entries_from(0, buffers)
}

/// `buffers` at bindings `first`, `first + 1`, ...
fn entries_from<'b>(first: u32, buffers: &[&'b wgpu::Buffer]) -> Vec<wgpu::BindGroupEntry<'b>> {
    buffers.iter().zip(first..).map(|(b, i)| at(i, b)).collect()
}

/// `buffer` at `binding` (a name from [`bindings`]).
pub(super) fn at(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// Texture `view` at `binding` (a name from [`bindings`]).
pub(super) fn view_at(binding: u32, view: &wgpu::TextureView) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::TextureView(view),
    }
}

impl<'a> Passes<'a> {
    pub(super) fn new(
        gpu: &'a Gpu,
        timer: &'a Timer<'a>,
        params: wgpu::Buffer,
        pixels: u32,
        opts: FrameOptions,
        geometry: &'a dyn Geometry,
    ) -> Self {
        Passes {
            gpu,
            opts,
            timer,
            params,
            pixels,
            geometry,
        }
    }

    /// The frame's parameter uniform (binding 0 of every pass).
    pub(super) fn params(&self) -> &wgpu::Buffer {
        &self.params
    }

    /// A geometry pass of `phase`, `buffers` its group (bindings 0, 1, ...), drawn by the
    /// client.
    pub(super) fn draw(
        &self,
        enc: &mut wgpu::CommandEncoder,
        phase: Phase,
        pipeline: &wgpu::RenderPipeline,
        buffers: &[&wgpu::Buffer],
        name: &'static str,
    ) {
        self.draw_group(enc, phase, pipeline, entries(buffers), name);
    }

    /// [`Passes::draw`] with the group's entries at the bindings they name.
    pub(super) fn draw_group(
        &self,
        enc: &mut wgpu::CommandEncoder,
        phase: Phase,
        pipeline: &wgpu::RenderPipeline,
        group: Vec<wgpu::BindGroupEntry<'_>>,
        name: &'static str,
    ) {
        let pass = GeometryPass {
            phase,
            pipeline,
            group,
            targets: &[],
            name,
        };
        let timestamps = self.timer.render(name);
        self.geometry
            .draw(self.gpu, enc, pass, &self.params, timestamps);
    }

    /// A blended method's geometry pass of `phase`: its targets cleared to the given colours
    /// and kept, `group` its own bindings (textures and buffers).
    pub(super) fn blend(
        &self,
        enc: &mut wgpu::CommandEncoder,
        phase: Phase,
        pipeline: &wgpu::RenderPipeline,
        group: Vec<wgpu::BindGroupEntry<'_>>,
        targets: &[(&wgpu::TextureView, wgpu::Color)],
        name: &'static str,
    ) {
        let pass = GeometryPass {
            phase,
            pipeline,
            group,
            targets,
            name,
        };
        let timestamps = self.timer.render(name);
        self.geometry
            .draw(self.gpu, enc, pass, &self.params, timestamps);
    }

    /// A resolve over the frame's pixels: `group` its bindings but the image (the client's, at
    /// `image_at`), through the client.
    pub(super) fn resolve(
        &self,
        enc: &mut wgpu::CommandEncoder,
        resolve: Resolve,
        pipeline: &wgpu::ComputePipeline,
        group: Vec<wgpu::BindGroupEntry<'_>>,
        name: &'static str,
    ) {
        self.compute(enc, name, |pass| {
            self.geometry
                .resolve(self.gpu, pass, resolve, pipeline, group)
        });
    }

    /// A timed compute pass `record` fills (several dispatches, one timestamp pair).
    pub(super) fn compute(
        &self,
        enc: &mut wgpu::CommandEncoder,
        name: &'static str,
        record: impl FnOnce(&mut wgpu::ComputePass),
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(name),
            timestamp_writes: self.timer.compute(name),
        });
        record(&mut pass);
    }

    /// A per-pixel compute pass, `buffers` bound as group 0 in binding order.
    pub(super) fn dispatch(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
        name: &'static str,
    ) {
        let g = self.gpu.bind(&pipeline.get_bind_group_layout(0), buffers);
        let (gx, gy) = grid(self.pixels, PIXEL_GROUP);
        self.compute(enc, name, |pass| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &g, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        });
    }

    /// The totals pass (totals.wgsl) and the frame's plan after it (plan.wgsl): the frame's
    /// fragments, covered pixels and largest count from `counts` into `totals`, then its F and
    /// flags there and DKB's records a batch into `batch`, from `plan` (a [`crate::plan`]
    /// input's uniform), in one compute pass.
    pub(super) fn totals_and_plan(
        &self,
        enc: &mut wgpu::CommandEncoder,
        counts: &wgpu::Buffer,
        totals: &wgpu::Buffer,
        plan: Option<(&wgpu::Buffer, &wgpu::Buffer)>,
    ) -> crate::error::Result<()> {
        let p = &self.gpu.pipelines;
        let totals_group = self.totals_group(counts, totals);
        let planned = plan.map(|(uniform, batch)| self.plan_group(totals, uniform, batch));
        let (gx, gy) = grid(self.pixels, PIXEL_GROUP);
        self.compute(enc, "totals", |pass| {
            pass.set_pipeline(&p.totals);
            pass.set_bind_group(0, &totals_group, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
            if let Some(g) = &planned {
                pass.set_pipeline(&p.plan);
                pass.set_bind_group(0, g, &[]);
                pass.dispatch_workgroups(1, 1, 1);
            }
        });
        Ok(())
    }

    /// The totals pass alone (its plan recorded later: [`Passes::plan`]).
    pub(super) fn totals(
        &self,
        enc: &mut wgpu::CommandEncoder,
        counts: &wgpu::Buffer,
        totals: &wgpu::Buffer,
    ) {
        let p = &self.gpu.pipelines;
        let g = self.totals_group(counts, totals);
        let (gx, gy) = grid(self.pixels, PIXEL_GROUP);
        self.compute(enc, "totals", |pass| {
            pass.set_pipeline(&p.totals);
            pass.set_bind_group(0, &g, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        });
    }

    /// The frame's plan (plan.wgsl) from its totals, in a pass of its own.
    pub(super) fn plan(
        &self,
        enc: &mut wgpu::CommandEncoder,
        totals: &wgpu::Buffer,
        plan: &wgpu::Buffer,
        batch: &wgpu::Buffer,
    ) {
        let g = self.plan_group(totals, plan, batch);
        self.compute(enc, "plan", |pass| {
            pass.set_pipeline(&self.gpu.pipelines.plan);
            pass.set_bind_group(0, &g, &[]);
            pass.dispatch_workgroups(1, 1, 1);
        });
    }

    fn totals_group(&self, counts: &wgpu::Buffer, totals: &wgpu::Buffer) -> wgpu::BindGroup {
        self.gpu.bind(
            &self.gpu.pipelines.totals.get_bind_group_layout(0),
            &[&self.params, counts, totals],
        )
    }

    fn plan_group(
        &self,
        totals: &wgpu::Buffer,
        plan: &wgpu::Buffer,
        batch: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        self.gpu.bind_at(
            &self.gpu.pipelines.plan.get_bind_group_layout(0),
            &[
                (bindings::plan::TOTALS, totals),
                (bindings::plan::BATCH, batch),
                (bindings::plan::PLAN, plan),
            ],
        )
    }
}
