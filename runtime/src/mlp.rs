//! The importance network's CPU twin: a 12-128-64-1 MLP (ReLU, ReLU, sigmoid) with input
//! standardisation, read from the weights contract. No burn here: plain loops, written like
//! the shader so the two read side by side. Smaller hidden layers (`dhoit train --hidden`) load
//! too, up to [`MAX_PARAMETERS`], the size the GPU's uniform buffer and the budget account for.
//!
//! Weights file (safetensors): `fc1.weight` `[12,H1]`, `fc1.bias` `[H1]`, `fc2.weight` `[H1,H2]`,
//! `fc2.bias` `[H2]`, `out.weight` `[H2,1]`, `out.bias` `[1]` (H1 = 128, H2 = 64 by default), all
//! f32, weights stored [in, out] as
//! burn's `Linear` keeps them (row i holds input i's weights to every output). Metadata:
//! `format` = "dhoit-mlp-1", `features` (JSON list of the 12 names, in order), `input_mean` and
//! `input_std` (JSON lists of 12 numbers), `layout` = "linear-in-out", and `target`, what the
//! output means (see [`Target`]; files without it predate it and mean `k_over_max_k`), and
//! optionally `precision`, the [`Precision`] the network is deployed at by default (f16 and
//! f16-math files hold f32 values already rounded to binary16; without the key, f32).

use crate::error::{Error, Result};
use crate::importance::{FEATURE_NAMES, FEATURES};
use crate::rng::Rng;
use crate::tensors::{self, Entry, FormatError};
use std::collections::HashMap;
use std::path::Path;

pub const FORMAT: &str = "dhoit-mlp-1";

pub const LAYOUT: &str = "linear-in-out";
/// Default hidden layer sizes.
pub const H1: usize = 128;
pub const H2: usize = 64;
/// Most parameters the GPU's uniform holds, counted as laid out there
/// ([`uniform_parameter_count`]): the default network's.
pub const MAX_PARAMETERS: usize = uniform_parameter_count(H1, H2);
/// The largest magnitude a weight, bias or input mean may have, and the range of an input's
/// standard deviation: far beyond anything training produces, and small enough that a
/// standardised input stays far from f32's range (see [`Mlp::from_bytes`]).
pub const MAX_PARAMETER: f32 = 1e6;
pub const MAX_MEAN: f32 = 1e9;
pub const STD_RANGE: (f32, f32) = (1e-9, 1e9);

/// The most standard deviations a standardised input may lie from its mean: inputs beyond are
/// clamped to it. Far outside anything real (features stay within a few dozen), it keeps every
/// sum of a network with parameters up to [`MAX_PARAMETER`] below 1e28, so no input, however
/// extreme, overflows the network into a NaN that burn, the CPU and the GPU would each treat
/// their own way.
pub const MAX_STANDARDISED: f32 = 1e4;

/// One standardised input: `clamp((f - mean) / std, -MAX_STANDARDISED, MAX_STANDARDISED)`.
pub fn standardise(f: f32, mean: f32, std: f32) -> f32 {
    ((f - mean) / std).clamp(-MAX_STANDARDISED, MAX_STANDARDISED)
}

/// The output non-linearity: the logistic sigmoid, and 0 where the sum is not a number (inputs
/// so extreme that the sums overflowed both ways; the allocation reads 0 as "no importance").
/// The GPU pass computes the same.
pub fn squash(acc: f32) -> f32 {
    let s = 1.0 / (1.0 + (-acc).exp());
    if s.is_nan() { 0.0 } else { s }
}

/// Refuses rows of features with a value that is not a finite number, naming the first (its
/// row, column and feature): what the network would silently turn into 0 or a clamped value
/// ([`Mlp::forward`]). `Gpu::predict` runs it before anything reaches the device, as the CLI
/// does for a features file.
pub fn check_features(rows: &[[f32; FEATURES]]) -> Result<()> {
    for (r, row) in rows.iter().enumerate() {
        if let Some(c) = row.iter().position(|v| !v.is_finite()) {
            return Err(Error::Invalid(format!(
                "feature row {r}, column {c} ({}): {} is not a finite number",
                FEATURE_NAMES[c], row[c]
            )));
        }
    }
    Ok(())
}

/// Largest second hidden layer accepted (the GPU pass keeps its sums in a private array).
pub const MAX_H2: usize = 128;

pub use crate::alloc::Target;

/// Where the network's uniform holds the standardisation means, deviations and the first
/// weight matrix, in floats (after a header of h1, h2 and two unused).
pub const MLP_MEAN_AT: usize = 4;
pub const MLP_STD_AT: usize = MLP_MEAN_AT + FEATURES;
pub const MLP_W1_AT: usize = MLP_STD_AT + FEATURES;

