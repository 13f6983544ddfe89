//! dhoit's methods in an application's own renderer, one protocol for all of them ([`Oit`]):
//! the application builds one transparent pipeline a phase ([`Oit::phases`]) on the module
//! dhoit gives it ([`Oit::store_module`]: dhoit's own pass code, its group at the index the
//! application chooses, its fragment entry the function the application's fragment shader
//! calls), and each frame [`Oit::record`] writes every pass of the frame into the
//! application's command encoder, calling it back for each geometry pass with the render pass
//! open and dhoit's group to set. The application submits, once, when it likes: a frame makes
//! no submission, no wait and no readback of its own, so frames can be in flight one after
//! another, several in one submission.
//!
//! Every method is a client of the same frame engine `Gpu::render` runs (`AppDraws`, the
//! engine's [`Geometry`]): the image is dhoit's own for the same fragments. What a frame
//! decides from its own count is decided on the device ([`crate::plan`]); the buffers it sizes
//! before the count follow the counts of earlier frames, which [`Oit::finished`] reads back
//! without waiting (see [`FrameReport`]).

use std::cell::RefCell;

use super::bindings::{self, oit_phase};
use super::passes::{Geometry, GeometryPass, Phase, Resolve, at, view_at};
use super::shader::{compute_pipeline, module_from};
use super::stream::{AppMethod, FrameReport, Stream};
use super::{Capture, Gpu, frame_params};
use crate::budget::{Budget, Occupancy};
use crate::composite::{MboitParams, WboitParams};
use crate::error::{Error, GpuError, Result};
use crate::importance::VkbParams;
use crate::mlp::Mlp;
use crate::wgsl::{MLAB_MAX_ROWS, PIXEL_GROUP, grid, shaders};

/// The formats the resolves write onto (storage textures every device supports).
pub const TARGET_FORMATS: [wgpu::TextureFormat; 3] = [
    wgpu::TextureFormat::Rgba8Unorm,
    wgpu::TextureFormat::Rgba16Float,
    wgpu::TextureFormat::Rgba32Float,
];

/// The application's textures a frame reads and writes, each of the frame's size.
#[derive(Clone, Copy)]
pub struct FrameTargets<'t> {
    /// The opaque pass's depth (a depth format, `TEXTURE_BINDING` and `RENDER_ATTACHMENT`):
    /// the occluder. dhoit's geometry passes attach it read-only and test it in the shader.
    pub depth: &'t wgpu::TextureView,
    /// The opaque image the transparency composites over (a float-sampled texture,
    /// `TEXTURE_BINDING`).
    pub under: &'t wgpu::TextureView,
    /// What the resolve writes: a storage texture (`STORAGE_BINDING`) of the format the method
    /// was made for (one of [`TARGET_FORMATS`]); it may be a copy the application blits or
    /// presents.
    pub target: &'t wgpu::TextureView,
}

/// What the application's draw callback gets for one of the frame's geometry passes, in the
/// render pass dhoit opened: which pass (the pipeline to set) and dhoit's group, to set at the
/// index the application built the module for.
pub struct PhaseDraw<'a> {
    pub phase: Phase,
    pub group: &'a wgpu::BindGroup,
}

/// The application's draw callback: it sets its pipeline for `draw.phase`, its own groups and
/// `draw.group` at dhoit's index, and draws its transparent geometry.
pub type DrawFn<'d> = dyn FnMut(&mut wgpu::RenderPass<'_>, PhaseDraw<'_>) + 'd;

/// One protocol for every method in an application's renderer: the budgeted linked list
/// ([`ListOit`]), FKB ([`KBufferOit`]), the exact A-buffer and MLAB ([`ExactOit`]), DKB and
/// VKB ([`AllocatedOit`]), WBOIT and MBOIT ([`BlendedOit`]).
///
/// ```
/// use dhoit_runtime::budget::Budget;
/// use dhoit_runtime::gpu::{self, AllocatedOit, Gpu, Oit};
/// use dhoit_runtime::mlp::Mlp;
///
/// let instance = wgpu::Instance::default();
/// let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
/// let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
///     required_features: gpu::required_features(),
///     required_limits: gpu::required_limits(),
///     ..Default::default()
/// }))
/// .unwrap();
/// // Once a device: dhoit's passes, built once and shared by every method made from it.
/// let gpu = Gpu::on_device(device.clone(), queue.clone(), &adapter.get_info())?;
/// let weights = Mlp::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/weights.safetensors").as_ref())?;
/// let format = wgpu::TextureFormat::Rgba16Float;
/// let mut oit: Box<dyn Oit> =
///     Box::new(AllocatedOit::dkb(&gpu, (64, 48), &weights, Budget::parse("25%")?, format)?);
/// // One transparent pipeline a phase: dhoit's module at group 1, then the application's code;
/// // its depth-stencil state and colour targets are dhoit's.
/// for &phase in oit.phases() {
///     let src = oit.store_module(phase, 1)
///         + "@fragment fn fs(@builtin(position) p: vec4<f32>) { oit_store(p, vec4<f32>(0.2, 0.4, 0.6, 0.5)); }";
///     let _module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
///         label: None,
///         source: wgpu::ShaderSource::Wgsl(src.into()),
///     });
///     let _layout = oit.bind_group_layout(phase); // the pipeline layout's group 1
///     let _depth = oit.depth_stencil(wgpu::TextureFormat::Depth32Float);
///     let _targets = oit.color_targets(phase);
/// }
/// // Per frame, into the application's encoder (its opaque pass before):
/// // oit.record(&mut encoder, &FrameTargets { depth, under, target }, &mut |pass, draw| {
/// //     /* set the pipeline for draw.phase, draw.group at 1, draw */ })?;
/// // queue.submit(...); later, oit.finished(false) reports the frames that have run.
/// # Ok::<(), dhoit_runtime::Error>(())
/// ```
pub trait Oit {
    /// The method, as dhoit's command line names it ("dkb", "linked-list", ...).
    fn method(&self) -> &'static str;

