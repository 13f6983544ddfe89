//! Training data: for each scene, view and budget, fragment lists -> the 12 features -> the
//! optimal allocation k* and what any other k would cost, for a uniform sample of the covered
//! pixels whose k is not forced (the most slots the pixel can use, `alloc::useful_cap`, above
//! the smallest k, so the network has a choice to make).
//!
//! What a k costs: the pixel's Lagrangian regret `R_p(k) = e_p(k) - e_p(k*) + mu (k - k*)`,
//! with `e_p` the pixel's error curve and `mu` the budget's multiplier (the optimal
//! allocation's critical gain per slot). Summed over a frame's pixels, for any allocation with
//! the same total, it is exactly the error above the optimum, `E(k) - E*`; divided by the
//! frame's optimal error `E*` (floored, see [`error_floor`]) it is `E / E* - 1`. Each sample
//! stores R at `k* - D ..= k* + D` ([`REGRET_WINDOW`] values; above n only the price of the
//! slots grows, below lo the first slope is extended), so a loss can weigh each pixel by what a
//! wrong k costs in the image. Samples keep the frame (scene, view, budget) they come from, so
//! a loss can fit a frame's predictions to its budget as the runtime does.
//!
//! On disk: one safetensors shard per (scene, view, budget) with `features` f32 [N,12],
//! `target` f32 [N] (the paper's `k* / max_q k*(q)`), `count` u32 [N] (n), `k_opt` u32 [N],
//! `tail_pair` u32 [N] (1 where the two farthest fragments share one colour) and
//! `regret` f32 [N, 17] (metadata: scene, view, width, height, budget, budget_fragments,
//! optimal_error, critical_gain), and a `manifest.json` written last, so a dataset without a
//! manifest is incomplete and refused.

use crate::{Error, IoOp, Result};
use dhoit_runtime::alloc;
use dhoit_runtime::budget::{self, Budget};
use dhoit_runtime::importance::{self, FEATURES};
use dhoit_runtime::raster;
use dhoit_runtime::rng::Rng;
use dhoit_runtime::scene::{self, Camera, Opacity};
use dhoit_runtime::tensors::{self, Entry, FormatError};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// A scene's opacity: one for every surface, or (`None`) the scene's own.
pub fn opacity_of(uniform: Option<f32>) -> Opacity {
    uniform.map_or(Opacity::Native, Opacity::Uniform)
}

/// Loads scenes as training and scoring see them: at one opacity or their own, their glass
/// tinted, as the command line renders it (`--glass tinted`). A name `NAME@A` is NAME with
/// every surface at opacity A whatever `opacity` says, so one set can hold a scene with its
/// own materials and at one opacity side by side ([`scene_and_opacity`]).
pub fn load_scenes(names: &[String], opacity: Option<f32>) -> Result<Vec<scene::Scene>> {
    names
        .iter()
        .map(|name| {
            let (name, opacity) = scene_and_opacity(name, opacity)?;
            let mut s = scene::load(name, opacity_of(opacity))?;
            s.glass = scene::Glass::Tinted;
            Ok(s)
        })
        .collect()
}

/// The scene a set's `name` loads and its opacity: `NAME@A` (A a number) is NAME at opacity A,
/// which must be above 0 and at most 1; any other name is itself at the set's `opacity`.
pub fn scene_and_opacity(name: &str, opacity: Option<f32>) -> Result<(&str, Option<f32>)> {
    let Some((scene, a)) = name
        .rsplit_once('@')
        .and_then(|(n, a)| a.parse::<f32>().ok().map(|a| (n, a)))
    else {
        return Ok((name, opacity));
    };
    check_opacity(a, format!("scene {name}"))?;
    Ok((scene, Some(a)))
}

/// Refuses a uniform opacity that is not above 0 and at most 1, the message starting with
/// `what` (where it was given: `--opacity 1.5`, `scene s.glb@1.5`). Commands check it before
/// their work; the scene loader would refuse it only when it loads.
pub fn check_opacity(a: f32, what: impl std::fmt::Display) -> Result<()> {
    if a > 0.0 && a <= 1.0 {
        return Ok(());
    }
    Err(Error::Config(format!(
        "{what}: an opacity is above 0 and at most 1"
    )))
}

