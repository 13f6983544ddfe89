//! The MLP's CPU twin and the weights contract.

mod common;

use dhoit_runtime::mlp::{H1, H2, Mlp};
use std::collections::HashMap;
use std::path::PathBuf;

/// A file in this binary's temporary folder (made once, shared by its tests: it stays).
fn temp(name: &str) -> PathBuf {
    static DIR: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| common::temp_dir("mlp").keep())
        .join(name)
}

/// The same network as matrix products in f64: an independent implementation.
fn reference(m: &Mlp, f: &[f32; 12]) -> f64 {
    let x: Vec<f64> = (0..12)
        .map(|i| ((f[i] - m.mean[i]) / m.std[i]) as f64)
        .collect();
    let layer = |x: &[f64], w: &[f32], b: &[f32], out: usize| -> Vec<f64> {
        (0..out)
            .map(|j| {
                (b[j] as f64
                    + x.iter()
                        .enumerate()
                        .map(|(i, v)| v * w[i * out + j] as f64)
                        .sum::<f64>())
                .max(0.0)
            })
            .collect()
    };
    let h1 = layer(&x, &m.w1, &m.b1, H1);
    let h2 = layer(&h1, &m.w2, &m.b2, H2);
    let z = m.b3 as f64
        + h2.iter()
            .zip(&m.w3)
            .map(|(a, b)| a * *b as f64)
            .sum::<f64>();
    1.0 / (1.0 + (-z).exp())
}

#[test]
fn forward_matches_an_independent_implementation() {
    let mut m = Mlp::random(1);
    m.mean = [0.1; 12];
    m.std = [0.5; 12];
    let mut rng = dhoit_runtime::rng::Rng::new(2);
    for _ in 0..500 {
        let f: [f32; 12] = std::array::from_fn(|_| rng.range(-2.0, 2.0));
        let (a, b) = (m.forward(&f) as f64, reference(&m, &f));
        assert!((a - b).abs() < 1e-5, "{a} vs {b}");
    }
}

#[test]
fn weights_round_trip_through_the_contract() {
    let mut m = Mlp::random(4);
    m.mean = std::array::from_fn(|i| i as f32 * 0.01);
    m.std = std::array::from_fn(|i| 1.0 + i as f32);
    let path = temp("roundtrip.safetensors");
    m.save(
        &path,
        &HashMap::from([("note".to_string(), "test".to_string())]),
    )
    .unwrap();
    assert_eq!(Mlp::load(&path).unwrap(), m);
}

#[test]
fn a_file_records_the_precision_it_is_deployed_at() {
    use dhoit_runtime::mlp::Precision;
    let m = Mlp::random_sized(5, 16, 8);
    for p in [Precision::F32, Precision::F16, Precision::F16Math] {
        let d = m.at_precision(p).unwrap();
        let path = temp(&format!("precision-{p}.safetensors"));
        // A stale key in the extra metadata does not survive: the network's own is written.
        let extra = HashMap::from([("precision".to_string(), "f16-math".to_string())]);
        d.save(&path, &extra).unwrap();
        let back = Mlp::load(&path).unwrap();
        assert_eq!(back, d, "{p}");
        assert_eq!(back.precision, p);
        // Loaded at f32 again: the rounded values, f32's uniform.
        let f = back.at_precision(Precision::F32).unwrap();
        assert_eq!(f.uniform_bytes(), 1_536, "{p}");
    }
}

/// Writes a weights file with one tensor or metadata entry changed.
fn broken(
    name: &str,
    edit: impl Fn(&mut Vec<(String, Vec<usize>, Vec<f32>)>, &mut HashMap<String, String>),
) -> PathBuf {
    let m = Mlp::random(5);
    let path = temp(&format!("{name}.safetensors"));
    m.save(&path, &HashMap::new()).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let (_, meta) = safetensors::SafeTensors::read_metadata(&bytes).unwrap();
    let mut meta = meta.metadata().clone().unwrap();
    let mut tensors: Vec<(String, Vec<usize>, Vec<f32>)> = st
        .tensors()
        .into_iter()
        .map(|(n, v)| {
            let data = v
                .data()
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            (n, v.shape().to_vec(), data)
        })
        .collect();
    edit(&mut tensors, &mut meta);
    let entries: Vec<dhoit_runtime::tensors::Entry> = tensors
        .iter()
        .map(|(n, s, d)| dhoit_runtime::tensors::Entry::f32(n, s.clone(), d))
        .collect();
    dhoit_runtime::tensors::write(&path, &entries, meta).unwrap();
    path
}

