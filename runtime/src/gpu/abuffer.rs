//! The exact A-buffer and MLAB: `abuffer_count.wgsl` (geometry) -> `scan.wgsl` (offsets) ->
//! `abuffer_store.wgsl` (geometry, exact memory: the pool of 8-byte capture keys holds the
//! fragments the frame was sized for, and the count's buffer then serves as the store's
//! cursors) -> `abuffer_resolve.wgsl` (sort and blend; twin `composite::exact_sorted`) or
//! `mlab_resolve.wgsl` (fragments in submission order into m blending rows; twin
//! `composite::mlab_pixel`, which needs each fragment's submission index, stored beside its key
//! for MLAB and for the tests' readback). The sorts are `sort.wgsl`.
//!
//! The pool is sized before the count ([`super::Sizing`]): to the frame's own fragments where
//! its client counted first; in an application's frame to an earlier frame's, where a pixel
//! whose fragments the pool does not hold whole stores none and the frame's status says so
//! (`STATUS_POOL_SHORT`).

use super::bindings::sort;
use super::buffers::{FrameStatus, read_back, read_u64s, u32s};
use super::passes::{Phase, Resolve, at, entries};
use super::{Recording, Sizing};
use crate::error::Result;
use crate::fragment::FragmentLists;
use crate::shared::count_bytes;

/// How the A-buffer's lists are blended.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Blend {
    /// Sorted front to back, exactly.
    Exact,
    /// MLAB's rows, in submission order.
    Mlab,
}

impl Recording<'_, '_, '_> {
    /// The fragments the frame's pool holds.
    fn pool_fragments(&self) -> u64 {
        match self.sizing {
            Sizing::Own(occ) => occ.fragments,
            Sizing::Ahead { fragments, .. } => fragments,
        }
    }

    /// The A-buffer's passes, blended as `blend` says. With diagnostics, the GPU's fragments
    /// are read back after the frame (front to back within a pixel).
    pub(super) fn abuffer(&mut self, blend: Blend, size: (u32, u32)) -> Result<()> {
        let (width, height) = size;
        let mlab = blend == Blend::Mlab;
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let total = self.pool_fragments();
        let fb = &mut self.fb;
        let counts = fb.storage("abuf.count", count_bytes(px), true)?;
        let offsets = fb.storage("abuf.offsets", 4 * (px + 1), true)?;
        passes.draw(fb.enc, Phase::Count, &p.count, &[&counts], "count");
        passes.prefix_sum(fb, &counts, &offsets)?;
        // The per-pixel sorts (sort and blend, MLAB) report a near loop limit here, a pool
        // that held fewer fragments than the frame, and a pixel too deep for any method.
        let status = fb.storage("status", FrameStatus::BYTES, true)?;
        // The count, read by the prefix sum, serves as the store's cursors.
        fb.enc.clear_buffer(&counts, 0, None);
        // Exact memory: the pool holds what the frame was sized for, a capture key each.
        let keys = fb.storage("abuf.keys", 8 * total, true)?;
        // Submission indices for MLAB's order (counted: its pipeline's), and for the tests'
        // readback (not counted, like the readback copies); else an empty binding.
        let none = fb.storage(
            "abuf.no_primitives",
            crate::shared::LEAST_BUFFER_BYTES,
            true,
        )?;
        let primitives = if mlab || passes.opts.diagnostics {
            fb.storage("abuf.primitives", 4 * total, mlab)?
        } else {
            none
        };
        // Each fragment's tint word where the frame stores them (tinted glass, colours above
        // white).
        let (tints, tinted) = fb.tints("abuf", total, self.words.any())?;
        let tinted_glass = self.words.tints();
        passes.draw(
            fb.enc,
            Phase::Store,
            &p.store,
            &[&offsets, &counts, &keys, &primitives, &tints],
            "store",
        );
        let (resolve, own, name) = match blend {
            Blend::Mlab => (Resolve::Mlab, gpu.extras().mlab_resolve(), "mlab blend"),
            Blend::Exact => (Resolve::Abuffer, &p.abuffer_resolve, "sort and blend"),
        };
        let mut group = entries(&[passes.params(), &offsets, &keys]);
        group.extend([
            at(sort::STATUS, &status),
            at(sort::PRIMITIVES, &primitives),
            at(sort::TINTS, &tints),
        ]);
        passes.resolve(fb.enc, resolve, own, group, name);
        self.out.counted = Some((offsets.clone(), 4 * px));
        if passes.opts.diagnostics {
            self.out.deferred.push(Box::new(move |gpu, out| {
                let offsets = u32s(&read_back(gpu, &offsets, 4 * (px + 1))?);
                let stored = offsets.last().map_or(0, |&n| n as u64).min(total);
                let mut fl = FragmentLists {
                    width,
                    height,
                    offsets,
                    tinted_glass,
                    ..Default::default()
                };
                let words = match tinted {
                    true => u32s(&read_back(gpu, &tints, 4 * stored)?),
                    false => Vec::new(),
                };
                for (i, key) in read_u64s(gpu, &keys, stored)?.into_iter().enumerate() {
                    let word = words.get(i).copied().unwrap_or(crate::fragment::CLEAR);
                    let (rgba, tint) = crate::fragment::stored_fragment(key as u32, word);
                    fl.depth.push(f32::from_bits((key >> 32) as u32));
                    fl.rgba.push(rgba);
                    if tinted {
                        fl.tint.push(tint);
                    }
                }
                fl.primitive = u32s(&read_back(gpu, &primitives, 4 * stored)?);
                out.fragments = Some(fl);
                Ok(())
            }));
        }
        self.out.status = Some(status);
        Ok(())
    }
}