pub const fn parameter_count(h1: usize, h2: usize) -> usize {
    FEATURES * h1 + h1 + h1 * h2 + h2 + h2 + 1
}

/// A layer's units as the GPU's uniform lays them out: padded to a multiple of four with
/// zero weights and biases, so the network pass reads four units at once (mlp.wgsl).
pub const fn padded_units(h: usize) -> usize {
    h.next_multiple_of(4)
}

/// The parameters a network of these sizes takes in the GPU's uniform: every layer padded to
/// [`padded_units`], the output bias to four (zeros add nothing to any sum). At most
/// [`MAX_PARAMETERS`] are accepted.
pub const fn uniform_parameter_count(h1: usize, h2: usize) -> usize {
    let (p1, p2) = (padded_units(h1), padded_units(h2));
    FEATURES * p1 + p1 + p1 * p2 + p2 + p2 + 4
}

/// Bytes of the GPU's weights uniform for a network of these sizes stored at `p`: the header
/// and the standardisation in f32 words ([`crate::wgsl::MLP_W1_AT`] of them), then the
/// [`uniform_parameter_count`] parameters, one f32 a word or two binary16 values a word
/// ([`Precision::half_weights`]), in whole vec4s. What [`crate::wgsl::mlp_uniform`] writes, the
/// network pass declares and DKB's budget counts ([`crate::budget::Layout::for_network`]): the
/// default network's 40,064 bytes at f32 and 20,096 at f16, a 16-8 network's 1,536 and 832.
pub const fn uniform_bytes(h1: usize, h2: usize, p: Precision) -> u64 {
    let params = uniform_parameter_count(h1, h2);
    let words = match p {
        Precision::F32 => params,
        // A multiple of four parameters: whole words.
        Precision::F16 | Precision::F16Math => params / 2,
    };
    ((MLP_W1_AT + words).div_ceil(4) * 16) as u64
}

/// Whether a covered pixel's k is forced whatever its importance, in a frame whose smallest k
/// is `lo` ([`crate::alloc::min_k`]: 1 where F covers every covered pixel): its useful cap
/// ([`crate::alloc::useful_cap`]) is lo, so every allocation gives it lo below the top tiers
/// and their k above (`n <= lo + 1`, or `lo + 2` where its two farthest fragments share one
/// colour).
pub fn forced(n: u32, pair: bool, lo: u32) -> bool {
    crate::alloc::useful_cap(n, lo, pair) <= lo
}

/// The networks dhoit ships, by their hidden layers' sizes, their weights built into the
/// library (`make train` writes the 128-64, the reference; `make nets` the others, on the same
/// data): an application deploys one with [`Mlp::shipped`], no file of its own. The smaller
/// ones cost a fraction of the 128-64's importance pass (the 16-8 about a tenth: `make trade`,
/// `make frame`) for about its accuracy at one opacity and less with materials
/// (docs/experiments.md); `dhoit fit --scene FILE` says which is good enough on a scene.
pub const SHIPPED: [(&str, &[u8]); 4] = [
    ("128-64", include_bytes!("../../data/weights.safetensors")),
    (
        "64-32",
        include_bytes!("../../data/nets/64-32/weights.safetensors"),
    ),
    (
        "32-16",
        include_bytes!("../../data/nets/32-16/weights.safetensors"),
    ),
    (
        "16-8",
        include_bytes!("../../data/nets/16-8/weights.safetensors"),
    ),
];

#[derive(Clone, Debug, PartialEq)]
pub struct Mlp {
    pub h1: usize,
    pub h2: usize,
    /// [FEATURES][H1], row-major [in, out].
    pub w1: Vec<f32>,
    pub b1: Vec<f32>,
    /// [H1][H2].
    pub w2: Vec<f32>,
    pub b2: Vec<f32>,
    /// `[H2][1]`.
    pub w3: Vec<f32>,
    pub b3: f32,
    pub mean: [f32; FEATURES],
    pub std: [f32; FEATURES],
    /// What the output means.
    pub target: Target,
    /// How the deployed network stores its weights (see [`Mlp::at_precision`]).
    pub precision: Precision,
}

/// How a deployed network stores its weights and biases, and in which precision its hidden
/// layers compute. The standardisation (means, deviations) and the output unit stay f32.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precision {
    #[default]
    F32,
    /// IEEE binary16, rounded to nearest even on the host: half the weights' bytes. The GPU
    /// unpacks them exactly, so the CPU twin (f32 arithmetic on the rounded values) stays its
    /// twin; against f32 the importance moves by at most [`F16_BOUND`] on the tests' batches.
    F16,
    /// Binary16 weights (as [`Precision::F16`]) and binary16 arithmetic in the two hidden layers
    /// (the inputs rounded to binary16 once standardised; every product and sum rounded), so a
    /// GPU with fast half precision runs two multiply-adds where f32 runs one; the output unit
    /// and the sigmoid stay f32. Needs the device's `SHADER_F16`. The twin rounds each product
    /// and each sum; a GPU may fuse them, so it is held to the twin within [`F16_MATH_GPU_BOUND`],
    /// and the twin to f32 within [`F16_MATH_BOUND`], on the tests' batches.
    F16Math,
}

