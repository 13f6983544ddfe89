//! burn, the runtime's CPU twin and the GPU's WGSL network compute one function: the same
//! weights file loaded into all three, the same batches through each, within 1e-5 (f32; more
//! only for inputs past 100 standard deviations, in proportion: `tolerance`), and
//! never a NaN or an infinity. The batches are random, from real renders, the golden features,
//! and extremes; the networks the default, saturated, dead and the smallest and largest sizes.
mod common;
use common::{gpu, root};

use dhoit_runtime::importance::FEATURES;
use dhoit_runtime::mlp::{self, Mlp};
use dhoit_runtime::rng::Rng;

type Rows = Vec<[f32; FEATURES]>;

fn default_weights() -> Mlp {
    Mlp::load(&root().join("data/weights.safetensors")).unwrap()
}

/// How far two f32 evaluations of the network may differ on `row`: 1e-5 where its inputs lie
/// within 100 standard deviations of the means (real features stay within a few dozen), and in
/// proportion to the largest standardised input beyond (at the clamp, 1e4 deviations, the
/// network's sums are a hundred times a real row's and so is their rounding).
fn tolerance(m: &Mlp, row: &[f32; FEATURES]) -> f32 {
    let largest = (0..FEATURES)
        .map(|i| mlp::standardise(row[i], m.mean[i], m.std[i]).abs())
        .fold(0.0f32, f32::max);
    1e-5 * (largest / 100.0).max(1.0)
}

/// The largest difference between any two of burn, the twin and the GPU, after checking every
/// output is a finite number in [0, 1].
fn spread(m: &Mlp, rows: &Rows, what: &str) -> f32 {
    let burn = dhoit_train::model::predict(m, rows);
    let twin: Vec<f32> = rows.iter().map(|r| m.forward(r)).collect();
    let mut all = vec![("burn", burn), ("twin", twin)];
    if let Some(g) = gpu() {
        all.push(("gpu", g.predict(m, rows).unwrap()));
    }
    for (name, v) in &all {
        assert_eq!(v.len(), rows.len(), "{what}: {name}");
        if let Some(i) = v
            .iter()
            .position(|x| !(x.is_finite() && (0.0..=1.0).contains(x)))
        {
            panic!("{what}: {name} gives {} for row {i}: {:?}", v[i], rows[i]);
        }
    }
    let mut worst = 0.0f32;
    for a in 0..all.len() {
        for b in a + 1..all.len() {
            for (i, (x, y)) in all[a].1.iter().zip(&all[b].1).enumerate() {
                let d = (x - y).abs();
                assert!(
                    d <= tolerance(m, &rows[i]),
                    "{what}: {} and {} differ by {d} on row {i} ({x} vs {y}): {:?}",
                    all[a].0,
                    all[b].0,
                    rows[i]
                );
                worst = worst.max(d);
            }
        }
    }
    worst
}

/// Rows in the ranges real features take.
fn random_rows(rng: &mut Rng, n: usize) -> Rows {
    (0..n)
        .map(|_| {
            let c = rng.f32() * 8.0;
            [
                c,
                rng.f32() * 6.0,
                rng.f32(),
                rng.f32() * 6.0 - 3.0,
                rng.f32(),
                rng.f32() - 0.5,
                -20.0 + 20.0 * rng.f32(),
                -20.0 + 20.0 * rng.f32(),
                rng.f32(),
                rng.f32(),
                rng.f32(),
                rng.f32(),
            ]
        })
        .collect()
}

