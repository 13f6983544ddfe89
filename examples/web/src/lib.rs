//! dhoit in a browser: a built-in scene rendered with DKB, VKB and the exact A-buffer side by
//! side, on the page's WebGPU (wasm32, wgpu's WebGPU backend), with the budget a slider sets.
//!
//! [`Demo`] is the page's whole renderer and builds for both targets: on wasm32 the page drives
//! it through [`web`] (wasm-bindgen), natively `dhoit-web` (src/main.rs) renders the same frames
//! on a WebGPU core device, which is what `scripts/web.sh test` holds the page's frames to.
//! Nothing in it blocks: every frame is recorded into an encoder, submitted, and its image
//! awaited ([`SceneStream::image_async`]), as a page must.

use dhoit_runtime::Result;
use dhoit_runtime::budget::Budget;
use dhoit_runtime::composite::Image;
use dhoit_runtime::frame::{Method, Options};
use dhoit_runtime::gpu::{Gpu, SceneStream};
use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::scene::{self, Camera, Opacity, Scene};

#[cfg(target_arch = "wasm32")]
pub mod web;

/// The committed network DKB runs (the page carries it in its wasm).
pub const WEIGHTS: &[u8] = include_bytes!("../../../data/weights.safetensors");

/// The methods the page shows, left to right (the A-buffer last: the reference).
pub const METHODS: [Method; 3] = [Method::Dkb, Method::Vkb, Method::Abuffer];

/// Every method a page's WebGPU runs (all of dhoit's streamed methods but MBOIT, which needs
/// `float32-blendable`), the A-buffer last: what `scripts/web.sh test` renders on Dawn.
pub const PAGE_METHODS: [Method; 7] = [
    Method::Dkb,
    Method::Vkb,
    Method::Fkb,
    Method::Mlab,
    Method::LinkedList,
    Method::Wboit,
    Method::Abuffer,
];

/// The built-in scenes the page offers (the first by default).
pub const SCENES: [&str; 4] = ["particles", "foliage", "hair", "glass"];

/// The page's first budget: a quarter of each frame's fragments.
pub const DEFAULT_BUDGET: &str = "25%";

/// Background behind the transparency.
const BACKGROUND: [f32; 3] = [1.0, 1.0, 1.0];

/// Frames a method renders at most before its image is shown: its first frame is sized before
/// any count of the scene's fragments, so a frame is drawn again until one's report says its
/// buffers held it.
const MAX_FRAMES: usize = 4;

/// One method's frame, as the page shows it.
#[derive(Clone, Debug)]
pub struct View {
    pub method: Method,
    /// Its image: sRGB, 8 bits a channel, RGBA, row-major.
    pub rgba: Vec<u8>,
    /// The linear image (RGB, f32).
    pub image: Image,
    /// Bytes the frame allocated for its fragments (its pool, slots and tails).
    pub bytes: u64,
    /// Whether the frame kept every fragment.
    pub exact: bool,
    /// Frames drawn before this one was shown.
    pub frames: usize,
}

/// The page's renderer: a scene, a camera and one [`SceneStream`] a method, on one device.
pub struct Demo {
    gpu: Gpu,
    weights: Mlp,
    size: (u32, u32),
    budget: Budget,
    cam: Camera,
    scene: Scene,
    methods: Vec<Method>,
    /// Each method's stream and the frames it has recorded.
    streams: Vec<(Method, SceneStream, u64)>,
}

impl Demo {
    /// The demo on an open device (the page's, or a native one): `methods` (the last the
    /// reference the others' errors are measured against; [`METHODS`] on the page) rendering
    /// `scene` (one of [`SCENES`], or any built-in) at `size` with `budget` (as `dhoit render
    /// --budget` reads it).
    pub async fn new(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: &wgpu::AdapterInfo,
        methods: &[Method],
        scene: &str,
        size: (u32, u32),
        budget: &str,
    ) -> Result<Demo> {
        let gpu = Gpu::on_device_async(device, queue, info).await?;
        let weights = Mlp::from_bytes(WEIGHTS).map_err(|e| {
            dhoit_runtime::Error::Invalid(format!("the page's network weights: {e}"))
        })?;
        let mut demo = Demo {
            gpu,
            weights,
            size,
            budget: Budget::parse(budget)?,
            cam: Camera::orbit(&Scene::default(), 0, 1, (1, 1)),
            scene: Scene::default(),
            methods: methods.to_vec(),
            streams: Vec::new(),
        };
        demo.set_scene(scene)?;
        Ok(demo)
    }

    /// The device dhoit runs on, as its adapter names it.
    pub fn adapter(&self) -> &str {
        self.gpu.adapter()
    }

    /// Shows `name` (a built-in scene) from its first orbit view: every method's stream made
    /// again for it.
    pub fn set_scene(&mut self, name: &str) -> Result<()> {
        let s = scene::load(name, Opacity::default())?;
        self.cam = Camera::orbit(&s, 0, scene::DEFAULT_VIEWS, self.size);
        self.show(s)
    }

    /// Every method's stream made for `s`.
    fn show(&mut self, s: Scene) -> Result<()> {
        let mut options = Options::new(self.budget, BACKGROUND);
        options.weights = Some(&self.weights);
        let streams = self
            .methods
            .iter()
            .map(|&m| {
                Ok((
                    m,
                    SceneStream::new(&self.gpu, &s, self.size, m, &options)?,
                    0,
                ))
            })
            .collect::<Result<Vec<_>>>()?;
        self.streams = streams;
        self.scene = s;
        Ok(())
    }

