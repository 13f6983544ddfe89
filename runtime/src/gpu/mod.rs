//! The wgpu renderer: the A-buffer, MLAB, the k-buffers, the list and the blended methods on
//! a Vulkan or DX12 device (here Mesa's lavapipe), each pass the twin of a CPU function that
//! the tests hold it to.
//!
//! One frame engine records every method's frame into its client's command encoder, with no
//! submission and no wait: what it decides from the frame's own count it decides on the device
//! (`plan.wgsl`, twin [`crate::plan`]). It draws geometry only through its client
//! (`passes::Geometry`): `Gpu::render` (`scene.rs`, dhoit's own frames: it uploads a scene,
//! counts first to size every buffer for the frame's own occupancy, submits and reads back) and
//! an application's renderer (`app.rs`: the [`Oit`](crate::gpu::Oit) protocol, one for every method). The engine
//! imports neither.
//!
//! One file a pass, beside its shaders (in `shaders/`, one file a pass, with the generated
//! prelude, `common.wgsl` and their includes prepended: `geometry.wgsl`, `mlp.wgsl`,
//! `sort.wgsl`; see [`crate::wgsl::shaders`]) and naming its twin:
//! - `abuffer.rs`: the A-buffer (`abuffer_count` -> `scan` -> `abuffer_store` ->
//!   `abuffer_resolve`) and MLAB (`mlab_resolve` on the A-buffer's fragments).
//! - `dkb.rs`: DKB's `features` and `importance_dkb` (the network of `mlp.wgsl`);
//!   `vkb.rs`: VKB's `vkb_count` and `importance_vkb`; both with `totals` and `plan`.
//! - `allocate.rs`: the allocation of k from importance (`allocate.wgsl`).
//! - `scan.rs`: the prefix sums (`scan.wgsl`).
//! - `capture.rs`: k, the two-mode `capture` (append or Loop64 insertion) and `resolve`, and
//!   both built for frames whose budget holds every fragment (`EVERY_FRAGMENT_FITS`).
//! - `list.rs`, `blend.rs`: the linked list; WBOIT and MBOIT.
//! - `predict.rs`: the network on rows of features (`predict.wgsl`).
//!
//! And the frame's machinery: `shader.rs` (modules and pipelines built, counted and recorded
//! for WebGPU), `pipelines.rs` (built once a device and shared by every method forked from
//! it: [`Gpu::fork`](crate::gpu::Gpu::fork); the network's per shape), `passes.rs` (recording
//! a pass), `buffers.rs` (pooled buffers, readback), `timer.rs`. `hooks.rs` runs one stage
//! alone for the tests (`Gpu::allocate`, `Gpu::plan`, `Gpu::u64_words`: hidden from the
//! documentation).
//!
//! Every buffer a method's frame allocates is labelled after the [`crate::budget::Layout`] entry
//! it realises and counted, so [`GpuFrame::allocated_bytes`](crate::gpu::GpuFrame::allocated_bytes) is what the device really holds.
//!
//! The renderer persists across frames: a frame takes its buffers from those earlier frames
//! left (cleared in its own encoder where reused), so a stream of like frames creates none.

mod abuffer;
mod allocate;
mod app;
mod blend;
mod buffers;
mod capture;
mod dkb;
mod hooks;
mod list;
mod passes;
mod pipelines;
mod predict;
mod scan;
mod scene;
mod shader;
mod stream;
mod timer;
mod vkb;

use abuffer::Blend;
pub use app::{
    AllocatedOit, BlendedOit, DrawFn, ExactOit, FrameTargets, KBufferOit, ListOit, Oit, PhaseDraw,
    TARGET_FORMATS,
};
pub use buffers::host_syncs;
use buffers::{FrameBuffers, Readback};
#[doc(hidden)]
pub use hooks::GpuAllocation;
use passes::Passes;
pub use passes::Phase;
use pipelines::Pipelines;
pub use scene::SceneStream;
pub use shader::{pipelines_built, record_pipelines};
pub use stream::FrameReport;
use timer::Timer;
/// The wgpu the renderer is built on (an application's device and encoder are its types).
pub use wgpu;

use crate::alloc::Target;
use crate::budget;
use crate::budget::{FragmentBudget, Occupancy};
use crate::composite::{Image, MboitParams, WboitParams};
use crate::error::{Error, GpuError, Result};
use crate::fragment::FragmentLists;
use crate::frame::{Allocation, Method, Options};
use crate::importance::{PixelStats, VkbParams};
use crate::mlp::{Mlp, Precision};
use crate::plan::{Plan, PlanBudget, PlanInput};
use crate::scene::Camera;
use crate::wgsl::bindings;
use crate::wgsl::{MLAB_MAX_ROWS, Params};

/// The WGSL of network pass `pass` ("predict", "importance_dkb") as built for `m`: for the
/// tests that hold its declarations to the host's buffers.
#[cfg(test)]
pub(crate) fn network_pass_source(pass: &'static str, m: &Mlp) -> String {
    pipelines::Variant::for_network(pass, m, true).source()
}

/// Features that let the k-buffers capture in one geometry pass: 64-bit integers and their
/// atomics ([`Capture::Wide`]). A device without them (WebGPU, Metal, many phones) runs every
/// method all the same, the k-buffers' capture in two passes with 32-bit atomics
/// ([`Capture::Portable`]; DKB's statistics take 32-bit atomics on every device). Timestamps
/// (`TIMESTAMP_QUERY`) are optional: with them a frame reports each pass's GPU time, without
/// them none.
pub fn required_features() -> wgpu::Features {
    wide_features()
}

/// The 64-bit integer features ([`required_features`]: `SHADER_INT64` and
/// `SHADER_INT64_ATOMIC_ALL_OPS`).
pub fn wide_features() -> wgpu::Features {
    wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_ALL_OPS
}

/// Features dhoit uses where the device has them: timestamps (each pass's time), binary16
/// arithmetic (networks deployed at f16-math) and 32-bit float blending (MBOIT).
pub fn optional_features() -> wgpu::Features {
    wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::SHADER_F16 | wgpu::Features::FLOAT32_BLENDABLE
}

/// The limits the passes need of a device: wgpu's defaults ([`wgpu::Limits::default`],
/// WebGPU's), 8 storage buffers a shader stage among them (a geometry pass's fragment stage
/// binds at most 8: three of the scene's and the capture's five). A frame's buffers are checked
/// against the device's own binding size when they are made.
pub fn required_limits() -> wgpu::Limits {
    wgpu::Limits::default()
}

/// Whether a device with `features` builds the passes that use 64-bit integers
/// ([`required_features`]); without, it runs the portable ones alone.
fn is_wide(features: wgpu::Features) -> bool {
    features.contains(wide_features())
}

