//! `dhoit generalise`: how DKB allocates on a kind of scene it has never seen, measured by the
//! project itself. Leave one family out: for each built-in generator family, a network is
//! trained on the dataset with every scene of that family removed (its training and its
//! validation seeds), and scored against the per-pixel optimal allocation on the family's
//! held-out scene (seed 1, which no dataset holds) beside a network trained the same way on
//! every family (in distribution), and beside the fold's network fine-tuned on that scene's
//! training views as `train --scene` does (what a user gains by fine-tuning on a scene of a
//! kind the network never saw). Every network is scored on the views fine-tuning holds out.
//! The figure to improve is the left-out one: the mean over the folds and the worst fold.
//! With `--seeds N` every network is trained at N seeds (0 to N-1) and each figure is the
//! geometric mean over them beside its range, so a change to the training set or the features
//! can be told from the spread of training alone.

use crate::cli::{OWN_EPOCHS, OWN_HELD_OUT, OWN_LR, SCORE_BUDGETS, bar, folder_of};
use crate::dataset::{self, DatasetConfig, Level, Samples};
use crate::score::{self, FrameScore, ScoreSpec, counted_geomean};
use crate::trainer::{self, TrainConfig};
use crate::{Error, Result};
use clap::Args;
use dhoit_runtime::mlp::{Mlp, Precision};
use dhoit_runtime::raster::Resolution;
use dhoit_runtime::scene::procedural::BUILTIN;
use dhoit_runtime::tensors;
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Args, Clone, Debug)]
pub struct GeneraliseArgs {
    /// Dataset to train the folds on (each fold drops its family's scenes from it). Default:
    /// the default dataset (data/generated/dataset, generated where missing or stale, as
    /// `dhoit train` does).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Families left out in turn, comma separated (default: every built-in generator the
    /// dataset holds).
    #[arg(long, value_delimiter = ',')]
    pub families: Vec<String>,
    /// Training seeds of each network (0 to N-1): every fold's network and the
    /// in-distribution one are trained at each, and each figure is the geometric mean over
    /// the seeds beside its range (the fine-tuned column fine-tunes seed 0's fold network).
    /// Each seed adds a training of every fold: about 40 s each at the defaults on 2 cores.
    #[arg(long, default_value_t = 1)]
    pub seeds: u64,
    /// Training epochs of each fold (and of the in-distribution network).
    #[arg(long, default_value_t = TrainConfig::default().epochs)]
    pub epochs: usize,
    /// Hidden layer sizes of the folds' networks, H1,H2.
    #[arg(long, value_delimiter = ',', default_value = "128,64")]
    pub hidden: Vec<usize>,
    /// Orbit views of each left-out scene scored, comma separated, of --orbit-views (by
    /// default those `train --scene` holds out: 1, 5, 7 and 11 of 12, angles no training or
    /// fine-tuning view has).
    #[arg(long = "view", value_delimiter = ',', default_value = "1,5,7,11")]
    pub views: Vec<usize>,
    /// Orbit views around each scored scene.
    #[arg(long, default_value_t = OWN_HELD_OUT.0)]
    pub orbit_views: usize,
    /// Leave out the fine-tuned column (each fold's network fine-tuned on its scene's own
    /// training views, as `train --scene` does).
    #[arg(long)]
    pub no_fine_tune: bool,
    /// Resolution the left-out scenes are scored at, WIDTHxHEIGHT.
    #[arg(long, default_value = "320x240")]
    pub res: Resolution,
    /// Budgets scored, comma separated: shares of each frame's fragments (25%) or slots per
    /// pixel.
    #[arg(
        long = "budget",
        value_delimiter = ',',
        default_value = SCORE_BUDGETS
    )]
    pub budgets: Vec<Level>,
    /// One uniform opacity for every surface of the scored scenes (the papers' protocol, as
    /// `score` takes it). Default: each scene's own, as the default dataset renders them.
    #[arg(long)]
    pub opacity: Option<f32>,
    /// The table (markdown) to write.
    #[arg(long, default_value = "docs/generalise.md")]
    pub out: PathBuf,
    /// Every fold's figures and every frame's score as JSON.
    #[arg(long, default_value = "out/generalise/generalise.json")]
    pub json: PathBuf,
}

