//! dhoit's methods in an application's own renderer, written as an outside user would: its
//! own device, vertex buffer and layout, WGSL vertex and fragment shaders (the fragment shader
//! ending in dhoit's `oit_store` or `oit_targets`), its own opaque pass and image under the
//! transparency, its own target, and one protocol for every method (`gpu::Oit`). The image
//! must be the one dhoit's own renderer gives for the same frame. Needs a GPU adapter (lavapipe
//! in CI); DHOIT_SKIP_GPU=1 skips explicitly.

mod common;

use common::{gpu, identity, quad};
use dhoit_runtime::budget::{self, Budget, Occupancy};
use dhoit_runtime::composite::{MboitParams, WboitParams, WboitWeight};
use dhoit_runtime::gpu::{
    self, AllocatedOit, BlendedOit, Capture, ExactOit, FrameOptions, FrameReport, FrameTargets,
    Gpu, KBufferOit, ListOit, Oit, Phase, Slots,
};
use dhoit_runtime::scene::{Camera, Scene};

const BG: [f32; 3] = [0.9, 0.85, 0.8];
const F32X4: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// The application's device, with dhoit's features and limits, and where the adapter has
/// them the optional ones: timestamps (`timestamps`), 32-bit float blending and the colour
/// attachments' bytes a sample (MBOIT's); and dhoit's passes on it.
fn app_device(timestamps: bool) -> (wgpu::Device, wgpu::Queue, Gpu) {
    let instance = wgpu::Instance::default();
    let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
    let mut features = gpu::required_features();
    features |= adapter.features() & wgpu::Features::FLOAT32_BLENDABLE;
    if timestamps {
        features |= adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
    }
    let mut limits = gpu::required_limits();
    limits.max_color_attachment_bytes_per_sample =
        adapter.limits().max_color_attachment_bytes_per_sample;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_features: features,
        required_limits: limits,
        ..Default::default()
    }))
    .unwrap();
    let g = Gpu::on_device(device.clone(), queue.clone(), &adapter.get_info()).unwrap();
    (device, queue, g)
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

/// The application's transparent fragment entry for the methods that store fragments: each
/// fragment with its facing (VKB's importance) and its triangle's index (MLAB's order); the
/// other methods' modules ignore them.
const APP_STORE: &str = r#"
@fragment
fn fs(in: V) {
    oit_store_ordered(in.position, in.color, in.order);
    _ = in.facing;
}
"#;

/// VKB's: its facing.
const APP_FACING: &str = r#"
@fragment
fn fs(in: V) {
    oit_store_facing(in.position, in.color, in.facing);
}
"#;

/// Its transparent fragment entry for the blended methods: it returns into dhoit's targets.
const APP_BLEND: &str = r#"
@fragment
fn fs(in: V) -> OitTargets {
    return oit_targets(in.position, in.color);
}
"#;

/// An application around a scene: its device and dhoit's passes on it, its vertices (the
/// opaque triangles first, then the transparent ones, in the scene's order or reversed), its
/// opaque pipeline, depth and opaque image.
struct App {
    device: wgpu::Device,
    queue: wgpu::Queue,
    gpu: Gpu,
    size: (u32, u32),
    vertices: wgpu::Buffer,
    opaque_vertices: u32,
    all_vertices: u32,
    own: wgpu::BindGroupLayout,
    opaque_pipeline: wgpu::RenderPipeline,
    depth: wgpu::Texture,
    under: wgpu::Texture,
}

/// One transparent pipeline a phase of the method.
type Pipelines = Vec<(Phase, wgpu::RenderPipeline)>;

const VERTEX_LAYOUT: [Option<wgpu::VertexBufferLayout>; 1] = [Some(wgpu::VertexBufferLayout {
    array_stride: 68,
    step_mode: wgpu::VertexStepMode::Vertex,
    attributes: &wgpu::vertex_attr_array![
        0 => Float32x3, 1 => Float32x4, 2 => Float32x3, 3 => Float32x3, 4 => Float32x3,
        5 => Uint32
    ],
})];

impl App {
    fn new(s: &Scene, size: (u32, u32), reversed: bool) -> App {
        Self::on(app_device(true), s, size, reversed)
    }

    fn on(
        (device, queue, gpu): (wgpu::Device, wgpu::Queue, Gpu),
        s: &Scene,
        (w, h): (u32, u32),
        reversed: bool,
    ) -> App {
        // Interleaved position (3 floats), colour (4), the triangle's three positions (9) and
        // its index in the scene (a u32). Each triangle's colour is its first vertex's.
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
        let mut data: Vec<f32> = Vec::new();
        for &t in &order {
            let corners: Vec<f32> = (3 * t..3 * t + 3)
                .flat_map(|v| s.positions[v].to_array())
                .collect();
            for v in 3 * t..3 * t + 3 {
                data.extend_from_slice(&s.positions[v].to_array());
                data.extend_from_slice(&s.colors[3 * t]);
                data.extend_from_slice(&corners);
                data.push(f32::from_bits(t as u32));
            }
        }
        let vertices = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("app vertices"),
            size: (4 * data.len()).max(16) as u64,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(&vertices, 0, bytemuck::cast_slice(&data));
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
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("app opaque"),
            source: wgpu::ShaderSource::Wgsl(APP_SHADER.into()),
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("app opaque"),
            bind_group_layouts: &[Some(&own)],
            immediate_size: 0,
        });
        // Its opaque pass writes colour and depth; its transparent passes write neither.
        let opaque_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("app opaque"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &VERTEX_LAYOUT,
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_opaque"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: F32X4,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let texture = |label, format, usage| texture(&device, (w, h), label, format, usage);
        let under = texture(
            "app image",
            F32X4,
            wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        // Its opaque depth, dhoit's occluder.
        let depth = texture(
            "app depth",
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let opaque_vertices = 3 * (0..triangles).filter(|&t| opaque(t)).count() as u32;
        App {
            device,
            queue,
            gpu,
            size: (w, h),
            vertices,
            opaque_vertices,
            all_vertices: 3 * order.len() as u32,
            own,
            opaque_pipeline,
            depth,
            under,
        }
    }

    /// The application's camera uniform and group for one frame.
    fn camera(&self, s: &Scene, cam: &Camera) -> wgpu::BindGroup {
        let camera = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("app camera"),
            size: 80,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut words = cam.view_proj.to_cols_array().to_vec();
        words.extend_from_slice(&cam.forward.to_array());
        words.push(s.uniform_opacity.unwrap_or(-1.0));
        self.queue
            .write_buffer(&camera, 0, bytemuck::cast_slice(&words));
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("app camera"),
            layout: &self.own,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: camera.as_entire_binding(),
            }],
        })
    }

    /// A target for the method's resolve.
    fn target(&self, format: wgpu::TextureFormat) -> wgpu::Texture {
        texture(
            &self.device,
            self.size,
            "app target",
            format,
            wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        )
    }

    /// One transparent pipeline a phase of `oit`: dhoit's module at group 1, then its own code,
    /// dhoit's colour targets and depth state.
    fn pipelines(&self, oit: &dyn Oit) -> Pipelines {
        oit.phases()
            .iter()
            .map(|&phase| {
                let entry = match (oit.method(), phase) {
                    ("wboit" | "mboit", _) => APP_BLEND,
                    ("vkb", _) => APP_FACING,
                    _ => APP_STORE,
                };
                let src = oit.store_module(phase, 1) + APP_SHADER + entry;
                let module = self
                    .device
                    .create_shader_module(wgpu::ShaderModuleDescriptor {
                        label: Some("app transparent"),
                        source: wgpu::ShaderSource::Wgsl(src.into()),
                    });
                let layout = self
                    .device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("app transparent"),
                        bind_group_layouts: &[Some(&self.own), Some(oit.bind_group_layout(phase))],
                        immediate_size: 0,
                    });
                let targets = oit.color_targets(phase);
                let p = self
                    .device
                    .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                        label: Some("app transparent"),
                        layout: Some(&layout),
                        vertex: wgpu::VertexState {
                            module: &module,
                            entry_point: Some("vs"),
                            compilation_options: Default::default(),
                            buffers: &VERTEX_LAYOUT,
                        },
                        primitive: wgpu::PrimitiveState::default(),
                        depth_stencil: Some(oit.depth_stencil(wgpu::TextureFormat::Depth32Float)),
                        multisample: Default::default(),
                        fragment: Some(wgpu::FragmentState {
                            module: &module,
                            entry_point: Some("fs"),
                            compilation_options: Default::default(),
                            targets: &targets,
                        }),
                        multiview_mask: None,
                        cache: None,
                    });
                (phase, p)
            })
            .collect()
    }

    /// One frame recorded into `enc`: the application's opaque pass, then dhoit's frame, which
    /// calls it back for each geometry pass.
    fn record(
        &self,
        enc: &mut wgpu::CommandEncoder,
        oit: &mut dyn Oit,
        pipelines: &Pipelines,
        camera: &wgpu::BindGroup,
        target: &wgpu::Texture,
    ) -> dhoit_runtime::Result<()> {
        let depth = self.depth.create_view(&Default::default());
        let under = self.under.create_view(&Default::default());
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("app opaque"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &under,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: BG[0] as f64,
                            g: BG[1] as f64,
                            b: BG[2] as f64,
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            pass.set_pipeline(&self.opaque_pipeline);
            pass.set_bind_group(0, camera, &[]);
            pass.set_vertex_buffer(0, self.vertices.slice(..));
            pass.draw(0..self.opaque_vertices, 0..1);
        }
        let target = target.create_view(&Default::default());
        let frame = FrameTargets {
            depth: &depth,
            under: &under,
            target: &target,
        };
        // Its transparent draws, with dhoit's group at 1, in the pass dhoit opened.
        oit.record(enc, &frame, &mut |pass, draw| {
            let pipeline = &pipelines
                .iter()
                .find(|(p, _)| *p == draw.phase)
                .expect("a pipeline a phase")
                .1;
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, camera, &[]);
            pass.set_bind_group(1, draw.group, &[]);
            pass.set_vertex_buffer(0, self.vertices.slice(..));
            pass.draw(self.opaque_vertices..self.all_vertices, 0..1);
        })
    }

    /// A target's colours, row-major.
    fn read(&self, target: &wgpu::Texture) -> Vec<[f32; 3]> {
        let (w, h) = self.size;
        let texel = target.format().block_copy_size(None).unwrap();
        let row = (texel * w).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("app readback"),
            size: (row * h) as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut enc = self.device.create_command_encoder(&Default::default());
        enc.copy_texture_to_buffer(
            target.as_image_copy(),
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
        self.queue.submit([enc.finish()]);
        staging
            .slice(..)
            .map_async(wgpu::MapMode::Read, |r| r.unwrap());
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .unwrap();
        let data = staging.slice(..).get_mapped_range().unwrap();
        let channel = |at: usize| match target.format() {
            wgpu::TextureFormat::Rgba32Float => {
                f32::from_le_bytes(data[at..at + 4].try_into().unwrap())
            }
            wgpu::TextureFormat::Rgba16Float => {
                half::f16::from_le_bytes(data[at..at + 2].try_into().unwrap()).to_f32()
            }
            wgpu::TextureFormat::Rgba8Unorm => data[at] as f32 / 255.0,
            f => panic!("{f:?}"),
        };
        let size = texel as usize / 4;
        (0..h as usize)
            .flat_map(|y| {
                (0..w as usize).map(move |x| {
                    let at = y * row as usize + texel as usize * x;
                    [channel(at), channel(at + size), channel(at + 2 * size)]
                })
            })
            .collect()
    }

    /// One frame of `oit` through `cam`, submitted on its own: the target's colours and the
    /// frame's report.
    fn frame(&self, oit: &mut dyn Oit, s: &Scene, cam: &Camera) -> (Vec<[f32; 3]>, FrameReport) {
        let pipelines = self.pipelines(oit);
        let camera = self.camera(s, cam);
        let target = self.target(oit.target_format());
        let mut enc = self.device.create_command_encoder(&Default::default());
        self.record(&mut enc, oit, &pipelines, &camera, &target)
            .unwrap();
        self.queue.submit([enc.finish()]);
        let image = self.read(&target);
        let mut reports = oit.finished(true).unwrap();
        assert_eq!(reports.len(), 1, "one frame, one report");
        let report = reports.pop().unwrap();
        assert!(report.error.is_none(), "{:?}", report.error);
        (image, report)
    }
}

