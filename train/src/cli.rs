//! Command-line front ends of the trainer, shared by `dhoit` and `dhoit-train`.

use crate::dataset::{self, DatasetConfig, Level};
use crate::model;
use crate::plot;
use crate::trainer::{self, TrainConfig};
use crate::{Error, Result};
use clap::Args;
use dhoit_runtime::importance::FEATURES;
use dhoit_runtime::mlp::{Mlp, Precision};
use dhoit_runtime::raster::Resolution;
use dhoit_runtime::tensors::{self, Entry, FormatError};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Where the default dataset is generated (ignored by git).
pub const DEFAULT_DATA: &str = "data/generated/dataset";
pub const DEFAULT_WEIGHTS: &str = "data/weights.safetensors";
/// The budgets `score` and `generalise` score at by default: the eval's ten.
pub const SCORE_BUDGETS: &str = "10%,25%,50%,75%,90%,0.25fpp,0.5fpp,1fpp,2fpp,4fpp";

#[derive(Args, Clone, Debug)]
pub struct DatasetArgs {
    /// Output directory (shards + manifest.json).
    #[arg(long, default_value = DEFAULT_DATA)]
    pub out: PathBuf,
    /// Scenes, comma separated: built-in names (with a seed: `particles:7`) or .gltf/.glb
    /// paths. Default: every built-in generator at seeds 2, 3 (training) and 4 (validation).
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Resolution WIDTHxHEIGHT.
    #[arg(long, default_value = "320x240")]
    pub res: Resolution,
    /// Orbit views per scene.
    #[arg(long, default_value_t = 4)]
    pub views: usize,
    /// Budget levels, comma separated: shares of each frame's fragments (25%), slots per pixel
    /// (2fpp) or `all` (every fragment).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "3%,5%,10%,20%,35%,50%,65%,80%,90%,95%"
    )]
    pub budgets: Vec<Level>,
    /// Share of the covered pixels whose k is not forced that is sampled.
    #[arg(long, default_value_t = DatasetConfig::default().sample)]
    pub sample: f64,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

impl DatasetArgs {
    pub fn config(&self) -> Result<DatasetConfig> {
        let Resolution { width, height } = self.res;
        let mut c = DatasetConfig {
            width,
            height,
            views: self.views,
            levels: self.budgets.clone(),
            sample: self.sample,
            seed: self.seed,
            ..DatasetConfig::default()
        };
        if !self.scenes.is_empty() {
            c.scenes = self.scenes.clone();
        }
        Ok(c)
    }
}

/// The progress bar of every long run (dataset, epochs, scoring, trade).
pub fn bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(
            "{msg:>10} [{bar:30}] {pos}/{len} {elapsed_precise} eta {eta}",
        )
        .expect("template")
        .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// `dhoit dataset`.
pub fn dataset(a: DatasetArgs) -> Result<()> {
    let config = a.config()?;
    generate(&config, &a.out)?;
    Ok(())
}

pub(crate) fn generate(config: &DatasetConfig, out: &Path) -> Result<dataset::Manifest> {
    let frames = config.scenes.len() * config.views;
    eprintln!(
        "dataset: {} scenes x {} views x {} budgets at {}x{} -> {}",
        config.scenes.len(),
        config.views,
        config.levels.len(),
        config.width,
        config.height,
        out.display()
    );
    let pb = bar(frames as u64, "frames");
    let m = dataset::generate(config, out, &|done, _| pb.set_position(done as u64))?;
    pb.finish_and_clear();
    eprintln!(
        "dataset: {} samples in {} shards, {:.1} s -> {}",
        m.samples,
        m.shards.len(),
        m.seconds,
        out.display()
    );
    Ok(m)
}

