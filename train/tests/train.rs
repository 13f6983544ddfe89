//! The trainer: datasets, the loss, reproducibility, and the weights contract end to end.

use burn::prelude::*;
use burn::tensor::TensorData;
use dhoit_runtime::importance::FEATURES;
use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::rng::Rng;
use dhoit_train::dataset::{self, DatasetConfig, Level};
use dhoit_train::model::{self, ImportanceNet, cpu_device};
use dhoit_train::trainer::{self, TrainConfig};
use std::path::PathBuf;

/// A fresh temporary folder, removed when the test drops it.
fn temp(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("dhoit-train-{name}-"))
        .tempdir()
        .unwrap()
}

fn small_config() -> DatasetConfig {
    DatasetConfig {
        scenes: vec!["shells".into(), "foliage".into(), "spheres".into()],
        width: 64,
        height: 48,
        views: 2,
        levels: vec![
            Level::SlotsPerPixel(1.0),
            Level::SlotsPerPixel(2.0),
            Level::All,
        ],
        sample: 0.5,
        seed: 3,
        opacity: Some(0.33),
    }
}

#[test]
fn datasets_are_deterministic_and_complete() {
    let (da, db) = (temp("ds-a"), temp("ds-b"));
    let (a, b) = (da.path(), db.path());
    let cfg = small_config();
    let ma = dataset::generate(&cfg, a, &|_, _| {}).unwrap();
    let mb = dataset::generate(&cfg, b, &|_, _| {}).unwrap();
    assert_eq!(ma.shards, mb.shards);
    assert_eq!(ma.shards.len(), 3 * 2 * 3);
    for s in &ma.shards {
        // Same tensors and metadata (the header's key order is not fixed by safetensors).
        let (fa, fb) = (
            std::fs::read(a.join(&s.file)).unwrap(),
            std::fs::read(b.join(&s.file)).unwrap(),
        );
        let (ta, tb) = (
            dhoit_runtime::tensors::File::parse(&fa).unwrap(),
            dhoit_runtime::tensors::File::parse(&fb).unwrap(),
        );
        assert!(
            ta.f32("features", None).unwrap() == tb.f32("features", None).unwrap(),
            "{}",
            s.file
        );
        assert!(
            ta.f32("target", None).unwrap() == tb.f32("target", None).unwrap(),
            "{}",
            s.file
        );
        assert!(ta.metadata == tb.metadata, "{}", s.file);
        // About half of the covered pixels are sampled.
        let share = s.samples as f64 / s.covered_pixels as f64;
        assert!((0.3..0.7).contains(&share), "{share}");
    }
    let (_, samples) = dataset::load(a).unwrap();
    assert_eq!(samples.len(), ma.samples);
    assert!(samples.target.iter().all(|t| (0.0..=1.0).contains(t)));
    // With every fragment in budget the target is n / max n.
    let all = ma.shards.iter().find(|s| s.budget == "all").unwrap();
    assert_eq!(all.budget_fragments, all.fragments);
    // A directory without a manifest is refused.
    std::fs::remove_file(a.join(dataset::MANIFEST)).unwrap();
    let e = dataset::load(a).unwrap_err().to_string();
    assert!(e.contains("manifest.json"), "{e}");
}

fn tiny_data(seed: u64, n: usize) -> dataset::Samples {
    let mut rng = Rng::new(seed);
    let mut s = dataset::Samples {
        scenes: vec!["a".into(), "b".into()],
        ..Default::default()
    };
    for i in 0..n {
        let f: [f32; FEATURES] = std::array::from_fn(|_| rng.f32());
        // A learnable target: a smooth function of two features.
        s.target.push((0.2 + 0.6 * f[0] * f[3]).clamp(0.0, 1.0));
        s.features.push(f);
        s.scene.push((i % 4 == 0) as u16);
    }
    s
}

fn quick(seed: u64, epochs: usize) -> TrainConfig {
    TrainConfig {
        epochs,
        lr: 0.05,
        batch: 64,
        momentum: 0.9,
        hidden: [32, 16],
        seed,
        validation_scenes: vec!["b".into()],
        loss: trainer::Loss::MseRelative,
        ..TrainConfig::default()
    }
}

