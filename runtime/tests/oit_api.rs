//! dhoit's linked list in an application's own renderer, written as an outside user would: its
//! own device, vertex buffer and layout, WGSL vertex and fragment shaders (the fragment shader
//! ending in dhoit's `oit_store`), its own image under the transparency and its own target.
//! The image must be the one dhoit's own renderer gives for the same frame. Needs a GPU adapter
//! (lavapipe in CI); DHOIT_SKIP_GPU=1 skips explicitly.

mod common;

use common::{gpu, identity, quad};
use dhoit_runtime::budget::{self, Budget};
use dhoit_runtime::composite::{MboitParams, WboitParams, WboitWeight};
use dhoit_runtime::gpu::{
    self, AllocatedFrame, AllocatedOit, ApplicationOit, BlendedOit, BlendedPhase, ExactOit,
    KBufferOit, ListOit, Phase, Slots,
};
use dhoit_runtime::gpu::{AllocatedMethod, FrameOptions};
use dhoit_runtime::scene::Camera;
use dhoit_runtime::scene::Scene;

const BG: [f32; 3] = [0.9, 0.85, 0.8];

/// The application's device, with dhoit's features and limits.
fn app_device() -> (wgpu::Device, wgpu::Queue) {
    app_device_blending(false)
}

/// [`app_device`], and where `blending` (MBOIT's), 32-bit float blending and the colour
/// attachments' bytes a sample where the adapter has them.
fn app_device_blending(blending: bool) -> (wgpu::Device, wgpu::Queue) {
    let instance = wgpu::Instance::default();
    let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
    let mut features = gpu::required_features();
    let mut limits = gpu::required_limits();
    if blending {
        features |= adapter.features() & wgpu::Features::FLOAT32_BLENDABLE;
        limits.max_color_attachment_bytes_per_sample =
            adapter.limits().max_color_attachment_bytes_per_sample;
    }
    pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_features: features,
        required_limits: limits,
        ..Default::default()
    }))
    .unwrap()
}

/// The application's shaders: its camera, one flat colour a triangle lit by a headlight as
/// dhoit's scenes are (ambient 0.3, the rest by the triangle's facing |n . forward|, which its
/// vertex stage computes from the triangle's three positions), the opacity the scene's
/// uniform one where it has one.
const APP_SHADER: &str = r#"
struct AppCamera {
    view_proj: mat4x4<f32>,
    // xyz: the direction the camera looks; w: the scene's uniform opacity, or -1.
    forward: vec4<f32>,
};
@group(0) @binding(0) var<uniform> app_camera: AppCamera;

struct V {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) color: vec4<f32>,
    @location(1) @interpolate(flat) facing: f32,
    // The triangle's index in the scene: its submission index, for MLAB.
    @location(2) @interpolate(flat) order: u32,
};

@vertex
fn vs(
    @location(0) p: vec3<f32>,
    @location(1) c: vec4<f32>,
    @location(2) p0: vec3<f32>,
    @location(3) p1: vec3<f32>,
    @location(4) p2: vec3<f32>,
    @location(5) order: u32,
) -> V {
    let n = normalize(cross(p1 - p0, p2 - p0));
    let facing = abs(dot(n, app_camera.forward.xyz));
    let light = 0.3 + (1.0 - 0.3) * facing;
    let a = select(c.a, app_camera.forward.w, app_camera.forward.w >= 0.0);
    return V(app_camera.view_proj * vec4<f32>(p, 1.0), vec4<f32>(c.rgb * light, a), facing, order);
}

@fragment
fn fs_opaque(in: V) -> @location(0) vec4<f32> {
    return in.color;
}
"#;

/// The application's transparent fragment entry for the methods that store fragments.
const APP_STORE: &str = r#"
@fragment
fn fs(in: V) {
    // The facing is VKB's (its importance); the other methods' modules ignore it.
    oit_store_facing(in.position, in.color, in.facing);
}
"#;

/// Its transparent fragment entry for the A-buffer and MLAB: each fragment with its
/// submission index (MLAB blends in that order; the exact blend needs none).
const APP_ORDERED: &str = r#"
@fragment
fn fs(in: V) {
    oit_store_ordered(in.position, in.color, in.order);
}
"#;

/// Its transparent fragment entry for the blended methods: it returns into dhoit's targets.
const APP_BLEND: &str = r#"
@fragment
fn fs(in: V) -> OitTargets {
    return oit_targets(in.position, in.color);
}
"#;

/// Renders `s` (seen through the identity camera) with the application's pipeline and one of
/// dhoit's methods, made on the application's device by `make`; returns the target's RGB,
/// row-major.
/// One of dhoit's methods on the application's device: one drawn once, the exact A-buffer,
/// drawn twice (count, then store), or DKB or VKB, drawn into each geometry pass it records (one
/// pipeline a phase).
enum AppOit {
    Once(Box<dyn ApplicationOit>),
    Exact(Box<ExactOit>),
    Allocated(Box<AllocatedOit>),
    Blended(Box<BlendedOit>),
}

/// Which of a method's transparent pipelines: the one of a method drawn once or twice, one of
/// DKB's or VKB's phases, or one of the blended methods'.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Key {
    One,
    Deep(Phase),
    Blend(BlendedPhase),
}

impl AppOit {
    /// The phases the application builds a transparent pipeline for (DKB's and the blended
    /// methods'; one for the rest).
    fn phases(&self) -> Vec<Key> {
        match self {
            AppOit::Allocated(o) => o.phases().iter().copied().map(Key::Deep).collect(),
            AppOit::Blended(o) => o.phases().iter().copied().map(Key::Blend).collect(),
            _ => vec![Key::One],
        }
    }
    /// dhoit's module, the application's shaders and its transparent fragment entry.
    fn shader(&self, group: u32, key: Key) -> String {
        let (module, entry) = match (self, key) {
            (AppOit::Once(o), _) => (o.store_module(group), APP_STORE),
            (AppOit::Exact(_), _) => (ExactOit::wgsl(group), APP_ORDERED),
            (AppOit::Allocated(o), Key::Deep(phase)) => (o.store_module(phase, group), APP_STORE),
            (AppOit::Blended(o), Key::Blend(phase)) => (o.store_module(phase, group), APP_BLEND),
            _ => unreachable!("{key:?} is not a phase of this method"),
        };
        module + APP_SHADER + entry
    }
    fn bind_group_layout(&self, key: Key) -> &wgpu::BindGroupLayout {
        match (self, key) {
            (AppOit::Once(o), _) => o.bind_group_layout(),
            (AppOit::Exact(o), _) => o.bind_group_layout(),
            (AppOit::Allocated(o), Key::Deep(phase)) => o.bind_group_layout(phase),
            (AppOit::Blended(o), Key::Blend(phase)) => o.bind_group_layout(phase),
            _ => unreachable!("{key:?} is not a phase of this method"),
        }
    }
}

