//! `dhoit compare`: scenes x views x budgets rendered with several methods on the CPU reference,
//! one typed row per frame and method, written as a terminal table, Markdown and JSON from the
//! same rows; a summary of the ratios that decide whether the network earns its place.

use crate::args::{
    NetworkPrecision, ViewArgs, check_view, k_used, load_scenes, load_weights, rasterize_view,
};
use anyhow::Result;
use clap::Args;
use dhoit_runtime::budget::{Budget, format_bytes};
use dhoit_runtime::frame::{Equal, Frame, Method, Options, Renderer};
use dhoit_runtime::image_io;
use dhoit_runtime::scene;
use dhoit_train::plot::{Montage, Scale};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;

#[derive(Args)]
pub struct CompareArgs {
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
    /// Budgets, comma separated: bytes (20MB, 40MiB), slots per pixel (2fpp) or shares of each
    /// frame's fragments (25%).
    #[arg(
        long = "budget",
        alias = "budgets",
        value_delimiter = ',',
        default_value = "2fpp",
        allow_hyphen_values = true
    )]
    budgets: Vec<Budget>,
    /// Methods, comma separated (dkb only when weights are found); all by default.
    #[arg(long, value_delimiter = ',')]
    methods: Vec<Method>,
    /// What a budget holds equal across methods: slots (the same F) or bytes (the same memory
    /// M, each method's F from its own layout; the paper's protocol). M is what DKB spends on
    /// the budget (never more than the exact A-buffer's bytes, unless --always-approximate);
    /// WBOIT and MBOIT run where their targets fit M, MBOIT with the most power moments that do
    /// (unless --mboit-moments is given).
    #[arg(long, default_value = "slots")]
    equal: Equal,
    /// Render each k-buffer's approximation even where the exact A-buffer needs fewer bytes
    /// than the method would at that budget (the papers' equal-F protocol: what measures the
    /// approximation itself). Without it such a frame renders the A-buffer, marked "(exact)".
    #[arg(long)]
    always_approximate: bool,
    #[command(flatten)]
    network: NetworkPrecision,
    #[command(flatten)]
    common: ViewArgs,
    #[command(flatten)]
    params: crate::args::MethodParams,
    /// Directory for images, report.json, report.md and summary.md.
    #[arg(long, default_value = "out/compare")]
    out: PathBuf,
    /// Write no images (tables and reports only: faster sweeps).
    #[arg(long)]
    no_images: bool,
    /// Also write the summary tables (Markdown, no images) to this file.
    #[arg(long)]
    summary: Option<PathBuf>,
    /// A picture to show in each montage's first column, beside the methods (a sample asset's
    /// screenshot, with `--camera asset`): PNG or JPEG, scaled to fit the frame on white.
    #[arg(long)]
    beside: Option<PathBuf>,
}

/// One method on one frame.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub scene: String,
    pub view: usize,
    pub width: u32,
    pub height: u32,
    pub budget: String,
    pub equal: &'static str,
    pub method: &'static str,
    pub mse: f64,
    /// Mean FLIP against the A-buffer image (sRGB8, 67 pixels per degree), in [0, 1].
    pub flip: f64,
    pub fragments_total: u64,
    pub fragments_captured: u64,
    pub budget_fragments: u64,
    pub budget_bytes: u64,
    pub allocated_bytes: u64,
    /// What the exact A-buffer allocates for the same frame (paper 004's memory: 8-byte keys).
    pub abuffer_bytes: u64,
    /// sum min(k, n) / F.
    pub budget_used: f64,
    /// Whether the k-buffer method rendered the exact A-buffer: its budget held every
    /// fragment, or the A-buffer needed no more bytes than the method would.
    pub exact: bool,
    pub raster_ms: f64,
    pub allocation_ms: f64,
    pub composite_ms: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub optimal: Option<serde_json::Value>,
}

impl Row {
    fn captured(&self) -> f64 {
        self.fragments_captured as f64 / self.fragments_total.max(1) as f64
    }
    /// Whether the frame tells allocations apart: F below the frame's fragments.
    fn counts(&self) -> bool {
        self.budget_fragments < self.fragments_total
    }
}

const HEADER: [&str; 10] = [
    "method",
    "MSE",
    "FLIP",
    "captured",
    "F(M)",
    "sum k / F",
    "allocated",
    "B/px",
    "/ A-buffer",
    "ms",
];