#[test]
fn seeded_training_is_reproducible_and_the_loss_falls() {
    let data = tiny_data(1, 2000);
    let a = trainer::train(&quick(7, 6), &data, &mut |_, _| {}).unwrap();
    let b = trainer::train(&quick(7, 6), &data, &mut |_, _| {}).unwrap();
    assert_eq!(a.mlp, b.mlp, "same seed, same weights");
    assert_eq!(
        a.history.iter().map(|e| e.train_loss).collect::<Vec<_>>(),
        b.history.iter().map(|e| e.train_loss).collect::<Vec<_>>()
    );
    let c = trainer::train(&quick(8, 6), &data, &mut |_, _| {}).unwrap();
    assert_ne!(a.mlp, c.mlp, "another seed, other weights");
    let first = a.history.first().unwrap().train_loss;
    let last = a.history.last().unwrap().train_loss;
    assert!(last < 0.5 * first, "training loss falls: {first} -> {last}");
    assert!(a.history[a.best_epoch].validation_loss <= a.history[0].validation_loss);
    assert_eq!(a.validation_samples, 500);
}

#[test]
fn l1_and_l2_terms_follow_their_formulas() {
    // A tiny model with known weights: fc1 [12,2], fc2 [2,2], out [2,1].
    let mut m = Mlp::random_sized(3, 2, 2);
    m.w1 = (0..24).map(|i| (i as f32 - 11.5) * 0.1).collect();
    m.w2 = vec![0.5, -1.5, 2.0, -0.25];
    let device = cpu_device(true);
    let net = ImportanceNet::from_mlp(&m, &device);
    let x = Tensor::<2>::from_data(
        TensorData::new(vec![0.3f32; 2 * FEATURES], [2, FEATURES]),
        &device,
    );
    let y = Tensor::<2>::from_data(TensorData::new(vec![0.25f32, 0.75], [2, 1]), &device);
    let value = |t: Tensor<1>| t.into_data().try_into_vec::<f32>().unwrap()[0] as f64;
    let (base, mse0, reg0) = trainer::loss(&net, x.clone(), y.clone(), 0.0, 0.0);
    let (l1_only, _, _) = trainer::loss(&net, x.clone(), y.clone(), 0.01, 0.0);
    let (both, mse, reg) = trainer::loss(&net, x.clone(), y.clone(), 0.01, 0.1);
    let (base, mse0, reg0) = (value(base), value(mse0), value(reg0));
    let (l1_only, both, mse, reg) = (value(l1_only), value(both), value(mse), value(reg));
    // By hand: sum |W1| = 0.1 * 2 * (0.5 + 1.5 + ... + 11.5) = 14.4; sum W2^2 = 6.5625.
    let sum_abs_w1: f64 = (0..24).map(|i| ((i as f64 - 11.5) * 0.1).abs()).sum();
    assert!((sum_abs_w1 - 14.4).abs() < 1e-9);
    let sum_sq_w2 = 0.25 + 2.25 + 4.0 + 0.0625;
    assert_eq!(reg0, 0.0);
    assert!((l1_only - base - 0.01 * sum_abs_w1).abs() < 1e-5);
    assert!((both - base - 0.01 * sum_abs_w1 - 0.1 * sum_sq_w2).abs() < 1e-5);
    assert!((reg - (0.01 * sum_abs_w1 + 0.1 * sum_sq_w2)).abs() < 1e-5);
    assert_eq!(mse, mse0);
    // And the MSE is the mean over the batch of (prediction - target)^2, by the runtime twin.
    let p: Vec<f32> = (0..2).map(|_| m.forward(&[0.3; FEATURES])).collect();
    let hand = ((p[0] - 0.25).powi(2) + (p[1] - 0.75).powi(2)) as f64 / 2.0;
    assert!((mse0 - hand).abs() < 1e-6, "{mse0} vs {hand}");
}