/// A device and queue with the pipeline's features, and the compiled passes.
///
/// A frame on the GPU takes the CPU's budget decision ([`Slots::for_method`] on the CPU's
/// allocation: F, and k where only the CPU computes it) and runs every other pass on the
/// device; [`GpuFrame`] says what it allocated and how long each pass took. A DKB or VKB frame
/// counts first and renders the exact A-buffer where that needs no more bytes than the method
/// would ([`budget::Decision::exact_when_cheaper`], [`GpuFrame::exact`]); the example asks for the
/// approximation itself, as its CPU options do.
///
/// ```
/// use dhoit_runtime::budget::Budget;
/// use dhoit_runtime::frame::{Method, Options, Renderer};
/// use dhoit_runtime::gpu::{FrameOptions, Gpu, Slots};
/// use dhoit_runtime::{mlp::Mlp, raster, scene};
///
/// let s = scene::load("hair", scene::Opacity::default())?;
/// let size = (128, 96); // (width, height), as every size in dhoit
/// let cam = scene::Camera::orbit(&s, 2, scene::DEFAULT_VIEWS, size);
/// let fragments = raster::rasterize(&s, &cam, size)?;
/// let weights = Mlp::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/weights.safetensors").as_ref())?;
/// let options = Options {
///     weights: Some(&weights),
///     ..Options::new(Budget::parse("1fpp")?, [1.0; 3]).always_approximate()
/// };
/// let renderer = Renderer::new(&fragments, options);
/// let cpu = renderer.allocate_for_gpu(Method::Dkb)?;
/// let gpu = Gpu::new()?; // an adapter with 64-bit atomics, or a typed error naming what lacks
/// let slots = Slots::for_method(Method::Dkb, &cpu, &options)?;
/// let approximate = FrameOptions::default().always_approximate();
/// let frame = gpu.render_with(&approximate, &s, &cam, size, options.background, slots)?;
/// let twin = renderer.render(Method::Dkb)?;
/// // The GPU rasterizes its own fragments, which can differ from the CPU's by one where an
/// // edge passes through a pixel centre (here one pixel moves by 9.4e-4; the tests hold each
/// // pass to its twin on the GPU's own fragments, within 1e-5).
/// assert!(frame.image.mse(&twin.image) < 1e-9);
/// assert!(frame.passes.contains(&"importance"));
/// # Ok::<(), dhoit_runtime::Error>(())
/// ```
pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// "name (backend, device type, driver)".
    adapter: String,
    timestamp_period: f32,
    /// Whether the device has timestamps (`TIMESTAMP_QUERY`, optional): without them every
    /// pass runs untimed.
    timestamps: bool,
    /// The device's compiled passes, shared by the renderers forked from this one
    /// ([`Gpu::fork`]).
    pipelines: std::sync::Arc<Pipelines>,
    /// Whether the device computes in binary16 (`SHADER_F16`): the importance pass runs a
    /// network deployed at [`Precision::F16Math`] only where it does.
    half_math: bool,
    /// Whether the device ends a shader invocation's loops early, silently (Mesa's lavapipe,
    /// after 65,535 iterations): then a frame whose passes came close to that (common.wgsl's
    /// LOOP_BUDGET) is refused. Other devices run loops to their end, and deep pixels render.
    bounded_loops: bool,
    /// Buffers of earlier frames, by label, reused when a frame asks for one of the same size
    /// and usage (cleared first, as a new buffer is), so a steady stream of frames creates
    /// none. Frames take their buffers out and put them back when done, so concurrent frames
    /// never share one.
    pool: std::sync::Mutex<std::collections::HashMap<String, wgpu::Buffer>>,
    /// Timestamp query sets of earlier frames.
    query_sets: std::sync::Mutex<Vec<wgpu::QuerySet>>,
    /// Buffers created for frames since the device opened (reused ones not counted).
    created: std::sync::atomic::AtomicU64,
}

/// What a frame renders and reads back beyond its method and budget. [`Gpu::render`] takes the
/// defaults, [`Gpu::render_with`] the caller's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameOptions {
    /// How a k-buffer frame's budget is decided, as on the CPU
    /// ([`crate::frame::Options::decision`]): a DKB or VKB frame, once it has counted its
    /// fragments, renders the exact A-buffer where that needs no more bytes than the method
    /// reserves at its budget or its budget holds every fragment ([`GpuFrame::exact`]); DKB's
    /// records in at most its record batches.
    pub decision: budget::Decision,
    /// Whether a frame reads back what the tests compare besides the image (fragments, slots,
    /// tails, importance, statistics): on by default; off, the image alone.
    pub diagnostics: bool,
    /// How the k-buffers insert fragments: 64-bit atomics in one pass or 32-bit ones in two
    /// ([`Capture`]); the same slots, tails and images, bit for bit.
    pub capture: Capture,
    /// How the passes are laid out: each switch picks one of two implementations with the same
    /// images, the bench measures both, the tests hold each to the other.
    pub tuning: Tuning,
}

/// A frame's passes' implementation choices ([`FrameOptions::tuning`]): the images are the same
/// whichever is chosen. The defaults are the fastest measured (`make bench`; docs/results.md
/// gives the figures).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tuning {
    /// DKB's importance pass skips the network where k does not depend on it (on).
    pub skip_forced: bool,
    /// The allocated k-buffers (DKB, VKB, uploaded importance) append the pixels that keep all
    /// their fragments ([`crate::composite::appends`]) and insert the rest (on); off, every
    /// fragment is inserted.
    pub two_mode_capture: bool,
    /// With the two-mode capture, a frame whose budget holds every fragment uses the capture
    /// and resolve built for k = n everywhere (on).
    pub fits_pipelines: bool,
    /// DKB's importance pass stages the network's first two layers in workgroup memory (off:
    /// slower on lavapipe).
    pub shared_weights: bool,
    /// A network pass runs its forward written out for its shape rather than mlp.wgsl's loops
    /// (on).
    pub unrolled_network: bool,
    /// DKB's features pass loads a pixel's nearest words and skips the atomicMax that cannot
    /// change them (on).
    pub features_preload: bool,
    /// The allocation's search adds into 32 copies of its totals in workgroup memory rather than
    /// one (off: slower on lavapipe).
    pub spread_search: bool,
    /// FKB lays its slots out layer-major rather than pixel-major (off).
    pub layer_major_fkb: bool,
    /// A DKB frame that follows one of its size gathers its network's statistics with its
    /// count, for the pixels the frame before marked (its geometry drawn twice: the count and
    /// the capture), where its records take one batch (on); off, every frame marks its own and
    /// draws a features pass of its own (three geometry passes, the frame of a cut).
    pub two_pass_dkb: bool,
}

impl Default for Tuning {
    fn default() -> Self {
        Tuning {
            skip_forced: true,
            two_mode_capture: true,
            fits_pipelines: true,
            shared_weights: false,
            unrolled_network: true,
            features_preload: true,
            spread_search: false,
            layer_major_fkb: false,
            two_pass_dkb: true,
        }
    }
}

/// How a k-buffer's capture inserts a fragment's 64-bit key (its depth, then its colour) into
/// a pixel's slots.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Capture {
    /// One geometry pass, NVIDIA's Loop64: a 64-bit `atomicMax` a slot
    /// (`SHADER_INT64_ATOMIC_ALL_OPS`; a device without it runs [`Capture::Portable`]).
    #[default]
    Wide,
    /// Two geometry passes with 32-bit atomics alone, for devices without 64-bit ones (WebGPU,
    /// Metal, most phones): the first inserts each fragment's depth into the slots' depth
    /// words, the second its colour into the colour words of the slots holding its depth, the
    /// colours of equal depths in the order of their RGBA8 words (as the 64-bit key orders
    /// them); a fragment left out of the slots goes to the tail. The same bytes a slot and a
    /// pixel as [`Capture::Wide`], one more geometry pass (DKB's features need no 64-bit atomic:
    /// its count and features pass are the same on either).
    Portable,
}

