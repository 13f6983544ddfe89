//! Helpers shared by the runtime's integration tests.
#![allow(dead_code)] // each test binary uses its own subset

#[cfg(feature = "gpu")]
use dhoit_runtime::gpu::Gpu;
use dhoit_runtime::scene::{self, Opacity};
use std::path::{Path, PathBuf};

#[path = "temp.rs"]
mod temp;
#[allow(unused_imports)] // each test binary uses its own subset
pub use temp::{TempDir, temp_dir};

/// The folder of real glTF scenes: $DHOIT_SCENES, else ../shared/scenes beside the workspace;
/// None when it does not exist (a fresh clone with nothing beside it).
pub fn scenes_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("DHOIT_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes"));
    dir.is_dir().then_some(dir)
}

/// A glTF scene file for a test: the real scene `rel` under [`scenes_dir`] when there is one,
/// else the built-in `stand_in` written as `.glb` by the exporter (which the loader then reads
/// like any file, from a folder that stays: the binary's tests share it). Says which on stderr.
pub fn real_or_exported(rel: &str, stand_in: &str) -> PathBuf {
    if let Some(dir) = scenes_dir() {
        let path = dir.join(rel);
        assert!(
            path.is_file(),
            "{} is missing from the real scenes at {}",
            rel,
            dir.display()
        );
        return path;
    }
    let path = temp_dir(&format!("standin-{}", scene::file_label(stand_in)))
        .keep()
        .join(format!("{}.glb", scene::file_label(stand_in)));
    let s = scene::load(stand_in, Opacity::Material).unwrap();
    scene::gltf::export(&s, &path).unwrap();
    eprintln!(
        "real scenes absent: {rel} replaced by the built-in {stand_in} exported as {}",
        path.display()
    );
    path
}

#[cfg(feature = "gpu")]
/// The GPU every GPU test of one test binary shares (Mesa's lavapipe in CI). Without an adapter
/// the test fails, unless DHOIT_SKIP_GPU=1 says to skip (None, and it says so).
pub fn gpu() -> Option<&'static Gpu> {
    static GPU: std::sync::OnceLock<Option<Gpu>> = std::sync::OnceLock::new();
    GPU.get_or_init(|| match Gpu::new() {
        Ok(g) => {
            eprintln!("GPU tests on {}", g.adapter());
            Some(g)
        }
        Err(e) if std::env::var("DHOIT_SKIP_GPU").as_deref() == Ok("1") => {
            eprintln!("SKIPPED (DHOIT_SKIP_GPU=1): {e}");
            None
        }
        Err(e) => panic!("{e} (set DHOIT_SKIP_GPU=1 to skip the GPU tests explicitly)"),
    })
    .as_ref()
}

/// The 64-bit device on the test adapter ([`gpu`] is it unless `DHOIT_DEVICE=webgpu-core` makes
/// every GPU test run on WebGPU's core device): for the tests that hold the core device to it.
#[cfg(feature = "gpu")]
pub fn wide() -> Option<&'static Gpu> {
    gpu()?;
    static WIDE: std::sync::OnceLock<Gpu> = std::sync::OnceLock::new();
    Some(WIDE.get_or_init(|| {
        Gpu::requiring(dhoit_runtime::gpu::wgpu::Features::empty())
            .expect("the test adapter with 64-bit atomics")
    }))
}

/// Whether the test device has `feature`. Where it lacks it (as WebGPU's core device does, on
/// which `make test` runs the GPU tests a second time: `DHOIT_DEVICE=webgpu-core`), says which
/// check is left out and why, so that nothing is skipped silently.
#[cfg(feature = "gpu")]
pub fn has(g: &Gpu, feature: dhoit_runtime::gpu::wgpu::Features, unchecked: &str) -> bool {
    let has = g.device().features().contains(feature);
    if !has {
        let names: Vec<&str> = (feature.features_wgpu.iter_names().map(|(n, _)| n))
            .chain(feature.features_webgpu.iter_names().map(|(n, _)| n))
            .collect();
        eprintln!(
            "NOT CHECKED on {} (it lacks {}): {unchecked}",
            g.adapter(),
            names.join(", ")
        );
    }
    has
}

/// Whether the test device runs the one-pass capture (64-bit atomics); where not, says which
/// check is left out ([`has`]).
#[cfg(feature = "gpu")]
pub fn is_wide(g: &Gpu, unchecked: &str) -> bool {
    if !g.is_wide() {
        eprintln!(
            "NOT CHECKED on {} (no 64-bit atomics: every capture is the portable one): {unchecked}",
            g.adapter()
        );
    }
    g.is_wide()
}