#[test]
fn trained_weights_load_in_the_runtime_and_agree_with_burn() {
    let data = tiny_data(2, 1500);
    let t = trainer::train(&quick(1, 3), &data, &mut |_, _| {}).unwrap();
    let dir = temp("export");
    let dir = dir.path();
    let path = dir.join("w.safetensors");
    t.mlp.save(&path, &Default::default()).unwrap();
    let loaded = Mlp::load(&path).unwrap();
    assert_eq!(loaded, t.mlp);
    // Names, shapes and metadata per the contract.
    let bytes = std::fs::read(&path).unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let mut names = st.names();
    names.sort();
    assert_eq!(
        names,
        [
            "fc1.bias",
            "fc1.weight",
            "fc2.bias",
            "fc2.weight",
            "out.bias",
            "out.weight"
        ]
    );
    assert_eq!(st.tensor("fc1.weight").unwrap().shape(), [12, 32]);
    assert_eq!(st.tensor("fc2.weight").unwrap().shape(), [32, 16]);
    assert_eq!(st.tensor("out.weight").unwrap().shape(), [16, 1]);
    let (_, meta) = safetensors::SafeTensors::read_metadata(&bytes).unwrap();
    let meta = meta.metadata().clone().unwrap();
    for key in ["format", "layout", "features", "input_mean", "input_std"] {
        assert!(meta.contains_key(key), "{key}");
    }
    // Runtime twin vs burn inference on random features, including out-of-range ones.
    let mut rng = Rng::new(4);
    let rows: Vec<[f32; FEATURES]> = (0..3000)
        .map(|_| std::array::from_fn(|_| rng.range(-1.0, 2.0)))
        .collect();
    let burn = model::predict(&loaded, &rows);
    let max = rows
        .iter()
        .zip(&burn)
        .map(|(r, b)| (loaded.forward(r) - b).abs())
        .fold(0.0f32, f32::max);
    assert!(max <= 1e-6, "max abs difference {max}");
}

/// The committed default weights are what `make train` writes on a fresh clone, bit for bit
/// where the machine computes training's floats as the training machine did (the fingerprint
/// config.json records, `trainer::float_fingerprint`), else to within 1% of their validation
/// loss, saying so:
/// the default dataset generated from nothing (into a folder of its own, so data/generated is
/// left alone) and the default training, compared byte for byte with data/weights.safetensors
/// (about a minute and a half on two cores). A user regression-testing predictions can
/// then rebuild the weights the golden predictions come from.
#[test]
fn the_committed_weights_are_what_make_train_writes() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let folder = temp("make-train");
    let dir = folder.path();
    let out = dir.join("weights.safetensors");
    // The default dataset, as `make train` generates it where data/generated has none.
    dataset::generate(&DatasetConfig::default(), &dir.join("dataset"), &|_, _| {}).unwrap();
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_dhoit-train"))
        .arg("--data")
        .arg(dir.join("dataset"))
        .arg("--out")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success(), "dhoit-train: {status}");
    let fresh = std::fs::read(&out).unwrap();
    let committed_path = root.join(dhoit_train::cli::DEFAULT_WEIGHTS);
    let committed = std::fs::read(&committed_path).unwrap();
    if fresh != committed {
        // Bit for bit only where this machine computes training's floats as the one that
        // trained the committed weights did (burn's kernels take other SIMD paths on other
        // CPUs): its fingerprint, recorded in config.json beside them.
        let config = |p: &std::path::Path| -> serde_json::Value {
            serde_json::from_slice(&std::fs::read(p.with_file_name("config.json")).unwrap())
                .unwrap()
        };
        let (theirs, ours) = (config(&committed_path), config(&out));
        let here = dhoit_train::trainer::float_fingerprint();
        assert_eq!(ours["float_fingerprint"], here.as_str());
        let recorded = theirs["float_fingerprint"].as_str();
        assert!(
            recorded.is_some_and(|r| r != here) || recorded.is_none(),
            "a fresh `make train` writes other weights than data/weights.safetensors on a machine \
             that computes floats as the training machine did (fingerprint {here}): retrain and \
             commit them (`make train`)"
        );
        // Another machine's floats (or weights trained before the fingerprint, or before its
        // scheme, was recorded): the same training must still reach their validation loss,
        // within 1%.
        let loss = |c: &serde_json::Value| c["best"]["validation_loss"].as_f64().unwrap();
        let (want, got) = (loss(&theirs), loss(&ours));
        let scheme = format!("{}-", dhoit_train::trainer::FINGERPRINT_SCHEME);
        eprintln!(
            "this machine's floats (fingerprint {here}) are not known to be those the committed \
             weights were trained with ({}): held to their validation loss, {want:.6} against \
             {got:.6}, not their bytes",
            match recorded {
                None => "not recorded".to_string(),
                Some(r) if !r.starts_with(&scheme) => format!("{r}, an earlier scheme"),
                Some(r) => r.to_string(),
            }
        );
        assert!(
            (got - want).abs() <= 0.01 * want,
            "a fresh `make train` reaches validation loss {got}, the committed weights {want}"
        );
    }
}

