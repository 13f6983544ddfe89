//! `dhoit`: deep hybrid order-independent transparency: render, compare and benchmark.

use anyhow::{Result, bail};
use clap::{Args, Parser, Subcommand};
use dhoit_runtime::budget::{Budget, FragmentBudget, format_bytes};
use dhoit_runtime::dump;
use dhoit_runtime::fragment::FragmentLists;
use dhoit_runtime::frame::{Equal, Method, Options, Renderer};
use dhoit_runtime::image_io;
use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::raster;
use dhoit_runtime::scene::{self, Camera, Opacity, Scene};
use std::path::{Path, PathBuf};
use std::time::Instant;

mod bench;
mod compare;
mod trade;

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

#[derive(Parser)]
#[command(
    name = "dhoit",
    version,
    about = "Deep hybrid order-independent transparency",
    long_about = "Deep hybrid order-independent transparency.\n\n\
        Renders many overlapping transparent surfaces with a k-buffer whose per-pixel k is \
        decided within a fixed memory budget, beside the exact A-buffer and the baselines.\n\n\
        Methods: abuffer (exact reference), fkb (fixed k-buffer), vkb (importance-map variable \
        k-buffer), dkb (deep k-buffer: the network's importance), optimal (the optimal \
        allocation), greedy-paper and greedy-increase (the paper's backward greedy, two heap \
        keys), mlab (multi-layer alpha blending).\n\n\
        Budgets are bytes with units (20MB, 40MiB) or average fragment slots per pixel (2fpp).\n\
        Scenes are built-in names (see `dhoit scenes`) or paths to .gltf/.glb files."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the built-in scenes (and glTF files under $DHOIT_SCENES) with triangle counts.
    Scenes,
    /// Render one view of a scene with one method.
    Render(RenderArgs),
    /// Render scenes x views x budgets with several methods: a quality table, images, side-by-side
    /// pictures, report.json and report.md.
    #[command(alias = "eval")]
    Compare(compare::CompareArgs),
    /// Generate a training dataset: features and optimal-allocation targets from scenes.
    Dataset(dhoit_train::cli::DatasetArgs),
    /// Train the importance network on the CPU (burn) and export safetensors weights.
    Train(dhoit_train::cli::TrainArgs),
    /// Predict importance for a features file with burn inference.
    Predict(dhoit_train::cli::PredictArgs),
    /// Score allocations from error curves, no images: optimal, VKB and the network(s) per scene
    /// and budget, as DKB/VKB and DKB/optimal ratios (fast; `compare` renders the images).
    Score(dhoit_train::cli::ScoreArgs),
    /// Export the 12 network features of one view's covered pixels (for predict).
    Features(FeaturesArgs),
    /// Measure CPU rasterization, compositing, allocation and training throughput; prints JSON.
    Bench(bench::BenchArgs),
    /// The speed-accuracy trade: networks of several sizes (the default and those shipped in
    /// data/nets/) on scenes, importance-pass time against MSE and FLIP, the Pareto front
    /// marked; trade.json, trade.md and plots.
    Trade(trade::TradeArgs),
    /// The smallest network whose MSE on a scene is within --target of the optimal
    /// allocation's; writes its weights.
    Fit(trade::FitArgs),
    /// Write a scene (a built-in, or a glTF file) as binary glTF 2.0: positions, vertex colours
    /// and alpha, to open it in other tools or to test the glTF loader without real scenes.
    Export(ExportArgs),
}

#[derive(Args)]
struct ExportArgs {
    /// A built-in scene name (`cad`, `particles:7`) or a .gltf/.glb path.
    #[arg(long)]
    scene: String,
    /// The .glb file to write (written whole or not at all).
    #[arg(long)]
    out: PathBuf,
    /// Give every surface this opacity instead of keeping the scene's own alpha.
    #[arg(long)]
    opacity: Option<f32>,
}