#[cfg(feature = "gpu")]
/// WebGPU's core device on the same adapter as [`gpu`] (`Gpu::portable`: no feature, wgpu's
/// default limits), shared by a test binary's tests: what a browser runs. None where [`gpu`]
/// skips.
pub fn core() -> Option<&'static Gpu> {
    gpu()?;
    static CORE: std::sync::OnceLock<Gpu> = std::sync::OnceLock::new();
    Some(CORE.get_or_init(|| {
        let g = Gpu::portable().expect("WebGPU's core device on the test adapter");
        eprintln!("WebGPU core device on {}", g.adapter());
        g
    }))
}

/// Largest absolute difference of two equally long slices.
pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[cfg(feature = "gpu")]
/// The methods that run on the CPU and the GPU alike: the A-buffer, FKB, the optimal
/// allocation (uploaded), VKB, DKB, WBOIT, MBOIT and the linked list.
pub const CPU_AND_GPU: [dhoit_runtime::frame::Method; 8] = {
    use dhoit_runtime::frame::Method;
    [
        Method::Abuffer,
        Method::Fkb,
        Method::Optimal,
        Method::Vkb,
        Method::Dkb,
        Method::Wboit,
        Method::Mboit,
        Method::LinkedList,
    ]
};

#[cfg(feature = "gpu")]
/// Each of `methods` rendered from the CPU's fragments `fl` (of `s` seen by `cam`) by the CPU
/// reference and by the GPU from the scene, through the mapping render and bench use
/// (`Slots::for_method`): (method, CPU frame, GPU image). FKB is left out where the budget
/// cannot give every pixel a slot (it is refused there, documented).
/// [`Gpu::render`] of the method's own passes: a DKB or VKB frame runs its method at any
/// budget, where by default (`FrameOptions::exact_when_cheaper`) it renders the exact A-buffer
/// wherever that is no dearer, which would hide the passes a test holds to their twins.
#[allow(dead_code)]
pub trait RenderMethod {
    fn render_method(
        &self,
        scene: &dhoit_runtime::scene::Scene,
        cam: &dhoit_runtime::scene::Camera,
        size: (u32, u32),
        background: [f32; 3],
        slots: dhoit_runtime::gpu::Slots,
    ) -> dhoit_runtime::Result<dhoit_runtime::gpu::GpuFrame>;
}

impl RenderMethod for Gpu {
    fn render_method(
        &self,
        scene: &dhoit_runtime::scene::Scene,
        cam: &dhoit_runtime::scene::Camera,
        size: (u32, u32),
        background: [f32; 3],
        slots: dhoit_runtime::gpu::Slots,
    ) -> dhoit_runtime::Result<dhoit_runtime::gpu::GpuFrame> {
        let opts = dhoit_runtime::gpu::FrameOptions::default().always_approximate();
        self.render_with(&opts, scene, cam, size, background, slots)
    }
}

pub fn cpu_and_gpu_frames(
    g: &Gpu,
    s: &dhoit_runtime::scene::Scene,
    cam: &dhoit_runtime::scene::Camera,
    fl: &dhoit_runtime::fragment::FragmentLists,
    options: dhoit_runtime::frame::Options,
    methods: &[dhoit_runtime::frame::Method],
) -> Vec<(
    dhoit_runtime::frame::Method,
    dhoit_runtime::frame::Frame,
    dhoit_runtime::composite::Image,
)> {
    use dhoit_runtime::frame::{Method, Renderer};
    use dhoit_runtime::gpu::Slots;
    // Each method's own passes: where the exact A-buffer is cheaper a k-buffer renders it
    // (Options::exact_when_cheaper), which would hide the passes held to their twins here.
    let options = options.always_approximate();
    let mut out = Vec::new();
    for &m in methods {
        let blends = || {
            has(
                g,
                dhoit_runtime::gpu::wgpu::Features::FLOAT32_BLENDABLE,
                "MBOIT on the GPU against its twin",
            )
        };
        if m == Method::Mboit && !blends() {
            continue;
        }
        let renderer = Renderer::new(fl, options);
        let allocation = match renderer.allocate(m) {
            Ok(a) => a,
            Err(dhoit_runtime::Error::Budget(..)) if m == Method::Fkb => continue,
            Err(e) => panic!("{}: {e}", m.name()),
        };
        let slots = Slots::for_method(m, &allocation, &options).unwrap();
        let mut cpu = renderer.composite(allocation.clone());
        let gpu = g
            .render_method(s, cam, fl.size(), options.background, slots)
            .unwrap();
        // The blended methods' twins on the GPU's own fragments (the A-buffer's, which the
        // same vertex stage rasterizes): where surfaces are coplanar or one 8-bit step apart, a
        // fragment's depth or opacity rasterized one unit differently moves MBOIT's
        // reconstruction by up to 0.1 (the method's own sensitivity, in 32 bits) and WBOIT's
        // revealage by a rounding step.
        if let Some(blend) = match m {
            Method::Wboit => Some(dhoit_runtime::composite::Method::Wboit(options.wboit)),
            Method::Mboit => Some(dhoit_runtime::composite::Method::Mboit(options.mboit)),
            _ => None,
        } {
            let own = own_fragments(g, s, cam, fl.size(), options.background);
            cpu.image = dhoit_runtime::composite::composite(&own, blend, options.background);
        }
        // The linked list's twin on the fragments the GPU kept: where F truncates, which
        // arrive first is the device's order, not submission's (the CPU reference's).
        if m == Method::LinkedList {
            let kept = gpu
                .fragments
                .as_ref()
                .expect("diagnostics read the kept fragments");
            let k = vec![options.list_sorted; kept.pixel_count()];
            let blend = dhoit_runtime::composite::Method::Hybrid(&k);
            cpu.image = dhoit_runtime::composite::composite(kept, blend, options.background);
        }
        out.push((m, cpu, gpu.image));
    }
    out
}

