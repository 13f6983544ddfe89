//! dhoit's own frames ([`Gpu::render`]): one client of the frame engine. It uploads a scene,
//! draws its opaque pass, and draws the scene's transparent triangles into each geometry pass
//! the engine records ([`SceneDraws`], the engine's [`Geometry`]), with dhoit's own pipelines;
//! then it submits the frame, waits for it and reads it back, with what the tests compare.
//!
//! It counts first where the method's memory follows the frame's count (the A-buffer, MLAB,
//! DKB, VKB, an uploaded importance): a submission of the opaque pass, the count and its totals,
//! read back, so every buffer of the frame is sized for its own occupancy (`Sizing::Own`, the
//! memory the tables count). An application's frame never waits (`app.rs`).

use super::bindings;
use super::buffers::{
    FrameBuffers, Readback, Statistics, read_back_with_async, read_frame, read_texture, read_words,
};
use super::passes::{Geometry, GeometryPass, Resolve, at, view_at};
use super::pipelines::{OPAQUE_COLOR_FORMAT, OPAQUE_DEPTH_FORMAT};
use super::stream::{AppMethod, FrameReport, Stream};
use super::timer::Timer;
use super::{
    Carried, FrameOptions, FrameSpec, Gpu, GpuFrame, Sizing, Slots, buffers, frame_params,
};
use crate::budget::{Budget, Occupancy};
use crate::composite::Image;
use crate::error::{Error, Result};
use crate::scene::{Camera, Scene};
use crate::shared::TOTALS_WORDS;
use crate::shared::count_bytes;
use crate::wgsl::{PIXEL_GROUP, Params, grid};

/// A scene's buffers and its opaque pass's targets, as dhoit's own frames draw them.
pub(super) struct FrameInputs {
    /// The scene client's own uniform for the opaque pass (the frame's engine has its own).
    params: wgpu::Buffer,
    /// Group 0 of every geometry pass after params: positions, colours, texture coordinates,
    /// triangle materials, materials, texels (geometry.wgsl), then the sRGB table.
    scene: [wgpu::Buffer; 7],
    /// The transparent triangles' vertex indices, then the opaque ones'.
    index: wgpu::Buffer,
    /// Indices of the transparent triangles, and of the opaque ones after them.
    transparent: u32,
    opaque: u32,
    /// The opaque pass's depth (the transparent passes' occluder) and colour (`fragment::pack_opaque`'s
    /// word in an R32, 0 where none): the application's, counted for no method.
    opaque_depth: wgpu::Texture,
    opaque_color: wgpu::Texture,
    depth_view: wgpu::TextureView,
    color_view: wgpu::TextureView,
    /// The image the resolve writes (RGBA f32 a pixel), read back.
    image: wgpu::Buffer,
}

/// dhoit's own frame as the engine's client: the scene's transparent triangles drawn into each
/// geometry pass with dhoit's pipeline of it, the resolve into the image over the opaque
/// pass's colour.
pub(super) struct SceneDraws<'i> {
    inputs: &'i FrameInputs,
}

