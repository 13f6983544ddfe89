//! `dhoit`: deep hybrid order-independent transparency: render, compare and benchmark.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use dhoit_runtime::budget::{Budget, format_bytes};
use dhoit_runtime::composite::Image;
use dhoit_runtime::frame::{self, Frame, Method};
use dhoit_runtime::raster::{self, FragmentLists};
use dhoit_runtime::scene::{self, Camera, Opacity, Scene};
use dhoit_runtime::{dump, image_io};
use std::path::{Path, PathBuf};
use std::time::Instant;

mod bench;

#[derive(Parser)]
#[command(
    name = "dhoit",
    version,
    about = "Deep hybrid order-independent transparency",
    long_about = "Deep hybrid order-independent transparency.\n\n\
        Renders many overlapping transparent surfaces with a k-buffer whose per-pixel k is \
        decided within a fixed memory budget, beside the exact A-buffer and the baselines \
        (fixed k-buffer, MLAB).\n\n\
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
    /// Render one view with every method, print a quality table and write images + report.json.
    Compare(CompareArgs),
    /// Measure CPU rasterization and compositing throughput; prints JSON.
    Bench(bench::BenchArgs),
}

#[derive(Args, Clone)]
struct SceneArgs {
    /// Built-in scene name (optionally `name:seed`) or path to a .gltf/.glb file.
    #[arg(long, default_value = "particles")]
    scene: String,
    /// Which orbit view to render.
    #[arg(long, default_value_t = 0)]
    view: usize,
    /// Number of orbit views around the scene (view I is at angle I/N of a turn).
    #[arg(long, default_value_t = scene::DEFAULT_VIEWS)]
    views: usize,
    /// Resolution WIDTHxHEIGHT.
    #[arg(long, default_value = "640x480")]
    res: String,
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
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Method: abuffer (exact reference), fkb (fixed k-buffer) or mlab.
    #[arg(long, default_value = "abuffer")]
    method: String,
    /// Where to run: cpu (the reference renderer). The GPU renderer is not built yet.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Memory budget: bytes (20MB, 40MiB) or slots per pixel (2fpp).
    #[arg(long, default_value = "2fpp")]
    budget: String,
    /// Output image (sRGB PNG).
    #[arg(long)]
    out: PathBuf,
    /// Also write the fragment dump (fragments.safetensors) into this directory.
    #[arg(long)]
    dump: Option<PathBuf>,
    /// Also write a heat map of the per-pixel k.
    #[arg(long)]
    kmap: Option<PathBuf>,
}

#[derive(Args)]
struct CompareArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Memory budget: bytes (20MB, 40MiB) or slots per pixel (2fpp).
    #[arg(long, default_value = "2fpp")]
    budget: String,
    /// Directory for the images and report.json.
    #[arg(long, default_value = "out/compare")]
    out: PathBuf,
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

/// A scene seen from one view, rasterized.
struct Prepared {
    scene: Scene,
    fragments: FragmentLists,
    raster_ms: f64,
}

fn prepare(a: &SceneArgs) -> Result<Prepared> {
    let (w, h) = raster::parse_resolution(&a.res)?;
    let opacity = if a.material_alpha {
        Opacity::Material
    } else {
        Opacity::Uniform(a.opacity)
    };
    let mut scene = scene::load(&a.scene, opacity)?;
    if let Some(seed) = a.shuffle {
        scene = scene.shuffled(seed);
    }
    if a.views == 0 || a.view >= a.views {
        bail!(
            "view {} does not exist: there are {} views (0..{})",
            a.view,
            a.views,
            a.views
        );
    }
    let cam = Camera::orbit(&scene, a.view, a.views, w, h);
    let t = Instant::now();
    let fragments = raster::rasterize(&scene, &cam, w, h)?;
    let raster_ms = t.elapsed().as_secs_f64() * 1e3;
    eprintln!(
        "{}: {} triangles, view {}/{}, {}x{}: {} fragments, max depth complexity {} ({:.0} ms)",
        scene.name,
        scene.triangle_count(),
        a.view,
        a.views,
        w,
        h,
        fragments.fragment_count(),
        fragments.max_depth_complexity(),
        raster_ms
    );
    Ok(Prepared {
        scene,
        fragments,
        raster_ms,
    })
}

