//! Training data: for each scene, view and budget, fragment lists -> the 12 features ->
//! the optimal allocation -> the per-image scale-free target `k_opt(p) / max_q k_opt(q)` for a
//! uniform sample of covered pixels. (Targets tried and measured worse on held-out scenes:
//! `k_opt / n`, `log2 k_opt`, `log2(k_opt / n)` and `k_opt / 64`; see the README.)
//!
//! On disk: one safetensors shard per (scene, view, budget) with `features` f32 [N,12] and
//! `target` f32 [N] (metadata: scene, view, width, height, budget, budget_fragments), and a
//! `manifest.json` written last, so a dataset without a manifest is incomplete and refused.

use crate::{Error, Result};
use dhoit_runtime::alloc;
use dhoit_runtime::budget::Budget;
use dhoit_runtime::importance::{self, FEATURES};
use dhoit_runtime::raster;
use dhoit_runtime::rng::Rng;
use dhoit_runtime::scene::{self, Camera, Opacity};
use dhoit_runtime::tensors::{self, Entry};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

pub const MANIFEST: &str = "manifest.json";
pub const FORMAT: &str = "dhoit-dataset-1";
/// What produced a dataset: change it whenever the features, targets or fragments change, so a
/// cached default dataset is regenerated rather than reused stale.
pub const GENERATOR: &str = "features-v2 rgba8-fragments";

/// A budget level of the dataset: average slots per pixel, or every fragment.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Level {
    SlotsPerPixel(f64),
    All,
}

