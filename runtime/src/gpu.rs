//! The wgpu renderer: the A-buffer and the k-buffer capture/resolve passes on any Vulkan, Metal
//! or DX12 device (here Mesa's lavapipe), each pass the twin of a CPU function that the tests
//! hold it to.
//!
//! Passes (shaders in `shaders/`, one file a pass, with the generated prelude, `common.wgsl`
//! and their includes prepended: `geometry.wgsl`, `mlp.wgsl`, `sort.wgsl`; see
//! [`crate::wgsl::shaders`]):
//! - A-buffer: `abuffer_count` (geometry) -> `scan` (offsets) -> `abuffer_store` (geometry, exact
//!   memory: the fragment pool is sized from the count) -> `abuffer_resolve` (sort and blend).
//! - k-buffer: per-pixel k uploaded (or one k for all), `scan` (slot bases) -> `capture`
//!   (geometry, lock-free 64-bit insertion, evicted fragments to integer tail sums) -> `resolve`.
//! - MLAB: the A-buffer's count, scan and store, then `mlab_resolve` (fragments in submission
//!   order into m blending rows).
//!
//! Every buffer a method's frame allocates is labelled after the [`crate::budget::Layout`] entry
//! it realises and counted, so [`GpuFrame::allocated_bytes`] is what the device really holds.
//!
//! The renderer persists across frames: pipelines are built once ([`Gpu::new`]; variants of the
//! network's passes on first use), and a frame takes its buffers from those earlier frames left
//! (cleared where reused), so a stream of like frames creates none.

use crate::alloc::Target;
use crate::budget::{self, Budget, FragmentBudget};
use crate::composite::Image;
use crate::error::{Error, GpuError, Result};
use crate::fragment::FragmentLists;
use crate::frame::{Allocation, Equal, Method, Options};
use crate::importance::{PixelStats, VkbParams};
use crate::mlp::{Mlp, Precision};
use crate::scene::{Camera, Scene};
use crate::wgsl::{
    ALLOC_GROUP, ALLOC_STATE_WORDS, AllocParams, MLAB_MAX_ROWS, PIXEL_GROUP, Params, SEARCH_ROUNDS,
    grid, mlp_uniform, shaders,
};
use wgpu::util::DeviceExt;

/// Features the pipeline cannot run without.
pub fn required_features() -> wgpu::Features {
    wgpu::Features::SHADER_INT64
        | wgpu::Features::SHADER_INT64_ATOMIC_ALL_OPS
        | wgpu::Features::TIMESTAMP_QUERY
}

/// A device and queue with the pipeline's features, and the compiled passes.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// "name (backend, device type, driver)".
    pub adapter: String,
    timestamp_period: f32,
    pipelines: Pipelines,
    /// Whether DKB's importance pass skips the network where k does not depend on it (on by
    /// default; the bench turns it off to show the time saved). The images are the same.
    pub skip_forced: bool,
    /// Whether the allocated k-buffers (DKB, VKB, uploaded importance), which know n(p) by the
    /// capture, append the pixels whose slots hold all but at most
    /// [`crate::composite::APPEND_SPILL`] fragments and insert the rest (capture.wgsl); off,
    /// every fragment is inserted (the bench's comparison). The images are the same.
    pub two_mode_capture: bool,
    /// Whether a frame reads back what the tests compare besides the image (the A-buffer's
    /// fragments, the k-buffer's slots and tails, importance and statistics): on by default;
    /// off, a frame reads back its image only (the bench's steady-state frames).
    pub diagnostics: bool,
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

/// Most buffers the pool keeps (beyond, a returned buffer is dropped).
const POOL_MAX: usize = 64;
/// Timestamped passes a frame has room for.
const TIMED_PASSES: u32 = 16;

impl Gpu {
    /// A buffer for a frame: the pooled one under `key` when its size and usage match (cleared
    /// through `clear` when given, since a reused buffer holds the last frame's data), else a
    /// new one (zeroed by wgpu).
    fn acquire(
        &self,
        key: &str,
        size: u64,
        usage: wgpu::BufferUsages,
        clear: Option<&mut Option<wgpu::CommandEncoder>>,
    ) -> wgpu::Buffer {
        let pooled = self
            .pool
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(key);
        match pooled {
            Some(b) if b.size() == size && b.usage() == usage => {
                if let Some(enc) = clear {
                    enc.get_or_insert_with(|| {
                        self.device.create_command_encoder(&Default::default())
                    })
                    .clear_buffer(&b, 0, None);
                }
                b
            }
            _ => {
                self.created
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(key),
                    size,
                    usage,
                    mapped_at_creation: false,
                })
            }
        }
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

struct Pipelines {
    count: wgpu::RenderPipeline,
    store: wgpu::RenderPipeline,
    capture: wgpu::RenderPipeline,
    scan_blocks: wgpu::ComputePipeline,
    scan_sums: wgpu::ComputePipeline,
    scan_add: wgpu::ComputePipeline,
    abuffer_resolve: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
    mlab_resolve: wgpu::ComputePipeline,
    allocate: Allocate,
    features: wgpu::RenderPipeline,
    totals: wgpu::ComputePipeline,
    /// The network's passes (DKB importance, predict), built for one network shape, precision
    /// and SKIP_FORCED each ([`Variant`]): the default network's at f32 at start-up, the others
    /// when first asked for ([`Gpu::network_pass`]).
    variants: std::sync::Mutex<std::collections::HashMap<Variant, wgpu::ComputePipeline>>,
    vkb_count: wgpu::RenderPipeline,
    importance_vkb: wgpu::ComputePipeline,
}

const TARGET_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R8Unorm;

impl Gpu {
    /// Opens the first adapter that has every required feature; the error names what the
    /// adapters lack.
    pub fn new() -> Result<Gpu> {
        Self::requiring(wgpu::Features::empty())
    }

    /// [`Gpu::new`], with `extra` features required on top of the pipeline's (tests use it to
    /// see what happens on an adapter that lacks one).
    pub fn requiring(extra: wgpu::Features) -> Result<Gpu> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        if adapters.is_empty() {
            return Err(GpuError::NoAdapter.into());
        }
        let need = required_features() | extra;
        let mut lacking = Vec::new();
        let adapter = adapters.into_iter().find(|a| {
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
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("dhoit"),
            required_features: need,
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Open {
            adapter: info.name.clone(),
            message: e.to_string(),
        })?;
        let adapter_name = format!(
            "{} ({:?}, {:?}, {} {})",
            info.name, info.backend, info.device_type, info.driver, info.driver_info
        );
        let pipelines = Pipelines::new(&device)?;
        Ok(Gpu {
            timestamp_period: queue.get_timestamp_period(),
            device,
            queue,
            adapter: adapter_name,
            pipelines,
            skip_forced: true,
            two_mode_capture: true,
            diagnostics: true,
            pool: Default::default(),
            query_sets: Default::default(),
            created: Default::default(),
        })
    }
}

fn module(device: &wgpu::Device, name: &str) -> wgpu::ShaderModule {
    module_from(device, name, shaders::source(name).expect("known pass"))
}

fn module_from(device: &wgpu::Device, label: &str, src: String) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    })
}

