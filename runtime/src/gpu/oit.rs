//! dhoit's methods in an application's own renderer: the budgeted linked list ([`ListOit`]) and
//! the fixed k-buffer ([`KBufferOit`]), drawn once, and the exact A-buffer ([`ExactOit`], and
//! MLAB from its fragments, [`ExactOit::mlab`]), drawn twice. The application owns the device, its
//! vertex layouts, pipelines, opaque pass and target; dhoit owns the method's buffers, a WGSL
//! function its fragment shader calls (`wgsl`: `oit_store`) through one bind group at the index
//! the application chooses, and the resolve onto the application's image (`resolve`). The same
//! store and resolve as dhoit's own frames (the list's `list_store.wgsl` and
//! `list_resolve.wgsl`; the k-buffer's `kbuffer_insert.wgsl`, which dhoit's capture runs, and
//! `resolve.wgsl`; the A-buffer's `scan.wgsl` and `abuffer_resolve.wgsl`), so the image is the
//! one dhoit renders for the same fragments.

use super::check_device;
use super::pipelines::{compute_pipeline, module_from, redeclare};
use crate::error::{Error, GpuError, Result};
use crate::wgsl::{MLAB_MAX_ROWS, PIXEL_GROUP, Params, grid, shaders};

/// The formats the resolves write onto (storage textures every device supports).
pub const TARGET_FORMATS: [wgpu::TextureFormat; 3] = [
    wgpu::TextureFormat::Rgba8Unorm,
    wgpu::TextureFormat::Rgba16Float,
    wgpu::TextureFormat::Rgba32Float,
];

/// What dhoit keeps on an application's device for one method: the buffers it creates (each
/// counted), the group the application's transparent pipeline binds (its buffers, its
/// uniform, the application's opaque depth), and the resolve onto each target format.
pub(super) struct AppSide {
    pub(super) device: wgpu::Device,
    width: u32,
    height: u32,
    /// The method, as labels and errors name it.
    name: &'static str,
    /// The resolve's pass (`wgsl::shaders::PASSES`), whose entry `entry` reads the
    /// application's image at `under_at` and writes its target at `under_at + 1`.
    pass: &'static str,
    entry: &'static str,
    under_at: u32,
    limit: u64,
    pub(super) allocated: u64,
    layout: Option<wgpu::BindGroupLayout>,
    /// The application's group: storage buffers, then its uniform, then the depth texture.
    store: Vec<wgpu::Buffer>,
    /// The resolve's buffers and their bindings.
    resolve: Vec<(u32, wgpu::Buffer)>,
    /// Cleared before each frame's transparent draws.
    cleared: Vec<wgpu::Buffer>,
    resolves: std::sync::Mutex<Vec<(wgpu::TextureFormat, wgpu::ComputePipeline)>>,
}

impl AppSide {
    /// Refuses a device that lacks what the passes need (named) and a frame with no pixels.
    pub(super) fn new(
        device: &wgpu::Device,
        (width, height): (u32, u32),
        name: &'static str,
        (pass, entry, under_at): (&'static str, &'static str, u32),
    ) -> Result<AppSide> {
        check_device(device, "the application's device")?;
        if width == 0 || height == 0 {
            return Err(Error::Invalid(format!(
                "a {width}x{height} frame has no pixels"
            )));
        }
        let have = device.limits();
        Ok(AppSide {
            device: device.clone(),
            width,
            height,
            name,
            pass,
            entry,
            under_at,
            limit: have
                .max_storage_buffer_binding_size
                .min(have.max_buffer_size),
            allocated: 0,
            layout: None,
            store: Vec::new(),
            resolve: Vec::new(),
            cleared: Vec::new(),
            resolves: Default::default(),
        })
    }