/// The application draws its transparent triangles in the scene's order, or reversed, seen
/// through the identity camera. Returns its target's colours, and what DKB's frame says of
/// itself.
fn app_frame(
    s: &Scene,
    size: (u32, u32),
    reversed: bool,
    make: impl FnOnce(&wgpu::Device, &wgpu::Queue) -> AppOit,
) -> (Vec<[f32; 3]>, Option<AllocatedFrame>) {
    app_frame_from(s, &identity(), size, reversed, make)
}

/// [`app_frame`] through `cam`. Each triangle's colour is its first vertex's (the scene's own
/// where its three share one, as dhoit takes it then).
fn app_frame_from(
    s: &Scene,
    cam: &Camera,
    (w, h): (u32, u32),
    reversed: bool,
    make: impl FnOnce(&wgpu::Device, &wgpu::Queue) -> AppOit,
) -> (Vec<[f32; 3]>, Option<AllocatedFrame>) {
    let (device, queue) = app_device_blending(true);
    let oit = make(&device, &queue);
    // Interleaved position (3 floats), colour (4), the triangle's three positions (9) and its
    // index in the scene (a u32), its own layout: the opaque triangles first, then the
    // transparent ones.
    let mut vertices: Vec<f32> = Vec::new();
    let opaque = |t: usize| !s.transparent(t);
    let triangles = s.positions.len() / 3;
    let mut transparent: Vec<usize> = (0..triangles).filter(|&t| !opaque(t)).collect();
    if reversed {
        transparent.reverse();
    }
    let order: Vec<usize> = (0..triangles)
        .filter(|&t| opaque(t))
        .chain(transparent)
        .collect();
    let opaque_vertices = 3 * (0..triangles).filter(|&t| opaque(t)).count() as u32;
    for &t in &order {
        let corners: Vec<f32> = (3 * t..3 * t + 3)
            .flat_map(|v| s.positions[v].to_array())
            .collect();
        for v in 3 * t..3 * t + 3 {
            let p = s.positions[v];
            vertices.extend_from_slice(&[p.x, p.y, p.z]);
            vertices.extend_from_slice(&s.colors[3 * t]);
            vertices.extend_from_slice(&corners);
            vertices.push(f32::from_bits(t as u32));
        }
    }
    let vbuf = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("app vertices"),
        size: (4 * vertices.len()) as u64,
        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    queue.write_buffer(&vbuf, 0, bytemuck::cast_slice(&vertices));
    let modules: Vec<wgpu::ShaderModule> = oit
        .phases()
        .into_iter()
        .map(|phase| {
            let src = oit.shader(1, phase);
            device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("app transparent"),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            })
        })
        .collect();
    // Group 0 is the application's (its camera); dhoit's at 1, as it chose.
    let camera = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("app camera"),
        size: 80,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut camera_words = cam.view_proj.to_cols_array().to_vec();
    camera_words.extend_from_slice(&cam.forward.to_array());
    camera_words.push(s.uniform_opacity.unwrap_or(-1.0));
    queue.write_buffer(&camera, 0, bytemuck::cast_slice(&camera_words));
    let own = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("app"),
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
        label: Some("app"),
        layout: &own,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: camera.as_entire_binding(),
        }],
    });
    let layout_for = |phase| {
        device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("app transparent"),
            bind_group_layouts: &[Some(&own), Some(oit.bind_group_layout(phase))],
            immediate_size: 0,
        })
    };
    let vertex_layout = [Some(wgpu::VertexBufferLayout {
        array_stride: 68,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![
            0 => Float32x3, 1 => Float32x4, 2 => Float32x3, 3 => Float32x3, 4 => Float32x3,
            5 => Uint32
        ],
    })];
    // Its opaque pass writes colour and depth; its transparent pass writes neither: the
    // fragments go to dhoit's list, which tests them against that depth (the occluder).
    // The opaque pass has its own layout, without dhoit's group (whose depth texture it writes).
    let opaque_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("app opaque"),
        bind_group_layouts: &[Some(&own)],
        immediate_size: 0,
    });
    let pipeline_for = |module: &wgpu::ShaderModule,
                        layout: &wgpu::PipelineLayout,
                        entry: &str,
                        targets: &[Option<wgpu::ColorTargetState>],
                        depth: bool| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(entry),
            layout: Some(layout),
            vertex: wgpu::VertexState {
                module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &vertex_layout,
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
                module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                targets,
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let target = |format, write_mask| {
        [Some(wgpu::ColorTargetState {
            format,
            blend: None,
            write_mask,
        })]
    };
    let opaque_pipeline = pipeline_for(
        &modules[0],
        &opaque_layout,
        "fs_opaque",
        &target(wgpu::TextureFormat::Rgba32Float, wgpu::ColorWrites::ALL),
        true,
    );
    // A target the transparent pass never writes (a render pass needs an attachment), or the
    // blended methods' own. One pipeline a phase of DKB's and MBOIT's.
    let pipelines: Vec<(Key, wgpu::RenderPipeline)> = oit
        .phases()
        .into_iter()
        .zip(&modules)
        .map(|(phase, module)| {
            let targets = match (&oit, phase) {
                (AppOit::Blended(o), Key::Blend(phase)) => o.color_targets(phase),
                _ => target(wgpu::TextureFormat::R8Unorm, wgpu::ColorWrites::empty()).to_vec(),
            };
            let p = pipeline_for(module, &layout_for(phase), "fs", &targets, false);
            (phase, p)
        })
        .collect();
    let pipeline_of = |phase: Key| {
        &pipelines
            .iter()
            .find(|(p, _)| *p == phase)
            .expect("a pipeline for each phase")
            .1
    };
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
    // Its opaque image (here the background alone), its target, and a render target for the
    // transparent pass, which writes no colour.
    let f32x4 = wgpu::TextureFormat::Rgba32Float;
    let under = texture(
        "app image",
        f32x4,
        wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::RENDER_ATTACHMENT,
    );
    let target = texture(
        "app target",
        f32x4,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
    );
    let raster = texture(
        "app raster",
        wgpu::TextureFormat::R8Unorm,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
    );
    // Its opaque depth, dhoit's occluder.
    let depth = texture(
        "app depth",
        wgpu::TextureFormat::Depth32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
    );
    let depth_view = depth.create_view(&Default::default());
    let view = |t: &wgpu::Texture| t.create_view(&Default::default());
    let mut enc = device.create_command_encoder(&Default::default());
    {
        let clear = wgpu::Color {
            r: BG[0] as f64,
            g: BG[1] as f64,
            b: BG[2] as f64,
            a: 1.0,
        };
        let under_view = view(&under);
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("app opaque"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &under_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
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
            ..Default::default()
        });
        pass.set_pipeline(&opaque_pipeline);
        pass.set_bind_group(0, &own_group, &[]);
        pass.set_vertex_buffer(0, vbuf.slice(..));
        pass.draw(0..opaque_vertices, 0..1);
    }
    let raster_view = view(&raster);
    // Its transparent draws, with dhoit's group at 1.
    let draw = |enc: &mut wgpu::CommandEncoder,
                group: &wgpu::BindGroup,
                phase: Key,
                timestamp_writes: Option<wgpu::RenderPassTimestampWrites>| {
        let attachments = match (&oit, phase) {
            (AppOit::Blended(o), Key::Blend(phase)) => o.color_attachments(phase),
            _ => vec![Some(wgpu::RenderPassColorAttachment {
                view: &raster_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Discard,
                },
            })],
        };
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("app transparent"),
            color_attachments: &attachments,
            timestamp_writes,
            ..Default::default()
        });
        pass.set_pipeline(pipeline_of(phase));
        pass.set_bind_group(0, &own_group, &[]);
        pass.set_bind_group(1, group, &[]);
        pass.set_vertex_buffer(0, vbuf.slice(..));
        pass.draw(opaque_vertices..order.len() as u32 * 3, 0..1);
    };
    let (under_view, target_view) = (view(&under), view(&target));
    let mut deep = None;
    match &oit {
        AppOit::Once(oit) => {
            oit.clear(&mut enc);
            draw(&mut enc, &oit.bind_group(&depth_view), Key::One, None);
            oit.resolve(&mut enc, &under_view, &target_view, f32x4, None)
                .unwrap();
        }
        AppOit::Exact(oit) => {
            oit.clear(&mut enc);
            draw(&mut enc, &oit.count_group(&depth_view), Key::One, None);
            let total = oit.count(enc, &queue).unwrap();
            assert_eq!(total, oit.fragments());
            // Exact memory: budget::ABUFFER's for the frame's fragments and the application's
            // two uniforms; MLAB's submission indices, 4 bytes a fragment, beside them.
            let px = (w * h) as u64;
            let abuffer = dhoit_runtime::budget::ABUFFER;
            let orders = oit.mlab_rows().map_or(0, |_| (4 * total).max(16));
            assert_eq!(
                oit.allocated_bytes(),
                abuffer.allocated_bytes(px, total.max(2)) + 32 + orders
            );
            enc = device.create_command_encoder(&Default::default());
            draw(&mut enc, &oit.store_group(&depth_view), Key::One, None);
            oit.resolve(&mut enc, &under_view, &target_view, f32x4, None)
                .unwrap();
        }
        AppOit::Allocated(oit) => {
            // Its opaque pass first, then DKB's frame, which calls it back for each pass.
            queue.submit([enc.finish()]);
            let frame = oit
                .render(&depth_view, &under_view, &target_view, &mut |enc, d| {
                    draw(enc, d.group, Key::Deep(d.phase), Some(d.timestamps))
                })
                .unwrap();
            deep = Some(frame);
            enc = device.create_command_encoder(&Default::default());
        }
        AppOit::Blended(oit) => {
            // Its passes in order (MBOIT's accumulation reads the moments' targets).
            for &phase in oit.phases() {
                let group = oit.bind_group(phase, &depth_view);
                draw(&mut enc, &group, Key::Blend(phase), None);
            }
            oit.resolve(&mut enc, &under_view, &target_view, f32x4, None)
                .unwrap();
        }
    }
    let row = (16 * w).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("app readback"),
        size: (row * h) as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
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
    queue.submit([enc.finish()]);
    staging
        .slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let data = staging.slice(..).get_mapped_range().unwrap();
    let floats: &[f32] = bytemuck::cast_slice(&data);
    let image = (0..h as usize)
        .flat_map(|y| {
            (0..w as usize).map(move |x| {
                let i = y * row as usize / 4 + 4 * x;
                [floats[i], floats[i + 1], floats[i + 2]]
            })
        })
        .collect();
    (image, deep)
}