#[derive(Args, Clone, Debug)]
pub struct TrainArgs {
    /// Dataset directory; the default dataset is generated there when missing.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Train on your own scenes instead of the built-in set: .gltf/.glb files or built-in names,
    /// comma separated. A dataset of their orbit views (angles i/8 of a turn) is generated
    /// beside --out; the network starts from --init (by default the default weights, when
    /// their sizes are --hidden: fine-tuning) and is scored against that start on held-out
    /// views (1, 5, 7 and 11 twelfths of a turn, which no training view sees).
    #[arg(long = "scene", value_delimiter = ',', conflicts_with = "data")]
    pub scenes: Vec<String>,
    /// Start from these weights (fine-tuning) instead of random ones.
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// With --scene: train from random weights instead of fine-tuning the default ones.
    #[arg(long, conflicts_with = "init", requires = "scenes")]
    pub scratch: bool,
    /// With --scene: resolution of the views trained on and scored.
    #[arg(long, default_value = "320x240", requires = "scenes")]
    pub res: Resolution,
    /// With --scene: one uniform opacity for every surface (the papers' protocol, as `score`
    /// and `compare` take it), for a scene whose own materials are opaque or to train as the
    /// eval measures. Default: each scene's own materials.
    #[arg(long, requires = "scenes")]
    pub opacity: Option<f32>,
    /// Weights file to write; config.json and the loss plot (loss.svg, loss.png) go beside it.
    /// Default: data/weights.safetensors, or out/finetune/SCENE/weights.safetensors with
    /// --scene.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Training epochs (default: 40, or 20 with --scene).
    #[arg(long)]
    pub epochs: Option<usize>,
    /// SGD learning rate (default: 3e-3, or 3e-4 with --scene).
    #[arg(long)]
    pub lr: Option<f64>,
    #[arg(long, default_value_t = TrainConfig::default().batch)]
    pub batch: usize,
    /// L1 coefficient on the first hidden layer's weights.
    #[arg(long, default_value_t = TrainConfig::default().l1)]
    pub l1: f64,
    /// L2 coefficient on the second hidden layer's weights.
    #[arg(long, default_value_t = TrainConfig::default().l2)]
    pub l2: f64,
    /// Hidden layer sizes, H1,H2.
    #[arg(long, value_delimiter = ',', default_value = "128,64")]
    pub hidden: Vec<usize>,
    /// SGD momentum (0 = plain SGD, as in the paper).
    #[arg(long, default_value_t = TrainConfig::default().momentum)]
    pub momentum: f64,
    /// Keep the learning rate constant instead of the cosine decay to lr / 20.
    #[arg(long)]
    pub constant_lr: bool,
    /// What the network learns. regret-level: what the k it asks for costs in the image above
    /// the optimal allocation, the output a slot request fitted to the budget by one level per
    /// frame (the default); regret: the same with the output a share of the pixel's fragments
    /// fitted by a scale; mse-share: MSE on k*/n; mse-relative: the paper's MSE on k*/max k*
    /// (output = proportional importance).
    #[arg(long, default_value = TrainConfig::default().loss.name())]
    pub loss: trainer::Loss,
    /// Gradient norm clipping (0: none).
    #[arg(long, default_value_t = TrainConfig::default().clip)]
    pub clip: f64,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Scenes held out for validation, comma separated (default: the seed-4 built-ins).
    #[arg(long, value_delimiter = ',')]
    pub validation: Vec<String>,
    /// The precision the weights deploy at, recorded in the file: f16 (weights and biases
    /// rounded to binary16, arithmetic in f32: half the bytes in DKB's memory, and at equal F
    /// the default network's MSE within 0.02% of f32's on the eval's frames), f32, or f16-math.
    /// Training itself runs in f32.
    #[arg(long, default_value = "f16")]
    pub precision: Precision,
}

