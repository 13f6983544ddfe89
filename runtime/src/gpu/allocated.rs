//! The allocated k-buffers (DKB: the network's k per pixel within a budget; VKB: paper 002's
//! importance maps) in an application's own renderer. dhoit runs its own frame, every compute
//! pass as [`Gpu::render`] runs it, on the application's device; where that frame would draw
//! one of its geometry passes, the application draws its own transparent geometry, with its
//! own pipeline built on the module [`AllocatedOit::store_module`] gives for that pass
//! (dhoit's pass code, not a copy) and the group dhoit hands it. The resolve composites onto
//! the application's target over its image.

use std::cell::RefCell;

use super::oit::{check_target_format, fragment_group_layout, onto_pipeline};
use super::{FrameOptions, Gpu, Slots};
use crate::budget::{self, Budget, FragmentBudget};
use crate::error::Result;
use crate::importance::VkbParams;
use crate::mlp::Mlp;
use crate::scene::{Camera, Scene};
use crate::wgsl::shaders;

/// One of dhoit's geometry passes that the application draws its transparent geometry into
/// (with one pipeline each, built on [`AllocatedOit::store_module`] for it). A frame draws
/// `Count` (each pixel's fragments), then either `Store` (where the exact A-buffer needs no
/// more bytes than the method would: [`AllocatedFrame::exact`]) or the method's statistics
/// (DKB's `Features`, VKB's `VkbCount`) and `Capture` (or `CaptureFits`, where the budget
/// turns out to hold every fragment): [`AllocatedOit::phases`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Phase {
    /// The count (abuffer_count.wgsl).
    Count,
    /// The exact A-buffer's store (abuffer_store.wgsl).
    Store,
    /// The network's features (features.wgsl).
    Features,
    /// VKB's count with the nearest fragment's depth and facing (vkb_count.wgsl).
    VkbCount,
    /// The capture into each pixel's k slots and its tail (capture.wgsl).
    Capture,
    /// The capture built for frames whose budget holds every fragment.
    CaptureFits,
}

/// What a phase's group holds before the parameters (14) and the opaque depth (15).
#[derive(Clone, Copy)]
enum Binding {
    Read,
    ReadWrite,
    Uniform,
}

impl Phase {
    /// Every phase.
    pub const ALL: [Phase; 6] = [
        Phase::Count,
        Phase::Store,
        Phase::Features,
        Phase::VkbCount,
        Phase::Capture,
        Phase::CaptureFits,
    ];

    /// The pass's name (`wgsl::shaders::PASSES`) and the declarations its variant changes.
    fn pass(self) -> (&'static str, &'static [(&'static str, &'static str)]) {
        match self {
            Phase::Count => ("abuffer_count", &[]),
            Phase::Store => ("abuffer_store", &[]),
            Phase::Features => ("features", &[]),
            Phase::VkbCount => ("vkb_count", &[]),
            Phase::Capture => ("capture", &[]),
            Phase::CaptureFits => (
                "capture",
                &[(
                    "const EVERY_FRAGMENT_FITS: bool = false;",
                    "const EVERY_FRAGMENT_FITS: bool = true;",
                )],
            ),
        }
    }

    /// The pass's group 1, binding by binding (as its WGSL declares it).
    fn bindings(self) -> &'static [Binding] {
        use Binding::*;
        match self {
            Phase::Count => &[ReadWrite],
            Phase::Store => &[Read, ReadWrite, ReadWrite, ReadWrite],
            Phase::Features => &[Read, ReadWrite, Uniform, Read],
            Phase::VkbCount => &[ReadWrite, ReadWrite],
            Phase::Capture | Phase::CaptureFits => {
                &[Read, ReadWrite, ReadWrite, ReadWrite, ReadWrite]
            }
        }
    }

    /// Its place in [`Phase::ALL`] (declaration order).
    fn index(self) -> usize {
        self as usize
    }

    /// The phase of dhoit's geometry pipeline `pipeline`.
    fn of(gpu: &Gpu, pipeline: &wgpu::RenderPipeline) -> Phase {
        let p = &gpu.pipelines;
        [
            (&p.count, Phase::Count),
            (&p.store, Phase::Store),
            (&p.features, Phase::Features),
            (&p.vkb_count, Phase::VkbCount),
            (&p.capture, Phase::Capture),
            (&p.capture_fits, Phase::CaptureFits),
        ]
        .into_iter()
        .find(|(q, _)| *q == pipeline)
        .map(|(_, phase)| phase)
        .expect("an AllocatedOit frame draws only Phase's passes (its FrameOptions fix them)")
    }
}