    pub(super) fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    pub(super) fn name(&self) -> &'static str {
        self.name
    }

    pub(super) fn pixels(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    /// A storage buffer of `size` bytes (at least 16), refused where the device cannot bind it.
    fn storage(&mut self, label: &str, size: u64) -> Result<wgpu::Buffer> {
        let size = size.max(16).next_multiple_of(4);
        if size > self.limit {
            return Err(GpuError::BufferTooLarge {
                label: label.to_string(),
                need: size,
                max: self.limit,
            }
            .into());
        }
        self.allocated += size;
        Ok(self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            // Copied from where a method reads a total back (ExactOit::count).
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        }))
    }

    /// A uniform holding `bytes`.
    pub(super) fn uniform(
        &mut self,
        queue: &wgpu::Queue,
        label: &str,
        bytes: &[u8],
    ) -> wgpu::Buffer {
        let b = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes.len() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(&b, 0, bytes);
        self.allocated += bytes.len() as u64;
        b
    }

    /// dhoit's `Params` for the resolve, with the method's own fields set by `set`.
    pub(super) fn resolve_params(
        &mut self,
        queue: &wgpu::Queue,
        set: impl FnOnce(&mut Params),
    ) -> wgpu::Buffer {
        let mut params: Params = bytemuck::Zeroable::zeroed();
        params.width = self.width;
        params.height = self.height;
        params.pixels = self.width * self.height;
        set(&mut params);
        self.uniform(queue, "oit.params", bytemuck::bytes_of(&params))
    }

    /// The application's group: `storage` (read-write storage at bindings 0..), `uniform` at
    /// the next binding, the opaque depth after it.
    fn store_group(&mut self, storage: &[&wgpu::Buffer], uniform: wgpu::Buffer) {
        let n = storage.len() as u32;
        let mut buffers: Vec<_> = (0..n)
            .map(|i| (i, wgpu::BufferBindingType::Storage { read_only: false }))
            .collect();
        buffers.push((n, wgpu::BufferBindingType::Uniform));
        let label = format!("dhoit {}", self.name);
        self.layout = Some(fragment_group_layout(&self.device, &label, &buffers, n + 1));
        self.store = storage.iter().map(|&b| b.clone()).collect();
        self.store.push(uniform);
    }

    fn layout(&self) -> &wgpu::BindGroupLayout {
        self.layout.as_ref().expect("built with its group")
    }

    fn bind_group(&self, opaque_depth: &wgpu::TextureView) -> wgpu::BindGroup {
        let mut entries: Vec<wgpu::BindGroupEntry> = self
            .store
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: self.store.len() as u32,
            resource: wgpu::BindingResource::TextureView(opaque_depth),
        });
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("dhoit {}", self.name)),
            layout: self.layout(),
            entries: &entries,
        })
    }

    fn clear(&self, enc: &mut wgpu::CommandEncoder) {
        for b in &self.cleared {
            enc.clear_buffer(b, 0, None);
        }
    }

    fn resolve(
        &self,
        enc: &mut wgpu::CommandEncoder,
        under: &wgpu::TextureView,
        target: &wgpu::TextureView,
        format: wgpu::TextureFormat,
        timestamps: Option<wgpu::ComputePassTimestampWrites>,
    ) -> Result<()> {
        let buffers: Vec<(u32, &wgpu::Buffer)> =
            self.resolve.iter().map(|(i, b)| (*i, b)).collect();
        self.resolve_with(enc, &buffers, &[], (under, target, format), timestamps)
    }

    /// The resolve with these buffers and textures at these bindings.
    pub(super) fn resolve_with(
        &self,
        enc: &mut wgpu::CommandEncoder,
        buffers: &[(u32, &wgpu::Buffer)],
        textures: &[(u32, &wgpu::TextureView)],
        (under, target, format): (&wgpu::TextureView, &wgpu::TextureView, wgpu::TextureFormat),
        timestamps: Option<wgpu::ComputePassTimestampWrites>,
    ) -> Result<()> {
        let pipeline = self.resolve_for(format)?;
        let mut entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: *i,
                resource: b.as_entire_binding(),
            })
            .chain(textures.iter().map(|(i, v)| wgpu::BindGroupEntry {
                binding: *i,
                resource: wgpu::BindingResource::TextureView(v),
            }))
            .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: self.under_at,
            resource: wgpu::BindingResource::TextureView(under),
        });
        entries.push(wgpu::BindGroupEntry {
            binding: self.under_at + 1,
            resource: wgpu::BindingResource::TextureView(target),
        });
        let label = format!("dhoit {} resolve", self.name);
        let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&label),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let (gx, gy) = grid(self.width * self.height, PIXEL_GROUP);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(&label),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(gx, gy, 1);
        Ok(())
    }

    fn resolve_for(&self, format: wgpu::TextureFormat) -> Result<wgpu::ComputePipeline> {
        let mut built = self.resolves.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, p)) = built.iter().find(|(f, _)| *f == format) {
            return Ok(p.clone());
        }
        let p = onto_pipeline(
            &self.device,
            (self.pass, self.entry),
            format,
            false,
            self.name,
        )?;
        built.push((format, p.clone()));
        Ok(p)
    }
}