fn compute_pipeline(
    device: &wgpu::Device,
    label: &str,
    m: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: None,
        module: m,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// A pass that runs the network, with its constants.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Variant {
    /// "importance_dkb" or "predict".
    pass: &'static str,
    skip_forced: bool,
    precision: Precision,
    /// The network's padded layer sizes ([`crate::mlp::padded_units`]), built into the pass so
    /// its loops have known lengths; (0, 0) reads them from the uniform.
    shape: (u32, u32),
}

impl Variant {
    fn pipeline(self, device: &wgpu::Device) -> wgpu::ComputePipeline {
        let label = format!(
            "{} {:?} {} {:?}",
            self.pass, self.skip_forced, self.precision, self.shape
        );
        let m = module_from(device, &label, self.source());
        compute_pipeline(device, &label, &m, "main")
    }

    /// The pass `pass` for network `m`, its sizes built in.
    fn for_network(pass: &'static str, m: &Mlp, skip_forced: bool) -> Variant {
        let p = |h| crate::mlp::padded_units(h) as u32;
        Variant {
            pass,
            skip_forced,
            precision: m.precision,
            shape: (p(m.h1), p(m.h2)),
        }
    }

    /// Its source: the pass's, with the constants it changes replaced.
    fn source(self) -> String {
        let mut src = shaders::source(self.pass).expect("known pass");
        let mut set = |from: &str, to: &str| {
            assert!(src.contains(from), "{} declares {from}", self.pass);
            src = src.replace(from, to);
        };
        if !self.skip_forced {
            set(
                "const SKIP_FORCED: bool = true;",
                "const SKIP_FORCED: bool = false;",
            );
        }
        if self.precision == Precision::F16 {
            set(
                "const F16_WEIGHTS: bool = false;",
                "const F16_WEIGHTS: bool = true;",
            );
        }
        let (p1, p2) = self.shape;
        // Known sizes: the private sums hold exactly p2 floats.
        if p1 != 0 {
            set(
                "const NET_P1: u32 = 0u;",
                &format!("const NET_P1: u32 = {p1}u;"),
            );
            set(
                "const NET_P2: u32 = 0u;",
                &format!("const NET_P2: u32 = {p2}u;"),
            );
            set(
                "const ACC2_VEC4S: u32 = MAX_H2 / 4u;",
                &format!("const ACC2_VEC4S: u32 = {}u;", p2 / 4),
            );
        }
        src
    }
}

impl Gpu {
    /// The pipeline of a network pass: built at start-up for the default network, else on
    /// first use.
    fn network_pass(&self, v: Variant) -> wgpu::ComputePipeline {
        let mut variants = self
            .pipelines
            .variants
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        variants
            .entry(v)
            .or_insert_with(|| v.pipeline(&self.device))
            .clone()
    }
}

impl Pipelines {
    fn new(device: &wgpu::Device) -> Result<Pipelines> {
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let geometry = |name: &str| {
            let m = module(device, name);
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(name),
                layout: None,
                vertex: wgpu::VertexState {
                    module: &m,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: None,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &m,
                    entry_point: Some("fs_main"),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: TARGET_FORMAT,
                        blend: None,
                        write_mask: wgpu::ColorWrites::empty(),
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let compute_entry =
            |name: &str, entry: &str| compute_pipeline(device, name, &module(device, name), entry);
        let compute = |name: &str| compute_entry(name, "main");
        let p = Pipelines {
            count: geometry("abuffer_count"),
            store: geometry("abuffer_store"),
            capture: geometry("capture"),
            scan_blocks: compute_entry("scan", "scan_blocks"),
            scan_sums: compute_entry("scan", "scan_sums"),
            scan_add: compute_entry("scan", "scan_add"),
            abuffer_resolve: compute("abuffer_resolve"),
            resolve: compute("resolve"),
            mlab_resolve: compute("mlab_resolve"),
            allocate: Allocate::new(device),
            features: geometry("features"),
            totals: compute("totals"),
            variants: std::sync::Mutex::new(
                [("importance_dkb", true), ("predict", true)]
                    .map(|(pass, skip)| {
                        let p = crate::mlp::padded_units;
                        let v = Variant {
                            pass,
                            skip_forced: skip,
                            precision: Precision::F32,
                            shape: (p(crate::mlp::H1) as u32, p(crate::mlp::H2) as u32),
                        };
                        (v, v.pipeline(device))
                    })
                    .into_iter()
                    .collect(),
            ),
            vkb_count: geometry("vkb_count"),
            importance_vkb: compute("importance_vkb"),
        };
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Pipeline(e.to_string()).into());
        }
        Ok(p)
    }
}

/// How the k-buffer gets its k.
#[derive(Clone, Copy, Debug)]
pub enum Slots<'a> {
    /// One k for every pixel (FKB).
    Uniform(u32),
    /// k per pixel, computed elsewhere (the optimal allocation, or any CPU allocation).
    PerPixel(&'a [u32]),
    /// MLAB with this many rows (at most [`MLAB_MAX_ROWS`]), blended from the A-buffer's
    /// fragments taken in submission order.
    Mlab(u32),
    /// Per-pixel importance (computed elsewhere), what it means and F: the GPU counts
    /// fragments, allocates k (`allocate.wgsl`, the twin of `alloc::allocate`), then captures
    /// and resolves.
    Importance(&'a [f32], Target, FragmentBudget),
    /// The variable k-buffer, every pass on the GPU: count and nearest fragment, totals, paper
    /// 002's importance, allocation, capture, resolve.
    Vkb(VkbParams, FragmentBudget),
    /// The deep k-buffer, every pass on the GPU: features, totals, the network's importance,
    /// allocation, capture, resolve.
    Dkb(&'a Mlp, FragmentBudget),
}

impl<'a> Slots<'a> {
    /// How the GPU renders `method` for the allocation the CPU made with `options` (`cpu`,
    /// from [`crate::frame::Renderer::allocate_for_gpu`] or `allocate`): FKB and MLAB with the
    /// CPU's k; VKB and DKB allocating on the device at the CPU's F (a share of the fragments
    /// at equal F stays a share, resolved from the GPU's own count); every allocation only the
    /// CPU makes (optimal, the greedies) uploaded as per-pixel k; `None` for the A-buffer. The
    /// one method-to-slots mapping: render, bench and the tests use it, so a method gets the
    /// same k whichever command renders it.
    pub fn for_method(
        method: Method,
        cpu: &'a Allocation,
        options: &Options<'a>,
    ) -> Result<Option<Slots<'a>>> {
        let budget = match options.budget {
            Budget::Share(ppm) if options.equal == Equal::Slots => FragmentBudget::Share(ppm),
            _ => FragmentBudget::Slots(cpu.budget_fragments),
        };
        let first = || cpu.k.first().copied().unwrap_or(0);
        Ok(match method {
            Method::Abuffer => None,
            Method::Fkb => Some(Slots::Uniform(first())),
            // MLAB on the GPU blends from the A-buffer (exact memory, not the budget's rows).
            Method::Mlab => Some(Slots::Mlab(first())),
            Method::Vkb => Some(Slots::Vkb(options.vkb, budget)),
            Method::Dkb => Some(Slots::Dkb(
                options.weights.ok_or_else(|| {
                    Error::Invalid("dkb needs network weights (--weights FILE)".into())
                })?,
                budget,
            )),
            Method::Optimal | Method::GreedyPaper | Method::GreedyIncrease => {
                Some(Slots::PerPixel(&cpu.k))
            }
        })
    }
}

/// The allocation pass's weight kind for a target (`Alloc.kind` in allocate.wgsl).
fn weight_kind(t: Target) -> u32 {
    match t {
        Target::RelativeK => 0,
        Target::ShareOfFragments => 1,
        Target::SlotRequest => 2,
    }
}

impl Gpu {
    /// The network on rows of features, on the GPU: the batch pass `predict.wgsl` runs the same
    /// WGSL network (`mlp.wgsl`) as the DKB importance pass. Rows go through in chunks that fit
    /// the device's largest binding.
    pub fn predict(
        &self,
        mlp: &Mlp,
        rows: &[[f32; crate::importance::FEATURES]],
    ) -> Result<Vec<f32>> {
        let weights = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("mlp.weights"),
                contents: bytemuck::cast_slice(&mlp_uniform(mlp)),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let limit = self.device.limits().max_storage_buffer_binding_size;
        let chunk = ((limit / 48) as usize).clamp(1, 1 << 22);
        let mut out = Vec::with_capacity(rows.len());
        for part in rows.chunks(chunk) {
            let n = part.len() as u32;
            // The pass reads the row count from the frame parameters' pixel count.
            let mut params: Params = bytemuck::Zeroable::zeroed();
            params.pixels = n;
            let params_buf = self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("params"),
                    contents: bytemuck::bytes_of::<Params>(&params),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            let input = self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("predict.rows"),
                    contents: bytemuck::cast_slice(part),
                    usage: wgpu::BufferUsages::STORAGE,
                });
            let size = (4 * n as u64).max(16);
            let output = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("predict.out"),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let pl = &self.network_pass(Variant::for_network("predict", mlp, true));
            let group = self.bind_at(
                &pl.get_bind_group_layout(0),
                &[(0, &params_buf), (1, &weights), (2, &input), (3, &output)],
            );
            let mut enc = self.device.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(pl);
                pass.set_bind_group(0, &group, &[]);
                let (gx, gy) = grid(n, PIXEL_GROUP);
                pass.dispatch_workgroups(gx, gy, 1);
            }
            self.queue.submit([enc.finish()]);
            out.extend(
                u32s(&read_back(self, &output, 4 * n as u64)?)
                    .into_iter()
                    .map(f32::from_bits),
            );
        }
        Ok(out)
    }
}