    /// The frame's size.
    fn size(&self) -> (u32, u32);

    /// The format of the targets the resolve writes.
    fn target_format(&self) -> wgpu::TextureFormat;

    /// The geometry passes a frame draws, each needing one application pipeline, in the order
    /// a frame first draws them (DKB's features pass may repeat: once a batch of its records).
    fn phases(&self) -> &[Phase];

    /// The WGSL the application's transparent fragment shader for `phase` starts with: dhoit's
    /// pass, its bindings at `group`, and the function the application's fragment entry calls
    /// with its fragment's `@builtin(position)` and straight (not premultiplied) colour:
    /// `oit_store(frag_coord, color)` for the methods that store fragments
    /// (`oit_store_facing(frag_coord, color, facing)` hands VKB the triangle's `|n . v|`;
    /// `oit_store_ordered(frag_coord, color, order)` hands MLAB its submission index), and
    /// for WBOIT and MBOIT `oit_targets(frag_coord, color) -> OitTargets`, which the entry
    /// returns. It declares dhoit's names (`Params`, `VertexOut`, `params` and the pass's
    /// buffers among them): the application's own must differ.
    fn store_module(&self, phase: Phase, group: u32) -> String;

    /// The layout of `phase`'s group, for the application's pipeline layout of that phase.
    fn bind_group_layout(&self, phase: Phase) -> &wgpu::BindGroupLayout;

    /// The colour targets of the application's pipeline for `phase`: none for the passes that
    /// store fragments, dhoit's targets (formats and blend states) for WBOIT's and MBOIT's.
    fn color_targets(&self, phase: Phase) -> Vec<Option<wgpu::ColorTargetState>>;

    /// The depth-stencil state of every phase's pipeline, for the application's depth format:
    /// dhoit attaches the opaque depth read-only (no test in the fixed function: the pass tests
    /// it in the shader, as dhoit's own passes do). The method remembers the formats it was
    /// asked for: a frame whose depth texture is of none of them is refused before anything is
    /// recorded ([`GpuError::FrameTexture`]), where wgpu would reject the whole encoder at
    /// submission.
    fn depth_stencil(&self, depth_format: wgpu::TextureFormat) -> wgpu::DepthStencilState;

    /// Records one frame into `enc`: every pass of it, each geometry pass through `draw` in a
    /// render pass dhoit opens (the opaque depth its read-only attachment, WBOIT's and MBOIT's
    /// targets its colour attachments), the resolve over `frame.under` onto `frame.target`.
    /// No submission and no wait: the application submits `enc` when it likes. Textures of
    /// another size or format than the method's are refused, by name, before anything is
    /// recorded.
    fn record(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        frame: &FrameTargets<'_>,
        draw: &mut DrawFn<'_>,
    ) -> Result<()>;

    /// Frames of `size` from the next on: the buffers are made again, the passes kept.
    fn resize(&mut self, size: (u32, u32)) -> Result<()>;

    /// The budget from the next frame on (DKB and VKB: bytes, slots a pixel or a share of
    /// each frame's fragments; FKB: slots a pixel, k; the list: bytes or fragments a pixel,
    /// its nodes; MLAB: its rows, as slots a pixel); the methods without a budget refuse it.
    fn set_budget(&mut self, budget: Budget) -> Result<()>;

    /// Whether the frames to come keep colours above white (off when made). On, a fragment's
    /// RGB is stored as 8 bits times a power of two up to 2^15 (its exponent in a word beside
    /// its key: 4 bytes a stored fragment, node, slot or pool word more; the k-buffers draw one
    /// more geometry pass,
    /// [`Phase::CaptureTints`], so [`Oit::phases`] changes), and the resolve writes what
    /// blends onto the float target: a fragment of colour 8.0 arrives as 8.0. Off, each
    /// fragment's colour clamps at white as it is stored. A byte budget given before is
    /// resolved again. Refused onto an `Rgba8Unorm` target, which holds nothing above white.
    fn set_hdr(&mut self, on: bool) -> Result<()>;