/// What the application's draw callback gets for one of the frame's geometry passes: which
/// pass (the pipeline to set), dhoit's group (at the index it built the module for) and the
/// timestamps its render pass should write (`timestamp_writes: Some(draw.timestamps)`), so
/// [`AllocatedFrame::pass_ms`] times the pass; without them the pass reads 0 ms.
pub struct PhaseDraw<'a> {
    pub phase: Phase,
    pub group: &'a wgpu::BindGroup,
    pub timestamps: wgpu::RenderPassTimestampWrites<'a>,
}

/// What one frame did.
#[derive(Clone, Debug)]
pub struct AllocatedFrame {
    /// Bytes of the buffers the frame held: the method's layout's (`budget::DKB` for the
    /// network, or `budget::VKB`), or the A-buffer's where it rendered that.
    pub allocated_bytes: u64,
    /// Whether the frame rendered the exact A-buffer, which needed no more bytes than the
    /// method would at its budget (or the budget held every fragment).
    pub exact: bool,
    /// GPU time of each pass, in ms, in the order recorded.
    pub pass_ms: Vec<(&'static str, f64)>,
}

/// Which allocated k-buffer, with what it needs.
#[derive(Clone, Debug)]
pub enum AllocatedMethod {
    /// DKB with this network (deployed at its precision).
    Dkb(Box<Mlp>),
    /// VKB with these parameters (paper 002's; `VkbParams::default()` has its defaults).
    Vkb(VkbParams),
}

/// DKB or VKB on an application's device: the method, the budget, the frame's size and the
/// format of the target it resolves onto, fixed when made. Each frame
/// ([`AllocatedOit::render`]) calls the application back for each geometry pass ([`Phase`]) it
/// records.
///
/// ```
/// use dhoit_runtime::budget::Budget;
/// use dhoit_runtime::gpu::{self, AllocatedOit};
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
/// let weights = Mlp::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/weights.safetensors").as_ref())?;
/// let format = wgpu::TextureFormat::Rgba16Float;
/// let dkb = AllocatedOit::dkb(&device, &queue, (64, 48), &weights, Budget::parse("25%")?, format)?;
/// // One transparent pipeline a phase: dhoit's module at group 1, then the application's code.
/// for &phase in dkb.phases() {
///     let src = dkb.store_module(phase, 1)
///         + "@fragment fn fs(@builtin(position) p: vec4<f32>) { oit_store(p, vec4<f32>(0.2, 0.4, 0.6, 0.5)); }";
///     let _module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
///         label: None,
///         source: wgpu::ShaderSource::Wgsl(src.into()),
///     });
///     let _layout = dkb.bind_group_layout(phase); // the pipeline layout's group 1
/// }
/// // Per frame: its opaque pass, submitted; then
/// // dkb.render(&depth, &opaque_image, &target, &mut |encoder, draw| {
/// //     /* a render pass on `encoder` with timestamp_writes: Some(draw.timestamps), the
/// //        pipeline for draw.phase, draw.group at 1, its transparent draws */ })?;
/// # Ok::<(), dhoit_runtime::Error>(())
/// ```
pub struct AllocatedOit {
    gpu: Gpu,
    size: (u32, u32),
    method: AllocatedMethod,
    budget: FragmentBudget,
    layouts: Vec<wgpu::BindGroupLayout>,
    /// The resolves' `onto` entries at the target's format: the general capture's, the one
    /// built for frames that fit, the A-buffer's.
    onto: [wgpu::ComputePipeline; 3],
    /// The frame dhoit records holds no geometry of its own.
    empty: Scene,
    exact_when_cheaper: bool,
    /// A byte budget, resolved against each frame's count ([`FrameOptions::counted_bytes`]).
    counted_bytes: Option<u64>,
}

impl AllocatedOit {
    /// DKB for frames of `width` x `height` with the network `weights` (deployed at their
    /// precision), `budget` (bytes, slots a pixel or a share of each frame's fragments, as
    /// [`Budget::parse`] reads them; bytes count DKB's layout for this network and are resolved
    /// against each frame's own count, so a frame gets the slots its occupancy leaves within
    /// them), resolving onto targets of `format` (one of [`super::TARGET_FORMATS`]). Refuses a
    /// device that lacks what the passes need (named), a precision it cannot compute, a frame
    /// size it cannot hold and a byte budget below DKB's fixed cost, before anything is built;
    /// a frame whose occupancy leaves its bytes no slot is refused with what it needs.
    pub fn dkb(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        size: (u32, u32),
        weights: &Mlp,
        budget: Budget,
        format: wgpu::TextureFormat,
    ) -> Result<AllocatedOit> {
        let method = AllocatedMethod::Dkb(Box::new(weights.clone()));
        Self::new(device, queue, size, method, budget, format)
    }