/// One family left out.
#[derive(Clone, Debug, Serialize)]
pub struct Fold {
    pub family: String,
    /// The scenes the fold's network trained on (none of the family's) and validated on.
    pub train_scenes: Vec<String>,
    pub validation_scenes: Vec<String>,
    pub train_samples: usize,
    /// The scene scored: the family's seed-1 scene, in no dataset.
    pub scored: String,
    /// Counted frames (those that truncate).
    pub frames: usize,
    #[serde(flatten)]
    pub figures: Figures,
    pub seconds: f64,
    pub scores: Vec<FrameScore>,
}

/// A fold's figures, or every fold's together: geometric means over the counted frames (and
/// the seeds) of error / optimal error.
#[derive(Clone, Debug, Serialize)]
pub struct Figures {
    /// The fold's network (which never saw the family), and the network trained on every
    /// family.
    pub left_out_over_optimal: f64,
    pub in_distribution_over_optimal: f64,
    /// The left-out and in-distribution figures of each seed's networks, seed 0 first: their
    /// range is the spread training alone gives.
    pub left_out_by_seed: Vec<f64>,
    pub in_distribution_by_seed: Vec<f64>,
    /// The fold's network of seed 0 fine-tuned on the scene's training views (where it ran).
    pub fine_tuned_over_optimal: Option<f64>,
    pub vkb_over_optimal: f64,
}

impl Figures {
    /// The figures of frames scored for the networks a fold scores (the fold's at each of
    /// `seeds` seeds, the in-distribution ones, then the fine-tuned one where `fine_tuned`).
    fn of(scores: &[FrameScore], seeds: usize, fine_tuned: bool) -> Figures {
        let over = |nets: std::ops::Range<usize>| {
            score::geomean(
                scores
                    .iter()
                    .filter(|s| s.counts())
                    .flat_map(|s| nets.clone().map(move |i| s.dkb_over_optimal(i))),
            )
        };
        let each = |i: usize| counted_geomean(scores, |s| s.dkb_over_optimal(i));
        Figures {
            left_out_over_optimal: over(0..seeds),
            in_distribution_over_optimal: over(seeds..2 * seeds),
            left_out_by_seed: (0..seeds).map(each).collect(),
            in_distribution_by_seed: (seeds..2 * seeds).map(each).collect(),
            fine_tuned_over_optimal: fine_tuned.then(|| each(2 * seeds)),
            vkb_over_optimal: counted_geomean(scores, FrameScore::vkb_over_optimal),
        }
    }
}

/// What the run wrote.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub data: PathBuf,
    pub epochs: usize,
    pub hidden: [usize; 2],
    pub opacity: Option<f32>,
    pub seeds: u64,
    pub folds: Vec<Fold>,
    /// Over every fold's counted frames together (and the seeds).
    #[serde(flatten)]
    pub figures: Figures,
    /// The fold whose left-out figure is the highest.
    pub worst: String,
    pub worst_over_optimal: f64,
}

/// The family of a built-in scene name (`hair:3`: `hair`), or None for a file.
fn family_of(scene: &str) -> Option<&str> {
    let name = scene.split(':').next()?;
    BUILTIN.iter().any(|(b, _)| *b == name).then_some(name)
}