impl Capture {
    /// The capture's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Capture::Wide => "wide",
            Capture::Portable => "portable",
        }
    }

    /// The capture named `name` (`wide` or `portable`).
    pub fn parse(name: &str) -> Result<Capture> {
        match name {
            "wide" => Ok(Capture::Wide),
            "portable" => Ok(Capture::Portable),
            other => Err(Error::Invalid(format!(
                "no capture '{other}': wide (64-bit atomics) or portable (32-bit atomics)"
            ))),
        }
    }
}

impl Default for FrameOptions {
    fn default() -> Self {
        FrameOptions {
            decision: budget::Decision::default(),
            diagnostics: true,
            capture: Capture::Wide,
            tuning: Tuning::default(),
        }
    }
}

impl FrameOptions {
    /// DKB's buffers for `mlp` as these options' frames create them
    /// ([`budget::Decision::dkb_layout`]).
    pub fn dkb_layout(&self, mlp: &crate::mlp::Mlp) -> budget::Layout {
        self.decision.dkb_layout(mlp)
    }

    /// These options with [`budget::Decision::exact_when_cheaper`] off: a DKB or VKB frame
    /// runs its method at any budget (as [`crate::frame::Options::always_approximate`] on the
    /// CPU).
    pub fn always_approximate(self) -> FrameOptions {
        FrameOptions {
            decision: self.decision.always_approximate(),
            ..self
        }
    }
}

/// Most buffers the pool keeps (beyond, a returned buffer is dropped).
const POOL_MAX: usize = 64;
/// Timestamped passes a frame has room for.
const TIMED_PASSES: u32 = 32;

impl Gpu {
    /// A buffer for a frame: the pooled one under `key` when its size and usage match (then
    /// `true`: it holds the last frame's data, which the frame clears where it needs zeros),
    /// else a new one (zeroed by wgpu).
    fn acquire(&self, key: &str, size: u64, usage: wgpu::BufferUsages) -> (wgpu::Buffer, bool) {
        let pooled = self
            .pool
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(key);
        match pooled {
            Some(b) if b.size() == size && b.usage() == usage => (b, true),
            _ => {
                self.created
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let b = self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(key),
                    size,
                    usage,
                    mapped_at_creation: false,
                });
                (b, false)
            }
        }
    }

    /// A renderer on the same device sharing this one's compiled passes (built once a device:
    /// the fork builds none) but none of its buffers: what each method an application makes
    /// holds ([`crate::gpu::pipelines_built`] counts what is built).
    pub fn fork(&self) -> Gpu {
        Gpu {
            device: self.device.clone(),
            queue: self.queue.clone(),
            adapter: self.adapter.clone(),
            timestamp_period: self.timestamp_period,
            timestamps: self.timestamps,
            pipelines: self.pipelines.clone(),
            half_math: self.half_math,
            bounded_loops: self.bounded_loops,
            pool: Default::default(),
            query_sets: Default::default(),
            created: Default::default(),
        }
    }

    /// "name (backend, device type, driver)".
    pub fn adapter(&self) -> &str {
        &self.adapter
    }

    /// The device the passes run on (the application's, with [`Gpu::on_device`]).
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue the frames are submitted to.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// Whether the device ends a shader invocation's loops early, silently (Mesa's lavapipe,
    /// after 65,535 iterations): then a frame whose passes came close to that is refused.
    pub fn bounded_loops(&self) -> bool {
        self.bounded_loops
    }

    /// Whether the device runs networks deployed at [`Precision::F16Math`] (it has
    /// `SHADER_F16`).
    pub fn has_half_math(&self) -> bool {
        self.half_math
    }

    /// Refuses a network this device cannot run: one deployed at [`Precision::F16Math`] on a
    /// device without half-precision shaders.
    pub(super) fn can_run(&self, mlp: &Mlp) -> Result<()> {
        if mlp.precision == Precision::F16Math && !self.half_math {
            return Err(GpuError::NoHalfMath {
                adapter: self.adapter.clone(),
            }
            .into());
        }
        Ok(())
    }

    /// Buffers created for frames so far: a frame like the one before creates none.
    pub fn buffers_created(&self) -> u64 {
        self.created.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Puts a frame's buffer back for the next frame.
    fn release(&self, key: String, buffer: wgpu::Buffer) {
        let mut pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
        if pool.len() < POOL_MAX || pool.contains_key(&key) {
            pool.insert(key, buffer);
        }
    }
}

/// The instances [`Gpu::new`] looks for adapters in (the `WGPU_*` environment variables
/// apply). wgpu checks every indirect dispatch's arguments by default, with a dispatch and two
/// barriers of its own before each (12 ms each on lavapipe, where DKB's frame records 17:
/// the allocation's weights, search rounds and marks, their prefix sum, the network's rows).
/// dhoit's shaders write those arguments themselves, every dimension at most 65,535 (`grid_of`
/// in common.wgsl, `args` in importance_dkb.wgsl), so it opens Vulkan, Metal and GL without
/// the check (`WGPU_VALIDATION_INDIRECT_CALL=1` turns it back on). D3D12 keeps it: there wgpu
/// supplies `num_workgroups`, which the passes read, through that check.
fn instances() -> [wgpu::Instance; 2] {
    instance_descriptors().map(wgpu::Instance::new)
}

/// Every adapter of [`instances`], in their order; an error where there is none.
fn adapters() -> Result<Vec<wgpu::Adapter>> {
    let mut adapters = Vec::new();
    for instance in instances() {
        adapters.extend(pollster::block_on(
            instance.enumerate_adapters(wgpu::Backends::all()),
        ));
    }
    if adapters.is_empty() {
        return Err(GpuError::NoAdapter.into());
    }
    Ok(adapters)
}

/// [`instances`]' descriptors: every backend but D3D12 without the indirect check, D3D12 with.
fn instance_descriptors() -> [wgpu::InstanceDescriptor; 2] {
    let mut direct = wgpu::InstanceDescriptor::new_without_display_handle();
    direct
        .flags
        .remove(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL);
    let mut direct = direct.with_env();
    direct.backends.remove(wgpu::Backends::DX12);
    let mut dx12 = wgpu::InstanceDescriptor::new_without_display_handle().with_env();
    dx12.backends &= wgpu::Backends::DX12;
    [direct, dx12]
}

impl Gpu {
    /// Opens the first adapter that has every required feature ([`required_features`]), else
    /// the first adapter, without them: every method runs, the k-buffers with the portable
    /// capture ([`Gpu::is_wide`] says which). Either way with the optional features the
    /// adapter has and its own limits. With `DHOIT_DEVICE=webgpu-core` in the environment, the
    /// first adapter as WebGPU's core device instead ([`Gpu::portable`]): what a page gets,
    /// for any command or test to run on.
    pub fn new() -> Result<Gpu> {
        match std::env::var("DHOIT_DEVICE").as_deref() {
            Ok("webgpu-core") => return Self::portable(),
            Ok("") | Err(_) => {}
            Ok(other) => {
                return Err(Error::Invalid(format!(
                    "DHOIT_DEVICE={other}: the one device it names is webgpu-core"
                )));
            }
        }
        match Self::requiring(wgpu::Features::empty()) {
            Err(Error::Gpu(GpuError::MissingFeatures { .. })) => {
                let a = adapters()?.swap_remove(0);
                let optional = a.features() & optional_features();
                let limits = a.limits();
                Self::open(&a, optional, limits, "dhoit")
            }
            other => other,
        }
    }

