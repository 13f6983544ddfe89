//! Allocation quality from error curves alone, no images: for scenes x views x budgets, the
//! total error (sum over pixels of `e_p(k_p)`, see `dhoit_runtime::alloc`) of the optimal
//! allocation, VKB and DKB with any number of weights files, and the ratios that decide whether
//! the network earns its place: per frame DKB / VKB and DKB / optimal, their geometric means per
//! scene and per budget, and the worst frame. Fast enough to compare training runs; `dhoit
//! compare` renders the images.
//!
//! A frame counts when the optimal allocation leaves some error (F below the frame's fragment
//! total). Errors below [`crate::dataset::error_floor`] (a mean squared error of 1e-14 per
//! channel, float rounding) are raised to it before ratios are taken, so frames that every
//! method renders as good as exactly do not decide a geometric mean.

use crate::Result;
use crate::dataset::{Level, error_floor, load_scenes};
use dhoit_runtime::alloc;
use dhoit_runtime::importance::{self, VkbParams};
use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::raster;
use dhoit_runtime::scene::{self, Camera};
use rayon::prelude::*;
use serde::Serialize;

/// One frame at one budget.
#[derive(Clone, Debug, Serialize)]
pub struct FrameScore {
    pub scene: String,
    pub view: usize,
    pub budget: String,
    pub pixels: u64,
    pub fragments: u64,
    pub budget_fragments: u64,
    /// Total error of the optimal allocation, VKB, and each network in order, with a tail of
    /// its own for every pixel that truncates (the optimal allocation's layout).
    pub optimal: f64,
    pub vkb: f64,
    pub dkb: Vec<f64>,
    /// The same in DKB's and VKB's own layout, whose tails share the slots' pool (a pixel
    /// short by two fragments or fewer keeps them whole: `ErrorCurves::pooled`): the optimum
    /// of that layout and what VKB and each network reach in it.
    pub optimal_pooled: f64,
    pub vkb_pooled: f64,
    pub dkb_pooled: Vec<f64>,
}

impl FrameScore {
    /// An error raised to the floor (see the module docs).
    pub fn floored(&self, e: f64) -> f64 {
        e.max(error_floor(self.pixels))
    }
    /// Whether the frame tells allocations apart: the optimum leaves some error.
    pub fn counts(&self) -> bool {
        self.budget_fragments < self.fragments
    }
    pub fn dkb_over_vkb(&self, i: usize) -> f64 {
        self.floored(self.dkb[i]) / self.floored(self.vkb)
    }
    pub fn dkb_over_optimal(&self, i: usize) -> f64 {
        self.floored(self.dkb[i]) / self.floored(self.optimal)
    }
    pub fn vkb_over_optimal(&self) -> f64 {
        self.floored(self.vkb) / self.floored(self.optimal)
    }
    /// DKB against the optimum of its own layout (pooled tails), both in that layout.
    pub fn dkb_over_pooled_optimal(&self, i: usize) -> f64 {
        self.floored(self.dkb_pooled[i]) / self.floored(self.optimal_pooled)
    }
    pub fn vkb_over_pooled_optimal(&self) -> f64 {
        self.floored(self.vkb_pooled) / self.floored(self.optimal_pooled)
    }
}

/// What to score.
pub struct ScoreSpec<'a> {
    pub scenes: &'a [String],
    pub views: &'a [usize],
    pub orbit_views: usize,
    pub width: u32,
    pub height: u32,
    pub levels: &'a [Level],
    /// One uniform opacity for every surface, or `None`: each scene's own.
    pub opacity: Option<f32>,
    pub networks: &'a [Mlp],
}

/// One budget level of a prepared frame: what does not depend on the network.
struct PreparedLevel {
    budget: String,
    f: u64,
    optimal: f64,
    vkb: f64,
    optimal_pooled: f64,
    vkb_pooled: f64,
    feats: Vec<[f32; importance::FEATURES]>,
    pairs: Vec<bool>,
}