pub const MANIFEST: &str = "manifest.json";
pub const FORMAT: &str = "dhoit-dataset-3";
/// What produced a dataset: change it whenever the features, targets or fragments change, so a
/// cached default dataset is regenerated rather than reused stale.
pub const GENERATOR: &str =
    "features-v6 rgba8-fragments regret-v1 families-v3 useful-cap tail-pair tinted-glass";

/// Half-width D of the regret window: R is stored at `k* - D ..= k* + D`.
pub const REGRET_HALF: usize = 8;
/// Values of R stored per sample.
pub const REGRET_WINDOW: usize = 2 * REGRET_HALF + 1;

/// The smallest optimal error a frame's regrets are divided by: a mean squared error of 1e-14
/// per channel (far below 8-bit visibility, near float rounding), so frames the optimum renders
/// almost exactly do not blow up the loss.
pub fn error_floor(pixels: u64) -> f64 {
    3.0 * pixels as f64 * 1e-14
}

/// A budget level of the dataset: a share of the frame's fragments, average slots per pixel, or
/// every fragment.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Level {
    /// Parts per million of the frame's fragments.
    Share(u32),
    SlotsPerPixel(f64),
    All,
}

impl std::str::FromStr for Level {
    type Err = Error;
    fn from_str(s: &str) -> Result<Level> {
        Level::parse(s)
    }
}

impl Level {
    pub fn parse(s: &str) -> Result<Level> {
        if s.trim().eq_ignore_ascii_case("all") {
            return Ok(Level::All);
        }
        match Budget::parse(s)? {
            Budget::SlotsPerPixel(v) => Ok(Level::SlotsPerPixel(v)),
            Budget::Share(ppm) => Ok(Level::Share(ppm)),
            Budget::Bytes(_) => Err(Error::Config(format!(
                "dataset budget '{s}': give a share of the fragments (such as 25%), slots per pixel (such as 2fpp) or 'all', so every resolution sees the same levels"
            ))),
        }
    }
    pub fn label(&self) -> String {
        match self {
            Level::Share(ppm) => Budget::Share(*ppm).to_string(),
            Level::SlotsPerPixel(v) => format!("{v}fpp"),
            Level::All => "all".into(),
        }
    }
    /// F for a frame: a share of its fragments, `floor(fpp |P|)`, or the frame's fragment count.
    pub fn fragments(&self, pixels: u64, total: u64) -> u64 {
        match *self {
            Level::Share(ppm) => budget::share_of(total, ppm),
            Level::SlotsPerPixel(v) => (v * pixels as f64).floor() as u64,
            Level::All => total,
        }
    }
}

/// What to generate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DatasetConfig {
    pub scenes: Vec<String>,
    pub width: u32,
    pub height: u32,
    pub views: usize,
    pub levels: Vec<Level>,
    /// Share of the eligible pixels kept per frame and level (uniform sample).
    pub sample: f64,
    pub seed: u64,
    /// One uniform opacity for every surface, or `None`: each scene's own (the papers'
    /// families at 0.33, the material families and glTF files by their materials).
    pub opacity: Option<f32>,
}

/// Seeds of the built-in generators the default dataset uses: the first ones for training,
/// the last for validation. Seed 1 (the plain built-in names) is never used, so the built-in
/// scenes stay held out for evaluation.
pub const TRAIN_SEEDS: [u64; 2] = [2, 3];
pub const VALIDATION_SEED: u64 = 4;

/// The default dataset's scenes: every built-in generator at the training and validation seeds.
pub fn default_scenes() -> Vec<String> {
    let seeds = TRAIN_SEEDS.iter().chain([VALIDATION_SEED].iter());
    seeds
        .flat_map(|seed| {
            scene::procedural::BUILTIN
                .iter()
                .map(move |s| format!("{}:{seed}", s.0))
        })
        .collect()
}

/// The default validation scenes: every built-in generator at the validation seed.
pub fn default_validation() -> Vec<String> {
    scene::procedural::BUILTIN
        .iter()
        .map(|s| format!("{}:{VALIDATION_SEED}", s.0))
        .collect()
}

/// The default budget levels: shares of each frame's fragments from 3% to 95%, which covers
/// what 0.25 to 4 slots per pixel mean on deep and shallow scenes alike.
pub fn default_levels() -> Vec<Level> {
    [3, 5, 10, 20, 35, 50, 65, 80, 90, 95]
        .into_iter()
        .map(|pct| Level::Share(pct * 10_000))
        .collect()
}