    /// Sizes the buffers of the frames to come for frames of exactly `occupancy` (what an
    /// application knows of its scene: give it an upper bound): the A-buffer's and MLAB's pool
    /// holds its fragments, DKB's and VKB's what their budget reserves for it (no more than its
    /// exact A-buffer, with `exact_when_cheaper`). A frame with more fragments than that is
    /// short ([`FrameReport::pool_short`]: the A-buffer and MLAB leave out the pixels past the
    /// pool's end, DKB and VKB keep fewer fragments in slots and more in the tails), and the
    /// frames after it are sized from its count. Without it, the method's first frame (and
    /// the first after a resize) counts its fragments first, in a submission of its own that
    /// it waits for, and is sized from that count; the frames after it from the counts the
    /// reports read back, with a quarter of headroom, and never wait.
    fn expect(&mut self, occupancy: Occupancy);

    /// The next frame starts a new shot (the camera jumped, the scene changed): DKB's frame
    /// then marks its own records and draws its features pass (three geometry passes: the
    /// count, [`Phase::Features`], the capture) rather than gather its statistics with its
    /// count for the pixels the frame before marked, as every frame after a frame of its size
    /// does. A resize is a cut of its own; a budget change is none. The other methods keep
    /// nothing from one frame for the next: for them it changes nothing.
    fn cut(&mut self);

    /// Bytes of the buffers the last frame recorded held (0 before the first).
    fn allocated_bytes(&self) -> u64;

    /// Reports of the frames recorded so far whose submission has run, in order, each once
    /// (a frame recorded but not yet submitted, or still running, is left for a later call;
    /// at most the last 16 are kept). With `wait`, it waits for the submitted ones. Their
    /// counts size the buffers of the frames to come. It may be called any time: its reports
    /// are mapped when their submission has run, never before.
    fn finished(&mut self, wait: bool) -> Result<Vec<FrameReport>>;
}

/// A method in an application's renderer: its frames ([`Stream`]), the format it resolves
/// onto and the layouts of its phases' groups.
struct AppFrame {
    stream: Stream,
    format: wgpu::TextureFormat,
    layouts: Vec<(Phase, wgpu::BindGroupLayout)>,
    /// The depth formats the application's pipelines were built for (`Oit::depth_stencil`).
    depth_formats: std::sync::Mutex<Vec<wgpu::TextureFormat>>,
}

impl AppFrame {
    fn new(
        gpu: &Gpu,
        size: (u32, u32),
        method: AppMethod,
        budget: Option<Budget>,
        format: wgpu::TextureFormat,
    ) -> Result<AppFrame> {
        check_target_format(format, method.name())?;
        let stream = Stream::new(gpu, size, method, budget)?;
        // Every phase's layout, with either capture.
        let mut phases = Vec::new();
        for (capture, tints) in [Capture::Wide, Capture::Portable]
            .into_iter()
            .flat_map(|c| [(c, false), (c, true)])
        {
            phases.extend(stream.method.phases(capture, tints));
        }
        phases.sort_by_key(|p| *p as u8);
        phases.dedup();
        let layouts = phases
            .iter()
            .map(|&phase| {
                (
                    phase,
                    phase_layout(&stream.gpu.device, &stream.method, phase),
                )
            })
            .collect();
        Ok(AppFrame {
            stream,
            format,
            layouts,
            depth_formats: Default::default(),
        })
    }

    /// The depth-stencil state of every phase's pipeline for `format`, which frames then expect
    /// their depth texture in.
    fn depth_stencil(&self, format: wgpu::TextureFormat) -> wgpu::DepthStencilState {
        let mut formats = self.depth_formats.lock().unwrap_or_else(|e| e.into_inner());
        if !formats.contains(&format) {
            formats.push(format);
        }
        wgpu::DepthStencilState {
            format,
            depth_write_enabled: Some(false),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: Default::default(),
            bias: Default::default(),
        }
    }

