//! GPU timestamps around each pass.

use super::buffers::read_back;
use super::{Gpu, TIMED_PASSES};
use crate::error::Result;

/// Timestamp queries around each pass (room for [`TIMED_PASSES`]; the set is reused by the
/// next frame).
pub(super) struct Timer<'a> {
    pub(super) gpu: &'a Gpu,
    pub(super) set: Option<wgpu::QuerySet>,
    pub(super) names: std::cell::RefCell<Vec<&'static str>>,
}

impl Drop for Timer<'_> {
    fn drop(&mut self) {
        if let Some(set) = self.set.take() {
            let mut sets = self
                .gpu
                .query_sets
                .lock()
                .unwrap_or_else(|e| e.into_inner());
            sets.push(set);
        }
    }
}

impl<'a> Timer<'a> {
    pub(super) fn new(gpu: &'a Gpu) -> Timer<'a> {
        let pooled = gpu
            .query_sets
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .pop();
        let set = pooled.unwrap_or_else(|| {
            gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * TIMED_PASSES,
            })
        });
        Timer {
            gpu,
            set: Some(set),
            names: Default::default(),
        }
    }
    pub(super) fn set(&self) -> &wgpu::QuerySet {
        self.set.as_ref().expect("held until the timer is dropped")
    }
    pub(super) fn next(&self, name: &'static str) -> (u32, u32) {
        let mut names = self.names.borrow_mut();
        names.push(name);
        let i = 2 * (names.len() as u32 - 1);
        (i, i + 1)
    }
    pub(super) fn read(&self, gpu: &Gpu) -> Result<Vec<(&'static str, f64)>> {
        let names = self.names.borrow();
        let n = 2 * names.len() as u64;
        let key = format!("timestamps.resolve {n}");
        let usage = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
        let buf = gpu.acquire(&key, 8 * n, usage, None);
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        enc.resolve_query_set(self.set(), 0..n as u32, &buf, 0);
        gpu.queue.submit([enc.finish()]);
        let raw = read_back(gpu, &buf, 8 * n);
        gpu.release(key, buf);
        let raw = raw?;
        let ticks: Vec<u64> = raw
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8")))
            .collect();
        Ok(names
            .iter()
            .enumerate()
            .map(|(i, &name)| {
                let dt = ticks[2 * i + 1].saturating_sub(ticks[2 * i]);
                (name, dt as f64 * gpu.timestamp_period as f64 / 1e6)
            })
            .collect())
    }
}
