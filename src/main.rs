//! `dhoit`: deep hybrid order-independent transparency: render, compare and benchmark.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use dhoit_runtime::budget::{Budget, FragmentBudget, format_bytes};
use dhoit_runtime::dump;
use dhoit_runtime::frame::{Equal, Frame, Method, Options, Renderer};
use dhoit_runtime::image_io::{self, Montage};
use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::raster::{self, FragmentLists};
use dhoit_runtime::scene::{self, Camera, Opacity, Scene};
use std::path::{Path, PathBuf};
use std::time::Instant;

mod bench;

/// The default weights (`make train` writes them): looked up in the working directory, then in
/// the source tree this binary was built from.
fn default_weights() -> Option<PathBuf> {
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
    Compare(CompareArgs),
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
}

#[derive(Args, Clone)]
struct ViewArgs {
    /// Resolution WIDTHxHEIGHT.
    #[arg(long, default_value = "640x480")]
    res: String,
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
    #[arg(long, default_value = "2fpp")]
    budget: String,
    /// What the budget fixes: slots (F; bytes follow from the method's layout) or bytes (the
    /// memory M; F follows from the layout, a budget in slots or % sets M by the per-pixel-k
    /// layout).
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
    /// Budget the features describe (feature 9 is F / sum n), for the DKB layout.
    #[arg(long, default_value = "2fpp")]
    budget: String,
    /// Keep at most this many covered pixels, evenly spaced (all by default).
    #[arg(long)]
    limit: Option<usize>,
    /// Output: safetensors with `features` f32 [N,12] and `pixel` u32 [N].
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args)]
struct CompareArgs {
    /// Scenes, comma separated: built-in names or .gltf/.glb paths.
    #[arg(
        long = "scene",
        alias = "scenes",
        value_delimiter = ',',
        default_value = "particles"
    )]
    scenes: Vec<String>,
    /// Views to render, comma separated.
    #[arg(
        long = "view",
        alias = "view-list",
        value_delimiter = ',',
        default_value = "0"
    )]
    view_list: Vec<usize>,
    /// Budgets, comma separated: bytes (20MB, 40MiB) or slots per pixel (2fpp).
    #[arg(
        long = "budget",
        alias = "budgets",
        value_delimiter = ',',
        default_value = "2fpp"
    )]
    budgets: Vec<String>,
    /// Methods, comma separated (dkb only when weights are found); all by default.
    #[arg(long, value_delimiter = ',')]
    methods: Vec<String>,
    /// What a budget holds equal across methods: slots (the same F) or bytes (the same memory
    /// M, each method's F from its own layout; the paper's protocol).
    #[arg(long, default_value = "slots", value_parser = parse_equal)]
    equal: Equal,
    #[command(flatten)]
    common: ViewArgs,
    /// Directory for images, report.json and report.md.
    #[arg(long, default_value = "out/compare")]
    out: PathBuf,
}

