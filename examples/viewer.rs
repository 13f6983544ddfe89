//! An application's own wgpu renderer with dhoit for its transparency (the budgeted linked list,
//! the fixed k-buffer with `--method fkb`, the exact A-buffer with `--method abuffer`, which
//! draws the transparent geometry twice, or the deep k-buffer with `--method dkb --budget 25%`,
//! whose frame calls the application back to draw into each of its geometry passes, or the
//! blended methods engines ship, `--method wboit` and `--method mboit`, whose passes write
//! dhoit's targets through the application's pipelines, or MLAB, `--method mlab --rows 4`, the
//! A-buffer's two draws with each fragment's submission index), headless: it loads a glTF file (or a
//! built-in scene), draws its opaque and alpha-masked materials with a depth buffer, hands its
//! transparent fragments to dhoit from its own WGSL (`oit_store`, or for the blended methods
//! `oit_targets`), resolves onto its own target over its opaque image, and writes one PNG per
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
//! glass's view-dependent opacity (its face-on opacity instead).

use anyhow::{Context, Result, bail};
use clap::Parser;
use dhoit_runtime::budget::Budget;
use dhoit_runtime::composite::Image;
use dhoit_runtime::composite::{MboitParams, WboitParams, WboitWeight};
use dhoit_runtime::gpu::{
    self, AllocatedOit, BlendedOit, ExactOit, FrameReport, FrameTargets, Gpu, KBufferOit, ListOit,
    Oit, Phase,
};
use dhoit_runtime::mlp::Mlp;
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
    /// geometry drawn twice, to count and to store) or `dkb` (the network decides each pixel's
    /// slots within --budget; the exact A-buffer where that needs no more bytes) or `vkb` (paper
    /// 002's importance maps decide them, as DKB) or `wboit` (weighted blended OIT, McGuire and
    /// Bavoil's eq. 10: two targets, no sort) or `mboit` (--moments power moments: two passes,
    /// needs a device that blends 32-bit floats).
    /// Or `mlab` (--rows blending rows, each pixel's fragments merged in their submission order:
    /// the A-buffer's two draws, each fragment with its triangle's index).
    #[arg(long, default_value = "linked-list", value_parser = clap::builder::PossibleValuesParser::new(dhoit_runtime::method::Method::those(dhoit_runtime::method::Method::in_application).iter().map(|m| m.name())))]
    method: String,
    /// MLAB's blending rows: 1 to 8.
    #[arg(long, default_value_t = 4)]
    rows: u32,
    /// WBOIT's weight function (McGuire and Bavoil): eq7, eq8 or eq9 of the view-space distance
    /// (from each view's planes), or eq10 of the window depth.
    #[arg(long, default_value = "eq10", value_parser = |s: &str| WboitWeight::parse(s).map_err(|e| e.to_string()))]
    wboit_weight: WboitWeight,
    /// MBOIT's power moments: 4, 6 or 8.
    #[arg(long, default_value_t = 4)]
    moments: u32,
    /// DKB's and VKB's budget: bytes (`20MB`), slots a pixel (`2fpp`) or a share of the frame's
    /// fragments (`25%`).
    #[arg(long, default_value = "25%")]
    budget: Budget,
    /// Run DKB or VKB at its budget even where the exact A-buffer needs no more bytes (by default such
    /// a frame is the A-buffer's: a k-buffer never costs more than the exact answer).
    #[arg(long)]
    always_approximate: bool,
    /// DKB's network (safetensors, as `dhoit train` writes it).
    #[arg(long, default_value = "data/weights.safetensors")]
    weights: PathBuf,
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
    /// Open an interactive window where a display exists, instead of writing PNG frames
    /// (needs the viewer built with `--features window`): drag to orbit, 1-8 for the linked
    /// list, FKB, the A-buffer, DKB, VKB, WBOIT, MBOIT and MLAB, +/- for the budget, n for DKB's next network (those
    /// under data/nets), a to toggle --always-approximate, the GPU times in the title.
    #[arg(long)]
    window: bool,
}

const SHADER: &str = r#"
struct Camera { view_proj: mat4x4<f32>, forward: vec4<f32> };
@group(0) @binding(0) var<uniform> camera: Camera;

// The material's base colour texture (a white texel where it has none) and its sampler.
@group(1) @binding(0) var base_color: texture_2d<f32>;
@group(1) @binding(1) var base_sampler: sampler;

struct V {
    @builtin(position) position: vec4<f32>,
    @location(0) color: vec4<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) @interpolate(flat) cutoff: f32,
    // |n . v| of the triangle (its normal against the camera's forward direction).
    @location(3) @interpolate(flat) facing: f32,
    // The triangle's index in the application's submission (MLAB's order).
    @location(4) @interpolate(flat) order: u32,
};