/// Orbit views a scene is trained on with `train --scene` (angles i/8 of a turn)...
pub const OWN_TRAIN_VIEWS: usize = 8;
/// ...and those it is scored on: views 1, 5, 7 and 11 of 12, angles no training view has.
pub const OWN_HELD_OUT: (usize, [usize; 4]) = (12, [1, 5, 7, 11]);
/// Learning rate with `train --scene` (a tenth of the default: fine-tuning).
pub const OWN_LR: f64 = 3e-4;
/// Epochs with `train --scene`.
pub const OWN_EPOCHS: usize = 20;

/// Where `train` writes its weights: --out, else with --scene out/finetune/SCENES/, else the
/// default weights.
fn out_path(a: &TrainArgs, own: bool) -> PathBuf {
    match &a.out {
        Some(p) => p.clone(),
        None if own => Path::new("out/finetune")
            .join(
                a.scenes
                    .iter()
                    .map(|s| dhoit_runtime::scene::file_label(s))
                    .collect::<Vec<_>>()
                    .join("+"),
            )
            .join("weights.safetensors"),
        None => PathBuf::from(DEFAULT_WEIGHTS),
    }
}

/// The network to start from: --init, or with --scene (`own`) the default weights when they
/// have the sizes asked for; none: random weights.
fn initial_network(
    a: &TrainArgs,
    own: bool,
    [h1, h2]: [usize; 2],
) -> Result<Option<(PathBuf, Mlp)>> {
    let default_weights = Path::new(DEFAULT_WEIGHTS);
    Ok(match &a.init {
        Some(p) => Some((p.clone(), Mlp::load(p)?)),
        None if own && !a.scratch && default_weights.is_file() => {
            let m = Mlp::load(default_weights)?;
            if [m.h1, m.h2] == [h1, h2] {
                Some((default_weights.to_path_buf(), m))
            } else {
                eprintln!(
                    "train: the default weights are {}-{}, not {h1}-{h2}: training from random weights",
                    m.h1, m.h2
                );
                None
            }
        }
        None => None,
    })
}

/// The dataset `train` reads: --data; with --scene one generated from the scenes into `dir`;
/// else the default one, generated where it is missing or stale.
fn data_dir(a: &TrainArgs, own: Option<&DatasetConfig>, dir: &Path) -> Result<PathBuf> {
    Ok(match (&a.data, own) {
        (Some(d), _) => d.clone(),
        (None, Some(c)) => {
            let d = dir.join("dataset");
            generate(c, &d)?;
            d
        }
        (None, None) => default_dataset()?,
    })
}

/// The default dataset's folder ([`DEFAULT_DATA`]), generated first where it is missing or
/// was made by another configuration or generator.
pub fn default_dataset() -> Result<PathBuf> {
    let d = PathBuf::from(DEFAULT_DATA);
    let default = DatasetConfig::default();
    let fresh = dataset::load(&d)
        .map(|(m, _)| m.config == default && m.generator == dataset::GENERATOR)
        .unwrap_or(false);
    if !fresh {
        generate(&default, &d)?;
    }
    Ok(d)
}