fn cells(r: &Row) -> [String; 10] {
    let pixels = (r.width as u64 * r.height as u64).max(1) as f64;
    [
        // A k-buffer that truncates no fragment because the A-buffer is no dearer, marked.
        if r.exact && r.counts() {
            format!("{} (exact)", r.method)
        } else {
            r.method.to_string()
        },
        format!("{:.4e}", r.mse),
        format!("{:.4}", r.flip),
        format!("{:.1}%", 100.0 * r.captured()),
        r.budget_fragments.to_string(),
        format!("{:.1}%", 100.0 * r.budget_used),
        format_bytes(r.allocated_bytes),
        format!("{:.1}", r.allocated_bytes as f64 / pixels),
        format!(
            "{:.2}",
            r.allocated_bytes as f64 / r.abuffer_bytes.max(1) as f64
        ),
        format!("{:.1}", r.allocation_ms + r.composite_ms),
    ]
}

/// A table as aligned text and as Markdown.
pub(crate) fn table(header: &[&str], rows: &[Vec<String>]) -> (String, String) {
    let widths: Vec<usize> = (0..header.len())
        .map(|c| {
            rows.iter()
                .map(|r| r[c].len())
                .chain([header[c].len()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |cols: Vec<&str>| -> String {
        cols.iter()
            .enumerate()
            .map(|(c, v)| {
                if c == 0 {
                    format!("{v:<w$}", w = widths[c])
                } else {
                    format!("{v:>w$}", w = widths[c])
                }
            })
            .collect::<Vec<_>>()
            .join("  ")
    };
    let mut text = line(header.to_vec()) + "\n";
    let mut md = format!(
        "| {} |\n|{}\n",
        header.join(" | "),
        "---|".repeat(header.len())
    );
    for r in rows {
        text += &(line(r.iter().map(String::as_str).collect()) + "\n");
        md += &format!("| {} |\n", r.join(" | "));
    }
    (text, md)
}

/// A mean squared error below which a frame counts as exact when ratios are taken (float
/// rounding; 8-bit quantisation alone is about 1e-6).
pub const MSE_FLOOR: f64 = 1e-14;

pub(crate) fn geomean(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    (v.iter().map(|x| x.ln()).sum::<f64>() / v.len() as f64).exp()
}

/// The arithmetic mean (NaN of nothing).
fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// One frame's MSE ratios.
struct Ratio {
    scene: String,
    budget: String,
    dkb_vkb: f64,
    dkb_optimal: f64,
    vkb_optimal: f64,
    /// Against the optimum of their own layout (`optimal-pooled`), where it ran.
    dkb_pooled: Option<f64>,
    vkb_pooled: Option<f64>,
    /// The frame's mean FLIP of DKB and of VKB.
    dkb_flip: f64,
    vkb_flip: f64,
}

/// DKB against VKB and the optimal allocation on every frame where all three ran and the
/// budget is below the frame's fragments.
fn ratios(rows: &[Row]) -> Vec<Ratio> {
    let find = |r: &Row, m: &str| {
        rows.iter().find(|x| {
            x.method == m && x.scene == r.scene && x.view == r.view && x.budget == r.budget
        })
    };
    rows.iter()
        .filter(|r| r.method == "dkb" && r.counts())
        .filter_map(|d| {
            let v = find(d, "vkb")?;
            let o = find(d, "optimal")?;
            let fl = |x: f64| x.max(MSE_FLOOR);
            let pooled = find(d, "optimal-pooled").map(|q| fl(q.mse));
            Some(Ratio {
                dkb_pooled: pooled.map(|q| fl(d.mse) / q),
                vkb_pooled: pooled.map(|q| fl(v.mse) / q),
                scene: d.scene.clone(),
                budget: d.budget.clone(),
                dkb_vkb: fl(d.mse) / fl(v.mse),
                dkb_optimal: fl(d.mse) / fl(o.mse),
                vkb_optimal: fl(v.mse) / fl(o.mse),
                dkb_flip: d.flip,
                vkb_flip: v.flip,
            })
        })
        .collect()
}

/// What the summary groups by, in the order the rows first name them (the A-buffer, the
/// reference, is no method of its tables).
struct Axes {
    budgets: Vec<String>,
    methods: Vec<&'static str>,
    scenes: Vec<String>,
}

impl Axes {
    fn of(rows: &[Row]) -> Axes {
        let mut x = Axes {
            budgets: Vec::new(),
            methods: Vec::new(),
            scenes: Vec::new(),
        };
        for r in rows {
            if !x.budgets.contains(&r.budget) {
                x.budgets.push(r.budget.clone());
            }
            if r.method != "abuffer" && !x.methods.contains(&r.method) {
                x.methods.push(r.method);
            }
            if !x.scenes.contains(&r.scene) {
                x.scenes.push(r.scene.clone());
            }
        }
        x
    }
}

/// The summary as aligned text and as Markdown, section by section.
#[derive(Default)]
struct Summary {
    text: String,
    md: String,
}

impl Summary {
    /// A titled table, in both.
    fn section(&mut self, title: &str, header: &[&str], rows: &[Vec<String>]) {
        let (t, m) = table(header, rows);
        let _ = write!(self.text, "\n{title}\n{t}");
        let _ = write!(self.md, "\n## {title}\n\n{m}");
    }
}

/// The summary: mean MSE and FLIP per budget and method, bytes a frame pixel, ratio tables per
/// scene and per budget, the accuracy targets with whether they hold, and scene x budget
/// matrices.
pub fn summary(rows: &[Row], equal: Equal) -> (String, String) {
    let axes = Axes::of(rows);
    let mut out = Summary::default();
    mean_tables(rows, &axes, equal, &mut out);
    memory_table(rows, &axes, equal, &mut out);
    let r = ratios(rows);
    if !r.is_empty() {
        ratio_tables(&r, &axes, equal, &mut out);
        targets_table(&r, &axes, &mut out);
        matrices(&r, &axes, &mut out);
    }
    (out.text, out.md)
}

/// Mean MSE and mean FLIP against the A-buffer, per budget and method.
fn mean_tables(rows: &[Row], axes: &Axes, equal: Equal, out: &mut Summary) {
    let Axes {
        budgets, methods, ..
    } = axes;
    let mut head = vec!["budget"];
    head.extend(methods.iter());
    type Metric = (&'static str, fn(&Row) -> f64, fn(f64) -> String);
    let metrics: [Metric; 2] = [
        ("MSE", |r| r.mse, |v| format!("{v:.3e}")),
        ("FLIP", |r| r.flip, |v| format!("{v:.4}")),
    ];
    for (metric, get, show) in metrics {
        let mean_rows: Vec<Vec<String>> = budgets
            .iter()
            .map(|b| {
                let mut row = vec![b.clone()];
                for m in methods {
                    let v: Vec<f64> = rows
                        .iter()
                        .filter(|r| r.budget == *b && r.method == *m)
                        .map(get)
                        .collect();
                    row.push(if v.is_empty() {
                        "n/a".into()
                    } else {
                        show(v.iter().sum::<f64>() / v.len() as f64)
                    });
                }
                row
            })
            .collect();
        let title = format!(
            "Mean {metric} against the A-buffer over all frames ({})",
            equal.name()
        );
        out.section(&title, &head, &mean_rows);
    }
}

/// Bytes a frame pixel as each method allocates them, beside the exact A-buffer's.
fn memory_table(rows: &[Row], axes: &Axes, equal: Equal, out: &mut Summary) {
    let Axes {
        budgets, methods, ..
    } = axes;
    // Memory: bytes a frame pixel as each method allocates them, beside the exact A-buffer's
    // for the same frames (8-byte keys; the output image counted for no method).
    let mut mem_head = vec!["budget", "abuffer"];
    mem_head.extend(methods.iter());
    let per_pixel = |r: &Row| r.allocated_bytes as f64 / (r.width as f64 * r.height as f64);
    let mem_rows: Vec<Vec<String>> = budgets
        .iter()
        .map(|b| {
            let at = |m: &str| -> Vec<&Row> {
                rows.iter()
                    .filter(|r| r.budget == *b && r.method == m)
                    .collect()
            };
            let mut row = vec![b.clone()];
            let exact = at("abuffer");
            row.push(format!(
                "{:.1}",
                mean(&exact.iter().map(|r| per_pixel(r)).collect::<Vec<_>>())
            ));
            for m in methods {
                let v = at(m);
                row.push(if v.is_empty() {
                    "n/a".into()
                } else {
                    let ratio: Vec<f64> = v
                        .iter()
                        .map(|r| r.allocated_bytes as f64 / r.abuffer_bytes.max(1) as f64)
                        .collect();
                    let worst = ratio.iter().copied().fold(0.0, f64::max);
                    format!(
                        "{:.1} ({:.2}x, worst {:.2}x)",
                        mean(&v.iter().map(|r| per_pixel(r)).collect::<Vec<_>>()),
                        geomean(&ratio),
                        worst
                    )
                });
            }
            row
        })
        .collect();
    let title = format!(
        "Bytes a frame pixel, mean over frames ({}; in brackets the geometric mean and the worst \
         frame of each method's bytes over the exact A-buffer's)",
        equal.name()
    );
    out.section(&title, &mem_head, &mem_rows);
}

/// The geometric mean of a ratio against the pooled optimum over `g`, where every frame of it
/// has one (`optimal-pooled` ran).
fn pooled_geomean(g: &[&Ratio], pick: fn(&Ratio) -> Option<f64>) -> Option<f64> {
    let v: Option<Vec<f64>> = g.iter().map(|x| pick(x)).collect();
    v.filter(|v| !v.is_empty()).map(|v| geomean(&v))
}

/// DKB against VKB and the optimal allocation, MSE ratios and FLIP, per scene and per budget.
fn ratio_tables(r: &[Ratio], axes: &Axes, equal: Equal, out: &mut Summary) {
    let Axes {
        budgets, scenes, ..
    } = axes;
    let group = |keep: &dyn Fn(&Ratio) -> bool| -> Vec<String> {
        let g: Vec<_> = r.iter().filter(|x| keep(x)).collect();
        let dv: Vec<f64> = g.iter().map(|x| x.dkb_vkb).collect();
        vec![
            g.len().to_string(),
            format!("{:.3}", geomean(&dv)),
            format!("{:.3}", dv.iter().copied().fold(0.0, f64::max)),
            format!(
                "{:.3}",
                geomean(&g.iter().map(|x| x.dkb_optimal).collect::<Vec<_>>())
            ),
            format!(
                "{:.3}",
                geomean(&g.iter().map(|x| x.vkb_optimal).collect::<Vec<_>>())
            ),
            pooled_geomean(&g, |x| x.dkb_pooled).map_or("-".into(), |v| format!("{v:.3}")),
            pooled_geomean(&g, |x| x.vkb_pooled).map_or("-".into(), |v| format!("{v:.3}")),
            format!(
                "{:.4}",
                mean(&g.iter().map(|x| x.dkb_flip).collect::<Vec<_>>())
            ),
            format!(
                "{:.4}",
                mean(&g.iter().map(|x| x.vkb_flip).collect::<Vec<_>>())
            ),
        ]
    };
    let head = [
        "",
        "frames",
        "DKB/VKB (geo. mean)",
        "worst DKB/VKB",
        "DKB/optimal",
        "VKB/optimal",
        "DKB/pooled optimum",
        "VKB/pooled optimum",
        "DKB FLIP",
        "VKB FLIP",
    ];
    let mut by_scene: Vec<Vec<String>> = Vec::new();
    for s in scenes {
        if r.iter().any(|x| x.scene == *s) {
            let mut row = vec![s.clone()];
            row.extend(group(&|x| x.scene == *s));
            by_scene.push(row);
        }
    }
    let mut all = vec!["all".to_string()];
    all.extend(group(&|_| true));
    by_scene.push(all);
    let mut by_budget: Vec<Vec<String>> = Vec::new();
    for b in budgets {
        if r.iter().any(|x| x.budget == *b) {
            let mut row = vec![b.clone()];
            row.extend(group(&|x| x.budget == *b));
            by_budget.push(row);
        }
    }
    let note = format!(
        "Frames whose budget is below their fragment total, {}; MSE below {MSE_FLOOR:e} counts as {MSE_FLOOR:e}.",
        equal.name()
    );
    for (title, rows) in [
        ("MSE ratios per scene", by_scene),
        ("MSE ratios per budget", by_budget),
    ] {
        let (t, m) = table(&head, &rows);
        let _ = write!(out.text, "\n{title} ({note})\n{t}");
        let _ = write!(out.md, "\n## {title}\n\n{note}\n\n{m}");
    }
}

/// The accuracy targets and whether they hold.
fn targets_table(r: &[Ratio], axes: &Axes, out: &mut Summary) {
    let scenes = &axes.scenes;
    // The targets. A scene every method renders exact to the floor at every budget (all its
    // ratios 1) decides nothing: it is named, not counted against the per-scene target.
    let decided = |s: &String| {
        r.iter()
            .any(|x| x.scene == *s && (x.dkb_vkb != 1.0 || x.vkb_optimal != 1.0))
    };
    let undecided: Vec<String> = scenes
        .iter()
        .filter(|s| r.iter().any(|x| x.scene == **s) && !decided(s))
        .cloned()
        .collect();
    let per_scene: Vec<(String, f64)> = scenes
        .iter()
        .filter(|s| decided(s))
        .filter_map(|s| {
            let v: Vec<f64> = r
                .iter()
                .filter(|x| x.scene == *s)
                .map(|x| x.dkb_vkb)
                .collect();
            (!v.is_empty()).then(|| (s.clone(), geomean(&v)))
        })
        .collect();
    let worst_scene = per_scene
        .iter()
        .cloned()
        .fold(("".to_string(), 0.0), |a, b| if b.1 > a.1 { b } else { a });
    let worst = r
        .iter()
        .fold(None::<&Ratio>, |a, x| match a {
            Some(y) if y.dkb_vkb >= x.dkb_vkb => Some(y),
            _ => Some(x),
        })
        .expect("some ratio");
    let frames_over = r.iter().filter(|x| x.dkb_vkb > 1.1).count();
    // Scenes whose mean FLIP for DKB is above VKB's.
    let flip_over: Vec<String> = scenes
        .iter()
        .filter(|s| {
            let g: Vec<&Ratio> = r.iter().filter(|x| x.scene == **s).collect();
            !g.is_empty()
                && mean(&g.iter().map(|x| x.dkb_flip).collect::<Vec<_>>())
                    > mean(&g.iter().map(|x| x.vkb_flip).collect::<Vec<_>>())
        })
        .cloned()
        .collect();
    // Against the optimum of DKB's own layout where it ran (optimal-pooled), else the per-pixel
    // one.
    let all: Vec<&Ratio> = r.iter().collect();
    let (opt, against) = match pooled_geomean(&all, |x| x.dkb_pooled) {
        Some(v) => (v, "the optimum of its own layout, optimal-pooled"),
        None => (
            geomean(&r.iter().map(|x| x.dkb_optimal).collect::<Vec<_>>()),
            "the per-pixel optimum, optimal",
        ),
    };
    let verdict = |ok: bool| if ok { "holds" } else { "does not hold" };
    let targets = vec![
        vec![
            "DKB/VKB <= 0.8 (geometric mean, every scene)".to_string(),
            if undecided.is_empty() {
                format!("worst scene {} at {:.3}", worst_scene.0, worst_scene.1)
            } else {
                format!(
                    "worst scene {} at {:.3} ({} exact to the floor for every method: {})",
                    worst_scene.0,
                    worst_scene.1,
                    undecided.len(),
                    undecided.join(", ")
                )
            },
            verdict(worst_scene.1 <= 0.8).to_string(),
        ],
        vec![
            "DKB/VKB <= 1.1 on every frame".to_string(),
            format!(
                "{frames_over} of {} frames above; worst {:.3} ({} at {})",
                r.len(),
                worst.dkb_vkb,
                worst.scene,
                worst.budget
            ),
            verdict(frames_over == 0).to_string(),
        ],
        vec![
            "DKB's mean FLIP <= VKB's on every scene".to_string(),
            if flip_over.is_empty() {
                "every scene".to_string()
            } else {
                format!("above on {}", flip_over.join(", "))
            },
            verdict(flip_over.is_empty()).to_string(),
        ],
        vec![
            "DKB/optimal <= 3 (geometric mean)".to_string(),
            format!("{opt:.3} (against {against})"),
            verdict(opt <= 3.0).to_string(),
        ],
        vec![
            "DKB/optimal <= 1.3 (moonshot)".to_string(),
            format!("{opt:.3} (against {against})"),
            verdict(opt <= 1.3).to_string(),
        ],
    ];
    out.section("Accuracy targets", &["target", "measured", ""], &targets);
}

/// Scene x budget matrices of DKB/VKB and DKB/optimal (Markdown only: wide).
fn matrices(r: &[Ratio], axes: &Axes, out: &mut Summary) {
    let Axes {
        budgets, scenes, ..
    } = axes;
    for (title, pick) in [
        (
            "DKB/VKB per scene and budget",
            (|x: &Ratio| x.dkb_vkb) as fn(&Ratio) -> f64,
        ),
        ("DKB/optimal per scene and budget", |x: &Ratio| {
            x.dkb_optimal
        }),
    ] {
        let cols: Vec<&String> = budgets
            .iter()
            .filter(|b| r.iter().any(|x| x.budget == **b))
            .collect();
        let mut head = vec!["scene"];
        head.extend(cols.iter().map(|b| b.as_str()));
        let rows: Vec<Vec<String>> = scenes
            .iter()
            .filter(|s| r.iter().any(|x| x.scene == **s))
            .map(|s| {
                let mut row = vec![s.clone()];
                for b in &cols {
                    let v: Vec<f64> = r
                        .iter()
                        .filter(|x| x.scene == *s && x.budget == **b)
                        .map(pick)
                        .collect();
                    row.push(if v.is_empty() {
                        "-".into()
                    } else {
                        format!("{:.2}", geomean(&v))
                    });
                }
                row
            })
            .collect();
        let (_, m) = table(&head, &rows);
        let _ = write!(
            out.md,
            "\n## {title}\n\nGeometric mean over the views; '-' where the budget holds every fragment.\n\n{m}"
        );
    }
}

pub fn run(a: CompareArgs) -> Result<()> {
    let budgets = a.budgets.clone();
    // The picture beside the methods, read before anything renders.
    let beside = a.beside.as_deref().map(read_beside).transpose()?;
    let (methods, weights) = methods_and_weights(&a)?;
    // Every scene and view checked before the first frame.
    for &view in &a.view_list {
        check_view(view, a.common.views)?;
    }
    let loaded = load_scenes(&a.scenes, &a.common)?;
    dhoit_runtime::tensors::create_folder(&a.out)?;
    let mut rows: Vec<Row> = Vec::new();
    let mut md = format!(
        "# dhoit comparison\n\nMSE against the A-buffer image (linear RGB), {}.\n",
        a.equal.name()
    );
    for (name, scene) in a.scenes.iter().zip(loaded) {
        let label = scene::file_label(name);
        for &view in &a.view_list {
            let (fl, raster_ms) = rasterize_view(&scene, view, &a.common)?;
            dhoit_runtime::frame::check_memory(&methods, &fl)?;
            for budget in &budgets {
                let mut options = a.params.apply(
                    Options {
                        weights: weights.as_ref(),
                        equal: a.equal,
                        decision: dhoit_runtime::budget::Decision {
                            exact_when_cheaper: !a.always_approximate,
                            ..Default::default()
                        },
                        ..Options::new(*budget, a.common.background)
                    },
                    &crate::args::view_camera(&scene, view, &a.common),
                );
                // In a memory M (equal bytes, or a budget in bytes) MBOIT takes the most power
                // moments whose targets fit M, as `versus` gives it, unless they are given.
                let mut moments_note = None;
                if a.params.mboit_moments.is_none() && methods.contains(&Method::Mboit) {
                    let px = fl.pixel_count() as u64;
                    if let Ok(Budget::Bytes(m)) = Renderer::new(&fl, options).budget()
                        && let Some(n) = dhoit_runtime::budget::mboit_moments_within(px, m)
                    {
                        options.mboit = a.params.mboit(n);
                        moments_note = Some(format!(
                            "mboit: {n} power moments, the most whose targets fit {}",
                            format_bytes(m)
                        ));
                    }
                }
                let (frames, skipped) = render_methods(&Renderer::new(&fl, options), &methods)?;
                let reference = frames[0].image.clone();
                let reference8 = image_io::to_srgb8(&reference);
                let flips: Vec<(f64, Vec<f32>)> = frames
                    .iter()
                    .map(|f| {
                        let test = image_io::to_srgb8(&f.image);
                        image_io::flip(&reference8, &test, fl.size())
                    })
                    .collect();
                let at = FrameAt {
                    scene: &scene.name,
                    view,
                    budget: budget.to_string(),
                    equal: a.equal,
                    raster_ms,
                };
                let frame_rows = rows_of(&frames, &flips, &fl, &reference, &at);
                md += &print_frame(&fl, &at, &frame_rows, &frames, &skipped);
                if let Some(note) =
                    moments_note.filter(|_| frames.iter().any(|f| f.method == Method::Mboit))
                {
                    println!("{note}");
                    md += &format!("\n{note}\n");
                }
                if !a.no_images {
                    let tag = format!("{label}_v{view}_{}", budget.to_string().replace(' ', ""));
                    let budget_label = format!("{budget} ({})", a.equal.name());
                    write_images(
                        &a.out.join(&tag),
                        &budget_label,
                        &fl,
                        (&frames, &frame_rows, &flips),
                        &reference,
                        beside.as_ref(),
                    )?;
                    let order: Vec<&str> = frames.iter().map(|f| f.method.name()).collect();
                    md += &format!(
                        "\n![{tag}]({tag}_montage.png)\n\nColumns: {}. Rows: image; k(p) used; colour error |C - C_exact|; FLIP error map (each row on the colour scale at its right, one scale for the row).\n",
                        order.join(", ")
                    );
                }
                rows.extend(frame_rows);
            }
        }
    }
    write_reports(&a, &rows, md)?;
    println!(
        "\n{}report.json, report.md and summary.md -> {}",
        if a.no_images {
            ""
        } else {
            "images, side-by-side montages, "
        },
        a.out.display()
    );
    Ok(())
}

/// The picture `--beside` names (its file name as its label), as sRGB.
fn read_beside(path: &std::path::Path) -> Result<(String, image::RgbImage)> {
    let label = path
        .file_name()
        .map_or("reference".into(), |n| n.to_string_lossy().into_owned());
    let img = image::open(path)
        .map_err(|e| anyhow::anyhow!("cannot read --beside {}: {e}", path.display()))?;
    Ok((label, img.to_rgb8()))
}

/// The methods to run, the A-buffer first, and the network DKB runs: asked for by name, DKB
/// needs its weights; among every method by default it is left out, saying so, where none are
/// found.
fn methods_and_weights(a: &CompareArgs) -> Result<(Vec<Method>, Option<dhoit_runtime::mlp::Mlp>)> {
    let mut methods: Vec<Method> = if a.methods.is_empty() {
        Method::ALL.to_vec()
    } else {
        a.methods.clone()
    };
    if !methods.contains(&Method::Abuffer) {
        methods.insert(0, Method::Abuffer);
    }
    let weights = load_weights(
        &a.common,
        a.network.precision,
        !a.methods.is_empty() && methods.contains(&Method::Dkb),
    )?;
    if weights.is_none() && methods.contains(&Method::Dkb) {
        eprintln!(
            "note: no weights found ({} or --weights), dkb left out",
            dhoit_train::cli::DEFAULT_WEIGHTS
        );
        methods.retain(|&m| m != Method::Dkb);
    }
    Ok((methods, weights))
}

/// Every method of one frame; a method the budget cannot hold (FKB and MLAB need a slot for
/// every pixel) is reported and left out, any other error stops the run. The A-buffer first.
fn render_methods(renderer: &Renderer, methods: &[Method]) -> Result<(Vec<Frame>, Vec<String>)> {
    let mut frames: Vec<Frame> = Vec::new();
    let mut skipped: Vec<String> = Vec::new();
    for &m in methods {
        match renderer.render(m) {
            Ok(f) => frames.push(f),
            Err(e @ dhoit_runtime::Error::Budget(..)) if m != Method::Abuffer => {
                skipped.push(format!("{}: {e}", m.name()));
            }
            Err(e) => return Err(e.into()),
        }
    }
    Ok((frames, skipped))
}

/// Which frame a row is of.
struct FrameAt<'a> {
    scene: &'a str,
    view: usize,
    budget: String,
    equal: Equal,
    raster_ms: f64,
}

/// The report's rows of one frame's methods, against the reference image.
fn rows_of(
    frames: &[Frame],
    flips: &[(f64, Vec<f32>)],
    fl: &dhoit_runtime::fragment::FragmentLists,
    reference: &dhoit_runtime::composite::Image,
    at: &FrameAt,
) -> Vec<Row> {
    let counts = fl.counts();
    frames
        .iter()
        .zip(flips)
        .map(|(f, (flip, _))| {
            let used =
                f.k.iter()
                    .zip(&counts)
                    .map(|(&k, &n)| k.min(n) as u64)
                    .sum::<u64>() as f64
                    / f.budget_fragments.max(1) as f64;
            Row {
                scene: at.scene.to_string(),
                view: at.view,
                width: fl.width,
                height: fl.height,
                budget: at.budget.clone(),
                equal: at.equal.name(),
                method: f.method.name(),
                mse: f.image.mse(reference),
                flip: *flip,
                fragments_total: f.fragments_total,
                fragments_captured: f.fragments_captured,
                budget_fragments: f.budget_fragments,
                budget_bytes: f.budget_bytes,
                allocated_bytes: f.allocated_bytes,
                // The frame's own A-buffer, its tint words included.
                abuffer_bytes: dhoit_runtime::budget::abuffer_bytes(
                    fl.pixel_count() as u64,
                    fl.fragment_count() as u64,
                    fl.tinted(),
                ),
                budget_used: used,
                exact: f.exact,
                raster_ms: at.raster_ms,
                allocation_ms: f.allocation_ms,
                composite_ms: f.composite_ms,
                optimal: f.optimal.map(|rep| {
                    let mut v = serde_json::to_value(rep).expect("report");
                    v["gap"] = rep.gap().into();
                    v
                }),
            }
        })
        .collect()
}

/// One frame's table, printed; its Markdown returned.
fn print_frame(
    fl: &dhoit_runtime::fragment::FragmentLists,
    at: &FrameAt,
    frame_rows: &[Row],
    frames: &[Frame],
    skipped: &[String],
) -> String {
    let title = format!(
        "{} view {}, {}x{}, budget {} ({}): {} fragments, max depth {}",
        at.scene,
        at.view,
        fl.width,
        fl.height,
        at.budget,
        at.equal.name(),
        fl.fragment_count(),
        fl.max_depth_complexity()
    );
    let cell_rows: Vec<Vec<String>> = frame_rows.iter().map(|r| cells(r).to_vec()).collect();
    let (t, m) = table(&HEADER, &cell_rows);
    println!("\n{title}\n\n{t}");
    let mut md = format!("\n## {title}\n\n{m}");
    for sk in skipped {
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
    md
}

/// report.json, report.md (the frames' tables, then the summary) and summary.md (and
/// `--summary`'s copy), written whole.
fn write_reports(a: &CompareArgs, rows: &[Row], mut md: String) -> Result<()> {
    let (text, sum_md) = summary(rows, a.equal);
    println!("{text}");
    md += &sum_md;
    let json = serde_json::to_string_pretty(rows)?;
    dhoit_runtime::tensors::write_atomic(&a.out.join("report.json"), json.as_bytes())?;
    dhoit_runtime::tensors::write_atomic(&a.out.join("report.md"), md.as_bytes())?;
    let mut small = format!(
        "# dhoit evaluation summary\n\nScenes: {}. Views {:?} at {}. MSE against the A-buffer \
         image, {}. Generated by `dhoit compare` (`make eval` regenerates this file); every frame in \
         report.md and report.json beside the images.\n",
        a.scenes
            .iter()
            .map(|s| scene::file_label(s))
            .collect::<Vec<_>>()
            .join(", "),
        a.view_list,
        a.common.res,
        a.equal.name()
    );
    small += &sum_md;
    dhoit_runtime::tensors::write_atomic(&a.out.join("summary.md"), small.as_bytes())?;
    if let Some(path) = &a.summary {
        dhoit_runtime::tensors::write_atomic(path, small.as_bytes())?;
    }
    Ok(())
}

/// A frame's FLIP score and error map.
type Flip = (f64, Vec<f32>);

/// The frame's images and montage, `STEM_METHOD.png` and `STEM_montage.png`: each method's
/// frame, report row and FLIP map, with `beside` (a name and a picture) in the first column.
fn write_images(
    stem: &std::path::Path,
    budget: &str,
    fl: &dhoit_runtime::fragment::FragmentLists,
    (frames, rows, flips): (&[Frame], &[Row], &[Flip]),
    reference: &dhoit_runtime::composite::Image,
    beside: Option<&(String, image::RgbImage)>,
) -> Result<()> {
    let counts = fl.counts();
    let covered: Vec<bool> = counts.iter().map(|&n| n > 0).collect();
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
    let used: Vec<Vec<f32>> = frames.iter().map(|f| k_used(&f.k, &counts)).collect();
    let k_max = used.iter().flatten().copied().fold(0.0f32, f32::max);
    let mut tiles = vec![Vec::new(), Vec::new(), Vec::new(), Vec::new()];
    let mut columns = Vec::new();
    for (col, f) in frames.iter().enumerate() {
        image_io::write_image(
            &PathBuf::from(format!("{}_{}.png", stem.display(), f.method.name())),
            &f.image,
        )?;
        tiles[0].push(image_io::to_srgb8(&f.image));
        tiles[1].push(image_io::heat_rgb8(&used[col], &covered, k_max));
        tiles[2].push(image_io::heat_rgb8(&errors[col], &covered, err_max));
        tiles[3].push(image_io::flip_rgb8(&flips[col].1, fl.size()));
        let r = &rows[col];
        columns.push(vec![
            f.method.name().to_string(),
            if f.method == Method::Abuffer {
                format!("{} fragments", r.fragments_total)
            } else {
                format!("F {} of {}", r.budget_fragments, r.fragments_total)
            },
            format!("MSE {:.2e}", r.mse),
            format!("FLIP {:.4}", r.flip),
        ]);
    }
    columns[0].insert(0, budget.to_string());
    for c in columns.iter_mut().skip(1) {
        c.insert(0, String::new());
    }
    if let Some((name, picture)) = beside {
        let (w, h) = fl.size();
        tiles[0].insert(0, fitted(picture, (w, h)));
        for row in tiles.iter_mut().skip(1) {
            row.insert(0, vec![255; (3 * w * h) as usize]);
        }
        columns.insert(
            0,
            vec![String::new(), name.clone(), "(the asset's own)".into()],
        );
    }
    let montage = Montage {
        tile_w: fl.width,
        tile_h: fl.height,
        tiles,
        columns,
        rows: vec![
            "image".into(),
            "k(p) used\n= min(k, n)".into(),
            "|C - C_exact|".into(),
            "FLIP".into(),
        ],
        scales: vec![
            None,
            Some(Scale {
                colour: image_io::ramp,
                lo: "0".into(),
                hi: format!("{k_max}"),
            }),
            Some(Scale {
                colour: image_io::ramp,
                lo: "0".into(),
                hi: format!("{err_max:.3}"),
            }),
            Some(Scale {
                colour: image_io::magma,
                lo: "0".into(),
                hi: "1".into(),
            }),
        ],
    };
    montage.write(&PathBuf::from(format!("{}_montage.png", stem.display())))?;
    Ok(())
}

/// `picture` scaled to fit `size` (width, height) (its aspect kept), centred on white: RGB8, a montage tile.
fn fitted(picture: &image::RgbImage, size: (u32, u32)) -> Vec<u8> {
    let (w, h) = size;
    let scale = (w as f32 / picture.width() as f32).min(h as f32 / picture.height() as f32);
    let (pw, ph) = (
        ((picture.width() as f32 * scale).round() as u32).clamp(1, w),
        ((picture.height() as f32 * scale).round() as u32).clamp(1, h),
    );
    let small = image::imageops::resize(picture, pw, ph, image::imageops::FilterType::Triangle);
    let mut tile = image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    image::imageops::overlay(
        &mut tile,
        &small,
        ((w - pw) / 2) as i64,
        ((h - ph) / 2) as i64,
    );
    tile.into_raw()
}
