//! dhoit's budgeted linked list in an application's own renderer: the application owns the
//! device, its vertex layouts, pipelines, opaque pass and target; dhoit owns the list's buffers,
//! a WGSL function its fragment shader calls ([`ListOit::wgsl`]: `oit_store`) through one bind
//! group at the index the application chooses, and the resolve onto the application's image
//! ([`ListOit::resolve`]). The same store and resolve as dhoit's own frames
//! (`list_store.wgsl`, `list_resolve.wgsl`), so the image is the one dhoit renders for the same
//! fragments.
//!
//! ```
//! use dhoit_runtime::gpu::{self, ListOit};
//!
//! // The application's device: dhoit's features and limits on top of its own.
//! let instance = wgpu::Instance::default();
//! let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
//! let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
//!     required_features: gpu::required_features(),
//!     required_limits: gpu::required_limits(),
//!     ..Default::default()
//! }))
//! .unwrap();
//! let (w, h) = (64, 48);
//! // A pool of 4 fragments a pixel (Bevy's default), the nearest 8 of a pixel sorted.
//! let oit = ListOit::new(&device, &queue, (w, h), 4 * (w * h) as u64, 8)?;
//! // The application's transparent fragment shader: dhoit's module at group 0, then its own
//! // code ending in `oit_store(position, colour)`.
//! let src = ListOit::wgsl(0)
//!     + "@fragment fn fs(@builtin(position) p: vec4<f32>) { oit_store(p, vec4<f32>(1.0, 0.0, 0.0, 0.5)); }";
//! let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
//!     label: None,
//!     source: wgpu::ShaderSource::Wgsl(src.into()),
//! });
//! let _layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
//!     label: None,
//!     bind_group_layouts: &[Some(oit.bind_group_layout())],
//!     immediate_size: 0,
//! });
//! // Once: let group = oit.bind_group(&its_opaque_depth_view). Per frame: oit.clear(&mut
//! // encoder); its opaque pass; its transparent draws with `group` at group 0 (no depth
//! // attachment needed: oit_store tests the opaque depth); oit.resolve(&mut encoder,
//! // &its_opaque_image, &its_target, format, None).
//! # let _ = module;
//! # Ok::<(), dhoit_runtime::Error>(())
//! ```

use super::check_device;
use super::pipelines::{compute_pipeline, module_from, redeclare};
use crate::error::{Error, GpuError, Result};
use crate::wgsl::{PIXEL_GROUP, Params, grid, shaders};

/// The formats [`ListOit::resolve`] writes (storage textures every device supports).
pub const TARGET_FORMATS: [wgpu::TextureFormat; 3] = [
    wgpu::TextureFormat::Rgba8Unorm,
    wgpu::TextureFormat::Rgba16Float,
    wgpu::TextureFormat::Rgba32Float,
];

/// The budgeted linked list's buffers and passes on an application's device.
pub struct ListOit {
    device: wgpu::Device,
    width: u32,
    height: u32,
    nodes: u64,
    heads: wgpu::Buffer,
    counter: wgpu::Buffer,
    layout: wgpu::BindGroupLayout,
    /// The application's group's buffers: heads, next, keys, counter, its uniform.
    store_buffers: [wgpu::Buffer; 5],
    /// The resolve's own buffers: params, heads, next, keys and status, with the views bound
    /// at each call.
    resolve_buffers: [wgpu::Buffer; 5],
    /// The resolve for each of [`TARGET_FORMATS`], built on first use.
    resolves: std::sync::Mutex<Vec<(wgpu::TextureFormat, wgpu::ComputePipeline)>>,
}