/// The trained network as it deploys (at `precision`) saved to `out`, beside it config.json
/// (the training's configuration, its dataset, history and float fingerprint) and the loss
/// curve; says where. Returns the network saved.
fn write_trained(
    config: &TrainConfig,
    (data_dir, manifest): (&Path, &dataset::Manifest),
    trained: &trainer::Trained,
    precision: Precision,
    out: &Path,
) -> Result<Mlp> {
    let dir = folder_of(out);
    let best = &trained.history[trained.best_epoch];
    let summary = serde_json::json!({
        "train": config,
        "dataset": {"dir": data_dir, "config": manifest.config, "samples": manifest.samples},
        "best_epoch": trained.best_epoch,
        "best": best,
        "history": trained.history,
        "train_samples": trained.train_samples,
        "validation_samples": trained.validation_samples,
        "seconds": trained.seconds,
        "samples_per_second": trained.samples_per_second,
        "float_fingerprint": crate::trainer::float_fingerprint(),
    });
    let meta: HashMap<String, String> = [
        (
            "train_config".to_string(),
            serde_json::to_string(&config).expect("config"),
        ),
        ("best_epoch".to_string(), trained.best_epoch.to_string()),
        (
            "validation_loss".to_string(),
            best.validation_loss.to_string(),
        ),
    ]
    .into_iter()
    .collect();
    // The network as it deploys (its weights rounded where the precision says so).
    let mlp = trained.mlp.at_precision(precision)?;
    mlp.save(out, &meta)?;
    tensors::write_atomic(
        &dir.join("config.json"),
        serde_json::to_string_pretty(&summary)
            .expect("json")
            .as_bytes(),
    )?;
    let plots = plot::loss_curve(&dir.join("loss"), &trained.history, trained.best_epoch);
    eprintln!(
        "train: best epoch {} (validation loss {:.4e}, train loss {:.4e}); {:.1} s, {:.0} samples/s -> {} (+ config.json{})",
        trained.best_epoch,
        best.validation_loss,
        best.train_loss,
        trained.seconds,
        trained.samples_per_second,
        out.display(),
        plots
            .iter()
            .filter_map(|p| p.file_name())
            .map(|n| format!(", {}", n.to_string_lossy()))
            .collect::<String>()
    );
    Ok(mlp)
}

/// `dhoit train`.
pub fn train(a: TrainArgs) -> Result<()> {
    let [h1, h2] = hidden_sizes(&a.hidden)?;
    let own = !a.scenes.is_empty();
    let out = out_path(&a, own);
    let default_weights = Path::new(DEFAULT_WEIGHTS);
    let init = initial_network(&a, own, [h1, h2])?;
    let config = train_config(&a, own, [h1, h2]);
    // Before any dataset is generated or loaded.
    config.check()?;
    let dir = folder_of(&out).to_path_buf();
    // The weights' folder before the data: a training run must not end unable to write them.
    tensors::create_folder(&dir)?;
    let own_config = own.then(|| own_dataset(&a.scenes, a.res, a.opacity, a.seed));
    if let Some(c) = &own_config {
        // Before any dataset is generated: a scene with nothing transparent gives no sample.
        check_transparent(&c.scenes, c.opacity)?;
    }
    let data_dir = data_dir(&a, own_config.as_ref(), &dir)?;
    let (manifest, samples) = dataset::load(&data_dir)?;
    eprintln!(
        "train: {} samples from {} ({} scenes)",
        samples.len(),
        data_dir.display(),
        samples.scenes.len()
    );
    let pb = bar(config.epochs as u64, "epochs");
    if let Some((p, _)) = &init {
        eprintln!("train: fine-tuning {}", p.display());
    }
    let prepared = own_config.as_ref().map(own_selection).transpose()?;
    let select =
        |m: &Mlp| -> Result<f64> { Ok(own_select(prepared.as_ref().expect("own scenes"), m)) };
    if own {
        eprintln!(
            "train: the best epoch is chosen by ln(error / optimal) on the training views (the validation loss below)"
        );
    }
    let select: Option<&trainer::Select> = if own { Some(&select) } else { None };
    let trained = trainer::train_from(
        &config,
        &samples,
        init.as_ref().map(|i| &i.1),
        select,
        &mut |e, _| {
            pb.suspend(|| {
            eprintln!(
                "epoch {:>3}: train loss {:.4e} (+ reg {:.2e}), validation loss {:.4e}, {:.1} s",
                e.epoch, e.train_loss, e.train_reg, e.validation_loss, e.seconds
            )
        });
            pb.inc(1);
        },
    )?;
    pb.finish_and_clear();
    let mlp = write_trained(&config, (&data_dir, &manifest), &trained, a.precision, &out)?;
    if let Some(c) = &own_config {
        let start = match &init {
            Some((p, m)) => Some((p.clone(), m.clone())),
            None if default_weights.is_file() => {
                Some((default_weights.to_path_buf(), Mlp::load(default_weights)?))
            }
            None => None,
        };
        held_out(c, start, &mlp, &out, &dir)?;
    }
    Ok(())
}