#[cfg(feature = "gpu")]
/// The GPU's own fragments of `s` seen by `cam`: its A-buffer's, read back (with their
/// submission indices and the opaque pass's colour and depth).
#[allow(dead_code)]
pub fn own_fragments(
    g: &Gpu,
    s: &dhoit_runtime::scene::Scene,
    cam: &dhoit_runtime::scene::Camera,
    size: (u32, u32),
    background: [f32; 3],
) -> dhoit_runtime::fragment::FragmentLists {
    g.render(s, cam, size, background, dhoit_runtime::gpu::Slots::Exact)
        .unwrap()
        .fragments
        .expect("diagnostics read the A-buffer's fragments back")
}

/// How far the GPU's blended methods (WBOIT, MBOIT) may lie from their twins. The twins round
/// their binary16 colour targets to nearest after each add, as most blend units do, but a
/// device may round either way (Vulkan allows both; lavapipe truncates): each add may differ by
/// a binary16 step (2^-10 of the sum), in the colour sums and in their weight, so a pixel of n
/// fragments by up to 2 n 2^-10 at worst. The steps mostly cancel in the ratio: measured on
/// lavapipe, at most 3.5e-3 (particles, 195 fragments deep), 2.1e-3 (hair), 4.6e-4 (three
/// layers). The bound is that measurement with a margin; a wrong weight, clear or formula moves
/// the image by far more.
#[allow(dead_code)]
pub const BLENDED_BOUND: f32 = 5e-3;

/// `bound`, or [`BLENDED_BOUND`] for the methods the device's blending computes.
#[allow(dead_code)]
pub fn twin_bound(m: dhoit_runtime::frame::Method, bound: f32) -> f32 {
    use dhoit_runtime::frame::Method;
    match m {
        Method::Wboit | Method::Mboit => bound.max(BLENDED_BOUND),
        _ => bound,
    }
}

/// A full-frame quad at depth `z` (seen through [`identity`]).
pub fn layer(s: &mut dhoit_runtime::scene::Scene, z: f32, c: [f32; 4]) {
    quad(s, (-1.0, -1.0, 1.0, 1.0), (z, z), c);
}

/// `fl` rendered by `m` on the CPU at one slot a pixel, the method's own approximation
/// (no budget decides the methods without slots).
pub fn render_one_fpp(
    fl: &dhoit_runtime::fragment::FragmentLists,
    m: dhoit_runtime::frame::Method,
    bg: [f32; 3],
) -> dhoit_runtime::composite::Image {
    use dhoit_runtime::budget::Budget;
    use dhoit_runtime::frame::Options;
    dhoit_runtime::frame::render(
        fl,
        m,
        Options::new(Budget::SlotsPerPixel(1.0), bg).always_approximate(),
    )
    .unwrap()
    .image
}

/// `n` full-frame quads stacked along view 0's direction (25 degrees up, azimuth 0.5 rad),
/// 0.02 apart, each its own colour at opacity 0.25: a frame as deep as `n` at every pixel,
/// whatever its size.
pub fn layers(n: usize) -> dhoit_runtime::scene::Scene {
    let mut deep = dhoit_runtime::scene::Scene::default();
    let e = 25f32.to_radians();
    let dir = glam::Vec3::new(e.cos() * 0.5f32.cos(), e.sin(), e.cos() * 0.5f32.sin());
    let u = dir.any_orthonormal_vector();
    let v = dir.cross(u);
    for i in 0..n {
        let o = dir * (-1.0 + 0.02 * i as f32);
        let c = [0.008 * i as f32, 0.8 - 0.006 * i as f32, 0.5, 0.25];
        let p =
            [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].map(|(a, b)| o + u * a + v * b);
        deep.push_triangle([p[0], p[1], p[2]], [c; 3]);
        deep.push_triangle([p[0], p[2], p[3]], [c; 3]);
    }
    deep
}