impl ListOit {
    /// The list for frames of `width` x `height` with a pool of `nodes` fragments (12 bytes
    /// each: what overflows it is dropped) and the nearest `sorted` of a pixel (1 to
    /// [`crate::composite::LIST_MAX_SORTED`]) blended in order. Refuses a device that lacks
    /// what the passes need (named), and sizes it cannot bind.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        (width, height): (u32, u32),
        nodes: u64,
        sorted: u32,
    ) -> Result<ListOit> {
        check_device(device, "the application's device")?;
        let have = device.limits();
        if width == 0 || height == 0 {
            return Err(Error::Invalid(format!(
                "a {width}x{height} frame has no pixels"
            )));
        }
        crate::composite::check_list_sorted(sorted)?;
        if nodes == 0 || nodes > u32::MAX as u64 - 1 {
            return Err(Error::Invalid(format!(
                "a pool of {nodes} nodes: 1 to {} (node indices are 32-bit)",
                u32::MAX - 1
            )));
        }
        let px = width as u64 * height as u64;
        let limit = have
            .max_storage_buffer_binding_size
            .min(have.max_buffer_size);
        let storage = |label: &str, size: u64| -> Result<wgpu::Buffer> {
            let size = size.max(16).next_multiple_of(4);
            if size > limit {
                return Err(GpuError::BufferTooLarge {
                    label: label.to_string(),
                    need: size,
                    max: limit,
                }
                .into());
            }
            Ok(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }))
        };
        let heads = storage("list.heads", 4 * px)?;
        let next = storage("list.next", 4 * nodes)?;
        let keys = storage("list.keys", 8 * nodes)?;
        let counter = storage("list.counter", 16)?;
        let status = storage("status", 16)?;
        // The application's uniform (width, nodes) and the resolve's own (dhoit's Params).
        let store_params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("list.store_params"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(
            &store_params,
            0,
            bytemuck::cast_slice(&[width, nodes as u32, 0, 0]),
        );
        let mut params: Params = bytemuck::Zeroable::zeroed();
        params.width = width;
        params.height = height;
        params.pixels = width * height;
        params.budget_fragments = nodes as u32;
        params.list_sorted = sorted;
        let resolve_params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("list.params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(&resolve_params, 0, bytemuck::bytes_of(&params));
        let rw = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: false },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("dhoit linked list"),
            entries: &[
                rw(0),
                rw(1),
                rw(2),
                rw(3),
                wgpu::BindGroupLayoutEntry {
                    binding: 4,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 5,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        });
        Ok(ListOit {
            device: device.clone(),
            width,
            height,
            nodes,
            resolve_buffers: [
                resolve_params,
                heads.clone(),
                next.clone(),
                keys.clone(),
                status,
            ],
            store_buffers: [heads.clone(), next, keys, counter.clone(), store_params],
            heads,
            counter,
            layout,
            resolves: Default::default(),
        })
    }

    /// The WGSL the application's transparent fragment shader starts with: the list's bindings
    /// at `group` and `fn oit_store(frag_coord: vec4<f32>, color: vec4<f32>)`, which it calls
    /// with its fragment's `@builtin(position)` and straight colour. Needs the shader-int64
    /// feature ([`super::required_features`] has it).
    pub fn wgsl(group: u32) -> String {
        shaders::OIT_LIST_STORE.replace("OIT_GROUP", &group.to_string())
    }

    /// The layout of the list's bind group, for the application's pipeline layout.
    pub fn bind_group_layout(&self) -> &wgpu::BindGroupLayout {
        &self.layout
    }

    /// The bind group the application sets at the group it gave [`ListOit::wgsl`] for its
    /// transparent draws, with its opaque depth (a depth texture of the frame's size with
    /// `TEXTURE_BINDING` usage, written by its opaque pass; cleared to 1 where it has none)
    /// as the occluder. Made once and kept while the depth texture lives.
    pub fn bind_group(&self, opaque_depth: &wgpu::TextureView) -> wgpu::BindGroup {
        let mut entries: Vec<wgpu::BindGroupEntry> = self
            .store_buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: 5,
            resource: wgpu::BindingResource::TextureView(opaque_depth),
        });
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dhoit linked list"),
            layout: &self.layout,
            entries: &entries,
        })
    }

    /// The pool's size in nodes.
    pub fn nodes(&self) -> u64 {
        self.nodes
    }

    /// Bytes of the list's buffers (as `budget::LINKED_LIST` counts them, less the raster
    /// target, which is the application's).
    pub fn allocated_bytes(&self) -> u64 {
        4 * self.width as u64 * self.height as u64 + 12 * self.nodes + 16 + 16 + 16
    }

    /// Empties the list for a new frame: recorded before the frame's transparent draws.
    pub fn clear(&self, enc: &mut wgpu::CommandEncoder) {
        enc.clear_buffer(&self.heads, 0, None);
        enc.clear_buffer(&self.counter, 0, None);
    }

    /// Composites the frame's list over the application's image `under` (a float-sampled
    /// texture of the frame's size: its opaque pass) onto `target`, a storage texture of the
    /// frame's size in one of [`TARGET_FORMATS`] (it may be a copy the application blits or
    /// presents). `timestamps`, where given, time the resolve's compute pass in the
    /// application's query set.
    pub fn resolve(
        &self,
        enc: &mut wgpu::CommandEncoder,
        under: &wgpu::TextureView,
        target: &wgpu::TextureView,
        format: wgpu::TextureFormat,
        timestamps: Option<wgpu::ComputePassTimestampWrites>,
    ) -> Result<()> {
        let pipeline = self.resolve_for(format)?;
        let mut entries: Vec<wgpu::BindGroupEntry> = self
            .resolve_buffers
            .iter()
            .zip([0u32, 1, 2, 3, 5])
            .map(|(b, i)| wgpu::BindGroupEntry {
                binding: i,
                resource: b.as_entire_binding(),
            })
            .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: 6,
            resource: wgpu::BindingResource::TextureView(under),
        });
        entries.push(wgpu::BindGroupEntry {
            binding: 7,
            resource: wgpu::BindingResource::TextureView(target),
        });
        let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dhoit linked list resolve"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let (gx, gy) = grid(self.width * self.height, PIXEL_GROUP);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("dhoit linked list resolve"),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(gx, gy, 1);
        Ok(())
    }

    fn resolve_for(&self, format: wgpu::TextureFormat) -> Result<wgpu::ComputePipeline> {
        let name = match format {
            wgpu::TextureFormat::Rgba8Unorm => "rgba8unorm",
            wgpu::TextureFormat::Rgba16Float => "rgba16float",
            wgpu::TextureFormat::Rgba32Float => "rgba32float",
            other => {
                return Err(Error::Invalid(format!(
                    "the linked list resolves onto {TARGET_FORMATS:?}, not {other:?}"
                )));
            }
        };
        let mut built = self.resolves.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, p)) = built.iter().find(|(f, _)| *f == format) {
            return Ok(p.clone());
        }
        let mut src = shaders::source("list_resolve").expect("known pass");
        redeclare(
            &mut src,
            "list_resolve",
            "texture_storage_2d<rgba32float, write>",
            &format!("texture_storage_2d<{name}, write>"),
        );
        let m = module_from(&self.device, "list_resolve (onto)", src);
        let p = compute_pipeline(&self.device, "list_resolve (onto)", &m, "onto");
        built.push((format, p.clone()));
        Ok(p)
    }
}