/// The two hidden layers' sizes of `--hidden`.
pub(crate) fn hidden_sizes(hidden: &[usize]) -> Result<[usize; 2]> {
    match hidden {
        &[h1, h2] => Ok([h1, h2]),
        _ => Err(Error::Config(format!(
            "--hidden takes two sizes, such as 128,64 (got {hidden:?})"
        ))),
    }
}

/// The folder an output file goes in (`.` for a bare file name).
pub(crate) fn folder_of(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// The dataset `train --scene` fine-tunes on: `scenes`' training views ([`OWN_TRAIN_VIEWS`]
/// at `res`), at `opacity` (None: their own materials).
pub fn own_dataset(
    scenes: &[String],
    res: Resolution,
    opacity: Option<f32>,
    seed: u64,
) -> DatasetConfig {
    DatasetConfig {
        scenes: scenes.to_vec(),
        width: res.width,
        height: res.height,
        views: OWN_TRAIN_VIEWS,
        seed,
        opacity,
        ..DatasetConfig::default()
    }
}

/// What fine-tuning judges an epoch by: the frames of every other training view of `c`
/// (half the cost), at [`HELD_OUT_BUDGETS`], prepared once ([`own_select`]); the held-out
/// views stay unseen.
pub fn own_selection(c: &DatasetConfig) -> Result<crate::score::Prepared> {
    let levels: Vec<Level> = HELD_OUT_BUDGETS
        .split(',')
        .map(Level::parse)
        .collect::<Result<_>>()?;
    let train_views: Vec<usize> = (0..OWN_TRAIN_VIEWS).step_by(2).collect();
    crate::score::Prepared::new(
        &crate::score::ScoreSpec {
            scenes: &c.scenes,
            views: &train_views,
            orbit_views: OWN_TRAIN_VIEWS,
            width: c.width,
            height: c.height,
            levels: &levels,
            opacity: c.opacity,
            networks: &[],
        },
        &|| {},
    )
}

/// An epoch's network judged as fine-tuning judges it: `ln` of its error over the optimal
/// allocation's on `prepared`'s frames (lower is better).
pub fn own_select(prepared: &crate::score::Prepared, m: &Mlp) -> f64 {
    let scores = prepared.score(std::slice::from_ref(m));
    crate::score::counted_geomean(&scores, |s| s.dkb_over_optimal(0)).ln()
}

/// The training's configuration from the command line: the defaults of a training from the
/// built-in scenes, or of fine-tuning on your own (`own`: a smaller learning rate, fewer
/// epochs, no validation scenes unless given).
/// Refuses, naming it, a scene of `scenes` (at `opacity`) with no transparent surface: its
/// frames have no fragment to allocate a slot to, so nothing to train on.
fn check_transparent(scenes: &[String], opacity: Option<f32>) -> Result<()> {
    if let Some(o) = opacity {
        dataset::check_opacity(o, format!("--opacity {o}"))?;
    }
    for (name, s) in scenes.iter().zip(dataset::load_scenes(scenes, opacity)?) {
        if !(0..s.triangle_count()).any(|t| s.transparent(t)) {
            return Err(Error::Config(format!(
                "scene {name} has no transparent surface with its own materials ({} \
                 triangles, all opaque): no fragment to allocate, nothing to train on; give \
                 every surface one opacity with --opacity (0.33, as the eval's protocol)",
                s.triangle_count()
            )));
        }
    }
    Ok(())
}

fn train_config(a: &TrainArgs, own: bool, [h1, h2]: [usize; 2]) -> TrainConfig {
    TrainConfig {
        loss: a.loss,
        clip: a.clip,
        epochs: a.epochs.unwrap_or(if own {
            OWN_EPOCHS
        } else {
            TrainConfig::default().epochs
        }),
        lr: a.lr.unwrap_or(if own {
            OWN_LR
        } else {
            TrainConfig::default().lr
        }),
        batch: a.batch,
        l1: a.l1,
        l2: a.l2,
        hidden: [h1, h2],
        momentum: a.momentum,
        cosine: !a.constant_lr,
        seed: a.seed,
        // Your own scenes are all trained on (the held-out views are scored after); the best
        // epoch is then chosen on the training loss.
        validation_scenes: if !a.validation.is_empty() {
            a.validation.clone()
        } else if own {
            Vec::new()
        } else {
            dataset::default_validation()
        },
    }
}

/// What `train --scene` reports: the start network and the trained one scored on views of the
/// same scenes that no training view saw.
#[derive(Clone, Debug, serde::Serialize)]
pub struct HeldOut {
    pub scenes: Vec<String>,
    pub orbit_views: usize,
    pub views: Vec<usize>,
    pub width: u32,
    pub height: u32,
    pub budgets: Vec<String>,
    /// The network compared against (the fine-tuning start, else the default weights).
    pub start: Option<String>,
    pub trained: String,
    /// Geometric means over the frames whose budget is below their fragments.
    pub start_over_optimal: Option<f64>,
    pub trained_over_optimal: f64,
    pub vkb_over_optimal: f64,
    /// start / trained: above 1 when training on the scene helped.
    pub gain: Option<f64>,
    pub frames: usize,
}

/// Budgets `train --scene` scores at.
pub const HELD_OUT_BUDGETS: &str = "10%,25%,50%,75%,90%";

fn held_out(
    c: &DatasetConfig,
    start: Option<(PathBuf, Mlp)>,
    trained: &Mlp,
    out: &Path,
    dir: &Path,
) -> Result<HeldOut> {
    let (orbit_views, views) = OWN_HELD_OUT;
    let budgets: Vec<String> = HELD_OUT_BUDGETS.split(',').map(String::from).collect();
    let levels: Vec<Level> = budgets
        .iter()
        .map(|b| Level::parse(b))
        .collect::<Result<_>>()?;
    let mut networks = vec![trained.clone()];
    if let Some((_, m)) = &start {
        networks.push(m.clone());
    }
    let spec = crate::score::ScoreSpec {
        scenes: &c.scenes,
        views: &views,
        orbit_views,
        width: c.width,
        height: c.height,
        levels: &levels,
        opacity: c.opacity,
        networks: &networks,
    };
    let pb = bar((c.scenes.len() * views.len()) as u64, "held out");
    let scores = crate::score::score(&spec, &|| pb.inc(1))?;
    pb.finish_and_clear();
    let geo =
        |ratio: fn(&crate::score::FrameScore) -> f64| crate::score::counted_geomean(&scores, ratio);
    let trained_ratio = geo(|s| s.dkb_over_optimal(0));
    let start_ratio = start.as_ref().map(|_| geo(|s| s.dkb_over_optimal(1)));
    let report = HeldOut {
        scenes: c.scenes.clone(),
        orbit_views,
        views: views.to_vec(),
        width: c.width,
        height: c.height,
        budgets,
        start: start.as_ref().map(|(p, _)| p.display().to_string()),
        trained: out.display().to_string(),
        start_over_optimal: start_ratio,
        trained_over_optimal: trained_ratio,
        vkb_over_optimal: geo(|s| s.vkb_over_optimal()),
        gain: start_ratio.map(|r| r / trained_ratio),
        frames: scores.iter().filter(|s| s.counts()).count(),
    };
    tensors::write_atomic(
        &dir.join("held_out.json"),
        serde_json::to_string_pretty(&report)
            .expect("json")
            .as_bytes(),
    )?;
    eprintln!(
        "held-out views {:?} of {orbit_views} ({} frames): error / optimal {} -> {:.3} trained (VKB {:.3}){} -> {}",
        views,
        report.frames,
        match (&report.start, start_ratio) {
            (Some(p), Some(r)) => format!("{r:.3} with {p}"),
            _ => "no start network".into(),
        },
        trained_ratio,
        report.vkb_over_optimal,
        report
            .gain
            .map(|g| format!(", {g:.2}x better"))
            .unwrap_or_default(),
        dir.join("held_out.json").display()
    );
    Ok(report)
}

#[derive(Args, Clone, Debug)]
pub struct PredictArgs {
    /// Weights file (safetensors, the weights contract).
    #[arg(long)]
    pub weights: PathBuf,
    /// Features file: safetensors with `features` f32 [N,12].
    #[arg(long)]
    pub input: PathBuf,
    /// Output file: safetensors with `importance` f32 [N].
    #[arg(long)]
    pub output: PathBuf,
    /// Where inference runs.
    #[arg(long, value_enum, default_value_t = PredictDevice::Cpu)]
    pub device: PredictDevice,
    /// The network's precision: f32; f16 (weights and biases rounded to binary16, as the
    /// GPU's f16 pass holds them; arithmetic in f32 on every device); or f16-math (binary16
    /// hidden-layer arithmetic too: the twin and the GPU only, burn computes in f32).
    /// Default: the one the weights file records (f16 for the default weights; f32 where it
    /// records none).
    #[arg(long)]
    pub precision: Option<Precision>,
}

/// Where `predict` runs the network.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PredictDevice {
    /// burn, Flex CPU backend (what training runs).
    Cpu,
    /// The runtime's plain-Rust network (the renderer's CPU twin).
    Twin,
    /// The WGSL network the renderer's importance pass runs (`dhoit` only).
    Gpu,
}

