//! `dhoit predict`: the network on a features file, in burn, the CPU twin or the GPU.

use anyhow::Result;
use dhoit_runtime::gpu::Gpu;
use dhoit_train::cli::{PredictArgs, PredictDevice};

/// `dhoit predict`: burn, the CPU twin, or the GPU's WGSL network.
pub fn run(a: PredictArgs) -> Result<()> {
    if a.device != PredictDevice::Gpu {
        return Ok(dhoit_train::cli::predict(a)?);
    }
    let gpu = Gpu::new()?;
    eprintln!("predict: on {}", gpu.adapter());
    Ok(dhoit_train::cli::predict_with(&a, &|mlp, rows| {
        Ok(gpu.predict(mlp, rows)?)
    })?)
}
