//! Command-line front ends of the trainer, shared by `dhoit` and `dhoit-train`.

use crate::dataset::{self, DatasetConfig, Level};
use crate::model;
use crate::plot;
use crate::trainer::{self, TrainConfig};
use crate::{Error, Result};
use clap::Args;
use dhoit_runtime::importance::FEATURES;
use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::tensors::{self, Entry};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Where the default dataset is generated (ignored by git).
pub const DEFAULT_DATA: &str = "data/generated/dataset";
pub const DEFAULT_WEIGHTS: &str = "data/weights.safetensors";

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
    pub res: String,
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
    pub budgets: Vec<String>,
    /// Share of the covered pixels whose k is not forced that is sampled.
    #[arg(long, default_value_t = DatasetConfig::default().sample)]
    pub sample: f64,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

impl DatasetArgs {
    pub fn config(&self) -> Result<DatasetConfig> {
        let (width, height) = dhoit_runtime::raster::parse_resolution(&self.res)?;
        let mut c = DatasetConfig {
            width,
            height,
            views: self.views,
            levels: self
                .budgets
                .iter()
                .map(|b| Level::parse(b))
                .collect::<Result<_>>()?,
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

fn bar(len: u64, what: &str) -> ProgressBar {
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

fn generate(config: &DatasetConfig, out: &Path) -> Result<dataset::Manifest> {
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
    /// Weights file to write (config.json and the loss plot, loss.svg and loss.png, go beside it).
    #[arg(long, default_value = DEFAULT_WEIGHTS)]
    pub out: PathBuf,
    #[arg(long, default_value_t = TrainConfig::default().epochs)]
    pub epochs: usize,
    /// SGD learning rate.
    #[arg(long, default_value_t = TrainConfig::default().lr)]
    pub lr: f64,
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
    #[arg(long, default_value = TrainConfig::default().loss.name(), value_parser = parse_loss)]
    pub loss: trainer::Loss,
    /// Gradient norm clipping (0: none).
    #[arg(long, default_value_t = TrainConfig::default().clip)]
    pub clip: f64,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Scenes held out for validation, comma separated (default: the seed-4 built-ins).
    #[arg(long, value_delimiter = ',')]
    pub validation: Vec<String>,
}

fn parse_loss(s: &str) -> std::result::Result<trainer::Loss, String> {
    trainer::Loss::parse(s).ok_or_else(|| {
        let names: Vec<_> = trainer::Loss::ALL.iter().map(|l| l.name()).collect();
        format!("unknown loss '{s}': expected one of {}", names.join(", "))
    })
}

/// `dhoit train`.
pub fn train(a: TrainArgs) -> Result<()> {
    let [h1, h2] = a.hidden[..] else {
        return Err(Error::Config(format!(
            "--hidden takes two sizes, such as 128,64 (got {:?})",
            a.hidden
        )));
    };
    let config = TrainConfig {
        loss: a.loss,
        clip: a.clip,
        epochs: a.epochs,
        lr: a.lr,
        batch: a.batch,
        l1: a.l1,
        l2: a.l2,
        hidden: [h1, h2],
        momentum: a.momentum,
        cosine: !a.constant_lr,
        seed: a.seed,
        validation_scenes: if a.validation.is_empty() {
            dataset::default_validation()
        } else {
            a.validation.clone()
        },
    };
    let data_dir = match &a.data {
        Some(d) => d.clone(),
        None => {
            let d = PathBuf::from(DEFAULT_DATA);
            let default = DatasetConfig::default();
            let fresh = dataset::load(&d)
                .map(|(m, _)| m.config == default && m.generator == dataset::GENERATOR)
                .unwrap_or(false);
            if !fresh {
                generate(&default, &d)?;
            }
            d
        }
    };
    let (manifest, samples) = dataset::load(&data_dir)?;
    eprintln!(
        "train: {} samples from {} ({} scenes)",
        samples.len(),
        data_dir.display(),
        samples.scenes.len()
    );
    let pb = bar(config.epochs as u64, "epochs");
    let trained = trainer::train(&config, &samples, &mut |e, _| {
        pb.suspend(|| {
            eprintln!(
                "epoch {:>3}: train loss {:.4e} (+ reg {:.2e}), validation loss {:.4e}, {:.1} s",
                e.epoch, e.train_loss, e.train_reg, e.validation_loss, e.seconds
            )
        });
        pb.inc(1);
    })?;
    pb.finish_and_clear();
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
    trained.mlp.save(&a.out, &meta)?;
    let dir = a
        .out
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
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
        a.out.display(),
        plots
            .iter()
            .filter_map(|p| p.file_name())
            .map(|n| format!(", {}", n.to_string_lossy()))
            .collect::<String>()
    );
    Ok(())
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
    /// Where inference runs: cpu (burn, NdArray backend), twin (the runtime's plain-Rust
    /// network) or gpu (the WGSL network the renderer's importance pass runs; `dhoit` only).
    #[arg(long, default_value = "cpu")]
    pub device: String,
}

/// Reads a features file (`features` f32 [N,12], finite).
pub fn read_features(path: &Path) -> Result<Vec<[f32; FEATURES]>> {
    let bytes = std::fs::read(path).map_err(|e| Error::read(path, e))?;
    parse_features(&bytes, path)
}

/// Parses a features file's bytes (`path` names it in errors).
pub fn parse_features(bytes: &[u8], path: &Path) -> Result<Vec<[f32; FEATURES]>> {
    let bad = |message: String| Error::Features {
        path: path.to_path_buf(),
        message,
    };
    let file = tensors::File::parse(bytes).map_err(bad)?;
    let (shape, v) = file.f32("features", None).map_err(bad)?;
    if shape.len() != 2 || shape[1] != FEATURES {
        return Err(bad(format!(
            "tensor 'features' has shape {shape:?}, expected [N, {FEATURES}]"
        )));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(bad(format!(
            "non-finite feature at row {}, column {}",
            i / FEATURES,
            i % FEATURES
        )));
    }
    Ok(v.chunks_exact(FEATURES)
        .map(|c| c.try_into().expect("12"))
        .collect())
}

/// `dhoit predict`.
pub fn predict(a: PredictArgs) -> Result<()> {
    predict_with(&a, &|mlp, rows| match a.device.as_str() {
        "cpu" => Ok(model::predict(mlp, rows)),
        "twin" => Ok(mlp.importance(rows, &vec![1; rows.len()])),
        other => Err(Error::Config(format!(
            "device '{other}' is not available here for predict: use cpu (burn) or twin (the \
             runtime's CPU twin); `dhoit predict` also offers gpu"
        ))),
    })
}

/// A way to run the network on rows of features (burn, the CPU twin, the GPU).
pub type Inference<'a> = dyn Fn(&Mlp, &[[f32; FEATURES]]) -> Result<Vec<f32>> + 'a;

/// `dhoit predict` with the inference given: reads the weights and the features, writes the
/// predictions (atomically).
pub fn predict_with(a: &PredictArgs, infer: &Inference) -> Result<()> {
    let mlp = Mlp::load(&a.weights)?;
    let rows = read_features(&a.input)?;
    let imp = infer(&mlp, &rows)?;
    let meta = HashMap::from([
        ("weights".to_string(), a.weights.display().to_string()),
        ("device".to_string(), a.device.clone()),
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
    pub res: String,
    /// Budgets, comma separated: shares of each frame's fragments (25%) or slots per pixel.
    #[arg(
        long = "budget",
        value_delimiter = ',',
        default_value = "10%,25%,50%,75%,90%,0.25fpp,0.5fpp,1fpp,2fpp,4fpp"
    )]
    pub budgets: Vec<String>,
    /// Uniform opacity of every surface.
    #[arg(long, default_value_t = 0.33)]
    pub opacity: f32,
    /// Also write every frame's totals as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `dhoit score`.
pub fn score(a: ScoreArgs) -> Result<()> {
    let (width, height) = dhoit_runtime::raster::parse_resolution(&a.res)?;
    let levels: Vec<Level> = a
        .budgets
        .iter()
        .map(|b| Level::parse(b))
        .collect::<Result<_>>()?;
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