/// What a GPU frame produced, read back.
#[derive(Clone, Debug)]
pub struct GpuFrame {
    pub image: Image,
    /// Milliseconds of each pass, from timestamp queries, in order.
    pub pass_ms: Vec<(&'static str, f64)>,
    /// Bytes of every buffer and target the method allocated for this frame.
    pub allocated_bytes: u64,
    /// A-buffer: the GPU's own fragments (sorted front to back within each pixel).
    pub fragments: Option<FragmentLists>,
    /// k-buffer: the slots (capture keys, front to back; `u64::MAX` where empty), their bases
    /// (`pixels + 1` entries) and the tail sums (five per pixel).
    pub slots: Option<(Vec<u64>, Vec<u32>, Vec<u32>)>,
    /// VKB and DKB: the importance the GPU computed (uploaded importance: after allocation's
    /// fixed-point conversion is not returned).
    pub importance: Option<Vec<f32>>,
    /// DKB: the features pass's per-pixel statistics.
    pub stats: Option<Vec<PixelStats>>,
    /// VKB: per pixel the count and the nearest fragment's `|n . e|`.
    pub vkb_nearest: Option<(Vec<u32>, Vec<f32>)>,
}

struct FrameBuffers<'a> {
    gpu: &'a Gpu,
    allocated: u64,
    /// The prefix sum's block totals, created on first use and shared by every scan.
    scan_blocks: Option<wgpu::Buffer>,
    /// The buffers this frame took (pool key, buffer), put back when it ends.
    taken: Vec<(String, wgpu::Buffer)>,
    /// Clears of reused buffers, submitted before the frame's next commands.
    clears: Option<wgpu::CommandEncoder>,
}

impl<'a> FrameBuffers<'a> {
    fn new(gpu: &'a Gpu) -> Self {
        FrameBuffers {
            gpu,
            allocated: 0,
            scan_blocks: None,
            taken: Vec::new(),
            clears: None,
        }
    }

    /// A pooled buffer; a label asked for twice in one frame gets two buffers.
    fn take(
        &mut self,
        label: &str,
        size: u64,
        usage: wgpu::BufferUsages,
        zero: bool,
    ) -> wgpu::Buffer {
        let nth = self
            .taken
            .iter()
            .filter(|(k, _)| k.rsplit_once('#').map(|(l, _)| l) == Some(label))
            .count();
        let key = format!("{label}#{nth}");
        let clears = if zero { Some(&mut self.clears) } else { None };
        let b = self.gpu.acquire(&key, size, usage, clears);
        self.taken.push((key, b.clone()));
        b
    }

    /// A storage buffer of `size` bytes (at least 16), counted in the frame's allocation when
    /// `counted`; an error naming the buffer when the device cannot bind one that large.
    fn storage(&mut self, label: &str, size: u64, counted: bool) -> Result<wgpu::Buffer> {
        let size = size.max(16).next_multiple_of(4);
        let limits = self.gpu.device.limits();
        let max = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if size > max {
            return Err(GpuError::BufferTooLarge {
                label: label.to_string(),
                need: size,
                max,
            }
            .into());
        }
        if counted {
            self.allocated += size;
        }
        let usage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST;
        Ok(self.take(label, size, usage, true))
    }

    /// A buffer holding `bytes` (zero-padded to at least 16 bytes, a multiple of 4).
    fn init(
        &mut self,
        label: &str,
        bytes: &[u8],
        usage: wgpu::BufferUsages,
        counted: bool,
    ) -> wgpu::Buffer {
        if counted {
            self.allocated += bytes.len() as u64;
        }
        let size = (bytes.len() as u64).max(16).next_multiple_of(4);
        let usage = usage | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let b = self.take(label, size, usage, false);
        if bytes.len() as u64 == size {
            self.gpu.queue.write_buffer(&b, 0, bytes);
        } else {
            let mut padded = bytes.to_vec();
            padded.resize(size as usize, 0);
            self.gpu.queue.write_buffer(&b, 0, &padded);
        }
        b
    }

    /// Submits `enc` (after the clears of the buffers taken since the last submission) and
    /// starts a new encoder in its place.
    fn submit(&mut self, enc: &mut wgpu::CommandEncoder) {
        let done = std::mem::replace(
            enc,
            self.gpu.device.create_command_encoder(&Default::default()),
        );
        let clears = self.clears.take().map(|c| c.finish());
        self.gpu
            .queue
            .submit(clears.into_iter().chain([done.finish()]));
    }
}

impl Drop for FrameBuffers<'_> {
    fn drop(&mut self) {
        for (key, b) in self.taken.drain(..) {
            self.gpu.release(key, b);
        }
    }
}