fn texture(
    device: &wgpu::Device,
    (w, h): (u32, u32),
    label: &str,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
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
}

/// The application's image of one frame of `s` through the identity camera, the method made
/// on its device by `make`, in the scene's order or reversed; and the frame's report.
fn app_frame(
    s: &Scene,
    size: (u32, u32),
    reversed: bool,
    make: impl FnOnce(&Gpu) -> Box<dyn Oit>,
) -> (Vec<[f32; 3]>, FrameReport) {
    let app = App::new(s, size, reversed);
    let mut oit = make(&app.gpu);
    app.frame(oit.as_mut(), s, &identity())
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

/// The largest difference of one channel between two images.
fn worst_difference(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0f32, f32::max))
        .fold(0.0f32, f32::max)
}

/// dhoit's own exact A-buffer of `s` through the identity camera, its fragments read back.
fn exact_frame(g: &Gpu, s: &Scene, size: (u32, u32)) -> dhoit_runtime::gpu::GpuFrame {
    g.render(s, &identity(), size, BG, Slots::Exact).unwrap()
}

/// The frame's occupancy as dhoit's own A-buffer counted it: what an application that knows
/// its scene tells its method to expect.
fn occupancy_of(exact: &dhoit_runtime::gpu::GpuFrame) -> Occupancy {
    Occupancy::of(&exact.fragments.as_ref().unwrap().counts())
}

#[test]
fn an_application_draws_through_dhoits_linked_list_and_gets_dhoits_image() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let s = layered_scene();
    let total = exact_frame(g, &s, (w, h))
        .fragments
        .unwrap()
        .fragment_count() as u64;
    assert!(total > 2 * (w * h) as u64 / 2, "{total} fragments");
    for sorted in [8, 2] {
        // A pool that holds every fragment: which arrive first does not matter.
        let nodes = total + 5;
        let slots = Slots::LinkedList { nodes, sorted };
        let harness = g.render(&s, &identity(), (w, h), BG, slots).unwrap();
        let (app, report) = app_frame(&s, (w, h), false, |g| {
            Box::new(ListOit::new(g, (w, h), nodes, sorted, F32X4).unwrap())
        });
        let worst = worst_difference(&app, &harness.image.data);
        assert!(
            worst <= 1e-5,
            "sorted {sorted}: the application's image differs by {worst}"
        );
        assert_eq!(report.allocated_bytes, harness.allocated_bytes);
        // Not the background: the application's fragments reached the list.
        let covered = app.iter().filter(|c| (c[0] - BG[0]).abs() > 1e-3).count();
        assert!(covered > (w * h / 2) as usize, "{covered} pixels covered");
    }
}