/// Clip space is world space: x, y in [-1, 1], window depth = z.
pub fn identity() -> dhoit_runtime::scene::Camera {
    dhoit_runtime::scene::Camera {
        view_proj: glam::Mat4::IDENTITY,
        forward: glam::Vec3::NEG_Z,
        eye: glam::Vec3::ZERO,
        near: 0.0,
        far: 0.0,
    }
}

/// A quad from (x0, y0) to (x1, y1) whose depth runs from z0 at x0 to z1 at x1 (seen through
/// [`identity`]).
pub fn quad(
    s: &mut dhoit_runtime::scene::Scene,
    (x0, y0, x1, y1): (f32, f32, f32, f32),
    (z0, z1): (f32, f32),
    c: [f32; 4],
) {
    use glam::Vec3;
    let (a, b) = (Vec3::new(x0, y0, z0), Vec3::new(x1, y0, z1));
    let (d, e) = (Vec3::new(x1, y1, z1), Vec3::new(x0, y1, z0));
    s.push_triangle([a, b, d], [c; 3]);
    s.push_triangle([a, d, e], [c; 3]);
}

/// The bytes a k-buffer frame of `layout` allocates for the allocation `k` of pixels holding
/// `counts` fragments at F = `f`, by the layout tables: its slots (FKB, an uploaded k), or,
/// where the tails are pooled (DKB, VKB), the pool it makes for the frame's budget and
/// occupancy before its allocation.
#[allow(dead_code)]
pub fn kbuffer_bytes(
    layout: &dhoit_runtime::budget::Layout,
    k: &[u32],
    counts: &[u32],
    f: u64,
) -> u64 {
    use dhoit_runtime::budget;
    let px = k.len() as u64;
    // The allocated k-buffers' pools are sized before their allocation, for what the budget
    // reserves at the frame's occupancy.
    if layout.tail_bytes > 0 {
        return layout.reserved_bytes(px, f, &budget::Occupancy::of(counts));
    }
    let slots = k.iter().map(|&k| k as u64).sum();
    layout.allocated_with_tails(px, slots, budget::tails_kept(k, counts))
}

/// `importance::pixel_stats` as DKB's GPU frame gathers them: for each pixel with a record (more
/// than `shared::TAIL_WORDS` fragments), but for the farthest keys (every pooled pixel is a
/// pair); a pixel of fewer has its count alone (it keeps them all whatever its k, which is
/// forced).
#[allow(dead_code)]
pub fn recorded_stats(
    fl: &dhoit_runtime::fragment::FragmentLists,
) -> Vec<dhoit_runtime::importance::PixelStats> {
    dhoit_runtime::importance::pixel_stats(fl)
        .into_iter()
        .map(|st| match st.count {
            n if n <= dhoit_runtime::shared::TAIL_WORDS => dhoit_runtime::importance::PixelStats {
                count: st.count,
                ..Default::default()
            },
            _ => dhoit_runtime::importance::PixelStats {
                farthest: [0; 2],
                ..st
            },
        })
        .collect()
}

/// The committed default network (data/weights.safetensors).
pub fn committed_weights() -> dhoit_runtime::mlp::Mlp {
    dhoit_runtime::mlp::Mlp::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/weights.safetensors"),
    )
    .unwrap()
}

/// A frame of `layers` coplanar-in-groups quads: over the left half `layers` quads in groups
/// of three at one depth (equal depths, other colours), over the right half a few at distinct
/// depths, one pixel-row strip of a single quad: ties, truncated and whole pixels.
pub fn tied_layers(layers: usize) -> dhoit_runtime::scene::Scene {
    let mut s = dhoit_runtime::scene::Scene::default();
    let v = glam::Vec3::new;
    for i in 0..layers + 4 {
        // Three quads a depth on the left; distinct depths on the right.
        let z = if i < layers {
            0.1 + 0.8 * (i / 3) as f32 / (layers / 3 + 1) as f32
        } else {
            0.15 + 0.2 * (i - layers) as f32
        };
        let (x0, x1) = if i < layers { (-1.0, 0.0) } else { (0.0, 1.0) };
        let y1 = if i == layers + 3 { -0.6 } else { 1.0 };
        let c = [
            ((i * 7) % 5) as f32 / 4.0,
            (i % 3) as f32 / 2.0,
            ((i * 5) % 7) as f32 / 6.0,
            0.2 + (i % 4) as f32 * 0.2,
        ];
        s.push_triangle([v(x0, -1.0, z), v(x1, -1.0, z), v(x0, y1, z)], [c; 3]);
        s.push_triangle([v(x1, -1.0, z), v(x1, y1, z), v(x0, y1, z)], [c; 3]);
    }
    s
}
