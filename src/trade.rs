//! `dhoit trade` and `dhoit fit`: the speed-accuracy trade of networks of several sizes on given
//! scenes (importance-pass time against MSE and FLIP, the Pareto front marked), and the smallest
//! network that meets a quality target on a scene.

use crate::args::{ViewArgs, check_view, default_weights, load_scene, load_scenes, rasterize_view};
use anyhow::{Context, Result, bail};
use clap::Args;
use dhoit_runtime::budget::Budget;
use dhoit_runtime::frame::{Equal, Method, Options, Renderer};
use dhoit_runtime::image_io;
use dhoit_runtime::mlp::{self, Mlp, Precision};
use dhoit_runtime::raster::Resolution;
use dhoit_runtime::scene::{self, Camera};
use dhoit_train::cli::bar;
use dhoit_train::plot::{self, TradePoint};
use indicatif::ProgressBar;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// Where the shipped networks of other sizes live: `data/nets/H1-H2/weights.safetensors`.
pub const NETS_DIR: &str = "data/nets";

/// What times the importance pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Timing {
    Auto,
    Cpu,
    Gpu,
}

impl std::str::FromStr for Timing {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Timing, String> {
        match s {
            "auto" => Ok(Timing::Auto),
            "cpu" => Ok(Timing::Cpu),
            "gpu" => Ok(Timing::Gpu),
            _ => Err(format!("'{s}': expected gpu, cpu or auto")),
        }
    }
}

#[derive(Args, Clone)]
pub struct QualityArgs {
    /// Weights files to compare, comma separated. Default: the default network and every
    /// network shipped beside it (data/nets/*/weights.safetensors).
    #[arg(long, value_delimiter = ',')]
    networks: Vec<PathBuf>,
    /// Budgets, comma separated: shares of each frame's fragments (25%), slots per pixel
    /// (2fpp) or bytes.
    #[arg(
        long = "budget",
        value_delimiter = ',',
        default_value = "10%,25%,50%,75%,90%",
        allow_hyphen_values = true
    )]
    budgets: Vec<Budget>,
    /// Orbit views whose images are measured, comma separated.
    #[arg(long = "view", value_delimiter = ',', default_value = "1,3")]
    view_list: Vec<usize>,
    #[command(flatten)]
    common: ViewArgs,
}

#[derive(Args)]
pub struct TradeArgs {
    /// Scenes, comma separated: built-in names or .gltf/.glb paths.
    #[arg(long = "scene", value_delimiter = ',', default_value = "particles")]
    scenes: Vec<String>,
    #[command(flatten)]
    quality: QualityArgs,
    /// Precisions of the network, comma separated: f32, f16 (binary16 weights, f32
    /// arithmetic), f16-math (binary16 weights and hidden-layer arithmetic; needs SHADER_F16).
    #[arg(long, value_delimiter = ',', default_value = "f32")]
    precision: Vec<Precision>,
    /// Resolution the importance pass is timed at (view 0, the first budget).
    #[arg(long, default_value = "640x480")]
    time_res: Resolution,
    /// What times the importance pass: gpu (timestamp queries on the adapter at hand), cpu
    /// (the runtime's CPU twin over the frame's covered pixels), or auto (gpu when an adapter
    /// exists).
    #[arg(long, default_value = "auto")]
    timing: Timing,
    /// Timed repetitions; the fastest is kept.
    #[arg(long, default_value_t = 3, value_parser = crate::args::parse_repeat)]
    repeat: usize,
    /// Directory for trade.json, trade.md and the plots (trade_SCENE.svg/.png, trade_all).
    #[arg(long, default_value = "out/trade")]
    out: PathBuf,
    /// Also write trade.json, trade.md and the all-scenes plot into this directory (small,
    /// committed: `make trade` writes docs/).
    #[arg(long)]
    summary: Option<PathBuf>,
}