/// The float fingerprint is a function of the machine alone (the same digest twice, in its
/// scheme), and it covers the optimiser `make train` steps with: the default's clipping by norm
/// acts in its steps (without it the digest differs), so the CPU-dependent sums of the norms
/// reach it.
#[test]
fn the_float_fingerprint_covers_the_clipped_step() {
    use dhoit_train::trainer::{
        FINGERPRINT_SCHEME, TrainConfig, float_fingerprint, float_fingerprint_of,
    };
    let a = float_fingerprint();
    assert_eq!(a, float_fingerprint());
    assert!(a.starts_with(&format!("{FINGERPRINT_SCHEME}-")), "{a}");
    assert!(TrainConfig::default().clip > 0.0);
    let unclipped = TrainConfig {
        clip: 0.0,
        ..TrainConfig::default()
    };
    assert_ne!(
        a,
        float_fingerprint_of(&unclipped),
        "the fingerprint's steps never clip"
    );
}

/// Each parameter's gradient from a set of burn `GradientsParams`, in the module's order.
fn grads_of(net: &ImportanceNet, g: &burn::optim::GradientsParams) -> Vec<Vec<f32>> {
    let flat2 = |id| {
        g.get::<2>(id)
            .expect("a weight's gradient")
            .into_data()
            .try_into_vec::<f32>()
            .unwrap()
    };
    let flat1 = |id| {
        g.get::<1>(id)
            .expect("a bias's gradient")
            .into_data()
            .try_into_vec::<f32>()
            .unwrap()
    };
    let bias = |l: &burn::nn::Linear| l.bias.as_ref().unwrap().id;
    vec![
        flat2(net.fc1.weight.id),
        flat1(bias(&net.fc1)),
        flat2(net.fc2.weight.id),
        flat1(bias(&net.fc2)),
        flat2(net.out.weight.id),
        flat1(bias(&net.out)),
    ]
}

/// The largest difference between two sets of gradients, relative to the largest gradient of
/// each parameter.
fn worst_relative(a: &[Vec<f32>], b: &[Vec<f32>]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| {
            let scale = a.iter().map(|v| v.abs()).fold(0.0f32, f32::max).max(1e-12) as f64;
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs() as f64 / scale)
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max)
}

/// A network and standardised rows for gradient checks: enough rows for several shards.
fn gradient_case(rows: usize) -> (ImportanceNet, Vec<f32>) {
    let m = Mlp::random_sized(5, 32, 16);
    let mut rng = Rng::new(9);
    let x: Vec<f32> = (0..rows * FEATURES).map(|_| rng.range(-2.0, 2.0)).collect();
    (ImportanceNet::from_mlp(&m, &cpu_device(true)), x)
}

#[test]
fn the_fused_step_s_mse_gradients_are_burn_autodiff_s() {
    let rows = 700; // three shards of 233 and 234 rows
    assert!(rows > 2 * dhoit_train::step::SHARD_ROWS);
    let (net, x) = gradient_case(rows);
    let mut rng = Rng::new(10);
    let y: Vec<f32> = (0..rows).map(|_| rng.f32()).collect();
    let (l1, l2) = (1e-3, 1e-2);
    // burn's autodiff graph.
    let device = cpu_device(true);
    let xt = Tensor::<2>::from_data(TensorData::new(x.clone(), [rows, FEATURES]), &device);
    let yt = Tensor::<2>::from_data(TensorData::new(y.clone(), [rows, 1]), &device);
    let (total, mse, _) = trainer::loss(&net, xt, yt, l1, l2);
    let mse = mse.into_data().try_into_vec::<f32>().unwrap()[0] as f64;
    let reference = burn::optim::GradientsParams::from_grads(total.backward(), &net);
    // The fused step, on the plain copy.
    let valid = net.valid();
    let plain = cpu_device(false);
    let pass = dhoit_train::step::forward(&valid, &x, &plain);
    let (value, d_out) = dhoit_train::step::mse_gradient(&pass.out, &y);
    let fused = dhoit_train::step::gradients(&valid, pass, &d_out, l1, l2, &plain);
    assert!((value - mse).abs() <= 1e-6 * mse, "loss {value} vs {mse}");
    let worst = worst_relative(&grads_of(&net, &reference), &grads_of(&net, &fused));
    eprintln!("mse: loss {value} vs {mse}, gradients within {worst:.2e} of their largest");
    assert!(worst < 1e-5, "gradients differ by {worst} of their largest");
    // The whole step in one task a shard (what training runs) gives the same gradients, bit for
    // bit, and the loss up to the order of its f64 sum.
    let (one_task, grads) = dhoit_train::step::mse_step(&valid, &x, &y, l1, l2, &plain);
    assert!(
        (one_task - value).abs() <= 1e-12 * value,
        "{one_task} vs {value}"
    );
    assert_eq!(grads_of(&net, &grads), grads_of(&net, &fused));
}