#[test]
fn an_application_draws_through_dhoits_k_buffer_and_gets_dhoits_fkb_image_in_any_order() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let px = (w * h) as u64;
    let s = layered_scene();
    let exact = exact_frame(g, &s, (w, h));
    for k in [1, 3, 8] {
        let harness = g
            .render(&s, &identity(), (w, h), BG, Slots::Uniform(k))
            .unwrap();
        // Either capture: the portable one draws two passes with 32-bit atomics alone, into the
        // same bytes.
        for (reversed, capture) in [
            (false, Capture::Wide),
            (true, Capture::Wide),
            (false, Capture::Portable),
            (true, Capture::Portable),
        ] {
            let (app, report) = app_frame(&s, (w, h), reversed, |g| {
                let oit = KBufferOit::new(g, (w, h), k, F32X4)
                    .unwrap()
                    .with_capture(capture);
                let phases = match capture {
                    Capture::Wide => vec![Phase::Capture],
                    Capture::Portable => vec![Phase::CaptureDepths, Phase::CaptureColours],
                };
                assert_eq!(oit.phases(), phases.as_slice());
                Box::new(oit)
            });
            let worst = worst_difference(&app, &harness.image.data);
            assert!(
                worst <= 1e-5,
                "k = {k}, reversed {reversed}, {capture:?}: the application's image differs \
                 from dhoit's FKB by {worst}"
            );
            // budget::FKB's buffers for k slots a pixel; a hand count: 8 bytes a slot, 16 + 4
            // a pixel for the tail, params, status, two unused 16-byte bindings.
            assert_eq!(
                report.allocated_bytes,
                budget::FKB.allocated_bytes(px, k as u64 * px)
            );
            assert_eq!(
                report.allocated_bytes,
                8 * k as u64 * px + 20 * px + 256 + 16 + 32
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

/// The A-buffer through the application's two draws: the exact image in either order, with
/// exact memory where its pool was sized for the frame (`Oit::expect`); sized for two
/// fragments a pixel before any count, a pool this frame outgrows keeps the pixels whose
/// fragments it holds whole, says so, and the frames after it hold them all.
#[test]
fn an_application_draws_twice_through_dhoits_a_buffer_and_gets_the_exact_image_in_any_order() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let px = (w * h) as u64;
    let s = layered_scene();
    let exact = exact_frame(g, &s, (w, h));
    let occ = occupancy_of(&exact);
    assert!(occ.fragments > px, "{} fragments", occ.fragments);
    for reversed in [false, true] {
        let (app, report) = app_frame(&s, (w, h), reversed, |g| {
            let mut oit = ExactOit::new(g, (w, h), F32X4).unwrap();
            oit.expect(occ);
            Box::new(oit)
        });
        let worst = worst_difference(&app, &exact.image.data);
        assert!(
            worst <= 1e-5,
            "reversed {reversed}: the application's image differs from dhoit's A-buffer by {worst}"
        );
        assert!(report.exact && !report.pool_short);
        assert_eq!(report.fragments, Some(occ.fragments));
        assert_eq!(report.allocated_bytes, exact.allocated_bytes);
    }
    // A pool sized for half this frame's fragments: the pixels past its end lose theirs,
    // and the frame says so.
    let app = App::new(&s, (w, h), false);
    let mut oit = ExactOit::new(&app.gpu, (w, h), F32X4).unwrap();
    oit.expect(Occupancy {
        fragments: occ.fragments / 2,
        ..occ
    });
    let (first, report) = app.frame(&mut oit, &s, &identity());
    assert!(report.pool_short && !report.exact, "{report:?}");
    assert_eq!(report.fragments, Some(occ.fragments));
    let off = worst_difference(&first, &exact.image.data);
    assert!(off > 1e-3, "a short pool dropped nothing ({off})");
    // The next frame's pool follows the count the first read back.
    let (next, report) = app.frame(&mut oit, &s, &identity());
    assert!(report.exact && !report.pool_short, "{report:?}");
    assert!(worst_difference(&next, &exact.image.data) <= 1e-5);
    assert!(
        report.allocated_bytes > exact.allocated_bytes,
        "the pool's headroom"
    );
}

/// MLAB through the application's two draws (the A-buffer's), each fragment handed with its
/// triangle's index as its submission index: the image is dhoit's own MLAB frame's within 1e-5
/// at 1, 2 and 4 rows, in either draw order (MLAB blends in the order the indices give, not the
/// arrival's), and at 1 and 2 rows not the exact image (the layers submitted out of depth
/// order); its bytes are the A-buffer's and 4 a fragment.
#[test]
fn an_application_draws_through_dhoits_mlab_and_gets_its_image_in_any_order() {
    let Some(g) = gpu() else { return };
    let size = (64, 48);
    // The layers in a shuffled submission order: front to back (as layered_scene submits
    // them) MLAB merges exactly.
    let s = layered_scene().shuffled(7);
    let exact = exact_frame(g, &s, size);
    let occ = occupancy_of(&exact);
    for rows in [1, 2, 4] {
        let harness = g
            .render(&s, &identity(), size, BG, Slots::Mlab(rows))
            .unwrap();
        // Merged into one or two rows out of depth order, MLAB is not the exact image (at
        // four rows, these up to seven layers lose nothing).
        let off = worst_difference(&harness.image.data, &exact.image.data);
        assert!(rows > 2 || off > 1e-3, "{rows} rows: MLAB is exact ({off})");
        for reversed in [false, true] {
            let (app, report) = app_frame(&s, size, reversed, |g| {
                let mut oit = ExactOit::mlab(g, size, rows, F32X4).unwrap();
                assert_eq!(oit.mlab_rows(), Some(rows));
                oit.expect(occ);
                Box::new(oit)
            });
            let worst = worst_difference(&app, &harness.image.data);
            assert!(
                worst <= 1e-5,
                "{rows} rows, reversed {reversed}: the application's image differs from \
                 dhoit's MLAB by {worst}"
            );
            assert_eq!(report.allocated_bytes, harness.allocated_bytes);
        }
    }
    // Rows outside 1..=8 refused.
    let (_, _, g) = app_device(false);
    for rows in [0, dhoit_runtime::wgsl::MLAB_MAX_ROWS + 1] {
        let e = ExactOit::mlab(&g, size, rows, F32X4)
            .err()
            .expect("refused")
            .to_string();
        assert!(e.contains("rows"), "{e}");
    }
}

/// DKB and VKB through the application's draws: the count, the features (VKB's count with the
/// nearest fragment) and the capture are its own pipelines (one a phase), every compute pass
/// dhoit's; sized for the frame's occupancy, the image is dhoit's own frame's (one that
/// truncates: not the exact image), in either draw order, with the same buffers as dhoit's own
/// frame, each of its passes timed. By default, where the pool sized for the frame holds every
/// fragment, the frame is exact.
#[test]
fn an_application_draws_through_dhoits_dkb_and_vkb_and_gets_their_images_in_any_order() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let px = (w * h) as u64;
    let s = layered_scene();
    let weights = common::committed_weights();
    let exact = exact_frame(g, &s, (w, h));
    let occ = occupancy_of(&exact);
    let vkb = dhoit_runtime::importance::VkbParams::default();
    for name in ["dkb", "vkb"] {
        let layout = match name {
            "dkb" => budget::DKB.for_network(&weights),
            _ => budget::VKB,
        };
        let statistics = if name == "dkb" { "features" } else { "count" };
        let make = |g: &Gpu, b: Budget| match name {
            "dkb" => AllocatedOit::dkb(g, (w, h), &weights, b, F32X4).unwrap(),
            _ => AllocatedOit::vkb(g, (w, h), vkb, b, F32X4).unwrap(),
        };
        // At every budget DKB's pool holds every record at once (at 0.1 fpp larger than its
        // slots and tails): the application's first frame draws its features phase once.
        for text in ["1fpp", "25%", "0.1fpp"] {
            let b = Budget::parse(text).unwrap();
            let f = b.fragment_budget(&layout, px).unwrap();
            let opts = FrameOptions::default().always_approximate();
            let slots = match name {
                "dkb" => Slots::Dkb(&weights, f.into()),
                _ => Slots::Vkb(vkb, f.into()),
            };
            let harness = g
                .render_with(&opts, &s, &identity(), (w, h), BG, slots)
                .unwrap();
            assert!(!harness.exact);
            let batches = harness.record_batches.unwrap_or(1);
            assert_eq!(batches, 1, "{name} at {text}");
            let off = worst_difference(&harness.image.data, &exact.image.data);
            assert!(
                off > 1e-3,
                "{name} at {text} is exact ({off}): nothing truncated"
            );
            // Reversed, once with the portable capture (two passes, 32-bit atomics alone).
            for (reversed, capture) in [
                (false, Capture::Wide),
                (true, Capture::Wide),
                (true, Capture::Portable),
            ] {
                let (app, report) = app_frame(&s, (w, h), reversed, |g| {
                    let mut oit = make(g, b).exact_when_cheaper(false).with_capture(capture);
                    oit.expect(occ);
                    Box::new(oit)
                });
                let worst = worst_difference(&app, &harness.image.data);
                assert!(
                    worst <= 1e-5,
                    "{name} at {text}, reversed {reversed}, {capture:?}: the application's \
                     image differs from dhoit's by {worst}"
                );
                assert!(!report.exact && !report.pool_short, "{report:?}");
                assert_eq!(
                    report.plan,
                    harness.plan.map(|p| dhoit_runtime::plan::Plan {
                        per_batch: 0,
                        batches: 0,
                        ..p
                    })
                );
                assert_eq!(report.allocated_bytes, harness.allocated_bytes);
                let drawn = report
                    .pass_ms
                    .iter()
                    .filter(|(p, _)| p == &statistics)
                    .count();
                assert_eq!(
                    drawn as u64,
                    if name == "dkb" { batches } else { 1 },
                    "{name} at {text}: {:?}",
                    report.pass_ms
                );
                let captures: &[&str] = match capture {
                    Capture::Wide => &["capture"],
                    Capture::Portable => &["capture depths", "capture colours"],
                };
                for pass in ["count", statistics, "importance", "resolve"]
                    .iter()
                    .chain(captures)
                {
                    let ms = report.pass_ms.iter().find(|(p, _)| p == pass);
                    assert!(
                        ms.is_some_and(|(_, ms)| *ms > 0.0),
                        "{name}, {pass}: {:?}",
                        report.pass_ms
                    );
                }
            }
        }
        // By default the pool is no larger than the exact A-buffer of the occupancy it was
        // sized for: where the budget reserves that much (90% of this frame, with its tails),
        // the frame's fragments fit it and the frame keeps them all.
        let b = Budget::parse("90%").unwrap();
        let (app, report) = app_frame(&s, (w, h), false, |g| {
            let mut oit = make(g, b);
            oit.expect(occ);
            Box::new(oit)
        });
        assert!(report.exact, "{name}: {report:?}");
        let worst = worst_difference(&app, &exact.image.data);
        assert!(
            worst <= 1e-5,
            "{name}, exact where cheaper: {worst} from the A-buffer"
        );
        let reserved = dhoit_runtime::frame::reserved_bytes(
            if name == "dkb" {
                dhoit_runtime::frame::Method::Dkb
            } else {
                dhoit_runtime::frame::Method::Vkb
            },
            &layout,
            px,
            b.fragment_budget(&layout, px).unwrap().of(occ.fragments),
            &occ,
        );
        assert!(report.allocated_bytes <= reserved, "{name}: {report:?}");
    }
}

/// An application's DKB frame after the first draws no features phase: its count phase
/// gathers the network's statistics for the pixels the frame before marked, so it draws its
/// geometry twice (the count, the capture), or with the portable capture four times (the count
/// with the nearest depths and the sums, the nearest keys' colours, the capture's two passes);
/// with the camera still it gives the first frame's image, which is dhoit's own. The first
/// frame and one after a cut mark their own records and draw the features phase.
#[test]
fn an_application_s_dkb_frames_after_the_first_gather_their_statistics_with_their_count() {
    let Some(g) = gpu() else { return };
    let weights = common::committed_weights();
    let s = layered_scene();
    let size = (64, 48);
    let exact = exact_frame(g, &s, size);
    let occ = occupancy_of(&exact);
    let b = Budget::parse("25%").unwrap();
    let f = b
        .fragment_budget(&budget::DKB.for_network(&weights), (size.0 * size.1) as u64)
        .unwrap();
    let opts = FrameOptions::default().always_approximate();
    let harness = g
        .render_with(
            &opts,
            &s,
            &identity(),
            size,
            BG,
            Slots::Dkb(&weights, f.into()),
        )
        .unwrap();
    assert!(worst_difference(&harness.image.data, &exact.image.data) > 1e-3);
    let geometry = |r: &FrameReport| -> Vec<&str> {
        let drawn = [
            "count",
            "features",
            "capture",
            "capture depths",
            "capture colours",
        ];
        r.passes
            .iter()
            .copied()
            .filter(|p| drawn.contains(p))
            .collect()
    };
    for (capture, first, after) in [
        (
            Capture::Wide,
            &["count", "features", "capture"][..],
            &["count", "capture"][..],
        ),
        (
            Capture::Portable,
            &["count", "features", "capture depths", "capture colours"][..],
            &["count", "capture depths", "capture colours"][..],
        ),
    ] {
        let app = App::new(&s, size, false);
        let mut oit = AllocatedOit::dkb(&app.gpu, size, &weights, b, F32X4)
            .unwrap()
            .exact_when_cheaper(false)
            .with_capture(capture);
        oit.expect(occ);
        let (one, r1) = app.frame(&mut oit, &s, &identity());
        let (two, r2) = app.frame(&mut oit, &s, &identity());
        assert_eq!(geometry(&r1), first, "{capture:?}: the first frame");
        assert_eq!(geometry(&r2), after, "{capture:?}: the frame after");
        assert!(one == two, "{capture:?}: the second frame differs");
        let worst = worst_difference(&two, &harness.image.data);
        assert!(worst <= 1e-5, "{capture:?}: {worst} from dhoit's own frame");
        oit.cut();
        let (three, r3) = app.frame(&mut oit, &s, &identity());
        assert_eq!(geometry(&r3), first, "{capture:?}: after a cut");
        assert!(three == two, "{capture:?}: after a cut");
    }
}
/// A byte budget for DKB or VKB in an application is a fixed pool: the bytes beside the
/// method's fixed ones. A frame there runs at the most slots those bytes hold for its own
/// occupancy (what `Gpu::render`, counting first, gives it: a slots' budget of
/// `PlanBudget::Bytes`),
/// allocates exactly M, and gives dhoit's image; where M holds the A-buffer, the frame is
/// exact. Bytes below what any frame needs are refused when the method is made.
#[test]
fn a_byte_budget_is_resolved_against_each_frames_own_count() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let px = (w * h) as u64;
    let s = layered_scene();
    let weights = common::committed_weights();
    let vkb = dhoit_runtime::importance::VkbParams::default();
    let exact = exact_frame(g, &s, (w, h));
    let occ = occupancy_of(&exact);
    let quarter = occ.fragments / 4;
    for name in ["dkb", "vkb"] {
        let layout = match name {
            "dkb" => budget::DKB.for_network(&weights),
            _ => budget::VKB,
        };
        let make = |g: &Gpu, b: Budget| match name {
            "dkb" => AllocatedOit::dkb(g, (w, h), &weights, b, F32X4),
            _ => AllocatedOit::vkb(g, (w, h), vkb, b, F32X4),
        };
        let m = layout.reserved_bytes(px, quarter, &occ);
        let f = layout.fragment_budget_counted(m, px, &occ).unwrap();
        assert!(f >= quarter && f < occ.fragments, "{name}: {f}");
        let bytes = dhoit_runtime::plan::PlanBudget::Bytes(m);
        let counted = match name {
            "dkb" => Slots::Dkb(&weights, bytes),
            _ => Slots::Vkb(vkb, bytes),
        };
        let opts = FrameOptions::default().always_approximate();
        let given = g
            .render_with(&opts, &s, &identity(), (w, h), BG, counted)
            .unwrap();
        for reversed in [false, true] {
            let (app, report) = app_frame(&s, (w, h), reversed, |g| {
                let oit = make(g, Budget::Bytes(m)).unwrap();
                Box::new(oit.exact_when_cheaper(false))
            });
            let worst = worst_difference(&app, &given.image.data);
            assert!(worst <= 1e-5, "{name}, reversed {reversed}: {worst}");
            assert!(!report.exact, "{name}");
            assert_eq!(report.plan.map(|p| p.f), Some(f), "{name}");
            // The totals the device added up, read back by name: the CPU's count of the
            // A-buffer's fragments.
            assert_eq!(report.occupancy, Some(occ), "{name}: the device's totals");
            assert_eq!(report.allocated_bytes, m, "{name}: the fixed pool");
        }
        // Bytes that hold the A-buffer beside the method's fixed ones: its image, exact.
        let holds = layout.fixed_bytes(px) + budget::SLOT_BYTES * occ.fragments;
        let (app, report) = app_frame(&s, (w, h), false, |g| {
            let mut oit = make(g, Budget::Bytes(holds)).unwrap();
            oit.expect(occ);
            Box::new(oit)
        });
        assert!(report.exact, "{name}");
        assert!(worst_difference(&app, &exact.image.data) <= 1e-5);
        // Bytes below what any frame needs (an empty one: the fixed bytes, DKB's marks).
        let (_, _, g) = app_device(false);
        let tiny = Budget::Bytes(layout.fixed_bytes(px) - 1);
        assert!(make(&g, tiny).is_err());
    }
}