/// The layout of the group an application's transparent fragment stage binds: `buffers` at
/// their bindings, each of its type, and the opaque depth texture at `depth_at`.
pub(super) fn fragment_group_layout(
    device: &wgpu::Device,
    label: &str,
    buffers: &[(u32, wgpu::BufferBindingType)],
    depth_at: u32,
) -> wgpu::BindGroupLayout {
    let mut entries: Vec<_> = buffers
        .iter()
        .map(|&(binding, ty)| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect();
    entries.push(wgpu::BindGroupLayoutEntry {
        binding: depth_at,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Depth,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    });
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
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
            "the {what} resolves onto {TARGET_FORMATS:?}, not {other:?}"
        ))),
    }
}

/// Resolve pass `pass`'s entry `entry` (its `onto`) writing a target of `format` (one of
/// [`TARGET_FORMATS`]; another is refused, naming `what` resolves), built for frames whose
/// budget holds every fragment where `fits`.
pub(super) fn onto_pipeline(
    device: &wgpu::Device,
    (pass, entry): (&'static str, &'static str),
    format: wgpu::TextureFormat,
    fits: bool,
    what: &str,
) -> Result<wgpu::ComputePipeline> {
    let name = check_target_format(format, what)?;
    let mut src = shaders::source(pass).expect("known pass");
    redeclare(
        &mut src,
        pass,
        "texture_storage_2d<rgba32float, write>",
        &format!("texture_storage_2d<{name}, write>"),
    );
    if fits {
        redeclare(
            &mut src,
            pass,
            "const EVERY_FRAGMENT_FITS: bool = false;",
            "const EVERY_FRAGMENT_FITS: bool = true;",
        );
    }
    let label = format!(
        "{pass} ({entry}{})",
        if fits { ", every fragment fits" } else { "" }
    );
    let m = module_from(device, &label, src);
    Ok(compute_pipeline(device, &label, &m, entry))
}

/// The budgeted linked list's buffers and passes on an application's device.
///
/// ```
/// use dhoit_runtime::gpu::{self, ApplicationOit, ListOit};
///
/// // The application's device: dhoit's features and limits on top of its own.
/// let instance = wgpu::Instance::default();
/// let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
/// let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
///     required_features: gpu::required_features(),
///     required_limits: gpu::required_limits(),
///     ..Default::default()
/// }))
/// .unwrap();
/// let (w, h) = (64, 48);
/// // A pool of 4 fragments a pixel (Bevy's default), the nearest 8 of a pixel sorted.
/// let oit = ListOit::new(&device, &queue, (w, h), 4 * (w * h) as u64, 8)?;
/// // The application's transparent fragment shader: dhoit's module at group 0, then its own
/// // code ending in `oit_store(position, colour)`.
/// let src = ListOit::wgsl(0)
///     + "@fragment fn fs(@builtin(position) p: vec4<f32>) { oit_store(p, vec4<f32>(1.0, 0.0, 0.0, 0.5)); }";
/// let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
///     label: None,
///     source: wgpu::ShaderSource::Wgsl(src.into()),
/// });
/// let _layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
///     label: None,
///     bind_group_layouts: &[Some(oit.bind_group_layout())],
///     immediate_size: 0,
/// });
/// // Once: let group = oit.bind_group(&its_opaque_depth_view). Per frame: oit.clear(&mut
/// // encoder); its opaque pass; its transparent draws with `group` at group 0 (no depth
/// // attachment needed: oit_store tests the opaque depth); oit.resolve(&mut encoder,
/// // &its_opaque_image, &its_target, format, None).
/// # let _ = module;
/// # Ok::<(), dhoit_runtime::Error>(())
/// ```
pub struct ListOit {
    side: AppSide,
    nodes: u64,
}