impl std::fmt::Display for PredictDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PredictDevice::Cpu => "cpu",
            PredictDevice::Twin => "twin",
            PredictDevice::Gpu => "gpu",
        })
    }
}

/// Reads a features file (`features` f32 [N,12], finite).
pub fn read_features(path: &Path) -> Result<Vec<[f32; FEATURES]>> {
    let bytes = std::fs::read(path).map_err(|e| Error::read(path, e))?;
    parse_features(&bytes, path)
}

/// Parses a features file's bytes (`path` names it in errors).
pub fn parse_features(bytes: &[u8], path: &Path) -> Result<Vec<[f32; FEATURES]>> {
    let bad = |fault: FormatError| Error::Features {
        path: path.to_path_buf(),
        fault,
    };
    let file = tensors::File::parse(bytes).map_err(bad)?;
    let (shape, v) = file.f32("features", None).map_err(bad)?;
    if shape.len() != 2 || shape[1] != FEATURES {
        return Err(bad(FormatError::Shape {
            name: "features".into(),
            found: shape,
            expected: format!("[N, {FEATURES}]"),
        }));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(bad(FormatError::Contract(format!(
            "non-finite feature at row {}, column {}",
            i / FEATURES,
            i % FEATURES
        ))));
    }
    Ok(v.chunks_exact(FEATURES)
        .map(|c| c.try_into().expect("12"))
        .collect())
}