/// A glTF file through the application: a built-in scene written as binary glTF and read
/// back by dhoit's loader, each triangle one colour, seen from an orbit camera at one uniform
/// opacity. The application's image is dhoit's own, within 1e-5, for every method: the
/// A-buffer, FKB, DKB, VKB, MLAB and the list (a pool that holds every fragment) in either
/// draw order, WBOIT and MBOIT in the scene's (reversed, within their targets' rounding).
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
    let cam = Camera::orbit(&s, 1, dhoit_runtime::scene::DEFAULT_VIEWS, (w, h));
    let px = (w * h) as u64;
    let exact = g
        .render(&s, &cam, (w, h), BG, dhoit_runtime::gpu::Slots::Exact)
        .unwrap();
    let occ = occupancy_of(&exact);
    assert!(occ.fragments > px / 2, "{} fragments", occ.fragments);
    let weights = common::committed_weights();
    let b = Budget::parse("1fpp").unwrap();
    let opts = FrameOptions::default().always_approximate();
    let dkb_f = b
        .fragment_budget(&budget::DKB.for_network(&weights), px)
        .unwrap();
    let vkb = dhoit_runtime::importance::VkbParams::default();
    let vkb_f = b.fragment_budget(&budget::VKB, px).unwrap();
    let nodes = occ.fragments + 5;
    let mboit = MboitParams::default();
    let cases: Vec<(&str, Slots)> = vec![
        ("abuffer", Slots::Exact),
        ("fkb", Slots::Uniform(2)),
        ("dkb", Slots::Dkb(&weights, dkb_f.into())),
        ("vkb", Slots::Vkb(vkb, vkb_f.into())),
        ("mlab", Slots::Mlab(2)),
        ("linked-list", Slots::LinkedList { nodes, sorted: 8 }),
        ("wboit", Slots::Wboit(WboitParams::default())),
        ("mboit", Slots::Mboit(mboit)),
    ];
    for (name, slots) in cases {
        if name == "mboit"
            && !common::has(
                g,
                wgpu::Features::FLOAT32_BLENDABLE,
                "MBOIT from a glTF file",
            )
        {
            continue;
        }
        let harness = g.render_with(&opts, &s, &cam, (w, h), BG, slots).unwrap();
        // Every method but the list (whose pool holds every fragment) approximates here.
        if !matches!(slots, Slots::Exact) && name != "linked-list" {
            let off = worst_difference(&harness.image.data, &exact.image.data);
            assert!(off > 1e-3, "{name} is exact ({off}): nothing truncated");
        }
        for reversed in [false, true] {
            let app = App::new(&s, (w, h), reversed);
            let mut oit: Box<dyn Oit> = match name {
                "abuffer" => Box::new(ExactOit::new(&app.gpu, (w, h), F32X4).unwrap()),
                "mlab" => Box::new(ExactOit::mlab(&app.gpu, (w, h), 2, F32X4).unwrap()),
                "linked-list" => Box::new(ListOit::new(&app.gpu, (w, h), nodes, 8, F32X4).unwrap()),
                "wboit" => Box::new(
                    BlendedOit::wboit(&app.gpu, (w, h), WboitParams::default(), F32X4).unwrap(),
                ),
                "mboit" => Box::new(BlendedOit::mboit(&app.gpu, (w, h), mboit, F32X4).unwrap()),
                "fkb" => Box::new(KBufferOit::new(&app.gpu, (w, h), 2, F32X4).unwrap()),
                "dkb" => Box::new(
                    AllocatedOit::dkb(&app.gpu, (w, h), &weights, b, F32X4)
                        .unwrap()
                        .exact_when_cheaper(false),
                ),
                _ => Box::new(
                    AllocatedOit::vkb(&app.gpu, (w, h), vkb, b, F32X4)
                        .unwrap()
                        .exact_when_cheaper(false),
                ),
            };
            oit.expect(occ);
            let (image, _) = app.frame(oit.as_mut(), &s, &cam);
            let worst = worst_difference(&image, &harness.image.data);
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
/// dhoit's `oit_targets`, its pipeline writes dhoit's targets with dhoit's blend states, in the
/// render passes dhoit opens. The image is dhoit's own frame's for the same draws within 1e-5
/// over the application's opaque occluder, for eqs. 10 and 7 of WBOIT (7 with planes) and 4,
/// 6 and 8 power moments where the device blends 32-bit floats; in the reversed order within
/// the targets' rounding (the devices add in submission order); the bytes are the layout
/// table's.
#[test]
fn an_application_draws_through_dhoits_wboit_and_mboit_and_gets_their_images() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let px = (w * h) as u64;
    let s = layered_scene();
    let exact = exact_frame(g, &s, (w, h));
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
    let (device, _, _) = app_device(false);
    let blends = device
        .features()
        .contains(wgpu::Features::FLOAT32_BLENDABLE)
        && common::has(
            g,
            wgpu::Features::FLOAT32_BLENDABLE,
            "MBOIT in dhoit's harness",
        );
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
    assert!(cases.len() >= 3 || !blends, "{} cases", cases.len());
    for (name, slots, layout) in cases {
        let harness = g.render(&s, &identity(), (w, h), BG, slots).unwrap();
        let off = worst_difference(&harness.image.data, &exact.image.data);
        assert!(off > 1e-3, "{name} is the exact image ({off})");
        let make = |g: &Gpu| -> Box<dyn Oit> {
            Box::new(match slots {
                Slots::Wboit(p) => BlendedOit::wboit(g, (w, h), p, F32X4).unwrap(),
                Slots::Mboit(p) => BlendedOit::mboit(g, (w, h), p, F32X4).unwrap(),
                _ => unreachable!(),
            })
        };
        let (app, report) = app_frame(&s, (w, h), false, make);
        let worst = worst_difference(&app, &harness.image.data);
        assert!(
            worst <= 1e-5,
            "{name}: the application's image differs from dhoit's by {worst}"
        );
        assert_eq!(
            report.allocated_bytes,
            layout.allocated_bytes(px, 0),
            "{name}: the layout table's bytes"
        );
        // Reversed: the same sums, added in another order at binary16 (WBOIT's 8-bit
        // revealage is a product of the same factors): on lavapipe 6e-4 to 2.3e-3.
        let (reversed, _) = app_frame(&s, (w, h), true, make);
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
/// floats, WBOIT's weight set on MBOIT, a budget, and a frame without pixels, each named.
#[test]
fn the_blended_methods_refuse_what_they_cannot_do() {
    let (_, _, g) = app_device(false);
    let error = |r: dhoit_runtime::Result<BlendedOit>| r.err().expect("refused").to_string();
    let no_planes = WboitParams {
        weight: WboitWeight::Eq7,
        near: 0.0,
        far: 0.0,
    };
    let e = error(BlendedOit::wboit(&g, (8, 8), no_planes, F32X4));
    assert!(e.contains("near and far"), "{e}");
    let e = error(BlendedOit::wboit(&g, (0, 8), WboitParams::default(), F32X4));
    assert!(e.contains("0x8"), "{e}");
    let five = MboitParams {
        moments: 5,
        ..MboitParams::default()
    };
    let e = error(BlendedOit::mboit(&g, (8, 8), five, F32X4));
    assert!(e.contains("4, 6 or 8"), "{e}");
    // A device never asked for 32-bit float blending.
    let instance = wgpu::Instance::default();
    let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
    let (plain, plain_queue) =
        pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            required_features: gpu::required_features(),
            required_limits: gpu::required_limits(),
            ..Default::default()
        }))
        .unwrap();
    let plain = Gpu::on_device(plain, plain_queue, &adapter.get_info()).unwrap();
    let e = error(BlendedOit::mboit(
        &plain,
        (8, 8),
        MboitParams::default(),
        F32X4,
    ));
    assert!(e.contains("FLOAT32_BLENDABLE"), "{e}");
    if g.device()
        .features()
        .contains(wgpu::Features::FLOAT32_BLENDABLE)
    {
        let mut oit = BlendedOit::mboit(&g, (8, 8), MboitParams::default(), F32X4).unwrap();
        let e = oit
            .set_wboit(WboitParams::default())
            .expect_err("refused")
            .to_string();
        assert!(e.contains("MBOIT"), "{e}");
    }
    let mut oit = BlendedOit::wboit(&g, (8, 8), WboitParams::default(), F32X4).unwrap();
    let e = oit.set_wboit(no_planes).expect_err("refused").to_string();
    assert!(e.contains("near and far"), "{e}");
    let e = oit
        .set_budget(Budget::parse("25%").unwrap())
        .expect_err("refused")
        .to_string();
    assert!(e.contains("wboit takes no budget"), "{e}");
}