impl ListOit {
    /// The list for frames of `width` x `height` with a pool of `nodes` fragments (12 bytes
    /// each: what overflows it is dropped) and the nearest `sorted` of a pixel (1 to
    /// [`crate::composite::LIST_MAX_SORTED`]) blended in order. Refuses a device that lacks
    /// what the passes need (named), and sizes it cannot bind.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        size: (u32, u32),
        nodes: u64,
        sorted: u32,
    ) -> Result<ListOit> {
        let mut side = AppSide::new(device, size, "linked list", ("list_resolve", "onto", 6))?;
        crate::composite::check_list_sorted(sorted)?;
        if nodes == 0 || nodes > u32::MAX as u64 - 1 {
            return Err(Error::Invalid(format!(
                "a pool of {nodes} nodes: 1 to {} (node indices are 32-bit)",
                u32::MAX - 1
            )));
        }
        let px = side.pixels();
        let heads = side.storage("list.heads", 4 * px)?;
        let next = side.storage("list.next", 4 * nodes)?;
        let keys = side.storage("list.keys", 8 * nodes)?;
        let counter = side.storage("list.counter", 16)?;
        let status = side.storage("status", 16)?;
        // The application's uniform (width, nodes) and the resolve's own (dhoit's Params).
        let store_params = side.uniform(
            queue,
            "list.store_params",
            bytemuck::cast_slice(&[size.0, nodes as u32, 0, 0]),
        );
        let params = side.resolve_params(queue, |p| {
            p.budget_fragments = nodes as u32;
            p.list_sorted = sorted;
        });
        side.store_group(&[&heads, &next, &keys, &counter], store_params);
        side.resolve = vec![
            (0, params),
            (1, heads.clone()),
            (2, next),
            (3, keys),
            (5, status),
        ];
        side.cleared = vec![heads, counter];
        Ok(ListOit { side, nodes })
    }

    /// The WGSL the application's transparent fragment shader starts with: the list's bindings
    /// at `group` and `fn oit_store(frag_coord: vec4<f32>, color: vec4<f32>)`, which it calls
    /// with its fragment's `@builtin(position)` and straight colour. Needs the shader-int64
    /// feature ([`super::required_features`] has it).
    pub fn wgsl(group: u32) -> String {
        shaders::application_module(&[shaders::OIT_FRAGMENT, shaders::OIT_LIST_STORE], group)
    }

    /// The pool's size in nodes.
    pub fn nodes(&self) -> u64 {
        self.nodes
    }
}

/// The fixed k-buffer (FKB: k slots a pixel, the rest approximated in its tail) on an
/// application's device: one geometry pass (the application's transparent draws) and the
/// resolve. Any draw order gives the same image.
///
/// ```
/// use dhoit_runtime::gpu::{self, ApplicationOit, KBufferOit};
///
/// let instance = wgpu::Instance::default();
/// let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
/// let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
///     required_features: gpu::required_features(),
///     required_limits: gpu::required_limits(),
///     ..Default::default()
/// }))
/// .unwrap();
/// // Four slots a pixel for a 64x48 frame: 8 bytes a slot, 20 a pixel for the tail.
/// let oit = KBufferOit::new(&device, &queue, (64, 48), 4)?;
/// assert!(oit.allocated_bytes() >= (8 * 4 + 20) * 64 * 48);
/// // Its transparent fragment shader: dhoit's module at group 1, then its own code.
/// let src = KBufferOit::wgsl(1)
///     + "@fragment fn fs(@builtin(position) p: vec4<f32>) { oit_store(p, vec4<f32>(0.2, 0.4, 0.6, 0.5)); }";
/// let _module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
///     label: None,
///     source: wgpu::ShaderSource::Wgsl(src.into()),
/// });
/// // Per frame, as with ListOit: oit.clear(&mut encoder); its opaque pass; its transparent
/// // draws with oit.bind_group(&its_opaque_depth_view) at group 1; oit.resolve(...).
/// # Ok::<(), dhoit_runtime::Error>(())
/// ```
pub struct KBufferOit {
    side: AppSide,
    k: u32,
}