/// `dhoit generalise`.
pub fn run(a: GeneraliseArgs) -> Result<()> {
    let [h1, h2] = crate::cli::hidden_sizes(&a.hidden)?;
    if a.epochs == 0 {
        return Err(Error::Config("--epochs: at least 1".into()));
    }
    if a.seeds == 0 {
        return Err(Error::Config("--seeds: at least 1".into()));
    }
    if let Some(o) = a.opacity {
        dataset::check_opacity(o, format!("--opacity {o}"))?;
    }
    let data_dir = match &a.data {
        Some(d) => d.clone(),
        None => crate::cli::default_dataset()?,
    };
    let (manifest, samples) = dataset::load(&data_dir)?;
    let families = families_left_out(&a.families, &samples, &data_dir)?;
    // The report's folders before the long work: a run must not end unable to write.
    for p in [&a.out, &a.json] {
        tensors::create_folder(folder_of(p))?;
    }
    let config = TrainConfig {
        epochs: a.epochs,
        hidden: [h1, h2],
        validation_scenes: validation_in(&manifest.config, &samples, None),
        ..TrainConfig::default()
    };
    config.check()?;
    eprintln!(
        "generalise: {} families left out in turn, {} epochs each, {h1}-{h2}, {} seed(s), from {} ({} samples)",
        families.len(),
        a.epochs,
        a.seeds,
        data_dir.display(),
        samples.len()
    );
    let pb = bar((families.len() as u64 + 1) * a.seeds, "trainings");
    let all = train_seeds(&config, &samples, a.seeds, &pb)?;
    let mut folds = Vec::new();
    for f in &families {
        let start = std::time::Instant::now();
        let train = samples.filter_scenes(|s| family_of(s) != Some(f.as_str()));
        let fold_config = TrainConfig {
            validation_scenes: validation_in(&manifest.config, &train, Some(f)),
            ..config.clone()
        };
        // Scored together: the fold's network at each seed, then the in-distribution ones,
        // then seed 0's fine-tuned.
        let mut networks = train_seeds(&fold_config, &train, a.seeds, &pb)?;
        networks.extend(all.iter().cloned());
        let scored = format!("{f}:1");
        if !a.no_fine_tune {
            let dir = fold_dir(&a.json, f);
            let tuned = pb.suspend(|| fine_tune(&scored, &networks[0], &a, [h1, h2], &dir))?;
            networks.push(tuned);
        }
        let scores = score_fold(&a, &scored, &networks)?;
        let fold = fold_of(f, &a, (&train, &fold_config), scored, scores, start);
        pb.suspend(|| eprintln!("{}", fold.line()));
        folds.push(fold);
    }
    pb.finish_and_clear();
    let report = summarise(&data_dir, &a, [h1, h2], folds);
    let text = serde_json::to_string_pretty(&report).expect("json");
    tensors::write_atomic(&a.json, text.as_bytes())?;
    let md = markdown(&report, &command_line(&a));
    tensors::write_atomic(&a.out, md.as_bytes())?;
    print!("{md}");
    eprintln!("generalise: -> {}, {}", a.out.display(), a.json.display());
    Ok(())
}

/// A network trained on `samples` as `config` says at each seed 0..`seeds`.
fn train_seeds(
    config: &TrainConfig,
    samples: &Samples,
    seeds: u64,
    pb: &indicatif::ProgressBar,
) -> Result<Vec<Mlp>> {
    (0..seeds)
        .map(|seed| {
            let seeded = TrainConfig {
                seed,
                ..config.clone()
            };
            let net = pb.suspend(|| train_quietly(&seeded, samples));
            pb.inc(1);
            net
        })
        .collect()
}

impl Fold {
    /// The fold's figures in a line, as the run prints each fold.
    fn line(&self) -> String {
        format!(
            "fold {:<10} DKB/optimal left out {:.3}, in distribution {:.3}, fine-tuned {}, VKB {:.3} ({} frames, {:.0} s)",
            self.family,
            self.figures.left_out_over_optimal,
            self.figures.in_distribution_over_optimal,
            self.figures
                .fine_tuned_over_optimal
                .map_or("-".into(), |v| format!("{v:.3}")),
            self.figures.vkb_over_optimal,
            self.frames,
            self.seconds
        )
    }
}