/// DKB and VKB refuse, before building anything, a target format the resolve cannot write, a
/// budget below the method's fixed cost and a frame without pixels, each named; on a device
/// without 64-bit atomics they, and FKB, draw the portable passes.
#[test]
fn the_allocated_k_buffers_refuse_what_they_cannot_do() {
    let (_, _, g) = app_device(false);
    let weights = common::committed_weights();
    let b = Budget::parse("25%").unwrap();
    let error = |r: dhoit_runtime::Result<AllocatedOit>| r.err().expect("refused").to_string();
    let bgra = wgpu::TextureFormat::Bgra8Unorm;
    let e = error(AllocatedOit::dkb(&g, (64, 48), &weights, b, bgra));
    assert!(
        e.contains("resolves onto") && e.contains("Bgra8Unorm"),
        "{e}"
    );
    let tiny = Budget::parse("1KB").unwrap();
    let e = error(AllocatedOit::dkb(&g, (64, 48), &weights, tiny, F32X4));
    assert!(e.contains("dkb needs"), "{e}");
    let vkb = dhoit_runtime::importance::VkbParams::default();
    let e = error(AllocatedOit::vkb(&g, (64, 48), vkb, tiny, F32X4));
    assert!(e.contains("vkb needs"), "{e}");
    assert!(AllocatedOit::vkb(&g, (0, 48), vkb, b, F32X4).is_err());
    let instance = wgpu::Instance::default();
    let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
    let (plain, plain_queue) =
        pollster::block_on(adapter.request_device(&Default::default())).unwrap();
    // A device opened with nothing (a page's WebGPU): every method runs, the k-buffers in the
    // portable passes (DKB's features need no 64-bit atomic).
    let plain = Gpu::on_device(plain, plain_queue, &adapter.get_info()).unwrap();
    assert!(!plain.is_wide());
    let d = AllocatedOit::dkb(&plain, (64, 48), &weights, b, F32X4).unwrap();
    assert_eq!(
        d.phases(),
        [
            Phase::CountFeatures,
            Phase::Features,
            Phase::CaptureDepths,
            Phase::CaptureColours
        ]
    );
    let fkb = KBufferOit::new(&plain, (64, 48), 2, F32X4).unwrap();
    assert_eq!(fkb.phases(), [Phase::CaptureDepths, Phase::CaptureColours]);
    let v = AllocatedOit::vkb(&plain, (64, 48), vkb, b, F32X4).unwrap();
    assert_eq!(
        v.phases(),
        [Phase::VkbCount, Phase::CaptureDepths, Phase::CaptureColours]
    );
}

/// FKB's and the list's fixed buffers are checked against the device's bindings and 32-bit
/// indices when they are made and when their budget changes.
#[test]
fn the_k_buffer_and_the_list_refuse_what_they_cannot_hold() {
    let (_, _, g) = app_device(false);
    let (w, h) = (64u32, 48u32);
    assert!(KBufferOit::new(&g, (w, h), 0, F32X4).is_err());
    assert!(KBufferOit::new(&g, (0, h), 2, F32X4).is_err());
    let e = KBufferOit::new(&g, (8192, 8192), 1 << 10, F32X4)
        .err()
        .unwrap();
    assert!(e.to_string().contains("32-bit"), "{e}");
    let e = KBufferOit::new(&g, (4096, 4096), 64, F32X4).err().unwrap();
    assert!(e.to_string().contains("oit.slots"), "{e}");
    let mut fkb = KBufferOit::new(&g, (w, h), 2, F32X4).unwrap();
    fkb.set_budget(Budget::parse("4fpp").unwrap()).unwrap();
    assert_eq!(fkb.k(), 4);
    let e = fkb.set_budget(Budget::parse("25%").unwrap()).unwrap_err();
    assert!(e.to_string().contains("before any count"), "{e}");
    assert!(ListOit::new(&g, (0, 48), 16, 8, F32X4).is_err());
    assert!(ListOit::new(&g, (64, 48), 0, 8, F32X4).is_err());
    assert!(ListOit::new(&g, (64, 48), 16, 0, F32X4).is_err());
    assert!(ListOit::new(&g, (64, 48), 16, 17, F32X4).is_err());
    let big = ListOit::new(&g, (64, 48), 1 << 40, 8, F32X4);
    assert!(big.is_err(), "a pool over 32-bit node indices");
    let mut list = ListOit::new(&g, (w, h), 16, 8, F32X4).unwrap();
    list.set_budget(Budget::parse("2fpp").unwrap()).unwrap();
    assert_eq!(list.nodes(), 2 * (w * h) as u64);
}