impl<'i> SceneDraws<'i> {
    pub(super) fn new(inputs: &'i FrameInputs) -> SceneDraws<'i> {
        SceneDraws { inputs }
    }

    /// Group 0 of a geometry pass (geometry.wgsl): params, the scene's buffers, the sRGB
    /// table, and for a transparent pass the opaque depth.
    fn geometry_group(
        &self,
        gpu: &Gpu,
        layout: &wgpu::BindGroupLayout,
        params: &wgpu::Buffer,
        transparent: bool,
    ) -> wgpu::BindGroup {
        let i = self.inputs;
        let buffers: Vec<&wgpu::Buffer> = std::iter::once(params).chain(&i.scene).collect();
        let depth = view_at(bindings::geometry::OPAQUE_DEPTH, &i.depth_view);
        let extra = if transparent { vec![depth] } else { Vec::new() };
        gpu.bind_with(layout, &buffers, extra)
    }

    /// The opaque pass (opaque.wgsl): the scene's opaque triangles into the depth and colour
    /// targets, cleared first (to 1 and 0; where the scene has none, that is all).
    pub(super) fn opaque(&self, gpu: &Gpu, enc: &mut wgpu::CommandEncoder, timer: Option<&Timer>) {
        let i = self.inputs;
        let pipeline = &gpu.pipelines.opaque;
        let g0 = self.geometry_group(gpu, &pipeline.get_bind_group_layout(0), &i.params, false);
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("opaque"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &i.color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &i.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: timer.and_then(|t| t.render("opaque")),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if i.opaque > 0 {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &g0, &[]);
            pass.set_index_buffer(i.index.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(i.transparent..i.transparent + i.opaque, 0, 0..1);
        }
    }
}

impl Geometry for SceneDraws<'_> {
    fn draw(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        pass: GeometryPass<'_>,
        params: &wgpu::Buffer,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) {
        let i = self.inputs;
        let pipeline = pass.pipeline;
        let g0 = self.geometry_group(gpu, &pipeline.get_bind_group_layout(0), params, true);
        let g1 = (!pass.group.is_empty()).then(|| {
            gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(pass.name),
                layout: &pipeline.get_bind_group_layout(1),
                entries: &pass.group,
            })
        });
        let colors = pass.color_attachments();
        // A storing pass writes no colour: the opaque depth, read-only, is its one attachment.
        let depth = colors
            .is_empty()
            .then_some(wgpu::RenderPassDepthStencilAttachment {
                view: &i.depth_view,
                depth_ops: None,
                stencil_ops: None,
            });
        let mut rp = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(pass.name),
            color_attachments: &colors,
            depth_stencil_attachment: depth,
            timestamp_writes: timestamps,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        rp.set_pipeline(pipeline);
        rp.set_bind_group(0, &g0, &[]);
        if let Some(g) = &g1 {
            rp.set_bind_group(1, g, &[]);
        }
        rp.set_index_buffer(i.index.slice(..), wgpu::IndexFormat::Uint32);
        rp.draw_indexed(0..i.transparent, 0, 0..1);
    }

    fn resolve(
        &self,
        gpu: &Gpu,
        cpass: &mut wgpu::ComputePass,
        resolve: Resolve,
        own: &wgpu::ComputePipeline,
        group: Vec<wgpu::BindGroupEntry<'_>>,
    ) {
        let i = self.inputs;
        // The image, and what the resolve composites over (behind.wgsl).
        let entries: Vec<wgpu::BindGroupEntry> = group
            .into_iter()
            .chain([
                at(resolve.image_at(), &i.image),
                view_at(bindings::behind::OPAQUE_COLOR, &i.color_view),
            ])
            .collect();
        let g = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &own.get_bind_group_layout(0),
            entries: &entries,
        });
        let (gx, gy) = grid(i.pixels(), PIXEL_GROUP);
        cpass.set_pipeline(own);
        cpass.set_bind_group(0, &g, &[]);
        cpass.dispatch_workgroups(gx, gy, 1);
    }
}

impl FrameInputs {
    fn pixels(&self) -> u32 {
        self.opaque_depth.width() * self.opaque_depth.height()
    }
}

impl Gpu {
    /// Renders one frame: the A-buffer when `slots` is None, else as `slots` says.
    pub fn render(
        &self,
        scene: &Scene,
        cam: &Camera,
        size: (u32, u32),
        background: [f32; 3],
        slots: Slots,
    ) -> Result<GpuFrame> {
        let opts = FrameOptions::default();
        self.render_with(&opts, scene, cam, size, background, slots)
    }