    /// VKB (paper 002's importance maps, `params`), as [`AllocatedOit::dkb`]. Its importance
    /// reads each pixel's nearest fragment's facing, `|n . v|` of its triangle: the
    /// application hands it with `oit_store_facing(frag_coord, color, facing)` (its shader's
    /// `oit_store` hands 1, face-on).
    pub fn vkb(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        size: (u32, u32),
        params: VkbParams,
        budget: Budget,
        format: wgpu::TextureFormat,
    ) -> Result<AllocatedOit> {
        Self::new(
            device,
            queue,
            size,
            AllocatedMethod::Vkb(params),
            budget,
            format,
        )
    }

    /// The method, as [`AllocatedOit::dkb`] and [`AllocatedOit::vkb`] make it.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        (width, height): (u32, u32),
        method: AllocatedMethod,
        budget: Budget,
        format: wgpu::TextureFormat,
    ) -> Result<AllocatedOit> {
        crate::raster::check_resolution(width, height)?;
        let what = "allocated k-buffer";
        check_target_format(format, what)?;
        let px = width as u64 * height as u64;
        let layout = match &method {
            // The layout its frames create (their options are the defaults but for those set
            // in `frame`).
            AllocatedMethod::Dkb(weights) => FrameOptions::default().dkb_layout(weights),
            AllocatedMethod::Vkb(_) => budget::VKB,
        };
        // A byte budget is resolved against each frame's own occupancy, read back before
        // anything is sized (FrameOptions::counted_bytes: DKB counts first, VKB too), refused
        // now only where no frame fits (the fixed bytes and the marks).
        let (budget, counted_bytes) = match budget {
            Budget::Bytes(m) => {
                layout.fragment_budget_counted(m, px, &budget::Occupancy::default())?;
                (FragmentBudget::Slots(0), Some(m))
            }
            b => (b.fragment_budget(&layout, px)?, None),
        };
        let gpu = Gpu::on_device(device.clone(), queue.clone(), &device.adapter_info())?;
        if let AllocatedMethod::Dkb(weights) = &method {
            gpu.can_run(weights)?;
        }
        let layouts = Phase::ALL
            .iter()
            .map(|&phase| phase_layout(device, phase))
            .collect();
        let onto = [
            onto_pipeline(device, ("resolve", "onto"), format, false, what)?,
            onto_pipeline(device, ("resolve", "onto"), format, true, what)?,
            onto_pipeline(device, ("abuffer_resolve", "onto"), format, false, what)?,
        ];
        Ok(AllocatedOit {
            gpu,
            size: (width, height),
            method,
            budget,
            layouts,
            onto,
            empty: Scene::default(),
            exact_when_cheaper: true,
            counted_bytes,
        })
    }