/// One of each method on `g` for frames of `size` resolving onto `format`: the list (a pool of
/// four fragments a pixel), FKB (2 slots), the A-buffer, MLAB (2 rows), DKB and VKB at 25%,
/// WBOIT and MBOIT.
fn every_method(g: &Gpu, size: (u32, u32), format: wgpu::TextureFormat) -> Vec<Box<dyn Oit>> {
    every_method_at(g, size, format, Budgets::default())
}

/// The budgets [`every_method_at`] makes the methods with: the list's nodes a pixel, FKB's k,
/// MLAB's rows, DKB's and VKB's budget.
#[derive(Clone, Copy)]
struct Budgets {
    nodes_per_pixel: u64,
    k: u32,
    rows: u32,
    allocated: Budget,
}

impl Default for Budgets {
    fn default() -> Budgets {
        Budgets {
            nodes_per_pixel: 4,
            k: 2,
            rows: 2,
            allocated: Budget::parse("25%").unwrap(),
        }
    }
}

/// [`every_method`] with the budgets `at`.
fn every_method_at(
    g: &Gpu,
    size: (u32, u32),
    format: wgpu::TextureFormat,
    at: Budgets,
) -> Vec<Box<dyn Oit>> {
    let weights = common::committed_weights();
    let vkb = dhoit_runtime::importance::VkbParams::default();
    let b = at.allocated;
    let nodes = at.nodes_per_pixel * (size.0 * size.1) as u64;
    let mut methods: Vec<Box<dyn Oit>> = vec![
        Box::new(ListOit::new(g, size, nodes, 8, format).unwrap()),
        Box::new(KBufferOit::new(g, size, at.k, format).unwrap()),
        Box::new(ExactOit::new(g, size, format).unwrap()),
        Box::new(ExactOit::mlab(g, size, at.rows, format).unwrap()),
        Box::new(AllocatedOit::dkb(g, size, &weights, b, format).unwrap()),
        Box::new(AllocatedOit::vkb(g, size, vkb, b, format).unwrap()),
        Box::new(BlendedOit::wboit(g, size, WboitParams::default(), format).unwrap()),
    ];
    if common::has(
        g,
        wgpu::Features::FLOAT32_BLENDABLE,
        "MBOIT among every method",
    ) {
        methods.push(Box::new(
            BlendedOit::mboit(g, size, MboitParams::default(), format).unwrap(),
        ));
    }
    methods
}

/// Several frames of a moving camera recorded into one encoder and submitted once give the
/// images the same method gives them one frame at a time, each submitted and read on its own
/// before the next is recorded, for every method: no frame waits within a submission (the first
/// of a method whose memory follows the count counts first, once), and none reads what the next
/// one writes. Each frame's report comes back once, in order. (One instance renders the frames
/// one at a time, as the one records them together: DKB's frame after the first gathers its
/// statistics for the pixels the frame before marked, so a new instance's first frame of the
/// same view, which marks its own, may differ from it.)
#[test]
fn frames_recorded_into_one_submission_are_the_frames_rendered_one_at_a_time() {
    let Some(g) = gpu() else { return };
    let size = (48, 36);
    let s =
        dhoit_runtime::scene::load("shells", dhoit_runtime::scene::Opacity::Uniform(0.4)).unwrap();
    let cams: Vec<Camera> = (0..4).map(|v| Camera::orbit(&s, v, 24, size)).collect();
    for m in 0..every_method(g, size, F32X4).len() {
        let app = App::new(&s, size, false);
        // One frame at a time, each submitted and read before the next is recorded.
        let mut one = every_method(&app.gpu, size, F32X4).swap_remove(m);
        let alone: Vec<Vec<[f32; 3]>> = cams
            .iter()
            .map(|cam| app.frame(one.as_mut(), &s, cam).0)
            .collect();
        // Every frame into one encoder, one submission.
        let mut oit = every_method(&app.gpu, size, F32X4).swap_remove(m);
        let name = oit.method();
        let pipelines = app.pipelines(oit.as_ref());
        let targets: Vec<wgpu::Texture> = cams.iter().map(|_| app.target(F32X4)).collect();
        let cameras: Vec<wgpu::BindGroup> = cams.iter().map(|c| app.camera(&s, c)).collect();
        let mut enc = app.device.create_command_encoder(&Default::default());
        let mut syncs = Vec::new();
        for (camera, target) in cameras.iter().zip(&targets) {
            let before = gpu::host_syncs();
            app.record(&mut enc, oit.as_mut(), &pipelines, camera, target)
                .unwrap();
            syncs.push(gpu::host_syncs() - before);
        }
        // Recording made no submission and no wait of its own, but where the method's first
        // frame counted its fragments first (the methods whose memory follows the count: its
        // submissions and waits).
        let counts = matches!(name, "abuffer" | "mlab" | "dkb" | "vkb");
        assert!(
            syncs[1..] == [0, 0, 0] && (syncs[0] > 0) == counts,
            "{name}: recording waited {syncs:?}"
        );
        // Recorded, not submitted: no report yet.
        assert!(oit.finished(false).unwrap().is_empty(), "{name}");
        app.queue.submit([enc.finish()]);
        let reports = oit.finished(true).unwrap();
        let frames: Vec<u64> = reports.iter().map(|r| r.frame).collect();
        assert_eq!(
            frames,
            vec![0, 1, 2, 3],
            "{name}: every frame's report, in order"
        );
        let mut moved = 0.0f32;
        for (i, (target, one)) in targets.iter().zip(&alone).enumerate() {
            let together = app.read(target);
            let worst = worst_difference(&together, one);
            assert!(
                worst <= 1e-6,
                "{name}, frame {i}: {worst} from the frame rendered alone"
            );
            moved = moved.max(worst_difference(&together, &alone[0]));
        }
        // The camera moved: the frames differ from one another.
        assert!(moved > 1e-3, "{name}: the frames are all alike ({moved})");
    }
}

/// Dhoit's passes are built once a device: a second method of a kind made from the same `Gpu`
/// builds no shader or pipeline, nor do its frames; every method resized, and given another
/// budget where it takes one, renders what a method made at that size and budget renders.
#[test]
fn a_second_method_builds_nothing_and_resized_ones_render_as_fresh_ones() {
    if gpu().is_none() {
        return;
    }
    let size = (48, 36);
    let s = layered_scene();
    let weights = common::committed_weights();
    let app = App::new(&s, size, false);
    let b = Budget::parse("25%").unwrap();
    // The first DKB on the device, and a frame of it: its network's passes and the resolve
    // onto this target format are built on first use.
    let mut first = AllocatedOit::dkb(&app.gpu, size, &weights, b, F32X4).unwrap();
    app.frame(&mut first, &s, &identity());
    let before = gpu::pipelines_built();
    let mut second = AllocatedOit::dkb(&app.gpu, size, &weights, b, F32X4).unwrap();
    let (image, _) = app.frame(&mut second, &s, &identity());
    assert_eq!(
        gpu::pipelines_built(),
        before,
        "the second DKB built passes"
    );
    assert!(!image.is_empty());
    // dhoit's passes on another device are built anew: what the count counts.
    let _other = app_device(false);
    assert!(
        gpu::pipelines_built() > before,
        "a new device's passes are counted"
    );
    // Every method resized, and given another budget where it takes one: as a fresh method
    // made at that size and budget; the methods without a budget refuse one.
    let (w2, h2) = (64, 48);
    let app2 = App::new(&s, (w2, h2), false);
    // The same device's application at the first size.
    let on = (app2.device.clone(), app2.queue.clone(), app2.gpu.fork());
    let app1 = App::on(on, &s, size, false);
    let mut compared = Vec::new();
    for budget in ["25%", "1fpp"] {
        let b2 = Budget::parse(budget).unwrap();
        // Fresh methods made with the budgets the moved ones are given.
        let at = Budgets {
            nodes_per_pixel: 8,
            k: 3,
            rows: 3,
            allocated: b2,
        };
        let fresh = every_method_at(&app2.gpu, (w2, h2), F32X4, at);
        let moved = every_method(&app2.gpu, size, F32X4);
        for (mut fresh, mut moved) in fresh.into_iter().zip(moved) {
            let name = moved.method();
            assert_eq!(name, fresh.method());
            let given = match name {
                "linked-list" => Some("8fpp"),
                "fkb" | "mlab" => Some("3fpp"),
                "dkb" | "vkb" => Some(budget),
                _ => None,
            };
            // A frame at the first size, then the change.
            app1.frame(moved.as_mut(), &s, &identity());
            moved.resize((w2, h2)).unwrap();
            match given {
                Some(g) => moved.set_budget(Budget::parse(g).unwrap()).unwrap(),
                None => assert!(moved.set_budget(b2).is_err(), "{name} took a budget"),
            }
            let (a, _) = app2.frame(moved.as_mut(), &s, &identity());
            let (f, _) = app2.frame(fresh.as_mut(), &s, &identity());
            assert_eq!(a.len(), (w2 * h2) as usize, "{name}");
            assert!(a == f, "{name} at {budget}: resized and rebudgeted");
            compared.push(name);
        }
    }
    // Every method of `every_method` was compared at both budgets (MBOIT where it blends).
    assert!(compared.len() >= 14, "{compared:?}");
}