    /// [`Gpu::render`] with the passes laid out and read back as `opts` says.
    pub fn render_with(
        &self,
        opts: &FrameOptions,
        scene: &Scene,
        cam: &Camera,
        size: (u32, u32),
        background: [f32; 3],
        slots: Slots,
    ) -> Result<GpuFrame> {
        let (width, height) = size;
        let scopes = self.begin_frame(size)?;
        let px = width as u64 * height as u64;
        // Tinted glass: every method keeps each fragment's tint or the product of them.
        let params = Params {
            uniform_alpha: scene.uniform_opacity.unwrap_or(-1.0),
            tinted: scene.tints() as u32,
            hdr: scene.hdr() as u32,
            ..frame_params(Some(cam), size, background)
        };
        let upload = std::time::Instant::now();
        let (inputs, scene_buffers) = self.frame_inputs(scene, &params, true)?;
        let upload_ms = upload.elapsed().as_secs_f64() * 1e3;
        let draws = SceneDraws { inputs: &inputs };
        // Where the method's memory follows the frame's count, the count first.
        let counted = matches!(
            slots,
            Slots::Exact | Slots::Mlab(_) | Slots::Importance(..) | Slots::Vkb(..) | Slots::Dkb(..)
        );
        // DKB's record marks of this frame, made with the count first, so the frame gathers its
        // statistics with its count as a frame of a stream does (the twin of a frame that
        // follows one of the same count; Tuning::two_pass_dkb).
        let marked = matches!(slots, Slots::Dkb(..)) && opts.tuning.two_pass_dkb;
        let (sizing, carried, _held) = match counted {
            true => {
                let (occ, carried, held) = self.count_first(&draws, &params, marked)?;
                (Sizing::Own(occ), carried, Some(held))
            }
            false => (Sizing::NOTHING, None, None),
        };
        let spec = FrameSpec {
            opts: *opts,
            size: (width, height),
            params,
            slots,
            sizing,
            carried,
        };
        let timer = Timer::new(self);
        let mut enc = self.device.create_command_encoder(&Default::default());
        draws.opaque(self, &mut enc, Some(&timer));
        let recorded = self.record_frame(&mut enc, &timer, &draws, &spec)?;
        self.submit(enc.finish());
        // The frame's passes finish first, so the readback's time is its own.
        self.wait("waiting for a submission")?;
        let readback = std::time::Instant::now();
        // RGBA f32 a pixel, straight from the mapped buffer into the image, unless the
        // resolve's status refuses the frame.
        let mut out = recorded.out;
        let data = read_frame(
            self,
            &inputs.image,
            16 * px,
            out.status.as_ref(),
            width,
            rgb_f32,
        )?;
        let readback_ms = readback.elapsed().as_secs_f64() * 1e3;
        let pass_ms = timer.read()?;
        let opaque = if opts.diagnostics && inputs.opaque > 0 {
            let color = read_texture(self, &inputs.opaque_color)?;
            let depth = read_texture(self, &inputs.opaque_depth)?;
            Some((
                color,
                depth.into_iter().map(f32::from_bits).collect::<Vec<f32>>(),
            ))
        } else {
            None
        };
        out.run_deferred(self)?;
        let Statistics {
            importance,
            stats,
            features_drawn,
            vkb_nearest,
            network_rows,
            plan,
        } = if opts.diagnostics {
            out.statistics(self, px)?
        } else {
            Statistics::default()
        };
        scopes.end()?;
        drop(recorded.taken);
        drop(scene_buffers);
        let mut fragments = out.fragments;
        if let (Some(fl), Some((color, depth))) = (&mut fragments, &opaque) {
            fl.opaque = color.clone();
            fl.opaque_depth = depth.clone();
        }
        Ok(GpuFrame {
            image: Image {
                width,
                height,
                data,
            },
            pass_ms,
            passes: timer.ran(),
            host_ms: vec![("scene upload", upload_ms), ("image readback", readback_ms)],
            allocated_bytes: recorded.allocated,
            exact: recorded.exact,
            fragments,
            slots: out.slots,
            importance,
            stats,
            features_drawn,
            vkb_nearest,
            opaque,
            variants: out.variants,
            network_rows,
            capture_counts: out.capture_counts,
            list_arrived: out.list_arrived,
            record_batches: out.record_batches,
            plan,
        })
    }