fn read_back(gpu: &Gpu, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>> {
    let size = bytes.max(4).next_multiple_of(4);
    // Staging buffers are pooled by size (the image's is the same every frame).
    let key = format!("readback {size}");
    let usage = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
    let staging = gpu.acquire(&key, size, usage, None);
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(buffer, 0, &staging, 0, size);
    gpu.queue.submit([enc.finish()]);
    let slice = staging.slice(..);
    slice.map_async(wgpu::MapMode::Read, |_| {});
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Lost {
            doing: "waiting for a submission",
            message: e.to_string(),
        })?;
    let data = slice
        .get_mapped_range()
        .map_err(|e| GpuError::Lost {
            doing: "reading back",
            message: e.to_string(),
        })?
        .to_vec();
    staging.unmap();
    gpu.release(key, staging);
    Ok(data[..bytes as usize].to_vec())
}

fn u32s(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Timestamp queries around each pass (room for [`TIMED_PASSES`]; the set is reused by the
/// next frame).
struct Timer<'a> {
    gpu: &'a Gpu,
    set: Option<wgpu::QuerySet>,
    names: std::cell::RefCell<Vec<&'static str>>,
}

impl Drop for Timer<'_> {
    fn drop(&mut self) {
        if let Some(set) = self.set.take() {
            let mut sets = self
                .gpu
                .query_sets
                .lock()
                .unwrap_or_else(|e| e.into_inner());
            sets.push(set);
        }
    }
}

impl<'a> Timer<'a> {
    fn new(gpu: &'a Gpu) -> Timer<'a> {
        let pooled = gpu
            .query_sets
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .pop();
        let set = pooled.unwrap_or_else(|| {
            gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * TIMED_PASSES,
            })
        });
        Timer {
            gpu,
            set: Some(set),
            names: Default::default(),
        }
    }
    fn set(&self) -> &wgpu::QuerySet {
        self.set.as_ref().expect("held until the timer is dropped")
    }
    fn next(&self, name: &'static str) -> (u32, u32) {
        let mut names = self.names.borrow_mut();
        names.push(name);
        let i = 2 * (names.len() as u32 - 1);
        (i, i + 1)
    }
    fn read(&self, gpu: &Gpu) -> Result<Vec<(&'static str, f64)>> {
        let names = self.names.borrow();
        let n = 2 * names.len() as u64;
        let key = format!("timestamps.resolve {n}");
        let usage = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
        let buf = gpu.acquire(&key, 8 * n, usage, None);
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        enc.resolve_query_set(self.set(), 0..n as u32, &buf, 0);
        gpu.queue.submit([enc.finish()]);
        let raw = read_back(gpu, &buf, 8 * n);
        gpu.release(key, buf);
        let raw = raw?;
        let ticks: Vec<u64> = raw
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8")))
            .collect();
        Ok(names
            .iter()
            .enumerate()
            .map(|(i, &name)| {
                let dt = ticks[2 * i + 1].saturating_sub(ticks[2 * i]);
                (name, dt as f64 * gpu.timestamp_period as f64 / 1e6)
            })
            .collect())
    }
}

/// The frame's shared bindings and the pass timer: every pass is one call.
struct Passes<'a> {
    gpu: &'a Gpu,
    timer: &'a Timer<'a>,
    /// params, positions, colours: group 0 of every geometry pass.
    geometry: [&'a wgpu::Buffer; 3],
    target: &'a wgpu::TextureView,
    vertices: u32,
    pixels: u32,
}

impl<'a> Passes<'a> {
    fn new(gpu: &'a Gpu, timer: &'a Timer<'a>, inputs: &'a FrameInputs) -> Self {
        Passes {
            gpu,
            timer,
            geometry: [&inputs.params, &inputs.positions, &inputs.colors],
            target: &inputs.target,
            vertices: inputs.vertices,
            pixels: inputs.pixels,
        }
    }

    /// A geometry pass over every triangle, `buffers` bound as group 1.
    fn draw(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        buffers: &[&wgpu::Buffer],
        name: &'static str,
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
        pass.draw(0..self.vertices, 0..1);
    }

    /// A compute pass, `buffers` bound as group 0 in binding order.
    fn dispatch(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
        name: &'static str,
    ) {
        // Every dispatched pass is per pixel.
        let (gx, gy) = grid(self.pixels, PIXEL_GROUP);
        let g = self.gpu.bind(&pipeline.get_bind_group_layout(0), buffers);
        let (b, e) = self.timer.next(name);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(name),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: self.timer.set(),
                beginning_of_pass_write_index: Some(b),
                end_of_pass_write_index: Some(e),
            }),
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &g, &[]);
        pass.dispatch_workgroups(gx, gy, 1);
    }

    /// Exclusive prefix sum of `values` into `offsets` (pixels + 1 entries): three dispatches
    /// with a block-total buffer of one u32 per 256 pixels.
    fn prefix_sum(
        &self,
        enc: &mut wgpu::CommandEncoder,
        fb: &mut FrameBuffers,
        values: &wgpu::Buffer,
        offsets: &wgpu::Buffer,
    ) -> Result<()> {
        let p = &self.gpu.pipelines;
        let px = self.pixels;
        let groups = px.div_ceil(budget::SCAN_BLOCK as u32);
        if fb.scan_blocks.is_none() {
            fb.scan_blocks = Some(fb.storage("scan.blocks", 4 * groups as u64, true)?);
        }
        let blocks = fb.scan_blocks.clone().expect("created above");
        let params = self.geometry[0];
        // Auto layouts keep only the bindings an entry point uses: `values` only the first.
        let bind = |pl: &wgpu::ComputePipeline, all: bool| {
            let mut entries = vec![(0, params), (2, offsets), (3, &blocks)];
            if all {
                entries.push((1, values));
            }
            self.gpu.bind_at(&pl.get_bind_group_layout(0), &entries)
        };
        let (b, e) = self.timer.next("prefix sum");
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("prefix sum"),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: self.timer.set(),
                beginning_of_pass_write_index: Some(b),
                end_of_pass_write_index: Some(e),
            }),
        });
        let (gx, gy) = grid(px, budget::SCAN_BLOCK as u32);
        for (pl, n, all) in [
            (&p.scan_blocks, (gx, gy), true),
            (&p.scan_sums, (1, 1), false),
            (&p.scan_add, (gx, gy), false),
        ] {
            let g = bind(pl, all);
            pass.set_pipeline(pl);
            pass.set_bind_group(0, &g, &[]);
            pass.dispatch_workgroups(n.0, n.1, 1);
        }
        Ok(())
    }

    /// The allocation (allocate.wgsl), recorded into `enc`: weights, setup, 11 rounds of search
    /// and choose, mark (one timed pass), the prefix of the marks, apply (another).
    fn allocate(
        &self,
        enc: &mut wgpu::CommandEncoder,
        fb: &mut FrameBuffers,
        b: AllocBuffers,
        budget: FragmentBudget,
        kind: u32,
    ) -> Result<()> {
        let gpu = self.gpu;
        let a = &gpu.pipelines.allocate;
        let (f, ppm) = match budget {
            FragmentBudget::Slots(f) => (f, 0),
            FragmentBudget::Share(ppm) => (0, ppm),
        };
        let ap = AllocParams {
            f_lo: f as u32,
            f_hi: (f >> 32) as u32,
            ppm,
            kind,
        };
        let params = fb.init(
            "alloc.params",
            bytemuck::bytes_of(&ap),
            wgpu::BufferUsages::UNIFORM,
            true,
        );
        let state = fb.storage("alloc.state", 8 * ALLOC_STATE_WORDS as u64, true)?;
        // The marks need 4 bytes a pixel only during the allocation: a buffer the frame no longer
        // needs by then holds them where there is one.
        let flags = match b.flags {
            Some(f) => f.clone(),
            None => fb.storage("alloc.flags", 4 * self.pixels as u64, true)?,
        };
        let bind = |marks: &wgpu::Buffer| {
            gpu.bind_at(
                &a.layout,
                &[
                    (0, self.geometry[0]),
                    (1, &params),
                    (2, b.counts),
                    (3, b.weights),
                    (4, b.k),
                    (5, &state),
                    (6, marks),
                    (7, b.totals),
                ],
            )
        };
        let (gx, gy) = grid(self.pixels, ALLOC_GROUP);
        {
            let group = bind(&flags);
            let (tb, te) = self.timer.next("allocation");
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("allocation"),
                timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                    query_set: self.timer.set(),
                    beginning_of_pass_write_index: Some(tb),
                    end_of_pass_write_index: Some(te),
                }),
            });
            pass.set_bind_group(0, &group, &[]);
            pass.set_pipeline(&a.weights);
            pass.dispatch_workgroups(gx, gy, 1);
            pass.set_pipeline(&a.setup);
            pass.dispatch_workgroups(1, 1, 1);
            for _ in 0..SEARCH_ROUNDS {
                pass.set_pipeline(&a.search);
                pass.dispatch_workgroups(gx, gy, 1);
                pass.set_pipeline(&a.choose);
                pass.dispatch_workgroups(1, 1, 1);
            }
            pass.set_pipeline(&a.mark);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        self.prefix_sum(enc, fb, &flags, b.prefix)?;
        let group = bind(b.prefix);
        let (tb, te) = self.timer.next("allocation apply");
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("allocation apply"),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: self.timer.set(),
                beginning_of_pass_write_index: Some(tb),
                end_of_pass_write_index: Some(te),
            }),
        });
        pass.set_bind_group(0, &group, &[]);
        pass.set_pipeline(&a.apply);
        pass.dispatch_workgroups(gx, gy, 1);
        Ok(())
    }
}

