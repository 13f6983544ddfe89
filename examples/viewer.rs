//! An application's own wgpu renderer with dhoit for its transparency (the budgeted linked list,
//! the fixed k-buffer with `--method fkb`, or the exact A-buffer with `--method abuffer`, which
//! draws the transparent geometry twice), headless: it loads a glTF file (or a built-in scene), draws its opaque and alpha-masked
//! materials with a depth buffer, hands its transparent fragments to dhoit from its own WGSL
//! (`oit_store`), resolves onto its own target over its opaque image, and writes one PNG per
//! orbit view with each pass's GPU time.
//!
//! ```sh
//! cargo run --release --example viewer -- ../shared/scenes/FlightHelmet/glTF/FlightHelmet.gltf \
//!     --res 640x480 --views 4 --fpp 4 --out out/viewer
//! ```
//!
//! The twenty lines that matter are marked `dhoit:`. Colours are the vertices' times the
//! materials' base colour times their base colour texture, sampled per fragment by the
//! application's own sampler (sRGB decoded by the texture format). What it does not do yet:
//! glass's view-dependent opacity (its face-on opacity instead), and VKB and DKB, whose passes
//! are dhoit's own (`gpu::Gpu`).

use anyhow::{Context, Result, bail};
use clap::Parser;
use dhoit_runtime::composite::Image;
use dhoit_runtime::gpu::{self, ApplicationOit, ExactOit, KBufferOit, ListOit};
use dhoit_runtime::scene::{self, Camera, Coverage, Opacity};
use std::path::PathBuf;

#[derive(Parser)]
struct Args {
    /// A .gltf/.glb file or a built-in scene name.
    scene: String,
    /// Resolution WIDTHxHEIGHT.
    #[arg(long, default_value = "640x480")]
    res: dhoit_runtime::raster::Resolution,
    /// Orbit views to render, one PNG each.
    #[arg(long, default_value_t = 4)]
    views: usize,
    /// dhoit's method: `linked-list` (a pool of --fpp fragments a frame pixel, what overflows
    /// it dropped) or `fkb` (--k slots a pixel, the rest approximated in a tail; any draw
    /// order gives the same image) or `abuffer` (every fragment, exact memory: the transparent
    /// geometry drawn twice, to count and to store).
    #[arg(long, default_value = "linked-list", value_parser = ["linked-list", "fkb", "abuffer"])]
    method: String,
    /// The list's pool, in fragments a frame pixel (Bevy's default is 4).
    #[arg(long, default_value_t = 4.0)]
    fpp: f64,
    /// Fragments a pixel sorted and blended in order (the linked list).
    #[arg(long, default_value_t = dhoit_runtime::composite::LIST_SORTED)]
    sorted: u32,
    /// Slots a pixel (FKB).
    #[arg(long, default_value_t = 4)]
    k: u32,
    /// Folder for the PNG frames.
    #[arg(long, default_value = "out/viewer")]
    out: PathBuf,
}

const SHADER: &str = r#"
struct Camera { view_proj: mat4x4<f32> };
@group(0) @binding(0) var<uniform> camera: Camera;

// The material's base colour texture (a white texel where it has none) and its sampler.
@group(1) @binding(0) var base_color: texture_2d<f32>;
@group(1) @binding(1) var base_sampler: sampler;

struct V {
    @builtin(position) position: vec4<f32>,
    @location(0) color: vec4<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) @interpolate(flat) cutoff: f32,
};

@vertex
fn vs(
    @location(0) p: vec3<f32>,
    @location(1) c: vec4<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) cutoff: f32,
) -> V {
    return V(camera.view_proj * vec4<f32>(p, 1.0), c, uv, cutoff);
}

fn shaded(in: V) -> vec4<f32> {
    return in.color * textureSample(base_color, base_sampler, in.uv);
}

@fragment
fn fs_opaque(in: V) -> @location(0) vec4<f32> {
    let c = shaded(in);
    if (c.a < in.cutoff) {
        discard;
    }
    return vec4<f32>(c.rgb, 1.0);
}

@fragment
fn fs_transparent(in: V) {
    oit_store(in.position, shaded(in)); // dhoit: the fragment goes to its method
}
"#;