    /// The frame's occupancy, counted first: its opaque pass, the count and the totals in a
    /// submission of their own, read back (buffers of their own, counted for no method); with
    /// `marked`, DKB's record marks of that count too, valid for the frame (the frame counts
    /// them as its memory), and the buffers held for it.
    fn count_first(
        &self,
        draws: &SceneDraws,
        params: &Params,
        marked: bool,
    ) -> Result<(Occupancy, Option<Carried>, buffers::Taken<'_>)> {
        let px = params.pixels as u64;
        let mut enc = self.device.create_command_encoder(&Default::default());
        let mut fb = FrameBuffers::new(self, &mut enc);
        let uniform = fb.init(
            "count first.params",
            bytemuck::bytes_of(params),
            wgpu::BufferUsages::UNIFORM,
            false,
        );
        let counts = fb.storage("count first.count", count_bytes(px), false)?;
        let totals = fb.storage("count first.totals", 4 * TOTALS_WORDS as u64, false)?;
        let marks = match marked {
            true => {
                let bytes = crate::budget::marks_bytes(px);
                let marks = fb.storage("dkb.record_marks", bytes, false)?;
                // Block totals of its own: the frame's scans take theirs while these are held.
                let groups = px.div_ceil(crate::budget::SCAN_BLOCK);
                let blocks = fb.storage("count first.scan_blocks", 4 * groups, false)?;
                Some((marks, blocks))
            }
            false => None,
        };
        let held = fb.into_taken();
        draws.opaque(self, &mut enc, None);
        let p = &self.pipelines;
        let pass = GeometryPass {
            phase: super::Phase::Count,
            pipeline: &p.count,
            group: super::passes::entries(&[&counts]),
            targets: &[],
            name: "count first",
        };
        draws.draw(self, &mut enc, pass, &uniform, None);
        let g = self.bind(
            &p.totals.get_bind_group_layout(0),
            &[&uniform, &counts, &totals],
        );
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            let (gx, gy) = grid(params.pixels, PIXEL_GROUP);
            pass.set_pipeline(&p.totals);
            pass.set_bind_group(0, &g, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
            if let Some((marks, blocks)) = &marks {
                self.mark_records(&uniform, &counts, marks, blocks, px)(&mut pass);
            }
        }
        self.submit(enc.finish());
        let words = (0..=crate::shared::TOTAL_DEEPER).map(|i| (&totals, 4 * i as u64));
        let w = read_words(self, &words.collect::<Vec<_>>())?;
        let carried = marks.map(|(marks, _)| Carried { marks, valid: true });
        Ok((Occupancy::from_totals(&w), carried, held))
    }