#[test]
fn the_regret_gradient_is_burn_autodiff_s_for_both_fits() {
    use dhoit_train::dataset::REGRET_WINDOW;
    let rows = 600;
    let (net, x) = gradient_case(rows);
    let synthetic = trainer::FrameSamples::synthetic(rows, 12.0, 11);
    let trainer::FrameSamples {
        counts,
        k_opts,
        pairs,
        regret,
        ..
    } = &synthetic;
    let device = cpu_device(true);
    let plain = cpu_device(false);
    let column =
        |v: &[f32]| Tensor::<2>::from_data(TensorData::new(v.to_vec(), [rows, 1]), &device);
    for loss in [trainer::Loss::Regret, trainer::Loss::RegretLevel] {
        // burn's autodiff graph of the same loss.
        let batch = trainer::RegretBatch {
            count: column(counts),
            k_opt: column(k_opts),
            regret: Tensor::from_data(
                TensorData::new(regret.concat(), [rows, REGRET_WINDOW]),
                &device,
            ),
            lo: synthetic.lo,
            counts: counts.clone(),
            pairs: pairs.clone(),
            k_opts: k_opts.clone(),
            share: synthetic.share,
        };
        let xt = Tensor::<2>::from_data(TensorData::new(x.clone(), [rows, FEATURES]), &device);
        let (total, value, _) = trainer::regret_loss(&net, loss, xt, batch, 1e-4, 1e-3);
        let reference_value = value.into_data().try_into_vec::<f32>().unwrap()[0] as f64;
        let reference = burn::optim::GradientsParams::from_grads(total.backward(), &net);
        // The fused step.
        let valid = net.valid();
        let pass = dhoit_train::step::forward(&valid, &x, &plain);
        let (fused_value, d_out) = trainer::regret_gradient(loss, &pass.out, &synthetic);
        let grads = dhoit_train::step::gradients(&valid, pass, &d_out, 1e-4, 1e-3, &plain);
        assert!(
            (fused_value - reference_value).abs() <= 1e-4 * reference_value.abs().max(1e-3),
            "{}: loss {fused_value} vs {reference_value}",
            loss.name()
        );
        let worst = worst_relative(&grads_of(&net, &reference), &grads_of(&net, &grads));
        eprintln!(
            "{}: loss {fused_value} vs {reference_value}, gradients within {worst:.2e} of their largest",
            loss.name()
        );
        assert!(
            worst < 1e-5,
            "{}: gradients differ by {worst} of their largest",
            loss.name()
        );
    }
}

/// A run's weights depend on its seed and data, not on how many threads run it: the fused
/// step cuts batches into shards by their row count and adds the shards' gradients in order.
#[test]
fn training_writes_the_same_weights_on_one_thread_and_on_many() {
    let data = tiny_data(3, 3000);
    let mut config = quick(5, 2);
    config.batch = 700; // shards of 233 and 234 rows
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| trainer::train(&config, &data, &mut |_, _| {}).unwrap())
    };
    let one = on(1);
    assert_eq!(one.mlp, on(3).mlp, "1 thread vs 3");
    assert_eq!(one.mlp, on(8).mlp, "1 thread vs 8");
}
