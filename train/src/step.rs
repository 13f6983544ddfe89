//! The fused training step: the network's forward pass, and its backward pass written out,
//! on burn tensors of the plain CPU device, in shards of rows run in parallel.
//!
//! burn's autodiff records every operation of a step in a graph behind one lock and replays it
//! backwards; for a three-layer network at batch 512 that bookkeeping cost more than the
//! matrix products themselves, and two threads stepping two graphs ran slower than one (README,
//! "Training throughput"). The backward of `sigmoid(relu(relu(x W1 + b1) W2 + b2) w3 + b3)` is
//! five matrix products and two masks, so it is written out here: the forward keeps each
//! shard's input and hidden activations, the loss's gradient with respect to the outputs comes
//! from the caller (computed on plain numbers: [`crate::trainer::regret_gradient`], or the
//! MSE's), and [`gradients`] returns burn [`GradientsParams`] for burn's optimiser. The tests
//! hold both the gradients and a whole training run to burn's autodiff on the same batches.
//!
//! Reproducible on any number of threads: a batch is cut into shards by its row count alone,
//! each shard's sums run inside one matrix product (gemm keeps an inner dimension of up to 512
//! in one pass, whatever the machine's caches, and a shard has at most [`SHARD_ROWS`] rows),
//! and the shards' gradients are added in shard order.

use crate::model::ImportanceNet;
use burn::optim::GradientsParams;
use burn::prelude::*;
use burn::tensor::TensorData;
use burn::tensor::activation::relu;
use dhoit_runtime::importance::FEATURES;
use rayon::prelude::*;
use std::ops::Range;

/// The most rows a shard holds: large enough that a shard's matrix products outweigh the cost
/// of a task, small enough that a frame of a few hundred pixels still feeds two cores.
pub const SHARD_ROWS: usize = 256;

/// What one shard's forward pass keeps for its backward pass.
struct Shard {
    rows: Range<usize>,
    x: Tensor<2>,
    h1: Tensor<2>,
    h2: Tensor<2>,
}

/// A batch's forward pass: the network's outputs, and what the backward pass needs.
pub struct Pass {
    shards: Vec<Shard>,
    /// The network's outputs (the sigmoid's), one per row, in row order.
    pub out: Vec<f32>,
}

/// The shards of `rows` rows: as few as [`SHARD_ROWS`] allows, of near-equal sizes.
fn shards(rows: usize) -> Vec<Range<usize>> {
    let n = rows.div_ceil(SHARD_ROWS).max(1);
    (0..n).map(|s| s * rows / n..(s + 1) * rows / n).collect()
}

fn floats<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().try_into_vec::<f32>().expect("f32 tensor")
}

/// One shard's forward pass: what the backward pass keeps, and the outputs.
fn shard_forward(
    net: &ImportanceNet,
    x: &[f32],
    rows: Range<usize>,
    device: &Device,
) -> (Shard, Vec<f32>) {
    let data = x[rows.start * FEATURES..rows.end * FEATURES].to_vec();
    let x = Tensor::<2>::from_data(TensorData::new(data, [rows.len(), FEATURES]), device);
    let h1 = relu(net.fc1.forward(x.clone()));
    let h2 = relu(net.fc2.forward(h1.clone()));
    // The sigmoid on plain numbers: a sum that is not a number stays one, so that a diverging
    // run is seen as such.
    let out = floats(net.out.forward(h2.clone()))
        .into_iter()
        .map(|z| 1.0 / (1.0 + (-z).exp()))
        .collect();
    (Shard { rows, x, h1, h2 }, out)
}

/// The forward pass over standardised rows (`x`: FEATURES values a row, row after row).
pub fn forward(net: &ImportanceNet, x: &[f32], device: &Device) -> Pass {
    let rows = x.len() / FEATURES;
    let done: Vec<(Shard, Vec<f32>)> = shards(rows)
        .into_par_iter()
        .map(|r| shard_forward(net, x, r, device))
        .collect();
    let mut out = Vec::with_capacity(rows);
    let mut kept = Vec::with_capacity(done.len());
    for (s, o) in done {
        out.extend(o);
        kept.push(s);
    }
    Pass { shards: kept, out }
}

/// One shard's gradients of the loss (not the regularisation) given `out`, its outputs, and
/// `d_out`, the loss's gradient with respect to each, in the order of [`register`].
fn shard_backward(
    s: Shard,
    out: &[f32],
    d_out: &[f32],
    w2t: &Tensor<2>,
    w3t: &Tensor<2>,
    device: &Device,
) -> [Tensor<2>; 6] {
    let n = s.rows.len();
    // Through the sigmoid: d/dz = d/dr r (1 - r).
    let g: Vec<f32> = out
        .iter()
        .zip(d_out)
        .map(|(&r, &d)| d * r * (1.0 - r))
        .collect();
    let g = Tensor::<2>::from_data(TensorData::new(g, [n, 1]), device);
    // Bias gradients as products with a row of ones, so that every sum over rows is a matrix
    // product's (the module docs).
    let ones = Tensor::<2>::ones([1, n], device);
    let dw3 = s.h2.clone().transpose().matmul(g.clone());
    let db3 = ones.clone().matmul(g.clone());
    // ReLU passes the gradient where its output is positive.
    let g2 = g.matmul(w3t.clone()) * s.h2.greater_elem(0.0).float();
    let dw2 = s.h1.clone().transpose().matmul(g2.clone());
    let db2 = ones.clone().matmul(g2.clone());
    let g1 = g2.matmul(w2t.clone()) * s.h1.greater_elem(0.0).float();
    let dw1 = s.x.transpose().matmul(g1.clone());
    let db1 = ones.matmul(g1);
    [dw1, db1, dw2, db2, dw3, db3]
}