@vertex
fn vs(
    @location(0) p: vec3<f32>,
    @location(1) c: vec4<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) cutoff: f32,
    @location(4) normal: vec3<f32>,
    @builtin(vertex_index) vertex: u32,
) -> V {
    let facing = abs(dot(normal, camera.forward.xyz));
    return V(camera.view_proj * vec4<f32>(p, 1.0), c, uv, cutoff, facing, vertex / 3u);
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

"#;

/// The transparent fragment entry of the methods that store fragments.
const STORE: &str = r#"
@fragment
fn fs_transparent(in: V) {
    // dhoit: the fragment goes to its method (the facing is VKB's; the others ignore it)
    oit_store_facing(in.position, shaded(in), in.facing);
}
"#;

/// MLAB's: the fragment with its submission index (its triangle's, in the vertex buffer).
const ORDERED: &str = r#"
@fragment
fn fs_transparent(in: V) {
    // dhoit: MLAB merges a pixel's fragments in this order
    oit_store_ordered(in.position, shaded(in), in.order);
}
"#;

/// The blended methods': the fragment returns into dhoit's targets.
const BLEND: &str = r#"
@fragment
fn fs_transparent(in: V) -> OitTargets {
    // dhoit: what its pass writes into its targets (discarded where it discards)
    return oit_targets(in.position, shaded(in));
}
"#;

/// One frame from `cam` drawn, copied into `staging` (rows of `row` bytes) and read back: its
/// image and its passes' times (waiting for it, as a headless run does).
fn draw_and_read(
    app: &App,
    frame: &Frame,
    cam: &Camera,
    (staging, row): (&wgpu::Buffer, u32),
    (w, h): (u32, u32),
) -> Result<(Image, [f64; 4])> {
    let mut enc = app.draw(frame, cam)?;
    enc.copy_texture_to_buffer(
        frame.target.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: staging,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(h),
            },
        },
        frame.target.size(),
    );
    app.queue.submit([enc.finish()]);
    staging.slice(..).map_async(wgpu::MapMode::Read, |r| {
        r.expect("the readback maps");
    });
    let ms = app.pass_ms(frame, true)?;
    let img = {
        let data = staging.slice(..).get_mapped_range()?;
        let floats: &[f32] = bytemuck::cast_slice(&data);
        let pixels = (0..h as usize)
            .flat_map(|y| {
                (0..w as usize).map(move |x| {
                    let i = y * row as usize / 4 + 4 * x;
                    [floats[i], floats[i + 1], floats[i + 2]]
                })
            })
            .collect();
        Image {
            width: w,
            height: h,
            data: pixels,
        }
    };
    staging.unmap();
    Ok((img, ms))
}

fn main() -> Result<()> {
    let a = Args::parse();
    let (w, h) = (a.res.width, a.res.height);
    let method = Method::of(&a)?;
    // DKB's networks: --weights, then (for the window's `n`) the smaller ones that ship.
    let weights = Mlp::load(&a.weights);
    if let (Method::Dkb { .. }, Err(e)) = (method, &weights) {
        bail!("--method dkb: {e}");
    }
    let mut networks: Vec<(String, Mlp)> = weights
        .into_iter()
        .map(|m| (a.weights.display().to_string(), m))
        .collect();
    for net in ["16-8", "32-16", "64-32"] {
        let path = PathBuf::from(format!("data/nets/{net}/weights.safetensors"));
        if let (true, Ok(m)) = (a.window, Mlp::load(&path)) {
            networks.push((net.to_string(), m));
        }
    }
    let s = scene::load(&a.scene, Opacity::Native)?;
    if !a.window {
        dhoit_runtime::tensors::create_folder(&a.out)?;
    }
    // A window needs its display before anything else is built.
    #[cfg(feature = "window")]
    let event_loop = match a.window {
        true => Some(window::event_loop()?),
        false => None,
    };
    #[cfg(not(feature = "window"))]
    if a.window {
        bail!("--window needs the viewer built with `--features window`");
    }
    // The application's device, with what dhoit needs on top.
    let instance = wgpu::Instance::default();
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))
        .context("no GPU adapter")?;
    // MBOIT adds into 32-bit float targets: blending them where the adapter can, and its
    // colour attachments' bytes a sample (eight moments take 36).
    // dhoit's optional features where the adapter has them (pass times; MBOIT's blending).
    let optional = adapter.features() & gpu::optional_features();
    let limits = wgpu::Limits {
        max_color_attachment_bytes_per_sample: adapter
            .limits()
            .max_color_attachment_bytes_per_sample,
        ..gpu::required_limits() // dhoit: its limits
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_features: gpu::required_features() | optional, // dhoit: its features
        required_limits: limits,
        ..Default::default()
    }))?;
    println!("{} on {}", s.name, adapter.get_info().name);
    // dhoit: its passes on the application's device, built once.
    let dhoit = Gpu::on_device(device.clone(), queue.clone(), &adapter.get_info())?;
    let app = App::new(device, queue, dhoit, s, networks);
    #[cfg(feature = "window")]
    if let Some(event_loop) = event_loop {
        return window::run(event_loop, &instance, &adapter, app, method, (w, h));
    }
    let frame = app.frame(method, (w, h))?;
    let row = (16 * w).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let staging = app.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: row as u64 * h as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    for v in 0..a.views {
        let cam = Camera::orbit(&app.scene, v, a.views, (w, h));
        // A frame's buffers are sized from the counts of the frames before (dhoit reads them
        // back without waiting): the first, or one after a view of fewer fragments, may be short
        // of its pool. Its report says so; it is drawn again, sized from its own count.
        let mut again = 0;
        let (img, ms) = loop {
            let (img, ms) = draw_and_read(&app, &frame, &cam, (&staging, row), (w, h))?;
            let short = frame.last.borrow().as_ref().is_some_and(|r| r.pool_short);
            if !short || again == 1 {
                break (img, ms);
            }
            again += 1;
            println!("view {v}: short of its pool (sized before its count): drawn again");
        };
        let path = a.out.join(format!("view{v}.png"));
        dhoit_runtime::image_io::write_image(&path, &img)?;
        let dkb = match ms[3] {
            0.0 => String::new(),
            c => format!(", dhoit's compute {c:.2} ms"),
        };
        println!(
            "view {v}: opaque {:.2} ms, transparent {:.2} ms{dkb}, resolve {:.2} ms -> {}{}",
            ms[0],
            ms[1],
            ms[2],
            path.display(),
            app.exact_note(&frame)
        );
    }
    println!(
        "{}: {} bytes on the device",
        app.describe(method),
        frame.oit.borrow().allocated_bytes()
    );
    Ok(())
}