    /// The geometry passes this method's frames draw, each needing the application's pipeline.
    pub fn phases(&self) -> &'static [Phase] {
        match self.method {
            AllocatedMethod::Dkb(_) => &[
                Phase::Count,
                Phase::Store,
                Phase::Features,
                Phase::Capture,
                Phase::CaptureFits,
            ],
            AllocatedMethod::Vkb(_) => &[
                Phase::Count,
                Phase::Store,
                Phase::VkbCount,
                Phase::Capture,
                Phase::CaptureFits,
            ],
        }
    }

    /// With `exact` false, every frame runs the method at its budget, even where the exact A-buffer
    /// would need fewer bytes (on by default: a k-buffer never costs more than the exact
    /// answer, and where it does not, the frame is the A-buffer's).
    pub fn exact_when_cheaper(self, exact: bool) -> AllocatedOit {
        AllocatedOit {
            exact_when_cheaper: exact,
            ..self
        }
    }

    /// The WGSL the application's fragment shader for `phase` starts with: dhoit's pass, its
    /// bindings at `group` and `fn oit_store(frag_coord: vec4<f32>, color: vec4<f32>)`, which
    /// the application calls with its fragment's `@builtin(position)` and straight colour. It
    /// declares dhoit's names (`Params`, `VertexOut`, `params` and the pass's buffers among
    /// them): the application's own must differ. Needs the shader-int64 feature
    /// ([`super::required_features`] has it).
    pub fn store_module(&self, phase: Phase, group: u32) -> String {
        Self::wgsl(phase, group)
    }

    /// [`AllocatedOit::store_module`], without an AllocatedOit.
    pub fn wgsl(phase: Phase, group: u32) -> String {
        let (pass, redeclare) = phase.pass();
        shaders::application_pass(pass, redeclare, group).expect("a geometry pass")
    }

    /// The layout of `phase`'s group, for the application's pipeline layout of that phase.
    pub fn bind_group_layout(&self, phase: Phase) -> &wgpu::BindGroupLayout {
        &self.layouts[phase.index()]
    }

    /// The frame's size.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// One frame: dhoit records and submits its passes on the application's queue; for each of
    /// its geometry passes it calls `draw` with an encoder, into which the application records
    /// its transparent draws ([`PhaseDraw`]), with `opaque_depth` (a depth texture of the
    /// frame's size, written by its opaque pass, which it has submitted) as the occluder. The
    /// resolve composites over `under` (its opaque image) onto `target`, a storage texture of
    /// the format this k-buffer was made for. Waits for the frame (it reads back how many slots to
    /// allocate, and the resolve's status).
    pub fn render(
        &self,
        opaque_depth: &wgpu::TextureView,
        under: &wgpu::TextureView,
        target: &wgpu::TextureView,
        draw: &mut dyn FnMut(&mut wgpu::CommandEncoder, PhaseDraw<'_>),
    ) -> Result<AllocatedFrame> {
        let app = AppDraws {
            draw: RefCell::new(draw),
            layouts: &self.layouts,
            opaque_depth,
            under,
            target,
            onto: &self.onto,
        };
        let opts = FrameOptions {
            diagnostics: false,
            exact_when_cheaper: self.exact_when_cheaper,
            counted_bytes: self.counted_bytes,
            ..FrameOptions::default()
        };
        let cam = Camera {
            view_proj: glam::Mat4::IDENTITY,
            forward: glam::Vec3::Z,
            eye: glam::Vec3::ZERO,
            near: 0.0,
            far: 0.0,
        };
        let slots = Some(match &self.method {
            AllocatedMethod::Dkb(weights) => Slots::Dkb(weights, self.budget),
            AllocatedMethod::Vkb(params) => Slots::Vkb(*params, self.budget),
        });
        let frame = self.gpu.render_frame(
            &opts,
            &self.empty,
            &cam,
            self.size,
            [0.0; 3],
            slots,
            Some(&app),
        )?;
        Ok(AllocatedFrame {
            allocated_bytes: frame.allocated_bytes,
            exact: frame.exact,
            pass_ms: frame.pass_ms,
        })
    }
}