impl KBufferOit {
    /// The k-buffer for frames of `width` x `height` with `k` slots a pixel (at least 1; slot
    /// indices are 32-bit). Refuses a device that lacks what the passes need (named), and
    /// sizes it cannot bind.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        size: (u32, u32),
        k: u32,
    ) -> Result<KBufferOit> {
        let mut side = AppSide::new(device, size, "k-buffer", ("resolve", "onto", 8))?;
        let px = side.pixels();
        if k == 0 || k as u64 * px > u32::MAX as u64 {
            return Err(Error::Invalid(format!(
                "k = {k} for {px} pixels: at least 1 slot a pixel, and at most {} slots in all \
                 (slot indices are 32-bit)",
                u32::MAX
            )));
        }
        let slots = side.storage("oit.slots", 8 * k as u64 * px)?;
        let tail = side.storage("oit.tail", 16 * px)?;
        let tail_count = side.storage("oit.tail_count", 4 * px)?;
        let status = side.storage("status", 16)?;
        // The resolve's slot bases and counts, which a uniform k never reads.
        let unused_offsets = side.storage("fkb.unused_offsets", 16)?;
        let unused_counts = side.storage("fkb.unused_counts", 16)?;
        let store_params = side.uniform(
            queue,
            "kbuffer.store_params",
            bytemuck::cast_slice(&[size.0, k, 0, 0]),
        );
        let params = side.resolve_params(queue, |p| p.k_uniform = k);
        side.store_group(&[&slots, &tail, &tail_count], store_params);
        side.resolve = vec![
            (0, params),
            (1, unused_offsets),
            (2, slots.clone()),
            (3, tail.clone()),
            (4, tail_count.clone()),
            (6, unused_counts),
            (7, status),
        ];
        side.cleared = vec![slots, tail, tail_count];
        Ok(KBufferOit { side, k })
    }

    /// The WGSL the application's transparent fragment shader starts with: the k-buffer's
    /// bindings at `group` and `fn oit_store(frag_coord: vec4<f32>, color: vec4<f32>)`, which
    /// it calls with its fragment's `@builtin(position)` and straight colour. Its names start
    /// with `oit_`. Needs the shader-int64 feature ([`super::required_features`] has it).
    pub fn wgsl(group: u32) -> String {
        shaders::application_module(
            &[
                shaders::OIT_FRAGMENT,
                shaders::KBUFFER_INSERT,
                shaders::OIT_KBUFFER_STORE,
            ],
            group,
        )
    }

    /// Slots a pixel.
    pub fn k(&self) -> u32 {
        self.k
    }
}

/// The exact A-buffer on an application's device: every fragment stored (exact memory: the
/// pool is sized to the frame's fragments), sorted and blended front to back. The application
/// draws its transparent geometry twice with the one pipeline it built on [`ExactOit::wgsl`]:
/// with [`ExactOit::count_group`], then, once [`ExactOit::count`] has summed the counts and
/// sized the pool (it submits and waits for the frame's fragment count, as dhoit's own
/// A-buffer does), with [`ExactOit::store_group`]; then [`ExactOit::resolve`].
///
/// ```
/// use dhoit_runtime::gpu::{self, ExactOit};
///
/// let instance = wgpu::Instance::default();
/// let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
/// let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
///     required_features: gpu::required_features(),
///     required_limits: gpu::required_limits(),
///     ..Default::default()
/// }))
/// .unwrap();
/// let oit = ExactOit::new(&device, &queue, (64, 48))?;
/// let _src = ExactOit::wgsl(1) + "@fragment fn fs(@builtin(position) p: vec4<f32>) { oit_store(p, vec4<f32>(1.0)); }";
/// // A frame with no transparent draw: the count finds no fragment, the pool stays empty.
/// let mut enc = device.create_command_encoder(&Default::default());
/// oit.clear(&mut enc);
/// assert_eq!(oit.count(enc, &queue)?, 0);
/// // Per frame: oit.clear; its opaque pass; its transparent draws with
/// // oit.count_group(&depth) at group 1; oit.count(encoder, &queue); the same draws with
/// // oit.store_group(&depth); oit.resolve(...).
/// # Ok::<(), dhoit_runtime::Error>(())
/// ```
pub struct ExactOit {
    side: AppSide,
    counts: wgpu::Buffer,
    offsets: wgpu::Buffer,
    blocks: wgpu::Buffer,
    params: wgpu::Buffer,
    status: wgpu::Buffer,
    /// The application's uniforms for the count and the store (their phase).
    phases: [wgpu::Buffer; 2],
    /// The pool, grown as frames need.
    pool: std::sync::Mutex<Pool>,
    /// MLAB's rows, where the A-buffer blends as MLAB does (it keeps submission indices).
    rows: Option<u32>,
    fragments: std::sync::atomic::AtomicU64,
    scan: [wgpu::ComputePipeline; 3],
}

/// The A-buffer's pool: each fragment's key (8 bytes) and, for MLAB, its submission index (4;
/// an empty binding otherwise), with its capacity in fragments.
struct Pool {
    keys: wgpu::Buffer,
    orders: wgpu::Buffer,
    fragments: u64,
}