fn export(a: ExportArgs) -> Result<()> {
    if !a
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
    {
        bail!(
            "--out {}: export writes binary glTF, give a .glb file name",
            a.out.display()
        );
    }
    let opacity = a.opacity.map_or(Opacity::Material, Opacity::Uniform);
    let s = scene::load(&a.scene, opacity)?;
    scene::gltf::export(&s, &a.out)?;
    println!(
        "{}: {} triangles -> {}",
        s.name,
        s.triangle_count(),
        a.out.display()
    );
    Ok(())
}

#[derive(Args, Clone)]
pub(crate) struct ViewArgs {
    /// Resolution WIDTHxHEIGHT.
    #[arg(long, default_value = "640x480", allow_hyphen_values = true)]
    pub(crate) res: String,
    /// Number of orbit views around the scene (view I is at angle I/N of a turn).
    #[arg(long, default_value_t = scene::DEFAULT_VIEWS)]
    views: usize,
    /// Uniform opacity of every surface (the reference uses 0.33).
    #[arg(long, default_value_t = 0.33, conflicts_with = "material_alpha")]
    opacity: f32,
    /// Keep material alpha instead of one uniform opacity.
    #[arg(long)]
    material_alpha: bool,
    /// Permute the triangle submission order with this seed.
    #[arg(long)]
    shuffle: Option<u64>,
    /// Background colour, linear R,G,B in [0, 1].
    #[arg(long, default_value = "1,1,1", value_parser = parse_rgb)]
    background: [f32; 3],
    /// Network weights for dkb (default: data/weights.safetensors when it exists).
    #[arg(long)]
    weights: Option<PathBuf>,
}

#[derive(Args)]
struct RenderArgs {
    /// Built-in scene name (optionally `name:seed`) or path to a .gltf/.glb file.
    #[arg(long, default_value = "particles")]
    scene: String,
    /// Which orbit view to render.
    #[arg(long, default_value_t = 0)]
    view: usize,
    #[command(flatten)]
    common: ViewArgs,
    /// Method (see `dhoit --help`).
    #[arg(long, default_value = "abuffer")]
    method: String,
    /// Where to run: cpu (the reference renderer) or gpu (wgpu; every method: optimal and the
    /// greedy allocations have their k computed on the CPU, MLAB blends from the A-buffer).
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Memory budget: bytes (20MB, 40MiB), slots per pixel (2fpp) or a share of the frame's
    /// fragments (25%).
    #[arg(long, default_value = "2fpp", allow_hyphen_values = true)]
    budget: String,
    /// What the budget fixes: slots (F; bytes follow from the method's layout) or bytes (the
    /// memory M; F follows from the layout, a budget in slots or % sets M to what DKB's layout
    /// needs for that F).
    #[arg(long, default_value = "slots", value_parser = parse_equal)]
    equal: Equal,
    /// Output image (sRGB PNG).
    #[arg(long)]
    out: PathBuf,
    /// Also write the fragment dump (fragments.safetensors) into this directory.
    #[arg(long)]
    dump: Option<PathBuf>,
    /// Also write a heat map of the per-pixel k actually used (min(k, n)).
    #[arg(long)]
    kmap: Option<PathBuf>,
}

#[derive(Args)]
struct FeaturesArgs {
    /// Built-in scene name (optionally `name:seed`) or path to a .gltf/.glb file.
    #[arg(long, default_value = "particles")]
    scene: String,
    #[arg(long, default_value_t = 0)]
    view: usize,
    #[command(flatten)]
    common: ViewArgs,
    /// Budget the features describe (F / sum n is a feature), for the DKB layout.
    #[arg(long, default_value = "2fpp", allow_hyphen_values = true)]
    budget: String,
    /// Keep at most this many covered pixels, evenly spaced (all by default).
    #[arg(long)]
    limit: Option<usize>,
    /// Output: safetensors with `features` f32 [N,12] and `pixel` u32 [N].
    #[arg(long)]
    out: PathBuf,
}

