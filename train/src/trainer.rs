//! The training loop: standardisation, the loss + L1 (first hidden layer's weights) + L2
//! (second hidden layer's weights), SGD on shuffled mini-batches, per-epoch train and validation
//! loss, and the best epoch kept.
//!
//! Losses ([`Loss`]): the paper's MSE on `k* / max k*`; MSE on `k* / n`; and the regret, what
//! the k the network asks for costs in the image. With `r` the output and n the pixel's
//! fragments, the network asks for `k = r n` slots; the loss is the pixel's Lagrangian regret
//! `R(k)` (dataset docs) interpolated linearly between the stored integers `k* - D ..= k* + D`
//! and extended linearly beyond, divided by the frame's optimal error. Its mean over a frame's
//! pixels is `(E / E* - 1)` over the pixel count: the loss is the image error above the
//! optimum, and its minimum for each pixel is at k*.
//!
//! Reproducible: initial weights and batch order come from the seed through the runtime's own
//! generator, not burn's global one.

use crate::dataset::{REGRET_HALF, REGRET_WINDOW, Samples};
use crate::model::{ImportanceNet, cpu_device, predict, standardised};
use crate::step;
use crate::{Error, Result};
use burn::grad_clipping::GradientClippingConfig;
use burn::optim::momentum::MomentumConfig;
use burn::optim::{GradientsParams, SgdConfig};
use burn::prelude::*;
use burn::tensor::TensorData;
use burn::tensor::activation::relu;
use dhoit_runtime::importance::FEATURES;
use dhoit_runtime::mlp::{self, Mlp, Target};
use dhoit_runtime::rng::Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// What the network is trained to minimise.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Loss {
    /// The paper's: MSE on `k* / max_q k*(q)`; the output is a proportional importance.
    MseRelative,
    /// MSE on `k* / n`; the output is the share of the pixel's fragments to keep.
    MseShare,
    /// What the k the network's frame gets costs in the image above the optimum (the module
    /// docs); the output is the share of the pixel's fragments to keep, and a frame's asks are
    /// fitted to its budget by a common scale, as the runtime's water-filling does.
    Regret,
    /// The regret with the output a slot request (256 r), fitted to the budget by a common
    /// level, as the runtime's additive allocation does. The default: with opacity a, a
    /// pixel's error falls by about `(1 - a)^2` a slot, so the optimal k of every pixel moves
    /// by the same number of slots when the budget's price per slot changes, which is what
    /// one level fits; it measured 4x closer to the optimum than the share (README).
    #[default]
    RegretLevel,
}

impl std::str::FromStr for Loss {
    type Err = crate::Error;
    fn from_str(s: &str) -> crate::Result<Loss> {
        Loss::parse(s).ok_or_else(|| {
            let names: Vec<_> = Loss::ALL.iter().map(|l| l.name()).collect();
            crate::Error::Config(format!(
                "unknown loss '{s}': expected one of {}",
                names.join(", ")
            ))
        })
    }
}

impl Loss {
    pub const ALL: [Loss; 4] = [
        Loss::MseRelative,
        Loss::MseShare,
        Loss::Regret,
        Loss::RegretLevel,
    ];
    pub fn name(self) -> &'static str {
        match self {
            Loss::MseRelative => "mse-relative",
            Loss::MseShare => "mse-share",
            Loss::Regret => "regret",
            Loss::RegretLevel => "regret-level",
        }
    }
    fn regret(self) -> bool {
        matches!(self, Loss::Regret | Loss::RegretLevel)
    }
    pub fn parse(s: &str) -> Option<Loss> {
        Self::ALL.into_iter().find(|l| l.name() == s)
    }
    /// What the trained network's output means.
    pub fn target(self) -> Target {
        match self {
            Loss::MseRelative => Target::RelativeK,
            Loss::MseShare | Loss::Regret => Target::ShareOfFragments,
            Loss::RegretLevel => Target::SlotRequest,
        }
    }
}

/// Training settings (saved as config.json beside the weights).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// What is minimised.
    #[serde(default)]
    pub loss: Loss,
    /// Gradient norm clipping (0: none).
    #[serde(default)]
    pub clip: f64,
    pub epochs: usize,
    /// SGD learning rate (0.001 in the paper).
    pub lr: f64,
    /// Mini-batch size (512 in the paper).
    pub batch: usize,
    /// L1 coefficient on the first hidden layer's weights.
    pub l1: f64,
    /// L2 coefficient on the second hidden layer's weights.
    pub l2: f64,
    /// Hidden layer sizes (128, 64 in the paper).
    pub hidden: [usize; 2],
    /// SGD momentum. The paper uses plain SGD (0); 0.9 reached a lower loss in the same epochs
    /// and beat VKB on held-out scenes where plain SGD did not (README).
    pub momentum: f64,
    /// Cosine decay of the learning rate over the run, from `lr` to `lr / 20`. A constant rate
    /// left the validation loss jumping by a third from epoch to epoch; the decay settles it.
    #[serde(default)]
    pub cosine: bool,
    pub seed: u64,
    /// Scenes held out for validation (never trained on).
    pub validation_scenes: Vec<String>,
}