/// dhoit's method and its budget, as the arguments (or the window's keys) choose them.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Method {
    List {
        fpp: f64,
        sorted: u32,
    },
    Fkb {
        k: u32,
    },
    Exact,
    /// The budget, which of the application's networks, and whether it runs where the exact
    /// A-buffer is no dearer.
    Dkb {
        budget: Budget,
        net: usize,
        always: bool,
    },
    /// VKB: the budget, and whether it runs where the exact A-buffer is no dearer.
    Vkb {
        budget: Budget,
        always: bool,
    },
    /// Weighted blended OIT with this weight function.
    Wboit {
        weight: WboitWeight,
    },
    /// Moment-based OIT with this many power moments.
    Mboit {
        moments: u32,
    },
    /// MLAB with this many blending rows.
    Mlab {
        rows: u32,
    },
}

impl Method {
    fn of(a: &Args) -> Result<Method> {
        if !(a.fpp.is_finite() && a.fpp > 0.0) {
            bail!(
                "--fpp is a positive number of fragments a pixel, not {}",
                a.fpp
            );
        }
        Ok(match a.method.as_str() {
            "abuffer" => Method::Exact,
            "fkb" => Method::Fkb { k: a.k },
            "dkb" => Method::Dkb {
                budget: a.budget,
                net: 0,
                always: a.always_approximate,
            },
            "vkb" => Method::Vkb {
                budget: a.budget,
                always: a.always_approximate,
            },
            "wboit" => Method::Wboit {
                weight: a.wboit_weight,
            },
            "mlab" => Method::Mlab { rows: a.rows },
            "mboit" => {
                MboitParams::with_moments(a.moments)?;
                Method::Mboit { moments: a.moments }
            }
            _ => Method::List {
                fpp: a.fpp,
                sorted: a.sorted,
            },
        })
    }

    fn describe(&self) -> String {
        match self {
            Method::Exact => "the exact A-buffer".into(),
            Method::Dkb { budget, .. } => format!("DKB at {budget}"),
            Method::Vkb { budget, .. } => format!("VKB at {budget}"),
            Method::Fkb { k } => format!("FKB, {k} slots a pixel"),
            Method::Wboit { weight } => format!("WBOIT ({})", weight.name()),
            Method::Mboit { moments } => format!("MBOIT, {moments} power moments"),
            Method::Mlab { rows } => format!("MLAB, {rows} rows"),
            Method::List { fpp, sorted } => {
                format!("linked list, {fpp} fragments a pixel of pool, the nearest {sorted} sorted")
            }
        }
    }

    /// dhoit: the method on the application's device (`gpu`: dhoit's passes, built once), for a
    /// frame of `(w, h)` seen by `cam` (WBOIT's planes: an orbit keeps its distance), DKB with
    /// one of `networks`. One protocol whatever the method: [`Oit`].
    fn build(
        &self,
        gpu: &Gpu,
        (w, h): (u32, u32),
        cam: &Camera,
        networks: &[(String, Mlp)],
    ) -> Result<Box<dyn Oit>> {
        Ok(match *self {
            Method::Dkb {
                budget,
                net,
                always,
            } => {
                let (_, weights) = networks.get(net).context("no network for DKB")?;
                let dkb = AllocatedOit::dkb(gpu, (w, h), weights, budget, RGBA)?;
                Box::new(dkb.exact_when_cheaper(!always))
            }
            Method::Vkb { budget, always } => {
                let params = dhoit_runtime::importance::VkbParams::default();
                let vkb = AllocatedOit::vkb(gpu, (w, h), params, budget, RGBA)?;
                Box::new(vkb.exact_when_cheaper(!always))
            }
            Method::Exact => Box::new(ExactOit::new(gpu, (w, h), RGBA)?),
            Method::Mlab { rows } => Box::new(ExactOit::mlab(gpu, (w, h), rows, RGBA)?),
            Method::Wboit { weight } => {
                let params = WboitParams::for_camera(weight, cam);
                Box::new(BlendedOit::wboit(gpu, (w, h), params, RGBA)?)
            }
            Method::Mboit { moments } => {
                let params = MboitParams::with_moments(moments)?;
                Box::new(BlendedOit::mboit(gpu, (w, h), params, RGBA)?)
            }
            Method::Fkb { k } => Box::new(KBufferOit::new(gpu, (w, h), k, RGBA)?),
            Method::List { fpp, sorted } => {
                let nodes = (fpp * (w as f64 * h as f64)).ceil() as u64;
                Box::new(ListOit::new(gpu, (w, h), nodes, sorted, RGBA)?)
            }
        })
    }
}

/// One draw: a material, its first vertex, its vertices, whether it is transparent.
struct Draw {
    material: usize,
    first: u32,
    vertices: u32,
    transparent: bool,
}