pub(crate) fn parse_equal(s: &str) -> std::result::Result<Equal, String> {
    Equal::parse(s).map_err(|e| e.to_string())
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

pub(crate) fn load_scene(name: &str, a: &ViewArgs) -> Result<Scene> {
    let opacity = if a.material_alpha {
        Opacity::Material
    } else {
        Opacity::Uniform(a.opacity)
    };
    let mut scene = scene::load(name, opacity)?;
    if let Some(seed) = a.shuffle {
        scene = scene.shuffled(seed);
    }
    Ok(scene)
}

pub(crate) fn rasterize_view(
    scene: &Scene,
    view: usize,
    a: &ViewArgs,
) -> Result<(FragmentLists, f64)> {
    let (w, h) = raster::parse_resolution(&a.res)?;
    if a.views == 0 || view >= a.views {
        bail!(
            "view {view} does not exist: there are {} views (0..{})",
            a.views,
            a.views
        );
    }
    let cam = Camera::orbit(scene, view, a.views, w, h);
    let t = Instant::now();
    let fl = raster::rasterize(scene, &cam, w, h)?;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    eprintln!(
        "{}: {} triangles, view {view}/{}, {w}x{h}: {} fragments, max depth complexity {} ({ms:.0} ms)",
        scene.name,
        scene.triangle_count(),
        a.views,
        fl.fragment_count(),
        fl.max_depth_complexity(),
    );
    Ok((fl, ms))
}

/// The weights DKB uses: --weights, else the default file when present.
pub(crate) fn load_weights(a: &ViewArgs, required: bool) -> Result<Option<Mlp>> {
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
    Ok(Some(Mlp::load(&path)?))
}

/// min(k, n) per pixel as a heat map tile, scaled by its maximum.
/// The k each pixel uses, min(k, n).
pub(crate) fn k_used(k: &[u32], counts: &[u32]) -> Vec<f32> {
    k.iter()
        .zip(counts)
        .map(|(&k, &n)| k.min(n) as f32)
        .collect()
}

pub(crate) fn kmap_rgb8(fl: &FragmentLists, k: &[u32]) -> (Vec<u8>, u32) {
    let counts = fl.counts();
    let covered: Vec<bool> = counts.iter().map(|&n| n > 0).collect();
    let used = k_used(k, &counts);
    let max = used.iter().copied().fold(0.0, f32::max);
    (image_io::heat_rgb8(&used, &covered, max), max as u32)
}

fn render(a: RenderArgs) -> Result<()> {
    let method = Method::parse(&a.method)?;
    let on_gpu = match a.device.as_str() {
        "cpu" => false,
        "gpu" => true,
        d => bail!("device '{d}' is not available: use --device cpu or --device gpu"),
    };
    let budget = Budget::parse(&a.budget)?;
    let weights = load_weights(&a.common, method == Method::Dkb)?;
    let scene = load_scene(&a.scene, &a.common)?;
    let (fl, _) = rasterize_view(&scene, a.view, &a.common)?;
    let options = Options {
        weights: weights.as_ref(),
        equal: a.equal,
        ..Options::new(budget, a.common.background)
    };
    let mut f = Renderer::new(&fl, options).render(method)?;
    let mut gpu_fragments = None;
    if on_gpu {
        let gpu = dhoit_runtime::gpu::Gpu::new()?;
        eprintln!("GPU: {}", gpu.adapter);
        let (w, h) = (fl.width, fl.height);
        let cam = Camera::orbit(&scene, a.view, a.common.views, w, h);
        let gpu_budget = match budget {
            Budget::Share(ppm) if a.equal == Equal::Slots => FragmentBudget::Share(ppm),
            _ => FragmentBudget::Slots(f.budget_fragments),
        };
        let slots = match method {
            Method::Abuffer => None,
            Method::Fkb => Some(dhoit_runtime::gpu::Slots::Uniform(f.k[0])),
            // MLAB on the GPU blends from the A-buffer (exact memory, not the budget's rows).
            Method::Mlab => Some(dhoit_runtime::gpu::Slots::Mlab(f.k[0])),
            // A share of the fragments is resolved on the GPU from its own count.
            Method::Vkb => Some(dhoit_runtime::gpu::Slots::Vkb(options.vkb, gpu_budget)),
            Method::Dkb => Some(dhoit_runtime::gpu::Slots::Dkb(
                weights.as_ref().expect("dkb loaded its weights"),
                gpu_budget,
            )),
            _ => Some(dhoit_runtime::gpu::Slots::PerPixel(&f.k)),
        };
        let g = gpu.render(&scene, &cam, w, h, a.common.background, slots)?;
        let passes: Vec<String> = g
            .pass_ms
            .iter()
            .map(|(n, ms)| format!("{n} {ms:.2} ms"))
            .collect();
        println!("GPU passes: {}", passes.join(", "));
        f.image = g.image;
        f.allocated_bytes = g.allocated_bytes;
        if let Some((_, bases, _)) = &g.slots {
            // The GPU's own k (VKB and DKB allocate on the device); what it captures follows.
            f.k = bases.windows(2).map(|b| b[1] - b[0]).collect();
            f.fragments_captured =
                f.k.iter()
                    .zip(fl.counts())
                    .map(|(&k, n)| k.min(n) as u64)
                    .sum();
        }
        gpu_fragments = match g.fragments {
            Some(fr) => Some(fr),
            None if a.dump.is_some() => {
                gpu.render(&scene, &cam, w, h, a.common.background, None)?
                    .fragments
            }
            None => None,
        };
    }
    image_io::write_png(&a.out, &f.image)?;
    println!(
        "{}: k up to {}, {:.1}% of {} fragments captured, F(M) = {}, budget {}, allocated {} -> {}",
        method.name(),
        f.k.iter().max().unwrap_or(&0),
        100.0 * f.fragments_captured as f64 / f.fragments_total.max(1) as f64,
        f.fragments_total,
        f.budget_fragments,
        format_bytes(f.budget_bytes),
        format_bytes(f.allocated_bytes),
        a.out.display()
    );
    if let Some(rep) = &f.optimal {
        println!(
            "optimal: total error {:.6e} ({}), lower bound {:.6e}, gap {:.3e}; greedy as printed {:.6e}, \
             increase-keyed {:.6e}",
            rep.total,
            rep.chosen,
            rep.lower_bound,
            rep.gap(),
            rep.greedy_paper_total,
            rep.greedy_increase_total
        );
    }
    if let Some(path) = &a.kmap {
        let (rgb, max) = kmap_rgb8(&fl, &f.k);
        image_io::write_rgb8(path, fl.width, fl.height, &rgb)?;
        println!("k map (0..{max}) -> {}", path.display());
    }
    if let Some(dir) = &a.dump {
        let d = dump::Dump {
            fragments: gpu_fragments.unwrap_or(fl),
            k: f.k,
            image: f.image,
            method: method.name().into(),
            budget_bytes: f.budget_bytes,
            budget_fragments: f.budget_fragments,
            background: a.common.background,
        };
        let path = dump::write(dir, &d)?;
        println!("dump -> {}", path.display());
    }
    Ok(())
}

fn features(a: FeaturesArgs) -> Result<()> {
    let budget = Budget::parse(&a.budget)?;
    let scene = load_scene(&a.scene, &a.common)?;
    let (fl, _) = rasterize_view(&scene, a.view, &a.common)?;
    let (_, f) = budget.resolve(
        &dhoit_runtime::budget::DKB,
        fl.pixel_count() as u64,
        fl.fragment_count() as u64,
    )?;
    let feats = dhoit_runtime::importance::features(&fl, f);
    let covered: Vec<usize> = (0..fl.pixel_count()).filter(|&p| fl.count(p) > 0).collect();
    let keep: Vec<usize> = match a.limit {
        Some(l) if l > 0 && l < covered.len() => {
            (0..l).map(|i| covered[i * covered.len() / l]).collect()
        }
        Some(0) => bail!("--limit must be positive"),
        _ => covered,
    };
    let rows: Vec<f32> = keep.iter().flat_map(|&p| feats[p]).collect();
    let pixels: Vec<u32> = keep.iter().map(|&p| p as u32).collect();
    let meta = std::collections::HashMap::from([
        ("scene".to_string(), scene.name.clone()),
        ("view".to_string(), a.view.to_string()),
        ("width".to_string(), fl.width.to_string()),
        ("height".to_string(), fl.height.to_string()),
        ("budget_fragments".to_string(), f.to_string()),
    ]);
    use dhoit_runtime::tensors::{self, Entry};
    tensors::write(
        &a.out,
        &[
            Entry::f32(
                "features",
                vec![keep.len(), dhoit_runtime::importance::FEATURES],
                &rows,
            ),
            Entry::u32("pixel", vec![keep.len()], &pixels),
        ],
        meta,
    )?;
    println!("{} pixels' features -> {}", keep.len(), a.out.display());
    Ok(())
}

/// `dhoit predict`: burn, the CPU twin, or the GPU's WGSL network.
fn predict(a: dhoit_train::cli::PredictArgs) -> Result<()> {
    if a.device != "gpu" {
        return Ok(dhoit_train::cli::predict(a)?);
    }
    let gpu = dhoit_runtime::gpu::Gpu::new()?;
    eprintln!("predict: on {}", gpu.adapter);
    Ok(dhoit_train::cli::predict_with(&a, &|mlp, rows| {
        Ok(gpu.predict(mlp, rows)?)
    })?)
}

fn scenes() -> Result<()> {
    println!("{:<12} {:>10}  description", "built-in", "triangles");
    for (name, desc) in scene::procedural::BUILTIN {
        let s = scene::procedural::build(name).expect("built-in scene");
        println!("{:<12} {:>10}  {}", name, s.triangle_count(), desc);
    }
    match std::env::var_os("DHOIT_SCENES") {
        Some(dir) => {
            println!("\nglTF files under {}:", Path::new(&dir).display());
            let mut files = Vec::new();
            find_gltf(Path::new(&dir), &mut files, 0);
            files.sort();
            for f in files {
                match scene::load(&f.to_string_lossy(), Opacity::Material) {
                    Ok(s) => println!("{:>10}  {}", s.triangle_count(), f.display()),
                    Err(e) => println!("{:>10}  {} ({e})", "error", f.display()),
                }
            }
        }
        None => println!("\n(set DHOIT_SCENES to a folder of .gltf/.glb files to list them too)"),
    }
    Ok(())
}

fn find_gltf(dir: &Path, out: &mut Vec<PathBuf>, depth: usize) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() && depth < 4 {
            find_gltf(&p, out, depth + 1);
        } else if p.extension().is_some_and(|x| x == "gltf" || x == "glb") {
            out.push(p);
        }
    }
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Scenes => scenes(),
        Command::Export(a) => export(a),
        Command::Render(a) => render(a),
        Command::Compare(a) => compare::run(a),
        Command::Dataset(a) => dhoit_train::cli::dataset(a).map_err(Into::into),
        Command::Train(a) => dhoit_train::cli::train(a).map_err(Into::into),
        Command::Predict(a) => predict(a),
        Command::Score(a) => dhoit_train::cli::score(a).map_err(Into::into),
        Command::Features(a) => features(a),
        Command::Bench(a) => bench::run(a),
        Command::Trade(a) => trade::trade(a),
        Command::Fit(a) => trade::fit(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