/// Overlapping quads of several colours, opacities and depths, facing the camera (dhoit's
/// scenes are lit by a headlight, which the application's shader does not model: facing it, the
/// light is 1), up to 7 deep, and an opaque occluder between the layers.
fn layered_scene() -> Scene {
    let mut s = Scene::default();
    for i in 0..7 {
        let f = i as f32;
        let c = [
            (f * 0.37) % 1.0,
            (f * 0.61) % 1.0,
            1.0 - f / 7.0,
            0.25 + 0.1 * f,
        ];
        let x0 = -0.9 + 0.15 * f;
        let z = 0.2 + 0.1 * f;
        quad(&mut s, (x0, -0.8 + 0.1 * f, x0 + 1.0, 0.7), (z, z), c);
    }
    // The application's opaque occluder, between the layers: what is behind it is hidden.
    // Its colour is 8-bit exact (dhoit's opaque image is RGBA8).
    s.materials.push(dhoit_runtime::scene::Material {
        coverage: dhoit_runtime::scene::Coverage::Opaque,
        ..Default::default()
    });
    let occluder = [51.0 / 255.0, 102.0 / 255.0, 153.0 / 255.0, 1.0];
    let (a, b) = (
        glam::Vec3::new(-0.5, -0.5, 0.55),
        glam::Vec3::new(0.3, -0.5, 0.55),
    );
    let (c, d) = (
        glam::Vec3::new(0.3, 0.2, 0.55),
        glam::Vec3::new(-0.5, 0.2, 0.55),
    );
    s.push_textured([a, b, c], [occluder; 3], [[0.0; 2]; 3], 1);
    s.push_textured([a, c, d], [occluder; 3], [[0.0; 2]; 3], 1);
    s
}