impl Level {
    pub fn parse(s: &str) -> Result<Level> {
        if s.trim().eq_ignore_ascii_case("all") {
            return Ok(Level::All);
        }
        match Budget::parse(s)? {
            Budget::SlotsPerPixel(v) => Ok(Level::SlotsPerPixel(v)),
            Budget::Bytes(_) => Err(Error::Config(format!(
                "dataset budget '{s}': give slots per pixel (such as 2fpp) or 'all', so every resolution sees the same levels"
            ))),
        }
    }
    pub fn label(&self) -> String {
        match self {
            Level::SlotsPerPixel(v) => format!("{v}fpp"),
            Level::All => "all".into(),
        }
    }
    /// F for a frame: `floor(fpp |P|)`, or the frame's fragment count.
    pub fn fragments(&self, pixels: u64, total: u64) -> u64 {
        match *self {
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
    /// Share of covered pixels kept (uniform sample).
    pub sample: f64,
    pub seed: u64,
    /// Uniform opacity of every surface.
    pub opacity: f32,
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

impl Default for DatasetConfig {
    fn default() -> Self {
        DatasetConfig {
            scenes: default_scenes(),
            width: 320,
            height: 240,
            views: 4,
            levels: vec![
                Level::SlotsPerPixel(1.0),
                Level::SlotsPerPixel(1.5),
                Level::SlotsPerPixel(2.0),
                Level::SlotsPerPixel(3.0),
                Level::All,
            ],
            sample: 0.2,
            seed: 0,
            opacity: 0.33,
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
    pub samples: usize,
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

/// In-memory samples, with the scene each came from.
#[derive(Clone, Debug, Default)]
pub struct Samples {
    pub features: Vec<[f32; FEATURES]>,
    pub target: Vec<f32>,
    /// Index into `scenes` of each sample.
    pub scene: Vec<u16>,
    pub scenes: Vec<String>,
}

impl Samples {
    pub fn len(&self) -> usize {
        self.target.len()
    }
    pub fn is_empty(&self) -> bool {
        self.target.is_empty()
    }
    /// The samples whose scene satisfies `keep`.
    pub fn filter_scenes(&self, keep: impl Fn(&str) -> bool) -> Samples {
        let mut out = Samples {
            scenes: self.scenes.clone(),
            ..Default::default()
        };
        for i in 0..self.len() {
            if keep(&self.scenes[self.scene[i] as usize]) {
                out.features.push(self.features[i]);
                out.target.push(self.target[i]);
                out.scene.push(self.scene[i]);
            }
        }
        out
    }
}

/// Features and scale-free optimal targets of the covered pixels of one frame at one budget
/// level: (features, targets, pixel indices, F).
pub fn frame_samples(
    fl: &raster::FragmentLists,
    curves: &alloc::ErrorCurves,
    level: Level,
) -> (Vec<[f32; FEATURES]>, Vec<f32>, Vec<usize>, u64) {
    let pixels = fl.pixel_count() as u64;
    let f = level.fragments(pixels, fl.fragment_count() as u64).max(1);
    let (k, _) = alloc::optimal(curves, f);
    let kmax = k.iter().copied().max().unwrap_or(1).max(1);
    let feats = importance::features(fl, f);
    let covered: Vec<usize> = (0..fl.pixel_count()).filter(|&p| fl.count(p) > 0).collect();
    let x = covered.iter().map(|&p| feats[p]).collect();
    let y = covered.iter().map(|&p| k[p] as f32 / kmax as f32).collect();
    (x, y, covered, f)
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
    raster::check_resolution(config.width, config.height)?;
    let start = Instant::now();
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    // A stale manifest must not describe shards about to be replaced.
    let manifest_path = out.join(MANIFEST);
    if manifest_path.exists() {
        std::fs::remove_file(&manifest_path).map_err(|e| Error::io(&manifest_path, e))?;
    }
    let scenes: Vec<scene::Scene> = config
        .scenes
        .iter()
        .map(|s| scene::load(s, Opacity::Uniform(config.opacity)))
        .collect::<std::result::Result<_, _>>()?;
    let jobs: Vec<(usize, usize)> = (0..scenes.len())
        .flat_map(|s| (0..config.views).map(move |v| (s, v)))
        .collect();
    let done = AtomicUsize::new(0);
    let shards: Vec<Vec<Shard>> = jobs
        .par_iter()
        .map(|&(si, view)| -> Result<Vec<Shard>> {
            let sc = &scenes[si];
            let cam = Camera::orbit(sc, view, config.views, config.width, config.height);
            let fl = raster::rasterize(sc, &cam, config.width, config.height)?;
            let curves = alloc::error_curves(&fl, [1.0; 3]);
            let mut shards = Vec::new();
            for (li, level) in config.levels.iter().enumerate() {
                let (x, y, _, f) = frame_samples(&fl, &curves, *level);
                let mut rng = Rng::new(
                    config.seed ^ (si as u64) << 40 ^ (view as u64) << 20 ^ li as u64 ^ 0xD5E7,
                );
                let keep: Vec<usize> = (0..x.len())
                    .filter(|_| (rng.f32() as f64) < config.sample)
                    .collect();
                let xs: Vec<f32> = keep.iter().flat_map(|&i| x[i]).collect();
                let ys: Vec<f32> = keep.iter().map(|&i| y[i]).collect();
                let label = scene::file_label(&config.scenes[si]);
                let file = format!("{label}_v{view}_{}.safetensors", level.label());
                let meta: HashMap<String, String> = [
                    ("format", FORMAT.to_string()),
                    ("scene", config.scenes[si].clone()),
                    ("view", view.to_string()),
                    ("width", config.width.to_string()),
                    ("height", config.height.to_string()),
                    ("budget", level.label()),
                    ("budget_fragments", f.to_string()),
                ]
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect();
                tensors::write(
                    &out.join(&file),
                    &[
                        Entry::f32("features", vec![keep.len(), FEATURES], &xs),
                        Entry::f32("target", vec![keep.len()], &ys),
                    ],
                    meta,
                )?;
                shards.push(Shard {
                    file,
                    scene: config.scenes[si].clone(),
                    view,
                    budget: level.label(),
                    budget_fragments: f,
                    fragments: fl.fragment_count() as u64,
                    covered_pixels: x.len() as u64,
                    samples: keep.len(),
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
            Error::io(&mpath, e)
        }
    })?;
    let manifest: Manifest = serde_json::from_str(&text)
        .map_err(|e| Error::Dataset(format!("{}: {e}", mpath.display())))?;
    if manifest.format != FORMAT {
        return Err(Error::Dataset(format!(
            "{}: format '{}' is not {FORMAT}",
            mpath.display(),
            manifest.format
        )));
    }
    let mut samples = Samples {
        scenes: manifest.config.scenes.clone(),
        ..Default::default()
    };
    for shard in &manifest.shards {
        let path: PathBuf = dir.join(&shard.file);
        let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
        let bad = |m: String| Error::Dataset(format!("{}: {m}", path.display()));
        let file = tensors::File::parse(&bytes).map_err(bad)?;
        let (_, x) = file
            .f32("features", Some(&[shard.samples, FEATURES]))
            .map_err(bad)?;
        let (_, y) = file.f32("target", Some(&[shard.samples])).map_err(bad)?;
        if x.iter().chain(&y).any(|v| !v.is_finite()) {
            return Err(bad("non-finite values".into()));
        }
        let si = samples
            .scenes
            .iter()
            .position(|s| *s == shard.scene)
            .ok_or_else(|| {
                bad(format!(
                    "scene '{}' is not in the manifest's scene list",
                    shard.scene
                ))
            })?;
        samples.features.extend(
            x.chunks_exact(FEATURES)
                .map(|c| <[f32; FEATURES]>::try_from(c).expect("12")),
        );
        samples.target.extend(y);
        samples
            .scene
            .extend(std::iter::repeat_n(si as u16, shard.samples));
    }
    Ok((manifest, samples))
}