fn main() -> Result<()> {
    let a = Args::parse();
    let (w, h) = (a.res.width, a.res.height);
    let s = scene::load(&a.scene, Opacity::Native)?;
    if !(a.fpp.is_finite() && a.fpp > 0.0) {
        bail!(
            "--fpp is a positive number of fragments a pixel, not {}",
            a.fpp
        );
    }
    dhoit_runtime::tensors::create_folder(&a.out)?;
    // The application's device, with what dhoit needs on top.
    let instance = wgpu::Instance::default();
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))
        .context("no GPU adapter")?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_features: gpu::required_features(), // dhoit: its features
        required_limits: gpu::required_limits(),     // dhoit: and limits
        ..Default::default()
    }))?;
    println!("{} on {}", s.name, adapter.get_info().name);
    // The application's vertices: position, colour (vertex x base colour; glass at its face-on
    // opacity), texture coordinates and the alpha cutoff (MASK; 0 for OPAQUE), by material,
    // opaque and masked materials first: one draw a material.
    let triangles = s.positions.len() / 3;
    let mut order: Vec<usize> = (0..triangles).collect();
    let material = |t: usize| s.triangle_material[t] as usize;
    order.sort_by_key(|&t| (s.materials[material(t)].transparent(), material(t)));
    let mut all = Vec::<f32>::new();
    // (material, first vertex, vertices, transparent)
    let mut draws: Vec<(usize, u32, u32, bool)> = Vec::new();
    for &t in &order {
        let m = &s.materials[material(t)];
        match draws.last_mut() {
            Some(d) if d.0 == material(t) => d.2 += 3,
            _ => draws.push((material(t), (all.len() / 10) as u32, 3, m.transparent())),
        }
        for v in 3 * t..3 * t + 3 {
            let p = s.positions[v];
            let mut c: [f32; 4] = std::array::from_fn(|i| s.colors[v][i] * m.base_color[i]);
            if m.transmission > 0.0 {
                c[3] *= scene::material::glass_opacity(m.transmission, m.f0(), 1.0);
            }
            let cutoff = match m.coverage {
                Coverage::Mask(cut) => cut,
                _ => 0.0,
            };
            let uv = s.uvs[v];
            all.extend_from_slice(&[p.x, p.y, p.z, c[0], c[1], c[2], c[3], uv[0], uv[1], cutoff]);
        }
    }
    let vertices = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("vertices"),
        size: (4 * all.len()).max(16) as u64,
        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    queue.write_buffer(&vertices, 0, bytemuck::cast_slice(&all));
    let camera = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("camera"),
        size: 64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    // dhoit: the list, its pool a budget of fragments a frame pixel, or the k-buffer.
    let nodes = (a.fpp * (w as f64 * h as f64)).ceil() as u64;
    let (oit, method) = match a.method.as_str() {
        "abuffer" => (
            Oit::Exact(Box::new(ExactOit::new(&device, &queue, (w, h))?)),
            "the exact A-buffer".to_string(),
        ),
        "fkb" => (
            Oit::Once(Box::new(KBufferOit::new(&device, &queue, (w, h), a.k)?)),
            format!("FKB, {} slots a pixel", a.k),
        ),
        _ => (
            Oit::Once(Box::new(ListOit::new(
                &device,
                &queue,
                (w, h),
                nodes,
                a.sorted,
            )?)),
            format!(
                "linked list, {} fragments a pixel of pool, the nearest {} sorted",
                a.fpp, a.sorted
            ),
        ),
    };
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("viewer"),
        // dhoit: its bindings and oit_store, at group 2.
        source: wgpu::ShaderSource::Wgsl((oit.store_module(2) + SHADER).into()),
    });
    let own_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("camera"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }],
    });
    let own_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("camera"),
        layout: &own_layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: camera.as_entire_binding(),
        }],
    });
    // Each material's texture and sampler, its own bind group.
    let material_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("material"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
        ],
    });
    let white = scene::Texture {
        width: 1,
        height: 1,
        texels: vec![u32::MAX],
        wrap: [scene::Wrap::Repeat; 2],
        nearest: true,
    };
    let address = |w: scene::Wrap| match w {
        scene::Wrap::Repeat => wgpu::AddressMode::Repeat,
        scene::Wrap::MirroredRepeat => wgpu::AddressMode::MirrorRepeat,
        scene::Wrap::ClampToEdge => wgpu::AddressMode::ClampToEdge,
    };
    let material_groups: Vec<wgpu::BindGroup> = s
        .materials
        .iter()
        .map(|m| {
            let t = m.texture.map_or(&white, |i| &s.textures[i as usize]);
            let size = wgpu::Extent3d {
                width: t.width,
                height: t.height,
                depth_or_array_layers: 1,
            };
            let tex = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("base colour"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8UnormSrgb,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            queue.write_texture(
                tex.as_image_copy(),
                bytemuck::cast_slice(&t.texels),
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(4 * t.width),
                    rows_per_image: Some(t.height),
                },
                size,
            );
            let filter = match t.nearest {
                true => wgpu::FilterMode::Nearest,
                false => wgpu::FilterMode::Linear,
            };
            let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
                address_mode_u: address(t.wrap[0]),
                address_mode_v: address(t.wrap[1]),
                mag_filter: filter,
                min_filter: wgpu::FilterMode::Linear,
                ..Default::default()
            });
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("material"),
                layout: &material_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(
                            &tex.create_view(&Default::default()),
                        ),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::Sampler(&sampler),
                    },
                ],
            })
        })
        .collect();
    let texture = |label, format, usage| {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    };
    let rgba = wgpu::TextureFormat::Rgba32Float;
    let use_both = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
    let image = texture("opaque image", rgba, use_both);
    let depth = texture("opaque depth", wgpu::TextureFormat::Depth32Float, use_both);
    let raster = texture(
        "raster",
        wgpu::TextureFormat::R8Unorm,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
    );
    let target = texture(
        "target",
        rgba,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
    );
    let view = |t: &wgpu::Texture| t.create_view(&Default::default());
    let (image_view, depth_view, raster_view, target_view) =
        (view(&image), view(&depth), view(&raster), view(&target));
    // dhoit: its group holds its buffers and this opaque depth, the occluder.
    let oit_group = match &oit {
        Oit::Once(o) => o.bind_group(&depth_view),
        Oit::Exact(o) => o.count_group(&depth_view), // the A-buffer's first draw counts
    };
    let layout = |groups: &[Option<&wgpu::BindGroupLayout>]| {
        device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: None,
            bind_group_layouts: groups,
            immediate_size: 0,
        })
    };
    let opaque_layout = layout(&[Some(&own_layout), Some(&material_layout)]);
    // dhoit: the transparent pipeline's layout has its group beside the application's.
    let transparent_layout = layout(&[
        Some(&own_layout),
        Some(&material_layout),
        Some(oit.bind_group_layout()),
    ]);
    let attributes =
        wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x4, 2 => Float32x2, 3 => Float32];
    let buffers = [Some(wgpu::VertexBufferLayout {
        array_stride: 40,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &attributes,
    })];
    let pipeline = |layout, entry, format, depth: bool, writes| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(entry),
            layout: Some(layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &buffers,
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: depth.then(|| wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: writes,
                })],
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let opaque_pipeline = pipeline(
        &opaque_layout,
        "fs_opaque",
        rgba,
        true,
        wgpu::ColorWrites::ALL,
    );
    let transparent_pipeline = pipeline(
        &transparent_layout,
        "fs_transparent",
        wgpu::TextureFormat::R8Unorm,
        false,
        wgpu::ColorWrites::empty(),
    );
    let queries = device.create_query_set(&wgpu::QuerySetDescriptor {
        label: Some("pass times"),
        ty: wgpu::QueryType::Timestamp,
        count: 8,
    });
    let resolved = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("pass times"),
        size: 64,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let row = (16 * w).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: row as u64 * h as u64 + 64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let pass_times = |i: u32| wgpu::RenderPassTimestampWrites {
        query_set: &queries,
        beginning_of_pass_write_index: Some(2 * i),
        end_of_pass_write_index: Some(2 * i + 1),
    };
    for v in 0..a.views {
        let cam = Camera::orbit(&s, v, a.views, w, h);
        queue.write_buffer(
            &camera,
            0,
            bytemuck::cast_slice(&cam.view_proj.to_cols_array()),
        );
        let mut enc = device.create_command_encoder(&Default::default());
        oit.clear(&mut enc); // dhoit: empty for the frame
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("opaque"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &image_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::WHITE),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: Some(pass_times(0)),
                ..Default::default()
            });
            pass.set_pipeline(&opaque_pipeline);
            pass.set_bind_group(0, &own_group, &[]);
            pass.set_vertex_buffer(0, vertices.slice(..));
            for &(m, first, n, _) in draws.iter().filter(|d| !d.3) {
                pass.set_bind_group(1, &material_groups[m], &[]);
                pass.draw(first..first + n, 0..1);
            }
        }
        // The transparent draws, with dhoit's group for them.
        let transparent = |enc: &mut wgpu::CommandEncoder, group: &wgpu::BindGroup, times| {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("transparent"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &raster_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Discard,
                    },
                })],
                timestamp_writes: Some(times),
                ..Default::default()
            });
            pass.set_pipeline(&transparent_pipeline);
            pass.set_bind_group(0, &own_group, &[]);
            pass.set_bind_group(2, group, &[]); // dhoit: its group for the draws
            pass.set_vertex_buffer(0, vertices.slice(..));
            for &(m, first, n, _) in draws.iter().filter(|d| d.3) {
                pass.set_bind_group(1, &material_groups[m], &[]);
                pass.draw(first..first + n, 0..1);
            }
        };
        transparent(&mut enc, &oit_group, pass_times(1));
        if let Oit::Exact(exact) = &oit {
            // dhoit: the counts summed and the pool sized (submitted and waited for), then the
            // same draws store the fragments.
            exact.count(enc, &queue)?;
            enc = device.create_command_encoder(&Default::default());
            transparent(&mut enc, &exact.store_group(&depth_view), pass_times(3));
        }
        // dhoit: its fragments over the opaque image, onto the target.
        let resolve_times = wgpu::ComputePassTimestampWrites {
            query_set: &queries,
            beginning_of_pass_write_index: Some(4),
            end_of_pass_write_index: Some(5),
        };
        oit.resolve(
            &mut enc,
            (&image_view, &target_view),
            rgba,
            Some(resolve_times),
        )?;
        enc.resolve_query_set(&queries, 0..8, &resolved, 0);
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &target,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: Some(h),
                },
            },
            target.size(),
        );
        enc.copy_buffer_to_buffer(&resolved, 0, &staging, row as u64 * h as u64, 64);
        queue.submit([enc.finish()]);
        staging.slice(..).map_async(wgpu::MapMode::Read, |r| {
            r.expect("the readback maps");
        });
        device.poll(wgpu::PollType::wait_indefinitely())?;
        let (img, ms) = {
            let data = staging.slice(..).get_mapped_range()?;
            let floats: &[f32] = bytemuck::cast_slice(&data[..(row * h) as usize]);
            let pixels = (0..h as usize)
                .flat_map(|y| {
                    (0..w as usize).map(move |x| {
                        let i = y * row as usize / 4 + 4 * x;
                        [floats[i], floats[i + 1], floats[i + 2]]
                    })
                })
                .collect();
            let stamps: &[u64] = bytemuck::cast_slice(&data[(row * h) as usize..]);
            let period = queue.get_timestamp_period() as f64 * 1e-6;
            let mut ms: Vec<f64> = (0..4)
                .map(|i| stamps[2 * i + 1].saturating_sub(stamps[2 * i]) as f64 * period)
                .collect();
            // The A-buffer's store draw is transparent time too.
            if matches!(oit, Oit::Exact(_)) {
                ms[1] += ms[3];
            }
            (
                Image {
                    width: w,
                    height: h,
                    data: pixels,
                },
                ms,
            )
        };
        staging.unmap();
        let path = a.out.join(format!("view{v}.png"));
        dhoit_runtime::image_io::write_png(&path, &img)?;
        println!(
            "view {v}: opaque {:.2} ms, transparent {:.2} ms, resolve {:.2} ms -> {}",
            ms[0],
            ms[1],
            ms[2],
            path.display()
        );
    }
    println!("{method}: {} bytes on the device", oit.allocated_bytes());
    Ok(())
}