fn expect(path: PathBuf, needle: &str) {
    let e = Mlp::load(&path).unwrap_err().to_string();
    assert!(e.contains(needle), "'{e}' should mention '{needle}'");
    assert!(e.contains(&path.display().to_string()), "{e}");
}

#[test]
fn wrong_weights_are_rejected_with_the_reason() {
    expect(
        broken("nan", |t, _| {
            t.iter_mut().find(|x| x.0 == "fc2.weight").unwrap().2[7] = f32::NAN
        }),
        "non-finite value",
    );
    expect(
        broken("shape", |t, _| {
            let x = t.iter_mut().find(|x| x.0 == "fc1.weight").unwrap();
            x.1 = vec![128, 12];
        }),
        "shape [128, 12], expected [12, 128]",
    );
    expect(
        broken("name", |t, _| t.retain(|x| x.0 != "out.bias")),
        "missing tensor 'out.bias'",
    );
    expect(
        broken("std", |_, m| {
            m.insert("input_std".into(), "[1,1,1,1,1,1,0,1,1,1,1,1]".into());
        }),
        "input_std[6]",
    );
    expect(
        broken("format", |_, m| {
            m.insert("format".into(), "other".into());
        }),
        "format 'other'",
    );
    expect(
        broken("features", |_, m| {
            m.insert("features".into(), "[\"a\"]".into());
        }),
        "features",
    );
    let garbage = temp("garbage.safetensors");
    std::fs::write(&garbage, b"not a weights file").unwrap();
    expect(garbage, "not a safetensors file");
    let e = Mlp::load(&temp("absent.safetensors"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot read"), "{e}");
}

/// The loader's errors are values a caller can match on, not only words: the kind, the tensor
/// and the position at fault.
#[test]
fn weights_errors_say_which_tensor_and_where() {
    use dhoit_runtime::tensors::FormatError;
    use dhoit_runtime::{Error, mlp::MAX_H2};
    let load = |path: PathBuf| match Mlp::load(&path) {
        Err(Error::Weights { path: p, fault }) => {
            assert_eq!(p, path);
            fault
        }
        other => panic!("expected a weights error, got {other:?}"),
    };
    let nan = broken("typed-nan", |t, _| {
        t.iter_mut().find(|x| x.0 == "fc2.weight").unwrap().2[7] = f32::NAN
    });
    assert_eq!(
        load(nan),
        FormatError::NonFinite {
            name: "fc2.weight".into(),
            index: 7
        }
    );
    let missing = broken("typed-missing", |t, _| t.retain(|x| x.0 != "out.bias"));
    assert_eq!(load(missing), FormatError::MissingTensor("out.bias".into()));
    let no_meta = broken("typed-meta", |_, m| {
        m.remove("layout");
    });
    assert_eq!(load(no_meta), FormatError::MissingMetadata("layout".into()));
    let wide = temp("typed-wide.safetensors");
    Mlp::random_sized(1, 4, MAX_H2 + 1)
        .save(&wide, &HashMap::new())
        .unwrap();
    assert!(matches!(load(wide), FormatError::Unsupported(_)));
}

/// What the library does with features that are not finite numbers: `Mlp::forward` gives what
/// its docs say (for a NaN, the network with its first hidden layer off, computed here by hand
/// from the later layers; for an infinity, the clamped input), and `check_features` refuses
/// them, naming the first by row, column and feature.
#[test]
fn features_that_are_not_numbers_give_what_forward_says_and_are_refused_by_the_check() {
    let m = Mlp::random(4);
    let mut f = [0.5f32; 12];
    f[3] = f32::NAN;
    let h2: Vec<f32> = m.b2.iter().map(|b| b.max(0.0)).collect();
    let z: f32 = h2.iter().zip(&m.w3).map(|(h, w)| h * w).sum::<f32>() + m.b3;
    let off = 1.0 / (1.0 + (-z).exp());
    assert!(
        (m.forward(&f) - off).abs() < 1e-6,
        "a NaN feature: {} against the first layer off, {off}",
        m.forward(&f)
    );
    f[3] = f32::INFINITY;
    let at_inf = m.forward(&f);
    f[3] = f32::MAX;
    assert_eq!(
        at_inf,
        m.forward(&f),
        "an infinite feature is clamped as f32::MAX is"
    );
    f[3] = f32::NAN;
    let rows = [[0.5f32; 12], f];
    assert!(dhoit_runtime::mlp::check_features(&rows[..1]).is_ok());
    let e = dhoit_runtime::mlp::check_features(&rows)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("row 1, column 3") && e.contains(dhoit_runtime::importance::FEATURE_NAMES[3]),
        "{e}"
    );
}
