//! The importance network's CPU twin: a 12-128-64-1 MLP (ReLU, ReLU, sigmoid) with input
//! standardisation, read from the weights contract. No burn here: plain loops, written like
//! the shader so the two read side by side.
//!
//! Weights file (safetensors): `fc1.weight` [12,128], `fc1.bias` [128], `fc2.weight` [128,64],
//! `fc2.bias` [64], `out.weight` [64,1], `out.bias` [1], all f32, weights stored [in, out] as
//! burn's `Linear` keeps them (row i holds input i's weights to every output). Metadata:
//! `format` = "dhoit-mlp-1", `features` (JSON list of the 12 names, in order), `input_mean` and
//! `input_std` (JSON lists of 12 numbers), `layout` = "linear-in-out".

use crate::error::{Error, Result};
use crate::importance::{FEATURE_NAMES, FEATURES};
use crate::rng::Rng;
use crate::tensors::{self, Entry};
use std::collections::HashMap;
use std::path::Path;

pub const FORMAT: &str = "dhoit-mlp-1";
pub const LAYOUT: &str = "linear-in-out";
pub const H1: usize = 128;
pub const H2: usize = 64;

#[derive(Clone, Debug, PartialEq)]
pub struct Mlp {
    /// [FEATURES][H1], row-major [in, out].
    pub w1: Vec<f32>,
    pub b1: Vec<f32>,
    /// [H1][H2].
    pub w2: Vec<f32>,
    pub b2: Vec<f32>,
    /// [H2][1].
    pub w3: Vec<f32>,
    pub b3: f32,
    pub mean: [f32; FEATURES],
    pub std: [f32; FEATURES],
}

impl Mlp {
    /// Seeded random weights (He-style scale), identity standardisation: for tests.
    pub fn random(seed: u64) -> Mlp {
        let mut rng = Rng::new(seed);
        let mut init = |n: usize, fan_in: usize| -> Vec<f32> {
            let s = (2.0 / fan_in as f32).sqrt();
            (0..n).map(|_| rng.normal() * s).collect()
        };
        Mlp {
            w1: init(FEATURES * H1, FEATURES),
            b1: init(H1, H1).iter().map(|v| v * 0.1).collect(),
            w2: init(H1 * H2, H1),
            b2: init(H2, H2).iter().map(|v| v * 0.1).collect(),
            w3: init(H2, H2),
            b3: 0.0,
            mean: [0.0; FEATURES],
            std: [1.0; FEATURES],
        }
    }

    /// The network on one feature vector: importance in (0, 1).
    pub fn forward(&self, f: &[f32; FEATURES]) -> f32 {
        let mut x = [0.0f32; FEATURES];
        for i in 0..FEATURES {
            x[i] = (f[i] - self.mean[i]) / self.std[i];
        }
        let mut h1 = [0.0f32; H1];
        for j in 0..H1 {
            let mut acc = self.b1[j];
            for i in 0..FEATURES {
                acc += x[i] * self.w1[i * H1 + j];
            }
            h1[j] = acc.max(0.0);
        }
        let mut h2 = [0.0f32; H2];
        for j in 0..H2 {
            let mut acc = self.b2[j];
            for i in 0..H1 {
                acc += h1[i] * self.w2[i * H2 + j];
            }
            h2[j] = acc.max(0.0);
        }
        let mut acc = self.b3;
        for i in 0..H2 {
            acc += h2[i] * self.w3[i];
        }
        1.0 / (1.0 + (-acc).exp())
    }

    /// Importance of every covered pixel (0 for uncovered ones).
    pub fn importance(&self, features: &[[f32; FEATURES]], counts: &[u32]) -> Vec<f32> {
        use rayon::prelude::*;
        features
            .par_iter()
            .zip(counts)
            .map(|(f, &n)| if n > 0 { self.forward(f) } else { 0.0 })
            .collect()
    }

    /// Reads and validates a weights file.
    pub fn load(path: &Path) -> Result<Mlp> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Self::from_bytes(&bytes).map_err(|message| Error::Weights {
            path: path.to_path_buf(),
            message,
        })
    }

    pub fn from_bytes(bytes: &[u8]) -> std::result::Result<Mlp, String> {
        let file = tensors::File::parse(bytes)?;
        let format = file.meta("format")?;
        if format != FORMAT {
            return Err(format!("format '{format}' is not {FORMAT}"));
        }
        let layout = file.meta("layout")?;
        if layout != LAYOUT {
            return Err(format!("layout '{layout}' is not {LAYOUT}"));
        }
        let names: Vec<String> = serde_json::from_str(file.meta("features")?)
            .map_err(|e| format!("metadata 'features': {e}"))?;
        if names != FEATURE_NAMES {
            return Err(format!(
                "features {names:?} differ from the runtime's {FEATURE_NAMES:?}"
            ));
        }
        let vec12 = |key: &str| -> std::result::Result<[f32; FEATURES], String> {
            let v: Vec<f32> = serde_json::from_str(file.meta(key)?)
                .map_err(|e| format!("metadata '{key}': {e}"))?;
            v.try_into().map_err(|v: Vec<f32>| {
                format!(
                    "metadata '{key}' has {} values, expected {FEATURES}",
                    v.len()
                )
            })
        };
        let mean = vec12("input_mean")?;
        let std = vec12("input_std")?;
        if let Some(i) = (0..FEATURES).find(|&i| !mean[i].is_finite()) {
            return Err(format!("input_mean[{i}] is not finite"));
        }
        if let Some(i) = (0..FEATURES).find(|&i| !(std[i].is_finite() && std[i] > 0.0)) {
            return Err(format!(
                "input_std[{i}] = {} is not a positive finite number",
                std[i]
            ));
        }
        let get = |name: &str, shape: &[usize]| -> std::result::Result<Vec<f32>, String> {
            let (_, v) = file.f32(name, Some(shape))?;
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(format!("tensor '{name}' has a non-finite value at {i}"));
            }
            Ok(v)
        };
        Ok(Mlp {
            w1: get("fc1.weight", &[FEATURES, H1])?,
            b1: get("fc1.bias", &[H1])?,
            w2: get("fc2.weight", &[H1, H2])?,
            b2: get("fc2.bias", &[H2])?,
            w3: get("out.weight", &[H2, 1])?,
            b3: get("out.bias", &[1])?[0],
            mean,
            std,
        })
    }

    /// Writes the weights contract (atomically); `extra` adds metadata (training config...).
    pub fn save(&self, path: &Path, extra: &HashMap<String, String>) -> Result<()> {
        let entries = [
            Entry::f32("fc1.weight", vec![FEATURES, H1], &self.w1),
            Entry::f32("fc1.bias", vec![H1], &self.b1),
            Entry::f32("fc2.weight", vec![H1, H2], &self.w2),
            Entry::f32("fc2.bias", vec![H2], &self.b2),
            Entry::f32("out.weight", vec![H2, 1], &self.w3),
            Entry::f32("out.bias", vec![1], &[self.b3]),
        ];
        let mut meta = extra.clone();
        meta.insert("format".into(), FORMAT.into());
        meta.insert("layout".into(), LAYOUT.into());
        meta.insert(
            "features".into(),
            serde_json::to_string(&FEATURE_NAMES).expect("names"),
        );
        meta.insert(
            "input_mean".into(),
            serde_json::to_string(&self.mean).expect("mean"),
        );
        meta.insert(
            "input_std".into(),
            serde_json::to_string(&self.std).expect("std"),
        );
        tensors::write(path, &entries, meta)
    }
}