/// One view, rasterized, with its error curves and baselines: networks are scored on it
/// without redoing any of that.
struct PreparedFrame {
    scene: String,
    view: usize,
    pixels: u64,
    fragments: u64,
    counts: Vec<u32>,
    curves: alloc::ErrorCurves,
    /// The curves in DKB's and VKB's layout (pooled tails).
    pooled: alloc::ErrorCurves,
    levels: Vec<PreparedLevel>,
}

/// Frames prepared once and scored for any number of networks (the best-epoch choice of
/// `train --scene` scores every epoch).
pub struct Prepared(Vec<PreparedFrame>);

impl Prepared {
    /// Rasterizes every (scene, view) of `spec` and computes what scoring needs but the
    /// networks; `progress` is called after each (scene, view).
    pub fn new(spec: &ScoreSpec, progress: &(dyn Fn() + Sync)) -> Result<Prepared> {
        // Every view and scene checked before the first frame.
        for &view in spec.views {
            scene::check_view(view, spec.orbit_views)?;
        }
        let scenes = load_scenes(spec.scenes, spec.opacity)?;
        let mut out = Vec::new();
        for (name, sc) in spec.scenes.iter().zip(scenes) {
            let frames: Vec<PreparedFrame> = spec
                .views
                .par_iter()
                .map(|&view| -> Result<PreparedFrame> {
                    let cam = Camera::orbit(&sc, view, spec.orbit_views, (spec.width, spec.height));
                    let fl = raster::rasterize(&sc, &cam, (spec.width, spec.height))?;
                    let curves = alloc::error_curves(&fl, [1.0; 3]);
                    let pooled = curves.pooled();
                    let counts = fl.counts();
                    let pixels = fl.pixel_count() as u64;
                    let total = fl.fragment_count() as u64;
                    let vkb_w: Vec<u32> = importance::vkb_importance(&fl, &VkbParams::default())
                        .iter()
                        .zip(&counts)
                        .map(|(&i, &n)| {
                            if n > 0 {
                                alloc::importance_weight(i)
                            } else {
                                0
                            }
                        })
                        .collect();
                    let levels = spec
                        .levels
                        .iter()
                        .map(|level| {
                            let f = level.fragments(pixels, total).max(1);
                            let (_, rep) = alloc::optimal(&curves, f);
                            let (_, rep_pooled) = alloc::optimal(&pooled, f);
                            let vkb_k = alloc::water_fill(&vkb_w, &counts, f);
                            let (feats, pairs) = importance::features_and_pairs(&fl, f);
                            PreparedLevel {
                                budget: level.label(),
                                f,
                                optimal: rep.total,
                                vkb: curves.total(&vkb_k),
                                optimal_pooled: rep_pooled.total,
                                vkb_pooled: pooled.total(&vkb_k),
                                feats,
                                pairs,
                            }
                        })
                        .collect();
                    progress();
                    Ok(PreparedFrame {
                        scene: scene::file_label(name),
                        view,
                        pixels,
                        fragments: total,
                        counts,
                        curves,
                        pooled,
                        levels,
                    })
                })
                .collect::<Result<_>>()?;
            out.extend(frames);
        }
        Ok(Prepared(out))
    }

    /// Every frame and budget scored for `networks`.
    pub fn score(&self, networks: &[Mlp]) -> Vec<FrameScore> {
        self.0
            .par_iter()
            .flat_map_iter(|fr| {
                fr.levels.iter().map(move |l| {
                    let ks: Vec<Vec<u32>> = networks
                        .iter()
                        .map(|m| m.allocate(&l.feats, &fr.counts, &l.pairs, l.f))
                        .collect();
                    FrameScore {
                        scene: fr.scene.clone(),
                        view: fr.view,
                        budget: l.budget.clone(),
                        pixels: fr.pixels,
                        fragments: fr.fragments,
                        budget_fragments: l.f,
                        optimal: l.optimal,
                        vkb: l.vkb,
                        optimal_pooled: l.optimal_pooled,
                        vkb_pooled: l.vkb_pooled,
                        dkb: ks.iter().map(|k| fr.curves.total(k)).collect(),
                        dkb_pooled: ks.iter().map(|k| fr.pooled.total(k)).collect(),
                    }
                })
            })
            .collect()
    }
}