    /// Refuses textures of another size or format than the frame's, naming both.
    fn check_targets(&self, t: &FrameTargets) -> Result<()> {
        let (w, h) = self.stream.size;
        let method = self.stream.method.name();
        let bad = |texture, expected: String, got: String| {
            Err(GpuError::FrameTexture {
                method,
                texture,
                expected,
                got,
            }
            .into())
        };
        for (texture, view) in [
            ("opaque depth", t.depth),
            ("opaque image", t.under),
            ("target", t.target),
        ] {
            let tex = view.texture();
            let got = (tex.width(), tex.height());
            if got != (w, h) {
                return bad(
                    texture,
                    format!("{w}x{h} frames"),
                    format!("{}x{} {:?}", got.0, got.1, tex.format()),
                );
            }
        }
        let depth = t.depth.texture();
        let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::RENDER_ATTACHMENT;
        if !depth.format().is_depth_stencil_format() || !depth.usage().contains(usage) {
            return bad(
                "opaque depth",
                "a depth texture with TEXTURE_BINDING and RENDER_ATTACHMENT".into(),
                format!("{:?} with {:?}", depth.format(), depth.usage()),
            );
        }
        // Its pipelines' depth format (the attachment's must be the pipeline's, or wgpu rejects
        // the submission).
        let formats = self
            .depth_formats
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        if !formats.is_empty() && !formats.contains(&depth.format()) {
            return bad(
                "opaque depth",
                format!(
                    "a depth texture of {formats:?}, the format its pipelines were built for (Oit::depth_stencil)"
                ),
                format!("{:?}", depth.format()),
            );
        }
        let under = t.under.texture();
        let float = matches!(
            under.format().sample_type(None, None),
            Some(wgpu::TextureSampleType::Float { .. })
        );
        if !float || !under.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING) {
            return bad(
                "opaque image",
                "a float texture with TEXTURE_BINDING".into(),
                format!("{:?} with {:?}", under.format(), under.usage()),
            );
        }
        let target = t.target.texture();
        if target.format() != self.format
            || !target
                .usage()
                .contains(wgpu::TextureUsages::STORAGE_BINDING)
        {
            return bad(
                "target",
                format!("{:?} with STORAGE_BINDING", self.format),
                format!("{:?} with {:?}", target.format(), target.usage()),
            );
        }
        Ok(())
    }

    fn record(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        frame: &FrameTargets<'_>,
        draw: &mut DrawFn<'_>,
    ) -> Result<()> {
        self.check_targets(frame)?;
        let params = crate::wgsl::Params {
            hdr: self.stream.hdr.into(),
            ..frame_params(None, self.stream.size, [0.0; 3])
        };
        if self.stream.uncounted() {
            // The first frame of a size counts first: its geometry drawn once more, in a
            // submission of dhoit's own, over an occluder at the far plane of the application's
            // depth format (its opaque pass has not run yet): every fragment in view counts.
            let depth = frame.depth.texture();
            let far = super::buffers::frame_texture(
                &self.stream.gpu.device,
                "count first.depth",
                self.stream.size,
                depth.format(),
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            );
            let far_view = far.create_view(&Default::default());
            let counting = FrameTargets {
                depth: &far_view,
                ..*frame
            };
            let app = AppDraws {
                draw: RefCell::new(&mut *draw),
                layouts: &self.layouts,
                frame: &counting,
                format: self.format,
            };
            let clear = |_: &Gpu, enc: &mut wgpu::CommandEncoder| {
                enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("count first: the far plane"),
                    color_attachments: &[],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &far_view,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(1.0),
                            store: wgpu::StoreOp::Store,
                        }),
                        stencil_ops: None,
                    }),
                    ..Default::default()
                });
            };
            self.stream.count_first(&app, &clear, params)?;
        }
        let app = AppDraws {
            draw: RefCell::new(draw),
            layouts: &self.layouts,
            frame,
            format: self.format,
        };
        self.stream.record(enc, &app, params)
    }

    fn set_hdr(&mut self, on: bool) -> Result<()> {
        if on && self.format == wgpu::TextureFormat::Rgba8Unorm {
            return Err(Error::Invalid(format!(
                "{} resolves onto {:?}, which holds no colour above white: colours above white need a float target",
                self.stream.method.name(),
                self.format
            )));
        }
        let s = &mut self.stream;
        let was = (s.hdr, s.words);
        // An application's fragments are untinted: their words hold exponents alone.
        (s.hdr, s.words) = (on, crate::budget::Words::of(false, on));
        if let Some(b) = s.asked
            && let Err(e) = s.set_budget(b)
        {
            (s.hdr, s.words) = was;
            return Err(e);
        }
        Ok(())
    }

    fn store_module(&self, phase: Phase, group: u32) -> String {
        self.check_phase(phase);
        match blend_pass(&self.stream.method, phase) {
            Some(pass) => shaders::application_blend_pass(pass.pass, pass.entry, group)
                .expect("a blended pass"),
            None => {
                let (pass, defs) = storing_pass(phase);
                shaders::application_pass(pass, defs, group).expect("a geometry pass")
            }
        }
    }

    fn check_phase(&self, phase: Phase) {
        assert!(
            self.stream.phases().contains(&phase),
            "{phase:?} is not a pass of {} (its phases: {:?})",
            self.stream.method.name(),
            self.stream.phases()
        );
    }

    fn bind_group_layout(&self, phase: Phase) -> &wgpu::BindGroupLayout {
        self.check_phase(phase);
        &self
            .layouts
            .iter()
            .find(|(p, _)| *p == phase)
            .expect("a layout a phase")
            .1
    }

    fn color_targets(&self, phase: Phase) -> Vec<Option<wgpu::ColorTargetState>> {
        self.check_phase(phase);
        blend_pass(&self.stream.method, phase).map_or_else(Vec::new, |p| p.color_targets())
    }
}