fn read_u64s(gpu: &Gpu, b: &wgpu::Buffer, n: u64, invert: bool) -> Result<Vec<u64>> {
    Ok(read_back(gpu, b, 8 * n)?
        .chunks_exact(8)
        .map(|c| {
            let v = u64::from_le_bytes(c.try_into().expect("8"));
            if invert { !v } else { v }
        })
        .collect())
}

impl Gpu {
    fn bind(&self, layout: &wgpu::BindGroupLayout, buffers: &[&wgpu::Buffer]) -> wgpu::BindGroup {
        let indexed: Vec<(u32, &wgpu::Buffer)> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| (i as u32, *b))
            .collect();
        self.bind_at(layout, &indexed)
    }

    /// A bind group with buffers at the given binding indices.
    fn bind_at(
        &self,
        layout: &wgpu::BindGroupLayout,
        buffers: &[(u32, &wgpu::Buffer)],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: *i,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout,
            entries: &entries,
        })
    }

    /// Renders one frame: the A-buffer when `slots` is None, else as `slots` says.
    pub fn render(
        &self,
        scene: &Scene,
        cam: &Camera,
        width: u32,
        height: u32,
        background: [f32; 3],
        slots: Option<Slots>,
    ) -> Result<GpuFrame> {
        let scopes = self.begin_frame(width, height)?;
        let pixels = width * height;
        let px = pixels as u64;
        let mut fb = FrameBuffers::new(self);
        let (budget, vkb, k_uniform) = match slots {
            Some(Slots::Importance(_, _, f) | Slots::Dkb(_, f)) => (f, VkbParams::default(), 0),
            Some(Slots::Vkb(v, f)) => (f, v, 0),
            Some(Slots::Uniform(k)) => (0.into(), VkbParams::default(), k.max(1)),
            Some(Slots::Mlab(m)) => {
                if m == 0 || m > MLAB_MAX_ROWS {
                    return Err(Error::Invalid(format!(
                        "MLAB on the GPU takes 1 to {MLAB_MAX_ROWS} rows, not {m}"
                    )));
                }
                (0.into(), VkbParams::default(), m)
            }
            Some(Slots::PerPixel(_)) | None => (0.into(), VkbParams::default(), 0),
        };
        let mut params = frame_params(cam, width, height, background, k_uniform, budget, vkb);
        // The allocated k-buffers know n(p) by the capture: two-mode capture (capture.wgsl).
        params.append = (self.two_mode_capture
            && matches!(
                slots,
                Some(Slots::Importance(..) | Slots::Vkb(..) | Slots::Dkb(..))
            ))
        .into();
        let inputs = self.frame_inputs(&mut fb, scene, &params);
        let timer = Timer::new(self);
        let passes = Passes::new(self, &timer, &inputs);
        let p = &self.pipelines;
        let params_buf = &inputs.params;
        let mut enc = self.device.create_command_encoder(&Default::default());
        // The image: its own buffer, or (DKB) the features' colour sums once they are read.
        let image: wgpu::Buffer;
        let mut out = Readback::default();
        match slots {
            None | Some(Slots::Mlab(_)) => {
                // The per-pixel sorts (sort and blend, MLAB) report a near loop limit here.
                let status = fb.storage("status", 16, true)?;
                image = fb.storage("oit.image", 16 * px, true)?;
                let counts = fb.storage("abuf.count", 4 * px, true)?;
                let offsets = fb.storage("abuf.offsets", 4 * (px + 1), true)?;
                let cursor = fb.storage("abuf.cursor", 4 * px, true)?;
                passes.draw(&mut enc, &p.count, &[&counts], "count");
                passes.prefix_sum(&mut enc, &mut fb, &counts, &offsets)?;
                fb.submit(&mut enc);
                // Exact memory: the pool holds what the count found.
                let total = u32s(&read_back(self, &offsets, 4 * (px + 1))?)[pixels as usize] as u64;
                let fragments = fb.storage("abuf.fragments", 16 * total, true)?;
                passes.draw(
                    &mut enc,
                    &p.store,
                    &[&offsets, &cursor, &fragments],
                    "store",
                );
                let (resolve, name) = match slots {
                    Some(_) => (&p.mlab_resolve, "mlab blend"),
                    None => (&p.abuffer_resolve, "sort and blend"),
                };
                passes.dispatch(
                    &mut enc,
                    resolve,
                    &[params_buf, &offsets, &fragments, &image, &status],
                    name,
                );
                fb.submit(&mut enc);
                if self.diagnostics {
                    let mut fl = FragmentLists {
                        width,
                        height,
                        offsets: u32s(&read_back(self, &offsets, 4 * (px + 1))?),
                        ..Default::default()
                    };
                    for f in u32s(&read_back(self, &fragments, 16 * total)?).chunks_exact(4) {
                        fl.depth.push(f32::from_bits(f[0]));
                        fl.rgba.push(crate::fragment::unpack_rgba8(f[1]));
                        fl.primitive.push(f[2]);
                    }
                    out.fragments = Some(fl);
                }
                out.status = Some(status);
            }
            Some(s) => {
                // Per-pixel buffers whose contents are read by the time of the capture, for the
                // tail (its sums, 16 bytes a pixel, and its count, 4) and the image (16) to live
                // in (DKB's features).
                let (mut reuse_tail, mut reuse_image) = (None, None);
                // k for every pixel: uniform, uploaded, or allocated here from importance.
                // n(p) when known (the allocated k-buffers): the capture's two modes read it.
                let (k_of, base, slot_count, counts) = match s {
                    Slots::Uniform(k) => {
                        // FKB reads none of these, but the shared capture layout binds them.
                        let unused_k = fb.storage("fkb.unused_k", 16, true)?;
                        let unused_offsets = fb.storage("fkb.unused_offsets", 16, true)?;
                        let unused_counts = fb.storage("fkb.unused_counts", 16, true)?;
                        (
                            unused_k,
                            unused_offsets,
                            k.max(1) as u64 * px,
                            unused_counts,
                        )
                    }
                    Slots::PerPixel(k) => {
                        if k.len() != pixels as usize {
                            return Err(Error::Invalid(format!(
                                "{} k values for {pixels} pixels",
                                k.len()
                            )));
                        }
                        let k_of = fb.init(
                            "oit.k",
                            bytemuck::cast_slice(k),
                            wgpu::BufferUsages::STORAGE,
                            true,
                        );
                        let base = fb.storage("oit.offsets", 4 * (px + 1), true)?;
                        passes.prefix_sum(&mut enc, &mut fb, &k_of, &base)?;
                        let unused_counts = fb.storage("oit.unused_counts", 16, true)?;
                        (k_of, base, k.iter().map(|&x| x as u64).sum(), unused_counts)
                    }
                    _ => {
                        let (counts, importance, totals, kind, marks) = match s {
                            Slots::Importance(imp, target, _) => {
                                if imp.len() != pixels as usize {
                                    return Err(Error::Invalid(format!(
                                        "{} importance values for {pixels} pixels",
                                        imp.len()
                                    )));
                                }
                                let counts = fb.storage("count", 4 * px, true)?;
                                let imp = fb.init(
                                    "oit.importance",
                                    bytemuck::cast_slice(imp),
                                    wgpu::BufferUsages::STORAGE,
                                    true,
                                );
                                let totals = fb.storage("totals", 16, true)?;
                                passes.draw(&mut enc, &p.count, &[&counts], "count");
                                passes.dispatch(
                                    &mut enc,
                                    &p.totals,
                                    &[params_buf, &counts, &totals],
                                    "totals",
                                );
                                (counts, imp, totals, weight_kind(target), None)
                            }
                            Slots::Vkb(..) => {
                                let counts = fb.storage("vkb.count", 4 * px, true)?;
                                let nearest = fb.storage("vkb.nearest", 8 * px, true)?;
                                let totals = fb.storage("vkb.totals", 16, true)?;
                                let imp = fb.storage("oit.importance", 4 * px, true)?;
                                passes.draw(&mut enc, &p.vkb_count, &[&counts, &nearest], "count");
                                passes.dispatch(
                                    &mut enc,
                                    &p.totals,
                                    &[params_buf, &counts, &totals],
                                    "totals",
                                );
                                passes.dispatch(
                                    &mut enc,
                                    &p.importance_vkb,
                                    &[params_buf, &counts, &nearest, &totals, &imp],
                                    "importance",
                                );
                                // The nearest keys are read: a copy for the frame's statistics
                                // (not counted), then the buffer holds the allocation's marks.
                                if self.diagnostics {
                                    let copy = fb.storage("vkb.nearest.readback", 8 * px, false)?;
                                    enc.copy_buffer_to_buffer(&nearest, 0, &copy, 0, 8 * px);
                                    out.vkb_nearest_buf = Some(copy);
                                }
                                let kind = weight_kind(Target::RelativeK);
                                (counts, imp, totals, kind, Some(nearest))
                            }
                            Slots::Dkb(mlp, _) => {
                                let weights = fb.init(
                                    "mlp.weights",
                                    bytemuck::cast_slice(&mlp_uniform(mlp)),
                                    wgpu::BufferUsages::UNIFORM,
                                    true,
                                );
                                let counts = fb.storage("features.count", 4 * px, true)?;
                                // The nearest key (8 bytes a pixel), then the tail's count; the
                                // two farthest keys (16), then the tail's sums; the colour sums
                                // (16), then the image. No buffer above 16 bytes a pixel, so a
                                // 4K frame fits 128 MiB bindings.
                                let nearest = fb.storage("features.nearest", 8 * px, true)?;
                                let farthest = fb.storage("features.farthest", 16 * px, true)?;
                                let sums = fb.storage("features.color_sums", 16 * px, true)?;
                                let totals = fb.storage("features.totals", 24, true)?;
                                let imp = fb.storage("oit.importance", 4 * px, true)?;
                                passes.draw(
                                    &mut enc,
                                    &p.features,
                                    &[&counts, &nearest, &farthest, &sums],
                                    "features",
                                );
                                passes.dispatch(
                                    &mut enc,
                                    &p.totals,
                                    &[params_buf, &counts, &totals],
                                    "totals",
                                );
                                passes.dispatch(
                                    &mut enc,
                                    &self.network_pass(Variant::for_network(
                                        "importance_dkb",
                                        mlp,
                                        self.skip_forced,
                                    )),
                                    &[
                                        params_buf, &weights, &counts, &nearest, &farthest, &sums,
                                        &totals, &imp,
                                    ],
                                    "importance",
                                );
                                // Copies for the frame's statistics (not counted), then the
                                // buffers serve the tail and the image.
                                if self.diagnostics {
                                    let mut copy = |b: &wgpu::Buffer, label: &str, bytes: u64| {
                                        let c = fb.storage(label, bytes * px, false)?;
                                        enc.copy_buffer_to_buffer(b, 0, &c, 0, bytes * px);
                                        Ok::<_, Error>(c)
                                    };
                                    out.stats_bufs = Some([
                                        copy(&nearest, "features.nearest.readback", 8)?,
                                        copy(&farthest, "features.farthest.readback", 16)?,
                                        copy(&sums, "features.color_sums.readback", 16)?,
                                    ]);
                                }
                                reuse_tail = Some((farthest, nearest));
                                reuse_image = Some(sums);
                                (counts, imp, totals, weight_kind(mlp.target), None)
                            }
                            _ => unreachable!("handled above"),
                        };
                        if self.diagnostics && matches!(s, Slots::Vkb(..) | Slots::Dkb(..)) {
                            // A readback copy (not counted, like the staging buffers): the
                            // allocation pass overwrites importance with its fixed point.
                            let copy = fb.storage("importance.readback", 4 * px, false)?;
                            enc.copy_buffer_to_buffer(&importance, 0, &copy, 0, 4 * px);
                            out.importance_buf = Some(copy);
                        }
                        let k_of = fb.storage("oit.k", 4 * px, true)?;
                        let base = fb.storage("oit.offsets", 4 * (px + 1), true)?;
                        passes.allocate(
                            &mut enc,
                            &mut fb,
                            AllocBuffers {
                                counts: &counts,
                                weights: &importance,
                                k: &k_of,
                                prefix: &base,
                                totals: &totals,
                                flags: marks.as_ref(),
                            },
                            budget,
                            kind,
                        )?;
                        passes.prefix_sum(&mut enc, &mut fb, &k_of, &base)?;
                        fb.submit(&mut enc);
                        let total =
                            u32s(&read_back(self, &base, 4 * (px + 1))?)[pixels as usize] as u64;
                        out.counts_buf = Some(counts.clone());
                        (k_of, base, total, counts)
                    }
                };
                let slots_buf = fb.storage("oit.slots", 8 * slot_count, true)?;
                // The tail: sum c8 a8 for r, g, b and sum a8 (16 bytes a pixel), and its count.
                let (tail, tail_count) = match reuse_tail {
                    Some((sums, count)) => {
                        // The tail starts from zero.
                        enc.clear_buffer(&sums, 0, None);
                        enc.clear_buffer(&count, 0, None);
                        (sums, count)
                    }
                    None => (
                        fb.storage("oit.tail", 16 * px, true)?,
                        fb.storage("oit.tail_count", 4 * px, true)?,
                    ),
                };
                image = match reuse_image {
                    Some(b) => b,
                    None => fb.storage("oit.image", 16 * px, true)?,
                };
                passes.draw(
                    &mut enc,
                    &p.capture,
                    &[&k_of, &base, &slots_buf, &tail, &tail_count, &counts],
                    "capture",
                );
                passes.dispatch(
                    &mut enc,
                    &p.resolve,
                    &[
                        params_buf,
                        &k_of,
                        &base,
                        &slots_buf,
                        &tail,
                        &tail_count,
                        &image,
                        &counts,
                    ],
                    "resolve",
                );
                fb.submit(&mut enc);
                if self.diagnostics {
                    let bases = match s {
                        Slots::Uniform(k) => (0..=pixels).map(|q| q * k.max(1)).collect(),
                        _ => u32s(&read_back(self, &base, 4 * (px + 1))?),
                    };
                    // Five words a pixel, as composite::capture gives them.
                    let sums = u32s(&read_back(self, &tail, 16 * px)?);
                    let counts = u32s(&read_back(self, &tail_count, 4 * px)?);
                    let tails = sums
                        .chunks_exact(4)
                        .zip(counts)
                        .flat_map(|(s, c)| [s[0], s[1], s[2], s[3], c])
                        .collect();
                    out.slots =
                        Some((read_u64s(self, &slots_buf, slot_count, true)?, bases, tails));
                }
            }
        }
        if let Some(status) = &out.status
            && u32s(&read_back(self, status, 4)?)[0] != 0
        {
            return Err(GpuError::LoopLimit {
                adapter: self.adapter.clone(),
            }
            .into());
        }
        let img = u32s(&read_back(self, &image, 16 * px)?);
        let pass_ms = timer.read(self)?;
        let (importance, stats, vkb_nearest) = if self.diagnostics {
            out.statistics(self, px)?
        } else {
            (None, None, None)
        };
        scopes.end()?;
        Ok(GpuFrame {
            image: Image {
                width,
                height,
                data: img
                    .chunks_exact(4)
                    .map(|c| {
                        [
                            f32::from_bits(c[0]),
                            f32::from_bits(c[1]),
                            f32::from_bits(c[2]),
                        ]
                    })
                    .collect(),
            },
            pass_ms,
            allocated_bytes: fb.allocated,
            fragments: out.fragments,
            slots: out.slots,
            importance,
            stats,
            vkb_nearest,
        })
    }
}