impl ExactOit {
    /// The A-buffer for frames of `width` x `height`. Refuses a device that lacks what the
    /// passes need (named), and sizes it cannot bind.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, size: (u32, u32)) -> Result<ExactOit> {
        Self::build(device, queue, size, None)
    }

    /// MLAB (Salvi and Vaidyanathan) with `rows` blending rows (1 to [`MLAB_MAX_ROWS`]), as
    /// dhoit computes it: every fragment stored as the A-buffer stores it, with its
    /// submission index (`oit_store_ordered`'s `order`), then each pixel's fragments merged
    /// into the rows in that order (`mlab_resolve.wgsl`, as dhoit's own MLAB frames). Its memory
    /// is the A-buffer's and 4 bytes a fragment, not the paper's rows: WebGPU has no fragment
    /// shader interlock to merge in the fragment stage. The application draws twice, as for
    /// the A-buffer.
    pub fn mlab(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        size: (u32, u32),
        rows: u32,
    ) -> Result<ExactOit> {
        if rows == 0 || rows > MLAB_MAX_ROWS {
            return Err(Error::Invalid(format!(
                "MLAB on the GPU takes 1 to {MLAB_MAX_ROWS} rows, not {rows}"
            )));
        }
        Self::build(device, queue, size, Some(rows))
    }

    fn build(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        size: (u32, u32),
        rows: Option<u32>,
    ) -> Result<ExactOit> {
        let (name, pass) = match rows {
            Some(_) => ("MLAB", "mlab_resolve"),
            None => ("A-buffer", "abuffer_resolve"),
        };
        let mut side = AppSide::new(device, size, name, (pass, "onto", 8))?;
        let px = side.pixels();
        let counts = side.storage("abuf.count", crate::shared::count_bytes(px))?;
        let offsets = side.storage("abuf.offsets", 4 * (px + 1))?;
        let blocks = side.storage("scan.blocks", 4 * px.div_ceil(crate::budget::SCAN_BLOCK))?;
        let status = side.storage("status", 16)?;
        let unused_primitives = side.storage("abuf.no_primitives", 16)?;
        // The pool, sized by each count (8 bytes a fragment, MLAB 4 more); empty until the
        // first.
        let empty = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        let pool = Pool {
            keys: empty("abuf.keys"),
            orders: match rows {
                Some(_) => empty("abuf.primitives"),
                None => unused_primitives.clone(),
            },
            fragments: 0,
        };
        let ordered = rows.is_some() as u32;
        let phases = [0u32, 1].map(|phase| {
            side.uniform(
                queue,
                "abuffer.store_params",
                bytemuck::cast_slice(&[size.0, phase, ordered, 0]),
            )
        });
        let params = side.resolve_params(queue, |p| {
            if let Some(m) = rows {
                p.k_uniform = m;
                p.store_primitives = 1;
            }
        });
        side.store_group(
            &[&counts, &offsets, &pool.keys, &pool.orders],
            phases[0].clone(),
        );
        side.cleared = vec![counts.clone()];
        let src = shaders::source("scan").expect("known pass");
        let m = module_from(device, "scan (application)", src);
        let scan = ["scan_blocks", "scan_sums", "scan_add"]
            .map(|e| compute_pipeline(device, "scan (application)", &m, e));
        Ok(ExactOit {
            side,
            counts,
            offsets,
            blocks,
            params,
            status,
            phases,
            pool: std::sync::Mutex::new(pool),
            rows,
            fragments: Default::default(),
            scan,
        })
    }

    /// The WGSL the application's transparent fragment shader starts with: the A-buffer's
    /// bindings at `group` and `fn oit_store(frag_coord: vec4<f32>, color: vec4<f32>)`, which
    /// it calls with its fragment's `@builtin(position)` and straight colour, in both draws;
    /// for MLAB ([`ExactOit::mlab`]) `fn oit_store_ordered(frag_coord, color, order: u32)`,
    /// `order` the fragment's submission index (its triangle's index in the application's
    /// submission, say), which MLAB merges a pixel's fragments in.
    pub fn wgsl(group: u32) -> String {
        shaders::application_module(
            &[
                shaders::OIT_FRAGMENT,
                shaders::COUNTS,
                shaders::OIT_ABUFFER_STORE,
            ],
            group,
        )
    }

    /// The layout of the A-buffer's bind groups, for the application's pipeline layout.
    pub fn bind_group_layout(&self) -> &wgpu::BindGroupLayout {
        self.side.layout()
    }

    /// Empties the counts for a new frame: recorded before its first transparent draw.
    pub fn clear(&self, enc: &mut wgpu::CommandEncoder) {
        self.side.clear(enc)
    }

    fn group(&self, phase: usize, opaque_depth: &wgpu::TextureView) -> wgpu::BindGroup {
        let pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
        let entries = [
            self.counts.as_entire_binding(),
            self.offsets.as_entire_binding(),
            pool.keys.as_entire_binding(),
            pool.orders.as_entire_binding(),
            self.phases[phase].as_entire_binding(),
            wgpu::BindingResource::TextureView(opaque_depth),
        ];
        let entries: Vec<wgpu::BindGroupEntry> = entries
            .into_iter()
            .enumerate()
            .map(|(i, resource)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource,
            })
            .collect();
        self.side
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("dhoit A-buffer"),
                layout: self.side.layout(),
                entries: &entries,
            })
    }

    /// The group for the first draw, which counts each pixel's fragments, with the
    /// application's opaque depth as the occluder (as [`ListOit::bind_group`]).
    pub fn count_group(&self, opaque_depth: &wgpu::TextureView) -> wgpu::BindGroup {
        self.group(0, opaque_depth)
    }

    /// After the count's draws, recorded in `enc`: the prefix sum of the counts, submitted with
    /// them, and the frame's fragment count read back; the pool grows to hold them. Returns
    /// the frame's fragments. Make the store's group after it ([`ExactOit::store_group`]).
    pub fn count(&self, mut enc: wgpu::CommandEncoder, queue: &wgpu::Queue) -> Result<u64> {
        let device = &self.side.device;
        let px = self.side.pixels();
        let (gx, gy) = grid(px as u32, crate::budget::SCAN_BLOCK as u32);
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("dhoit A-buffer prefix sum"),
                timestamp_writes: None,
            });
            for (i, pl) in self.scan.iter().enumerate() {
                let mut entries = vec![(0, &self.params), (2, &self.offsets), (3, &self.blocks)];
                if i == 0 {
                    entries.push((1, &self.counts));
                }
                let entries: Vec<wgpu::BindGroupEntry> = entries
                    .into_iter()
                    .map(|(binding, b)| wgpu::BindGroupEntry {
                        binding,
                        resource: b.as_entire_binding(),
                    })
                    .collect();
                let g = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("dhoit A-buffer prefix sum"),
                    layout: &pl.get_bind_group_layout(0),
                    entries: &entries,
                });
                pass.set_pipeline(pl);
                pass.set_bind_group(0, &g, &[]);
                if i == 1 {
                    pass.dispatch_workgroups(1, 1, 1);
                } else {
                    pass.dispatch_workgroups(gx, gy, 1);
                }
            }
        }
        // The counts, summed, become the store's cursors.
        enc.clear_buffer(&self.counts, 0, None);
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dhoit A-buffer total"),
            size: 4,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        enc.copy_buffer_to_buffer(&self.offsets, 4 * px, &staging, 0, 4);
        queue.submit([enc.finish()]);
        staging.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Validation(e.to_string()))?;
        let total = {
            let data = staging
                .slice(..)
                .get_mapped_range()
                .map_err(|e| GpuError::Validation(e.to_string()))?;
            bytemuck::cast_slice::<u8, u32>(&data)[0] as u64
        };
        let mut pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
        if total > pool.fragments {
            let grown = |label: &str, bytes: u64| {
                let size = (bytes * total).max(16);
                if size > self.side.limit {
                    return Err(GpuError::BufferTooLarge {
                        label: label.to_string(),
                        need: size,
                        max: self.side.limit,
                    });
                }
                Ok(device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size,
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                }))
            };
            let keys = grown("abuf.keys", 8)?;
            if self.rows.is_some() {
                pool.orders = grown("abuf.primitives", 4)?;
            }
            pool.keys = keys;
            pool.fragments = total;
        }
        self.fragments
            .store(total, std::sync::atomic::Ordering::Relaxed);
        Ok(total)
    }

    /// The group for the second draw, which stores each fragment, made after
    /// [`ExactOit::count`] (the pool it binds may have grown).
    pub fn store_group(&self, opaque_depth: &wgpu::TextureView) -> wgpu::BindGroup {
        self.group(1, opaque_depth)
    }

    /// The last counted frame's fragments.
    pub fn fragments(&self) -> u64 {
        self.fragments.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Bytes of the buffers the A-buffer holds: `budget::ABUFFER`'s for the largest frame it
    /// counted (its pool 8 bytes a fragment; MLAB's 4 more) and the application's two
    /// 16-byte uniforms.
    pub fn allocated_bytes(&self) -> u64 {
        let pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
        let orders = match self.rows {
            Some(_) => pool.orders.size(),
            None => 0,
        };
        self.side.allocated + pool.keys.size() + orders
    }

    /// MLAB's rows, where this A-buffer blends as MLAB does ([`ExactOit::mlab`]).
    pub fn mlab_rows(&self) -> Option<u32> {
        self.rows
    }

    /// Sorts each pixel's fragments and blends them over the application's image `under` onto
    /// `target` (as [`ListOit::resolve`]).
    pub fn resolve(
        &self,
        enc: &mut wgpu::CommandEncoder,
        under: &wgpu::TextureView,
        target: &wgpu::TextureView,
        format: wgpu::TextureFormat,
        timestamps: Option<wgpu::ComputePassTimestampWrites>,
    ) -> Result<()> {
        let (keys, orders) = {
            let pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
            (pool.keys.clone(), pool.orders.clone())
        };
        let buffers = [
            (0, &self.params),
            (1, &self.offsets),
            (2, &keys),
            (4, &self.status),
            (5, &orders),
        ];
        self.side
            .resolve_with(enc, &buffers, &[], (under, target, format), timestamps)
    }
}