    /// The first adapter opened as WebGPU's core device: no feature (not even the optional
    /// ones) and wgpu's default limits ([`wgpu::Limits::default`], 8 storage buffers a stage).
    /// Every method runs, the k-buffers with the portable capture (MBOIT where the adapter
    /// blends 32-bit floats: not here, where nothing optional is asked for); what runs here runs
    /// in a browser.
    pub fn portable() -> Result<Gpu> {
        let a = adapters()?.swap_remove(0);
        let (features, limits) = (wgpu::Features::empty(), wgpu::Limits::default());
        Self::open(&a, features, limits, "dhoit (WebGPU core)")
    }

    /// `adapter` opened with `features` and `limits`, and the passes built on it.
    fn open(
        adapter: &wgpu::Adapter,
        features: wgpu::Features,
        limits: wgpu::Limits,
        label: &str,
    ) -> Result<Gpu> {
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some(label),
            required_features: features,
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| GpuError::Open {
            adapter: info.name.clone(),
            message: e.to_string(),
        })?;
        Self::build(device, queue, &info)
    }

    /// Whether the device builds the passes that use 64-bit integers (the one-pass capture and
    /// features pass): it has [`required_features`].
    pub fn is_wide(&self) -> bool {
        self.pipelines.wide.is_some()
    }

    /// The capture a frame asking for `asked` runs: `asked`, or the portable one on a device
    /// without 64-bit atomics.
    pub(super) fn capture_for(&self, asked: Capture) -> Capture {
        match self.is_wide() {
            true => asked,
            false => Capture::Portable,
        }
    }

    /// [`Gpu::new`], with `extra` features required on top of the pipeline's (tests use it to
    /// see what happens on an adapter that lacks one).
    pub fn requiring(extra: wgpu::Features) -> Result<Gpu> {
        let need = required_features() | extra;
        // Requested where offered: the pass times, the importance pass's f16-math variant,
        // MBOIT's moments.
        let optional = optional_features();
        let mut lacking = Vec::new();
        let adapter = adapters()?.into_iter().find(|a| {
            let missing = need - a.features();
            if !missing.is_empty() {
                lacking.push(format!("{} lacks {missing:?}", a.get_info().name));
            }
            missing.is_empty()
        });
        let Some(adapter) = adapter else {
            return Err(GpuError::MissingFeatures {
                lacking: lacking.join("; "),
            }
            .into());
        };
        let features = need | (adapter.features() & optional);
        Self::open(&adapter, features, adapter.limits(), "dhoit")
    }

    /// dhoit on the application's own device and queue (clones of its handles: wgpu's are
    /// shared), with `info` its adapter's ([`wgpu::Adapter::get_info`]). A device opened without
    /// [`required_features`] (64-bit integers and their atomics) runs every method, its
    /// k-buffers with the portable capture; one below wgpu's default limits
    /// ([`required_limits`]) is refused; with `SHADER_F16` the importance pass also runs networks at f16-math, and with
    /// `FLOAT32_BLENDABLE` MBOIT runs (its frames are refused, the feature named, without it). Frames allocate from
    /// the device's own limits.
    ///
    /// ```
    /// # let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    /// # let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
    /// // The application's device, opened as it likes, with the features dhoit needs.
    /// let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
    ///     required_features: dhoit_runtime::gpu::required_features(),
    ///     required_limits: dhoit_runtime::gpu::required_limits(),
    ///     ..Default::default()
    /// }))
    /// .unwrap();
    /// let gpu = dhoit_runtime::gpu::Gpu::on_device(device.clone(), queue.clone(), &adapter.get_info())?;
    /// assert!(gpu.adapter().contains(&adapter.get_info().name));
    /// # Ok::<(), dhoit_runtime::Error>(())
    /// ```
    pub fn on_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: &wgpu::AdapterInfo,
    ) -> Result<Gpu> {
        pollster::block_on(Self::on_device_async(device, queue, info))
    }

    /// [`Gpu::on_device`] without blocking, for a page's WebGPU device (wasm32), where nothing
    /// may wait: the future resolves once the device has validated dhoit's passes.
    pub async fn on_device_async(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: &wgpu::AdapterInfo,
    ) -> Result<Gpu> {
        check_device(&device, &info.name)?;
        Self::build_async(device, queue, info).await
    }

    /// The passes' pipelines on an open device.
    fn build(device: wgpu::Device, queue: wgpu::Queue, info: &wgpu::AdapterInfo) -> Result<Gpu> {
        pollster::block_on(Self::build_async(device, queue, info))
    }

    async fn build_async(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: &wgpu::AdapterInfo,
    ) -> Result<Gpu> {
        let features = device.features();
        let adapter_name = format!(
            "{} ({:?}, {:?}, {} {})",
            info.name, info.backend, info.device_type, info.driver, info.driver_info
        );
        let wide = is_wide(features);
        // wgpu's handles are Send and Sync, but on wasm32 (one thread) they are neither.
        #[cfg_attr(target_arch = "wasm32", allow(clippy::arc_with_non_send_sync))]
        let pipelines = std::sync::Arc::new(Pipelines::new(&device, wide).await?);
        Ok(Gpu {
            timestamp_period: queue.get_timestamp_period(),
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
            device,
            queue,
            adapter: adapter_name,
            pipelines,
            half_math: features.contains(wgpu::Features::SHADER_F16),
            bounded_loops: info.name.contains("llvmpipe") || info.driver.contains("llvmpipe"),
            pool: Default::default(),
            query_sets: Default::default(),
            created: Default::default(),
        })
    }
}