impl TrainConfig {
    /// The rules a configuration must follow whatever the data (sizes, rates, coefficients):
    /// checked before a dataset is loaded or generated, so a bad value costs nothing.
    pub fn check(&self) -> Result<()> {
        if self.epochs == 0 || self.batch == 0 {
            return Err(Error::Config("epochs and batch must be positive".into()));
        }
        let non_negative = |v: f64| v.is_finite() && v >= 0.0;
        if !(self.lr.is_finite() && self.lr > 0.0 && non_negative(self.l1) && non_negative(self.l2))
        {
            return Err(Error::Config(format!(
                "lr {} must be a positive number, l1 {} and l2 {} finite and non-negative",
                self.lr, self.l1, self.l2
            )));
        }
        if !non_negative(self.clip) {
            return Err(Error::Config("clip must be a non-negative number".into()));
        }
        if !(0.0..1.0).contains(&self.momentum) {
            return Err(Error::Config(format!(
                "momentum {} must be in [0, 1)",
                self.momentum
            )));
        }
        let [h1, h2] = self.hidden;
        if h1 == 0
            || h2 == 0
            || h2 > mlp::MAX_H2
            || mlp::uniform_parameter_count(h1, h2) > mlp::MAX_PARAMETERS
        {
            return Err(Error::Config(format!(
                "hidden sizes {h1},{h2}: need positive sizes, H2 at most {}, and at most {} parameters with each layer padded to a multiple of 4 units, as the GPU lays them out (128,64 has that many)",
                mlp::MAX_H2,
                mlp::MAX_PARAMETERS
            )));
        }
        Ok(())
    }
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            loss: Loss::default(),
            clip: 1.0,
            epochs: 40,
            lr: 3e-3,
            batch: 512,
            l1: 1e-6,
            l2: 1e-5,
            hidden: [mlp::H1, mlp::H2],
            momentum: 0.9,
            cosine: true,
            seed: 0,
            validation_scenes: crate::dataset::default_validation(),
        }
    }
}

impl TrainConfig {
    /// The learning rate once `done` (0 to 1) of the run's steps are taken.
    pub fn learning_rate(&self, done: f64) -> f64 {
        if self.cosine {
            let c = 0.5 * (1.0 + (std::f64::consts::PI * done.clamp(0.0, 1.0)).cos());
            self.lr * (0.05 + 0.95 * c)
        } else {
            self.lr
        }
    }
}

/// One epoch's figures.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Epoch {
    pub epoch: usize,
    /// Mean loss over the epoch's batches (regularisation excluded).
    pub train_loss: f64,
    /// Mean of the regularisation terms over the epoch's batches.
    pub train_reg: f64,
    /// The loss on the held-out scenes (on the training set when none are held out).
    pub validation_loss: f64,
    pub seconds: f64,
}

/// What training produced.
#[derive(Clone, Debug)]
pub struct Trained {
    /// The best epoch's weights, with the standardisation.
    pub mlp: Mlp,
    pub best_epoch: usize,
    pub history: Vec<Epoch>,
    pub train_samples: usize,
    pub validation_samples: usize,
    pub seconds: f64,
    /// Training samples per second over the whole run.
    pub samples_per_second: f64,
}