impl Default for DatasetConfig {
    fn default() -> Self {
        DatasetConfig {
            scenes: default_scenes(),
            width: 320,
            height: 240,
            views: 4,
            levels: default_levels(),
            sample: 0.06,
            seed: 0,
            opacity: None,
        }
    }
}

/// One shard's entry in the manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Shard {
    pub file: String,
    pub scene: String,
    pub view: usize,
    pub budget: String,
    pub budget_fragments: u64,
    pub fragments: u64,
    pub covered_pixels: u64,
    /// Covered pixels whose k is not forced (the most slots they can use above the smallest k).
    #[serde(default)]
    pub eligible_pixels: u64,
    pub samples: usize,
    /// The optimal allocation's total error and critical gain.
    #[serde(default)]
    pub optimal_error: f64,
    #[serde(default)]
    pub critical_gain: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    #[serde(default)]
    pub generator: String,
    pub config: DatasetConfig,
    pub shards: Vec<Shard>,
    pub samples: usize,
    pub seconds: f64,
}

/// In-memory samples, with the scene each came from. `target` is always present; `count`,
/// `k_opt` and `regret` are present for datasets generated from scenes (empty otherwise).
#[derive(Clone, Debug, Default)]
pub struct Samples {
    pub features: Vec<[f32; FEATURES]>,
    /// The paper's target `k* / max_q k*(q)`.
    pub target: Vec<f32>,
    /// n(p).
    pub count: Vec<u32>,
    /// k*(p), the optimal allocation.
    pub k_opt: Vec<u32>,
    /// Whether the pixel's two farthest fragments share one colour (`importance::tail_pair`).
    pub pair: Vec<bool>,
    /// `R_p(k* + j) / max(E*, floor)` for j = -D..=D.
    pub regret: Vec<[f32; REGRET_WINDOW]>,
    /// Index into `scenes` of each sample.
    pub scene: Vec<u16>,
    pub scenes: Vec<String>,
    /// The frame (scene, view, budget) of each sample, an index into `frame_lo`.
    pub frame: Vec<u32>,
    /// Per frame: the smallest k a covered pixel gets (1, or 0 when F is below the covered
    /// pixels).
    pub frame_lo: Vec<u32>,
    /// The share of each frame's eligible pixels sampled (a frame's regrets sum to
    /// `share (E / E* - 1)`).
    pub share: f64,
}

impl Samples {
    pub fn len(&self) -> usize {
        self.target.len()
    }
    pub fn is_empty(&self) -> bool {
        self.target.is_empty()
    }
    /// Whether the cost of every k (count, k*, regret) is known for every sample.
    pub fn has_regret(&self) -> bool {
        self.regret.len() == self.len()
            && self.count.len() == self.len()
            && self.pair.len() == self.len()
            && self.frame.len() == self.len()
    }
    /// Sample indices grouped by frame, in frame order.
    pub fn frames(&self) -> Vec<Vec<usize>> {
        let mut out = vec![Vec::new(); self.frame_lo.len()];
        for (i, &f) in self.frame.iter().enumerate() {
            out[f as usize].push(i);
        }
        out.retain(|v| !v.is_empty());
        out
    }
    /// The samples at these indices.
    pub fn select(&self, idx: impl Iterator<Item = usize>) -> Samples {
        let mut out = Samples {
            scenes: self.scenes.clone(),
            frame_lo: self.frame_lo.clone(),
            share: self.share,
            ..Default::default()
        };
        let full = self.has_regret();
        for i in idx {
            out.features.push(self.features[i]);
            out.target.push(self.target[i]);
            out.scene.push(self.scene[i]);
            if full {
                out.count.push(self.count[i]);
                out.k_opt.push(self.k_opt[i]);
                out.pair.push(self.pair[i]);
                out.regret.push(self.regret[i]);
                out.frame.push(self.frame[i]);
            }
        }
        out
    }
    /// The samples whose scene satisfies `keep`.
    pub fn filter_scenes(&self, keep: impl Fn(&str) -> bool) -> Samples {
        self.select((0..self.len()).filter(|&i| keep(&self.scenes[self.scene[i] as usize])))
    }
}