/// What a frame renders: the exact A-buffer, or a method of bounded memory and how it gets its
/// k (or rows, or nodes).
#[derive(Clone, Copy, Debug)]
pub enum Slots<'a> {
    /// The exact A-buffer: every fragment stored, sorted and blended (abuffer_*.wgsl).
    Exact,
    /// One k for every pixel (FKB).
    Uniform(u32),
    /// k per pixel, computed elsewhere (the optimal allocation, or any CPU allocation).
    PerPixel(&'a [u32]),
    /// MLAB with this many rows (at most [`MLAB_MAX_ROWS`]), blended from the A-buffer's
    /// fragments taken in submission order.
    Mlab(u32),
    /// Weighted blended OIT, as engines ship it: one geometry pass into an RGBA16F accumulation
    /// and an R8 revealage, then a composite (the twin: `composite::wboit_blended`), with
    /// these parameters (its weight function).
    Wboit(WboitParams),
    /// Moment-based OIT with these parameters, as Munstermann et al. lay it out: a pass adding
    /// b_0 and four power moments into 32-bit float targets, a pass adding the
    /// transmittance-weighted colour into an RGBA16F one, a composite (the twin:
    /// `composite::mboit_blended`). Needs `FLOAT32_BLENDABLE`.
    Mboit(MboitParams),
    /// The budgeted linked list (`list_store.wgsl`, `list_resolve.wgsl`): a pool of `nodes`
    /// fragments handed out first come, first served, each pixel's nearest `sorted` blended in
    /// order over the rest's tail (1 to [`crate::composite::LIST_MAX_SORTED`]).
    LinkedList { nodes: u64, sorted: u32 },
    /// Per-pixel importance (computed elsewhere), what it means and F: the GPU counts
    /// fragments, allocates k (`allocate.wgsl`, the twin of `alloc::allocate`), then captures
    /// and resolves.
    Importance(&'a [f32], Target, FragmentBudget),
    /// The variable k-buffer, every pass on the GPU: count and nearest fragment, totals, paper
    /// 002's importance, allocation, capture, resolve. Its budget: F (slots or a share of the
    /// frame's fragments), or bytes, resolved once the frame's count is known against its own
    /// occupancy (`Layout::fragment_budget_counted`).
    Vkb(VkbParams, PlanBudget),
    /// The deep k-buffer, every pass on the GPU: features, totals, the network's importance,
    /// allocation, capture, resolve. Its budget as [`Slots::Vkb`]'s.
    Dkb(&'a Mlp, PlanBudget),
}

impl<'a> Slots<'a> {
    /// How the GPU renders `method` for the allocation the CPU made with `options` (`cpu`,
    /// from [`crate::frame::Renderer::allocate_for_gpu`] or `allocate`): FKB and MLAB with the
    /// CPU's k; VKB and DKB allocating on the device at the CPU's F (a share of the fragments
    /// at equal F stays a share, resolved from the GPU's own count); every allocation only the
    /// CPU makes (optimal, the greedies) uploaded as per-pixel k; [`Slots::Exact`] for the
    /// A-buffer, and for any k-buffer whose budget holds every fragment (`Allocation::exact`). The
    /// one method-to-slots mapping: render, bench and the tests use it, so a method gets the
    /// same k whichever command renders it.
    pub fn for_method(
        method: Method,
        cpu: &'a Allocation,
        options: &Options<'a>,
    ) -> Result<Slots<'a>> {
        let budget = cpu.fragment_budget;
        let first = || cpu.k.first().copied().unwrap_or(0);
        // Where the budget holds every fragment, the A-buffer (exact, with its memory).
        if cpu.exact {
            return Ok(Slots::Exact);
        }
        Ok(match method {
            Method::Abuffer => Slots::Exact,
            Method::Fkb => Slots::Uniform(first()),
            // MLAB on the GPU blends from the A-buffer (exact memory, not the budget's rows).
            Method::Mlab => Slots::Mlab(first()),
            Method::Wboit => Slots::Wboit(options.wboit),
            Method::Mboit => Slots::Mboit(options.mboit),
            Method::LinkedList => Slots::LinkedList {
                nodes: cpu.budget_fragments,
                sorted: options.list_sorted,
            },
            Method::Vkb => Slots::Vkb(options.vkb, budget.into()),
            Method::Dkb => Slots::Dkb(
                options.weights.ok_or_else(crate::frame::no_weights)?,
                budget.into(),
            ),
            Method::Optimal | Method::GreedyPaper | Method::GreedyIncrease => {
                Slots::PerPixel(&cpu.k)
            }
            Method::OptimalPooled => {
                return Err(Error::Invalid(
                    "optimal-pooled is computed on the CPU only (--device cpu, compare, score): \
                     the GPU's uploaded k keeps a tail a pixel"
                        .into(),
                ));
            }
        })
    }
}

/// Refuses a device below wgpu's default limits ([`wgpu::Limits::default`], what the portable
/// passes need), naming what it lacks (`adapter` names the device in the error). One without
/// [`required_features`] runs the portable passes alone.
pub(super) fn check_device(device: &wgpu::Device, adapter: &str) -> Result<()> {
    let mut missing = Vec::new();
    required_limits().check_limits_with_fail_fn(&device.limits(), false, |name, need, has| {
        missing.push(format!("{name} {has} (needs {need})"))
    });
    if !missing.is_empty() {
        return Err(GpuError::DeviceLacks {
            adapter: adapter.to_string(),
            missing: missing.join(", "),
        }
        .into());
    }
    Ok(())
}

/// The allocation pass's weight kind for a target (`Alloc.kind` in allocate.wgsl).
fn weight_kind(t: Target) -> u32 {
    match t {
        Target::RelativeK => 0,
        Target::ShareOfFragments => 1,
        Target::SlotRequest => 2,
    }
}

/// What a GPU frame produced, read back.
#[derive(Clone, Debug)]
pub struct GpuFrame {
    pub image: Image,
    /// Milliseconds of each pass, from timestamp queries, in order (none where the device has
    /// no timestamps).
    pub pass_ms: Vec<(&'static str, f64)>,
    /// Every pass the frame recorded, in order, on any device.
    pub passes: Vec<&'static str>,
    /// Host milliseconds outside the passes: "scene upload" (positions widened to vec4 and
    /// written with the colours), "image readback" (copy, map and convert the image).
    pub host_ms: Vec<(&'static str, f64)>,
    /// Bytes of every buffer and target the method allocated for this frame.
    pub allocated_bytes: u64,
    /// Whether a DKB or VKB frame rendered the exact A-buffer in its place
    /// ([`budget::Decision::exact_when_cheaper`]): its image, bytes and fragments are the A-buffer's.
    pub exact: bool,
    /// A-buffer: the GPU's own fragments (sorted front to back within each pixel).
    pub fragments: Option<FragmentLists>,
    /// k-buffer: the slots (capture keys, front to back; `u64::MAX` where empty), their bases
    /// (`pixels + 1` entries) and the tail sums (five per pixel).
    pub slots: Option<(Vec<u64>, Vec<u32>, Vec<u32>)>,
    /// VKB and DKB: the importance the GPU computed (uploaded importance: after allocation's
    /// fixed-point conversion is not returned).
    pub importance: Option<Vec<f32>>,
    /// DKB: the features pass's per-pixel statistics, where it drew.
    pub stats: Option<Vec<PixelStats>>,
    /// DKB: whether its features pass drew the frame's triangles: not when the budget holds
    /// every fragment (k = n whatever the importance: its count, read back first, says so).
    pub features_drawn: Option<bool>,
    /// VKB: per pixel the count and the nearest fragment's `|n . e|`.
    pub vkb_nearest: Option<(Vec<u32>, Vec<f32>)>,
    /// With diagnostics, where the scene has opaque surfaces: the opaque pass's colour and
    /// depth per pixel ([`FragmentLists::opaque`] and `opaque_depth`; the A-buffer's
    /// `fragments` carry them too).
    pub opaque: Option<(Vec<u32>, Vec<f32>)>,
    /// The pass variants the frame recorded, where an option of the device chooses between
    /// two ("features: preload", "network: written out", "allocation search: 32 copies",
    /// "capture: built for frames that fit", "fkb slots: layer-major", ...): so a test that
    /// compares an option on and off can see that the other path ran.
    pub variants: Vec<&'static str>,
    /// DKB, with diagnostics: how many pixels its network ran on (the length of the compacted
    /// list its importance pass selects: covered pixels whose k is not forced, or every covered
    /// pixel with `skip_forced` off); None where the frame did not record the network.
    pub network_rows: Option<u32>,
    /// k-buffers, with diagnostics: each pixel's cursor as the capture left it, before the
    /// resolve, so a test can see which mode each pixel took. With per-pixel tails (FKB, an
    /// uploaded k) the tail's count: n where the two-mode capture appended (its cursor counts
    /// every fragment), the fragments pushed out where it inserted. With the tails pooled
    /// (DKB, VKB, an allocated importance) the count: 0 where it appended (its cursor takes
    /// it down), n where it inserted.
    pub capture_counts: Option<Vec<u32>>,
    /// The linked list, with diagnostics: the fragments that arrived at its store, kept or
    /// dropped (its `fragments` are those it kept).
    pub list_arrived: Option<u64>,
    /// DKB, VKB and an uploaded importance, with diagnostics: the plan the frame made on the
    /// device from its own count ([`crate::plan`]; its `batches` are the features passes
    /// recorded).
    pub plan: Option<Plan>,
    /// DKB, where its features pass drew: the batches it gathered its records in
    /// ([`crate::budget::PoolState::batch`]: more than one where the pool is smaller than
    /// the records, each batch drawing the features pass once).
    pub record_batches: Option<u64>,
}

impl Gpu {
    fn bind(&self, layout: &wgpu::BindGroupLayout, buffers: &[&wgpu::Buffer]) -> wgpu::BindGroup {
        self.bind_with(layout, buffers, Vec::new())
    }

    /// A bind group of `buffers` at bindings 0, 1, ... and the `extra` entries (textures).
    fn bind_with<'b>(
        &self,
        layout: &wgpu::BindGroupLayout,
        buffers: &[&'b wgpu::Buffer],
        extra: Vec<wgpu::BindGroupEntry<'b>>,
    ) -> wgpu::BindGroup {
        let mut entries = passes::entries(buffers);
        entries.extend(extra);
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout,
            entries: &entries,
        })
    }

    /// A bind group with buffers at the given binding indices.
    fn bind_at(
        &self,
        layout: &wgpu::BindGroupLayout,
        buffers: &[(u32, &wgpu::Buffer)],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> =
            buffers.iter().map(|&(i, b)| passes::at(i, b)).collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout,
            entries: &entries,
        })
    }
}