/// The most the f16 network's output may differ from the f32 network's (importance in (0, 1)),
/// held by the equivalence tests on the golden, random and rendered features.
pub const F16_BOUND: f32 = 5e-3;

/// The most the f16-math network's output (its CPU twin) may differ from the f32 network's,
/// held by the equivalence tests on the golden, random and rendered features.
pub const F16_MATH_BOUND: f32 = 5e-3;

/// The most the GPU's f16-math importance may differ from its twin's (which rounds every
/// product and sum, where a GPU may fuse a multiply and an add into one rounding).
pub const F16_MATH_GPU_BOUND: f32 = 5e-3;

impl Precision {
    pub const ALL: [Precision; 3] = [Precision::F32, Precision::F16, Precision::F16Math];
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F16 => "f16",
            Precision::F16Math => "f16-math",
        }
    }

    /// Whether the weights are stored as binary16 (two to a uniform word).
    pub fn half_weights(self) -> bool {
        self != Precision::F32
    }
}

impl std::fmt::Display for Precision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Precision {
    type Err = Error;
    fn from_str(s: &str) -> Result<Precision> {
        Precision::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                Error::Invalid(format!(
                    "precision '{s}' is not offered by the importance pass (it offers f32, f16, f16-math)"
                ))
            })
    }
}

impl Mlp {
    /// Seeded random weights (He-style scale) of the default size, identity standardisation.
    pub fn random(seed: u64) -> Mlp {
        Self::random_sized(seed, H1, H2)
    }

    /// Seeded random weights with the given hidden sizes.
    pub fn random_sized(seed: u64, h1: usize, h2: usize) -> Mlp {
        let mut rng = Rng::new(seed);
        let mut init = |n: usize, fan_in: usize| -> Vec<f32> {
            let s = (2.0 / fan_in as f32).sqrt();
            (0..n).map(|_| rng.normal() * s).collect()
        };
        Mlp {
            h1,
            h2,
            w1: init(FEATURES * h1, FEATURES),
            b1: init(h1, h1).iter().map(|v| v * 0.1).collect(),
            w2: init(h1 * h2, h1),
            b2: init(h2, h2).iter().map(|v| v * 0.1).collect(),
            w3: init(h2, h2),
            b3: 0.0,
            mean: [0.0; FEATURES],
            std: [1.0; FEATURES],
            target: Target::default(),
            precision: Precision::F32,
        }
    }

    /// The network deployed at `p`: for f16 and f16-math, every weight and bias rounded to the
    /// nearest binary16 value (ties to even), which the twin then computes with in f32 (f16) or
    /// binary16 (f16-math's hidden layers), as the GPU does. A weight beyond binary16's range
    /// (65,504) is refused, naming it.
    pub fn at_precision(&self, p: Precision) -> Result<Mlp> {
        let mut m = self.clone();
        m.precision = p;
        if p == Precision::F32 {
            return Ok(m);
        }
        let round = |name: &str, v: &mut [f32]| -> Result<()> {
            for (i, x) in v.iter_mut().enumerate() {
                let h = half::f16::from_f32(*x);
                if !h.is_finite() {
                    return Err(Error::Invalid(format!(
                        "{name}[{i}] = {x} is beyond f16's range (65504): this network cannot run at f16"
                    )));
                }
                *x = h.to_f32();
            }
            Ok(())
        };
        round("fc1.weight", &mut m.w1)?;
        round("fc1.bias", &mut m.b1)?;
        round("fc2.weight", &mut m.w2)?;
        round("fc2.bias", &mut m.b2)?;
        round("out.weight", &mut m.w3)?;
        round("out.bias", std::slice::from_mut(&mut m.b3))?;
        Ok(m)
    }

    /// Bytes of this network's weights on the GPU, at its precision ([`uniform_bytes`]).
    pub fn uniform_bytes(&self) -> u64 {
        uniform_bytes(self.h1, self.h2, self.precision)
    }