/// Extreme rows: all zeros, all ones, 1e6, 1e-9, negative, far outside the standardisation,
/// the largest finite magnitudes.
fn extreme_rows(m: &Mlp) -> Rows {
    let mut rows: Rows = vec![
        [0.0; FEATURES],
        [1.0; FEATURES],
        [1e6; FEATURES],
        [1e-9; FEATURES],
        [-1.0; FEATURES],
        [-1e6; FEATURES],
        [f32::MAX; FEATURES],
        [f32::MIN; FEATURES],
        [f32::MIN_POSITIVE; FEATURES],
    ];
    for k in [-1e4f32, -100.0, 100.0, 1e4] {
        rows.push(std::array::from_fn(|i| m.mean[i] + k * m.std[i]));
    }
    for i in 0..FEATURES {
        let mut r = [0.5; FEATURES];
        r[i] = 1e30;
        rows.push(r);
        r[i] = -1e30;
        rows.push(r);
    }
    rows
}

fn frame_rows(name: &str) -> Rows {
    use dhoit_runtime::scene::{self, Camera, Opacity};
    let s = scene::load(name, Opacity::default()).unwrap();
    let cam = Camera::orbit(&s, 1, scene::DEFAULT_VIEWS, (96, 72));
    let fl = dhoit_runtime::raster::rasterize(&s, &cam, (96, 72)).unwrap();
    let counts = fl.counts();
    dhoit_runtime::importance::features(&fl, fl.fragment_count() as u64 / 3)
        .into_iter()
        .zip(counts)
        .filter(|(_, n)| *n > 0)
        .map(|(f, _)| f)
        .collect()
}

#[test]
fn burn_the_twin_and_the_gpu_agree_on_every_batch() {
    let m = default_weights();
    let mut rng = Rng::new(12);
    let golden =
        dhoit_train::cli::read_features(&root().join("data/golden/features.safetensors")).unwrap();
    let mut worst = Vec::new();
    for (what, rows) in [
        ("random", random_rows(&mut rng, 4096)),
        ("golden", golden),
        ("particles render", frame_rows("particles")),
        ("cad render", frame_rows("cad")),
        ("extremes", extreme_rows(&m)),
    ] {
        worst.push((what, spread(&m, &rows, what)));
    }
    eprintln!("largest difference between burn, twin and GPU: {worst:?}");
}

/// The default network with its weights changed by `edit`.
fn edited(edit: impl FnOnce(&mut Mlp)) -> Mlp {
    let mut m = default_weights();
    edit(&mut m);
    m
}

#[test]
fn they_agree_at_the_limits_of_the_network() {
    let mut rng = Rng::new(5);
    let mut rows = random_rows(&mut rng, 512);
    let mut worst = Vec::new();
    let saturated_high = edited(|m| m.b3 = 60.0);
    let saturated_low = edited(|m| m.b3 = -60.0);
    // Every first-layer unit dead: the output is the sigmoid of the biases alone.
    let dead = edited(|m| m.b1.iter_mut().for_each(|b| *b = -mlp::MAX_PARAMETER));
    let mut cases: Vec<(String, Mlp)> = vec![
        ("saturated at 1".into(), saturated_high),
        ("saturated at 0".into(), saturated_low),
        ("every hidden unit dead".into(), dead),
    ];
    for (h1, h2) in [(1, 1), (8, 128), (16, 8), (128, 64)] {
        let mut m = Mlp::random_sized(7, h1, h2);
        m.mean = default_weights().mean;
        m.std = default_weights().std;
        cases.push((format!("random {h1}-{h2}"), m));
    }
    for (what, m) in &cases {
        let w = spread(m, &rows, what);
        worst.push((what.clone(), w));
        let x = spread(m, &extreme_rows(m), &format!("{what}, extremes"));
        worst.push((format!("{what}, extremes"), x));
    }
    // The saturated networks give exactly 1 and 0 on ordinary rows.
    let hi: Vec<f32> = rows.iter().map(|r| cases[0].1.forward(r)).collect();
    assert!(hi.iter().all(|&v| v > 0.999_999));
    let lo: Vec<f32> = rows.iter().map(|r| cases[1].1.forward(r)).collect();
    assert!(lo.iter().all(|&v| v < 1e-6));
    let dead: Vec<f32> = rows.iter().map(|r| cases[2].1.forward(r)).collect();
    assert!(
        dead.windows(2).all(|w| w[0] == w[1]),
        "a dead network is constant"
    );
    rows.truncate(1);
    eprintln!("largest difference at the limits: {worst:?}");
}

