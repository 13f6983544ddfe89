//! Batch prediction: `predict.wgsl` runs the network of `mlp.wgsl` (as the DKB importance
//! pass does) on rows of 12 features; the twins are `Mlp::forward` and the trainer's burn model.

use super::Gpu;
use super::bindings::{mlp, predict};
use super::buffers::{read_back, u32s};
use super::pipelines::{self, Variant};
use crate::error::Result;
use crate::mlp::{Mlp, Precision};
use crate::wgsl::{PIXEL_GROUP, Params, grid, mlp_uniform};
use wgpu::util::DeviceExt;

impl Gpu {
    /// The network on rows of features, on the GPU: the batch pass `predict.wgsl` runs the same
    /// WGSL network (`mlp.wgsl`) as the DKB importance pass. Rows go through in chunks that fit
    /// the device's largest binding. Rows with a feature that is not a finite number are
    /// refused ([`crate::mlp::check_features`]): WGSL does not say what `clamp` makes of a NaN.
    pub fn predict(
        &self,
        mlp: &Mlp,
        rows: &[[f32; crate::importance::FEATURES]],
    ) -> Result<Vec<f32>> {
        crate::mlp::check_features(rows)?;
        self.can_run(mlp)?;
        let weights = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("mlp.weights"),
                contents: bytemuck::cast_slice(&mlp_uniform(mlp)),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let limit = self.device.limits().max_storage_buffer_binding_size;
        let chunk = ((limit / 48) as usize).clamp(1, 1 << 22);
        let mut out = Vec::with_capacity(rows.len());
        for part in rows.chunks(chunk) {
            let n = part.len() as u32;
            // The pass reads the row count from the frame parameters' pixel count.
            let mut params: Params = bytemuck::Zeroable::zeroed();
            params.pixels = n;
            let params_buf = self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("params"),
                    contents: bytemuck::bytes_of::<Params>(&params),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            let input = self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("predict.rows"),
                    contents: bytemuck::cast_slice(part),
                    usage: wgpu::BufferUsages::STORAGE,
                });
            let size = (4 * n as u64).max(crate::shared::LEAST_BUFFER_BYTES);
            let output = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("predict.out"),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let pl = &self.network_pass(Variant::for_network("predict", mlp, true));
            let mut entries = vec![
                (predict::PARAMS, &params_buf),
                (mlp::WEIGHTS, &weights),
                (predict::ROWS, &input),
                (predict::PREDICTIONS, &output),
            ];
            if mlp.precision == Precision::F16Math {
                // The weights' binary16 view (pipelines::unrolled_forward).
                entries.push((pipelines::WEIGHTS_H, &weights));
            }
            let group = self.bind_at(&pl.get_bind_group_layout(0), &entries);
            let mut enc = self.device.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(pl);
                pass.set_bind_group(0, &group, &[]);
                let (gx, gy) = grid(n, PIXEL_GROUP);
                pass.dispatch_workgroups(gx, gy, 1);
            }
            self.submit(enc.finish());
            out.extend(
                u32s(&read_back(self, &output, 4 * n as u64)?)
                    .into_iter()
                    .map(f32::from_bits),
            );
        }
        Ok(out)
    }
}