#[test]
fn an_application_draws_through_dhoits_linked_list_and_gets_dhoits_image() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let s = layered_scene();
    let total = g
        .render(&s, &identity(), w, h, BG, None)
        .unwrap()
        .fragments
        .unwrap()
        .fragment_count() as u64;
    assert!(total > 2 * (w * h) as u64 / 2, "{total} fragments");
    for sorted in [8, 2] {
        // A pool that holds every fragment: which arrive first does not matter.
        let nodes = total + 5;
        let harness = g
            .render(
                &s,
                &identity(),
                w,
                h,
                BG,
                Some(Slots::LinkedList { nodes, sorted }),
            )
            .unwrap();
        let app = app_frame(&s, (w, h), false, |d, q| {
            AppOit::Once(Box::new(ListOit::new(d, q, (w, h), nodes, sorted).unwrap()))
        })
        .0;
        let worst = worst_difference(&app, &harness.image.data);
        assert!(
            worst <= 1e-5,
            "sorted {sorted}: the application's image differs by {worst}"
        );
        // Not the background: the application's fragments reached the list.
        let covered = app.iter().filter(|c| (c[0] - BG[0]).abs() > 1e-3).count();
        assert!(covered > (w * h / 2) as usize, "{covered} pixels covered");
    }
}

/// The largest difference of one channel between two images.
fn worst_difference(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0f32, f32::max))
        .fold(0.0f32, f32::max)
}

#[test]
fn an_application_draws_through_dhoits_k_buffer_and_gets_dhoits_fkb_image_in_any_order() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let s = layered_scene();
    let exact = g.render(&s, &identity(), w, h, BG, None).unwrap();
    for k in [1, 3, 8] {
        let harness = g
            .render(&s, &identity(), w, h, BG, Some(Slots::Uniform(k)))
            .unwrap();
        for reversed in [false, true] {
            let app = app_frame(&s, (w, h), reversed, |d, q| {
                AppOit::Once(Box::new(KBufferOit::new(d, q, (w, h), k).unwrap()))
            })
            .0;
            let worst = worst_difference(&app, &harness.image.data);
            assert!(
                worst <= 1e-5,
                "k = {k}, reversed {reversed}: the application's image differs from dhoit's \
                 FKB by {worst}"
            );
        }
        // Below the scene's depth the slots truncate: the image is not the exact one (so the
        // tail, not only the slots, was compared), and at 8 slots it is.
        let off = worst_difference(&harness.image.data, &exact.image.data);
        if k < 7 {
            assert!(
                off > 1e-3,
                "k = {k}: FKB is exact ({off}): nothing truncated"
            );
        } else {
            assert!(off <= 1e-5, "k = {k}: FKB is not exact ({off})");
        }
    }
}

#[test]
fn an_application_draws_twice_through_dhoits_a_buffer_and_gets_the_exact_image_in_any_order() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let s = layered_scene();
    let exact = g.render(&s, &identity(), w, h, BG, None).unwrap();
    let fragments = exact.fragments.as_ref().unwrap().fragment_count() as u64;
    for reversed in [false, true] {
        let app = app_frame(&s, (w, h), reversed, |d, q| {
            AppOit::Exact(Box::new(ExactOit::new(d, q, (w, h)).unwrap()))
        })
        .0;
        let worst = worst_difference(&app, &exact.image.data);
        assert!(
            worst <= 1e-5,
            "reversed {reversed}: the application's image differs from dhoit's A-buffer by {worst}"
        );
    }
    // Before any count, the pool is empty (a 16-byte binding).
    let (device, queue) = app_device();
    let oit = ExactOit::new(&device, &queue, (w, h)).unwrap();
    let px = (w * h) as u64;
    let abuffer = dhoit_runtime::budget::ABUFFER;
    assert_eq!(oit.allocated_bytes(), abuffer.allocated_bytes(px, 2) + 32);
    assert!(fragments > px / 2, "{fragments} fragments");
}

/// MLAB through the application's two draws (the A-buffer's), each fragment handed with its
/// triangle's index as its submission index: the image is dhoit's own MLAB frame's within 1e-5
/// at 1, 2 and 4 rows, in either draw order (MLAB blends in the order the indices give, not the
/// arrival's), and at 1 and 2 rows not the exact image (the layers submitted out of depth
/// order); its bytes are the A-buffer's and 4 a fragment.
#[test]
fn an_application_draws_through_dhoits_mlab_and_gets_its_image_in_any_order() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let px = (w * h) as u64;
    // The layers in a shuffled submission order: front to back (as layered_scene submits
    // them) MLAB merges exactly.
    let s = layered_scene().shuffled(7);
    let exact = g.render(&s, &identity(), w, h, BG, None).unwrap();
    let fragments = exact.fragments.as_ref().unwrap().fragment_count() as u64;
    for rows in [1, 2, 4] {
        let harness = g
            .render(&s, &identity(), w, h, BG, Some(Slots::Mlab(rows)))
            .unwrap();
        // Merged into one or two rows out of depth order, MLAB is not the exact image (at
        // four rows, these up to seven layers lose nothing).
        let off = worst_difference(&harness.image.data, &exact.image.data);
        assert!(rows > 2 || off > 1e-3, "{rows} rows: MLAB is exact ({off})");
        for reversed in [false, true] {
            let app = app_frame(&s, (w, h), reversed, |d, q| {
                let oit = ExactOit::mlab(d, q, (w, h), rows).unwrap();
                assert_eq!(oit.mlab_rows(), Some(rows));
                AppOit::Exact(Box::new(oit))
            })
            .0;
            let worst = worst_difference(&app, &harness.image.data);
            assert!(
                worst <= 1e-5,
                "{rows} rows, reversed {reversed}: the application's image differs from \
                 dhoit's MLAB by {worst}"
            );
        }
    }
    // The A-buffer's bytes and 4 a fragment, once counted; rows outside 1..=8 refused.
    let (device, queue) = app_device();
    let oit = ExactOit::mlab(&device, &queue, (w, h), 4).unwrap();
    let mut enc = device.create_command_encoder(&Default::default());
    oit.clear(&mut enc);
    assert_eq!(oit.count(enc, &queue).unwrap(), 0);
    let abuffer = dhoit_runtime::budget::ABUFFER;
    assert_eq!(
        oit.allocated_bytes(),
        abuffer.allocated_bytes(px, 2) + 32 + 16
    );
    for rows in [0, dhoit_runtime::wgsl::MLAB_MAX_ROWS + 1] {
        let e = ExactOit::mlab(&device, &queue, (w, h), rows)
            .err()
            .expect("refused")
            .to_string();
        assert!(e.contains("rows"), "{e}");
    }
    assert!(fragments > px / 2, "{fragments} fragments");
}