/// What a frame's buffers are sized for before the frame is counted on the device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Sizing {
    /// The frame's own occupancy: its client counted first (`Gpu::render`, whose memory is the
    /// frame's own to the byte). The host then knows every decision of the frame's plan
    /// ([`crate::plan`]): where it keeps every fragment a DKB or VKB frame is the A-buffer's,
    /// and a frame records only the passes it runs.
    Own(Occupancy),
    /// Buffers made before the count, from what the client expects (an application's frame:
    /// an earlier frame's count, read back without waiting): the A-buffer's and MLAB's pool
    /// holds `fragments`, an allocated k-buffer's slot pool is `pool_bytes`, and DKB records
    /// `batches` features passes. The frame's plan fits what it has into them on the device.
    Ahead {
        fragments: u64,
        pool_bytes: u64,
        batches: u64,
    },
}

impl Sizing {
    /// No pool: the methods whose memory does not follow the frame's count (FKB, WBOIT, MBOIT,
    /// the linked list, an uploaded allocation).
    const NOTHING: Sizing = Sizing::Ahead {
        fragments: 0,
        pool_bytes: 0,
        batches: 1,
    };
}

/// A frame for the engine to record: how, at what size, its parameters (the client's camera,
/// background and opacity), which method ([`Slots`]; the A-buffer where None) and what its
/// buffers are sized for.
struct FrameSpec<'s> {
    opts: FrameOptions,
    size: (u32, u32),
    params: Params,
    slots: Slots<'s>,
    sizing: Sizing,
    /// DKB's record marks from the frame before, where its client keeps them ([`Carried`]).
    carried: Option<Carried>,
}

/// DKB's record marks a frame's client keeps from one frame for the next (an application's
/// stream, `Gpu::render`'s count first): the pixels of more than TAIL_WORDS fragments of the
/// frame that marked them (totals.wgsl's mark_records, records.wgsl), `marks_bytes` of the
/// frame's pixels. Where they are `valid` (the last frame of this size marked them), a DKB frame
/// gathers its network's statistics for those pixels with its count
/// ([`Tuning::two_pass_dkb`]) and draws no features pass; every DKB frame leaves its own
/// marks there for the frame after.
#[derive(Clone, Debug)]
pub(super) struct Carried {
    pub(super) marks: wgpu::Buffer,
    pub(super) valid: bool,
}

/// A frame's parameters for its method (`spec.slots`: its k, budget, importance map's
/// parameters, blending and list settings, what its capture does), the words its fragments
/// keep, and, for the allocated k-buffers, its plan (None where the exact A-buffer renders in
/// their place; the outer None for the other methods): made before the parameters, as a DKB
/// frame gathers its statistics with its count where its plan lets it.
fn method_params(
    spec: &FrameSpec,
    px: u64,
) -> Result<(Params, budget::Words, Option<Option<Planned>>)> {
    let slots = spec.slots;
    let opts = spec.opts;
    let mut params = spec.params;
    let (budget, vkb, k_uniform) = match slots {
        // A byte budget's F waits for the frame's count: the plan's (Recording::planned).
        Slots::Importance(_, _, f) => (f, VkbParams::default(), 0),
        Slots::Dkb(_, f) => (f.fragments().unwrap_or(0.into()), VkbParams::default(), 0),
        Slots::Vkb(v, f) => (f.fragments().unwrap_or(0.into()), v, 0),
        Slots::Uniform(k) => (0.into(), VkbParams::default(), k.max(1)),
        Slots::Mlab(m) => {
            if m == 0 || m > MLAB_MAX_ROWS {
                return Err(Error::Invalid(format!(
                    "MLAB on the GPU takes 1 to {MLAB_MAX_ROWS} rows, not {m}"
                )));
            }
            (0.into(), VkbParams::default(), m)
        }
        Slots::LinkedList { nodes, sorted } => {
            crate::composite::check_list_sorted(sorted)?;
            (nodes.into(), VkbParams::default(), 0)
        }
        Slots::PerPixel(_) | Slots::Wboit(_) | Slots::Mboit(_) | Slots::Exact => {
            (0.into(), VkbParams::default(), 0)
        }
    };
    set_method_params(&mut params, k_uniform, budget, vkb);
    let words = budget::Words::of(params.tinted != 0, params.tinted != 0 || params.hdr != 0);
    // The allocated k-buffers' plan (None: the exact A-buffer in their place), made before
    // the parameters: a DKB frame gathers its statistics with its count where it can.
    let planned = match slots {
        Slots::Importance(..)
        | Slots::Vkb(..)
        | Slots::Dkb(..)
        | Slots::PerPixel(_)
        | Slots::Uniform(_) => Some(planned(slots, &opts, px, spec.sizing, words)?),
        _ => None,
    };
    if let (Slots::Dkb(..), Some(Some(planned))) = (slots, &planned) {
        params.dkb_records = planned.gathered_with_count(&opts, spec.carried.as_ref()) as u32;
    }
    let allocated = matches!(
        slots,
        Slots::Importance(..) | Slots::Vkb(..) | Slots::Dkb(..)
    );
    // The allocated k-buffers know n(p) by the capture: two-mode capture (capture.wgsl),
    // and their tails in the slot pool.
    params.append = (opts.tuning.two_mode_capture && allocated).into();
    params.pooled_tail = allocated.into();
    params.layer_major = (opts.tuning.layer_major_fkb && matches!(slots, Slots::Uniform(_))).into();
    if let Slots::LinkedList { sorted, .. } = slots {
        params.list_sorted = sorted;
    }
    if let Slots::Mboit(m) = slots {
        blend::set_mboit(&mut params, &m);
    }
    if let Slots::Wboit(w) = slots {
        blend::set_wboit(&mut params, &w)?;
    }
    params.store_primitives = (matches!(slots, Slots::Mlab(_)) || opts.diagnostics).into();
    Ok((params, words, planned))
}

