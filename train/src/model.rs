//! The importance network as a burn module, and its conversions to and from the runtime's
//! plain-Rust [`Mlp`] (the weights contract).
//!
//! burn's `Linear` stores its weight as [d_input, d_output] (row layout), which is the
//! contract's layout, so weights copy across without a transpose.

use burn::module::Param;
use burn::nn::Linear;
use burn::prelude::*;
use burn::tensor::TensorData;
use burn::tensor::activation::{relu, sigmoid};
use dhoit_runtime::importance::FEATURES;
use dhoit_runtime::mlp::{Mlp, Target};
use rayon::prelude::*;

#[derive(Module, Debug)]
pub struct ImportanceNet {
    pub fc1: Linear,
    pub fc2: Linear,
    pub out: Linear,
}

/// The CPU device (burn's Flex backend, its default CPU backend since 0.22); `autodiff` adds
/// gradient tracking (the reference the fused training step is held to in tests).
pub fn cpu_device(autodiff: bool) -> Device {
    let d = Device::flex();
    if autodiff { d.autodiff() } else { d }
}

fn linear(w: &[f32], b: &[f32], d_in: usize, d_out: usize, device: &Device) -> Linear {
    Linear {
        weight: Param::from_tensor(Tensor::from_data(
            TensorData::new(w.to_vec(), [d_in, d_out]),
            device,
        )),
        bias: Some(Param::from_tensor(Tensor::from_data(
            TensorData::new(b.to_vec(), [d_out]),
            device,
        ))),
    }
}

fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().try_into_vec::<f32>().expect("f32 parameters")
}

impl ImportanceNet {
    /// The network holding `m`'s weights (standardisation is applied to inputs outside).
    pub fn from_mlp(m: &Mlp, device: &Device) -> ImportanceNet {
        ImportanceNet {
            fc1: linear(&m.w1, &m.b1, FEATURES, m.h1, device),
            fc2: linear(&m.w2, &m.b2, m.h1, m.h2, device),
            out: linear(&m.w3, &[m.b3], m.h2, 1, device),
        }
    }

    /// The weights as the runtime's MLP, with the given standardisation.
    pub fn to_mlp(&self, mean: [f32; FEATURES], std: [f32; FEATURES], target: Target) -> Mlp {
        let w = |l: &Linear| values(l.weight.val());
        let b = |l: &Linear| values(l.bias.as_ref().expect("bias").val());
        let w1 = w(&self.fc1);
        let h1 = w1.len() / FEATURES;
        let b1 = b(&self.fc1);
        let w2 = w(&self.fc2);
        let h2 = w2.len() / h1;
        Mlp {
            h1,
            h2,
            w1,
            b1,
            w2,
            b2: b(&self.fc2),
            w3: w(&self.out),
            b3: b(&self.out)[0],
            mean,
            std,
            target,
            precision: dhoit_runtime::mlp::Precision::F32,
        }
    }

    /// Importance in (0, 1) for standardised inputs [N, 12] -> [N, 1].
    pub fn forward(&self, x: Tensor<2>) -> Tensor<2> {
        let h1 = relu(self.fc1.forward(x));
        let h2 = relu(self.fc2.forward(h1));
        sigmoid(self.out.forward(h2))
    }
}

/// Standardised inputs, row after row (FEATURES values a row).
pub fn standardised(
    rows: &[[f32; FEATURES]],
    mean: &[f32; FEATURES],
    std: &[f32; FEATURES],
) -> Vec<f32> {
    rows.iter()
        .flat_map(|r| {
            (0..FEATURES).map(move |i| dhoit_runtime::mlp::standardise(r[i], mean[i], std[i]))
        })
        .collect()
}

/// Standardised inputs as a tensor.
pub fn input_tensor(
    rows: &[[f32; FEATURES]],
    mean: &[f32; FEATURES],
    std: &[f32; FEATURES],
    device: &Device,
) -> Tensor<2> {
    let flat = standardised(rows, mean, std);
    Tensor::from_data(TensorData::new(flat, [rows.len(), FEATURES]), device)
}

/// burn inference over many rows, in chunks run in parallel, on the plain CPU device.
pub fn predict(m: &Mlp, rows: &[[f32; FEATURES]]) -> Vec<f32> {
    let device = cpu_device(false);
    let net = ImportanceNet::from_mlp(m, &device);
    let chunks: Vec<Vec<f32>> = rows
        .par_chunks(4096)
        .map(|chunk| {
            let y = net.forward(input_tensor(chunk, &m.mean, &m.std, &device));
            // As `mlp::squash`: 0 where the sums overflowed both ways.
            values(y)
                .into_iter()
                .map(|v| if v.is_nan() { 0.0 } else { v })
                .collect()
        })
        .collect();
    chunks.concat()
}