/// DKB and VKB through the application's draws: the count, the features (VKB's count with the
/// nearest fragment) and the capture are its own pipelines (one a phase), every compute pass
/// dhoit's; the image is dhoit's own frame's (one that truncates: not the exact image), in
/// either draw order, with the same buffers as dhoit's own frame, and
/// each of its passes timed by its timestamps. By default, where the A-buffer needs no more
/// bytes (this small frame), the frame is exact.
#[test]
fn an_application_draws_through_dhoits_dkb_and_vkb_and_gets_their_images_in_any_order() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let px = (w * h) as u64;
    let s = layered_scene();
    let weights = common::committed_weights();
    let exact = g.render(&s, &identity(), w, h, BG, None).unwrap();
    let f32x4 = wgpu::TextureFormat::Rgba32Float;
    let vkb = dhoit_runtime::importance::VkbParams::default();
    let methods = [
        (
            "dkb",
            AllocatedMethod::Dkb(Box::new(weights.clone())),
            "features",
        ),
        ("vkb", AllocatedMethod::Vkb(vkb), "count"),
    ];
    for (name, method, statistics) in &methods {
        let layout = match method {
            AllocatedMethod::Dkb(m) => budget::DKB.for_network(m),
            AllocatedMethod::Vkb(_) => budget::VKB,
        };
        // At 0.1 fpp DKB's pool holds a third of its records at a time: the application
        // draws its features phase once for each batch.
        for text in ["1fpp", "25%", "0.1fpp"] {
            let b = Budget::parse(text).unwrap();
            let f = b.fragment_budget(&layout, px).unwrap();
            let opts = FrameOptions {
                ..FrameOptions::default().always_approximate()
            };
            let slots = match method {
                AllocatedMethod::Dkb(m) => Slots::Dkb(m, f),
                AllocatedMethod::Vkb(v) => Slots::Vkb(*v, f),
            };
            let harness = g
                .render_with(&opts, &s, &identity(), (w, h), BG, Some(slots))
                .unwrap();
            assert!(!harness.exact);
            let batches = harness.record_batches.unwrap_or(1);
            assert_eq!(harness.record_batches.is_some(), *name == "dkb");
            assert!(
                batches > 1 || text != "0.1fpp" || *name != "dkb",
                "{name} at {text}: {batches} batches"
            );
            let off = worst_difference(&harness.image.data, &exact.image.data);
            assert!(
                off > 1e-3,
                "{name} at {text} is exact ({off}): nothing truncated"
            );
            for reversed in [false, true] {
                let (app, frame) = app_frame(&s, (w, h), reversed, |d, q| {
                    let oit = AllocatedOit::new(d, q, (w, h), method.clone(), b, f32x4).unwrap();
                    AppOit::Allocated(Box::new(oit.exact_when_cheaper(false)))
                });
                let frame = frame.unwrap();
                let worst = worst_difference(&app, &harness.image.data);
                assert!(
                    worst <= 1e-5,
                    "{name} at {text}, reversed {reversed}: the application's image differs \
                     from dhoit's by {worst}"
                );
                assert!(!frame.exact);
                assert_eq!(frame.allocated_bytes, harness.allocated_bytes);
                let drawn = frame
                    .pass_ms
                    .iter()
                    .filter(|(p, _)| p == statistics)
                    .count();
                assert_eq!(
                    drawn as u64,
                    if *name == "dkb" { batches } else { 1 },
                    "{name} at {text}: {:?}",
                    frame.pass_ms
                );
                for pass in ["count", statistics, "importance", "capture", "resolve"] {
                    let ms = frame.pass_ms.iter().find(|(p, _)| p == &pass);
                    assert!(
                        ms.is_some_and(|(_, ms)| *ms > 0.0),
                        "{name}, {pass}: {:?}",
                        frame.pass_ms
                    );
                }
            }
        }
        // DKB at 25% needs more than the A-buffer here (its weights); VKB, 6 bytes a pixel and
        // no weights, needs more at 90% (its tails), less at 25%.
        let dearer = if *name == "dkb" { "25%" } else { "90%" };
        let (app, frame) = app_frame(&s, (w, h), false, |d, q| {
            let b = Budget::parse(dearer).unwrap();
            let oit = AllocatedOit::new(d, q, (w, h), method.clone(), b, f32x4).unwrap();
            AppOit::Allocated(Box::new(oit))
        });
        let frame = frame.unwrap();
        assert!(frame.exact, "{name}: the A-buffer is cheaper here");
        let worst = worst_difference(&app, &exact.image.data);
        assert!(
            worst <= 1e-5,
            "{name}, exact where cheaper: {worst} from the A-buffer"
        );
        assert_eq!(frame.allocated_bytes, exact.allocated_bytes);
    }
}