#[test]
fn every_loader_refuses_weights_at_the_limits() {
    let good = std::fs::read(root().join("data/weights.safetensors")).unwrap();
    let m = Mlp::from_bytes(&good).unwrap();
    let dir = common::temp_dir("equiv");
    for (what, edit, needle) in [
        (
            "NaN",
            (|m: &mut Mlp| m.w2[3] = f32::NAN) as fn(&mut Mlp),
            "non-finite",
        ),
        (
            "infinity",
            |m: &mut Mlp| m.b1[0] = f32::INFINITY,
            "non-finite",
        ),
        ("huge", |m: &mut Mlp| m.w3[0] = 1e20, "largest magnitude"),
        ("zero std", |m: &mut Mlp| m.std[4] = 0.0, "input_std[4]"),
    ] {
        let mut bad = m.clone();
        edit(&mut bad);
        let path = dir.join(format!("{what}.safetensors"));
        bad.save(&path, &Default::default()).unwrap();
        // The runtime (and so the GPU upload, which takes an Mlp) and the predict command,
        // which loads for burn.
        let e = Mlp::load(&path).unwrap_err().to_string();
        assert!(e.contains(needle), "{what}: {e}");
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_dhoit"))
            .args(["predict", "--weights"])
            .arg(&path)
            .arg("--input")
            .arg(root().join("data/golden/features.safetensors"))
            .arg("--output")
            .arg(dir.join("never.safetensors"))
            .output()
            .unwrap();
        assert!(!o.status.success(), "{what}");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(needle),
            "{what}"
        );
    }
    // A hidden layer larger than the GPU pass holds.
    let big = Mlp::random_sized(1, 4, mlp::MAX_H2 + 1);
    let path = dir.join("big.safetensors");
    big.save(&path, &Default::default()).unwrap();
    let e = Mlp::load(&path).unwrap_err().to_string();
    assert!(e.contains("at most"), "{e}");
}