/// What the application keeps whatever dhoit's method and the frame's size: its device, the
/// scene's vertices, its camera and its materials.
struct App {
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// dhoit: its passes on this device, built once and shared by every method made from it.
    gpu: Gpu,
    scene: scene::Scene,
    vertices: wgpu::Buffer,
    camera: wgpu::Buffer,
    own_layout: wgpu::BindGroupLayout,
    own_group: wgpu::BindGroup,
    material_layout: wgpu::BindGroupLayout,
    material_groups: Vec<wgpu::BindGroup>,
    draws: Vec<Draw>,
    /// DKB's networks, by name.
    networks: Vec<(String, Mlp)>,
}

/// What depends on the method and the size: dhoit's method, the pipelines built with its
/// modules (one a phase), the frame's textures and the opaque pass's timestamps.
struct Frame {
    oit: std::cell::RefCell<Box<dyn Oit>>,
    opaque_pipeline: wgpu::RenderPipeline,
    /// One transparent pipeline a phase of the method.
    transparent_pipelines: Vec<(Phase, wgpu::RenderPipeline)>,
    image_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    target: wgpu::Texture,
    target_view: wgpu::TextureView,
    /// The opaque pass's timestamps, where the device has them.
    queries: Option<wgpu::QuerySet>,
    resolved: wgpu::Buffer,
    times: wgpu::Buffer,
    /// dhoit's last report of a frame that has run.
    last: std::cell::RefCell<Option<FrameReport>>,
}

/// The format of the application's images (opaque and resolved).
const RGBA: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// The format of its opaque depth.
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The application's vertices: position, colour (vertex x base colour; glass at its face-on
/// opacity), texture coordinates, the alpha cutoff (MASK; 0 for OPAQUE) and the face's normal, 13
/// floats each, by material, opaque and masked materials first: one draw a material.
fn vertices_by_material(s: &scene::Scene) -> (Vec<f32>, Vec<Draw>) {
    let triangles = s.positions.len() / 3;
    let mut order: Vec<usize> = (0..triangles).collect();
    let material = |t: usize| s.triangle_material[t] as usize;
    order.sort_by_key(|&t| (s.materials[material(t)].transparent(), material(t)));
    let mut all = Vec::<f32>::new();
    let mut draws: Vec<Draw> = Vec::new();
    for &t in &order {
        let m = &s.materials[material(t)];
        match draws.last_mut() {
            Some(d) if d.material == material(t) => d.vertices += 3,
            _ => draws.push(Draw {
                material: material(t),
                first: (all.len() / 13) as u32,
                vertices: 3,
                transparent: m.transparent(),
            }),
        }
        // The triangle's geometric normal, for its facing.
        let [p0, p1, p2] = [0, 1, 2].map(|i| s.positions[3 * t + i]);
        let n = (p1 - p0).cross(p2 - p0).normalize_or_zero();
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
            all.extend_from_slice(&[
                p.x, p.y, p.z, c[0], c[1], c[2], c[3], uv[0], uv[1], cutoff, n.x, n.y, n.z,
            ]);
        }
    }
    (all, draws)
}

/// Each material's base colour texture (white where it has none) and sampler, its own bind
/// group of `layout`.
fn material_groups(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    s: &scene::Scene,
    layout: &wgpu::BindGroupLayout,
) -> Vec<wgpu::BindGroup> {
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
    s.materials
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
                layout,
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
        .collect()
}

/// The application's pipeline of `entry` in `module` (vertex entry `vs`), over the 13-float
/// vertices of [`vertices_by_material`].
fn render_pipeline(
    device: &wgpu::Device,
    (module, entry): (&wgpu::ShaderModule, &str),
    layout: &wgpu::PipelineLayout,
    targets: &[Option<wgpu::ColorTargetState>],
    depth_stencil: wgpu::DepthStencilState,
) -> wgpu::RenderPipeline {
    let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x4, 2 => Float32x2, 3 => Float32, 4 => Float32x3];
    let buffers = [Some(wgpu::VertexBufferLayout {
        array_stride: 52,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &attributes,
    })];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(entry),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &buffers,
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(depth_stencil),
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
}

/// The opaque pass's timestamps (where the device has them), the buffer they resolve into and
/// its readback.
fn opaque_pass_timer(
    device: &wgpu::Device,
) -> (Option<wgpu::QuerySet>, wgpu::Buffer, wgpu::Buffer) {
    let timed = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let queries = timed.then(|| {
        device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("opaque pass time"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        })
    });
    let buffer = |label, usage| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: 16,
            usage,
            mapped_at_creation: false,
        })
    };
    let resolved = buffer(
        "opaque pass time",
        wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
    );
    let times = buffer(
        "opaque pass time readback",
        wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
    );
    (queries, resolved, times)
}

/// The application's frame textures at `(w, h)`: its opaque image and depth (drawn, then read
/// by dhoit), and the target dhoit resolves onto (copied out headless, or drawn onto the
/// window's surface).
fn frame_textures(device: &wgpu::Device, (w, h): (u32, u32)) -> [wgpu::Texture; 3] {
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
    let use_both = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
    let image = texture("opaque image", RGBA, use_both);
    let depth = texture("opaque depth", DEPTH, use_both);
    // Copied out (headless) or drawn onto the window's surface.
    let target = texture(
        "target",
        RGBA,
        wgpu::TextureUsages::STORAGE_BINDING
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::TEXTURE_BINDING,
    );
    [image, depth, target]
}