/// A storing phase's pass (`wgsl::shaders::PASSES`) and the definitions its variant gives.
fn storing_pass(phase: Phase) -> (&'static str, &'static [(&'static str, shaders::Value)]) {
    match phase {
        Phase::Count => ("abuffer_count", &[]),
        Phase::Store => ("abuffer_store", &[]),
        Phase::Features => ("features", &[]),
        Phase::VkbCount => ("vkb_count", &[]),
        Phase::Capture => ("capture", &[]),
        Phase::CaptureFits => ("capture", &[shaders::EVERY_FRAGMENT_FITS]),
        Phase::CountFeatures => ("count_features", &[]),
        Phase::CaptureDepths => ("capture_depths", &[]),
        Phase::CaptureColours => ("capture_colours", &[]),
        Phase::ListStore => ("list_store", &[]),
        Phase::CaptureTints => ("capture_tints", &[]),
        Phase::WboitAccumulate | Phase::MboitMoments | Phase::MboitAccumulate => {
            unreachable!("{phase:?} blends into targets")
        }
    }
}

/// A blended phase's pass, for the method's parameters (MBOIT's moments).
fn blend_pass(method: &AppMethod, phase: Phase) -> Option<super::blend::BlendPass> {
    match (method, phase) {
        (_, Phase::WboitAccumulate) => Some(super::blend::BlendPass::WBOIT),
        (AppMethod::Mboit(m), Phase::MboitMoments | Phase::MboitAccumulate) => {
            let [moments, accumulate] =
                super::blend::BlendPass::mboit(m.moments).expect("checked when made");
            Some(match phase {
                Phase::MboitMoments => moments,
                _ => accumulate,
            })
        }
        _ => None,
    }
}

/// What a phase's group holds before the parameters (14) and the opaque depth (15).
#[derive(Clone, Copy)]
enum Binding {
    Read,
    ReadWrite,
    Uniform,
    /// A float texture (one of MBOIT's targets the accumulation reads).
    Texture,
    /// A binding the pass declares and does not read (absent from its group).
    Unused,
}

/// A phase's group 1, binding by binding (as its WGSL declares it).
fn bindings_of(method: &AppMethod, phase: Phase) -> Vec<Binding> {
    use Binding::*;
    match phase {
        Phase::Count => vec![ReadWrite],
        Phase::Store => vec![Read, ReadWrite, ReadWrite, ReadWrite, ReadWrite],
        // The record marks, the records, the optical depths, the batch; the counts.
        Phase::Features => {
            vec![Read, ReadWrite, Uniform, Read]
        }
        Phase::CountFeatures => {
            vec![Read, ReadWrite, Uniform, Unused, ReadWrite]
        }
        Phase::VkbCount => vec![ReadWrite, ReadWrite],
        Phase::Capture | Phase::CaptureFits | Phase::CaptureDepths | Phase::CaptureColours => {
            vec![Read, ReadWrite, ReadWrite, ReadWrite, ReadWrite]
        }
        Phase::ListStore => vec![ReadWrite; 5],
        // The bases, the slots, the per-pixel tails' sums, the counts (at 4) and the tints.
        Phase::CaptureTints => vec![Read, ReadWrite, ReadWrite, Unused, ReadWrite, ReadWrite],
        Phase::WboitAccumulate => vec![],
        Phase::MboitMoments => vec![Uniform],
        Phase::MboitAccumulate => {
            let reads = blend_pass(method, Phase::MboitMoments).map_or(0, |p| p.targets.len());
            vec![Texture; reads]
        }
    }
}

/// A phase's group layout: the pass's bindings, the parameters and the opaque depth
/// (oit_phase.wgsl's).
fn phase_layout(device: &wgpu::Device, method: &AppMethod, phase: Phase) -> wgpu::BindGroupLayout {
    let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty,
        count: None,
    };
    let buffer = |ty| wgpu::BindingType::Buffer {
        ty,
        has_dynamic_offset: false,
        min_binding_size: None,
    };
    let texture = |sample_type| wgpu::BindingType::Texture {
        sample_type,
        view_dimension: wgpu::TextureViewDimension::D2,
        multisampled: false,
    };
    let mut entries: Vec<_> = bindings_of(method, phase)
        .into_iter()
        .enumerate()
        .filter_map(|(i, b)| {
            let ty = match b {
                Binding::Read => buffer(wgpu::BufferBindingType::Storage { read_only: true }),
                Binding::ReadWrite => buffer(wgpu::BufferBindingType::Storage { read_only: false }),
                Binding::Uniform => buffer(wgpu::BufferBindingType::Uniform),
                Binding::Texture => texture(wgpu::TextureSampleType::Float { filterable: false }),
                Binding::Unused => return None,
            };
            Some(entry(i as u32, ty))
        })
        .collect();
    let (params, depth) = (oit_phase::PARAMS, oit_phase::OIT_OPAQUE_DEPTH);
    entries.push(entry(params, buffer(wgpu::BufferBindingType::Uniform)));
    entries.push(entry(depth, texture(wgpu::TextureSampleType::Depth)));
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(&format!("dhoit {} {phase:?}", method.name())),
        entries: &entries,
    })
}

/// The WGSL name of `format`, one of [`TARGET_FORMATS`]; another is refused, naming `what`
/// resolves.
pub(super) fn check_target_format(format: wgpu::TextureFormat, what: &str) -> Result<&'static str> {
    match format {
        wgpu::TextureFormat::Rgba8Unorm => Ok("rgba8unorm"),
        wgpu::TextureFormat::Rgba16Float => Ok("rgba16float"),
        wgpu::TextureFormat::Rgba32Float => Ok("rgba32float"),
        other => Err(Error::Invalid(format!(
            "{what} resolves onto {TARGET_FORMATS:?}, not {other:?}"
        ))),
    }
}