/// The `Oit` types make every method the registry says an application ships
/// (`Method::in_application`), each once, and none other: what [`every_method`] holds the
/// protocol's tests to (MBOIT where the device blends 32-bit floats).
#[test]
fn every_method_an_application_ships_has_an_oit_type() {
    let Some(g) = gpu() else { return };
    let made: Vec<&str> = every_method(g, (16, 12), F32X4)
        .iter()
        .map(|m| m.method())
        .collect();
    let blends_f32 = g
        .device()
        .features()
        .contains(wgpu::Features::FLOAT32_BLENDABLE);
    let mut want: Vec<&str> = dhoit_runtime::method::Method::those(|m| m.in_application())
        .iter()
        .map(|m| m.name())
        .filter(|&m| blends_f32 || m != "mboit")
        .collect();
    let mut got = made;
    want.sort_unstable();
    got.sort_unstable();
    assert_eq!(got, want, "the application's methods");
}

/// Every method renders on a device opened without timestamps (`TIMESTAMP_QUERY` is
/// optional): the same image, no pass times.
#[test]
fn every_method_renders_without_timestamps() {
    if gpu().is_none() {
        return;
    }
    let size = (48, 36);
    let s = layered_scene();
    let timed = App::new(&s, size, false);
    let untimed = App::on(app_device(false), &s, size, false);
    assert!(
        !untimed
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
    );
    let pairs = every_method(&timed.gpu, size, F32X4)
        .into_iter()
        .zip(every_method(&untimed.gpu, size, F32X4));
    for (mut a, mut b) in pairs {
        let (ia, ra) = timed.frame(a.as_mut(), &s, &identity());
        let (ib, rb) = untimed.frame(b.as_mut(), &s, &identity());
        let name = a.method();
        assert!(worst_difference(&ia, &ib) <= 1e-6, "{name}");
        assert!(!ra.pass_ms.is_empty(), "{name}: timed");
        assert!(rb.pass_ms.is_empty(), "{name}: untimed");
    }
}

/// A frame given textures of another size or format than the method's is refused before
/// anything is recorded, with a typed error naming the texture and both sizes, by every
/// method: each of the three textures of another size alone (the others right), and a target
/// of another format; the right ones record.
#[test]
fn every_method_refuses_textures_of_another_size_or_format() {
    if gpu().is_none() {
        return;
    }
    let s = layered_scene();
    let (small, big) = ((32, 24), (64, 48));
    // The application renders at 64x48; each method was made for 64x48, onto f32 targets or
    // 8-bit ones.
    let app = App::new(&s, big, false);
    let camera = app.camera(&s, &identity());
    let at = |size, label, format, usage| texture(&app.device, size, label, format, usage);
    let sampled = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::RENDER_ATTACHMENT;
    let storage = wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC;
    let textures = |size| {
        [
            at(size, "depth", wgpu::TextureFormat::Depth32Float, sampled),
            at(size, "image", F32X4, sampled),
            at(size, "target", F32X4, storage),
        ]
    };
    let (right, wrong) = (textures(big), textures(small));
    let view = |t: &wgpu::Texture| t.create_view(&Default::default());
    let made = every_method(&app.gpu, big, F32X4)
        .into_iter()
        .zip(every_method(&app.gpu, big, wgpu::TextureFormat::Rgba8Unorm));
    for (mut oit, mut other) in made {
        let name = oit.method();
        for (i, texture) in ["opaque depth", "opaque image", "target"]
            .into_iter()
            .enumerate()
        {
            let views: Vec<wgpu::TextureView> = (0..3)
                .map(|j| view(if j == i { &wrong[j] } else { &right[j] }))
                .collect();
            let frame = FrameTargets {
                depth: &views[0],
                under: &views[1],
                target: &views[2],
            };
            let mut enc = app.device.create_command_encoder(&Default::default());
            let e = oit
                .record(&mut enc, &frame, &mut |_, _| {
                    panic!("{name}: a draw recorded for a frame refused")
                })
                .expect_err("refused");
            match &e {
                dhoit_runtime::Error::Gpu(dhoit_runtime::error::GpuError::FrameTexture {
                    texture: t,
                    ..
                }) => assert_eq!(*t, texture, "{name}: {e}"),
                _ => panic!("{name}, {texture}: {e}"),
            }
            let text = e.to_string();
            assert!(
                text.contains("64x48") && text.contains("32x24"),
                "{name}: {text}"
            );
        }
        let target = app.target(F32X4);
        // The right size: it records.
        let pipelines = app.pipelines(oit.as_ref());
        let mut enc = app.device.create_command_encoder(&Default::default());
        app.record(&mut enc, oit.as_mut(), &pipelines, &camera, &target)
            .unwrap();
        app.queue.submit([enc.finish()]);
        assert!(oit.finished(true).unwrap()[0].error.is_none(), "{name}");
        // The right size, another target format.
        let pipelines = app.pipelines(other.as_ref());
        let mut enc = app.device.create_command_encoder(&Default::default());
        let e = app
            .record(&mut enc, other.as_mut(), &pipelines, &camera, &target)
            .expect_err("refused")
            .to_string();
        assert!(
            e.contains("target") && e.contains("Rgba8Unorm"),
            "{name}: {e}"
        );
        // And the right one records, its image dhoit's resolve onto 8 bits.
        let target8 = app.target(wgpu::TextureFormat::Rgba8Unorm);
        app.record(&mut enc, other.as_mut(), &pipelines, &camera, &target8)
            .unwrap();
        app.queue.submit([enc.finish()]);
        assert!(other.finished(true).unwrap()[0].error.is_none(), "{name}");
    }
}

/// Every method's first frame (no count read back, no `expect`), and the first after a resize,
/// counts its fragments first and is sized for them: at 3 and at 30 fragments a pixel no frame
/// is short, the A-buffer's is exact, DKB's and VKB's keep the F their budget asks for (a
/// quarter of the frame's fragments, or all of them where their pool holds them).
#[test]
fn every_method_s_first_frame_holds_what_its_budget_asks_for_at_3_and_30_fragments_a_pixel() {
    let Some(g) = gpu() else { return };
    let size = (48, 36);
    for n in [3, 30] {
        let mut s = Scene::default();
        for i in 0..n {
            let z = 0.05 + 0.9 * i as f32 / n as f32;
            let c = [(i % 3) as f32 / 2.0, (i % 5) as f32 / 4.0, 0.8, 0.3];
            quad(&mut s, (-1.0, -1.0, 1.0, 1.0), (z, z), c);
        }
        let exact = exact_frame(g, &s, size);
        let total = occupancy_of(&exact).fragments;
        assert_eq!(total, n * (size.0 * size.1) as u64);
        let app = App::new(&s, size, false);
        let on = (app.device.clone(), app.queue.clone(), app.gpu.fork());
        let app_small = App::on(on, &s, (32, 24), false);
        let small = every_method(&app.gpu, (32, 24), F32X4);
        for (mut oit, mut resized) in every_method(&app.gpu, size, F32X4).into_iter().zip(small) {
            let name = oit.method();
            // Resized after a frame of its first size: the first frame of the new size.
            app_small.frame(resized.as_mut(), &s, &identity());
            resized.resize(size).unwrap();
            for (oit, label) in [(&mut oit, "first"), (&mut resized, "resized")] {
                let (image, r) = app.frame(oit.as_mut(), &s, &identity());
                // Sized from its count (a page's would be sized before any: guessed).
                assert!(
                    !r.pool_short && !r.guessed,
                    "{name} at {n} fpp, {label}: {r:?}"
                );
                match name {
                    "abuffer" => {
                        assert!(r.exact, "{name} at {n} fpp, {label}");
                        let worst = worst_difference(&image, &exact.image.data);
                        assert!(worst <= 1e-5, "{name} at {n} fpp, {label}: {worst}");
                    }
                    "dkb" | "vkb" => {
                        let plan = r.plan.unwrap();
                        let f = if plan.exact { total } else { total / 4 };
                        assert_eq!(plan.f, f, "{name} at {n} fpp, {label}: {plan:?}");
                    }
                    _ => {}
                }
            }
        }
    }
}