/// A byte budget for DKB or VKB in an application is resolved against each frame's own count
/// (`FrameOptions::counted_bytes`): before the count it could only leave room for a tail (DKB:
/// and a record) for every pixel, far fewer slots than the frame needs, or none at all. With M
/// what the method reserves at a quarter of this frame's fragments (the CPU's accounting of the
/// CPU's rasterization), the frame runs at F(M) for its occupancy, at least that quarter,
/// allocates no more than M, and gives the image dhoit renders at that F; where M holds the
/// A-buffer, the frame is the A-buffer's.
#[test]
fn a_byte_budget_is_resolved_against_each_frames_own_count() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let px = (w * h) as u64;
    let s = layered_scene();
    let weights = common::committed_weights();
    let vkb = dhoit_runtime::importance::VkbParams::default();
    let fl = dhoit_runtime::raster::rasterize(&s, &identity(), w, h).unwrap();
    let occ = budget::Occupancy::of(&fl.counts());
    let quarter = occ.fragments / 4;
    let exact = g.render(&s, &identity(), w, h, BG, None).unwrap();
    let f32x4 = wgpu::TextureFormat::Rgba32Float;
    for name in ["dkb", "vkb"] {
        let (layout, method) = match name {
            "dkb" => (
                budget::DKB.for_network(&weights),
                AllocatedMethod::Dkb(Box::new(weights.clone())),
            ),
            _ => (budget::VKB, AllocatedMethod::Vkb(vkb)),
        };
        let slots_at = |f: u64| match name {
            "dkb" => Slots::Dkb(&weights, f.into()),
            _ => Slots::Vkb(vkb, f.into()),
        };
        let m = layout.reserved_bytes(px, quarter, &occ);
        // Uncounted, M leaves fewer slots than a quarter (or none).
        let before = Budget::Bytes(m).fragment_budget(&layout, px);
        assert!(
            before
                .as_ref()
                .map_or(true, |f| f.of(occ.fragments) < quarter),
            "{name}: {before:?}"
        );
        let f = layout.fragment_budget_counted(m, px, &occ).unwrap();
        assert!(
            f >= quarter && f < occ.fragments,
            "{name}: {f} of {}",
            occ.fragments
        );
        let approximate = FrameOptions::default().always_approximate();
        let harness = g
            .render_with(&approximate, &s, &identity(), (w, h), BG, Some(slots_at(f)))
            .unwrap();
        // The harness itself, given the bytes: the same frame.
        let counted = FrameOptions {
            counted_bytes: Some(m),
            ..approximate
        };
        let given = g
            .render_with(&counted, &s, &identity(), (w, h), BG, Some(slots_at(0)))
            .unwrap();
        assert_eq!(given.image.data, harness.image.data, "{name}");
        assert!(
            given.allocated_bytes <= m && harness.allocated_bytes <= m,
            "{name}: {} and {} > {m}",
            given.allocated_bytes,
            harness.allocated_bytes
        );
        for reversed in [false, true] {
            let (app, frame) = app_frame(&s, (w, h), reversed, |d, q| {
                let b = Budget::Bytes(m);
                let oit = AllocatedOit::new(d, q, (w, h), method.clone(), b, f32x4).unwrap();
                AppOit::Allocated(Box::new(oit.exact_when_cheaper(false)))
            });
            let frame = frame.unwrap();
            let worst = worst_difference(&app, &harness.image.data);
            assert!(worst <= 1e-5, "{name}, reversed {reversed}: {worst}");
            assert!(!frame.exact);
            assert_eq!(frame.allocated_bytes, given.allocated_bytes, "{name}");
        }
        // Bytes that hold the A-buffer: its frame, exact.
        let (app, frame) = app_frame(&s, (w, h), false, |d, q| {
            let b = Budget::Bytes(exact.allocated_bytes);
            let oit = AllocatedOit::new(d, q, (w, h), method.clone(), b, f32x4).unwrap();
            AppOit::Allocated(Box::new(oit))
        });
        let frame = frame.unwrap();
        assert!(frame.exact, "{name}");
        assert!(worst_difference(&app, &exact.image.data) <= 1e-5);
        // Bytes below what any frame needs (an empty one: the fixed bytes, DKB's marks) are
        // refused when the k-buffer is made.
        let (d, q) = app_device();
        let tiny = Budget::Bytes(layout.fixed_bytes(px) - 1);
        assert!(AllocatedOit::new(&d, &q, (w, h), method.clone(), tiny, f32x4).is_err());
    }
}

/// A glTF file through the application: a built-in scene written as binary glTF and read
/// back by dhoit's loader (a real glTF where ../shared/scenes has one is textured, which an
/// application samples with its own sampler: not dhoit's texels), each triangle one colour,
/// seen from an orbit camera at one uniform opacity. The application's image is dhoit's own,
/// within 1e-5, for every method: the A-buffer, FKB, DKB, VKB, MLAB and the list (a pool that
/// holds every fragment) in either draw order, WBOIT and MBOIT in the scene's (reversed, within
/// their targets' rounding).
#[test]
fn an_application_draws_a_gltf_file_and_gets_dhoits_images() {
    let Some(g) = gpu() else { return };
    let (w, h) = (96, 72);
    let path = std::env::temp_dir().join(format!("dhoit-oit-api-{}.glb", std::process::id()));
    let built_in = dhoit_runtime::scene::load("shells", Default::default()).unwrap();
    dhoit_runtime::scene::gltf::export(&built_in, &path).unwrap();
    let opacity = dhoit_runtime::scene::Opacity::Uniform(0.4);
    // Its triangles in a shuffled order: the shells' own (one shell after another) is one
    // that MLAB merges exactly.
    let mut s = dhoit_runtime::scene::load(path.to_str().unwrap(), opacity)
        .unwrap()
        .shuffled(5);
    std::fs::remove_file(&path).unwrap();
    for t in 0..s.triangle_count() {
        let c = s.colors[3 * t];
        s.colors[3 * t + 1] = c;
        s.colors[3 * t + 2] = c;
    }
    let cam = Camera::orbit(&s, 1, dhoit_runtime::scene::DEFAULT_VIEWS, w, h);
    let px = (w * h) as u64;
    let exact = g.render(&s, &cam, w, h, BG, None).unwrap();
    let fragments = exact.fragments.as_ref().unwrap().fragment_count() as u64;
    assert!(fragments > px / 2, "{fragments} fragments");
    let f32x4 = wgpu::TextureFormat::Rgba32Float;
    let weights = common::committed_weights();
    let b = Budget::parse("1fpp").unwrap();
    let opts = FrameOptions {
        ..FrameOptions::default().always_approximate()
    };
    let dkb_f = b
        .fragment_budget(&budget::DKB.for_network(&weights), px)
        .unwrap();
    let vkb = dhoit_runtime::importance::VkbParams::default();
    let vkb_f = b.fragment_budget(&budget::VKB, px).unwrap();
    let nodes = fragments + 5;
    let mboit = MboitParams::default();
    let cases: Vec<(&str, Option<Slots>)> = vec![
        ("abuffer", None),
        ("fkb", Some(Slots::Uniform(2))),
        ("dkb", Some(Slots::Dkb(&weights, dkb_f))),
        ("vkb", Some(Slots::Vkb(vkb, vkb_f))),
        ("mlab", Some(Slots::Mlab(2))),
        ("linked-list", Some(Slots::LinkedList { nodes, sorted: 8 })),
        ("wboit", Some(Slots::Wboit(WboitParams::default()))),
        ("mboit", Some(Slots::Mboit(mboit))),
    ];
    for (name, slots) in cases {
        let harness = g.render_with(&opts, &s, &cam, (w, h), BG, slots).unwrap();
        // Every method but the list (whose pool holds every fragment) approximates here.
        if slots.is_some() && name != "linked-list" {
            let off = worst_difference(&harness.image.data, &exact.image.data);
            assert!(off > 1e-3, "{name} is exact ({off}): nothing truncated");
        }
        for reversed in [false, true] {
            let (app, _) = app_frame_from(&s, &cam, (w, h), reversed, |d, q| match name {
                "abuffer" => AppOit::Exact(Box::new(ExactOit::new(d, q, (w, h)).unwrap())),
                "mlab" => AppOit::Exact(Box::new(ExactOit::mlab(d, q, (w, h), 2).unwrap())),
                "linked-list" => {
                    let list = ListOit::new(d, q, (w, h), nodes, 8).unwrap();
                    AppOit::Once(Box::new(list))
                }
                "wboit" => {
                    let oit = BlendedOit::wboit(d, q, (w, h), WboitParams::default()).unwrap();
                    AppOit::Blended(Box::new(oit))
                }
                "mboit" => {
                    AppOit::Blended(Box::new(BlendedOit::mboit(d, q, (w, h), mboit).unwrap()))
                }
                "fkb" => AppOit::Once(Box::new(KBufferOit::new(d, q, (w, h), 2).unwrap())),
                _ => {
                    let method = match name {
                        "dkb" => AllocatedMethod::Dkb(Box::new(weights.clone())),
                        _ => AllocatedMethod::Vkb(vkb),
                    };
                    let oit = AllocatedOit::new(d, q, (w, h), method, b, f32x4).unwrap();
                    AppOit::Allocated(Box::new(oit.exact_when_cheaper(false)))
                }
            });
            let worst = worst_difference(&app, &harness.image.data);
            // The blended methods add in submission order at their targets' precision.
            let bound = match (name, reversed) {
                ("wboit" | "mboit", true) => 5e-3,
                _ => 1e-5,
            };
            assert!(
                worst <= bound,
                "{name}, reversed {reversed}: the application's image differs from dhoit's by {worst}"
            );
        }
    }
}