/// The families to leave out in turn: those `asked` (each must have a scene in the dataset),
/// or every built-in generator the dataset holds.
fn families_left_out(asked: &[String], samples: &Samples, data_dir: &Path) -> Result<Vec<String>> {
    let present = scenes_in(samples);
    let held: Vec<&str> = present.iter().filter_map(|s| family_of(s)).collect();
    let families: Vec<String> = if asked.is_empty() {
        BUILTIN
            .iter()
            .map(|(b, _)| b.to_string())
            .filter(|f| held.contains(&f.as_str()))
            .collect()
    } else {
        asked.to_vec()
    };
    for f in &families {
        if !held.contains(&f.as_str()) {
            return Err(Error::Config(format!(
                "family '{f}' has no scene in the dataset {} (its families: {})",
                data_dir.display(),
                dedup(&held).join(", ")
            )));
        }
    }
    if families.is_empty() {
        return Err(Error::Config(format!(
            "the dataset {} holds no built-in family to leave out",
            data_dir.display()
        )));
    }
    Ok(families)
}

/// Every frame's score of `scene` (its held-out views, the budgets) for `networks`.
fn score_fold(a: &GeneraliseArgs, scene: &str, networks: &[Mlp]) -> Result<Vec<FrameScore>> {
    let scenes = [scene.to_string()];
    let spec = ScoreSpec {
        scenes: &scenes,
        views: &a.views,
        orbit_views: a.orbit_views,
        width: a.res.width,
        height: a.res.height,
        levels: &a.budgets,
        opacity: a.opacity,
        networks,
    };
    score::score(&spec, &|| {})
}

/// Fold `family`'s figures from its frames' scores (networks: the fold's at each seed, the
/// in-distribution ones, then the fine-tuned one where it ran).
fn fold_of(
    family: &str,
    a: &GeneraliseArgs,
    (train, config): (&Samples, &TrainConfig),
    scored: String,
    scores: Vec<FrameScore>,
    start: std::time::Instant,
) -> Fold {
    Fold {
        family: family.to_string(),
        train_scenes: scenes_in(train),
        validation_scenes: config.validation_scenes.clone(),
        train_samples: train.len(),
        scored,
        frames: scores.iter().filter(|s| s.counts()).count(),
        figures: Figures::of(&scores, a.seeds as usize, !a.no_fine_tune),
        seconds: start.elapsed().as_secs_f64(),
        scores,
    }
}

/// The scenes `samples` has rows of (its table of names may hold more: a selection keeps it).
fn scenes_in(samples: &Samples) -> Vec<String> {
    let mut used = vec![false; samples.scenes.len()];
    for &i in &samples.scene {
        used[i as usize] = true;
    }
    samples
        .scenes
        .iter()
        .zip(used)
        .filter(|&(_, u)| u)
        .map(|(s, _)| s.clone())
        .collect()
}

fn dedup(v: &[&str]) -> Vec<String> {
    let mut out: Vec<String> = v.iter().map(|s| s.to_string()).collect();
    out.sort();
    out.dedup();
    out
}

/// The validation scenes of a dataset generated by `config` that `samples` still holds, less
/// those of family `out`: the default's (every family at the validation seed) where the
/// dataset is the default one, else none (the best epoch by the training loss).
fn validation_in(config: &DatasetConfig, samples: &Samples, out: Option<&str>) -> Vec<String> {
    let present = scenes_in(samples);
    let wanted = match config.scenes == dataset::default_scenes() {
        true => dataset::default_validation(),
        false => config
            .scenes
            .iter()
            .filter(|s| s.ends_with(&format!(":{}", dataset::VALIDATION_SEED)))
            .cloned()
            .collect(),
    };
    wanted
        .into_iter()
        .filter(|s| present.contains(s))
        .filter(|s| out.is_none_or(|f| family_of(s) != Some(f)))
        .collect()
}