/// `dhoit predict`.
pub fn predict(a: PredictArgs) -> Result<()> {
    predict_with(&a, &|mlp, rows| match a.device {
        PredictDevice::Cpu => Ok(model::predict(mlp, rows)),
        PredictDevice::Twin => Ok(mlp.importance(rows, &vec![1; rows.len()])),
        PredictDevice::Gpu => Err(Error::Config(
            "device gpu is not available here for predict: use cpu (burn) or twin (the \
             runtime's CPU twin); `dhoit predict` also offers gpu"
                .into(),
        )),
    })
}

/// A way to run the network on rows of features (burn, the CPU twin, the GPU).
pub type Inference<'a> = dyn Fn(&Mlp, &[[f32; FEATURES]]) -> Result<Vec<f32>> + 'a;

/// `dhoit predict` with the inference given: reads the weights and the features, writes the
/// predictions (atomically).
pub fn predict_with(a: &PredictArgs, infer: &Inference) -> Result<()> {
    let loaded = Mlp::load(&a.weights)?;
    let precision = a.precision.unwrap_or(loaded.precision);
    if precision == Precision::F16Math && a.device == PredictDevice::Cpu {
        return Err(Error::Config(
            "precision f16-math computes in binary16, which burn (device cpu) does not: use \
             device twin or gpu, or precision f16 (binary16 weights, f32 arithmetic)"
                .into(),
        ));
    }
    let mlp = loaded.at_precision(precision)?;
    let rows = read_features(&a.input)?;
    let imp = infer(&mlp, &rows)?;
    let meta = HashMap::from([
        ("weights".to_string(), a.weights.display().to_string()),
        ("device".to_string(), a.device.to_string()),
        ("precision".to_string(), precision.to_string()),
    ]);
    tensors::write(
        &a.output,
        &[Entry::f32("importance", vec![imp.len()], &imp)],
        meta,
    )?;
    eprintln!(
        "predict ({}): {} rows -> {}",
        a.device,
        imp.len(),
        a.output.display()
    );
    Ok(())
}