impl App {
    fn new(
        device: wgpu::Device,
        queue: wgpu::Queue,
        gpu: Gpu,
        s: scene::Scene,
        networks: Vec<(String, Mlp)>,
    ) -> App {
        let (all, draws) = vertices_by_material(&s);
        let vertices = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vertices"),
            size: (4 * all.len()).max(16) as u64,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(&vertices, 0, bytemuck::cast_slice(&all));
        let camera = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("camera"),
            size: 80,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
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
        let material_groups = material_groups(&device, &queue, &s, &material_layout);
        App {
            device,
            queue,
            gpu,
            scene: s,
            vertices,
            camera,
            own_layout,
            own_group,
            material_layout,
            material_groups,
            draws,
            networks,
        }
    }

    /// The method, and for DKB its network.
    fn describe(&self, method: Method) -> String {
        match method {
            Method::Dkb { net, .. } => {
                let name = self.networks.get(net).map_or("?", |n| n.0.as_str());
                format!("{}, network {name}", method.describe())
            }
            _ => method.describe(),
        }
    }

    /// dhoit's method at `(w, h)`, the pipelines with its modules and the frame's textures.
    fn frame(&self, method: Method, size: (u32, u32)) -> Result<Frame> {
        let device = &self.device;
        let cam = Camera::orbit(&self.scene, 0, 4, size);
        let oit = method.build(&self.gpu, size, &cam, &self.networks)?;
        // dhoit: the module a phase gives (its bindings at group 2, its store function), then
        // the application's shaders and its transparent entry.
        let entry = match oit.method() {
            "wboit" | "mboit" => BLEND,
            "mlab" => ORDERED,
            _ => STORE,
        };
        let modules: Vec<wgpu::ShaderModule> = oit
            .phases()
            .iter()
            .map(|&phase| {
                device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("viewer"),
                    source: wgpu::ShaderSource::Wgsl(
                        (oit.store_module(phase, 2) + SHADER + entry).into(),
                    ),
                })
            })
            .collect();
        let opaque_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("viewer opaque"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let [image, depth, target] = frame_textures(device, size);
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let layout = |groups: &[Option<&wgpu::BindGroupLayout>]| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: None,
                bind_group_layouts: groups,
                immediate_size: 0,
            })
        };
        let opaque_layout = layout(&[Some(&self.own_layout), Some(&self.material_layout)]);
        let pipeline = |module: &wgpu::ShaderModule,
                        layout: &wgpu::PipelineLayout,
                        entry: &str,
                        targets: &[Option<wgpu::ColorTargetState>],
                        depth_stencil: wgpu::DepthStencilState| {
            render_pipeline(device, (module, entry), layout, targets, depth_stencil)
        };
        let opaque_pipeline = pipeline(
            &opaque_module,
            &opaque_layout,
            "fs_opaque",
            &[Some(wgpu::ColorTargetState {
                format: RGBA,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
            wgpu::DepthStencilState {
                format: DEPTH,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            },
        );
        // dhoit: each phase's pipeline has dhoit's group beside the application's, dhoit's
        // colour targets (the blended methods'; none for the others) and its depth state
        // (the opaque depth attached read-only).
        let transparent_pipelines = oit
            .phases()
            .iter()
            .zip(&modules)
            .map(|(&phase, module)| {
                let layout = layout(&[
                    Some(&self.own_layout),
                    Some(&self.material_layout),
                    Some(oit.bind_group_layout(phase)),
                ]);
                let targets = oit.color_targets(phase);
                let depth = oit.depth_stencil(DEPTH);
                (
                    phase,
                    pipeline(module, &layout, "fs_transparent", &targets, depth),
                )
            })
            .collect();
        let (queries, resolved, times) = opaque_pass_timer(device);
        Ok(Frame {
            oit: std::cell::RefCell::new(oit),
            opaque_pipeline,
            transparent_pipelines,
            image_view: view(&image),
            depth_view: view(&depth),
            target_view: view(&target),
            target,
            queries,
            resolved,
            times,
            last: Default::default(),
        })
    }

    /// One frame from `cam` recorded into a new encoder: the opaque pass, then dhoit's frame,
    /// which calls the transparent draws back for each of its geometry passes and resolves
    /// onto `frame.target`. Nothing is submitted or waited for: the caller submits (after its
    /// copy or presentation).
    fn draw(&self, frame: &Frame, cam: &Camera) -> Result<wgpu::CommandEncoder> {
        let mut camera = cam.view_proj.to_cols_array().to_vec();
        camera.extend_from_slice(&cam.forward.extend(0.0).to_array());
        self.queue
            .write_buffer(&self.camera, 0, bytemuck::cast_slice(&camera));
        let mut enc = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("opaque"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &frame.image_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::WHITE),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &frame.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: frame
                    .queries
                    .as_ref()
                    .map(|q| wgpu::RenderPassTimestampWrites {
                        query_set: q,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: Some(1),
                    }),
                ..Default::default()
            });
            pass.set_pipeline(&frame.opaque_pipeline);
            pass.set_bind_group(0, &self.own_group, &[]);
            pass.set_vertex_buffer(0, self.vertices.slice(..));
            for d in self.draws.iter().filter(|d| !d.transparent) {
                pass.set_bind_group(1, &self.material_groups[d.material], &[]);
                pass.draw(d.first..d.first + d.vertices, 0..1);
            }
        }
        if let Some(q) = &frame.queries {
            enc.resolve_query_set(q, 0..2, &frame.resolved, 0);
            enc.copy_buffer_to_buffer(&frame.resolved, 0, &frame.times, 0, 16);
        }
        // dhoit: the frame's textures: the opaque depth (the occluder), the opaque image
        // (what the transparency composites over), the target.
        let targets = FrameTargets {
            depth: &frame.depth_view,
            under: &frame.image_view,
            target: &frame.target_view,
        };
        // dhoit: its passes into this encoder; for each geometry pass it opens, the
        // application's transparent draws with dhoit's group at 2.
        frame
            .oit
            .borrow_mut()
            .record(&mut enc, &targets, &mut |pass, draw| {
                let pipeline = &frame
                    .transparent_pipelines
                    .iter()
                    .find(|(p, _)| *p == draw.phase)
                    .expect("a pipeline for each of dhoit's phases")
                    .1;
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, &self.own_group, &[]);
                pass.set_bind_group(2, draw.group, &[]); // dhoit: its group for the draws
                pass.set_vertex_buffer(0, self.vertices.slice(..));
                for d in self.draws.iter().filter(|d| d.transparent) {
                    pass.set_bind_group(1, &self.material_groups[d.material], &[]);
                    pass.draw(d.first..d.first + d.vertices, 0..1);
                }
            })?;
        Ok(enc)
    }

    /// The GPU times of the last frame that has run (waiting for it with `wait`): opaque,
    /// transparent (the application's draws in dhoit's geometry passes), resolve and dhoit's
    /// compute passes, in milliseconds.
    fn pass_ms(&self, frame: &Frame, wait: bool) -> Result<[f64; 4]> {
        // dhoit: reports of the frames that have run (read without waiting unless asked).
        let reports = frame.oit.borrow_mut().finished(wait)?;
        if let Some(r) = reports.into_iter().last() {
            if let Some(e) = r.error {
                return Err(e.into());
            }
            *frame.last.borrow_mut() = Some(FrameReport { error: None, ..r });
        }
        let mut opaque = 0.0;
        if wait && frame.queries.is_some() {
            frame
                .times
                .slice(..)
                .map_async(wgpu::MapMode::Read, |r| r.expect("the times map"));
            self.device.poll(wgpu::PollType::wait_indefinitely())?;
            {
                let data = frame.times.slice(..).get_mapped_range()?;
                let stamps: &[u64] = bytemuck::cast_slice(&data);
                let period = self.queue.get_timestamp_period() as f64 * 1e-6;
                opaque = stamps[1].saturating_sub(stamps[0]) as f64 * period;
            }
            frame.times.unmap();
        }
        let last = frame.last.borrow();
        let passes = last.as_ref().map_or(&[][..], |r| &r.pass_ms[..]);
        let sum = |names: &[&str], of: bool| {
            let p = passes.iter().filter(|(n, _)| names.contains(n) == of);
            p.map(|(_, t)| t).sum::<f64>()
        };
        let geometry = [
            "count",
            "store",
            "features",
            "capture",
            "accumulate",
            "moments",
        ];
        let resolve = [
            "resolve",
            "sort and blend",
            "mlab blend",
            "wboit composite",
            "mboit composite",
        ];
        Ok([
            opaque,
            sum(&geometry, true),
            sum(&resolve, true),
            sum(&[&geometry[..], &resolve[..]].concat(), false),
        ])
    }

    /// Whether the last frame read back was exact (DKB, VKB: their pool held every fragment).
    fn exact_note(&self, frame: &Frame) -> &'static str {
        let last = frame.last.borrow();
        match (frame.oit.borrow().method(), last.as_ref()) {
            ("dkb" | "vkb", Some(r)) if r.exact => " (exact: its pool held every fragment)",
            _ => "",
        }
    }
}