/// A network trained on `samples` (no output but errors), at the precision `train` deploys.
fn train_quietly(config: &TrainConfig, samples: &Samples) -> Result<Mlp> {
    let trained = trainer::train_from(config, samples, None, None, &mut |_, _| {})?;
    Ok(trained.mlp.at_precision(Precision::F16)?)
}

/// Where a fold's fine-tuning dataset goes: beside the JSON report.
fn fold_dir(json: &Path, family: &str) -> PathBuf {
    folder_of(json).join(format!("fold-{family}"))
}

/// `net` fine-tuned on `scene` as `dhoit train --scene` does it: its training views' dataset
/// (generated into `dir`), [`OWN_EPOCHS`] at [`OWN_LR`], the best epoch the one closest to the
/// optimum on the training views; at the precision `train` deploys.
fn fine_tune(
    scene: &str,
    net: &Mlp,
    a: &GeneraliseArgs,
    hidden: [usize; 2],
    dir: &Path,
) -> Result<Mlp> {
    let c = crate::cli::own_dataset(&[scene.to_string()], a.res, a.opacity, 0);
    let data = dir.join("dataset");
    crate::cli::generate(&c, &data)?;
    let (_, samples) = dataset::load(&data)?;
    let prepared = crate::cli::own_selection(&c)?;
    let select = |m: &Mlp| -> Result<f64> { Ok(crate::cli::own_select(&prepared, m)) };
    let config = TrainConfig {
        epochs: OWN_EPOCHS,
        lr: OWN_LR,
        hidden,
        validation_scenes: Vec::new(),
        ..TrainConfig::default()
    };
    let trained = trainer::train_from(&config, &samples, Some(net), Some(&select), &mut |_, _| {})?;
    Ok(trained.mlp.at_precision(Precision::F16)?)
}

fn summarise(data: &Path, a: &GeneraliseArgs, hidden: [usize; 2], folds: Vec<Fold>) -> Report {
    let every: Vec<FrameScore> = folds.iter().flat_map(|f| f.scores.clone()).collect();
    let worst = folds
        .iter()
        .map(|f| (f.family.clone(), f.figures.left_out_over_optimal))
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .unwrap_or_default();
    Report {
        data: data.to_path_buf(),
        epochs: a.epochs,
        hidden,
        opacity: a.opacity,
        seeds: a.seeds,
        figures: Figures::of(&every, a.seeds as usize, !a.no_fine_tune),
        worst: worst.0,
        worst_over_optimal: worst.1,
        folds,
    }
}

/// The command that reproduces the run (its options as given).
fn command_line(a: &GeneraliseArgs) -> String {
    let mut c = String::from("dhoit generalise");
    if let Some(d) = &a.data {
        c += &format!(" --data {}", d.display());
    }
    if !a.families.is_empty() {
        c += &format!(" --families {}", a.families.join(","));
    }
    c += &format!(" --epochs {} --hidden {}", a.epochs, join(&a.hidden));
    if a.seeds != 1 {
        c += &format!(" --seeds {}", a.seeds);
    }
    c += &format!(
        " --view {} --orbit-views {} --res {}x{}",
        join(&a.views),
        a.orbit_views,
        a.res.width,
        a.res.height
    );
    if a.no_fine_tune {
        c += " --no-fine-tune";
    }
    if let Some(o) = a.opacity {
        c += &format!(" --opacity {o}");
    }
    c += &format!(" --out {}", a.out.display());
    c
}

fn join<T: ToString>(v: &[T]) -> String {
    v.iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(",")
}

/// The `log` share of VKB's distance to the optimum that DKB closes: 1 at the optimum, 0 at
/// VKB's error.
fn closed(dkb: f64, vkb: f64) -> f64 {
    if vkb <= 1.0 {
        return 1.0;
    }
    1.0 - dkb.max(1.0).ln() / vkb.ln()
}