/// WBOIT and MBOIT through the application's own pipelines: its fragment entry returns
/// dhoit's `oit_targets`, its pipeline writes dhoit's targets with dhoit's blend states, its
/// render passes open dhoit's attachments. The image is dhoit's own frame's for the same draws
/// within 1e-5 over the application's opaque occluder, for eqs. 10 and 7 of WBOIT (7 with
/// planes) and 4, 6 and 8 power moments where the device blends 32-bit floats; in the reversed
/// order within the targets' rounding (the devices add in submission order); the bytes are the
/// layout table's.
#[test]
fn an_application_draws_through_dhoits_wboit_and_mboit_and_gets_their_images() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let px = (w * h) as u64;
    let s = layered_scene();
    let exact = g.render(&s, &identity(), w, h, BG, None).unwrap();
    let planes = |weight| WboitParams {
        weight,
        near: 0.5,
        far: 4.0,
    };
    let mut cases: Vec<(String, Slots, budget::Layout)> = [WboitWeight::Eq10, WboitWeight::Eq7]
        .into_iter()
        .map(|weight| {
            let p = planes(weight);
            (format!("wboit {weight:?}"), Slots::Wboit(p), budget::WBOIT)
        })
        .collect();
    let (device, _) = app_device_blending(true);
    let blends = device
        .features()
        .contains(wgpu::Features::FLOAT32_BLENDABLE);
    let room = device.limits().max_color_attachment_bytes_per_sample;
    for moments in [4, 6, 8] {
        // b_0, the four moments and the extra ones, bytes a sample.
        let need = 4 + 16 + [0, 8, 16][(moments as usize - 4) / 2];
        if blends && need <= room {
            let p = MboitParams::with_moments(moments).unwrap();
            let name = format!("mboit {moments}");
            cases.push((name, Slots::Mboit(p), budget::mboit(moments)));
        } else {
            eprintln!("mboit {moments}: the device cannot blend them ({blends}, {room} bytes)");
            assert!(moments > 4 || !blends, "lavapipe blends four moments");
        }
    }
    assert!(cases.len() >= 3, "{} cases", cases.len());
    for (name, slots, layout) in cases {
        let harness = g.render(&s, &identity(), w, h, BG, Some(slots)).unwrap();
        let off = worst_difference(&harness.image.data, &exact.image.data);
        assert!(off > 1e-3, "{name} is the exact image ({off})");
        let make = |d: &wgpu::Device, q: &wgpu::Queue| {
            let oit = match slots {
                Slots::Wboit(p) => BlendedOit::wboit(d, q, (w, h), p),
                Slots::Mboit(p) => BlendedOit::mboit(d, q, (w, h), p),
                _ => unreachable!(),
            };
            let oit = oit.unwrap();
            assert_eq!(
                oit.allocated_bytes(),
                layout.allocated_bytes(px, 0),
                "{name}: the layout table's bytes"
            );
            AppOit::Blended(Box::new(oit))
        };
        let app = app_frame(&s, (w, h), false, make).0;
        let worst = worst_difference(&app, &harness.image.data);
        assert!(
            worst <= 1e-5,
            "{name}: the application's image differs from dhoit's by {worst}"
        );
        // Reversed: the same sums, added in another order at binary16 (WBOIT's 8-bit
        // revealage is a product of the same factors): on lavapipe 6e-4 to 2.3e-3.
        let reversed = app_frame(&s, (w, h), true, make).0;
        let worst = worst_difference(&reversed, &harness.image.data);
        assert!(
            worst <= 5e-3,
            "{name}, reversed: the application's image differs from dhoit's by {worst}"
        );
        let covered = app.iter().filter(|c| (c[0] - BG[0]).abs() > 1e-3).count();
        assert!(
            covered > (w * h / 2) as usize,
            "{name}: {covered} pixels covered"
        );
    }
}