/// One frame at one budget level: the samples of its eligible pixels.
#[derive(Clone, Debug, Default)]
pub struct FrameSamples {
    pub features: Vec<[f32; FEATURES]>,
    pub target: Vec<f32>,
    pub count: Vec<u32>,
    pub k_opt: Vec<u32>,
    pub regret: Vec<[f32; REGRET_WINDOW]>,
    /// Whether the pixel's two farthest fragments share one colour (`importance::tail_pair`).
    pub pair: Vec<bool>,
    /// Pixel index of each sample.
    pub pixel: Vec<usize>,
    /// F, and the covered pixels.
    pub budget_fragments: u64,
    pub covered: u64,
    pub optimal_error: f64,
    pub critical_gain: f64,
}

/// The regret window of one pixel (see the module docs), divided by `scale`. Above n the
/// error stays e(n) and only the price of the slots grows (`mu` each), so asking for more than
/// n still costs a little, as it does the other pixels.
pub fn regret_window(
    curve: &[f64],
    k_opt: u32,
    lo: u32,
    mu: f64,
    scale: f64,
) -> [f32; REGRET_WINDOW] {
    let n = curve.len() as i64 - 1;
    let lo = lo as i64;
    let ks = k_opt as i64;
    let r = |k: i64| curve[k.min(n) as usize] - curve[ks as usize] + mu * (k - ks) as f64;
    // Below lo, extend the first slope (k never goes there, but a gradient should lead back).
    let slope = if lo < n {
        (r(lo) - r(lo + 1)).max(0.0)
    } else {
        0.0
    };
    std::array::from_fn(|j| {
        let k = ks + j as i64 - REGRET_HALF as i64;
        let v = if k < lo {
            r(lo) + slope * (lo - k) as f64
        } else {
            r(k)
        };
        (v / scale) as f32
    })
}

/// The samples of one frame at one budget level: every covered pixel whose k is not forced.
pub fn frame_samples(
    fl: &dhoit_runtime::fragment::FragmentLists,
    curves: &alloc::ErrorCurves,
    level: Level,
) -> FrameSamples {
    let pixels = fl.pixel_count() as u64;
    let f = level.fragments(pixels, fl.fragment_count() as u64).max(1);
    let (k, report) = alloc::optimal(curves, f);
    let counts = fl.counts();
    let lo = alloc::min_k(&counts, f);
    let kmax = k.iter().copied().max().unwrap_or(1).max(1);
    let (feats, pairs) = importance::features_and_pairs(fl, f);
    let scale = report.total.max(error_floor(pixels));
    let mut out = FrameSamples {
        budget_fragments: f,
        covered: counts.iter().filter(|&&n| n > 0).count() as u64,
        optimal_error: report.total,
        critical_gain: report.critical_gain,
        ..Default::default()
    };
    for p in 0..fl.pixel_count() {
        // Forced: no choice between lo and the most the pixel can use.
        if alloc::useful_cap(counts[p], lo, pairs[p]) <= lo {
            continue;
        }
        out.features.push(feats[p]);
        out.pair.push(pairs[p]);
        out.target.push(k[p] as f32 / kmax as f32);
        out.count.push(counts[p]);
        out.k_opt.push(k[p]);
        out.regret.push(regret_window(
            curves.curve(p),
            k[p],
            lo,
            report.critical_gain,
            scale,
        ));
        out.pixel.push(p);
    }
    out
}