fn write_kmap(path: &Path, fl: &FragmentLists, k: &[u32]) -> Result<()> {
    let counts = fl.counts();
    let covered: Vec<bool> = counts.iter().map(|&n| n > 0).collect();
    let used: Vec<f32> = k
        .iter()
        .zip(&counts)
        .map(|(&k, &n)| k.min(n) as f32)
        .collect();
    let max = used.iter().copied().fold(0.0, f32::max);
    image_io::write_heatmap(path, fl.width, fl.height, &used, &covered, max)?;
    Ok(())
}

fn render(a: RenderArgs) -> Result<()> {
    if a.device != "cpu" {
        bail!(
            "device '{}' is not available: only the CPU reference renderer (--device cpu) exists so far",
            a.device
        );
    }
    let method = Method::parse(&a.method)?;
    let budget = Budget::parse(&a.budget)?;
    let p = prepare(&a.scene)?;
    let f = frame::render(&p.fragments, method, budget, a.scene.background)?;
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
    if let Some(path) = &a.kmap {
        write_kmap(path, &p.fragments, &f.k)?;
    }
    if let Some(dir) = &a.dump {
        let d = dump::Dump {
            fragments: p.fragments,
            k: f.k,
            image: f.image,
            method: method.name().into(),
            budget_bytes: f.budget_bytes,
            budget_fragments: f.budget_fragments,
            background: a.scene.background,
        };
        let path = dump::write(dir, &d)?;
        println!("dump -> {}", path.display());
    }
    Ok(())
}

fn compare(a: CompareArgs) -> Result<()> {
    let budget = Budget::parse(&a.budget)?;
    let p = prepare(&a.scene)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let mut frames: Vec<Frame> = Vec::new();
    for m in Method::ALL {
        frames.push(frame::render(&p.fragments, m, budget, a.scene.background)?);
    }
    let reference: Image = frames[0].image.clone();
    println!(
        "\n{} ({} triangles), view {}, {}x{}, budget {}: {} fragments, max depth {}\n",
        p.scene.name,
        p.scene.triangle_count(),
        a.scene.view,
        p.fragments.width,
        p.fragments.height,
        budget,
        p.fragments.fragment_count(),
        p.fragments.max_depth_complexity()
    );
    println!(
        "{:<8} {:>12} {:>10} {:>12} {:>12} {:>10}",
        "method", "MSE", "captured", "F(M)", "allocated", "time ms"
    );
    let mut records = Vec::new();
    for f in &frames {
        let mse = f.image.mse(&reference);
        let captured = f.fragments_captured as f64 / f.fragments_total.max(1) as f64;
        println!(
            "{:<8} {:>12.3e} {:>9.1}% {:>12} {:>12} {:>10.1}",
            f.method.name(),
            mse,
            100.0 * captured,
            f.budget_fragments,
            format_bytes(f.allocated_bytes),
            f.allocation_ms + f.composite_ms
        );
        let png = a.out.join(format!("{}.png", f.method.name()));
        image_io::write_png(&png, &f.image)?;
        records.push(serde_json::json!({
            "scene": p.scene.name, "view": a.scene.view, "width": p.fragments.width,
            "height": p.fragments.height, "budget": budget.to_string(), "method": f.method.name(),
            "mse": mse, "fragments_total": f.fragments_total, "fragments_captured": f.fragments_captured,
            "budget_fragments": f.budget_fragments, "budget_bytes": f.budget_bytes,
            "allocated_bytes": f.allocated_bytes, "raster_ms": p.raster_ms,
            "allocation_ms": f.allocation_ms, "composite_ms": f.composite_ms,
        }));
    }
    let report = a.out.join("report.json");
    dhoit_runtime::tensors::write_atomic(
        &report,
        serde_json::to_string_pretty(&records)?.as_bytes(),
    )?;
    println!("\nimages and report.json -> {}", a.out.display());
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
        Command::Bench(a) => bench::run(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