fn parse_equal(s: &str) -> std::result::Result<Equal, String> {
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

fn load_scene(name: &str, a: &ViewArgs) -> Result<Scene> {
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

fn rasterize_view(scene: &Scene, view: usize, a: &ViewArgs) -> Result<(FragmentLists, f64)> {
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
fn load_weights(a: &ViewArgs, required: bool) -> Result<Option<Mlp>> {
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
fn kmap_rgb8(fl: &FragmentLists, k: &[u32]) -> (Vec<u8>, u32) {
    let counts = fl.counts();
    let covered: Vec<bool> = counts.iter().map(|&n| n > 0).collect();
    let used: Vec<f32> = k
        .iter()
        .zip(&counts)
        .map(|(&k, &n)| k.min(n) as f32)
        .collect();
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

fn compare(a: CompareArgs) -> Result<()> {
    let budgets: Vec<Budget> = a
        .budgets
        .iter()
        .map(|b| Budget::parse(b))
        .collect::<Result<_, _>>()?;
    let mut methods: Vec<Method> = if a.methods.is_empty() {
        Method::ALL.to_vec()
    } else {
        a.methods
            .iter()
            .map(|m| Method::parse(m))
            .collect::<Result<_, _>>()?
    };
    if !methods.contains(&Method::Abuffer) {
        methods.insert(0, Method::Abuffer);
    }
    let weights = load_weights(
        &a.common,
        !a.methods.is_empty() && methods.contains(&Method::Dkb),
    )?;
    if weights.is_none() && methods.contains(&Method::Dkb) {
        eprintln!(
            "note: no weights found ({} or --weights), dkb left out",
            dhoit_train::cli::DEFAULT_WEIGHTS
        );
        methods.retain(|&m| m != Method::Dkb);
    }
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let mut records = Vec::new();
    let mut md =
        String::from("# dhoit comparison\n\nMSE against the A-buffer image (linear RGB).\n");
    for name in &a.scenes {
        let scene = load_scene(name, &a.common)?;
        let label = scene::file_label(name);
        for &view in &a.view_list {
            let (fl, raster_ms) = rasterize_view(&scene, view, &a.common)?;
            for budget in &budgets {
                let options = Options {
                    weights: weights.as_ref(),
                    equal: a.equal,
                    ..Options::new(*budget, a.common.background)
                };
                let renderer = Renderer::new(&fl, options);
                // A method the budget cannot hold (FKB and MLAB need a slot for every pixel) is
                // reported and left out of this frame; any other error stops the run.
                let mut frames: Vec<Frame> = Vec::new();
                let mut skipped: Vec<String> = Vec::new();
                for &m in &methods {
                    match renderer.render(m) {
                        Ok(f) => frames.push(f),
                        Err(e @ dhoit_runtime::Error::Budget(..)) if m != Method::Abuffer => {
                            skipped.push(format!("{}: {e}", m.name()));
                        }
                        Err(e) => return Err(e.into()),
                    }
                }
                let reference = frames[0].image.clone();
                let title = format!(
                    "{} view {view}, {}x{}, budget {budget}: {} fragments, max depth {}",
                    scene.name,
                    fl.width,
                    fl.height,
                    fl.fragment_count(),
                    fl.max_depth_complexity()
                );
                println!("\n{title}\n");
                let header = format!(
                    "{:<16} {:>11} {:>9} {:>10} {:>10} {:>11} {:>9}",
                    "method", "MSE", "captured", "F(M)", "used", "allocated", "ms"
                );
                println!("{header}");
                md += &format!(
                    "\n## {title}\n\n| method | MSE | captured | F(M) | sum k / F | allocated | ms |\n|---|---|---|---|---|---|---|\n"
                );
                let tag = format!("{label}_v{view}_{}", budget.to_string().replace(' ', ""));
                let counts = fl.counts();
                let covered: Vec<bool> = counts.iter().map(|&n| n > 0).collect();
                let mut montage = Montage::new(fl.width, fl.height, frames.len() as u32, 3);
                let errors: Vec<Vec<f32>> = frames
                    .iter()
                    .map(|f| {
                        f.image
                            .data
                            .iter()
                            .zip(&reference.data)
                            .map(|(x, r)| (0..3).map(|i| (x[i] - r[i]).powi(2)).sum::<f32>().sqrt())
                            .collect()
                    })
                    .collect();
                let err_max = errors.iter().flatten().copied().fold(0.0f32, f32::max);
                for (col, f) in frames.iter().enumerate() {
                    let mse = f.image.mse(&reference);
                    let captured = f.fragments_captured as f64 / f.fragments_total.max(1) as f64;
                    let used =
                        f.k.iter()
                            .zip(&counts)
                            .map(|(&k, &n)| k.min(n) as u64)
                            .sum::<u64>() as f64
                            / f.budget_fragments.max(1) as f64;
                    let ms = f.allocation_ms + f.composite_ms;
                    println!(
                        "{:<16} {:>11.4e} {:>8.1}% {:>10} {:>9.1}% {:>11} {:>9.1}",
                        f.method.name(),
                        mse,
                        100.0 * captured,
                        f.budget_fragments,
                        100.0 * used,
                        format_bytes(f.allocated_bytes),
                        ms
                    );
                    md += &format!(
                        "| {} | {:.4e} | {:.1}% | {} | {:.1}% | {} | {:.1} |\n",
                        f.method.name(),
                        mse,
                        100.0 * captured,
                        f.budget_fragments,
                        100.0 * used,
                        format_bytes(f.allocated_bytes),
                        ms
                    );
                    image_io::write_png(
                        &a.out.join(format!("{tag}_{}.png", f.method.name())),
                        &f.image,
                    )?;
                    montage.put(col as u32, 0, &image_io::to_srgb8(&f.image));
                    montage.put(col as u32, 1, &kmap_rgb8(&fl, &f.k).0);
                    montage.put(
                        col as u32,
                        2,
                        &image_io::heat_rgb8(&errors[col], &covered, err_max),
                    );
                    let mut rec = serde_json::json!({
                        "scene": scene.name, "view": view, "width": fl.width, "height": fl.height,
                        "budget": budget.to_string(), "method": f.method.name(), "mse": mse,
                        "fragments_total": f.fragments_total, "fragments_captured": f.fragments_captured,
                        "budget_fragments": f.budget_fragments, "budget_bytes": f.budget_bytes,
                        "allocated_bytes": f.allocated_bytes,
                        "ms": {"raster": raster_ms, "allocation": f.allocation_ms, "composite": f.composite_ms},
                    });
                    if let Some(rep) = &f.optimal {
                        rec["optimal"] = serde_json::to_value(rep)?;
                        rec["optimal"]["gap"] = rep.gap().into();
                    }
                    records.push(rec);
                }
                for sk in &skipped {
                    println!("not run: {sk}");
                    md += &format!("\nnot run: {sk}\n");
                }
                if let Some(rep) = frames.iter().find_map(|f| f.optimal) {
                    let line = format!(
                        "optimal allocation: total error {:.4e} ({}), certified gap {:.2e} ({:.2}% of the total)",
                        rep.total,
                        rep.chosen,
                        rep.gap(),
                        100.0 * rep.gap() / rep.total.max(1e-300)
                    );
                    println!("{line}");
                    md += &format!("\n{line}\n");
                }
                let pic = format!("{tag}_montage.png");
                montage.write(&a.out.join(&pic))?;
                let order: Vec<&str> = frames.iter().map(|f| f.method.name()).collect();
                md += &format!(
                    "\n![{tag}]({pic})\n\nColumns: {}. Rows: image; k(p) used (dark blue 0 to yellow: the method's max); colour error |C - C_exact| (one scale for the row).\n",
                    order.join(", ")
                );
            }
        }
    }
    // Summary: mean MSE of each method per budget over every frame.
    let mut summary = String::from("\nmean MSE over all frames\n");
    let mut md_sum = String::from("\n## Summary: mean MSE over all frames\n\n| budget |");
    let names: Vec<&str> = methods
        .iter()
        .filter(|&&m| m != Method::Abuffer)
        .map(|m| m.name())
        .collect();
    summary += &format!("{:<10}", "budget");
    for n in &names {
        summary += &format!(" {n:>16}");
        md_sum += &format!(" {n} |");
    }
    md_sum += &format!("\n|---|{}\n", "---|".repeat(names.len()));
    for budget in &budgets {
        let b = budget.to_string();
        summary += &format!("\n{b:<10}");
        md_sum += &format!("| {b} |");
        for n in &names {
            let v: Vec<f64> = records
                .iter()
                .filter(|r| r["budget"] == b.as_str() && r["method"] == *n)
                .filter_map(|r| r["mse"].as_f64())
                .collect();
            if v.is_empty() {
                summary += &format!(" {:>16}", "n/a");
                md_sum += " n/a |";
                continue;
            }
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            summary += &format!(" {mean:>16.4e}");
            md_sum += &format!(" {mean:.4e} |");
        }
        md_sum += "\n";
    }
    println!("{summary}");
    md += &md_sum;
    let text = serde_json::to_string_pretty(&records)?;
    dhoit_runtime::tensors::write_atomic(&a.out.join("report.json"), text.as_bytes())?;
    dhoit_runtime::tensors::write_atomic(&a.out.join("report.md"), md.as_bytes())?;
    println!(
        "\nimages, side-by-side montages, report.json and report.md -> {}",
        a.out.display()
    );
    Ok(())
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
        Command::Render(a) => render(a),
        Command::Compare(a) => compare(a),
        Command::Dataset(a) => dhoit_train::cli::dataset(a).map_err(Into::into),
        Command::Train(a) => dhoit_train::cli::train(a).map_err(Into::into),
        Command::Predict(a) => dhoit_train::cli::predict(a).map_err(Into::into),
        Command::Score(a) => dhoit_train::cli::score(a).map_err(Into::into),
        Command::Features(a) => features(a),
        Command::Bench(a) => bench::run(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