/// The per-frame uniform.
fn frame_params(
    cam: &Camera,
    width: u32,
    height: u32,
    background: [f32; 3],
    k_uniform: u32,
    budget: FragmentBudget,
    vkb: VkbParams,
) -> Params {
    let (budget_fragments, budget_ppm) = match budget {
        FragmentBudget::Slots(f) => (f, 0),
        FragmentBudget::Share(ppm) => (0, ppm),
    };
    Params {
        view_proj: cam.view_proj.to_cols_array_2d(),
        forward: cam.forward.extend(0.0).to_array(),
        background: [background[0], background[1], background[2], 1.0],
        width,
        height,
        k_uniform,
        pixels: width * height,
        budget_fragments: budget_fragments.min(u32::MAX as u64) as u32,
        vkb_alpha: vkb.alpha,
        vkb_exponent: vkb.periphery_exponent,
        vkb_noise: vkb.noise,
        vkb_seed: vkb.seed,
        budget_ppm,
        append: 0,
        _pad: [0; 29],
    }
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

/// A frame's shared bindings and render target ([`Gpu::frame_inputs`]).
struct FrameInputs {
    params: wgpu::Buffer,
    positions: wgpu::Buffer,
    colors: wgpu::Buffer,
    target: wgpu::TextureView,
    vertices: u32,
    pixels: u32,
}

/// What [`Gpu::allocate`] read back.
#[derive(Clone, Debug)]
pub struct GpuAllocation {
    /// n(p), the GPU's own count.
    pub counts: Vec<u32>,
    /// k(p).
    pub k: Vec<u32>,
    /// Exclusive prefix sums of k (`pixels + 1` entries): the slot bases.
    pub bases: Vec<u32>,
    pub pass_ms: Vec<(&'static str, f64)>,
}

impl Gpu {
    /// Checks the frame's size before anything is allocated (an error with the numbers), and
    /// starts catching the validation and out-of-memory errors its commands raise.
    fn begin_frame(&self, width: u32, height: u32) -> Result<Scopes> {
        crate::raster::check_resolution(width, height)?;
        let max = self.device.limits().max_texture_dimension_2d;
        if width > max || height > max {
            return Err(GpuError::FrameTooLarge { width, height, max }.into());
        }
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        Ok(Scopes { oom, validation })
    }

    /// What every geometry pass binds (group 0: params, positions, colours) and the R8 target
    /// rasterization needs (never written; counted in the frame's bytes).
    fn frame_inputs(&self, fb: &mut FrameBuffers, scene: &Scene, params: &Params) -> FrameInputs {
        let params_buf = fb.init(
            "params",
            bytemuck::bytes_of(params),
            wgpu::BufferUsages::UNIFORM,
            true,
        );
        let pos: Vec<[f32; 4]> = scene
            .positions
            .iter()
            .map(|p| p.extend(1.0).to_array())
            .collect();
        let positions = fb.init(
            "scene.positions",
            bytemuck::cast_slice(&pos),
            wgpu::BufferUsages::STORAGE,
            false,
        );
        let colors = fb.init(
            "scene.colors",
            bytemuck::cast_slice(&scene.colors),
            wgpu::BufferUsages::STORAGE,
            false,
        );
        let (width, height) = (params.width, params.height);
        fb.allocated += width as u64 * height as u64;
        let target = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("raster.target"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: TARGET_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        FrameInputs {
            params: params_buf,
            positions,
            colors,
            target: target.create_view(&Default::default()),
            vertices: scene.positions.len() as u32,
            pixels: params.pixels,
        }
    }

    /// The allocation alone, on the GPU: the count pass, totals, the allocation of k from
    /// `importance` (one value a pixel, meaning what `target` says) at `budget`, and the
    /// prefix sums of k; no capture. The twin is `alloc::allocate` on the returned counts.
    /// Five buffers of 4 bytes a pixel, so a 7680x4320 frame fits a device whose bindings
    /// hold 133 MB (lavapipe's 128 MiB do), where a whole k-buffer frame does not.
    pub fn allocate(
        &self,
        scene: &Scene,
        cam: &Camera,
        (width, height): (u32, u32),
        importance: &[f32],
        target: Target,
        budget: FragmentBudget,
    ) -> Result<GpuAllocation> {
        let scopes = self.begin_frame(width, height)?;
        let pixels = width * height;
        let px = pixels as u64;
        if importance.len() != pixels as usize {
            return Err(Error::Invalid(format!(
                "{} importance values for {pixels} pixels",
                importance.len()
            )));
        }
        let mut fb = FrameBuffers::new(self);
        let params = frame_params(cam, width, height, [1.0; 3], 0, budget, Default::default());
        let inputs = self.frame_inputs(&mut fb, scene, &params);
        let timer = Timer::new(self);
        let passes = Passes::new(self, &timer, &inputs);
        let p = &self.pipelines;
        let mut enc = self.device.create_command_encoder(&Default::default());
        let counts = fb.storage("count", 4 * px, true)?;
        let imp = fb.init(
            "oit.importance",
            bytemuck::cast_slice(importance),
            wgpu::BufferUsages::STORAGE,
            true,
        );
        let totals = fb.storage("totals", 16, true)?;
        let k = fb.storage("oit.k", 4 * px, true)?;
        let base = fb.storage("oit.offsets", 4 * (px + 1), true)?;
        passes.draw(&mut enc, &p.count, &[&counts], "count");
        passes.dispatch(
            &mut enc,
            &p.totals,
            &[&inputs.params, &counts, &totals],
            "totals",
        );
        passes.allocate(
            &mut enc,
            &mut fb,
            AllocBuffers {
                counts: &counts,
                weights: &imp,
                k: &k,
                prefix: &base,
                totals: &totals,
                flags: None,
            },
            budget,
            weight_kind(target),
        )?;
        passes.prefix_sum(&mut enc, &mut fb, &k, &base)?;
        fb.submit(&mut enc);
        let out = GpuAllocation {
            counts: u32s(&read_back(self, &counts, 4 * px)?),
            k: u32s(&read_back(self, &k, 4 * px)?),
            bases: u32s(&read_back(self, &base, 4 * (px + 1))?),
            pass_ms: timer.read(self)?,
        };
        scopes.end()?;
        Ok(out)
    }
}

/// The allocation's entry points (shaders/allocate.wgsl), sharing one explicit layout.
struct Allocate {
    layout: wgpu::BindGroupLayout,
    weights: wgpu::ComputePipeline,
    setup: wgpu::ComputePipeline,
    search: wgpu::ComputePipeline,
    choose: wgpu::ComputePipeline,
    mark: wgpu::ComputePipeline,
    apply: wgpu::ComputePipeline,
}

/// The buffers the allocation reads and writes.
struct AllocBuffers<'a> {
    counts: &'a wgpu::Buffer,
    /// Importance in; the fixed-point weights in place.
    weights: &'a wgpu::Buffer,
    k: &'a wgpu::Buffer,
    /// Scratch for the prefix of the marks (the slot offsets, computed after).
    prefix: &'a wgpu::Buffer,
    totals: &'a wgpu::Buffer,
    /// A dead buffer of at least 4 bytes a pixel to hold the marks (else one is allocated).
    flags: Option<&'a wgpu::Buffer>,
}

impl Allocate {
    fn new(device: &wgpu::Device) -> Allocate {
        let entry = |binding: u32, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("allocate"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Uniform),
                entry(1, wgpu::BufferBindingType::Uniform),
                entry(2, wgpu::BufferBindingType::Storage { read_only: true }),
                entry(3, rw),
                entry(4, rw),
                entry(5, rw),
                entry(6, rw),
                entry(7, wgpu::BufferBindingType::Storage { read_only: true }),
            ],
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("allocate"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let m = module(device, "allocate");
        let make = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pl),
                module: &m,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        Allocate {
            weights: make("weights"),
            setup: make("setup"),
            search: make("search"),
            choose: make("choose"),
            mark: make("mark"),
            apply: make("apply"),
            layout,
        }
    }
}

/// What a frame leaves to read back after its passes.
#[derive(Default)]
struct Readback {
    fragments: Option<FragmentLists>,
    /// The A-buffer resolve's loop-limit status word.
    status: Option<wgpu::Buffer>,
    slots: Option<(Vec<u64>, Vec<u32>, Vec<u32>)>,
    counts_buf: Option<wgpu::Buffer>,
    importance_buf: Option<wgpu::Buffer>,
    /// DKB: the nearest keys, the two farthest keys and the colour sums.
    stats_bufs: Option<[wgpu::Buffer; 3]>,
    vkb_nearest_buf: Option<wgpu::Buffer>,
}

type Statistics = (
    Option<Vec<f32>>,
    Option<Vec<PixelStats>>,
    Option<(Vec<u32>, Vec<f32>)>,
);

impl Readback {
    /// Importance, DKB statistics and VKB nearest facing, where the frame computed them.
    fn statistics(&self, gpu: &Gpu, px: u64) -> Result<Statistics> {
        let importance = match &self.importance_buf {
            Some(b) => Some(
                u32s(&read_back(gpu, b, 4 * px)?)
                    .into_iter()
                    .map(f32::from_bits)
                    .collect(),
            ),
            None => None,
        };
        let Some(counts) = &self.counts_buf else {
            return Ok((importance, None, None));
        };
        let counts = u32s(&read_back(gpu, counts, 4 * px)?);
        let stats = match &self.stats_bufs {
            Some([nearest, farthest, sums]) => {
                let nearest = read_u64s(gpu, nearest, px, false)?;
                let farthest = read_u64s(gpu, farthest, 2 * px, false)?;
                let sums = u32s(&read_back(gpu, sums, 16 * px)?);
                Some(
                    (0..px as usize)
                        .map(|q| PixelStats {
                            count: counts[q],
                            nearest_key: if counts[q] > 0 { !nearest[q] } else { 0 },
                            color_sum: [sums[4 * q], sums[4 * q + 1], sums[4 * q + 2]],
                            color_sq_sum: sums[4 * q + 3],
                            farthest: [farthest[2 * q], farthest[2 * q + 1]],
                        })
                        .collect(),
                )
            }
            None => None,
        };
        let vkb_nearest = match &self.vkb_nearest_buf {
            Some(b) => {
                let facing = read_u64s(gpu, b, px, true)?
                    .iter()
                    .zip(&counts)
                    .map(|(&v, &c)| if c > 0 { f32::from_bits(v as u32) } else { 1.0 })
                    .collect();
                Some((counts.clone(), facing))
            }
            None => None,
        };
        Ok((importance, stats, vkb_nearest))
    }
}