/// A resolve's `onto` entry writing a target of `format`, built once a device and format
/// (shared by every method forked from one [`Gpu`]).
fn onto_pipeline(
    gpu: &Gpu,
    resolve: Resolve,
    format: wgpu::TextureFormat,
) -> wgpu::ComputePipeline {
    let mut built = gpu.pipelines.onto.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(p) = built.get(&(resolve, format)) {
        return p.clone();
    }
    let (pass, entry, _) = resolve.onto();
    let name = check_target_format(format, "dhoit").expect("checked when made");
    let mut defs = vec![("OntoTexture", shaders::Value::StorageTexture(name))];
    if resolve.fits() {
        defs.push(shaders::EVERY_FRAGMENT_FITS);
    }
    let src = shaders::source_with(pass, &defs).expect("a resolve and its definitions");
    let label = format!("{pass} ({entry}, {format:?})");
    let m = module_from(&gpu.device, &label, src);
    let p = compute_pipeline(&gpu.device, &label, &m, entry);
    built.insert((resolve, format), p.clone());
    p
}

/// An application's frame, as the engine's client: its draws in dhoit's geometry passes, its
/// image and target around the resolve.
struct AppDraws<'a, 'd> {
    draw: RefCell<&'a mut DrawFn<'d>>,
    layouts: &'a [(Phase, wgpu::BindGroupLayout)],
    frame: &'a FrameTargets<'a>,
    format: wgpu::TextureFormat,
}

impl Geometry for AppDraws<'_, '_> {
    fn draw(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        pass: GeometryPass<'_>,
        params: &wgpu::Buffer,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) {
        let layout = &self
            .layouts
            .iter()
            .find(|(p, _)| *p == pass.phase)
            .unwrap_or_else(|| {
                panic!(
                    "the engine drew {:?}, not a phase of the method",
                    pass.phase
                )
            })
            .1;
        let colors = pass.color_attachments();
        let entries: Vec<wgpu::BindGroupEntry> = pass
            .group
            .into_iter()
            .chain([
                at(bindings::oit_phase::PARAMS, params),
                view_at(bindings::oit_phase::OIT_OPAQUE_DEPTH, self.frame.depth),
            ])
            .collect();
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(pass.name),
            layout,
            entries: &entries,
        });
        let mut rp = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(pass.name),
            color_attachments: &colors,
            // The opaque depth, read-only: the application's pipeline tests nothing in the
            // fixed function (Oit::depth_stencil); the pass tests it in the shader.
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: self.frame.depth,
                depth_ops: None,
                stencil_ops: None,
            }),
            timestamp_writes: timestamps,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        (self.draw.borrow_mut())(
            &mut rp,
            PhaseDraw {
                phase: pass.phase,
                group: &group,
            },
        );
    }

    fn resolve(
        &self,
        gpu: &Gpu,
        cpass: &mut wgpu::ComputePass,
        resolve: Resolve,
        _own: &wgpu::ComputePipeline,
        group: Vec<wgpu::BindGroupEntry<'_>>,
    ) {
        let onto = onto_pipeline(gpu, resolve, self.format);
        let (_, _, [under_at, target_at]) = resolve.onto();
        let entries: Vec<wgpu::BindGroupEntry> = group
            .into_iter()
            .chain([
                view_at(under_at, self.frame.under),
                view_at(target_at, self.frame.target),
            ])
            .collect();
        let g = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dhoit resolve"),
            layout: &onto.get_bind_group_layout(0),
            entries: &entries,
        });
        let t = self.frame.target.texture();
        let (gx, gy) = grid(t.width() * t.height(), PIXEL_GROUP);
        cpass.set_pipeline(&onto);
        cpass.set_bind_group(0, &g, &[]);
        cpass.dispatch_workgroups(gx, gy, 1);
    }
}

macro_rules! oit_of_app_frame {
    ($t:ty) => {
        impl Oit for $t {
            fn method(&self) -> &'static str {
                self.0.stream.method.name()
            }
            fn size(&self) -> (u32, u32) {
                self.0.stream.size
            }
            fn target_format(&self) -> wgpu::TextureFormat {
                self.0.format
            }
            fn phases(&self) -> &[Phase] {
                self.0.stream.phases()
            }
            fn store_module(&self, phase: Phase, group: u32) -> String {
                self.0.store_module(phase, group)
            }
            fn bind_group_layout(&self, phase: Phase) -> &wgpu::BindGroupLayout {
                self.0.bind_group_layout(phase)
            }
            fn color_targets(&self, phase: Phase) -> Vec<Option<wgpu::ColorTargetState>> {
                self.0.color_targets(phase)
            }
            fn depth_stencil(&self, depth_format: wgpu::TextureFormat) -> wgpu::DepthStencilState {
                self.0.depth_stencil(depth_format)
            }
            fn record(
                &mut self,
                enc: &mut wgpu::CommandEncoder,
                frame: &FrameTargets<'_>,
                draw: &mut DrawFn<'_>,
            ) -> Result<()> {
                self.0.record(enc, frame, draw)
            }
            fn resize(&mut self, size: (u32, u32)) -> Result<()> {
                self.0.stream.resize(size)
            }
            fn set_budget(&mut self, budget: Budget) -> Result<()> {
                self.0.stream.set_budget(budget)
            }
            fn set_hdr(&mut self, on: bool) -> Result<()> {
                self.0.set_hdr(on)
            }
            fn expect(&mut self, occupancy: Occupancy) {
                self.0.stream.expect(occupancy);
            }
            fn cut(&mut self) {
                self.0.stream.cut();
            }
            fn allocated_bytes(&self) -> u64 {
                self.0.stream.last_bytes
            }
            fn finished(&mut self, wait: bool) -> Result<Vec<FrameReport>> {
                self.0.stream.finished(wait)
            }
        }
    };
}

