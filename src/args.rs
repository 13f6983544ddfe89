//! What several commands share: the view options, their value parsers, and loading a scene,
//! its fragments and the weights.

use anyhow::{Result, bail};
use clap::Args;
use dhoit_runtime::fragment::FragmentLists;
use dhoit_runtime::image_io;
use dhoit_runtime::mlp::{Mlp, Precision};
use dhoit_runtime::raster::{self, Resolution};
use dhoit_runtime::scene::{self, Camera, Opacity, Scene};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The default weights (`make train` writes them): looked up in the working directory, then in
/// the source tree this binary was built from.
pub(crate) fn default_weights() -> Option<PathBuf> {
    let rel = Path::new(dhoit_train::cli::DEFAULT_WEIGHTS);
    [
        rel.to_path_buf(),
        Path::new(env!("CARGO_MANIFEST_DIR")).join(rel),
    ]
    .into_iter()
    .find(|p| p.is_file())
}

/// The network's precision, for the commands that render DKB.
#[derive(Args, Clone, Copy)]
pub(crate) struct NetworkPrecision {
    /// Precision of the network for dkb: f32; f16 (binary16 weights, f32 arithmetic; the CPU
    /// twin computes with the same rounded weights); or f16-math (binary16 weights and
    /// hidden-layer arithmetic, for GPUs with fast half precision; the device needs
    /// SHADER_F16). Default: the precision the weights file names (`dhoit fit` writes it),
    /// else f32.
    #[arg(long)]
    pub(crate) precision: Option<Precision>,
}

#[derive(Args, Clone)]
pub(crate) struct ViewArgs {
    /// Resolution WIDTHxHEIGHT.
    #[arg(long, default_value = "640x480", allow_hyphen_values = true)]
    pub(crate) res: Resolution,
    /// Number of orbit views around the scene (view I is at angle I/N of a turn).
    #[arg(long, default_value_t = scene::DEFAULT_VIEWS, value_parser = parse_views)]
    pub(crate) views: usize,
    /// Where the camera stands: `orbit` (the orbit's views, `--view`), or `asset`: the
    /// camera the glTF file gives (its first), else its front (looking along -Z, level, where
    /// glTF viewers start): the viewpoint of the screenshots the sample assets ship.
    #[arg(long, default_value = "orbit", value_parser = ["orbit", "asset"])]
    pub(crate) camera: String,
    /// One uniform opacity for every surface, as the papers' protocol has it (the reference
    /// uses 0.33): no opaque surfaces, alpha modes and glass ignored, both faces drawn. Without
    /// it, each scene's own: glTF files and the built-in material families (`dhoit scenes`)
    /// by their materials, the papers' built-in families at 0.33.
    #[arg(long, conflicts_with = "material_alpha")]
    pub(crate) opacity: Option<f32>,
    /// Let the materials decide even for the papers' built-in families (their vertex alpha).
    #[arg(long)]
    pub(crate) material_alpha: bool,
    /// How glass (KHR_materials_transmission) lets through what is behind it: `tinted`, per
    /// channel, its base colour filtering the light (a red pane passes red), its colour the
    /// Fresnel reflection; or `grey`, one opacity, so clear glass of any colour passes every
    /// colour (the library's default; the network is trained on tinted glass). Every method
    /// composites tinted glass, on the CPU and the GPU: the A-buffer,
    /// MLAB and the linked list store a tint a fragment or node (4 bytes more), the k-buffers
    /// a tint a slot and their tails' per-channel sums (FKB 4 bytes a slot and 12 a pixel
    /// more, VKB and DKB 8 a word of their pool), WBOIT and MBOIT an RGBA8 transmittance (3
    /// and 4 bytes more a pixel). A byte budget holds the tints.
    #[arg(long, default_value = "tinted", value_parser = ["grey", "tinted"])]
    pub(crate) glass: String,
    /// Permute the triangle submission order with this seed.
    #[arg(long)]
    pub(crate) shuffle: Option<u64>,
    /// Background colour, linear R,G,B in [0, 1].
    #[arg(long, default_value = "1,1,1", value_parser = parse_rgb)]
    pub(crate) background: [f32; 3],
    /// Network weights for dkb (default: data/weights.safetensors when it exists).
    #[arg(long)]
    pub(crate) weights: Option<PathBuf>,
}