#[derive(Args)]
pub struct FitArgs {
    /// The scene to fit: a .gltf/.glb path or a built-in name.
    #[arg(long)]
    scene: String,
    /// The quality to meet: the network's MSE at most TARGET times the optimal allocation's
    /// (geometric mean over the views and budgets whose budget is below the frame's fragments).
    #[arg(long, default_value_t = 1.5)]
    target: f64,
    #[command(flatten)]
    quality: QualityArgs,
    /// Precisions to consider, comma separated: f16 halves a network's weights (binary16, f32
    /// arithmetic); f16-math also computes the hidden layers in binary16 (the device that runs
    /// it needs SHADER_F16). The chosen one is recorded in the weights file.
    #[arg(long, value_delimiter = ',', default_value = "f32,f16")]
    precision: Vec<Precision>,
    /// Where the chosen network's weights are written.
    #[arg(long)]
    out: PathBuf,
}

/// A network to compare.
#[derive(Clone)]
struct Net {
    path: PathBuf,
    label: String,
    /// At `precision`.
    mlp: Mlp,
    parameters: usize,
    precision: Precision,
}

fn networks(q: &QualityArgs) -> Result<Vec<Net>> {
    if let Some(w) = &q.common.weights {
        bail!(
            "--weights {}: trade and fit compare the networks given with --networks (comma \
             separated), or every shipped one",
            w.display()
        );
    }
    let mut paths = q.networks.clone();
    if paths.is_empty() {
        let default = default_weights()
            .context("no network given (--networks) and the default weights are not found")?;
        paths.push(default.clone());
        let nets = default
            .parent()
            .map(|d| d.join("nets"))
            .unwrap_or_else(|| PathBuf::from(NETS_DIR));
        if let Ok(dir) = std::fs::read_dir(&nets) {
            for e in dir.flatten() {
                let w = e.path().join("weights.safetensors");
                if w.is_file() {
                    paths.push(w);
                }
            }
        }
    }
    let mut out: Vec<Net> = paths
        .iter()
        .map(|p| -> Result<Net> {
            let m = Mlp::load(p)?;
            Ok(Net {
                path: p.clone(),
                label: format!("{}-{}", m.h1, m.h2),
                parameters: mlp::parameter_count(m.h1, m.h2),
                precision: m.precision,
                mlp: m,
            })
        })
        .collect::<Result<_>>()?;
    out.sort_by_key(|n| n.parameters);
    Ok(out)
}

/// Every network of [`networks`] at every precision of `precisions`, network by network.
fn networks_at(q: &QualityArgs, precisions: &[Precision]) -> Result<Vec<Net>> {
    networks(q)?
        .into_iter()
        .flat_map(|n| precisions.iter().map(move |&p| (n.clone(), p)))
        .map(|(n, p)| {
            Ok(Net {
                mlp: n.mlp.at_precision(p)?,
                precision: p,
                ..n
            })
        })
        .collect()
}

/// One network on one frame and budget.
#[derive(Clone, Debug, Serialize)]
pub struct Measure {
    pub view: usize,
    pub budget: String,
    pub budget_fragments: u64,
    pub fragments: u64,
    pub mse: f64,
    pub flip: f64,
    pub optimal_mse: f64,
    pub vkb_mse: f64,
    /// At equal bytes (`trade` only): M, what DKB with this network spends on the frame at the
    /// budget (its weights counted; the exact A-buffer's bytes where those are no more,
    /// [`Renderer::budget`]), the one memory both methods get.
    pub bytes: Option<u64>,
    /// The exact A-buffer's bytes for the frame (M never exceeds them).
    pub abuffer_bytes: u64,
    /// DKB's MSE at M (exact where M holds every fragment).
    pub bytes_mse: Option<f64>,
    /// VKB's MSE at the same M: its F is what M leaves it once its own layout is paid, so a
    /// network's weights are slots VKB gets and DKB does not. None where VKB's layout does not
    /// fit in M.
    pub bytes_vkb_mse: Option<f64>,
}