/// The blended methods refuse, before building anything, a weight of the view-space distance
/// without planes, a count of moments MBOIT lacks, MBOIT on a device that cannot blend 32-bit
/// floats, WBOIT's weight set on MBOIT, and a frame without pixels, each named.
#[test]
fn the_blended_methods_refuse_what_they_cannot_do() {
    let (device, queue) = app_device();
    let error = |r: dhoit_runtime::Result<BlendedOit>| r.err().expect("refused").to_string();
    let no_planes = WboitParams {
        weight: WboitWeight::Eq7,
        near: 0.0,
        far: 0.0,
    };
    let e = error(BlendedOit::wboit(&device, &queue, (8, 8), no_planes));
    assert!(e.contains("near and far"), "{e}");
    let e = error(BlendedOit::wboit(
        &device,
        &queue,
        (0, 8),
        WboitParams::default(),
    ));
    assert!(e.contains("no pixels"), "{e}");
    let five = MboitParams {
        moments: 5,
        ..MboitParams::default()
    };
    let (blending, q) = app_device_blending(true);
    let e = error(BlendedOit::mboit(&blending, &q, (8, 8), five));
    assert!(e.contains("4, 6 or 8"), "{e}");
    // The plain device never asked for 32-bit float blending.
    assert!(
        !device
            .features()
            .contains(wgpu::Features::FLOAT32_BLENDABLE)
    );
    let e = error(BlendedOit::mboit(
        &device,
        &queue,
        (8, 8),
        MboitParams::default(),
    ));
    assert!(e.contains("FLOAT32_BLENDABLE"), "{e}");
    if blending
        .features()
        .contains(wgpu::Features::FLOAT32_BLENDABLE)
    {
        let oit = BlendedOit::mboit(&blending, &q, (8, 8), MboitParams::default()).unwrap();
        let e = oit
            .set_wboit(&q, WboitParams::default())
            .expect_err("refused")
            .to_string();
        assert!(e.contains("MBOIT has no weight function"), "{e}");
    }
    let oit = BlendedOit::wboit(&device, &queue, (8, 8), WboitParams::default()).unwrap();
    let e = oit
        .set_wboit(&queue, no_planes)
        .expect_err("refused")
        .to_string();
    assert!(e.contains("near and far"), "{e}");
}

/// DKB and VKB refuse, before building anything, a target format the resolve cannot write, a
/// budget below the method's fixed cost, a frame without pixels and a device without dhoit's
/// features, each named.
#[test]
fn the_allocated_k_buffers_refuse_what_they_cannot_do() {
    let (device, queue) = app_device();
    let weights = common::committed_weights();
    let b = Budget::parse("25%").unwrap();
    let f32x4 = wgpu::TextureFormat::Rgba32Float;
    let error = |r: dhoit_runtime::Result<AllocatedOit>| r.err().expect("refused").to_string();
    let e = error(AllocatedOit::dkb(
        &device,
        &queue,
        (64, 48),
        &weights,
        b,
        wgpu::TextureFormat::Bgra8Unorm,
    ));
    assert!(
        e.contains("resolves onto") && e.contains("Bgra8Unorm"),
        "{e}"
    );
    let tiny = Budget::parse("1KB").unwrap();
    let e = error(AllocatedOit::dkb(
        &device,
        &queue,
        (64, 48),
        &weights,
        tiny,
        f32x4,
    ));
    assert!(e.contains("dkb needs"), "{e}");
    let vkb = dhoit_runtime::importance::VkbParams::default();
    let e = error(AllocatedOit::vkb(
        &device,
        &queue,
        (64, 48),
        vkb,
        tiny,
        f32x4,
    ));
    assert!(e.contains("vkb needs"), "{e}");
    assert!(AllocatedOit::vkb(&device, &queue, (0, 48), vkb, b, f32x4).is_err());
    let instance = wgpu::Instance::default();
    let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
    let (plain, plain_queue) =
        pollster::block_on(adapter.request_device(&Default::default())).unwrap();
    let e = error(AllocatedOit::vkb(
        &plain,
        &plain_queue,
        (64, 48),
        vkb,
        b,
        f32x4,
    ));
    assert!(e.contains("opened without"), "{e}");
}

#[test]
fn the_k_buffer_counts_its_buffers_and_refuses_what_it_cannot_hold() {
    let (device, queue) = app_device();
    let (w, h) = (64u32, 48u32);
    let px = (w * h) as u64;
    for k in [1, 4] {
        let oit = KBufferOit::new(&device, &queue, (w, h), k).unwrap();
        assert_eq!(oit.k(), k);
        // budget::FKB's buffers for k slots a pixel and the application's 16-byte uniform.
        let fkb = dhoit_runtime::budget::FKB;
        assert_eq!(
            oit.allocated_bytes(),
            fkb.allocated_bytes(px, k as u64 * px) + 16
        );
        // A hand count: 8 bytes a slot, 16 + 4 a pixel for the tail, params, status, two
        // unused 16-byte bindings, the application's uniform.
        assert_eq!(
            oit.allocated_bytes(),
            8 * k as u64 * px + 20 * px + 256 + 16 + 32 + 16
        );
    }
    assert!(KBufferOit::new(&device, &queue, (w, h), 0).is_err());
    assert!(KBufferOit::new(&device, &queue, (0, h), 2).is_err());
    let e = KBufferOit::new(&device, &queue, (8192, 8192), 1 << 10)
        .err()
        .unwrap();
    assert!(e.to_string().contains("32-bit"), "{e}");
    let e = KBufferOit::new(&device, &queue, (4096, 4096), 64)
        .err()
        .unwrap();
    assert!(e.to_string().contains("oit.slots"), "{e}");
}

#[test]
fn the_list_refuses_what_it_cannot_hold_or_write() {
    let (device, queue) = app_device();
    assert!(ListOit::new(&device, &queue, (0, 48), 16, 8).is_err());
    assert!(ListOit::new(&device, &queue, (64, 48), 0, 8).is_err());
    assert!(ListOit::new(&device, &queue, (64, 48), 16, 0).is_err());
    assert!(ListOit::new(&device, &queue, (64, 48), 16, 17).is_err());
    let big = ListOit::new(&device, &queue, (64, 48), 1 << 40, 8);
    assert!(big.is_err(), "a pool over 32-bit node indices");
    // A device without dhoit's features is named as lacking them.
    let instance = wgpu::Instance::default();
    let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
    let (plain, plain_queue) =
        pollster::block_on(adapter.request_device(&Default::default())).unwrap();
    let e = ListOit::new(&plain, &plain_queue, (64, 48), 16, 8)
        .err()
        .unwrap();
    assert!(e.to_string().contains("opened without"), "{e}");
    let oit = ListOit::new(&device, &queue, (4, 4), 16, 8).unwrap();
    // budget::LINKED_LIST's buffers and the application's uniform.
    let list = dhoit_runtime::budget::LINKED_LIST;
    assert_eq!(oit.allocated_bytes(), list.allocated_bytes(16, 16) + 16);
    assert_eq!(oit.allocated_bytes(), 4 * 16 + 12 * 16 + 256 + 16 + 16 + 16);
    assert_eq!(oit.nodes(), 16);
}