/// Scores every frame; `progress` is called after each (scene, view).
pub fn score(spec: &ScoreSpec, progress: &(dyn Fn() + Sync)) -> Result<Vec<FrameScore>> {
    Ok(Prepared::new(spec, progress)?.score(spec.networks))
}

/// Geometric mean of `ratio` over the frames whose budget is below their fragments (those
/// that tell allocations apart).
pub fn counted_geomean(scores: &[FrameScore], ratio: impl Fn(&FrameScore) -> f64) -> f64 {
    geomean(scores.iter().filter(|s| s.counts()).map(ratio))
}

/// Geometric mean (1 for no values).
pub fn geomean(v: impl IntoIterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x.ln();
        n += 1;
    }
    if n == 0 { 1.0 } else { (s / n as f64).exp() }
}

/// Frames summarised together.
enum Group {
    Scene(String),
    Budget(String),
    All,
}

impl Group {
    fn holds(&self, s: &FrameScore) -> bool {
        match self {
            Group::Scene(sc) => s.scene == *sc,
            Group::Budget(b) => s.budget == *b,
            Group::All => true,
        }
    }
    fn label(&self) -> String {
        match self {
            Group::Scene(sc) => format!("scene {sc}"),
            Group::Budget(b) => format!("budget {b}"),
            Group::All => "all".into(),
        }
    }
}

/// Summary lines: for each network, per scene and per budget the geometric means of DKB / VKB,
/// DKB / optimal and VKB / optimal, the worst frame's DKB / VKB, and the overall figures.
pub fn summary(scores: &[FrameScore], names: &[String]) -> String {
    let counted: Vec<&FrameScore> = scores.iter().filter(|s| s.counts()).collect();
    let mut out = String::new();
    let mut groups: Vec<Group> = Vec::new();
    let mut scenes: Vec<String> = counted.iter().map(|s| s.scene.clone()).collect();
    scenes.dedup();
    let mut budgets: Vec<String> = Vec::new();
    for s in &counted {
        if !budgets.contains(&s.budget) {
            budgets.push(s.budget.clone());
        }
    }
    groups.extend(scenes.into_iter().map(Group::Scene));
    groups.extend(budgets.into_iter().map(Group::Budget));
    groups.push(Group::All);
    for (i, name) in names.iter().enumerate() {
        out += &format!(
            "\n{name}: geometric means over frames (frames, DKB/VKB, DKB/optimal, VKB/optimal, worst DKB/VKB; \
             then DKB/optimal and VKB/optimal in DKB's and VKB's own layout, pooled tails)\n"
        );
        for g in &groups {
            let label = g.label();
            let f: Vec<&&FrameScore> = counted.iter().filter(|s| g.holds(s)).collect();
            if f.is_empty() {
                continue;
            }
            let worst = f.iter().map(|s| s.dkb_over_vkb(i)).fold(0.0f64, f64::max);
            out += &format!(
                "  {label:<28} {:>4}  {:>8.3}  {:>8.3}  {:>8.3}  {:>8.3}  |  {:>8.3}  {:>8.3}\n",
                f.len(),
                geomean(f.iter().map(|s| s.dkb_over_vkb(i))),
                geomean(f.iter().map(|s| s.dkb_over_optimal(i))),
                geomean(f.iter().map(|s| s.vkb_over_optimal())),
                worst,
                geomean(f.iter().map(|s| s.dkb_over_pooled_optimal(i))),
                geomean(f.iter().map(|s| s.vkb_over_pooled_optimal())),
            );
        }
    }
    out
}
