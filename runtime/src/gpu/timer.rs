//! GPU timestamps around each pass, where the device has them (`TIMESTAMP_QUERY`, optional:
//! without it every pass runs untimed). A frame resolves its queries into a buffer in its own
//! encoder ([`Timer::resolve`]), so the times are read once its client's submission has run.

use super::buffers::read_back;
use super::{Gpu, TIMED_PASSES};
use crate::error::Result;

/// Timestamp queries around each pass (room for [`TIMED_PASSES`]; the set is reused by the
/// next frame).
pub(super) struct Timer<'a> {
    pub(super) gpu: &'a Gpu,
    /// None where the device has no timestamps.
    set: Option<wgpu::QuerySet>,
    names: std::cell::RefCell<Vec<&'static str>>,
    /// Every pass recorded, timed or not, in order.
    ran: std::cell::RefCell<Vec<&'static str>>,
    /// The buffer the frame's queries were resolved into ([`Timer::resolve`]).
    resolved: std::cell::RefCell<Option<(String, wgpu::Buffer)>>,
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
        if let Some((key, b)) = self.resolved.borrow_mut().take() {
            self.gpu.release(key, b);
        }
    }
}

impl<'a> Timer<'a> {
    pub(super) fn new(gpu: &'a Gpu) -> Timer<'a> {
        let set = gpu.timestamps.then(|| {
            let pooled = gpu
                .query_sets
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .pop();
            pooled.unwrap_or_else(|| {
                gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count: 2 * TIMED_PASSES,
                })
            })
        });
        Timer {
            gpu,
            set,
            names: Default::default(),
            ran: Default::default(),
            resolved: Default::default(),
        }
    }

    /// The next pass's pair of queries, where the device has timestamps and the set has room.
    fn next(&self, name: &'static str) -> Option<(&wgpu::QuerySet, u32, u32)> {
        self.ran.borrow_mut().push(name);
        let set = self.set.as_ref()?;
        let mut names = self.names.borrow_mut();
        if names.len() as u32 >= TIMED_PASSES {
            return None;
        }
        names.push(name);
        let i = 2 * (names.len() as u32 - 1);
        Some((set, i, i + 1))
    }

    /// The timestamps a render pass named `name` writes.
    pub(super) fn render(&self, name: &'static str) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        self.next(name)
            .map(|(query_set, b, e)| wgpu::RenderPassTimestampWrites {
                query_set,
                beginning_of_pass_write_index: Some(b),
                end_of_pass_write_index: Some(e),
            })
    }

    /// The timestamps a compute pass named `name` writes.
    pub(super) fn compute(
        &self,
        name: &'static str,
    ) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        self.next(name)
            .map(|(query_set, b, e)| wgpu::ComputePassTimestampWrites {
                query_set,
                beginning_of_pass_write_index: Some(b),
                end_of_pass_write_index: Some(e),
            })
    }

    /// The frame's queries resolved into a buffer, recorded in `enc` after its last pass.
    pub(super) fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        let (Some(set), n) = (self.set.as_ref(), 2 * self.names.borrow().len() as u32) else {
            return;
        };
        if n == 0 {
            return;
        }
        let key = format!("timestamps.resolve {n}");
        let usage = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
        let (buf, _) = self.gpu.acquire(&key, 8 * n as u64, usage);
        enc.resolve_query_set(set, 0..n, &buf, 0);
        if let Some((key, b)) = self.resolved.replace(Some((key, buf))) {
            self.gpu.release(key, b);
        }
    }

    /// Every pass recorded, timed or not (a device without timestamps times none), in order.
    pub(super) fn ran(&self) -> Vec<&'static str> {
        self.ran.borrow().clone()
    }

    /// The passes timed, in the order recorded.
    pub(super) fn names(&self) -> Vec<&'static str> {
        self.names.borrow().clone()
    }

    /// The buffer the frame's queries were resolved into ([`Timer::resolve`]): two ticks a
    /// pass, in the order of [`Timer::names`].
    pub(super) fn resolved(&self) -> Option<wgpu::Buffer> {
        self.resolved.borrow().as_ref().map(|(_, b)| b.clone())
    }

    /// Each pass's milliseconds, in the order recorded, once the frame has run (none where the
    /// device has no timestamps).
    pub(super) fn read(&self) -> Result<Vec<(&'static str, f64)>> {
        let names = self.names.borrow();
        let resolved = self.resolved.borrow();
        let Some((_, buf)) = resolved.as_ref() else {
            return Ok(Vec::new());
        };
        let raw = read_back(self.gpu, buf, 16 * names.len() as u64)?;
        let ticks: Vec<u64> = raw
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8")))
            .collect();
        let period = self.gpu.timestamp_period as f64;
        Ok(names
            .iter()
            .enumerate()
            .map(|(i, &name)| {
                let dt = ticks[2 * i + 1].saturating_sub(ticks[2 * i]);
                (name, dt as f64 * period / 1e6)
            })
            .collect())
    }
}