/// The shards' gradients summed in shard order, the regularisation's added (d(l1 |w|)/dw =
/// l1 sign(w), d(l2 w^2)/dw = 2 l2 w), as burn's optimiser takes them.
fn register(net: &ImportanceNet, parts: Vec<[Tensor<2>; 6]>, l1: f64, l2: f64) -> GradientsParams {
    let mut parts = parts.into_iter();
    let mut sum = parts.next().expect("at least one shard");
    for p in parts {
        for (a, b) in sum.iter_mut().zip(p) {
            *a = a.clone() + b;
        }
    }
    let [dw1, db1, dw2, db2, dw3, db3] = sum;
    let dw1 = dw1 + net.fc1.weight.val().sign().mul_scalar(l1);
    let dw2 = dw2 + net.fc2.weight.val().mul_scalar(2.0 * l2);
    let mut grads = GradientsParams::new();
    let bias = |l: &burn::nn::Linear| l.bias.as_ref().expect("bias").id;
    let flat = |t: Tensor<2>| {
        let n = t.dims()[1];
        t.reshape([n])
    };
    grads.register(net.fc1.weight.id, dw1);
    grads.register(bias(&net.fc1), flat(db1));
    grads.register(net.fc2.weight.id, dw2);
    grads.register(bias(&net.fc2), flat(db2));
    grads.register(net.out.weight.id, dw3);
    grads.register(bias(&net.out), flat(db3));
    grads
}

fn transposed(net: &ImportanceNet) -> (Tensor<2>, Tensor<2>) {
    (
        net.fc2.weight.val().transpose(),
        net.out.weight.val().transpose(),
    )
}

/// The gradients of `loss + l1 sum|W1| + l2 sum W2^2` with respect to every parameter, given
/// `d_out`, the loss's gradient with respect to each output of `pass` (same order).
pub fn gradients(
    net: &ImportanceNet,
    pass: Pass,
    d_out: &[f32],
    l1: f64,
    l2: f64,
    device: &Device,
) -> GradientsParams {
    assert_eq!(d_out.len(), pass.out.len(), "one gradient an output");
    let (w2t, w3t) = transposed(net);
    let out = &pass.out;
    let parts: Vec<[Tensor<2>; 6]> = pass
        .shards
        .into_par_iter()
        .map(|s| {
            let r = s.rows.clone();
            shard_backward(s, &out[r.clone()], &d_out[r], &w2t, &w3t, device)
        })
        .collect();
    register(net, parts, l1, l2)
}

/// A whole step of the MSE loss against `y`: `(loss, gradients)` as [`forward`],
/// [`mse_gradient`] and [`gradients`] give them, each shard's forward and backward passes in
/// one task (the MSE's gradient of a row needs that row alone).
pub fn mse_step(
    net: &ImportanceNet,
    x: &[f32],
    y: &[f32],
    l1: f64,
    l2: f64,
    device: &Device,
) -> (f64, GradientsParams) {
    let (w2t, w3t) = transposed(net);
    let n = y.len().max(1) as f64;
    let scale = (2.0 / n) as f32;
    let parts: Vec<(f64, [Tensor<2>; 6])> = shards(y.len())
        .into_par_iter()
        .map(|r| {
            let (s, out) = shard_forward(net, x, r.clone(), device);
            let y = &y[r];
            let se: f64 = out
                .iter()
                .zip(y)
                .map(|(&o, &y)| ((o - y) as f64).powi(2))
                .sum();
            let d_out: Vec<f32> = out.iter().zip(y).map(|(&o, &y)| scale * (o - y)).collect();
            (se, shard_backward(s, &out, &d_out, &w2t, &w3t, device))
        })
        .collect();
    let se: f64 = parts.iter().map(|p| p.0).sum();
    (
        se / n,
        register(net, parts.into_iter().map(|p| p.1).collect(), l1, l2),
    )
}

/// The mean squared error of `out` against `y`, and its gradient with respect to `out`.
pub fn mse_gradient(out: &[f32], y: &[f32]) -> (f64, Vec<f32>) {
    let n = out.len().max(1) as f64;
    let value = out
        .iter()
        .zip(y)
        .map(|(&o, &y)| ((o - y) as f64).powi(2))
        .sum::<f64>()
        / n;
    let scale = (2.0 / n) as f32;
    let grad = out.iter().zip(y).map(|(&o, &y)| scale * (o - y)).collect();
    (value, grad)
}