/// `--window`: the same frames in an interactive window (built with `--features window`).
/// Drag with the left button to orbit; `1` to `8` switch to the linked list, FKB, the A-buffer,
/// DKB, VKB, WBOIT, MBOIT and MLAB; `+` and `-` double and halve the budget (the list's
/// fragments a pixel, FKB's k, DKB's budget, MLAB's rows; MBOIT's moments 4, 6, 8); `n` takes DKB's next network, `a` toggles --always-approximate;
/// `Esc` or `q` quits. The title shows the method, the GPU time of each pass and the frame
/// time. The image is resolved as headless, then drawn onto the window's surface.
#[cfg(feature = "window")]
mod window {
    use super::{App, Frame, Method, RGBA, WboitWeight};
    use anyhow::{Context, Result, anyhow};
    use dhoit_runtime::budget::Budget;
    use dhoit_runtime::scene::Camera;
    use std::sync::Arc;
    use winit::application::ApplicationHandler;
    use winit::event::{ElementState, MouseButton, WindowEvent};
    use winit::event_loop::{ActiveEventLoop, EventLoop};
    use winit::keyboard::{Key, NamedKey};
    use winit::window::{Window, WindowId};

    /// The display's event loop, or an error saying there is none.
    pub fn event_loop() -> Result<EventLoop<()>> {
        EventLoop::new().context(
            "--window found no display (DISPLAY or WAYLAND_DISPLAY); without --window the \
             viewer writes its frames as PNG files",
        )
    }