/// dhoit's method: one drawn once, or the exact A-buffer, drawn twice.
enum Oit {
    Once(Box<dyn ApplicationOit>),
    Exact(Box<ExactOit>),
}

impl Oit {
    fn store_module(&self, group: u32) -> String {
        match self {
            Oit::Once(o) => o.store_module(group),
            Oit::Exact(_) => ExactOit::wgsl(group),
        }
    }
    fn bind_group_layout(&self) -> &wgpu::BindGroupLayout {
        match self {
            Oit::Once(o) => o.bind_group_layout(),
            Oit::Exact(o) => o.bind_group_layout(),
        }
    }
    fn clear(&self, enc: &mut wgpu::CommandEncoder) {
        match self {
            Oit::Once(o) => o.clear(enc),
            Oit::Exact(o) => o.clear(enc),
        }
    }
    fn resolve(
        &self,
        enc: &mut wgpu::CommandEncoder,
        views: (&wgpu::TextureView, &wgpu::TextureView),
        format: wgpu::TextureFormat,
        timestamps: Option<wgpu::ComputePassTimestampWrites>,
    ) -> dhoit_runtime::Result<()> {
        match self {
            Oit::Once(o) => o.resolve(enc, views.0, views.1, format, timestamps),
            Oit::Exact(o) => o.resolve(enc, views.0, views.1, format, timestamps),
        }
    }
    fn allocated_bytes(&self) -> u64 {
        match self {
            Oit::Once(o) => o.allocated_bytes(),
            Oit::Exact(o) => o.allocated_bytes(),
        }
    }
}