/// What an application does with one of dhoit's methods on its own device, whichever it is:
/// bind its group in the transparent pipeline, clear it each frame, resolve it onto its target.
pub trait ApplicationOit {
    /// The WGSL the application's transparent fragment shader starts with, the method's
    /// bindings at `group` (the type's own `wgsl`): it ends its fragment shader in a call to
    /// `oit_store(frag_coord: vec4<f32>, color: vec4<f32>)` with its fragment's
    /// `@builtin(position)` and straight (not premultiplied) colour.
    fn store_module(&self, group: u32) -> String;

    /// The layout of the method's bind group, for the application's pipeline layout.
    fn bind_group_layout(&self) -> &wgpu::BindGroupLayout;

    /// The bind group the application sets at the group it gave the module for its
    /// transparent draws, with its opaque depth (a depth texture of the frame's size with
    /// `TEXTURE_BINDING` usage, written by its opaque pass; cleared to 1 where it has none) as
    /// the occluder. Made once and kept while the depth texture lives.
    fn bind_group(&self, opaque_depth: &wgpu::TextureView) -> wgpu::BindGroup;

    /// Bytes of the buffers the method created: its `budget` layout's and the application's
    /// 16-byte uniform.
    fn allocated_bytes(&self) -> u64;

    /// Empties the method's buffers for a new frame: recorded before its transparent draws.
    fn clear(&self, enc: &mut wgpu::CommandEncoder);