/// Every network's images on every view and budget of one scene: at equal F (every network's
/// slots those of the budget) and, with `equal_bytes`, at equal bytes as well (DKB and VKB in
/// the memory DKB spends with that network: [`at_equal_bytes`]).
fn quality(
    s: &scene::Scene,
    q: &QualityArgs,
    nets: &[Net],
    equal_bytes: bool,
    pb: &ProgressBar,
) -> Result<Vec<Vec<Measure>>> {
    let budgets = &q.budgets;
    let mut out: Vec<Vec<Measure>> = nets.iter().map(|_| Vec::new()).collect();
    for &view in &q.view_list {
        let (fl, _) = rasterize_view(s, view, &q.common)?;
        for b in budgets {
            // The networks' own approximations are what the trade measures.
            let plain = Renderer::new(
                &fl,
                Options::new(*b, q.common.background).always_approximate(),
            );
            let exact = plain.render(Method::Abuffer)?;
            let exact8 = image_io::to_srgb8(&exact.image);
            let optimal = plain.render(Method::Optimal)?;
            let vkb = plain.render(Method::Vkb)?;
            for (i, n) in nets.iter().enumerate() {
                let opts = Options {
                    weights: Some(&n.mlp),
                    ..Options::new(*b, q.common.background).always_approximate()
                };
                let f = Renderer::new(&fl, opts).render(Method::Dkb)?;
                let (flip, _) = image_io::flip(&exact8, &image_io::to_srgb8(&f.image), fl.size());
                let (bytes, bytes_mse, bytes_vkb_mse) = match equal_bytes {
                    true => at_equal_bytes(&fl, *b, q.common.background, &n.mlp, &exact.image)?,
                    false => (None, None, None),
                };
                out[i].push(Measure {
                    view,
                    budget: b.to_string(),
                    budget_fragments: f.budget_fragments,
                    fragments: f.fragments_total,
                    mse: f.image.mse(&exact.image),
                    flip,
                    optimal_mse: optimal.image.mse(&exact.image),
                    vkb_mse: vkb.image.mse(&exact.image),
                    bytes,
                    abuffer_bytes: exact.allocated_bytes,
                    bytes_mse,
                    bytes_vkb_mse,
                });
            }
            pb.inc(1);
        }
    }
    Ok(out)
}

/// DKB with `mlp` and VKB at equal bytes on one frame, as `compare --equal bytes` renders
/// them: M (what DKB spends at `budget` with this network's weights, or the exact A-buffer's
/// bytes where those are no more), DKB's MSE at M and VKB's (None where its layout does not
/// fit M: a refusal, not an error).
fn at_equal_bytes(
    fl: &dhoit_runtime::fragment::FragmentLists,
    budget: Budget,
    background: [f32; 3],
    mlp: &Mlp,
    exact: &dhoit_runtime::composite::Image,
) -> Result<(Option<u64>, Option<f64>, Option<f64>)> {
    let opts = Options {
        weights: Some(mlp),
        equal: Equal::Bytes,
        ..Options::new(budget, background)
    };
    let r = Renderer::new(fl, opts);
    let dkb = r.render(Method::Dkb)?;
    let vkb = match r.render(Method::Vkb) {
        Ok(v) => Some(v.image.mse(exact)),
        Err(dhoit_runtime::Error::Budget(..)) => None,
        Err(e) => return Err(e.into()),
    };
    Ok((Some(dkb.budget_bytes), Some(dkb.image.mse(exact)), vkb))
}

const FLOOR: f64 = crate::compare::MSE_FLOOR;

/// Geometric mean, values floored at [`FLOOR`] as in `compare`'s summary.
fn geomean(v: impl IntoIterator<Item = f64>) -> f64 {
    crate::compare::geomean(&v.into_iter().map(|x| x.max(FLOOR)).collect::<Vec<_>>())
}

/// Geometric mean of MSE / the optimal allocation's over the frames that count.
fn over_optimal(m: &[Measure]) -> f64 {
    geomean(counted(m).map(|x| x.mse.max(FLOOR) / x.optimal_mse.max(FLOOR)))
}

/// Geometric mean of MSE / VKB's over the frames that count.
fn over_vkb(m: &[Measure]) -> f64 {
    geomean(counted(m).map(|x| x.mse.max(FLOOR) / x.vkb_mse.max(FLOOR)))
}