/// The engines' methods' own parameters, at their published defaults.
#[derive(Args, Clone)]
pub(crate) struct MethodParams {
    /// MBOIT's power moments beside b_0: 4, 6 or 8 (32-bit float targets: 20, 28 or 36 bytes a
    /// pixel, and 8 for the colour; default 4; in `versus`, and at a memory M in `compare`, the
    /// most that fit it).
    #[arg(long, value_parser = parse_mboit_moments)]
    pub(crate) mboit_moments: Option<u32>,
    /// MBOIT's moment bias: how far the normalized moments are pulled towards a symmetric
    /// distribution before the reconstruction, in [0, 1) (default: the paper's for the
    /// moments, 5e-7, 5e-6 or 5e-5 for 4, 6 or 8 in 32 bits).
    #[arg(long, value_parser = parse_unit_open)]
    pub(crate) mboit_bias: Option<f32>,
    /// MBOIT's overestimation: the share of a fragment's own absorbance that counts as in front
    /// of it (the paper's 0.25; in [0, 1]).
    #[arg(long, default_value_t = 0.25, value_parser = parse_unit)]
    pub(crate) mboit_overestimation: f32,
    /// The linked list's fragments a pixel sorted and blended in order at resolve, the rest as
    /// a tail (Bevy's 8; 1 to 16).
    #[arg(long, default_value_t = dhoit_runtime::composite::LIST_SORTED, value_parser = parse_list_sorted)]
    pub(crate) list_sorted: u32,
    /// WBOIT's weight function (McGuire and Bavoil 2013): eq7, eq8 or eq9 of the view-space
    /// distance in the scene's units (the paper tunes them for 0.1 to 500; the camera's planes
    /// give it from the depth), or eq10 of the window depth alone.
    #[arg(long, default_value = "eq10", value_parser = parse_wboit_weight)]
    pub(crate) wboit_weight: dhoit_runtime::composite::WboitWeight,
    /// The most batches DKB gathers its network's records in (1 to 3): 1 holds them all at
    /// once in its slot pool, so a frame after the first gathers them with its count (two
    /// geometry passes); more take less memory where the records outweigh the slots (a small
    /// budget on a deep frame), and draw a features pass for each batch (a geometry pass
    /// more each). The image is the same.
    #[arg(long, default_value_t = dhoit_runtime::budget::RECORD_BATCHES, value_parser = parse_record_batches)]
    pub(crate) record_batches: u64,
}

impl MethodParams {
    /// MBOIT's parameters with `moments` power moments (4, 6 or 8): the given bias, else the
    /// paper's for them.
    pub(crate) fn mboit(&self, moments: u32) -> dhoit_runtime::composite::MboitParams {
        let paper =
            dhoit_runtime::composite::MboitParams::with_moments(moments).unwrap_or_default();
        dhoit_runtime::composite::MboitParams {
            bias: self.mboit_bias.unwrap_or(paper.bias),
            overestimation: self.mboit_overestimation,
            ..paper
        }
    }

    /// `o` with these parameters, for a frame seen by `cam` (WBOIT's weights of the view-space
    /// distance read its planes).
    pub(crate) fn apply<'a>(
        &self,
        o: dhoit_runtime::frame::Options<'a>,
        cam: &dhoit_runtime::scene::Camera,
    ) -> dhoit_runtime::frame::Options<'a> {
        dhoit_runtime::frame::Options {
            mboit: self.mboit(self.mboit_moments.unwrap_or(4)),
            list_sorted: self.list_sorted,
            wboit: dhoit_runtime::composite::WboitParams::for_camera(self.wboit_weight, cam),
            decision: dhoit_runtime::budget::Decision {
                record_batches: self.record_batches,
                ..o.decision
            },
            ..o
        }
    }
}

fn parse_unit_with(s: &str, open: bool) -> std::result::Result<f32, String> {
    let v: f32 = s.parse().map_err(|_| format!("'{s}' is not a number"))?;
    let ok = v.is_finite() && v >= 0.0 && if open { v < 1.0 } else { v <= 1.0 };
    match ok {
        true => Ok(v),
        false if open => Err(format!("{v} is not in [0, 1)")),
        false => Err(format!("{v} is not in [0, 1]")),
    }
}

fn parse_unit(s: &str) -> std::result::Result<f32, String> {
    parse_unit_with(s, false)
}

fn parse_unit_open(s: &str) -> std::result::Result<f32, String> {
    parse_unit_with(s, true)
}

fn parse_mboit_moments(s: &str) -> std::result::Result<u32, String> {
    let n = s
        .parse::<u32>()
        .map_err(|_| format!("'{s}' is not a number of power moments (4, 6 or 8)"))?;
    dhoit_runtime::composite::MboitParams::with_moments(n)
        .map(|_| n)
        .map_err(|e| e.to_string())
}

fn parse_record_batches(s: &str) -> std::result::Result<u64, String> {
    let most = dhoit_runtime::budget::MOST_RECORD_BATCHES;
    match s.parse::<u64>() {
        Ok(n) if (1..=most).contains(&n) => Ok(n),
        _ => Err(format!(
            "DKB gathers its records in 1 to {most} batches, not '{s}' (past {most} the tails \
             already take more of the pool than a batch of records)"
        )),
    }
}

fn parse_list_sorted(s: &str) -> std::result::Result<u32, String> {
    let n = s
        .parse::<u32>()
        .map_err(|_| format!("'{s}' is not a whole number of fragments a pixel"))?;
    dhoit_runtime::composite::check_list_sorted(n)
        .map(|()| n)
        .map_err(|e| e.to_string())
}