    /// Draws the resolved image onto the surface: one triangle over the window, a texel each.
    const PRESENT: &str = r#"
@group(0) @binding(0) var image: texture_2d<f32>;
@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}
@fragment
fn fs(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    return vec4<f32>(textureLoad(image, vec2<i32>(p.xy), 0).rgb, 1.0);
}
"#;

    struct Shown {
        window: Arc<Window>,
        surface: wgpu::Surface<'static>,
        config: wgpu::SurfaceConfiguration,
        present: wgpu::RenderPipeline,
        frame: Frame,
        group: wgpu::BindGroup,
    }

    struct Viewer<'a> {
        instance: &'a wgpu::Instance,
        adapter: &'a wgpu::Adapter,
        app: App,
        method: Method,
        size: (u32, u32),
        shown: Option<Shown>,
        azimuth: f32,
        elevation: f32,
        drag: Option<(f64, f64)>,
        cursor: (f64, f64),
        last: std::time::Instant,
        error: Option<anyhow::Error>,
    }

    pub fn run(
        event_loop: EventLoop<()>,
        instance: &wgpu::Instance,
        adapter: &wgpu::Adapter,
        app: App,
        method: Method,
        size: (u32, u32),
    ) -> Result<()> {
        let mut viewer = Viewer {
            instance,
            adapter,
            app,
            method,
            size,
            shown: None,
            azimuth: 0.5,
            elevation: 25f32.to_radians(),
            drag: None,
            cursor: (0.0, 0.0),
            last: std::time::Instant::now(),
            error: None,
        };
        event_loop.run_app(&mut viewer)?;
        viewer.error.map_or(Ok(()), Err)
    }

    impl Viewer<'_> {
        fn open(&mut self, el: &ActiveEventLoop) -> Result<()> {
            let (w, h) = self.size;
            let attributes = Window::default_attributes()
                .with_title("dhoit viewer")
                .with_inner_size(winit::dpi::PhysicalSize::new(w, h));
            let window = Arc::new(el.create_window(attributes)?);
            let surface = self.instance.create_surface(window.clone())?;
            let size = window.inner_size();
            let mut config = surface
                .get_default_config(self.adapter, size.width.max(1), size.height.max(1))
                .ok_or_else(|| anyhow!("the adapter cannot present to this window"))?;
            let caps = surface.get_capabilities(self.adapter);
            // The image is linear: an sRGB surface encodes it as the PNG files are.
            if let Some(&f) = caps.formats.iter().find(|f| f.is_srgb()) {
                config.format = f;
            }
            surface.configure(&self.app.device, &config);
            let device = &self.app.device;
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("present"),
                source: wgpu::ShaderSource::Wgsl(PRESENT.into()),
            });
            let present = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("present"),
                layout: None,
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs"),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: Default::default(),
                depth_stencil: None,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs"),
                    compilation_options: Default::default(),
                    targets: &[Some(config.format.into())],
                }),
                multiview_mask: None,
                cache: None,
            });
            self.size = (config.width, config.height);
            let frame = self.app.frame(self.method, self.size)?;
            let group = present_group(device, &present, &frame);
            self.shown = Some(Shown {
                window,
                surface,
                config,
                present,
                frame,
                group,
            });
            Ok(())
        }

        /// The method or size changed: dhoit's object and the frame's textures anew.
        fn rebuild(&mut self) -> Result<()> {
            let Some(shown) = &mut self.shown else {
                return Ok(());
            };
            shown.frame = self.app.frame(self.method, self.size)?;
            shown.group = present_group(&self.app.device, &shown.present, &shown.frame);
            Ok(())
        }

        fn redraw(&mut self) -> Result<()> {
            let Some(shown) = &self.shown else {
                return Ok(());
            };
            let texture = match shown.surface.get_current_texture() {
                wgpu::CurrentSurfaceTexture::Success(t)
                | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
                wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                    shown.surface.configure(&self.app.device, &shown.config);
                    return Ok(());
                }
                _ => return Ok(()),
            };
            let (w, h) = self.size;
            let cam = Camera::orbit_at(&self.app.scene, self.azimuth, self.elevation, (w, h));
            let mut enc = self.app.draw(&shown.frame, &cam)?;
            {
                let view = texture.texture.create_view(&Default::default());
                let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("present"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    ..Default::default()
                });
                pass.set_pipeline(&shown.present);
                pass.set_bind_group(0, &shown.group, &[]);
                pass.draw(0..3, 0..1);
            }
            self.app.queue.submit([enc.finish()]);
            shown.window.pre_present_notify();
            self.app.queue.present(texture);
            // dhoit: the times of the last frame that has run, read without waiting.
            let ms = self.app.pass_ms(&shown.frame, false)?;
            let now = std::time::Instant::now();
            let frame_ms = now.duration_since(self.last).as_secs_f64() * 1e3;
            self.last = now;
            shown.window.set_title(&format!(
                "dhoit viewer: {}, {w}x{h}: opaque {:.2} ms, transparent {:.2} ms, dhoit's compute \
                 {:.2} ms, resolve {:.2} ms (GPU); frame {frame_ms:.1} ms{}",
                self.app.describe(self.method),
                ms[0],
                ms[1],
                ms[3],
                ms[2],
                self.app.exact_note(&shown.frame)
            ));
            shown.window.request_redraw();
            Ok(())
        }

        /// The keys: a method, a budget twice or half as large; whether to rebuild.
        fn key(&mut self, el: &ActiveEventLoop, key: &Key) -> bool {
            let m = self.method;
            self.method = match key.as_ref() {
                Key::Named(NamedKey::Escape) | Key::Character("q") => {
                    el.exit();
                    return false;
                }
                Key::Character("1") => Method::List {
                    fpp: 4.0,
                    sorted: dhoit_runtime::composite::LIST_SORTED,
                },
                Key::Character("2") => Method::Fkb { k: 4 },
                Key::Character("3") => Method::Exact,
                Key::Character("4") if !self.app.networks.is_empty() => Method::Dkb {
                    budget: Budget::Share(250_000),
                    net: 0,
                    always: false,
                },
                Key::Character("5") => Method::Vkb {
                    budget: Budget::Share(250_000),
                    always: false,
                },
                Key::Character("6") => Method::Wboit {
                    weight: WboitWeight::Eq10,
                },
                Key::Character("7") => Method::Mboit { moments: 4 },
                Key::Character("8") => Method::Mlab { rows: 4 },
                Key::Character("n") => match m {
                    Method::Dkb {
                        budget,
                        net,
                        always,
                    } => Method::Dkb {
                        budget,
                        net: (net + 1) % self.app.networks.len().max(1),
                        always,
                    },
                    _ => m,
                },
                Key::Character("a") => match m {
                    Method::Dkb {
                        budget,
                        net,
                        always,
                    } => Method::Dkb {
                        budget,
                        net,
                        always: !always,
                    },
                    Method::Vkb { budget, always } => Method::Vkb {
                        budget,
                        always: !always,
                    },
                    _ => m,
                },
                Key::Character("+" | "=") => resized(m, true),
                Key::Character("-") => resized(m, false),
                _ => m,
            };
            self.method != m
        }
    }

    /// `m` with its budget doubled (`up`) or halved: the list's fragments a pixel, FKB's k,
    /// DKB's and VKB's budget.
    fn resized(m: Method, up: bool) -> Method {
        let by = if up { 2.0 } else { 0.5 };
        match m {
            Method::List { fpp, sorted } => Method::List {
                fpp: if up {
                    (fpp * 2.0).min(64.0)
                } else {
                    (fpp / 2.0).max(0.125)
                },
                sorted,
            },
            Method::Fkb { k } => Method::Fkb {
                k: if up { (k * 2).min(64) } else { (k / 2).max(1) },
            },
            Method::Dkb {
                budget,
                net,
                always,
            } => Method::Dkb {
                budget: scaled(budget, by),
                net,
                always,
            },
            Method::Vkb { budget, always } => Method::Vkb {
                budget: scaled(budget, by),
                always,
            },
            Method::Exact | Method::Wboit { .. } => m,
            Method::Mlab { rows } => Method::Mlab {
                rows: if up {
                    (rows * 2).min(8)
                } else {
                    (rows / 2).max(1)
                },
            },
            Method::Mboit { moments } => Method::Mboit {
                moments: if up {
                    (moments + 2).min(8)
                } else {
                    moments.saturating_sub(2).max(4)
                },
            },
        }
    }

    /// A budget `by` times as large (a share at most the whole frame).
    fn scaled(b: Budget, by: f64) -> Budget {
        match b {
            Budget::Share(ppm) => Budget::Share(((ppm as f64 * by) as u32).clamp(1_000, 1_000_000)),
            Budget::SlotsPerPixel(f) => Budget::SlotsPerPixel((f * by).clamp(0.0625, 64.0)),
            Budget::Bytes(n) => Budget::Bytes(((n as f64 * by) as u64).max(1 << 20)),
        }
    }

    fn present_group(
        device: &wgpu::Device,
        present: &wgpu::RenderPipeline,
        frame: &Frame,
    ) -> wgpu::BindGroup {
        debug_assert_eq!(frame.target.format(), RGBA);
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("present"),
            layout: &present.get_bind_group_layout(0),
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&frame.target_view),
            }],
        })
    }

    impl ApplicationHandler for Viewer<'_> {
        fn resumed(&mut self, el: &ActiveEventLoop) {
            if self.shown.is_none()
                && let Err(e) = self.open(el)
            {
                self.error = Some(e);
                el.exit();
            }
        }

        fn window_event(&mut self, el: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
            let done = match event {
                WindowEvent::CloseRequested => {
                    el.exit();
                    Ok(())
                }
                WindowEvent::Resized(s) if s.width > 0 && s.height > 0 => {
                    self.size = (s.width, s.height);
                    if let Some(shown) = &mut self.shown {
                        shown.config.width = s.width;
                        shown.config.height = s.height;
                        shown.surface.configure(&self.app.device, &shown.config);
                    }
                    self.rebuild()
                }
                WindowEvent::RedrawRequested => self.redraw(),
                WindowEvent::MouseInput {
                    state,
                    button: MouseButton::Left,
                    ..
                } => {
                    self.drag = (state == ElementState::Pressed).then_some(self.cursor);
                    Ok(())
                }
                WindowEvent::CursorMoved { position, .. } => {
                    self.cursor = (position.x, position.y);
                    if let Some((x, y)) = self.drag {
                        self.azimuth += 0.01 * (position.x - x) as f32;
                        self.elevation =
                            (self.elevation + 0.01 * (position.y - y) as f32).clamp(-1.5, 1.5);
                        self.drag = Some(self.cursor);
                    }
                    Ok(())
                }
                WindowEvent::KeyboardInput { event, .. }
                    if event.state == ElementState::Pressed =>
                {
                    if self.key(el, &event.logical_key) {
                        self.rebuild()
                    } else {
                        Ok(())
                    }
                }
                _ => Ok(()),
            };
            if let Err(e) = done {
                self.error = Some(e);
                el.exit();
            }
        }
    }
}