/// Geometric mean of DKB's MSE / VKB's at equal bytes over the frames that count and VKB
/// runs in (NaN where there are none, as for the other ratios: `-` in the tables, null in
/// the JSON).
fn over_vkb_at_equal_bytes(m: &[Measure]) -> f64 {
    let ratios: Vec<f64> = counted(m)
        .filter_map(|x| Some(x.bytes_mse?.max(FLOOR) / x.bytes_vkb_mse?.max(FLOOR)))
        .collect();
    match ratios.is_empty() {
        true => f64::NAN,
        false => geomean(ratios),
    }
}

/// A ratio for the tables: `-` where no frame counted (every budget held the scene's
/// fragments, so no allocation is told apart).
fn ratio_cell(x: f64) -> String {
    match x.is_finite() {
        true => format!("{x:.3}"),
        false => "-".into(),
    }
}

/// The frames that tell allocations apart (budget below the frame's fragments).
fn counted(m: &[Measure]) -> impl Iterator<Item = &Measure> {
    m.iter().filter(|x| x.budget_fragments < x.fragments)
}

/// One network at one precision on one scene.
#[derive(Clone, Debug, Serialize)]
pub struct Point {
    pub network: String,
    pub weights: String,
    pub parameters: usize,
    pub precision: String,
    /// Bytes of the network's weights on the GPU at this precision (counted in DKB's memory).
    pub weight_bytes: u64,
    /// Importance-pass time, milliseconds (see the report's `timing`).
    pub time_ms: f64,
    /// Geometric mean MSE over views and budgets.
    pub mse: f64,
    /// Mean FLIP over views and budgets.
    pub flip: f64,
    /// Geometric mean of MSE / the optimal allocation's MSE over the frames whose budget is
    /// below their fragments.
    pub mse_over_optimal: f64,
    pub mse_over_vkb: f64,
    /// Geometric mean of DKB's MSE / VKB's at equal bytes (M what DKB spends with this network,
    /// its weights counted: [`Measure::bytes`]), over the frames that count and VKB fits.
    pub mse_over_vkb_equal_bytes: f64,
    /// Mean of M over the exact A-buffer's bytes, over every frame.
    pub bytes_over_abuffer: f64,
    pub front: bool,
    pub frames: Vec<Measure>,
}

fn point(n: &Net, time_ms: f64, m: Vec<Measure>) -> Point {
    Point {
        network: n.label.clone(),
        weights: n.path.display().to_string(),
        parameters: n.parameters,
        precision: n.precision.to_string(),
        weight_bytes: n.mlp.uniform_bytes(),
        time_ms,
        mse: geomean(m.iter().map(|x| x.mse)),
        flip: m.iter().map(|x| x.flip).sum::<f64>() / m.len().max(1) as f64,
        mse_over_optimal: over_optimal(&m),
        mse_over_vkb: over_vkb(&m),
        mse_over_vkb_equal_bytes: over_vkb_at_equal_bytes(&m),
        bytes_over_abuffer: bytes_over_abuffer(&m),
        front: false,
        frames: m,
    }
}

/// Mean of M over the exact A-buffer's bytes (0 where no frame was measured at equal bytes).
fn bytes_over_abuffer(m: &[Measure]) -> f64 {
    let r: Vec<f64> = m
        .iter()
        .filter_map(|x| Some(x.bytes? as f64 / x.abuffer_bytes.max(1) as f64))
        .collect();
    r.iter().sum::<f64>() / r.len().max(1) as f64
}