/// Generates a dataset into `out`. `progress` is called with (done, total) after each frame.
pub fn generate(
    config: &DatasetConfig,
    out: &Path,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Manifest> {
    if config.scenes.is_empty() || config.views == 0 || config.levels.is_empty() {
        return Err(Error::Config(
            "a dataset needs at least one scene, view and budget".into(),
        ));
    }
    if !(config.sample > 0.0 && config.sample <= 1.0) {
        return Err(Error::Config(format!(
            "sample share {} is not in (0, 1]",
            config.sample
        )));
    }
    raster::check_resolution((config.width, config.height))?;
    let start = Instant::now();
    // Every scene first: one that does not load leaves `out` (a dataset there included) as it
    // was.
    let scenes = load_scenes(&config.scenes, config.opacity)?;
    dhoit_runtime::tensors::create_folder(out)?;
    // A stale manifest must not describe shards about to be replaced.
    let manifest_path = out.join(MANIFEST);
    if manifest_path.exists() {
        std::fs::remove_file(&manifest_path)
            .map_err(|e| Error::io_op(IoOp::Remove, &manifest_path, e))?;
    }
    let jobs: Vec<(usize, usize)> = (0..scenes.len())
        .flat_map(|s| (0..config.views).map(move |v| (s, v)))
        .collect();
    let done = AtomicUsize::new(0);
    let shards: Vec<Vec<Shard>> = jobs
        .par_iter()
        .map(|&(si, view)| -> Result<Vec<Shard>> {
            let sc = &scenes[si];
            let cam = Camera::orbit(sc, view, config.views, (config.width, config.height));
            let fl = raster::rasterize(sc, &cam, (config.width, config.height))?;
            let curves = alloc::error_curves(&fl, [1.0; 3]);
            let mut shards = Vec::new();
            for (li, level) in config.levels.iter().enumerate() {
                let fs = frame_samples(&fl, &curves, *level);
                let mut rng = Rng::new(
                    config.seed ^ (si as u64) << 40 ^ (view as u64) << 20 ^ li as u64 ^ 0xD5E7,
                );
                let keep: Vec<usize> = (0..fs.target.len())
                    .filter(|_| (rng.f32() as f64) < config.sample)
                    .collect();
                let xs: Vec<f32> = keep.iter().flat_map(|&i| fs.features[i]).collect();
                let ys: Vec<f32> = keep.iter().map(|&i| fs.target[i]).collect();
                let ns: Vec<u32> = keep.iter().map(|&i| fs.count[i]).collect();
                let ks: Vec<u32> = keep.iter().map(|&i| fs.k_opt[i]).collect();
                let ps: Vec<u32> = keep.iter().map(|&i| u32::from(fs.pair[i])).collect();
                let rs: Vec<f32> = keep.iter().flat_map(|&i| fs.regret[i]).collect();
                let label = scene::file_label(&config.scenes[si]);
                let file = format!(
                    "{label}_v{view}_{}.safetensors",
                    level.label().replace('%', "pct")
                );
                let meta: HashMap<String, String> = [
                    ("format", FORMAT.to_string()),
                    ("scene", config.scenes[si].clone()),
                    ("view", view.to_string()),
                    ("width", config.width.to_string()),
                    ("height", config.height.to_string()),
                    ("budget", level.label()),
                    ("budget_fragments", fs.budget_fragments.to_string()),
                    ("optimal_error", fs.optimal_error.to_string()),
                    ("critical_gain", fs.critical_gain.to_string()),
                ]
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect();
                tensors::write(
                    &out.join(&file),
                    &[
                        Entry::f32("features", vec![keep.len(), FEATURES], &xs),
                        Entry::f32("target", vec![keep.len()], &ys),
                        Entry::u32("count", vec![keep.len()], &ns),
                        Entry::u32("k_opt", vec![keep.len()], &ks),
                        Entry::u32("tail_pair", vec![keep.len()], &ps),
                        Entry::f32("regret", vec![keep.len(), REGRET_WINDOW], &rs),
                    ],
                    meta,
                )?;
                shards.push(Shard {
                    file,
                    scene: config.scenes[si].clone(),
                    view,
                    budget: level.label(),
                    budget_fragments: fs.budget_fragments,
                    fragments: fl.fragment_count() as u64,
                    covered_pixels: fs.covered,
                    eligible_pixels: fs.target.len() as u64,
                    samples: keep.len(),
                    optimal_error: fs.optimal_error,
                    critical_gain: fs.critical_gain,
                });
            }
            progress(done.fetch_add(1, Ordering::SeqCst) + 1, jobs.len());
            Ok(shards)
        })
        .collect::<Result<_>>()?;
    let shards: Vec<Shard> = shards.into_iter().flatten().collect();
    let manifest = Manifest {
        format: FORMAT.into(),
        generator: GENERATOR.into(),
        config: config.clone(),
        samples: shards.iter().map(|s| s.samples).sum(),
        shards,
        seconds: start.elapsed().as_secs_f64(),
    };
    let text = serde_json::to_string_pretty(&manifest).expect("manifest serialises");
    tensors::write_atomic(&manifest_path, text.as_bytes())?;
    Ok(manifest)
}

/// Reads a whole dataset (every shard of its manifest).
pub fn load(dir: &Path) -> Result<(Manifest, Samples)> {
    let mpath = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&mpath).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            Error::Dataset(format!(
                "{} has no {MANIFEST}: not a dataset, or its generation did not finish",
                dir.display()
            ))
        } else {
            Error::read(&mpath, e)
        }
    })?;
    let manifest: Manifest = serde_json::from_str(&text)
        .map_err(|e| Error::Dataset(format!("{}: {e}", mpath.display())))?;
    if manifest.format != FORMAT {
        return Err(Error::Dataset(format!(
            "{}: format '{}' is not {FORMAT} (regenerate it with `dhoit dataset`)",
            mpath.display(),
            manifest.format
        )));
    }
    let mut samples = Samples {
        scenes: manifest.config.scenes.clone(),
        share: manifest.config.sample,
        ..Default::default()
    };
    for shard in &manifest.shards {
        let path: PathBuf = dir.join(&shard.file);
        let bytes = std::fs::read(&path).map_err(|e| Error::read(&path, e))?;
        let bad = |fault: FormatError| Error::Shard {
            path: path.clone(),
            fault,
        };
        let contract = |m: String| bad(FormatError::Contract(m));
        let file = tensors::File::parse(&bytes).map_err(bad)?;
        let n = shard.samples;
        let (_, x) = file.f32("features", Some(&[n, FEATURES])).map_err(bad)?;
        let (_, y) = file.f32("target", Some(&[n])).map_err(bad)?;
        let (_, counts) = file.u32("count", Some(&[n])).map_err(bad)?;
        let (_, k_opt) = file.u32("k_opt", Some(&[n])).map_err(bad)?;
        let (_, pair) = file.u32("tail_pair", Some(&[n])).map_err(bad)?;
        let (_, r) = file.f32("regret", Some(&[n, REGRET_WINDOW])).map_err(bad)?;
        if x.iter().chain(&y).chain(&r).any(|v| !v.is_finite()) {
            return Err(contract("non-finite values".into()));
        }
        if let Some(i) = (0..n).find(|&i| counts[i] == 0 || k_opt[i] > counts[i]) {
            return Err(contract(format!(
                "sample {i}: k_opt {} does not fit n {}",
                k_opt[i], counts[i]
            )));
        }
        let si = samples
            .scenes
            .iter()
            .position(|s| *s == shard.scene)
            .ok_or_else(|| {
                contract(format!(
                    "scene '{}' is not in the manifest's scene list",
                    shard.scene
                ))
            })?;
        samples.features.extend(
            x.chunks_exact(FEATURES)
                .map(|c| <[f32; FEATURES]>::try_from(c).expect("12")),
        );
        samples.target.extend(y);
        samples.count.extend(counts);
        samples.k_opt.extend(k_opt);
        samples.pair.extend(pair.iter().map(|&p| p != 0));
        samples.regret.extend(
            r.chunks_exact(REGRET_WINDOW)
                .map(|c| <[f32; REGRET_WINDOW]>::try_from(c).expect("window")),
        );
        samples.scene.extend(std::iter::repeat_n(si as u16, n));
        let frame = samples.frame_lo.len() as u32;
        samples.frame.extend(std::iter::repeat_n(frame, n));
        samples
            .frame_lo
            .push(u32::from(shard.budget_fragments >= shard.covered_pixels));
    }
    Ok((manifest, samples))
}

#[cfg(test)]
mod scene_name_tests {
    #[test]
    fn a_scene_name_may_carry_its_own_opacity() {
        use super::scene_and_opacity as of;
        assert_eq!(of("hair:3", None).unwrap(), ("hair:3", None));
        assert_eq!(of("hair:3", Some(0.5)).unwrap(), ("hair:3", Some(0.5)));
        assert_eq!(of("a/b.glb@0.33", None).unwrap(), ("a/b.glb", Some(0.33)));
        assert_eq!(
            of("a/b.glb@0.33", Some(0.9)).unwrap(),
            ("a/b.glb", Some(0.33))
        );
        // Not a number after '@': part of the name.
        assert_eq!(of("a@b/c.glb", None).unwrap(), ("a@b/c.glb", None));
        assert!(of("c.glb@1.5", None).is_err());
        assert!(of("c.glb@0", None).is_err());
    }
}