/// A frame recorded into its client's encoder, not yet run: what the client reads back once
/// its submission has run, and the buffers it holds until then.
struct Recorded<'a> {
    out: Readback,
    taken: buffers::Taken<'a>,
    /// Bytes of every buffer the method allocated for the frame.
    allocated: u64,
    /// Whether a DKB or VKB frame rendered the exact A-buffer in its place (its client counted
    /// first, and the A-buffer was no dearer).
    exact: bool,
    /// Whether the frame left its own record marks in its client's [`Carried`] marks (a DKB
    /// frame that recorded its statistics' passes): the next frame may gather with its count.
    marked: bool,
}

/// One frame being recorded: its passes, the buffers it takes (and the encoder it records
/// into) and what it will read back. Each pass file adds its part of the frame as a method.
struct Recording<'f, 'a, 'e> {
    passes: &'f Passes<'e>,
    fb: FrameBuffers<'a, 'e>,
    out: Readback,
    /// Pixels.
    px: u64,
    sizing: Sizing,
    /// What the methods that store fragments store beside each one's key (`Params::tinted` or
    /// `Params::hdr`): its tint word (tint and colour exponent), and where the glass is tinted
    /// the k-buffers' tails' sums of what the tints take away.
    words: budget::Words,
    /// DKB's record marks from the frame before ([`FrameSpec::carried`]).
    carried: Option<Carried>,
    /// Whether DKB's passes left this frame's record marks in the carried ones.
    marked: bool,
}

impl Gpu {
    /// Records one frame into `enc`, every pass of it, its geometry drawn by `geometry` (the
    /// frame's client), timed by `timer` where the device has timestamps: no submission, no
    /// wait. What depends on the frame's count is decided on the device ([`crate::plan`]).
    fn record_frame<'a, 'e>(
        &'a self,
        enc: &'e mut wgpu::CommandEncoder,
        timer: &'e Timer<'a>,
        geometry: &'e dyn passes::Geometry,
        spec: &FrameSpec,
    ) -> Result<Recorded<'a>> {
        let opts = spec.opts;
        let size = spec.size;
        let (width, height) = size;
        let px = width as u64 * height as u64;
        let slots = spec.slots;
        let (params, words, planned) = method_params(spec, px)?;
        let mut fb = FrameBuffers::new(self, enc);
        let params_buf = fb.init(
            "params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
            true,
        );
        let passes = Passes::new(self, timer, params_buf, params.pixels, opts, geometry);
        let mut rec = Recording {
            passes: &passes,
            fb,
            out: Readback::default(),
            px,
            sizing: spec.sizing,
            words,
            carried: spec.carried.clone(),
            marked: false,
        };
        if matches!(slots, Slots::Uniform(_)) {
            rec.out.variants.push(if opts.tuning.layer_major_fkb {
                "fkb slots: layer-major"
            } else {
                "fkb slots: pixel-major"
            });
        }
        let mut exact = false;
        match slots {
            Slots::Exact => rec.abuffer(Blend::Exact, size)?,
            Slots::Mlab(_) => rec.abuffer(Blend::Mlab, size)?,
            Slots::Wboit(_) => rec.wboit(size)?,
            Slots::Mboit(m) => rec.mboit(size, m.moments)?,
            Slots::LinkedList { nodes, .. } => rec.linked_list(nodes, size)?,
            s => match planned.expect("planned above") {
                None => {
                    exact = true;
                    rec.abuffer(Blend::Exact, size)?
                }
                Some(planned) => {
                    let k = rec.k_for(s, planned)?;
                    rec.capture_and_resolve(s, k)?
                }
            },
        }
        timer.resolve(rec.fb.enc);
        let allocated = rec.fb.allocated;
        Ok(Recorded {
            out: rec.out,
            taken: rec.fb.into_taken(),
            allocated,
            exact,
            marked: rec.marked,
        })
    }
}

/// An allocated k-buffer's frame as its client sized it: its plan's input, the plan itself
/// where the host knows it ([`Sizing::Own`]), and the features passes DKB records.
#[derive(Clone, Copy, Debug)]
struct Planned {
    input: PlanInput,
    host: Option<Plan>,
}

impl Planned {
    /// Whether the host knows that the frame keeps every fragment (k = n): then it records no
    /// statistics, importance or features pass.
    fn known_exact(&self) -> bool {
        self.host.is_some_and(|p| p.exact)
    }

    /// DKB's records a batch holds where the host does not know the plan: as many as the pool
    /// holds ([`budget::PoolState`]: a record and its entry in the network's list each), at
    /// least one, at most a pixel each (`plan.wgsl` takes the smaller of that and the records).
    fn records_held(&self, px: u64) -> u64 {
        let ps = self
            .input
            .layout
            .pool_state
            .expect("DKB keeps its records in its pool");
        (self.input.pool_bytes / (ps.record_bytes + ps.list_bytes)).clamp(1, px)
    }

    /// The records whose statistics a DKB frame gathers with its count
    /// ([`Tuning::two_pass_dkb`]): as many as its pool holds at once, where it gathers any
    /// (the host does not know it keeps every fragment), its records take one batch, and
    /// `carried` holds valid marks from the frame before; else 0: it marks its own records and
    /// draws a features pass for them.
    fn gathered_with_count(&self, opts: &FrameOptions, carried: Option<&Carried>) -> u64 {
        let px = self.input.pixels;
        match opts.tuning.two_pass_dkb
            && !self.known_exact()
            && self.input.batches <= 1
            && carried.is_some_and(|c| c.valid)
        {
            true => self.records_held(px),
            false => 0,
        }
    }
}