/// Marks the points no other point dominates (as fast or faster, weights as small or smaller,
/// MSE and FLIP as low or lower, and better in one of the four).
pub fn mark_front(points: &mut [Point]) {
    let key = |p: &Point| [p.time_ms, p.weight_bytes as f64, p.mse, p.flip];
    let keys: Vec<[f64; 4]> = points.iter().map(key).collect();
    for (i, p) in points.iter_mut().enumerate() {
        p.front = !keys.iter().enumerate().any(|(j, o)| {
            j != i
                && o.iter().zip(&keys[i]).all(|(a, b)| a <= b)
                && o.iter().zip(&keys[i]).any(|(a, b)| a < b)
        });
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct SceneTrade {
    pub scene: String,
    pub points: Vec<Point>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// What timed the importance pass: `gpu: ADAPTER` or `cpu (N threads)`.
    pub timing: String,
    pub time_resolution: String,
    pub resolution: String,
    pub views: Vec<usize>,
    pub budgets: Vec<String>,
    pub networks: Vec<String>,
    pub precisions: Vec<String>,
    pub scenes: Vec<SceneTrade>,
}

enum Timer {
    Gpu(Box<dhoit_runtime::gpu::Gpu>),
    Cpu,
}

impl Timer {
    /// The timer `timing` asks for: the GPU's timestamps, the CPU twin, or (auto) the GPU where
    /// there is one, saying so where there is none.
    fn of(timing: Timing) -> Result<Timer> {
        Ok(match timing {
            Timing::Cpu => Timer::Cpu,
            Timing::Gpu => Timer::Gpu(Box::new(dhoit_runtime::gpu::Gpu::new()?)),
            Timing::Auto => match dhoit_runtime::gpu::Gpu::new() {
                Ok(g) => Timer::Gpu(Box::new(g)),
                Err(e) => {
                    eprintln!("trade: no GPU ({e}): timing the CPU twin");
                    Timer::Cpu
                }
            },
        })
    }

    fn name(&self) -> String {
        match self {
            Timer::Gpu(g) => format!("gpu timestamps: {}", g.adapter()),
            Timer::Cpu => format!("cpu twin ({} threads)", rayon::current_num_threads()),
        }
    }

    /// What timing `s`'s view 0 at `budget` needs, computed once for every network: the
    /// camera and F on the GPU; the rasterized frame's features on the CPU.
    fn frame(&self, s: &scene::Scene, (w, h): (u32, u32), budget: Budget) -> Result<TimedFrame> {
        let cam = Camera::orbit(s, 0, scene::DEFAULT_VIEWS, (w, h));
        let pixels = (w * h) as u64;
        Ok(match self {
            Timer::Gpu(_) => {
                let f = budget.fragment_budget(&dhoit_runtime::budget::DKB, pixels)?;
                TimedFrame::Gpu { cam, f, w, h }
            }
            Timer::Cpu => {
                let fl = dhoit_runtime::raster::rasterize(s, &cam, (w, h))?;
                let total = fl.fragment_count() as u64;
                let (_, f) = budget.resolve(&dhoit_runtime::budget::DKB, pixels, total)?;
                let (feats, _) = dhoit_runtime::importance::features_and_pairs(&fl, f);
                TimedFrame::Cpu {
                    feats,
                    counts: fl.counts(),
                }
            }
        })
    }

    /// The importance pass's time for `mlp` on a prepared frame of `s`, fastest of `repeat`.
    fn time(&self, s: &scene::Scene, frame: &TimedFrame, mlp: &Mlp, repeat: usize) -> Result<f64> {
        let mut best = f64::INFINITY;
        for _ in 0..repeat.max(1) {
            let t = match (self, frame) {
                (Timer::Gpu(g), TimedFrame::Gpu { cam, f, w, h }) => g
                    .render_with(
                        // The network's own pass, whatever the exact A-buffer would cost.
                        &dhoit_runtime::gpu::FrameOptions::default().always_approximate(),
                        s,
                        cam,
                        (*w, *h),
                        [1.0; 3],
                        dhoit_runtime::gpu::Slots::Dkb(mlp, (*f).into()),
                    )?
                    .pass_ms
                    .iter()
                    .filter(|p| p.0 == "importance")
                    // None where the budget holds every fragment (k = n needs no importance).
                    .fold(0.0, |a, p| a + p.1),
                (_, TimedFrame::Cpu { feats, counts }) => {
                    let t = Instant::now();
                    std::hint::black_box(mlp.importance(feats, counts));
                    t.elapsed().as_secs_f64() * 1e3
                }
                (Timer::Cpu, TimedFrame::Gpu { .. }) => {
                    unreachable!("frames come from their timer")
                }
            };
            best = best.min(t);
        }
        Ok(best)
    }
}

/// One scene's timed frame (see [`Timer::frame`]).
enum TimedFrame {
    Gpu {
        cam: Camera,
        f: dhoit_runtime::budget::FragmentBudget,
        w: u32,
        h: u32,
    },
    Cpu {
        feats: Vec<[f32; dhoit_runtime::importance::FEATURES]>,
        counts: Vec<u32>,
    },
}

pub fn trade(a: TradeArgs) -> Result<()> {
    // Every network at every precision: quality and time of each.
    let nets: Vec<Net> = networks_at(&a.quality, &a.precision)?;
    let time_res = a.time_res.size();
    let first_budget = *a
        .quality
        .budgets
        .first()
        .context("give at least one budget")?;
    let timer = Timer::of(a.timing)?;
    eprintln!(
        "trade: {} networks at {} precisions ({}) on {} scenes; importance pass timed by {}",
        nets.len() / a.precision.len().max(1),
        a.precision.len(),
        nets.iter()
            .map(|n| format!("{} {}", n.label, n.precision))
            .collect::<Vec<_>>()
            .join(", "),
        a.scenes.len(),
        timer.name()
    );
    // Every scene and view checked before the first frame.
    for &view in &a.quality.view_list {
        check_view(view, a.quality.common.views)?;
    }
    let loaded = load_scenes(&a.scenes, &a.quality.common)?;
    dhoit_runtime::tensors::create_folder(&a.out)?;
    let steps = a.scenes.len() * a.quality.view_list.len() * a.quality.budgets.len();
    let pb = bar(steps as u64, "frames");
    let mut scenes = Vec::new();
    for (name, s) in a.scenes.iter().zip(loaded) {
        let measures = quality(&s, &a.quality, &nets, true, &pb)?;
        let frame = timer.frame(&s, time_res, first_budget)?;
        let mut points = Vec::new();
        for (n, m) in nets.iter().zip(measures) {
            let t = pb.suspend(|| timer.time(&s, &frame, &n.mlp, a.repeat))?;
            points.push(point(n, t, m));
        }
        mark_front(&mut points);
        scenes.push(SceneTrade {
            scene: scene::file_label(name),
            points,
        });
    }
    pb.finish_and_clear();
    // Every scene together: geometric means of time and MSE, mean FLIP.
    if scenes.len() > 1 {
        scenes.push(every_scene(&scenes));
    }
    let report = Report {
        timing: timer.name(),
        time_resolution: a.time_res.to_string(),
        resolution: a.quality.common.res.to_string(),
        views: a.quality.view_list.clone(),
        budgets: a.quality.budgets.iter().map(Budget::to_string).collect(),
        networks: nets.iter().map(|n| n.label.clone()).collect(),
        precisions: a.precision.iter().map(Precision::to_string).collect(),
        scenes,
    };
    let (text, md) = tables(&report);
    println!("{text}");
    let json = serde_json::to_string_pretty(&report)?;
    dhoit_runtime::tensors::write_atomic(&a.out.join("trade.json"), json.as_bytes())?;
    dhoit_runtime::tensors::write_atomic(&a.out.join("trade.md"), md.as_bytes())?;
    let plots = write_plots(&report, &timer, &a.out);
    if let Some(dir) = &a.summary {
        dhoit_runtime::tensors::create_folder(dir)?;
        // The small form: per-frame measures left out.
        let mut small = report.clone();
        for s in &mut small.scenes {
            for p in &mut s.points {
                p.frames.clear();
            }
        }
        dhoit_runtime::tensors::write_atomic(
            &dir.join("trade.json"),
            serde_json::to_string_pretty(&small)?.as_bytes(),
        )?;
        dhoit_runtime::tensors::write_atomic(&dir.join("trade.md"), md.as_bytes())?;
        let last = &report.scenes.last().expect("a scene").scene;
        for ext in ["svg", "png"] {
            let from = a.out.join(format!("trade_{last}.{ext}"));
            if from.is_file() {
                std::fs::copy(&from, dir.join(format!("trade.{ext}")))
                    .with_context(|| format!("cannot copy {}", from.display()))?;
            }
        }
    }
    println!(
        "trade.json, trade.md{} -> {}",
        if plots.is_empty() {
            ""
        } else {
            " and the plots"
        },
        a.out.display()
    );
    Ok(())
}

/// Every scene's trade together, as one scene named "all": geometric means of time and MSE,
/// mean FLIP, the ratios over every frame, its own front.
fn every_scene(scenes: &[SceneTrade]) -> SceneTrade {
    let mut points: Vec<Point> = scenes[0]
        .points
        .iter()
        .enumerate()
        .map(|(i, p0)| {
            let all: Vec<&Point> = scenes.iter().map(|s| &s.points[i]).collect();
            let frames: Vec<Measure> = all.iter().flat_map(|p| p.frames.clone()).collect();
            let mut p = Point {
                time_ms: geomean(all.iter().map(|p| p.time_ms)),
                ..p0.clone()
            };
            p.mse = geomean(all.iter().map(|p| p.mse));
            p.flip = all.iter().map(|p| p.flip).sum::<f64>() / all.len() as f64;
            p.mse_over_optimal = over_optimal(&frames);
            p.mse_over_vkb = over_vkb(&frames);
            p.mse_over_vkb_equal_bytes = over_vkb_at_equal_bytes(&frames);
            p.bytes_over_abuffer = bytes_over_abuffer(&frames);
            p.frames = Vec::new();
            p
        })
        .collect();
    mark_front(&mut points);
    SceneTrade {
        scene: "all".into(),
        points,
    }
}

/// The trade's plot of every scene of `report` into `out` (`trade_SCENE.svg` and `.png`):
/// the files written.
fn write_plots(report: &Report, timer: &Timer, out: &std::path::Path) -> Vec<PathBuf> {
    let time_label = match timer {
        // The adapter's short name: "llvmpipe (LLVM ...)" -> "llvmpipe".
        Timer::Gpu(g) => format!(
            "importance pass, ms (GPU timestamps, {})",
            g.adapter().split(" (").next().unwrap_or("GPU")
        ),
        Timer::Cpu => "importance pass, ms (CPU twin)".to_string(),
    };
    let mut plots = Vec::new();
    for s in &report.scenes {
        let pts: Vec<TradePoint> = s
            .points
            .iter()
            .map(|p| TradePoint {
                label: format!(
                    "{} {} ({})",
                    p.network,
                    p.precision,
                    dhoit_runtime::budget::format_bytes(p.weight_bytes)
                ),
                time_ms: p.time_ms,
                mse: p.mse,
                flip: p.flip,
                front: p.front,
            })
            .collect();
        let title = format!(
            "{}: importance-pass time at {} against quality at {} ({} budgets, {} views)",
            s.scene,
            report.time_resolution,
            report.resolution,
            report.budgets.len(),
            report.views.len()
        );
        plots.extend(plot::trade(
            &out.join(format!("trade_{}", s.scene)),
            &title,
            &time_label,
            &pts,
        ));
    }
    plots
}

fn tables(r: &Report) -> (String, String) {
    let mut text = String::new();
    let mut md = format!(
        "# dhoit: the speed-accuracy trade\n\nImportance pass timed by {} at {}; quality at {} on views {:?}, budgets {} (MSE: geometric mean; FLIP: mean; ratios over the frames whose budget is below their fragments). Weights: the network's bytes on the GPU at that precision, counted in DKB's memory. MSE, FLIP and the first two ratios at equal F (every network the budget's slots); `MSE / VKB, equal bytes`: DKB with that network and VKB in one memory M, what DKB spends with those weights (the exact A-buffer's bytes where those are no more), so the weights' bytes are slots VKB gets and DKB does not (frames whose budget is below their fragments and VKB fits M); `M / A-buffer`: M over the exact A-buffer's bytes, mean over frames. `*`: on the Pareto front (time, weights, MSE, FLIP). Generated by `dhoit trade` (`make trade`).\n",
        r.timing,
        r.time_resolution,
        r.resolution,
        r.views,
        r.budgets.join(", ")
    );
    const HEAD: [&str; 12] = [
        "network",
        "precision",
        "parameters",
        "weights (B)",
        "time (ms)",
        "MSE",
        "FLIP",
        "MSE / optimal",
        "MSE / VKB",
        "MSE / VKB, equal bytes",
        "M / A-buffer",
        "front",
    ];
    for s in &r.scenes {
        let rows: Vec<Vec<String>> = s
            .points
            .iter()
            .map(|p| {
                vec![
                    p.network.clone(),
                    p.precision.clone(),
                    p.parameters.to_string(),
                    p.weight_bytes.to_string(),
                    format!("{:.3}", p.time_ms),
                    format!("{:.3e}", p.mse),
                    format!("{:.4}", p.flip),
                    ratio_cell(p.mse_over_optimal),
                    ratio_cell(p.mse_over_vkb),
                    ratio_cell(p.mse_over_vkb_equal_bytes),
                    format!("{:.3}", p.bytes_over_abuffer),
                    if p.front { "*" } else { "" }.to_string(),
                ]
            })
            .collect();
        let (t, m) = crate::compare::table(&HEAD, &rows);
        text += &format!("\n{}\n{t}", s.scene);
        md += &format!("\n## {}\n\n{m}", s.scene);
    }
    (text, md)
}

/// `dhoit fit`.
pub fn fit(a: FitArgs) -> Result<()> {
    if !(a.target.is_finite() && a.target >= 1.0) {
        bail!(
            "--target {}: a ratio to the optimal allocation's MSE, at least 1",
            a.target
        );
    }
    for &view in &a.quality.view_list {
        check_view(view, a.quality.common.views)?;
    }
    if a.precision.is_empty() {
        bail!("--precision: give at least one of f32, f16, f16-math");
    }
    // Every network at every precision, fewest weight bytes first (then fewest parameters, then
    // the precisions in the order given): the first that meets the target is the cheapest.
    let mut nets: Vec<Net> = networks_at(&a.quality, &a.precision)?;
    nets.sort_by_key(|n| (n.mlp.uniform_bytes(), n.parameters));
    let steps = a.quality.view_list.len() * a.quality.budgets.len();
    let pb = bar(steps as u64, "frames");
    let s = load_scene(&a.scene, &a.quality.common)?;
    dhoit_runtime::tensors::create_parent(&a.out)?;
    let measures = quality(&s, &a.quality, &nets, false, &pb)?;
    pb.finish_and_clear();
    let mut chosen = None;
    for (n, m) in nets.iter().zip(&measures) {
        let frames = counted(m).count();
        let ratio = if frames == 0 { 1.0 } else { over_optimal(m) };
        let ok = ratio <= a.target;
        println!(
            "{:>7} {:<8} ({} parameters, {} of weights): MSE / optimal {ratio:.3} over {} frames{}",
            n.label,
            n.precision,
            n.parameters,
            dhoit_runtime::budget::format_bytes(n.mlp.uniform_bytes()),
            frames,
            if ok { "  meets the target" } else { "" }
        );
        if ok && chosen.is_none() {
            chosen = Some((n, ratio));
        }
    }
    let Some((n, ratio)) = chosen else {
        bail!(
            "no network meets MSE <= {} x optimal on {}: fine-tune one on it (`dhoit train --scene {}`) or loosen --target",
            a.target,
            a.scene,
            a.scene
        );
    };
    // The chosen file's own metadata (its training settings) kept, its precision recorded.
    let bytes =
        std::fs::read(&n.path).with_context(|| format!("cannot read {}", n.path.display()))?;
    let extra = dhoit_runtime::tensors::File::parse(&bytes)
        .with_context(|| format!("cannot read {}", n.path.display()))?
        .metadata;
    n.mlp.save(&a.out, &extra)?;
    println!(
        "fit: {} at {} ({} of weights) is the cheapest network within {}x of the optimal allocation on {} ({ratio:.3}) -> {}",
        n.label,
        n.precision,
        dhoit_runtime::budget::format_bytes(n.mlp.uniform_bytes()),
        a.target,
        a.scene,
        a.out.display()
    );
    Ok(())
}