    /// The scene's buffers (uploaded), its opaque pass's targets and the image, and the pooled
    /// buffers they were taken from (held until the frame is read).
    pub(super) fn frame_inputs(
        &self,
        scene: &Scene,
        params: &Params,
        image: bool,
    ) -> Result<(FrameInputs, buffers::Taken<'_>)> {
        // The scene's buffers are written by the queue, before any command: no encoder of
        // theirs records a clear.
        let mut none = self.device.create_command_encoder(&Default::default());
        let mut fb = FrameBuffers::new(self, &mut none);
        let params_buf = fb.init(
            "scene.params",
            bytemuck::bytes_of(params),
            wgpu::BufferUsages::UNIFORM,
            false,
        );
        let pos: Vec<[f32; 4]> = scene
            .positions
            .iter()
            .map(|p| p.extend(1.0).to_array())
            .collect();
        let (materials, texels) = crate::wgsl::gpu_materials(scene);
        let storage = wgpu::BufferUsages::STORAGE;
        let mut upload = |label: &str, bytes: &[u8]| fb.init(label, bytes, storage, false);
        let positions = upload("scene.positions", bytemuck::cast_slice(&pos));
        let colors = upload("scene.colors", bytemuck::cast_slice(&scene.colors));
        let uvs = upload("scene.uvs", bytemuck::cast_slice(&scene.uvs));
        let tri_material = upload(
            "scene.triangle_material",
            bytemuck::cast_slice(&scene.triangle_material),
        );
        let mats = upload("scene.materials", bytemuck::cast_slice(&materials));
        let texels = upload("scene.texels", bytemuck::cast_slice(&texels));
        let srgb = fb.init(
            "scene.srgb",
            bytemuck::cast_slice(&crate::scene::material::srgb_table()),
            wgpu::BufferUsages::UNIFORM,
            false,
        );
        // The transparent triangles' vertices first, then the opaque ones', each in
        // submission order (the vertex stage pulls vertex `index`, so a fragment keeps its
        // triangle's submission index).
        let tris = scene.triangle_count() as u32;
        let (transparent, opaque): (Vec<u32>, Vec<u32>) =
            (0..tris).partition(|&t| scene.transparent(t as usize));
        let indices: Vec<u32> = transparent
            .iter()
            .chain(&opaque)
            .flat_map(|&t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        let index = fb.init(
            "scene.indices",
            bytemuck::cast_slice(&indices),
            wgpu::BufferUsages::INDEX,
            false,
        );
        // The image a frame resolves into, where it does (else an empty buffer).
        let image_bytes = if image { 16 * params.pixels as u64 } else { 16 };
        let image = fb.storage("application.image", image_bytes, false)?;
        let size = (params.width, params.height);
        let texture = |label: &str, format, usage| {
            buffers::frame_texture(&self.device, label, size, format, usage)
        };
        let sampled = wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC;
        let opaque_depth = texture("application.opaque_depth", OPAQUE_DEPTH_FORMAT, sampled);
        let opaque_color = texture("application.opaque_color", OPAQUE_COLOR_FORMAT, sampled);
        let inputs = FrameInputs {
            params: params_buf,
            scene: [positions, colors, uvs, tri_material, mats, texels, srgb],
            index,
            transparent: 3 * transparent.len() as u32,
            opaque: 3 * opaque.len() as u32,
            depth_view: opaque_depth.create_view(&Default::default()),
            color_view: opaque_color.create_view(&Default::default()),
            opaque_depth,
            opaque_color,
            image,
        };
        Ok((inputs, fb.into_taken()))
    }
}

impl Readback {
    /// The reads a frame's passes left for after it ran (the A-buffer's fragments, the
    /// k-buffer's slots and tails, the list's), in order.
    fn run_deferred(&mut self, gpu: &Gpu) -> Result<()> {
        for read in std::mem::take(&mut self.deferred) {
            read(gpu, self)?;
        }
        Ok(())
    }
}

/// dhoit's own scene drawn frame after frame as an application's renderer draws them: each
/// frame recorded into an encoder with no wait (the scene's opaque pass, then the method's
/// frame, its geometry dhoit's own pipelines), its buffers sized from the counts of the frames
/// before (as an application's methods are, `Oit`), its image read back only where asked.
/// What `dhoit bench` runs frames in flight with.
pub struct SceneStream {
    stream: Stream,
    inputs: FrameInputs,
    background: [f32; 3],
    uniform_alpha: f32,
    /// `Params::tinted`: 1 where the scene's glass is tinted.
    tinted: u32,
    /// `Params::hdr`: 1 where its colours keep their range above white.
    hdr: u32,
}

impl SceneStream {
    /// `method` (with what `options` gives it: its budget, DKB's weights, VKB's, WBOIT's,
    /// MBOIT's and the list's parameters, exact where cheaper or not) for `scene` at `size`,
    /// on a fork of `gpu`. The methods an application runs: the A-buffer, FKB, MLAB, DKB,
    /// VKB, WBOIT, MBOIT and the list; the others (optimal, the greedies) are refused.
    pub fn new(
        gpu: &Gpu,
        scene: &Scene,
        size: (u32, u32),
        method: crate::frame::Method,
        options: &crate::frame::Options,
    ) -> Result<SceneStream> {
        use crate::frame::Method as M;
        let (app, budget) = match method {
            M::Abuffer => (AppMethod::Abuffer, None),
            M::Fkb => (AppMethod::Fkb { k: 1 }, Some(options.budget)),
            M::Mlab => (AppMethod::Mlab { rows: 1 }, Some(options.budget)),
            M::Dkb => {
                let weights = options.weights.ok_or_else(crate::frame::no_weights)?;
                (
                    AppMethod::Dkb(Box::new(weights.clone())),
                    Some(options.budget),
                )
            }
            M::Vkb => (AppMethod::Vkb(options.vkb), Some(options.budget)),
            M::Wboit => (AppMethod::Wboit(options.wboit), None),
            M::Mboit => (AppMethod::Mboit(options.mboit), None),
            M::LinkedList => (
                AppMethod::List {
                    nodes: 1,
                    sorted: options.list_sorted,
                },
                Some(options.budget),
            ),
            m => {
                return Err(Error::Invalid(format!(
                    "{m} is not a method a renderer streams (its k is computed on the CPU)"
                )));
            }
        };
        let mut stream = Stream::new(gpu, size, app, None)?;
        stream.decision = options.decision;
        let tinted = scene.tints() as u32;
        let hdr = scene.hdr() as u32;
        // Its budget resolved once it knows whether its fragments keep tint words.
        stream.words = scene.words();
        if let Some(b) = budget {
            stream.set_budget(b)?;
        }
        let params = Params {
            tinted,
            hdr,
            ..frame_params(None, size, options.background)
        };
        let (inputs, taken) = stream.gpu.frame_inputs(scene, &params, true)?;
        // The scene's buffers are the stream's for its life, never the pool's.
        taken.keep();
        Ok(SceneStream {
            stream,
            inputs,
            background: options.background,
            uniform_alpha: scene.uniform_opacity.unwrap_or(-1.0),
            tinted,
            hdr,
        })
    }