    /// Weights and biases in the uniform's order (fc1 weight and bias, fc2 weight and bias, out
    /// weight and bias).
    pub fn parameters(&self) -> impl Iterator<Item = f32> + '_ {
        self.w1
            .iter()
            .chain(&self.b1)
            .chain(&self.w2)
            .chain(&self.b2)
            .chain(&self.w3)
            .chain(std::iter::once(&self.b3))
            .copied()
    }

    /// The network on one feature vector: importance in (0, 1). A feature that is not a
    /// number makes every first hidden unit's sum one, which the ReLU (`max(0)`) turns into 0:
    /// the output is then the network's with the first hidden layer off, whatever the other
    /// features (the GPU need not do the same); an infinite feature is clamped as any other out
    /// of range one. Callers with features from outside (a file, another renderer) check them
    /// first: [`check_features`].
    pub fn forward(&self, f: &[f32; FEATURES]) -> f32 {
        self.forward_with(f, &mut Vec::new())
    }

    /// [`Mlp::forward`] with a reusable scratch buffer for the hidden activations.
    pub fn forward_with(&self, f: &[f32; FEATURES], scratch: &mut Vec<f32>) -> f32 {
        if self.precision == Precision::F16Math {
            self.forward_rounded(f, scratch, |v| half::f16::from_f32(v).to_f32())
        } else {
            self.forward_rounded(f, scratch, |v| v)
        }
    }

    /// The forward with every standardised input, weight, product and sum of the hidden layers
    /// passed through `round`: as is at f32 and f16 (whose weights are already binary16);
    /// rounded to binary16 at [`Precision::F16Math`] (overflowing to an infinity as binary16
    /// does), the twin of its pass (gpu::pipelines::unrolled_forward), where a GPU may fuse a
    /// product and a sum. The output unit is f32 either way.
    // Indexed loops on purpose: the twin of mlp.wgsl's mlp_forward, operation for operation
    // and in the same order of sums, so the GPU can be held to it within float rounding.
    #[allow(clippy::needless_range_loop)]
    fn forward_rounded(
        &self,
        f: &[f32; FEATURES],
        scratch: &mut Vec<f32>,
        round: impl Fn(f32) -> f32,
    ) -> f32 {
        let (n1, n2) = (self.h1, self.h2);
        scratch.clear();
        scratch.resize(n1 + n2, 0.0);
        let (h1, h2) = scratch.split_at_mut(n1);
        let mut x = [0.0f32; FEATURES];
        for i in 0..FEATURES {
            x[i] = round(standardise(f[i], self.mean[i], self.std[i]));
        }
        for j in 0..n1 {
            let mut acc = round(self.b1[j]);
            for i in 0..FEATURES {
                acc = round(acc + round(x[i] * round(self.w1[i * n1 + j])));
            }
            h1[j] = acc.max(0.0);
        }
        for j in 0..n2 {
            let mut acc = round(self.b2[j]);
            for i in 0..n1 {
                acc = round(acc + round(h1[i] * round(self.w2[i * n2 + j])));
            }
            h2[j] = acc.max(0.0);
        }
        let mut acc = self.b3;
        for i in 0..n2 {
            acc += h2[i] * self.w3[i];
        }
        squash(acc)
    }

    /// Importance of every covered pixel (0 for uncovered ones).
    pub fn importance(&self, features: &[[f32; FEATURES]], counts: &[u32]) -> Vec<f32> {
        use rayon::prelude::*;
        features
            .par_iter()
            .zip(counts)
            .map_init(Vec::new, |scratch, (f, &n)| {
                if n > 0 {
                    self.forward_with(f, scratch)
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// DKB's allocation of `f` slots: the network's importance, marked where a pixel's two
    /// farthest fragments share one colour (`pairs`, [`crate::importance::tail_pair`]; such a
    /// pixel can use a slot fewer), fitted to the budget by a scale
    /// ([`crate::alloc::water_fill`]) or a level ([`crate::alloc::level_fill`]).
    pub fn allocate(
        &self,
        features: &[[f32; FEATURES]],
        counts: &[u32],
        pairs: &[bool],
        f: u64,
    ) -> Vec<u32> {
        let imp = self.dkb_importance(features, counts, pairs, f);
        crate::alloc::allocate(&imp, counts, self.target, f)
    }

    /// DKB's allocation of `f` slots as its frames make it, their tails pooled: every pixel a
    /// pair (`alloc::allocate_pooled`: a pixel left out by no more than a tail's two fragments
    /// keeps them all, `shared::stored_k`), so no farthest key is gathered, and the importance
    /// of [`Mlp::dkb_importance_pooled`].
    pub fn allocate_pooled(
        &self,
        features: &[[f32; FEATURES]],
        counts: &[u32],
        f: u64,
    ) -> Vec<u32> {
        let imp = self.dkb_importance_pooled(features, counts, f);
        crate::alloc::allocate_pooled(&imp, counts, self.target, f)
    }

    /// DKB's importance map as its GPU frames write it, their tails pooled: every pixel with a
    /// record (more than `shared::TAIL_WORDS` fragments) marked as a pair, its importance the
    /// network's output or 0 where forced (at most lo + 2 fragments: [`forced`]); 0 unmarked
    /// at a pixel without one (nothing gathered: it keeps all it has whatever its k) and
    /// wherever [`Mlp::dkb_importance`] gives it.
    pub fn dkb_importance_pooled(
        &self,
        features: &[[f32; FEATURES]],
        counts: &[u32],
        f: u64,
    ) -> Vec<f32> {
        let pairs: Vec<bool> = counts
            .iter()
            .map(|&n| n > crate::shared::TAIL_WORDS)
            .collect();
        let mut imp = self.dkb_importance(features, counts, &pairs, f);
        for (i, &n) in imp.iter_mut().zip(counts) {
            if n <= crate::shared::TAIL_WORDS {
                *i = 0.0;
            }
        }
        imp
    }

    /// [`Mlp::dkb_importance_pooled`] for a frame that gathers its statistics with its count
    /// (`gpu::Tuning::two_pass_dkb`), for the pixels the frame before marked
    /// ([`crate::importance::record_marks`] of its counts: `recorded` says which of this frame's
    /// pixels have a record, as many as its pool held). A pixel of more than
    /// `shared::TAIL_WORDS` fragments without one takes, where the frame truncates, the mean of
    /// the requests the network gave the recorded pixels it decided (summed in the fixed point
    /// of `shared::request_units`, as importance_dkb.wgsl's gather takes it), with the pair
    /// mark; where it decided none, the least weight, 0 with the pair mark. Where every
    /// deeper pixel has a record, it is [`Mlp::dkb_importance_pooled`] itself.
    pub fn dkb_importance_recorded(
        &self,
        features: &[[f32; FEATURES]],
        counts: &[u32],
        f: u64,
        recorded: &[bool],
    ) -> Vec<f32> {
        let pooled = self.dkb_importance_pooled(features, counts, f);
        let all_fit = f >= counts.iter().map(|&n| n as u64).sum::<u64>();
        let lo = crate::alloc::min_k(counts, f);
        // The requests the network gave (the recorded pixels it decided: not forced).
        let (mut sum, mut decided) = (0u64, 0u32);
        for (p, &n) in counts.iter().enumerate() {
            if recorded[p] && !all_fit && n > crate::shared::TAIL_WORDS && !forced(n, true, lo) {
                let v = f32::from_bits(pooled[p].to_bits() & !crate::alloc::PAIR_BIT);
                sum += crate::shared::request_units(v) as u64;
                decided += 1;
            }
        }
        let unit = (1u32 << crate::shared::REQUEST_SUM_BITS) as f32;
        let mean = match decided {
            0 => 0.0,
            d => sum as f32 / d as f32 / unit,
        };
        let mut imp = pooled;
        for ((i, &n), &r) in imp.iter_mut().zip(counts).zip(recorded) {
            if !r && !all_fit && n > crate::shared::TAIL_WORDS {
                *i = crate::alloc::mark_pair(mean, true);
            }
        }
        imp
    }

    /// DKB's importance map, as the GPU's importance pass writes it: the network's output with
    /// the pair mark, and 0 wherever k does not depend on it, without running the network
    /// there: with the mark at a pixel whose useful cap is the frame's lo ([`forced`]);
    /// unmarked at an empty pixel and at every pixel of a frame whose budget holds all its
    /// fragments (k = n: the GPU does not gather that frame's features at all, so it knows no
    /// pair).
    pub fn dkb_importance(
        &self,
        features: &[[f32; FEATURES]],
        counts: &[u32],
        pairs: &[bool],
        f: u64,
    ) -> Vec<f32> {
        use rayon::prelude::*;
        let all_fit = f >= counts.iter().map(|&n| n as u64).sum::<u64>();
        let lo = crate::alloc::min_k(counts, f);
        features
            .par_iter()
            .zip(counts)
            .zip(pairs)
            .map_init(Vec::new, |scratch, ((x, &n), &pair)| {
                if n == 0 || all_fit {
                    return 0.0;
                }
                let i = if forced(n, pair, lo) {
                    0.0
                } else {
                    self.forward_with(x, scratch)
                };
                crate::alloc::mark_pair(i, pair)
            })
            .collect()
    }

    /// Reads and validates a weights file: a missing tensor, a wrong shape or a non-finite
    /// value is an error naming it.
    ///
    /// ```
    /// use dhoit_runtime::mlp::Mlp;
    /// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/weights.safetensors");
    /// let m = Mlp::load(path.as_ref())?;
    /// assert_eq!((m.h1, m.h2), (128, 64));
    /// // One pixel's 12 features to its request, in (0, 1).
    /// let r = m.forward(&[0.5; 12]);
    /// assert!(r > 0.0 && r < 1.0);
    /// assert!(Mlp::load("no/such/weights.safetensors".as_ref()).is_err());
    /// # Ok::<(), dhoit_runtime::Error>(())
    /// ```
    pub fn load(path: &Path) -> Result<Mlp> {
        let bytes = std::fs::read(path).map_err(|e| Error::read(path, e))?;
        Self::from_bytes(&bytes).map_err(|fault| Error::Weights {
            path: path.to_path_buf(),
            fault,
        })
    }

    /// The shipped network `name` ([`SHIPPED`]: "128-64", the reference, "64-32", "32-16" or
    /// "16-8"), or an error naming the shipped ones.
    ///
    /// ```
    /// use dhoit_runtime::mlp::Mlp;
    /// let small = Mlp::shipped("16-8")?;
    /// assert_eq!((small.h1, small.h2), (16, 8));
    /// let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/weights.safetensors");
    /// assert_eq!(Mlp::shipped("128-64")?, Mlp::load(file.as_ref())?);
    /// assert!(Mlp::shipped("8-4").unwrap_err().to_string().contains("16-8"));
    /// # Ok::<(), dhoit_runtime::Error>(())
    /// ```
    pub fn shipped(name: &str) -> Result<Mlp> {
        let Some((_, bytes)) = SHIPPED.iter().find(|(n, _)| *n == name) else {
            let names: Vec<&str> = SHIPPED.iter().map(|(n, _)| *n).collect();
            return Err(Error::Invalid(format!(
                "no shipped network '{name}': {}",
                names.join(", ")
            )));
        };
        Self::from_bytes(bytes).map_err(|fault| Error::Weights {
            path: std::path::PathBuf::from(format!("the shipped {name} network")),
            fault,
        })
    }

    pub fn from_bytes(bytes: &[u8]) -> std::result::Result<Mlp, FormatError> {
        use FormatError::{Contract, Metadata};
        let file = tensors::File::parse(bytes)?;
        let format = file.meta("format")?;
        if format != FORMAT {
            return Err(Contract(format!("format '{format}' is not {FORMAT}")));
        }
        let layout = file.meta("layout")?;
        if layout != LAYOUT {
            return Err(Contract(format!("layout '{layout}' is not {LAYOUT}")));
        }
        let names: Vec<String> = file.meta_json("features")?;
        if names != FEATURE_NAMES {
            return Err(Contract(format!(
                "features {names:?} differ from the runtime's {FEATURE_NAMES:?}"
            )));
        }
        let vec12 = |key: &str| -> std::result::Result<[f32; FEATURES], FormatError> {
            let v: Vec<f32> = file.meta_json(key)?;
            v.try_into().map_err(|v: Vec<f32>| Metadata {
                key: key.into(),
                message: format!("{} values, expected {FEATURES}", v.len()),
            })
        };
        let target = match file.metadata.get("target") {
            None => Target::RelativeK,
            Some(t) => Target::parse(t).ok_or_else(|| Metadata {
                key: "target".into(),
                message: format!("'{t}', expected k_over_n, k_over_max_k or slot_request"),
            })?,
        };
        // The precision the network is meant to run at (`dhoit fit` chooses one); files without
        // it run at f32 unless the user says otherwise.
        let precision = match file.metadata.get("precision") {
            None => Precision::F32,
            Some(p) => p.parse::<Precision>().map_err(|_| Metadata {
                key: "precision".into(),
                message: format!("'{p}', expected f32, f16 or f16-math"),
            })?,
        };
        let mean = vec12("input_mean")?;
        let std = vec12("input_std")?;
        check_standardisation(&mean, &std)?;
        let get = |name: &str, shape: &[usize]| -> std::result::Result<Vec<f32>, FormatError> {
            let (_, v) = file.f32(name, Some(shape))?;
            if let Some(index) = v.iter().position(|x| !x.is_finite()) {
                return Err(FormatError::NonFinite {
                    name: name.into(),
                    index,
                });
            }
            if let Some(i) = v.iter().position(|x| x.abs() > MAX_PARAMETER) {
                return Err(Contract(format!(
                    "tensor '{name}' has {} at {i}, beyond the largest magnitude accepted ({MAX_PARAMETER:e})",
                    v[i]
                )));
            }
            Ok(v)
        };
        let (h1, h2) = hidden_sizes(&file)?;
        Mlp {
            h1,
            h2,
            w1: get("fc1.weight", &[FEATURES, h1])?,
            b1: get("fc1.bias", &[h1])?,
            w2: get("fc2.weight", &[h1, h2])?,
            b2: get("fc2.bias", &[h2])?,
            w3: get("out.weight", &[h2, 1])?,
            b3: get("out.bias", &[1])?[0],
            mean,
            std,
            target,
            precision: Precision::F32,
        }
        .at_precision(precision)
        .map_err(|e| Metadata {
            key: "precision".into(),
            message: e.to_string(),
        })
    }

    /// Writes the weights contract (atomically); `extra` adds metadata (training config...).
    pub fn save(&self, path: &Path, extra: &HashMap<String, String>) -> Result<()> {
        let (h1, h2) = (self.h1, self.h2);
        let entries = [
            Entry::f32("fc1.weight", vec![FEATURES, h1], &self.w1),
            Entry::f32("fc1.bias", vec![h1], &self.b1),
            Entry::f32("fc2.weight", vec![h1, h2], &self.w2),
            Entry::f32("fc2.bias", vec![h2], &self.b2),
            Entry::f32("out.weight", vec![h2, 1], &self.w3),
            Entry::f32("out.bias", vec![1], &[self.b3]),
        ];
        let mut meta = extra.clone();
        meta.insert("format".into(), FORMAT.into());
        meta.insert("layout".into(), LAYOUT.into());
        meta.insert("target".into(), self.target.name().into());
        // The weights are stored as f32 either way (rounded to binary16 already where the
        // precision stores them so); the key says how to deploy them.
        if self.precision != Precision::F32 {
            meta.insert("precision".into(), self.precision.name().into());
        } else {
            meta.remove("precision");
        }
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

/// The standardisation a weights file carries: every mean finite and at most [`MAX_MEAN`] in
/// magnitude, every deviation within [`STD_RANGE`].
fn check_standardisation(
    mean: &[f32; FEATURES],
    std: &[f32; FEATURES],
) -> std::result::Result<(), FormatError> {
    if let Some(i) = (0..FEATURES).find(|&i| !(mean[i].is_finite() && mean[i].abs() <= MAX_MEAN)) {
        return Err(FormatError::Contract(format!(
            "input_mean[{i}] = {} is not a finite number of magnitude at most {MAX_MEAN:e}",
            mean[i]
        )));
    }
    let (lo, hi) = STD_RANGE;
    if let Some(i) = (0..FEATURES).find(|&i| !(lo..=hi).contains(&std[i])) {
        return Err(FormatError::Contract(format!(
            "input_std[{i}] = {} is not in [{lo:e}, {hi:e}]",
            std[i]
        )));
    }
    Ok(())
}

/// The hidden sizes of a weights file, from its first two weight matrices (every other shape
/// must agree), refused where the GPU's uniform buffer cannot hold them.
fn hidden_sizes(file: &tensors::File) -> std::result::Result<(usize, usize), FormatError> {
    use FormatError::{Shape, Unsupported};
    let s1 = file.tensor("fc1.weight")?.shape().to_vec();
    let s2 = file.tensor("fc2.weight")?.shape().to_vec();
    let (h1, h2) = match (&s1[..], &s2[..]) {
        ([FEATURES, a], [b, c]) if a == b && *a > 0 && *c > 0 => (*a, *c),
        ([FEATURES, _], _) => {
            return Err(Shape {
                name: "fc2.weight".into(),
                found: s2,
                expected: format!("[{}, H2]", s1[1]),
            });
        }
        _ => {
            return Err(Shape {
                name: "fc1.weight".into(),
                found: s1,
                expected: format!("[{FEATURES}, {H1}]"),
            });
        }
    };
    if h2 > MAX_H2 {
        return Err(Unsupported(format!(
            "the second hidden layer has {h2} units; at most {MAX_H2} are supported"
        )));
    }
    if uniform_parameter_count(h1, h2) > MAX_PARAMETERS {
        return Err(Unsupported(format!(
            "hidden sizes {h1},{h2} take {} parameters on the GPU (layers padded to multiples of 4 units); at most {MAX_PARAMETERS} fit its uniform buffer",
            uniform_parameter_count(h1, h2)
        )));
    }
    Ok((h1, h2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::alloc::{self, Target};
    use crate::rng::Rng;

    /// What the importance pass skips is what no allocation looks at: the k of a forced pixel
    /// (useful cap lo, the frame's smallest k: 0 at F below the covered pixels, else 1), and
    /// every k of a frame whose budget holds all its fragments, are the same whatever
    /// importance they are given, for every target and budget.
    #[test]
    fn skipped_pixels_get_the_same_k_whatever_their_importance() {
        let mut rng = Rng::new(11);
        let pixels = 4000;
        let counts: Vec<u32> = (0..pixels)
            .map(|_| match rng.f32() {
                x if x < 0.2 => 0,
                x if x < 0.5 => 1,
                x if x < 0.6 => 2,
                x if x < 0.7 => 3,
                x => (x * 40.0) as u32,
            })
            .collect();
        let pairs: Vec<bool> = counts.iter().map(|&n| n >= 2 && rng.f32() < 0.3).collect();
        let covered = counts.iter().filter(|&&n| n > 0).count() as u64;
        let total: u64 = counts.iter().map(|&n| n as u64).sum();
        // Forced where lo is 0 (n 2, a pair) and only where it is 1 (n 2, not; n 3, a pair).
        for (n, pair) in [(2, true), (2, false), (3, true)] {
            assert!(
                counts
                    .iter()
                    .zip(&pairs)
                    .any(|(&c, &p)| c == n && p == pair)
            );
        }
        for target in [
            Target::RelativeK,
            Target::ShareOfFragments,
            Target::SlotRequest,
        ] {
            for f in [covered / 2, covered, total / 3, total - 1, total, total + 7] {
                let all_fit = f >= total;
                let lo = alloc::min_k(&counts, f);
                let imp: Vec<f32> = pairs
                    .iter()
                    .map(|&p| alloc::mark_pair(rng.f32() * 1.5, p))
                    .collect();
                let skipped: Vec<f32> = imp
                    .iter()
                    .zip(&counts)
                    .zip(&pairs)
                    .map(|((&i, &n), &p)| {
                        if n == 0 || all_fit || forced(n, p, lo) {
                            alloc::mark_pair(0.0, p)
                        } else {
                            i
                        }
                    })
                    .collect();
                assert_eq!(
                    alloc::allocate(&imp, &counts, target, f),
                    alloc::allocate(&skipped, &counts, target, f),
                    "{target:?}, F = {f}"
                );
            }
        }
    }

    /// A frame that gathers its statistics with its count: every deeper pixel recorded, its
    /// importance is the pooled one's; one the frame before left unmarked takes, by hand, the
    /// mean of the requests the network gave the recorded pixels it decided, with the pair
    /// mark, or where it decided none the least weight (0 with the pair mark) where the frame
    /// truncates, 0 where it keeps every fragment; a pixel of two or fewer gets 0 whether
    /// marked or not.
    #[test]
    fn unrecorded_deeper_pixels_take_the_mean_request_or_the_least_weight() {
        let m = Mlp::random(3);
        let counts = [0u32, 1, 2, 3, 5, 9, 4, 7];
        let mut rng = Rng::new(5);
        let features: Vec<[f32; FEATURES]> = counts
            .iter()
            .map(|_| std::array::from_fn(|_| rng.f32()))
            .collect();
        let f = 10;
        let pooled = m.dkb_importance_pooled(&features, &counts, f);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
        let all = m.dkb_importance_recorded(&features, &counts, f, &[true; 8]);
        assert_eq!(bits(&all), bits(&pooled));
        let some = [false, false, true, false, true, false, true, true];
        let got = m.dkb_importance_recorded(&features, &counts, f, &some);
        let least = alloc::mark_pair(0.0, true).to_bits();
        // lo is 1 (F covers the 7 covered pixels): pixel 3 (n 3) is forced, so the network
        // decides the recorded 4 (n 5), 6 (n 4) and 7 (n 7); their requests in 2^-20 units.
        let request = |q: usize| f32::from_bits(pooled[q].to_bits() & !alloc::PAIR_BIT);
        let units: u64 = [4, 6, 7]
            .iter()
            .map(|&q| (request(q) as f64 * 1048576.0).round() as u64)
            .sum();
        let mean = units as f32 / 3.0 / 1048576.0;
        assert!(mean > 0.0);
        for (p, &n) in counts.iter().enumerate() {
            let want = match (some[p], n > crate::shared::TAIL_WORDS) {
                (_, false) => 0,
                (true, true) => pooled[p].to_bits(),
                (false, true) => alloc::mark_pair(mean, true).to_bits(),
            };
            assert_eq!(got[p].to_bits(), want, "pixel {p} of {n}");
        }
        // Nothing recorded, nothing decided: the least weight.
        let got = m.dkb_importance_recorded(&features, &counts, f, &[false; 8]);
        assert!(got.iter().zip(&counts).all(|(i, &n)| i.to_bits()
            == if n > crate::shared::TAIL_WORDS {
                least
            } else {
                0
            }));
        // Every fragment kept: 0 unmarked, recorded or not.
        let total: u64 = counts.iter().map(|&n| n as u64).sum();
        let kept = m.dkb_importance_recorded(&features, &counts, total, &some);
        assert!(kept.iter().all(|i| i.to_bits() == 0));
    }

    #[test]
    fn forced_means_no_useful_slot() {
        // Where a covered pixel may get no slot (lo 0), and where each gets one.
        assert!(forced(1, false, 0));
        assert!(forced(2, true, 0));
        assert!(!forced(2, false, 0));
        assert!(!forced(3, true, 0));
        assert!(forced(0, false, 0));
        assert!(forced(2, false, 1));
        assert!(forced(3, true, 1));
        assert!(!forced(3, false, 1));
        assert!(!forced(4, true, 1));
    }
}