/// How a DKB, VKB or uploaded importance frame runs: None where its client counted first and,
/// with [`budget::Decision::exact_when_cheaper`], the frame renders the exact A-buffer as the CPU's
/// would ([`crate::plan::Counted::exact`]; then the frame is the A-buffer's), else its plan's
/// input (the pool sized for the occupancy its client expects, `sizing`) and, counted first,
/// the plan the device will make. `words` are what its fragments store beside their keys.
fn planned(
    s: Slots,
    opts: &FrameOptions,
    px: u64,
    sizing: Sizing,
    words: budget::Words,
) -> Result<Option<Planned>> {
    let (method, mut layout, asked) = match s {
        Slots::Dkb(mlp, b) => (Method::Dkb, opts.dkb_layout(mlp), b),
        Slots::Vkb(_, b) => (Method::Vkb, budget::VKB, b),
        Slots::Importance(_, _, f) => (Method::Vkb, budget::VKB, f.into()),
        // FKB's and an uploaded k's frames: their k is given, no F to plan.
        _ => (Method::Vkb, budget::VKB, 0.into()),
    };
    // Where the frame is tinted, its slots and tails take what the tints leave of M
    // (Layout::tinted_fragment_budget).
    let plan_budget = match asked {
        PlanBudget::Bytes(m) => PlanBudget::Bytes(layout.tinted_budget(m, px, words)),
        b => b,
    };
    let exact_when_cheaper =
        opts.decision.exact_when_cheaper && matches!(s, Slots::Dkb(..) | Slots::Vkb(..));
    let (pool_bytes, batches, host) = match sizing {
        Sizing::Own(occ) => {
            // What the budget comes to on this count, decided as the CPU decides it: a byte
            // budget that holds DKB's records only in batches takes a pool of a batch.
            let counted = crate::plan::counted(method, &layout, asked, px, &occ, words)?;
            if let PlanBudget::Bytes(m) = plan_budget {
                layout = layout.for_bytes(m, px, &occ);
            }
            if exact_when_cheaper && counted.exact(true) {
                return Ok(None);
            }
            let pool_bytes = layout.pool_for(px, counted.f, &occ);
            let batches = layout
                .pool_state
                .map_or(1, |ps| ps.batch(pool_bytes, occ.deeper).1);
            (pool_bytes, batches, Some(occ))
        }
        Sizing::Ahead {
            pool_bytes,
            batches,
            ..
        } => (pool_bytes, batches, None),
    };
    let input = PlanInput {
        layout,
        pixels: px,
        budget: plan_budget,
        pool_bytes,
        batches,
        exact_when_cheaper,
    };
    let host = host.map(|occ| crate::plan::plan(&input, &occ));
    Ok(Some(Planned { input, host }))
}

/// The per-frame uniform, as a client gives it: the camera (`cam`, None for an application's
/// frame: its own vertex stage projects), the frame's size and the background; the method's
/// fields are the engine's ([`Gpu::record_frame`]).
fn frame_params(cam: Option<&Camera>, size: (u32, u32), background: [f32; 3]) -> Params {
    let (width, height) = size;
    let (view_proj, forward, eye) = match cam {
        Some(c) => (
            c.view_proj.to_cols_array_2d(),
            c.forward.extend(0.0).to_array(),
            c.eye.extend(1.0).to_array(),
        ),
        None => (
            glam::Mat4::IDENTITY.to_cols_array_2d(),
            [0.0, 0.0, 1.0, 0.0],
            [0.0; 4],
        ),
    };
    Params {
        view_proj,
        forward,
        background: [background[0], background[1], background[2], 1.0],
        eye,
        width,
        height,
        k_uniform: 0,
        pixels: width * height,
        budget_fragments: 0,
        vkb_alpha: 0.0,
        vkb_exponent: 0.0,
        vkb_noise: 0.0,
        vkb_seed: 0,
        budget_ppm: 0,
        append: 0,
        layer_major: 0,
        uniform_alpha: -1.0,
        store_primitives: 0,
        mboit_bias: 0.0,
        mboit_overestimation: 0.0,
        list_sorted: 0,
        pooled_tail: 0,
        wboit_weight: 0,
        wboit_near: 0.0,
        wboit_far: 0.0,
        tinted: 0,
        hdr: 0,
        dkb_records: 0,
        _pad: [0; 12],
    }
}

/// The method's fields of the frame's uniform: FKB's or MLAB's k, F (slots or a share: the
/// list reads its nodes there), VKB's parameters.
fn set_method_params(params: &mut Params, k_uniform: u32, budget: FragmentBudget, vkb: VkbParams) {
    let (budget_fragments, budget_ppm) = match budget {
        FragmentBudget::Slots(f) => (f, 0),
        FragmentBudget::Share(ppm) => (0, ppm),
    };
    params.k_uniform = k_uniform;
    params.budget_fragments = budget_fragments.min(u32::MAX as u64) as u32;
    params.budget_ppm = budget_ppm;
    params.vkb_alpha = vkb.alpha;
    params.vkb_exponent = vkb.periphery_exponent;
    params.vkb_noise = vkb.noise;
    params.vkb_seed = vkb.seed;
}

/// The error scopes a frame records under ([`Gpu::begin_frame`]).
struct Scopes {
    // Fields drop in order: the scope pushed last first, should a frame end early.
    oom: wgpu::ErrorScopeGuard,
    validation: wgpu::ErrorScopeGuard,
}

impl Scopes {
    /// The first out-of-memory, then validation, error the frame raised.
    fn end(self) -> Result<()> {
        if let Some(e) = pollster::block_on(self.oom.pop()) {
            return Err(GpuError::OutOfMemory(e.to_string()).into());
        }
        if let Some(e) = pollster::block_on(self.validation.pop()) {
            return Err(GpuError::Validation(e.to_string()).into());
        }
        Ok(())
    }
}

impl Gpu {
    /// Checks the frame's size before anything is allocated (an error with the numbers), and
    /// starts catching the validation and out-of-memory errors its commands raise.
    fn begin_frame(&self, size: (u32, u32)) -> Result<Scopes> {
        let (width, height) = size;
        crate::raster::check_resolution(size)?;
        let max = self.device.limits().max_texture_dimension_2d;
        if width > max || height > max {
            return Err(GpuError::FrameTooLarge { width, height, max }.into());
        }
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        Ok(Scopes { oom, validation })
    }
}

#[cfg(test)]
mod tests {
    use super::instance_descriptors;
    use wgpu::{Backends, InstanceFlags};

    /// dhoit's own device skips wgpu's check of indirect dispatches (its shaders bound their
    /// arguments) everywhere but D3D12, which needs it for `num_workgroups`, and the two
    /// instances share no backend (an adapter is offered once).
    #[test]
    fn indirect_dispatches_are_unchecked_except_on_d3d12() {
        let env = |v: &str| std::env::var(v).is_ok();
        if env("WGPU_VALIDATION_INDIRECT_CALL") || env("WGPU_BACKEND") {
            eprintln!("SKIPPED: WGPU_VALIDATION_INDIRECT_CALL or WGPU_BACKEND is set");
            return;
        }
        let [direct, dx12] = instance_descriptors();
        assert!(
            !direct
                .flags
                .contains(InstanceFlags::VALIDATION_INDIRECT_CALL)
        );
        assert!(dx12.flags.contains(InstanceFlags::VALIDATION_INDIRECT_CALL));
        assert!(!direct.backends.contains(Backends::DX12));
        assert!(direct.backends.contains(Backends::VULKAN | Backends::METAL));
        assert_eq!(dx12.backends, Backends::DX12);
        assert!((direct.backends & dx12.backends).is_empty());
    }
}