    /// One frame seen by `cam` recorded into `enc`: the opaque pass, then the method's frame.
    /// Nothing is submitted or waited for; the frame's image is in the stream's image once
    /// its submission has run.
    pub fn record(&mut self, enc: &mut wgpu::CommandEncoder, cam: &Camera) -> Result<()> {
        let params = Params {
            uniform_alpha: self.uniform_alpha,
            tinted: self.tinted,
            hdr: self.hdr,
            ..frame_params(Some(cam), self.stream.size, self.background)
        };
        // The opaque pass's camera, by the queue: a submission's frames share the last one
        // written, so each frame goes in a submission of its own.
        let gpu = &self.stream.gpu;
        gpu.queue
            .write_buffer(&self.inputs.params, 0, bytemuck::bytes_of(&params));
        let draws = SceneDraws::new(&self.inputs);
        if self.stream.uncounted() {
            // The first frame of a size counts first, behind its opaque pass.
            let opaque = |gpu: &Gpu, enc: &mut wgpu::CommandEncoder| draws.opaque(gpu, enc, None);
            self.stream.count_first(&draws, &opaque, params)?;
        }
        let gpu = &self.stream.gpu;
        draws.opaque(gpu, enc, None);
        self.stream.record(enc, &draws, params)
    }

    /// Reports of the frames that have run (as `Oit::finished`).
    pub fn finished(&mut self, wait: bool) -> Result<Vec<FrameReport>> {
        self.stream.finished(wait)
    }

    /// The next frame starts a new shot (as `Oit::cut`): DKB's marks its own records and draws
    /// its features pass.
    pub fn cut(&mut self) {
        self.stream.cut();
    }

    /// Sizes the buffers of the frames to come for frames of `occupancy` (as `Oit::expect`).
    pub fn expect(&mut self, occupancy: Occupancy) {
        self.stream.expect(occupancy);
    }

    /// The last frame's image, once its submission has run (this waits for it).
    pub fn image(&self) -> Result<Image> {
        pollster::block_on(self.image_async())
    }

    /// [`SceneStream::image`] without blocking: what a page (wasm32) awaits, where nothing may
    /// wait for the GPU.
    pub async fn image_async(&self) -> Result<Image> {
        let (w, h) = self.stream.size;
        let bytes = 16 * w as u64 * h as u64;
        let data =
            read_back_with_async(&self.stream.gpu, &self.inputs.image, bytes, rgb_f32).await?;
        Ok(Image {
            width: w,
            height: h,
            data,
        })
    }

    /// The budget of the frames to come (as `Oit::set_budget`): refused, the method named,
    /// where the method cannot take it.
    pub fn set_budget(&mut self, budget: Budget) -> Result<()> {
        self.stream.set_budget(budget)
    }

    /// The device the stream records for (the application submits on its queue).
    pub fn gpu(&self) -> &Gpu {
        &self.stream.gpu
    }
}

/// A frame's image buffer (RGBA f32 a pixel) as RGB.
fn rgb_f32(b: &[u8]) -> Vec<[f32; 3]> {
    let f = |c: &[u8]| f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
    b.chunks_exact(16)
        .map(|c| [f(&c[0..4]), f(&c[4..8]), f(&c[8..12])])
        .collect()
}