/// Mean and standard deviation of each feature (std floored so constant features stay finite).
pub fn standardisation(rows: &[[f32; FEATURES]]) -> ([f32; FEATURES], [f32; FEATURES]) {
    let n = rows.len().max(1) as f64;
    let mut mean = [0.0f64; FEATURES];
    for r in rows {
        for i in 0..FEATURES {
            mean[i] += r[i] as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n);
    let mut var = [0.0f64; FEATURES];
    for r in rows {
        for i in 0..FEATURES {
            var[i] += (r[i] as f64 - mean[i]).powi(2);
        }
    }
    let std = var.map(|v| {
        let s = (v / n).sqrt();
        if s > 1e-12 { s as f32 } else { 1.0 }
    });
    (mean.map(|m| m as f32), std)
}

/// The loss of one batch: `(mse + l1 sum|W1| + l2 sum W2^2, mse, regularisation)`.
pub fn loss(
    net: &ImportanceNet,
    x: Tensor<2>,
    y: Tensor<2>,
    l1: f64,
    l2: f64,
) -> (Tensor<1>, Tensor<1>, Tensor<1>) {
    let pred = net.forward(x);
    let mse = (pred - y).square().mean();
    let reg = regularisation(net, l1, l2);
    (mse.clone() + reg.clone(), mse, reg)
}

/// The regularisation terms of a network: `l1 sum|W1| + l2 sum W2^2`.
fn regularisation(net: &ImportanceNet, l1: f64, l2: f64) -> Tensor<1> {
    net.fc1.weight.val().abs().sum().mul_scalar(l1)
        + net.fc2.weight.val().square().sum().mul_scalar(l2)
}

/// A frame's batch with what the regret loss needs: n and k* [B,1], the regret windows [B,W],
/// the frame's smallest k.
pub struct RegretBatch {
    pub count: Tensor<2>,
    pub k_opt: Tensor<2>,
    pub regret: Tensor<2>,
    pub lo: f32,
    /// n and k* as numbers, and the pixels whose two farthest fragments share one colour, for
    /// the fit.
    pub counts: Vec<f32>,
    pub pairs: Vec<bool>,
    pub k_opts: Vec<f32>,
    /// The share of the frame's pixels sampled.
    pub share: f64,
}

/// The slots a pixel asks for, from the network's output: `r n` (a share of its fragments) or
/// `256 r` (a slot request).
fn asks(loss: Loss, r: Tensor<2>, count: Tensor<2>) -> Tensor<2> {
    match loss {
        Loss::RegretLevel => r.mul_scalar(dhoit_runtime::alloc::REQUEST_SLOTS),
        _ => r * count,
    }
}

/// What one unit of the network's output asks for in a pixel of `n` fragments: 256 slots (a
/// slot request) or `n` (a share of its fragments), as [`asks`] has it on tensors.
fn ask_scale(loss: Loss, n: f32) -> f32 {
    match loss {
        Loss::RegretLevel => dhoit_runtime::alloc::REQUEST_SLOTS,
        _ => n,
    }
}

/// The most slots a pixel of `n` fragments can use (`alloc::useful_cap`), as a number.
fn useful_cap(n: f32, lo: f32, pair: bool) -> f64 {
    dhoit_runtime::alloc::useful_cap(n as u32, lo as u32, pair) as f64
}

/// The frame's fit of asks `c` to the budget `sum k*`, as the runtime's allocation does it
/// (continuously): the scale s with `sum clamp(s c, lo, cap) = sum k*`, or the level L with
/// `sum clamp(c - L, lo, cap) = sum k*`, cap the most slots a pixel can use
/// (`alloc::useful_cap`). Returns s, or -L.
pub fn fit(additive: bool, c: &[f32], n: &[f32], pairs: &[bool], k_opt: &[f32], lo: f32) -> f64 {
    fit_capped(additive, c, &caps(n, pairs, lo), k_opt, lo)
}

/// The most slots each pixel can use (`alloc::useful_cap`), as numbers.
fn caps(n: &[f32], pairs: &[bool], lo: f32) -> Vec<f64> {
    n.iter()
        .zip(pairs)
        .map(|(&n, &pair)| useful_cap(n, lo, pair))
        .collect()
}

/// [`fit`] with the pixels' caps ([`caps`]) given.
fn fit_capped(additive: bool, c: &[f32], caps: &[f64], k_opt: &[f32], lo: f32) -> f64 {
    let target: f64 = k_opt.iter().map(|&k| k as f64).sum();
    let total = |x: f64| -> f64 {
        c.iter()
            .zip(caps)
            .map(|(&c, &cap)| {
                let k = if additive { c as f64 + x } else { c as f64 * x };
                k.clamp(lo as f64, cap)
            })
            .sum()
    };
    // Bisection on the shift x (increasing totals): the scale in log space.
    let (mut a, mut b) = if additive {
        (-1e6f64, 1e6f64)
    } else {
        (-40.0f64, 40.0f64)
    };
    let at = |y: f64| if additive { y } else { y.exp() };
    for _ in 0..80 {
        let m = 0.5 * (a + b);
        if total(at(m)) < target {
            a = m;
        } else {
            b = m;
        }
    }
    at(0.5 * (a + b))
}

/// The regret loss of one frame's batch (module docs) in burn's autodiff: `(loss + reg, loss,
/// reg)`. The frame's fit is taken as a constant (by the envelope theorem its gradient does not
/// change the loss's at the fitted value). Training runs [`regret_gradient`], the same loss on
/// plain numbers with its gradient written out; this formulation is the reference the tests
/// hold it to.
pub fn regret_loss(
    net: &ImportanceNet,
    loss: Loss,
    x: Tensor<2>,
    b: RegretBatch,
    l1: f64,
    l2: f64,
) -> (Tensor<1>, Tensor<1>, Tensor<1>) {
    let device = x.device();
    let rows = b.regret.dims()[0];
    let half = REGRET_HALF as f32;
    let offsets: Vec<f32> = (0..REGRET_WINDOW).map(|j| j as f32 - half).collect();
    let offsets = Tensor::<2>::from_data(TensorData::new(offsets, [1, REGRET_WINDOW]), &device);
    let c = asks(loss, net.forward(x), b.count);
    let values = c
        .clone()
        .into_data()
        .try_into_vec::<f32>()
        .expect("f32 asks");
    let additive = loss == Loss::RegretLevel;
    let shift = fit(additive, &values, &b.counts, &b.pairs, &b.k_opts, b.lo);
    // Pixels the fit clamps (to lo or their cap) keep that k; the others share what is left,
    // through a shift written as a function of their asks so the gradient sees that asking
    // more leaves less for the rest: sum k = sum k* exactly. A pixel clamped on the far side
    // of its k* (it asks for less than lo while k* > lo, say) would get no gradient at all and
    // stay wrong; its ask gets the gradient of its regret at the clamp, the fit held constant
    // (straight through: the value is the clamped k).
    let (mut mask, mut fixed, mut through) =
        (vec![0.0f32; rows], vec![0.0f32; rows], vec![0.0f32; rows]);
    let (mut fixed_sum, mut free) = (0.0f64, 0usize);
    for i in 0..rows {
        let k = if additive {
            values[i] as f64 + shift
        } else {
            values[i] as f64 * shift
        };
        let (lo, cap) = (b.lo as f64, useful_cap(b.counts[i], b.lo, b.pairs[i]));
        if k <= lo || k >= cap {
            fixed[i] = k.clamp(lo, cap) as f32;
            fixed_sum += fixed[i] as f64;
            let ko = b.k_opts[i] as f64;
            if (k <= lo && ko > lo) || (k >= cap && ko < cap) {
                through[i] = 1.0;
            }
        } else {
            mask[i] = 1.0;
            free += 1;
        }
    }
    let target: f64 = b.k_opts.iter().map(|&k| k as f64).sum();
    let column = |v: Vec<f32>| Tensor::<2>::from_data(TensorData::new(v, [rows, 1]), &device);
    let (mask, fixed, through) = (column(mask), column(fixed), column(through));
    let moved = if additive {
        c.clone().add_scalar(shift)
    } else {
        c.clone().mul_scalar(shift)
    };
    let fixed = fixed + (moved.clone() - moved.detach()) * through;
    let free_asks = c.clone() * mask.clone();
    let k = if free == 0 {
        fixed
    } else if additive {
        let x = free_asks
            .clone()
            .sum()
            .neg()
            .add_scalar(target - fixed_sum)
            .div_scalar(free as f64)
            .reshape([1, 1]);
        (c + x) * mask + fixed
    } else {
        let scale = free_asks
            .sum()
            .recip()
            .mul_scalar(target - fixed_sum)
            .reshape([1, 1]);
        c * scale * mask + fixed
    };
    let d = k - b.k_opt;
    let inside = d.clone().clamp(-half, half);
    let hats = relu((inside - offsets).abs().neg().add_scalar(1.0));
    let interp = (b.regret.clone() * hats).sum_dim(1);
    let w = REGRET_WINDOW;
    let slope_lo =
        b.regret.clone().slice([0..rows, 0..1]) - b.regret.clone().slice([0..rows, 1..2]);
    let slope_hi =
        b.regret.clone().slice([0..rows, w - 1..w]) - b.regret.slice([0..rows, w - 2..w - 1]);
    let beyond = slope_lo.clamp_min(0.0) * relu(d.clone().neg().sub_scalar(half))
        + slope_hi.clamp_min(0.0) * relu(d.sub_scalar(half));
    // The frame's E / E* - 1 estimated from its sample, then its logarithm: the loss is
    // ln(E / E*), whose mean over frames is the log of the geometric mean of the ratio.
    let excess = (interp + beyond).sum().div_scalar(b.share);
    let loss = excess.add_scalar(1.0).clamp_min(1e-6).log();
    let reg = regularisation(net, l1, l2);
    (loss.clone() + reg.clone(), loss, reg)
}

/// The regret of one pixel that gets `k` (continuous) slots (the CPU twin of the interpolation
/// in [`regret_loss`]).
pub fn pixel_regret(k: f64, k_opt: u32, window: &[f32; REGRET_WINDOW]) -> f64 {
    pixel_regret_slope(k, k_opt as f64, window).0
}

/// [`pixel_regret`] and its derivative with respect to k: the slope of the interpolated
/// segment inside the window, the extension's outside (0 where either is flat).
fn pixel_regret_slope(k: f64, k_opt: f64, window: &[f32; REGRET_WINDOW]) -> (f64, f64) {
    let half = REGRET_HALF as f64;
    let d = k - k_opt;
    let inside = d.clamp(-half, half);
    let (mut v, mut slope) = (0.0, 0.0);
    for (j, &r) in window.iter().enumerate() {
        let t = inside - (j as f64 - half);
        let hat = 1.0 - t.abs();
        if hat > 0.0 {
            v += r as f64 * hat;
            // The hat's derivative, where the clamp passes d through.
            if d > -half && d < half {
                slope -= r as f64 * t.signum() * (t != 0.0) as u8 as f64;
            }
        }
    }
    let w = REGRET_WINDOW;
    let slope_lo = (window[0] as f64 - window[1] as f64).max(0.0);
    let slope_hi = (window[w - 1] as f64 - window[w - 2] as f64).max(0.0);
    v += slope_lo * (-d - half).max(0.0) + slope_hi * (d - half).max(0.0);
    if d < -half {
        slope -= slope_lo;
    } else if d > half {
        slope += slope_hi;
    }
    (v, slope)
}

/// One frame's samples, as the regret loss reads them: each pixel's n, k* and regret window,
/// and whether its two farthest fragments share one colour; the frame's smallest k and the
/// share of its pixels sampled.
pub struct FrameSamples {
    pub counts: Vec<f32>,
    pub k_opts: Vec<f32>,
    pub pairs: Vec<bool>,
    pub regret: Vec<[f32; REGRET_WINDOW]>,
    pub lo: f32,
    pub share: f64,
}

impl FrameSamples {
    /// The samples `idx` of `s`, one frame's.
    pub fn of(s: &Samples, idx: &[usize]) -> FrameSamples {
        FrameSamples {
            counts: idx.iter().map(|&i| s.count[i] as f32).collect(),
            k_opts: idx.iter().map(|&i| s.k_opt[i] as f32).collect(),
            pairs: idx.iter().map(|&i| s.pair[i]).collect(),
            regret: idx.iter().map(|&i| s.regret[i]).collect(),
            lo: s.frame_lo[s.frame[idx[0]] as usize] as f32,
            share: s.share,
        }
    }

    /// A made-up frame: `rows` pixels of 1 to `max_n` fragments, optima below n, convex regret
    /// windows (every fifth flat below its optimum, so that no extension reaches past the
    /// window there), every seventh pixel's two farthest fragments of one colour, smallest k 1
    /// and half its pixels sampled. The benchmark steps on it; the tests hold the loss's
    /// gradient to autodiff on it.
    pub fn synthetic(rows: usize, max_n: f32, seed: u64) -> FrameSamples {
        let mut rng = Rng::new(seed);
        let counts: Vec<f32> = (0..rows)
            .map(|_| 1.0 + (rng.f32() * max_n).floor())
            .collect();
        let k_opts = counts
            .iter()
            .map(|&n| 1.0 + (rng.f32() * n).floor().min(n - 1.0))
            .collect();
        let regret = (0..rows)
            .map(|i| {
                let a = 1e-3 * (0.1 + rng.f32());
                std::array::from_fn(|j| {
                    let d = j as f32 - REGRET_HALF as f32;
                    if i % 5 == 0 && d < 0.0 {
                        0.0
                    } else {
                        a * d * d
                    }
                })
            })
            .collect();
        FrameSamples {
            counts,
            k_opts,
            pairs: (0..rows).map(|i| i % 7 == 0).collect(),
            regret,
            lo: 1.0,
            share: 0.5,
        }
    }
}

/// The regret loss of one frame (module docs, [`regret_loss`]) for the network's outputs `r`,
/// and its gradient with respect to each output: the training step's loss, on plain numbers.
///
/// The frame's fit (scale or level) is held constant, pixels the fit clamps keep their k (with
/// the straight-through gradient where k* lies beyond the clamp), and the others share what is
/// left, so that asking more leaves less for the rest: exactly what [`regret_loss`]'s graph
/// differentiates.
pub fn regret_gradient(loss: Loss, r: &[f32], f: &FrameSamples) -> (f64, Vec<f32>) {
    let rows = r.len();
    let additive = loss == Loss::RegretLevel;
    // The asks, as f32 (as the network's graph has them).
    let c: Vec<f32> = (0..rows)
        .map(|i| r[i] * ask_scale(loss, f.counts[i]))
        .collect();
    let caps = caps(&f.counts, &f.pairs, f.lo);
    let shift = fit_capped(additive, &c, &caps, &f.k_opts, f.lo);
    let lo = f.lo as f64;
    // Which pixels the fit clamps, at what k; the others are free.
    let mut k = vec![0.0f64; rows];
    let mut free = vec![false; rows];
    let mut through = vec![false; rows];
    let (mut fixed_sum, mut free_asks, mut n_free) = (0.0f64, 0.0f64, 0usize);
    for i in 0..rows {
        let moved = if additive {
            c[i] as f64 + shift
        } else {
            c[i] as f64 * shift
        };
        let cap = caps[i];
        if moved <= lo || moved >= cap {
            k[i] = moved.clamp(lo, cap) as f32 as f64;
            fixed_sum += k[i];
            let ko = f.k_opts[i] as f64;
            through[i] = (moved <= lo && ko > lo) || (moved >= cap && ko < cap);
        } else {
            free[i] = true;
            free_asks += c[i] as f64;
            n_free += 1;
        }
    }
    let target: f64 = f.k_opts.iter().map(|&k| k as f64).sum();
    // The free pixels' k: their asks moved by the level that spends what is left, or scaled by
    // the scale that does.
    let level = (target - fixed_sum - free_asks) / n_free.max(1) as f64;
    let scale = (target - fixed_sum) / free_asks;
    for i in (0..rows).filter(|&i| free[i]) {
        k[i] = if additive {
            c[i] as f64 + level
        } else {
            c[i] as f64 * scale
        };
    }
    // The frame's E / E* - 1 from its sample, and its logarithm.
    let mut slope = vec![0.0f64; rows];
    let mut excess = 0.0;
    for i in 0..rows {
        let (v, s) = pixel_regret_slope(k[i], f.k_opts[i] as f64, &f.regret[i]);
        excess += v;
        slope[i] = s;
    }
    excess /= f.share;
    let value = (1.0 + excess).max(1e-6).ln();
    let d_excess = if 1.0 + excess > 1e-6 {
        1.0 / (1.0 + excess) / f.share
    } else {
        0.0
    };
    // dL/dk of every pixel, then through k(c): a free pixel's k depends on every free ask.
    let g_k: Vec<f64> = slope.iter().map(|s| s * d_excess).collect();
    let (mut free_g, mut free_gc) = (0.0f64, 0.0f64);
    for i in (0..rows).filter(|&i| free[i]) {
        free_g += g_k[i];
        free_gc += g_k[i] * c[i] as f64;
    }
    let grad = (0..rows)
        .map(|j| {
            let d_c = if free[j] {
                if additive {
                    g_k[j] - free_g / n_free as f64
                } else {
                    scale * g_k[j] - scale / free_asks * free_gc
                }
            } else if through[j] {
                g_k[j] * if additive { 1.0 } else { shift }
            } else {
                0.0
            };
            (d_c * ask_scale(loss, f.counts[j]) as f64) as f32
        })
        .collect();
    (value, grad)
}

/// The mean over frames of `ln(E / E*)` estimated from the samples, each frame fitted to its
/// budget.
fn frame_regret(loss: Loss, pred: &[f32], s: &Samples) -> f64 {
    let additive = loss == Loss::RegretLevel;
    let frames = s.frames();
    // Each frame on its own thread, summed in frame order (the same on any number of threads).
    let logs: Vec<f64> = frames
        .par_iter()
        .map(|idx| {
            let f = FrameSamples::of(s, idx);
            let c: Vec<f32> = idx
                .iter()
                .zip(&f.counts)
                .map(|(&i, &n)| pred[i] * ask_scale(loss, n))
                .collect();
            let shift = fit(additive, &c, &f.counts, &f.pairs, &f.k_opts, f.lo);
            let mut excess = 0.0;
            for (j, &i) in idx.iter().enumerate() {
                let k = if additive {
                    c[j] as f64 + shift
                } else {
                    c[j] as f64 * shift
                };
                excess += pixel_regret(k, s.k_opt[i], &s.regret[i]);
            }
            (1.0 + excess / s.share).max(1e-6).ln()
        })
        .collect();
    logs.iter().sum::<f64>() / frames.len().max(1) as f64
}

fn scalar(t: Tensor<1>) -> f64 {
    t.into_data().try_into_vec::<f32>().expect("f32")[0] as f64
}

/// The training target of a sample under an MSE loss.
fn mse_target(loss: Loss, s: &Samples, i: usize) -> f32 {
    match loss {
        Loss::MseShare => s.k_opt[i] as f32 / s.count[i] as f32,
        _ => s.target[i],
    }
}

/// The mean loss of `m` on samples (burn inference; the regret by its CPU twin).
pub fn evaluate(m: &Mlp, s: &Samples, loss: Loss) -> f64 {
    if s.is_empty() {
        return f64::NAN;
    }
    let pred = predict(m, &s.features);
    if loss.regret() {
        return frame_regret(loss, &pred, s);
    }
    let sum: f64 = (0..s.len())
        .map(|i| ((pred[i] - mse_target(loss, s, i)) as f64).powi(2))
        .sum();
    sum / s.len() as f64
}

/// Mean squared error of `m` on samples against the paper's target (burn inference).
pub fn mse(m: &Mlp, s: &Samples) -> f64 {
    evaluate(m, s, Loss::MseRelative)
}

/// Trains on `data`, holding out `config.validation_scenes`. `progress` gets each epoch.
pub fn train(
    config: &TrainConfig,
    data: &Samples,
    progress: &mut dyn FnMut(&Epoch, usize),
) -> Result<Trained> {
    train_from(config, data, None, None, progress)
}

/// How a trained network is judged to pick the best epoch, lower is better (by default the
/// loss on the validation scenes).
pub type Select<'a> = dyn Fn(&Mlp) -> Result<f64> + 'a;

/// [`train`], starting from `init` when given (fine-tuning: its sizes must be the config's, its
/// output the loss's, and its standardisation is kept so that it keeps its meaning), and
/// choosing the best epoch by `select` when given (reported as the validation loss).
pub fn train_from(
    config: &TrainConfig,
    data: &Samples,
    init: Option<&Mlp>,
    select: Option<&Select>,
    progress: &mut dyn FnMut(&Epoch, usize),
) -> Result<Trained> {
    config.check()?;
    check_data(config, data)?;
    let (train_set, val_set) = held_out(config, data)?;
    // The network lives on the autodiff device, as burn's optimiser steps it; each step runs on
    // its plain copy (`valid`: the same tensors, no graph).
    let device = cpu_device(true);
    let plain = cpu_device(false);
    let init = initial_network(config, init, &train_set)?;
    let (mean, std) = (init.mean, init.std);
    let mut net = ImportanceNet::from_mlp(&init, &device);
    let mut optim = optimiser(config);
    let mut history = Vec::new();
    let mut best: Option<(f64, usize, Mlp)> = None;
    let start = Instant::now();
    // The features standardised once, in the row-major layout the step's tensors take; a
    // batch gathers its rows from here.
    let xs = standardised(&train_set.features, &mean, &std);
    // The regret losses take one frame (scene, view, budget) a batch, as the budget is fitted
    // per frame; the MSE losses shuffled mini-batches of `batch` samples.
    let frames = if config.loss.regret() {
        train_set.frames()
    } else {
        Vec::new()
    };
    for epoch in 0..config.epochs {
        let t = Instant::now();
        let (stepped, sum_mse, sum_reg, batches) = train_epoch(
            config,
            epoch,
            (&train_set, &xs, &frames),
            net,
            &mut optim,
            &plain,
        );
        net = stepped;
        let current = net.to_mlp(mean, std, config.loss.target());
        let validation_loss = if let Some(select) = select {
            select(&current)?
        } else if val_set.is_empty() {
            evaluate(&current, &train_set, config.loss)
        } else {
            evaluate(&current, &val_set, config.loss)
        };
        let e = Epoch {
            epoch,
            train_loss: sum_mse / batches as f64,
            train_reg: sum_reg / batches as f64,
            validation_loss,
            seconds: t.elapsed().as_secs_f64(),
        };
        if !e.train_loss.is_finite() {
            return Err(Error::Diverged {
                epoch,
                loss: e.train_loss,
            });
        }
        progress(&e, config.epochs);
        history.push(e);
        if best.as_ref().is_none_or(|b| validation_loss < b.0) {
            best = Some((validation_loss, epoch, current));
        }
    }
    let (_, best_epoch, mlp) = best.expect("at least one epoch");
    let seconds = start.elapsed().as_secs_f64();
    Ok(Trained {
        mlp,
        best_epoch,
        history,
        train_samples: train_set.len(),
        validation_samples: val_set.len(),
        seconds,
        samples_per_second: (train_set.len() * config.epochs) as f64 / seconds,
    })
}

/// The training and validation samples: the validation scenes held out, each set refused
/// with what is wrong where it is empty.
fn held_out(config: &TrainConfig, data: &Samples) -> Result<(Samples, Samples)> {
    let held = |s: &str| config.validation_scenes.iter().any(|v| v == s);
    let train_set = data.filter_scenes(|s| !held(s));
    let val_set = data.filter_scenes(held);
    if data.is_empty() {
        return Err(Error::Config(
            "the dataset holds no sample: no pixel of its scenes' views has a k the network \
             decides (no transparent fragment, or none deeper than 2 or 3 fragments, whose k \
             is forced); for opaque materials `train --scene` takes --opacity"
                .into(),
        ));
    }
    if train_set.is_empty() {
        return Err(Error::Config(format!(
            "no training samples left after holding out the validation scenes ({}): every \
             sample is from them",
            config.validation_scenes.join(", ")
        )));
    }
    Ok((train_set, val_set))
}

/// One epoch's steps of `optim` on `net`: its batches in the order the epoch's seed draws them
/// (one frame each for the regret losses, from `frames`; shuffled samples for the MSE ones),
/// their rows gathered from `xs` (the standardised features). The stepped network, the sums of
/// the batches' losses and regularisations, and the number of batches.
fn train_epoch(
    config: &TrainConfig,
    epoch: usize,
    (train_set, xs, frames): (&Samples, &[f32], &[Vec<usize>]),
    mut net: ImportanceNet,
    optim: &mut burn::optim::ModuleOptimizer,
    plain: &Device,
) -> (ImportanceNet, f64, f64, usize) {
    let mut rows = Vec::with_capacity(config.batch * FEATURES);
    let mut ys = Vec::with_capacity(config.batch);
    let mut rng = Rng::new(config.seed ^ (epoch as u64 + 1).wrapping_mul(0x9E37_79B9));
    let batches_of = epoch_batches(config, &mut rng, frames, train_set.len());
    let (mut sum_mse, mut sum_reg, mut batches) = (0.0, 0.0, 0usize);
    for chunk in &batches_of {
        rows.clear();
        for &i in chunk {
            rows.extend_from_slice(&xs[i * FEATURES..(i + 1) * FEATURES]);
        }
        let valid = net.valid();
        let (value, grads) = match config.loss {
            l @ (Loss::Regret | Loss::RegretLevel) => {
                // The frame's fit needs every output: the forward pass, the loss's
                // gradient on plain numbers, then the backward pass.
                let pass = step::forward(&valid, &rows, plain);
                let frame = FrameSamples::of(train_set, chunk);
                let (value, d_out) = regret_gradient(l, &pass.out, &frame);
                let grads = step::gradients(&valid, pass, &d_out, config.l1, config.l2, plain);
                (value, grads)
            }
            l => {
                ys.clear();
                ys.extend(chunk.iter().map(|&i| mse_target(l, train_set, i)));
                step::mse_step(&valid, &rows, &ys, config.l1, config.l2, plain)
            }
        };
        sum_reg += scalar(regularisation(&valid, config.l1, config.l2));
        let done =
            (epoch * batches_of.len() + batches) as f64 / (config.epochs * batches_of.len()) as f64;
        net = optim.step(config.learning_rate(done), net, grads);
        sum_mse += value;
        batches += 1;
    }
    (net, sum_mse, sum_reg, batches)
}

/// What training needs of its data: each sample's n, k* and regret for the regret losses, and
/// every validation scene among the dataset's.
fn check_data(config: &TrainConfig, data: &Samples) -> Result<()> {
    if config.loss != Loss::MseRelative && !data.has_regret() {
        return Err(Error::Config(format!(
            "the {} loss needs each sample's n, k* and regret (a dataset generated by `dhoit dataset`)",
            config.loss.name()
        )));
    }
    for v in &config.validation_scenes {
        if !data.scenes.contains(v) {
            return Err(Error::Config(format!(
                "validation scene '{v}' is not in the dataset (scenes: {})",
                data.scenes.join(", ")
            )));
        }
    }
    Ok(())
}

/// The network training starts from: `init` where given (its sizes must be the config's and its
/// output the loss's), else random weights of the config's seed, standardised on `train_set`.
fn initial_network(config: &TrainConfig, init: Option<&Mlp>, train_set: &Samples) -> Result<Mlp> {
    let [h1, h2] = config.hidden;
    Ok(match init {
        Some(m) => {
            if [m.h1, m.h2] != [h1, h2] {
                return Err(Error::Config(format!(
                    "cannot fine-tune a {}-{} network as {h1}-{h2}: give --hidden {},{}",
                    m.h1, m.h2, m.h1, m.h2
                )));
            }
            if m.target != config.loss.target() {
                return Err(Error::Config(format!(
                    "the initial network's output is {:?}, the {} loss trains {:?}",
                    m.target,
                    config.loss.name(),
                    config.loss.target()
                )));
            }
            m.clone()
        }
        None => {
            let (mean, std) = standardisation(&train_set.features);
            let mut m = Mlp::random_sized(config.seed, h1, h2);
            m.mean = mean;
            m.std = std;
            m.target = config.loss.target();
            m
        }
    })
}

/// An epoch's batches, in the epoch's order: the regret losses one frame a batch (`frames`,
/// the samples of each), the MSE losses shuffled mini-batches of `config.batch` of the `n`
/// samples.
fn epoch_batches(
    config: &TrainConfig,
    rng: &mut Rng,
    frames: &[Vec<usize>],
    n: usize,
) -> Vec<Vec<usize>> {
    if config.loss.regret() {
        rng.permutation(frames.len())
            .into_iter()
            .map(|f| frames[f].clone())
            .collect()
    } else {
        rng.permutation(n)
            .chunks(config.batch)
            .map(|c| c.to_vec())
            .collect()
    }
}

/// The optimiser a training configuration steps with: SGD, its momentum, and its gradient
/// clipping by norm (whose norms are burn's sums, the one part of a step whose floats depend on
/// the CPU's SIMD width: [`float_fingerprint`]).
fn optimiser(config: &TrainConfig) -> burn::optim::ModuleOptimizer {
    let mut sgd = SgdConfig::new();
    if config.momentum > 0.0 {
        sgd = sgd.with_momentum(Some(MomentumConfig::new().with_momentum(config.momentum)));
    }
    if config.clip > 0.0 {
        sgd = sgd.with_gradient_clipping(Some(GradientClippingConfig::Norm(config.clip as f32)));
    }
    sgd.init()
}

/// What a training benchmark steps: the network, its optimiser ([`optimiser`] of a training
/// configuration), random features and targets.
struct Bench {
    /// The device the step's inputs are on: the plain one for the fused step, the autodiff one
    /// for burn's graph (the network is on the autodiff device either way, as the optimiser
    /// needs).
    device: Device,
    net: ImportanceNet,
    optim: burn::optim::ModuleOptimizer,
    x: Vec<f32>,
    y: Vec<f32>,
}

/// The throughput benchmarks' configuration: `make train`'s optimiser without its clipping
/// (SGD, momentum 0.9), so they time the step alone.
fn unclipped() -> TrainConfig {
    TrainConfig {
        clip: 0.0,
        ..TrainConfig::default()
    }
}

fn bench_setup(rows: usize, autodiff: bool, config: &TrainConfig) -> Bench {
    let mut rng = Rng::new(1);
    let m = Mlp::random(1);
    Bench {
        net: ImportanceNet::from_mlp(&m, &cpu_device(true)),
        device: cpu_device(autodiff),
        optim: optimiser(config),
        x: (0..rows * FEATURES)
            .map(|_| rng.f32() * 2.0 - 1.0)
            .collect(),
        y: (0..rows).map(|_| rng.f32()).collect(),
    }
}

/// Samples per second of `steps` runs of `step` over `rows` samples, after one warm-up run.
fn per_second(rows: usize, steps: usize, mut step: impl FnMut()) -> f64 {
    step();
    let start = Instant::now();
    for _ in 0..steps {
        step();
    }
    (rows * steps) as f64 / start.elapsed().as_secs_f64()
}

/// Training throughput: samples per second of `steps` SGD steps at `batch` of the MSE loss
/// (forward, loss, backward, optimiser step: the fused step training runs), on random
/// features.
pub fn bench_training(batch: usize, steps: usize) -> f64 {
    let mut b = bench_setup(batch, false, &unclipped());
    per_second(batch, steps, || {
        let valid = b.net.valid();
        let (_, grads) = step::mse_step(&valid, &b.x, &b.y, 1e-6, 1e-5, &b.device);
        b.net = b.optim.step(1e-3, b.net.clone(), grads);
    })
}

/// [`bench_training`] through burn's autodiff graph instead of the fused step (what training
/// ran before it, kept as the reference).
pub fn bench_training_autodiff(batch: usize, steps: usize) -> f64 {
    let mut b = bench_setup(batch, true, &unclipped());
    per_second(batch, steps, || {
        let x = Tensor::from_data(TensorData::new(b.x.clone(), [batch, FEATURES]), &b.device);
        let y = Tensor::from_data(TensorData::new(b.y.clone(), [batch, 1]), &b.device);
        let (total, mse, _) = loss(&b.net, x, y, 1e-6, 1e-5);
        let grads = GradientsParams::from_grads(total.backward(), &b.net);
        b.net = b.optim.step(1e-3, b.net.clone(), grads);
        scalar(mse);
    })
}

/// The regret-loss step's throughput (what `make train` runs): samples per second of `steps`
/// steps on a [`FrameSamples::synthetic`] frame of `rows` pixels, the frame's fit included.
pub fn bench_regret_step(rows: usize, steps: usize) -> f64 {
    let mut b = bench_setup(rows, false, &unclipped());
    let frame = FrameSamples::synthetic(rows, 30.0, 3);
    per_second(rows, steps, || {
        let valid = b.net.valid();
        let pass = step::forward(&valid, &b.x, &b.device);
        let (_, d_out) = regret_gradient(Loss::RegretLevel, &pass.out, &frame);
        let grads = step::gradients(&valid, pass, &d_out, 1e-6, 1e-5, &b.device);
        b.net = b.optim.step(1e-3, b.net.clone(), grads);
    })
}

/// The scheme of [`float_fingerprint`]'s digests, their prefix: a digest of another scheme
/// (an earlier one recorded no prefix) never equals one of this.
pub const FINGERPRINT_SCHEME: &str = "v2";

/// How this machine computes training's floats, as a digest: four regret-loss steps (the step
/// `make train` runs, with its optimiser: momentum and clipping by norm) on a synthetic frame from
/// a fixed network, then the parameters' bits and their squared norms as burn sums them. burn's
/// sums take the widest SIMD the CPU has (8 lanes with AVX2, 16 with AVX-512), so their bits,
/// and a clipped step's, differ between such CPUs where the step's matrix products do not.
/// Training records it (config.json), so a test can tell "this machine computes floats as the
/// one that trained the committed weights did" (then a fresh training must give them bit for
/// bit) from "it does not" (then no run can, and it is held to their validation loss). About a
/// millisecond.
pub fn float_fingerprint() -> String {
    float_fingerprint_of(&TrainConfig::default())
}

/// [`float_fingerprint`] for the optimiser of `config` (its momentum and clipping).
pub fn float_fingerprint_of(config: &TrainConfig) -> String {
    let rows = 256;
    let mut b = bench_setup(rows, false, config);
    let frame = FrameSamples::synthetic(rows, 30.0, 3);
    for _ in 0..4 {
        let valid = b.net.valid();
        let pass = step::forward(&valid, &b.x, &b.device);
        let (_, d_out) = regret_gradient(Loss::RegretLevel, &pass.out, &frame);
        let grads = step::gradients(&valid, pass, &d_out, 1e-6, 1e-5, &b.device);
        b.net = b.optim.step(1e-3, b.net.clone(), grads);
    }
    let valid = b.net.valid();
    // Each parameter's squared norm as the clipping computes it (burn's square and sum).
    let norm = |t: Tensor<2>| t.square().sum().into_scalar::<f32>();
    let bias = |l: &burn::nn::Linear| l.bias.as_ref().expect("a bias").val().unsqueeze::<2>();
    let norms = vec![
        norm(valid.fc1.weight.val()),
        norm(bias(&valid.fc1)),
        norm(valid.fc2.weight.val()),
        norm(bias(&valid.fc2)),
        norm(valid.out.weight.val()),
        norm(bias(&valid.out)),
    ];
    let m = valid.to_mlp([0.0; FEATURES], [1.0; FEATURES], Target::RelativeK);
    // FNV-1a over every parameter's bits, then the norms'.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for v in [&m.w1, &m.b1, &m.w2, &m.b2, &m.w3, &vec![m.b3], &norms] {
        for x in v.iter() {
            for byte in x.to_bits().to_le_bytes() {
                h = (h ^ byte as u64).wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    format!("{FINGERPRINT_SCHEME}-{h:016x}")
}

/// burn inference throughput: samples per second of [`predict`] over `n` random rows.
pub fn bench_inference(n: usize) -> f64 {
    let mut rng = Rng::new(2);
    let m = Mlp::random(2);
    let rows: Vec<[f32; FEATURES]> = (0..n).map(|_| std::array::from_fn(|_| rng.f32())).collect();
    predict(&m, &rows[..n.min(1024)]);
    let start = Instant::now();
    let out = predict(&m, &rows);
    assert_eq!(out.len(), n);
    n as f64 / start.elapsed().as_secs_f64()
}