/// A phase's group layout: the pass's buffers, the parameters (14), the opaque depth (15).
fn phase_layout(device: &wgpu::Device, phase: Phase) -> wgpu::BindGroupLayout {
    let mut buffers: Vec<_> = phase
        .bindings()
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let ty = match b {
                Binding::Read => wgpu::BufferBindingType::Storage { read_only: true },
                Binding::ReadWrite => wgpu::BufferBindingType::Storage { read_only: false },
                Binding::Uniform => wgpu::BufferBindingType::Uniform,
            };
            (i as u32, ty)
        })
        .collect();
    buffers.push((14, wgpu::BufferBindingType::Uniform));
    fragment_group_layout(device, &format!("dhoit {phase:?}"), &buffers, 15)
}

/// An application's frame, as the frame's passes see it ([`super::passes::Passes`]).
pub(super) trait AppGeometry {
    /// The application's draws for dhoit's geometry pass `pipeline`, `buffers` its group 1.
    fn draw(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        buffers: &[&wgpu::Buffer],
        params: &wgpu::Buffer,
        timestamps: wgpu::RenderPassTimestampWrites<'_>,
    );

    /// Dhoit's resolve `pipeline`'s `onto` entry in `pass`: `buffers` but the image
    /// (`buffers[image_at]`), over the application's image onto its target, on a grid.
    fn resolve(
        &self,
        gpu: &Gpu,
        pass: &mut wgpu::ComputePass,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
        image_at: usize,
        grid: (u32, u32),
    );
}

/// The application's draw callback ([`AllocatedOit::render`]).
type DrawFn<'d> = dyn FnMut(&mut wgpu::CommandEncoder, PhaseDraw<'_>) + 'd;

struct AppDraws<'a, 'd> {
    draw: RefCell<&'a mut DrawFn<'d>>,
    layouts: &'a [wgpu::BindGroupLayout],
    opaque_depth: &'a wgpu::TextureView,
    under: &'a wgpu::TextureView,
    target: &'a wgpu::TextureView,
    onto: &'a [wgpu::ComputePipeline; 3],
}

impl AppGeometry for AppDraws<'_, '_> {
    fn draw(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        buffers: &[&wgpu::Buffer],
        params: &wgpu::Buffer,
        timestamps: wgpu::RenderPassTimestampWrites<'_>,
    ) {
        let phase = Phase::of(gpu, pipeline);
        let extra = vec![
            wgpu::BindGroupEntry {
                binding: 14,
                resource: params.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 15,
                resource: wgpu::BindingResource::TextureView(self.opaque_depth),
            },
        ];
        let group = gpu.bind_with(&self.layouts[phase.index()], buffers, extra);
        (self.draw.borrow_mut())(
            enc,
            PhaseDraw {
                phase,
                group: &group,
                timestamps,
            },
        );
    }

    fn resolve(
        &self,
        gpu: &Gpu,
        pass: &mut wgpu::ComputePass,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
        image_at: usize,
        (gx, gy): (u32, u32),
    ) {
        let p = &gpu.pipelines;
        let onto = [&p.resolve, &p.resolve_fits, &p.abuffer_resolve]
            .iter()
            .position(|q| *q == pipeline)
            .map(|i| &self.onto[i])
            .expect("an AllocatedOit frame resolves only with the k-buffer's and the A-buffer's resolves");
        // The buffers at their bindings but the image (the application's target instead).
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != image_at)
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .chain([
                wgpu::BindGroupEntry {
                    binding: 8,
                    resource: wgpu::BindingResource::TextureView(self.under),
                },
                wgpu::BindGroupEntry {
                    binding: 9,
                    resource: wgpu::BindingResource::TextureView(self.target),
                },
            ])
            .collect();
        let group = gpu.bind_with(&onto.get_bind_group_layout(0), &[], entries);
        pass.set_pipeline(onto);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(gx, gy, 1);
    }
}