/// The budgeted linked list, as Bevy ships it: a pool of nodes handed out first come, each
/// pixel's nearest `sorted` blended in order over the rest's tail, what overflows dropped.
/// One geometry pass ([`Phase::ListStore`]).
pub struct ListOit(AppFrame);

impl ListOit {
    /// A list of `nodes` fragments in all (Bevy's default: 4 a pixel), the nearest `sorted` of
    /// a pixel sorted (1 to [`crate::composite::LIST_MAX_SORTED`]), resolving onto targets of
    /// `format`.
    pub fn new(
        gpu: &Gpu,
        size: (u32, u32),
        nodes: u64,
        sorted: u32,
        format: wgpu::TextureFormat,
    ) -> Result<ListOit> {
        crate::composite::check_list_sorted(sorted)?;
        if nodes == 0 {
            return Err(Error::Invalid(
                "the linked list takes 1 node or more".into(),
            ));
        }
        let method = AppMethod::List { nodes, sorted };
        Ok(ListOit(AppFrame::new(gpu, size, method, None, format)?))
    }

    /// The nodes the pool holds.
    pub fn nodes(&self) -> u64 {
        match self.0.stream.method {
            AppMethod::List { nodes, .. } => nodes,
            _ => unreachable!("a list"),
        }
    }
}

/// The fixed k-buffer (FKB): k slots a pixel, the rest in a tail. One geometry pass
/// ([`Phase::Capture`]).
pub struct KBufferOit(AppFrame);

impl KBufferOit {
    /// FKB of `k` slots a pixel (at least 1), resolving onto targets of `format`.
    pub fn new(
        gpu: &Gpu,
        size: (u32, u32),
        k: u32,
        format: wgpu::TextureFormat,
    ) -> Result<KBufferOit> {
        if k == 0 {
            return Err(Error::Invalid("FKB keeps at least 1 slot a pixel".into()));
        }
        Ok(KBufferOit(AppFrame::new(
            gpu,
            size,
            AppMethod::Fkb { k },
            None,
            format,
        )?))
    }

    /// With `capture`, the frames to come insert their fragments as it says
    /// ([`Capture::Portable`]: two passes with 32-bit atomics, [`Oit::phases`] then draws
    /// [`Phase::CaptureDepths`] and [`Phase::CaptureColours`] in place of [`Phase::Capture`]).
    /// The images are the same. A device without 64-bit atomics captures in the portable
    /// passes whatever `capture` says.
    pub fn with_capture(mut self, capture: Capture) -> KBufferOit {
        self.0.stream.set_capture(capture);
        self
    }

    /// The slots a pixel.
    pub fn k(&self) -> u32 {
        match self.0.stream.method {
            AppMethod::Fkb { k } => k,
            _ => unreachable!("FKB"),
        }
    }
}

/// The exact A-buffer (paper 004), and MLAB blended from its fragments in submission order.
/// Two geometry passes: the count, then the store ([`Phase::Count`], [`Phase::Store`]). Its
/// pool is sized before each frame's count, from earlier frames' (with some headroom): a
/// frame with more fragments than the pool keeps the pixels whose fragments it holds whole, in
/// pixel order, and says so ([`FrameReport::pool_short`]); the next frames' pool is larger.
pub struct ExactOit(AppFrame);

impl ExactOit {
    /// The exact A-buffer, resolving onto targets of `format`.
    pub fn new(gpu: &Gpu, size: (u32, u32), format: wgpu::TextureFormat) -> Result<ExactOit> {
        Ok(ExactOit(AppFrame::new(
            gpu,
            size,
            AppMethod::Abuffer,
            None,
            format,
        )?))
    }

    /// MLAB with `rows` blending rows (1 to [`MLAB_MAX_ROWS`]), as dhoit computes it: the
    /// A-buffer's fragments merged in the order of the indices the application hands
    /// `oit_store_ordered(frag_coord, color, order)` (WebGPU has no fragment shader interlock
    /// to merge in the fragment stage). Its memory is the A-buffer's and 4 bytes a fragment.
    pub fn mlab(
        gpu: &Gpu,
        size: (u32, u32),
        rows: u32,
        format: wgpu::TextureFormat,
    ) -> Result<ExactOit> {
        if rows == 0 || rows > MLAB_MAX_ROWS {
            return Err(Error::Invalid(format!(
                "MLAB on the GPU takes 1 to {MLAB_MAX_ROWS} rows, not {rows}"
            )));
        }
        let method = AppMethod::Mlab { rows };
        Ok(ExactOit(AppFrame::new(gpu, size, method, None, format)?))
    }

    /// MLAB's rows, where this A-buffer blends as MLAB does.
    pub fn mlab_rows(&self) -> Option<u32> {
        match self.0.stream.method {
            AppMethod::Mlab { rows } => Some(rows),
            _ => None,
        }
    }
}

