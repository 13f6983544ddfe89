//! `dhoit versus`: every OIT method at equal bytes on one chart per budget, GPU frame time
//! (timestamp queries on the adapter at hand) against MSE and FLIP, the Pareto front marked: where
//! DKB sits among what an engine could use instead (WBOIT, MBOIT, the budgeted linked list, FKB,
//! VKB, the exact A-buffer).

use crate::args::{ViewArgs, check_view, load_scenes, load_weights, parse_repeat, rasterize_view};
use anyhow::{Context, Result, bail};
use clap::Args;
use dhoit_runtime::budget::{self, Budget};
use dhoit_runtime::frame::{Method, Options, Renderer};
use dhoit_runtime::gpu::{FrameOptions, Gpu, Slots};
use dhoit_runtime::image_io;
use dhoit_runtime::mlp::Mlp;
use dhoit_train::cli::bar;
use dhoit_train::plot::{self, TradePoint};
use serde::Serialize;
use std::path::PathBuf;

/// `--methods`' default: every method at equal bytes, comma separated.
static DEFAULT_METHODS: std::sync::LazyLock<String> = std::sync::LazyLock::new(|| {
    let names: Vec<&str> = Method::those(Method::at_equal_bytes)
        .iter()
        .map(|m| m.name())
        .collect();
    names.join(",")
});

#[derive(Args)]
pub struct VersusArgs {
    /// Scenes, comma separated: built-in names or .gltf/.glb paths.
    #[arg(
        long = "scene",
        value_delimiter = ',',
        default_value = "particles,hair"
    )]
    scenes: Vec<String>,
    /// Orbit views, comma separated.
    #[arg(long = "view", value_delimiter = ',', default_value = "1")]
    view_list: Vec<usize>,
    /// Memories M, comma separated, as multiples of each frame's exact A-buffer bytes (0.5: half
    /// what the exact answer needs). Every method gets the same M in bytes, its F (or its
    /// moments, or its accumulation targets) from its own layout; a method whose memory does
    /// not fit in M does not run at that M (the table counts its frames).
    #[arg(
        long = "memory",
        value_delimiter = ',',
        default_value = "0.25,0.5,0.75,1"
    )]
    memories: Vec<f64>,
    /// Methods, comma separated; by default every method whose GPU frame keeps to its budget's
    /// bytes (`Method::at_equal_bytes`).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = DEFAULT_METHODS.as_str()
    )]
    methods: Vec<String>,
    /// More networks for DKB beside its weights (--weights, or the default ones), comma
    /// separated weights files: each runs as its own entry, `dkb H1-H2` (the shipped ones are
    /// data/nets/*/weights.safetensors), in the same M, its weights counted in its memory, so
    /// the chart shows what a network's size costs in time, bytes and error beside the other
    /// methods.
    #[arg(long, value_delimiter = ',')]
    networks: Vec<PathBuf>,
    /// The precision every network DKB runs is deployed at (f32, f16, f16-math); by default
    /// each file's own (the default weights say f16).
    #[arg(long)]
    precision: Option<dhoit_runtime::mlp::Precision>,
    /// Timed repetitions of each GPU frame; the fastest is kept.
    #[arg(long, default_value_t = 3, value_parser = parse_repeat)]
    repeat: usize,
    /// Directory for versus.json, versus.md and the plots (versus_BUDGET.svg/.png).
    #[arg(long, default_value = "out/versus")]
    out: PathBuf,
    /// Also write versus.json, versus.md and the plots into this directory (small, committed:
    /// `make versus` writes docs/).
    #[arg(long)]
    summary: Option<PathBuf>,
    #[command(flatten)]
    common: ViewArgs,
    #[command(flatten)]
    params: crate::args::MethodParams,
}

/// One method on one frame.
#[derive(Clone, Debug, Serialize)]
pub struct Measure {
    pub scene: String,
    pub view: usize,
    pub mse: f64,
    pub flip: f64,
    /// The GPU frame's passes, milliseconds (the fastest of the repetitions).
    pub gpu_ms: f64,
    /// Bytes the method allocated, a frame pixel.
    pub bytes_per_pixel: f64,
    /// Whether the k-buffer rendered the exact A-buffer, no dearer at this M.
    pub exact: bool,
}