fn parse_wboit_weight(
    s: &str,
) -> std::result::Result<dhoit_runtime::composite::WboitWeight, String> {
    dhoit_runtime::composite::WboitWeight::parse(s).map_err(|e| e.to_string())
}

fn parse_rgb(s: &str) -> std::result::Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|c| c.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("'{s}' is not R,G,B"))?;
    match v[..] {
        [r, g, b] if v.iter().all(|c| c.is_finite() && (0.0..=1.0).contains(c)) => Ok([r, g, b]),
        _ => Err(format!(
            "'{s}' is not three numbers in [0, 1] separated by commas"
        )),
    }
}

/// `--views`: a whole number of at least one.
fn parse_views(s: &str) -> std::result::Result<usize, String> {
    let n = s
        .parse::<usize>()
        .map_err(|e| format!("'{s}' is not a number of views: {e}"))?;
    scene::check_view(0, n)
        .map(|()| n)
        .map_err(|e| e.to_string())
}

/// `--repeat`: a whole number of at least one (timed repetitions).
pub(crate) fn parse_repeat(s: &str) -> std::result::Result<usize, String> {
    match s.parse::<usize>() {
        Ok(0) => Err("at least one repetition is needed to time anything".into()),
        Ok(n) => Ok(n),
        Err(e) => Err(format!("'{s}' is not a number of repetitions: {e}")),
    }
}

pub(crate) fn load_scene(name: &str, a: &ViewArgs) -> Result<Scene> {
    let opacity = match (a.material_alpha, a.opacity) {
        (true, _) => Opacity::Material,
        (false, Some(o)) => Opacity::Uniform(o),
        (false, None) => Opacity::Native,
    };
    let mut scene = scene::load(name, opacity)?;
    if a.glass == "tinted" {
        scene.glass = scene::Glass::Tinted;
    }
    if let Some(seed) = a.shuffle {
        scene = scene.shuffled(seed);
    }
    Ok(scene)
}

/// Every scene of a command that renders several, loaded before the first frame: a name that
/// is neither built in nor a glTF file stops the command before it writes anything.
pub(crate) fn load_scenes(names: &[String], a: &ViewArgs) -> Result<Vec<Scene>> {
    names.iter().map(|name| load_scene(name, a)).collect()
}

/// That `view` is one of the orbit's `views` ([`scene::check_view`]).
pub(crate) fn check_view(view: usize, views: usize) -> Result<()> {
    Ok(scene::check_view(view, views)?)
}

/// The camera of `view` of the orbit at the resolution `a` gives (what [`rasterize_view`]
/// rasterizes through).
pub(crate) fn view_camera(scene: &Scene, view: usize, a: &ViewArgs) -> Camera {
    match a.camera.as_str() {
        "asset" => Camera::asset(scene, a.res.size()),
        _ => Camera::orbit(scene, view, a.views, a.res.size()),
    }
}

pub(crate) fn rasterize_view(
    scene: &Scene,
    view: usize,
    a: &ViewArgs,
) -> Result<(FragmentLists, f64)> {
    check_view(view, a.views)?;
    let cam = view_camera(scene, view, a);
    let t = Instant::now();
    let fl = raster::rasterize(scene, &cam, a.res.size())?;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    eprintln!(
        "{}: {} triangles, view {view}/{}, {}: {} fragments, max depth complexity {} ({ms:.0} ms)",
        scene.name,
        scene.triangle_count(),
        a.views,
        a.res,
        fl.fragment_count(),
        fl.max_depth_complexity(),
    );
    Ok((fl, ms))
}

/// The weights DKB uses: --weights, else the default file when present, at `precision`, or
/// at the one the file names when none is given.
pub(crate) fn load_weights(
    a: &ViewArgs,
    precision: Option<Precision>,
    required: bool,
) -> Result<Option<Mlp>> {
    let path = match &a.weights {
        Some(p) => p.clone(),
        None => match default_weights() {
            Some(p) => p,
            None if required => bail!(
                "dkb needs network weights: pass --weights FILE (or train the default ones with `make train`)"
            ),
            None => return Ok(None),
        },
    };
    let m = Mlp::load(&path)?;
    match precision {
        Some(p) => Ok(Some(m.at_precision(p)?)),
        None => Ok(Some(m)),
    }
}

/// The k each pixel uses, min(k, n).
pub(crate) fn k_used(k: &[u32], counts: &[u32]) -> Vec<f32> {
    k.iter()
        .zip(counts)
        .map(|(&k, &n)| k.min(n) as f32)
        .collect()
}

/// min(k, n) per pixel as a heat map tile, scaled by its maximum.
pub(crate) fn kmap_rgb8(fl: &FragmentLists, k: &[u32]) -> (Vec<u8>, u32) {
    let counts = fl.counts();
    let covered: Vec<bool> = counts.iter().map(|&n| n > 0).collect();
    let used = k_used(k, &counts);
    let max = used.iter().copied().fold(0.0, f32::max);
    (image_io::heat_rgb8(&used, &covered, max), max as u32)
}