/// The allocated k-buffers: DKB (the network's k per pixel within a budget) and VKB (paper
/// 002's importance maps). DKB draws [`Phase::Count`], [`Phase::Features`] (once a batch of
/// its records) and [`Phase::Capture`]; VKB [`Phase::VkbCount`] and [`Phase::Capture`]. Where
/// a frame's pool holds every fragment, the frame keeps them all (the exact image, with
/// `exact_when_cheaper`, the default).
pub struct AllocatedOit(AppFrame);

impl AllocatedOit {
    /// DKB with the network `weights` (deployed at their precision) at `budget` (bytes, slots a
    /// pixel or a share of each frame's fragments, as [`Budget::parse`] reads them),
    /// resolving onto targets of `format`. Refuses a precision the device cannot compute and a
    /// byte budget below DKB's fixed bytes, before anything is built.
    pub fn dkb(
        gpu: &Gpu,
        size: (u32, u32),
        weights: &Mlp,
        budget: Budget,
        format: wgpu::TextureFormat,
    ) -> Result<AllocatedOit> {
        let method = AppMethod::Dkb(Box::new(weights.clone()));
        Ok(AllocatedOit(AppFrame::new(
            gpu,
            size,
            method,
            Some(budget),
            format,
        )?))
    }

    /// VKB with `params` (paper 002's), as [`AllocatedOit::dkb`]. Its importance reads each
    /// pixel's nearest fragment's facing, `|n . v|` of its triangle: the application hands it
    /// with `oit_store_facing(frag_coord, color, facing)` (`oit_store` hands 1, face-on).
    pub fn vkb(
        gpu: &Gpu,
        size: (u32, u32),
        params: VkbParams,
        budget: Budget,
        format: wgpu::TextureFormat,
    ) -> Result<AllocatedOit> {
        Ok(AllocatedOit(AppFrame::new(
            gpu,
            size,
            AppMethod::Vkb(params),
            Some(budget),
            format,
        )?))
    }

    /// With `exact` false, every frame runs the method at its budget, even where its pool
    /// holds every fragment (on by default: a k-buffer never costs more than the exact
    /// answer, and where the memory it holds has room for it, the frame is exact).
    pub fn exact_when_cheaper(mut self, exact: bool) -> AllocatedOit {
        self.0.stream.decision.exact_when_cheaper = exact;
        self
    }

    /// With `capture`, the frames to come insert their fragments as it says (as
    /// [`KBufferOit::with_capture`]).
    pub fn with_capture(mut self, capture: Capture) -> AllocatedOit {
        self.0.stream.set_capture(capture);
        self
    }
}

/// The blended methods, as engines ship them: WBOIT (McGuire and Bavoil) and MBOIT
/// (Munstermann et al.). Their geometry passes write dhoit's targets through the device's
/// blending: the application's pipeline for a phase has [`Oit::color_targets`] and its
/// fragment entry returns `oit_targets(frag_coord, color)`. WBOIT draws
/// [`Phase::WboitAccumulate`], MBOIT [`Phase::MboitMoments`] then [`Phase::MboitAccumulate`].
pub struct BlendedOit(AppFrame);

impl BlendedOit {
    /// WBOIT with `params` (its weight function and planes), resolving onto targets of
    /// `format`.
    pub fn wboit(
        gpu: &Gpu,
        size: (u32, u32),
        params: WboitParams,
        format: wgpu::TextureFormat,
    ) -> Result<BlendedOit> {
        params.check()?;
        let method = AppMethod::Wboit(params);
        Ok(BlendedOit(AppFrame::new(gpu, size, method, None, format)?))
    }

    /// MBOIT with `params` (4, 6 or 8 power moments), resolving onto targets of `format`.
    /// Needs a device with `FLOAT32_BLENDABLE` and, for six and eight moments, colour
    /// attachments of 28 and 36 bytes a sample: refused, named, without them.
    pub fn mboit(
        gpu: &Gpu,
        size: (u32, u32),
        params: MboitParams,
        format: wgpu::TextureFormat,
    ) -> Result<BlendedOit> {
        let [moments, _] = super::blend::BlendPass::mboit(params.moments)?;
        if !super::blend::mboit_fits(&gpu.device, &moments) {
            return Err(GpuError::DeviceLacks {
                adapter: gpu.adapter().to_string(),
                missing: super::blend::mboit_lacks(&gpu.device, params.moments, &moments),
            }
            .into());
        }
        let method = AppMethod::Mboit(params);
        Ok(BlendedOit(AppFrame::new(gpu, size, method, None, format)?))
    }

    /// WBOIT's weight function and planes for the frames to come (eqs. 7-9 read the
    /// view-space distance through the camera's planes); MBOIT refuses it.
    pub fn set_wboit(&mut self, params: WboitParams) -> Result<()> {
        params.check()?;
        match &mut self.0.stream.method {
            AppMethod::Wboit(w) => {
                *w = params;
                Ok(())
            }
            _ => Err(Error::Invalid("set_wboit on MBOIT".into())),
        }
    }
}

oit_of_app_frame!(ListOit);
oit_of_app_frame!(KBufferOit);
oit_of_app_frame!(ExactOit);
oit_of_app_frame!(AllocatedOit);
oit_of_app_frame!(BlendedOit);