/// One method at one budget, over every scene and view.
#[derive(Clone, Debug, Serialize)]
pub struct Point {
    pub method: String,
    /// Geometric means (MSE floored as `compare`'s summary does), FLIP's arithmetic mean.
    pub gpu_ms: f64,
    pub mse: f64,
    pub flip: f64,
    pub bytes_per_pixel: f64,
    /// Frames on which no other method is as fast and as accurate (MSE and FLIP).
    pub front_frames: usize,
    /// On the front of the means: no other method that ran every frame is at least as good in
    /// time, MSE and FLIP, and better in one (false for a method that ran fewer frames).
    pub front: bool,
    pub frames: Vec<Measure>,
}

#[derive(Clone, Debug, Serialize)]
pub struct BudgetTrade {
    pub budget: String,
    /// M as a multiple of each frame's exact A-buffer bytes.
    pub memory: f64,
    /// The frames (a method that did not fit in M ran fewer).
    pub frames: usize,
    pub points: Vec<Point>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub adapter: String,
    pub resolution: String,
    pub views: Vec<usize>,
    pub scenes: Vec<String>,
    pub budgets: Vec<BudgetTrade>,
}

/// Whether `a` dominates `b` on (time, MSE, FLIP).
fn dominates(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(&b).all(|(x, y)| x <= y) && a.iter().zip(&b).any(|(x, y)| x < y)
}

/// Flags the keys no other key dominates.
pub fn front(keys: &[[f64; 3]]) -> Vec<bool> {
    (0..keys.len())
        .map(|i| {
            !keys
                .iter()
                .enumerate()
                .any(|(j, o)| j != i && dominates(*o, keys[i]))
        })
        .collect()
}

/// One entry of the chart: a method, and for DKB the network it runs (`dkb` with its weights,
/// `dkb H1-H2` with each of --networks; None for every other method).
struct Entry {
    method: Method,
    label: String,
    weights: Option<Mlp>,
}

/// The methods asked for, in order, DKB once for its weights and once for each of --networks
/// (right after it, or alone where --networks is given without dkb among the methods).
fn entries(a: &VersusArgs, methods: &[Method]) -> Result<Vec<Entry>> {
    let dkb = methods.contains(&Method::Dkb) || !a.networks.is_empty();
    let weights = load_weights(&a.common, a.precision, dkb)?;
    let mut extra = Vec::new();
    for p in &a.networks {
        let m = Mlp::load(p)?;
        let m = match a.precision {
            Some(pr) => m.at_precision(pr)?,
            None => m,
        };
        let label = format!("dkb {}-{}", m.h1, m.h2);
        if extra.iter().any(|e: &Entry| e.label == label) {
            bail!(
                "--networks: two networks of {}-{}: versus labels DKB's networks by their sizes",
                m.h1,
                m.h2
            );
        }
        extra.push(Entry {
            method: Method::Dkb,
            label,
            weights: Some(m),
        });
    }
    let mut out = Vec::new();
    for &m in methods {
        out.push(Entry {
            method: m,
            label: m.name().to_string(),
            weights: (m == Method::Dkb).then(|| weights.clone()).flatten(),
        });
        if m == Method::Dkb {
            out.append(&mut extra);
        }
    }
    out.append(&mut extra);
    Ok(out)
}

pub fn run(a: VersusArgs) -> Result<()> {
    let methods = checked_methods(&a)?;
    let entries = entries(&a, &methods)?;
    let loaded = load_scenes(&a.scenes, &a.common)?;
    let gpu = Gpu::new().context("versus times every method's GPU frame")?;
    eprintln!("versus: GPU frames timed on {}", gpu.adapter());
    dhoit_runtime::tensors::create_folder(&a.out)?;
    let measures = measure(&a, &entries, &loaded, &gpu)?;
    let frames = a.scenes.len() * a.view_list.len();
    let report = Report {
        adapter: gpu.adapter().to_string(),
        resolution: a.common.res.to_string(),
        views: a.view_list.clone(),
        scenes: loaded.iter().map(|s| s.name.clone()).collect(),
        budgets: a
            .memories
            .iter()
            .zip(&measures)
            .map(|(&x, at_x)| trade_at(x, &entries, at_x, frames))
            .collect(),
    };
    write_outputs(&a, &report)
}