    /// The camera as 24 words: its view-projection matrix (column-major), its forward
    /// direction, its eye, its near and far planes, each f32's bits. The host's f32 maths
    /// differ between targets in their last bits (wasm's libm and the native one's sines), so
    /// a test that holds two builds' frames to each other hands one's camera and geometry to
    /// the other ([`Demo::set_camera_bits`], [`Demo::set_geometry_bits`]).
    pub fn camera_bits(&self) -> [u32; 24] {
        let c = &self.cam;
        let mut words = [0u32; 24];
        let floats = c
            .view_proj
            .to_cols_array()
            .into_iter()
            .chain(c.forward.to_array())
            .chain(c.eye.to_array())
            .chain([c.near, c.far]);
        for (w, f) in words.iter_mut().zip(floats) {
            *w = f.to_bits();
        }
        words
    }

    /// Sees the scene through the camera `words` give ([`Demo::camera_bits`]).
    pub fn set_camera_bits(&mut self, words: &[u32]) -> Result<()> {
        let f = finite_words(words, 24, "a camera")?;
        self.cam = Camera {
            view_proj: glam::Mat4::from_cols_slice(&f[..16]),
            forward: glam::Vec3::from_slice(&f[16..19]),
            eye: glam::Vec3::from_slice(&f[19..22]),
            near: f[22],
            far: f[23],
        };
        Ok(())
    }

    /// The scene's vertices as f32 bits: every position (x, y, z), then every colour (RGBA).
    pub fn geometry_bits(&self) -> Vec<u32> {
        let s = &self.scene;
        s.positions
            .iter()
            .flat_map(|p| p.to_array())
            .chain(s.colors.iter().flatten().copied())
            .map(f32::to_bits)
            .collect()
    }

    /// The scene's vertices replaced by `words` ([`Demo::geometry_bits`] of a scene of as many
    /// vertices), every method's stream made again for them.
    pub fn set_geometry_bits(&mut self, words: &[u32]) -> Result<()> {
        let mut s = self.scene.clone();
        let n = s.positions.len();
        let f = finite_words(words, 7 * n, "the scene's geometry")?;
        for (i, p) in s.positions.iter_mut().enumerate() {
            *p = glam::Vec3::from_slice(&f[3 * i..3 * i + 3]);
        }
        for (i, c) in s.colors.iter_mut().enumerate() {
            c.copy_from_slice(&f[3 * n + 4 * i..3 * n + 4 * i + 4]);
        }
        self.show(s)
    }

    /// The scene shown.
    pub fn scene(&self) -> &str {
        &self.scene.name
    }

    /// The budget of every method that has one from the next frame (`"25%"`, `"1fpp"`,
    /// `"2MB"`, ...; FKB, MLAB and the list take slots a pixel or bytes).
    pub fn set_budget(&mut self, budget: &str) -> Result<()> {
        let budget = Budget::parse(budget)?;
        for (m, s, _) in &mut self.streams {
            if !matches!(m, Method::Abuffer | Method::Wboit | Method::Mboit) {
                s.set_budget(budget)?;
            }
        }
        self.budget = budget;
        Ok(())
    }

    /// Every method's frame, in the demo's order. Each frame is recorded, submitted and its
    /// image awaited; a frame whose report is not yet read, says it was sized before any count
    /// of the scene (a page's first) or was short of its pool is drawn again, at most
    /// [`MAX_FRAMES`] times, so the image shown is the budget's.
    pub async fn render(&mut self) -> Result<Vec<View>> {
        let mut views = Vec::new();
        for (method, stream, recorded) in &mut self.streams {
            let mut frames = 0;
            let (image, report) = loop {
                let number = *recorded;
                let mut enc = self
                    .gpu
                    .device()
                    .create_command_encoder(&Default::default());
                stream.record(&mut enc, &self.cam)?;
                self.gpu.queue().submit([enc.finish()]);
                *recorded += 1;
                frames += 1;
                let image = stream.image_async().await?;
                let mut reports = stream.finished(false)?;
                if let Some(e) = reports.iter_mut().find_map(|r| r.error.take()) {
                    return Err(e);
                }
                let report = reports.into_iter().find(|r| r.frame == number);
                // Shown once a frame's report says its buffers were sized from a count and held it
                // (a page's first frame is sized before any: short of its pool, or holding more
                // than the budget's frames; the next is sized from this one's count).
                let settled = report.as_ref().is_some_and(|r| !r.pool_short && !r.guessed);
                if settled || frames == MAX_FRAMES {
                    break (image, report);
                }
            };
            views.push(View {
                method: *method,
                rgba: to_rgba8(&image),
                image,
                bytes: report.as_ref().map_or(0, |r| r.allocated_bytes),
                exact: report.as_ref().is_some_and(|r| r.exact),
                frames,
            });
        }
        Ok(views)
    }
}

/// An image as a canvas takes it: sRGB, RGBA8, opaque.
pub fn to_rgba8(img: &Image) -> Vec<u8> {
    dhoit_runtime::image_io::to_srgb8(img)
        .chunks_exact(3)
        .flat_map(|c| [c[0], c[1], c[2], 255])
        .collect()
}

/// `words` as f32s, where there are `n` of them and each is finite.
fn finite_words(words: &[u32], n: usize, what: &str) -> Result<Vec<f32>> {
    let f: Vec<f32> = words.iter().map(|&w| f32::from_bits(w)).collect();
    if f.len() != n || f.iter().any(|x| !x.is_finite()) {
        return Err(dhoit_runtime::Error::Invalid(format!(
            "{what} is {n} finite f32 words; these are {} words, {} of them finite",
            words.len(),
            f.iter().filter(|x| x.is_finite()).count()
        )));
    }
    Ok(f)
}