/// A depth texture of another format than the one the application built its pipelines for
/// (`Oit::depth_stencil`) is refused with a typed error before anything is recorded (wgpu
/// would reject the whole encoder at submission): the encoder stays valid, and no report comes
/// of it.
#[test]
fn a_depth_of_another_format_than_the_pipelines_is_refused_before_recording() {
    if gpu().is_none() {
        return;
    }
    let s = layered_scene();
    let size = (48, 36);
    let app = App::new(&s, size, false);
    let camera = app.camera(&s, &identity());
    for mut oit in every_method(&app.gpu, size, F32X4) {
        let name = oit.method();
        // Built for the application's Depth32Float.
        let pipelines = app.pipelines(oit.as_ref());
        let other = texture(
            &app.device,
            size,
            "app depth 24",
            wgpu::TextureFormat::Depth24Plus,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let (depth, under) = (
            other.create_view(&Default::default()),
            app.under.create_view(&Default::default()),
        );
        let target = app.target(F32X4);
        let target_view = target.create_view(&Default::default());
        let frame = FrameTargets {
            depth: &depth,
            under: &under,
            target: &target_view,
        };
        let mut enc = app.device.create_command_encoder(&Default::default());
        let mut drawn = 0;
        let e = oit
            .record(&mut enc, &frame, &mut |_, _| drawn += 1)
            .expect_err("refused");
        let text = e.to_string();
        assert!(
            matches!(
                e,
                dhoit_runtime::Error::Gpu(dhoit_runtime::error::GpuError::FrameTexture { .. })
            ) && text.contains("Depth24Plus")
                && text.contains("Depth32Float"),
            "{name}: {text}"
        );
        assert_eq!(drawn, 0, "{name}: drew before refusing");
        // Nothing was recorded: the encoder submits, and no frame reports.
        app.queue.submit([enc.finish()]);
        assert!(oit.finished(true).unwrap().is_empty(), "{name}");
        // The right depth records and runs.
        app.record(
            &mut app.device.create_command_encoder(&Default::default()),
            oit.as_mut(),
            &pipelines,
            &camera,
            &target,
        )
        .unwrap();
    }
}

/// Reports come only of frames that ran: a frame recorded into an encoder the application
/// drops, and one whose submission fails (the application's own command after it is invalid,
/// so wgpu rejects the whole encoder), report nothing, and the next frames are sized from the
/// frames that ran.
#[test]
fn reports_come_only_of_frames_that_ran() {
    if gpu().is_none() {
        return;
    }
    let weights = common::committed_weights();
    let s = layered_scene();
    let size = (48, 36);
    let app = App::new(&s, size, false);
    let camera = app.camera(&s, &identity());
    let b = Budget::parse("25%").unwrap();
    let mut oit: Box<dyn Oit> =
        Box::new(AllocatedOit::dkb(&app.gpu, size, &weights, b, F32X4).unwrap());
    let pipelines = app.pipelines(oit.as_ref());
    let target = app.target(F32X4);
    // Frame 0 runs.
    let mut enc = app.device.create_command_encoder(&Default::default());
    app.record(&mut enc, oit.as_mut(), &pipelines, &camera, &target)
        .unwrap();
    app.queue.submit([enc.finish()]);
    let first = oit.finished(true).unwrap();
    assert_eq!(first.iter().map(|r| r.frame).collect::<Vec<_>>(), [0]);
    let bytes = first[0].allocated_bytes;
    // Frame 1 into an encoder never submitted.
    let mut dropped = app.device.create_command_encoder(&Default::default());
    app.record(&mut dropped, oit.as_mut(), &pipelines, &camera, &target)
        .unwrap();
    drop(dropped);
    // Frame 2 into an encoder with an invalid command of the application's after it.
    let mut bad = app.device.create_command_encoder(&Default::default());
    app.record(&mut bad, oit.as_mut(), &pipelines, &camera, &target)
        .unwrap();
    let small = app.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("app small"),
        size: 16,
        usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    bad.copy_buffer_to_buffer(&small, 0, &small, 8, 64);
    let scope = app.device.push_error_scope(wgpu::ErrorFilter::Validation);
    app.queue.submit([bad.finish()]);
    assert!(
        pollster::block_on(scope.pop()).is_some(),
        "the application's invalid copy"
    );
    // Frame 3 runs.
    let mut enc = app.device.create_command_encoder(&Default::default());
    app.record(&mut enc, oit.as_mut(), &pipelines, &camera, &target)
        .unwrap();
    app.queue.submit([enc.finish()]);
    let reports = oit.finished(true).unwrap();
    assert_eq!(
        reports.iter().map(|r| r.frame).collect::<Vec<_>>(),
        [3],
        "{reports:?}"
    );
    let r = &reports[0];
    assert!(!r.pool_short && r.error.is_none(), "{r:?}");
    assert_eq!(r.allocated_bytes, bytes);
}

/// Colours above white in an application's renderer. With `set_hdr(true)` onto an
/// `Rgba16Float` target, three full-frame layers whose colours pass white (a grey one of 0.4,
/// alpha 0.4, in front of one of (8, 3.2, 1.6), alpha 0.4, in front of an opaque (16, 3.2, 6.4))
/// composite to what a hand computation gives, 0.4 x 0.4 + 0.6 x 0.4 x 8 + 0.36 x 16 = 7.84
/// in red (and 2.08, 2.848), within binary16's step, in every method that keeps all three (the
/// A-buffer, the list, FKB with two slots and a tail of one, MLAB merging the last two); the
/// others keep their light above white. The storing methods' frames hold a word more a
/// fragment, node or slot, and no more (no tail sums: an application's fragments are
/// untinted). Off, each colour clamps at white as it is stored (0.76), and onto
/// `Rgba8Unorm` asking for it is refused, naming why.
#[test]
fn an_application_gets_light_above_white_onto_a_float_target() {
    if gpu().is_none() {
        return;
    }
    let (w, h) = (32, 24);
    let mut s = Scene::default();
    common::layer(&mut s, 0.2, [0.4, 0.4, 0.4, 0.4]);
    common::layer(&mut s, 0.5, [8.0, 3.2, 1.6, 0.4]);
    common::layer(&mut s, 0.8, [16.0, 3.2, 6.4, 1.0]);
    let app = App::new(&s, (w, h), false);
    let f16 = wgpu::TextureFormat::Rgba16Float;
    let exact_methods = ["linked-list", "fkb", "abuffer", "mlab"];
    let hdr = every_method(&app.gpu, (w, h), f16);
    let ldr = every_method(&app.gpu, (w, h), f16);
    let px = (w * h) as u64;
    for (mut on, mut off) in hdr.into_iter().zip(ldr) {
        let name = on.method();
        on.set_hdr(true).unwrap();
        // The second frames, whose buffers the first ones' counts sized.
        app.frame(on.as_mut(), &s, &identity());
        app.frame(off.as_mut(), &s, &identity());
        let (bright, report) = app.frame(on.as_mut(), &s, &identity());
        let (clamped, plain) = app.frame(off.as_mut(), &s, &identity());
        for (p, (c, l)) in bright.iter().zip(&clamped).enumerate() {
            if exact_methods.contains(&name) {
                for (i, want) in [7.84f32, 2.08, 2.848].into_iter().enumerate() {
                    assert!(
                        (c[i] - want).abs() <= want * 2f32.powi(-10),
                        "{name}: pixel {p} {c:?}"
                    );
                }
                assert!(
                    (0..3).all(|i| (l[i] - 0.76).abs() <= 1e-3),
                    "{name} off: {l:?}"
                );
            } else {
                assert!(c[0] > 1.5 && c[0] < 16.0, "{name}: pixel {p} {c:?}");
                assert!(l[0] <= 1.0 + 1e-3, "{name} off: pixel {p} {l:?}");
            }
        }
        // A word a node (four a pixel) or a slot (two: no sums in the tails, the glass being
        // untinted); a word a fragment the A-buffer's pool holds (three a pixel here, and its
        // headroom); a word a pool word of DKB's and VKB's.
        let more = report.allocated_bytes - plain.allocated_bytes;
        match name {
            "linked-list" => assert_eq!(more, 4 * 4 * px, "{name}"),
            "fkb" => assert_eq!(more, 4 * 2 * px, "{name}"),
            "wboit" | "mboit" => assert_eq!(more, 0, "{name}"),
            "abuffer" | "mlab" => assert!(more % 4 == 0 && more >= 4 * 3 * px, "{name}"),
            _ => assert!(more > 0, "{name}"),
        }
    }
    let mut eight = KBufferOit::new(&app.gpu, (w, h), 2, wgpu::TextureFormat::Rgba8Unorm).unwrap();
    let e = eight.set_hdr(true).unwrap_err().to_string();
    assert!(
        e.contains("Rgba8Unorm") && e.contains("float target"),
        "{e}"
    );
    eight.set_hdr(false).unwrap();
}