#[derive(Args, Clone, Debug)]
pub struct ScoreArgs {
    /// Weights files to score, comma separated (default: data/weights.safetensors).
    #[arg(long, value_delimiter = ',')]
    pub weights: Vec<PathBuf>,
    /// Scenes, comma separated: built-in names (with a seed: `particles:7`) or .gltf/.glb
    /// paths. Default: every built-in generator at the validation seed (never evaluated on).
    #[arg(long = "scene", value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Orbit views to score, comma separated.
    #[arg(long = "view", value_delimiter = ',', default_value = "1,3")]
    pub views: Vec<usize>,
    /// Orbit views around each scene.
    #[arg(long, default_value_t = dhoit_runtime::scene::DEFAULT_VIEWS)]
    pub orbit_views: usize,
    /// Resolution WIDTHxHEIGHT.
    #[arg(long, default_value = "320x240")]
    pub res: Resolution,
    /// Budgets, comma separated: shares of each frame's fragments (25%) or slots per pixel.
    #[arg(
        long = "budget",
        value_delimiter = ',',
        default_value = SCORE_BUDGETS
    )]
    pub budgets: Vec<Level>,
    /// One uniform opacity for every surface (the papers' protocol). Default: each scene's
    /// own (materials for glTF files and the material families, 0.33 for the papers' ones).
    #[arg(long)]
    pub opacity: Option<f32>,
    /// Also write every frame's totals as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `dhoit score`.
pub fn score(a: ScoreArgs) -> Result<()> {
    let Resolution { width, height } = a.res;
    let levels: Vec<Level> = a.budgets.clone();
    let paths = if a.weights.is_empty() {
        vec![PathBuf::from(DEFAULT_WEIGHTS)]
    } else {
        a.weights.clone()
    };
    let networks: Vec<Mlp> = paths
        .iter()
        .map(|p| Mlp::load(p))
        .collect::<std::result::Result<_, _>>()?;
    let scenes = if a.scenes.is_empty() {
        dataset::default_validation()
    } else {
        a.scenes.clone()
    };
    let spec = crate::score::ScoreSpec {
        scenes: &scenes,
        views: &a.views,
        orbit_views: a.orbit_views,
        width,
        height,
        levels: &levels,
        opacity: a.opacity,
        networks: &networks,
    };
    let pb = bar((scenes.len() * a.views.len()) as u64, "frames");
    let scores = crate::score::score(&spec, &|| pb.inc(1))?;
    pb.finish_and_clear();
    let names: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    print!("{}", crate::score::summary(&scores, &names));
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&scores).expect("json");
        tensors::write_atomic(path, text.as_bytes())?;
    }
    Ok(())
}