/// The methods asked for, once the memories and views are known to be valid.
fn checked_methods(a: &VersusArgs) -> Result<Vec<Method>> {
    let methods: Vec<Method> = a
        .methods
        .iter()
        .map(|m| Method::parse(m))
        .collect::<std::result::Result<_, _>>()?;
    if methods.is_empty() || a.memories.is_empty() {
        bail!("give at least one method and one memory");
    }
    if let Some(x) = a.memories.iter().find(|x| !(x.is_finite() && **x > 0.0)) {
        bail!("a memory is a positive multiple of the A-buffer's bytes, not {x}");
    }
    for &view in &a.view_list {
        check_view(view, a.common.views)?;
    }
    Ok(methods)
}

/// Every frame of every method at every memory: `[memory][method]`, one [`Measure`] a frame
/// the method runs in that memory (a method whose fixed cost, or whose memory that does not
/// follow the budget, exceeds M does not run there).
fn measure(
    a: &VersusArgs,
    entries: &[Entry],
    loaded: &[dhoit_runtime::scene::Scene],
    gpu: &Gpu,
) -> Result<Vec<Vec<Vec<Measure>>>> {
    let pb = bar(
        (loaded.len() * a.view_list.len() * a.memories.len()) as u64,
        "frames",
    );
    let mut measures = vec![vec![Vec::new(); entries.len()]; a.memories.len()];
    let frame_opts = FrameOptions {
        diagnostics: false,
        // The GPU's frames are timed with the records' batches the CPU counts bytes for.
        decision: dhoit_runtime::budget::Decision {
            record_batches: a.params.record_batches,
            ..Default::default()
        },
        ..FrameOptions::default()
    };
    for s in loaded {
        for &view in &a.view_list {
            let (fl, _) = rasterize_view(s, view, &a.common)?;
            let size = fl.size();
            let cam = dhoit_runtime::scene::Camera::orbit(s, view, a.common.views, size);
            let px = fl.pixel_count() as f64;
            let exact_bytes = budget::ABUFFER
                .allocated_bytes(fl.pixel_count() as u64, fl.fragment_count() as u64);
            for (bi, &x) in a.memories.iter().enumerate() {
                let m_bytes = (x * exact_bytes as f64).floor() as u64;
                let opts = a.params.apply(
                    Options::new(Budget::Bytes(m_bytes), a.common.background),
                    &cam,
                );
                let r = Renderer::new(&fl, opts);
                let exact = r.render(Method::Abuffer)?;
                let exact8 = image_io::to_srgb8(&exact.image);
                // MBOIT takes the most power moments whose targets fit M (unless given).
                let mboit_opts = Options {
                    mboit: a.params.mboit(a.params.mboit_moments.unwrap_or_else(|| {
                        budget::mboit_moments_within(fl.pixel_count() as u64, m_bytes).unwrap_or(4)
                    })),
                    ..opts
                };
                let r_mboit = Renderer::new(&fl, mboit_opts);
                for (mi, e) in entries.iter().enumerate() {
                    let m = e.method;
                    // DKB with the entry's network: its own weights in its layout.
                    let r_dkb;
                    let (r, opts) = match m {
                        Method::Mboit => (&r_mboit, mboit_opts),
                        Method::Dkb => {
                            let dkb_opts = Options {
                                weights: e.weights.as_ref(),
                                ..opts
                            };
                            r_dkb = Renderer::new(&fl, dkb_opts);
                            (&r_dkb, dkb_opts)
                        }
                        _ => (&r, opts),
                    };
                    let cpu = match r.allocate(m) {
                        Ok(al) => al,
                        // A fixed cost above M (or FKB below a slot a pixel): not run.
                        Err(dhoit_runtime::Error::Budget(..)) => continue,
                        Err(e) => return Err(e.into()),
                    };
                    let f = r.composite(cpu.clone());
                    // Memory that does not follow the budget (the A-buffer's, WBOIT's, MBOIT's)
                    // either fits in M or the method does not run there.
                    if f.allocated_bytes > m_bytes {
                        continue;
                    }
                    let slots = Slots::for_method(m, &cpu, &opts)?;
                    let mut best = f64::INFINITY;
                    for _ in 0..a.repeat {
                        let g =
                            gpu.render_with(&frame_opts, s, &cam, size, opts.background, slots)?;
                        best = best.min(g.pass_ms.iter().map(|p| p.1).sum());
                    }
                    let (flip, _) = image_io::flip(&exact8, &image_io::to_srgb8(&f.image), size);
                    measures[bi][mi].push(Measure {
                        scene: s.name.clone(),
                        view,
                        mse: f.image.mse(&exact.image),
                        flip,
                        gpu_ms: best,
                        bytes_per_pixel: f.allocated_bytes as f64 / px,
                        exact: cpu.exact,
                    });
                }
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();
    Ok(measures)
}

/// One memory's trade: each method's means over the frames it ran (`at_x[method]`), the front of
/// the means among the methods that ran all `frames`, and each method's count of per-frame
/// fronts it is on.
/// (GPU ms, MSE, FLIP) over `frames`: geometric means (MSE floored as `compare`'s summary
/// does), FLIP's arithmetic mean.
fn means(frames: &[Measure]) -> [f64; 3] {
    let floor = crate::compare::MSE_FLOOR;
    let geomean = |v: Vec<f64>| crate::compare::geomean(&v);
    [
        geomean(frames.iter().map(|x| x.gpu_ms).collect()),
        geomean(frames.iter().map(|x| x.mse.max(floor)).collect()),
        frames.iter().map(|x| x.flip).sum::<f64>() / frames.len() as f64,
    ]
}

fn trade_at(x: f64, entries: &[Entry], at_x: &[Vec<Measure>], frames: usize) -> BudgetTrade {
    let mut points: Vec<Point> = entries
        .iter()
        .zip(at_x)
        .filter(|(_, fr)| !fr.is_empty())
        .map(|(e, fr)| {
            let [gpu_ms, mse, flip] = means(fr);
            Point {
                method: e.label.clone(),
                gpu_ms,
                mse,
                flip,
                bytes_per_pixel: fr.iter().map(|x| x.bytes_per_pixel).sum::<f64>()
                    / fr.len() as f64,
                front_frames: 0,
                front: false,
                frames: fr.clone(),
            }
        })
        .collect();
    // The front of the means, among the methods that ran every frame (a mean over fewer frames
    // is not comparable).
    let keys: Vec<[f64; 3]> = points
        .iter()
        .map(|p| match p.frames.len() == frames {
            true => [p.gpu_ms, p.mse, p.flip],
            false => [f64::INFINITY; 3],
        })
        .collect();
    for (p, on) in points.iter_mut().zip(front(&keys)) {
        p.front = on && p.frames.len() == frames;
    }
    count_frame_fronts(&mut points);
    BudgetTrade {
        budget: format!("{x}x the A-buffer's bytes"),
        memory: x,
        frames,
        points,
    }
}

/// Per frame, the methods that ran it (FKB does not where M holds no slot a pixel), each on
/// that frame's front or not: counted into [`Point::front_frames`].
fn count_frame_fronts(points: &mut [Point]) {
    let floor = crate::compare::MSE_FLOOR;
    let mut frames: Vec<(String, usize)> = Vec::new();
    for p in points.iter() {
        for x in &p.frames {
            if !frames.contains(&(x.scene.clone(), x.view)) {
                frames.push((x.scene.clone(), x.view));
            }
        }
    }
    for (scene, view) in &frames {
        let at = |p: &Point| {
            p.frames
                .iter()
                .find(|x| &x.scene == scene && x.view == *view)
                .map(|x| [x.gpu_ms, x.mse.max(floor), x.flip])
        };
        let keys: Vec<[f64; 3]> = points
            .iter()
            .map(|p| at(p).unwrap_or([f64::INFINITY; 3]))
            .collect();
        for (p, on) in points.iter_mut().zip(front(&keys)) {
            p.front_frames += usize::from(on && at(p).is_some());
        }
    }
}

/// One scene at one memory: each method that ran all of the scene's frames there, its
/// (GPU ms, MSE, FLIP) over them (geometric means, FLIP's mean), and whether it is on that
/// scene's front (no other such method as fast and as accurate).
fn scene_front(b: &BudgetTrade, scene: &str) -> Vec<(String, [f64; 3], bool)> {
    let views = b
        .points
        .iter()
        .map(|p| p.frames.iter().filter(|f| f.scene == scene).count())
        .max()
        .unwrap_or(0);
    let ran: Vec<(String, [f64; 3])> = b
        .points
        .iter()
        .filter_map(|p| {
            let fr: Vec<Measure> = p
                .frames
                .iter()
                .filter(|f| f.scene == scene)
                .cloned()
                .collect();
            (views > 0 && fr.len() == views).then(|| (p.method.clone(), means(&fr)))
        })
        .collect();
    let keys: Vec<[f64; 3]> = ran.iter().map(|r| r.1).collect();
    ran.into_iter()
        .zip(front(&keys))
        .map(|((m, k), on)| (m, k, on))
        .collect()
}

/// Per scene, one chart of every method at every memory, the front over all of them marked,
/// into `dir/versus_scene_NAME`.
fn scene_charts(dir: &std::path::Path, report: &Report) -> Vec<std::path::PathBuf> {
    let mut plots = Vec::new();
    for scene in &report.scenes {
        let mut pts: Vec<TradePoint> = report
            .budgets
            .iter()
            .flat_map(|b| {
                scene_front(b, scene)
                    .into_iter()
                    .map(move |(m, k, _)| TradePoint {
                        label: format!("{m} at {}x", b.memory),
                        time_ms: k[0],
                        mse: k[1],
                        flip: k[2],
                        front: false,
                    })
            })
            .collect();
        // The chart's front is over every method at every memory: the line a reader follows
        // for the best time and accuracy on this scene (the table has each memory's).
        let keys: Vec<[f64; 3]> = pts.iter().map(|p| [p.time_ms, p.mse, p.flip]).collect();
        for (p, on) in pts.iter_mut().zip(front(&keys)) {
            p.front = on;
        }
        if pts.is_empty() {
            continue;
        }
        let name: String = scene
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        let stem = dir.join(format!("versus_scene_{name}"));
        let title = format!("{scene}: every method at each memory");
        let time = format!("GPU frame, ms ({})", report.adapter);
        plots.extend(plot::trade(&stem, &title, &time, &pts));
    }
    plots
}

/// The report as Markdown (printed too) and JSON, one chart a memory, into `--out` and, where
/// asked, the summary folder; one chart a scene into `--out`.
fn write_outputs(a: &VersusArgs, report: &Report) -> Result<()> {
    let md = table(report);
    print!("{md}");
    let text = serde_json::to_string_pretty(report)?;
    dhoit_runtime::tensors::write_atomic(&a.out.join("versus.json"), text.as_bytes())?;
    dhoit_runtime::tensors::write_atomic(&a.out.join("versus.md"), md.as_bytes())?;
    let mut plots = Vec::new();
    for b in &report.budgets {
        let pts: Vec<TradePoint> = b
            .points
            .iter()
            .map(|p| TradePoint {
                // A mean over fewer frames says so: it is not the others' mean.
                label: match p.frames.len() == b.frames {
                    true => p.method.clone(),
                    false => format!("{} ({} of {} frames)", p.method, p.frames.len(), b.frames),
                },
                time_ms: p.gpu_ms,
                mse: p.mse,
                flip: p.flip,
                front: p.front,
            })
            .collect();
        let stem = a.out.join(format!("versus_{}", file_part(b.memory)));
        let title = format!("every method at equal bytes, {}", b.budget);
        let time = format!("GPU frame, ms ({})", report.adapter);
        plots.extend(plot::trade(&stem, &title, &time, &pts));
    }
    let scenes = scene_charts(&a.out, report);
    if let Some(dir) = &a.summary {
        dhoit_runtime::tensors::create_folder(dir)?;
        dhoit_runtime::tensors::write_atomic(&dir.join("versus.json"), text.as_bytes())?;
        dhoit_runtime::tensors::write_atomic(&dir.join("versus.md"), md.as_bytes())?;
        for p in &plots {
            let to = dir.join(p.file_name().context("a plot's name")?);
            std::fs::copy(p, &to).with_context(|| format!("cannot copy {}", p.display()))?;
        }
    }
    println!(
        "versus.json, versus.md, {} plots and {} a scene -> {}",
        plots.len(),
        scenes.len(),
        a.out.display()
    );
    Ok(())
}

/// A memory as part of a file name, with no dot for the extension to take (`0.5` -> `0p5x`).
fn file_part(memory: f64) -> String {
    format!("{memory}x").replace('.', "p")
}

fn table(r: &Report) -> String {
    let mut md = format!(
        "# Every method at equal bytes\n\n`dhoit versus` on {} (views {:?}, {}), GPU frames \
         timed on {}: one memory M for every method, a multiple of each frame's exact A-buffer \
         bytes (each method's own F, moments or targets from its own layout; a method whose \
         memory does not fit in M does not run there: *frames* counts where it did), a \
         k-buffer rendering the exact A-buffer where that is no dearer; `dkb` runs its default \
         network, `dkb H1-H2` each other network given (`--networks`), each network's weights \
         in its memory. Geometric means over \
         the frames a method ran (MSE against the exact A-buffer, floored at {:e}; FLIP its \
         mean); *front*: no other method that ran every frame is as fast and as accurate in \
         MSE and FLIP over the means (n/a: it ran fewer); *front frames*: the frames on which \
         no other method is as fast and as accurate.\n",
        r.scenes.join(", "),
        r.views,
        r.resolution,
        r.adapter,
        crate::compare::MSE_FLOOR
    );
    for b in &r.budgets {
        md += &format!(
            "\n## M = {}\n\n| method | frames | GPU ms | MSE | FLIP | bytes a pixel | exact \
             frames | front | front frames |\n|---|---:|---:|---:|---:|---:|---:|---|---:|\n",
            b.budget
        );
        for p in &b.points {
            md += &format!(
                "| {} | {} of {} | {:.2} | {:.3e} | {:.4} | {:.1} | {} of {} | {} | {} of {} |\n",
                p.method,
                p.frames.len(),
                b.frames,
                p.gpu_ms,
                p.mse,
                p.flip,
                p.bytes_per_pixel,
                p.frames.iter().filter(|f| f.exact).count(),
                p.frames.len(),
                match (p.front, p.frames.len() == b.frames) {
                    (true, _) => "yes",
                    (false, true) => "",
                    (false, false) => "n/a",
                },
                p.front_frames,
                p.frames.len()
            );
        }
        // Per scene: each method's MSE (its views' geometric mean), "-" where it did not fit.
        md += &format!(
            "\nPer scene, MSE:\n\n| scene | {} |\n|---|{}\n",
            b.points
                .iter()
                .map(|p| p.method.as_str())
                .collect::<Vec<_>>()
                .join(" | "),
            "---:|".repeat(b.points.len())
        );
        for scene in &r.scenes {
            let cells: Vec<String> = b
                .points
                .iter()
                .map(|p| {
                    let v: Vec<f64> = p
                        .frames
                        .iter()
                        .filter(|f| &f.scene == scene)
                        .map(|f| f.mse.max(crate::compare::MSE_FLOOR))
                        .collect();
                    match v.is_empty() {
                        true => "-".to_string(),
                        false => format!("{:.2e}", crate::compare::geomean(&v)),
                    }
                })
                .collect();
            md += &format!("| {scene} | {} |\n", cells.join(" | "));
        }
    }
    // Per scene, the front at each memory among the methods that ran its frames there.
    md += &format!(
        "\n## The front per scene\n\nAt each memory, the methods that ran every view of the \
         scene and that no other such method beats in GPU time, MSE and FLIP (one chart a \
         scene, every method at every memory with the front over all of them: \
         `versus_scene_NAME.png` in `--out`, out/versus for `make versus`).\n\n| scene | {} |\n|---|{}\n",
        r.budgets
            .iter()
            .map(|b| format!("{}x", b.memory))
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(r.budgets.len())
    );
    for scene in &r.scenes {
        let cells: Vec<String> = r
            .budgets
            .iter()
            .map(|b| {
                let on: Vec<String> = scene_front(b, scene)
                    .into_iter()
                    .filter(|x| x.2)
                    .map(|x| x.0)
                    .collect();
                match on.is_empty() {
                    true => "(none fits)".to_string(),
                    false => on.join(", "),
                }
            })
            .collect();
        md += &format!("| {scene} | {} |\n", cells.join(" | "));
    }
    md
}

#[cfg(test)]
mod tests {
    use super::{BudgetTrade, Measure, Point, front, scene_front};

    fn measure(scene: &str, view: usize, gpu_ms: f64, mse: f64) -> Measure {
        Measure {
            scene: scene.into(),
            view,
            mse,
            flip: 0.1,
            gpu_ms,
            bytes_per_pixel: 10.0,
            exact: false,
        }
    }

    fn point(method: &str, frames: Vec<Measure>) -> Point {
        Point {
            method: method.into(),
            gpu_ms: 0.0,
            mse: 0.0,
            flip: 0.0,
            bytes_per_pixel: 0.0,
            front_frames: 0,
            front: false,
            frames,
        }
    }

    /// A scene's front takes the methods that ran every one of its views, each over those
    /// views (geometric means), and marks the undominated; a method missing a view is left out.
    #[test]
    fn a_scenes_front_is_over_its_own_views() {
        let b = BudgetTrade {
            budget: "0.5x".into(),
            memory: 0.5,
            frames: 4,
            points: vec![
                // Faster and more accurate on "a" (over both views), slower on "b".
                point(
                    "fast",
                    vec![
                        measure("a", 1, 1.0, 1e-6),
                        measure("a", 3, 4.0, 1e-4),
                        measure("b", 1, 9.0, 1e-3),
                    ],
                ),
                point(
                    "slow",
                    vec![
                        measure("a", 1, 3.0, 1e-5),
                        measure("a", 3, 3.0, 1e-4),
                        measure("b", 1, 1.0, 1e-4),
                    ],
                ),
                // Ran one view of "a" only.
                point("partial", vec![measure("a", 1, 0.1, 1e-9)]),
            ],
        };
        let a = scene_front(&b, "a");
        assert_eq!(
            a.iter().map(|x| (x.0.as_str(), x.2)).collect::<Vec<_>>(),
            [("fast", true), ("slow", false)]
        );
        assert!((a[0].1[0] - 2.0).abs() < 1e-12 && (a[0].1[1] - 1e-5).abs() < 1e-17);
        let on_b: Vec<_> = scene_front(&b, "b").into_iter().filter(|x| x.2).collect();
        assert_eq!(on_b.len(), 1);
        assert_eq!(on_b[0].0, "slow");
        assert!(scene_front(&b, "c").is_empty());
    }

    #[test]
    fn the_front_keeps_the_undominated() {
        // (time, MSE, FLIP): the second is beaten by the first in all three, the third is
        // fastest, the fourth most accurate; a tie dominates nothing.
        let keys = [
            [1.0, 1e-5, 0.1],
            [2.0, 2e-5, 0.2],
            [0.5, 1e-3, 0.3],
            [5.0, 1e-7, 0.01],
            [1.0, 1e-5, 0.1],
        ];
        assert_eq!(front(&keys), [true, false, true, true, true]);
    }
}