/// The table's title and what it measures, how.
fn preamble(r: &Report, command: &str) -> String {
    let mut s = String::from("# DKB on families it has never seen (leave one out)\n\n");
    s += &format!(
        "Written by `{command}`. Each fold trains a {}-{} network for {} epochs on the dataset \
         ({}) with every scene of one built-in family removed, then scores it with `score`'s \
         measure (error against the per-pixel optimal allocation, geometric mean over the frames \
         that truncate) on that family's seed-1 scene, which no dataset holds, from the views \
         `train --scene` holds out; beside it the network trained the same way on every family \
         (in distribution: the default training), the fold's network fine-tuned on the scene's \
         own training views as `train --scene` does, and VKB. {}. {}\n\n",
        r.hidden[0],
        r.hidden[1],
        r.epochs,
        r.data.display(),
        match r.opacity {
            Some(o) => format!("Every surface at opacity {o}"),
            None => "Each scene's own opacity".into(),
        },
        match r.seeds {
            1 => "One training seed (0) a network.".to_string(),
            n => format!(
                "Every network trained at {n} seeds (0 to {}): the left-out and \
                 in-distribution figures are geometric means over them, the range in \
                 brackets that of the seeds' own figures (the fine-tuned column starts from \
                 seed 0's fold network).",
                n - 1
            ),
        }
    );
    s
}

fn markdown(r: &Report, command: &str) -> String {
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    let mut s = preamble(r, command);
    s += "| family left out | frames | DKB/optimal, left out | in distribution | left out, fine-tuned on the scene | VKB/optimal | gap to the optimum closed: left out | in distribution | fine-tuned |\n";
    s += "|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    let ranged = |v: f64, seeds: &[f64]| match seeds.len() {
        0 | 1 => format!("{v:.3}"),
        _ => {
            let lo = seeds.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = seeds.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            format!("{v:.3} ({lo:.3}-{hi:.3})")
        }
    };
    let row = |name: &str, frames: usize, f: &Figures| {
        let (l, i) = (f.left_out_over_optimal, f.in_distribution_over_optimal);
        let (t, v) = (f.fine_tuned_over_optimal, f.vkb_over_optimal);
        format!(
            "| {name} | {frames} | {} | {} | {} | {v:.3} | {:.0}% | {:.0}% | {} |\n",
            ranged(l, &f.left_out_by_seed),
            ranged(i, &f.in_distribution_by_seed),
            opt(t),
            100.0 * closed(l, v),
            100.0 * closed(i, v),
            t.map_or("-".into(), |t| format!("{:.0}%", 100.0 * closed(t, v))),
        )
    };
    for f in &r.folds {
        s += &row(&f.family, f.frames, &f.figures);
    }
    let frames: usize = r.folds.iter().map(|f| f.frames).sum();
    s += &row("**every fold**", frames, &r.figures);
    s += &format!(
        "\nLeft out, DKB/optimal {:.3} over every fold (in distribution {:.3}, fine-tuned on \
         the scene {}); the worst fold {} at {:.3}. The gap closed is the share of VKB's log \
         distance to the optimum that DKB removes.\n",
        r.figures.left_out_over_optimal,
        r.figures.in_distribution_over_optimal,
        opt(r.figures.fine_tuned_over_optimal),
        r.worst,
        r.worst_over_optimal
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_family_is_the_name_of_a_built_in_before_its_seed() {
        assert_eq!(family_of("hair:3"), Some("hair"));
        assert_eq!(family_of("hair"), Some("hair"));
        assert_eq!(family_of("scene.glb"), None);
        assert_eq!(family_of("hairy:3"), None);
    }

    #[test]
    fn the_gap_closed_is_one_at_the_optimum_and_none_at_vkb() {
        assert_eq!(closed(1.0, 8.0), 1.0);
        assert_eq!(closed(8.0, 8.0), 0.0);
        // Half VKB's log distance: sqrt(8) is half of 8's log.
        assert!((closed(8f64.sqrt(), 8.0) - 0.5).abs() < 1e-12);
    }
}