    /// Composites the frame's fragments over the application's image `under` (a float-sampled
    /// texture of the frame's size: its opaque pass) onto `target`, a storage texture of the
    /// frame's size in one of [`TARGET_FORMATS`] (it may be a copy the application blits or
    /// presents). `timestamps`, where given, time the resolve's compute pass in the
    /// application's query set.
    fn resolve(
        &self,
        enc: &mut wgpu::CommandEncoder,
        under: &wgpu::TextureView,
        target: &wgpu::TextureView,
        format: wgpu::TextureFormat,
        timestamps: Option<wgpu::ComputePassTimestampWrites>,
    ) -> Result<()>;
}

macro_rules! application_oit {
    ($t:ty) => {
        impl ApplicationOit for $t {
            fn store_module(&self, group: u32) -> String {
                <$t>::wgsl(group)
            }
            fn bind_group_layout(&self) -> &wgpu::BindGroupLayout {
                self.side.layout()
            }
            fn bind_group(&self, opaque_depth: &wgpu::TextureView) -> wgpu::BindGroup {
                self.side.bind_group(opaque_depth)
            }
            fn allocated_bytes(&self) -> u64 {
                self.side.allocated
            }
            fn clear(&self, enc: &mut wgpu::CommandEncoder) {
                self.side.clear(enc)
            }
            fn resolve(
                &self,
                enc: &mut wgpu::CommandEncoder,
                under: &wgpu::TextureView,
                target: &wgpu::TextureView,
                format: wgpu::TextureFormat,
                timestamps: Option<wgpu::ComputePassTimestampWrites>,
            ) -> Result<()> {
                self.side.resolve(enc, under, target, format, timestamps)
            }
        }
    };
}

application_oit!(ListOit);
application_oit!(KBufferOit);