/// The batches the precisions are held on: random rows (seeded), the golden features, and the
/// features of two renders.
fn precision_batches(seed: u64) -> [(&'static str, Rows); 4] {
    let mut rng = Rng::new(seed);
    let golden =
        dhoit_train::cli::read_features(&root().join("data/golden/features.safetensors")).unwrap();
    [
        ("random", random_rows(&mut rng, 4096)),
        ("golden", golden),
        ("particles render", frame_rows("particles")),
        ("cad render", frame_rows("cad")),
    ]
}

/// The f16 network (weights and biases rounded to binary16, f32 arithmetic) is one function on
/// burn, the twin and the GPU's f16 pass, within 1e-5, never NaN; against the f32 network its
/// importance moves by at most `mlp::F16_BOUND` on every batch; and a weight binary16 cannot
/// hold is refused by name.
#[test]
fn the_f16_network_is_one_function_within_its_bound_of_f32() {
    use dhoit_runtime::mlp::Precision;
    let batches = precision_batches(21);
    let sized = |h1, h2| {
        let mut m = Mlp::random_sized(9, h1, h2);
        m.mean = default_weights().mean;
        m.std = default_weights().std;
        m
    };
    let mut nets = vec![("default".to_string(), default_weights())];
    for dir in ["16-8", "32-16", "64-32"] {
        let path = root()
            .join("data/nets")
            .join(dir)
            .join("weights.safetensors");
        nets.push((dir.to_string(), Mlp::load(&path).unwrap()));
    }
    nets.push(("random 128-64".into(), sized(128, 64)));
    let (mut worst_devices, mut worst_f32) = (0.0f32, Vec::new());
    for (name, m) in &nets {
        let h = m.at_precision(Precision::F16).unwrap();
        assert_eq!(h.precision, Precision::F16);
        if m.precision == Precision::F16 {
            // The default weights deploy at f16 and are stored rounded: rounding again is the
            // identity (the random 128-64 network holds rounding's effect at their size).
            assert!(h.w2 == m.w2 && h.w1 == m.w1, "{name}: stored unrounded");
        } else {
            assert!(
                h.w2.iter().zip(&m.w2).any(|(a, b)| a != b),
                "{name}: nothing rounded"
            );
        }
        let mut worst = 0.0f32;
        for (what, rows) in &batches {
            worst_devices = worst_devices.max(spread(&h, rows, &format!("{name} f16, {what}")));
            for (i, r) in rows.iter().enumerate() {
                let d = (h.forward(r) - m.forward(r)).abs();
                assert!(
                    d <= mlp::F16_BOUND,
                    "{name}, {what}, row {i}: f16 and f32 differ by {d} (bound {})",
                    mlp::F16_BOUND
                );
                worst = worst.max(d);
            }
        }
        spread(&h, &extreme_rows(&h), &format!("{name} f16, extremes"));
        worst_f32.push((name.clone(), worst));
    }
    eprintln!(
        "f16: burn, twin and GPU within {worst_devices:e}; largest |f16 - f32| per network: \
         {worst_f32:?} (bound {})",
        mlp::F16_BOUND
    );
    let big = edited(|m| m.w2[5] = 7e4);
    let e = big.at_precision(Precision::F16).unwrap_err().to_string();
    assert!(e.contains("fc2.weight[5]") && e.contains("f16"), "{e}");
}

/// The GPU's batch pass refuses features that are not finite numbers, naming the first,
/// before anything reaches the device: WGSL does not say what its `clamp` makes of a NaN.
#[test]
fn the_gpu_network_refuses_features_that_are_not_numbers() {
    let Some(g) = gpu() else { return };
    let mut rows = vec![[0.5f32; FEATURES]; 3];
    rows[2][7] = f32::NAN;
    let e = g
        .predict(&default_weights(), &rows)
        .unwrap_err()
        .to_string();
    assert!(e.contains("row 2, column 7"), "{e}");
    rows[2][7] = f32::NEG_INFINITY;
    assert!(g.predict(&default_weights(), &rows).is_err());
    rows[2][7] = 0.5;
    assert_eq!(g.predict(&default_weights(), &rows).unwrap().len(), 3);
}

/// The f16-math network (binary16 weights and hidden-layer arithmetic, `Precision::F16Math`):
/// its CPU twin moves the importance by at most `mlp::F16_MATH_BOUND` from the f32 network on
/// every batch, the GPU's pass stays within `mlp::F16_MATH_GPU_BOUND` of the twin (a GPU may
/// fuse what the twin rounds twice), and at the limits both give an importance in [0, 1]. A
/// device without half-precision shaders refuses it by name (there the GPU part is skipped,
/// saying so: lavapipe has it).
#[test]
fn the_f16_math_network_stays_within_its_bounds_of_f32_and_its_twin() {
    use dhoit_runtime::mlp::Precision;
    let batches = precision_batches(23);
    let mut nets = vec![("default".to_string(), default_weights())];
    for dir in ["16-8", "64-32"] {
        let path = root()
            .join("data/nets")
            .join(dir)
            .join("weights.safetensors");
        nets.push((dir.to_string(), Mlp::load(&path).unwrap()));
    }
    let g = gpu().filter(|g| {
        if !g.has_half_math() {
            let h = default_weights().at_precision(Precision::F16Math).unwrap();
            let e = g.predict(&h, &[[0.5; FEATURES]]).unwrap_err().to_string();
            assert!(e.contains("SHADER_F16") && e.contains("f16-math"), "{e}");
            eprintln!(
                "{} lacks SHADER_F16 (refused: {e}): its f16-math pass is not compared",
                g.adapter()
            );
        }
        g.has_half_math()
    });
    let (mut worst_f32, mut worst_gpu) = (Vec::new(), 0.0f32);
    for (name, m) in &nets {
        let h = m.at_precision(Precision::F16Math).unwrap();
        assert!(h.precision.half_weights());
        let w16 = m.at_precision(Precision::F16).unwrap();
        let mut worst = 0.0f32;
        let mut moved = false;
        for (what, rows) in &batches {
            let twin: Vec<f32> = rows.iter().map(|r| h.forward(r)).collect();
            for (i, r) in rows.iter().enumerate() {
                let d = (twin[i] - m.forward(r)).abs();
                assert!(
                    d <= mlp::F16_MATH_BOUND,
                    "{name}, {what}, row {i}: f16-math and f32 differ by {d} (bound {})",
                    mlp::F16_MATH_BOUND
                );
                worst = worst.max(d);
                moved |= twin[i] != w16.forward(r);
            }
            if let Some(g) = &g {
                let on_gpu = g.predict(&h, rows).unwrap();
                // The GPU computes in binary16, not in f32 with the same weights: its outputs
                // are 20 times nearer its twin's than the f16-weights pass's (the bound alone,
                // wider than f16-math's whole effect, would not tell them apart; measured on
                // lavapipe: 1e-6 to 3e-5 against 5e-3 to 0.9, summed over a batch).
                let f32_math = g.predict(&w16, rows).unwrap();
                let to_twin: f64 = on_gpu
                    .iter()
                    .zip(&twin)
                    .map(|(a, b)| (a - b).abs() as f64)
                    .sum();
                let to_f32: f64 = on_gpu
                    .iter()
                    .zip(&f32_math)
                    .map(|(a, b)| (a - b).abs() as f64)
                    .sum();
                eprintln!(
                    "{name}, {what}: GPU f16-math {to_twin:.3e} from its twin, {to_f32:.3e} from f32 arithmetic"
                );
                assert!(
                    to_twin < 0.05 * to_f32,
                    "{name}, {what}: the GPU's f16-math pass is {to_twin:.3e} from its twin and \
                     {to_f32:.3e} from the f32 arithmetic (summed over the batch)"
                );
                for (i, (a, b)) in on_gpu.iter().zip(&twin).enumerate() {
                    let d = (a - b).abs();
                    assert!(
                        d <= mlp::F16_MATH_GPU_BOUND,
                        "{name}, {what}, row {i}: the GPU's f16-math pass and its twin differ \
                         by {d} ({a} vs {b}; bound {})",
                        mlp::F16_MATH_GPU_BOUND
                    );
                    worst_gpu = worst_gpu.max(d);
                }
            }
        }
        // Half-precision arithmetic, not only half-precision weights.
        assert!(
            moved,
            "{name}: f16-math computes what f16 weights in f32 do"
        );
        let rows = extreme_rows(&h);
        let mut all = vec![rows.iter().map(|r| h.forward(r)).collect::<Vec<f32>>()];
        if let Some(g) = &g {
            all.push(g.predict(&h, &rows).unwrap());
        }
        for v in all {
            assert!(
                v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)),
                "{name}: f16-math at the limits gives {v:?}"
            );
        }
        worst_f32.push((name.clone(), worst));
    }
    // burn computes in f32: `predict` refuses f16-math there, writing nothing.
    let folder = common::temp_dir("f16-math");
    let out = folder.join("weights.safetensors");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_dhoit"))
        .args(["predict", "--precision", "f16-math", "--weights"])
        .arg(root().join("data/weights.safetensors"))
        .arg("--input")
        .arg(root().join("data/golden/features.safetensors"))
        .arg("--output")
        .arg(&out)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("burn") && e.contains("f16-math"),
        "{e}"
    );
    assert!(!out.exists());
    eprintln!(
        "f16-math: largest |twin - f32| per network {worst_f32:?} (bound {}); largest \
         |GPU - twin| {worst_gpu:e} (bound {})",
        mlp::F16_MATH_BOUND,
        mlp::F16_MATH_GPU_BOUND
    );
}
