//! The exact A-buffer and MLAB: `abuffer_count.wgsl` (geometry) -> `scan.wgsl` (offsets) ->
//! `abuffer_store.wgsl` (geometry, exact memory: the pool of 8-byte capture keys is sized from
//! the count, whose buffer then serves as the store's cursors) -> `abuffer_resolve.wgsl` (sort
//! and blend; twin `composite::exact_sorted`) or `mlab_resolve.wgsl` (fragments in submission
//! order into m blending rows; twin `composite::mlab_pixel`, which needs each fragment's
//! submission index, stored beside its key for MLAB and for the tests' readback). The sorts
//! are `sort.wgsl`.

use super::Recording;
use super::buffers::{FrameStatus, read_back, read_u64s, read_words, u32s};
use crate::budget::Occupancy;
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

/// The count pass and its prefix sum, with the frame's fragment count read back: what the
/// A-buffer sizes its pool from, and what an allocated k-buffer decides by whether the exact
/// A-buffer is no dearer than its own reservation ([`super::FrameOptions::exact_when_cheaper`]);
/// where it is not, the method takes these two buffers as its count and slot bases.
pub(super) struct Counted {
    /// n(p).
    pub(super) counts: wgpu::Buffer,
    /// The exclusive prefix sums of n (`pixels + 1` entries).
    pub(super) offsets: wgpu::Buffer,
    /// The frame's fragments.
    pub(super) total: u64,
    /// Where asked for, the frame's occupancy (totals.wgsl) and the words it was read from
    /// (fragments, covered, max count, deep, an unused word, deeper; 24 bytes read by the host
    /// to decide, like a
    /// staging buffer: not the method's memory), which DKB then copies as its totals.
    pub(super) occupancy: Option<(Occupancy, wgpu::Buffer)>,
}

impl Recording<'_, '_> {
    /// The count and its prefix sum, submitted, and the frame's fragments read back (the
    /// offsets' last entry); with `occupancy`, the count's totals too, in the same submission
    /// and readback: for the decision between the exact A-buffer and an allocated k-buffer
    /// whose tails the occupancy bounds.
    pub(super) fn count(&mut self, occupancy: bool) -> Result<Counted> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let (fb, enc) = (&mut self.fb, &mut self.enc);
        let counts = fb.storage("abuf.count", count_bytes(px), true)?;
        let offsets = fb.storage("abuf.offsets", 4 * (px + 1), true)?;
        passes.draw(enc, &gpu.pipelines.count, &[&counts], "count");
        passes.prefix_sum(enc, fb, &counts, &offsets)?;
        let totals = match occupancy {
            true => Some(fb.storage("count.occupancy.readback", 24, false)?),
            false => None,
        };
        if let Some(t) = &totals {
            passes.totals(enc, &counts, t);
        }
        fb.submit(enc);
        let mut words = vec![(&offsets, 4 * px)];
        if let Some(t) = &totals {
            words.extend([(t, 4), (t, 12), (t, 20)]);
        }
        let w = read_words(gpu, &words)?;
        let total = w[0] as u64;
        let occupancy = totals.map(|t| {
            let occ = Occupancy {
                fragments: total,
                covered: w[1] as u64,
                deep: w[2] as u64,
                deeper: w[3] as u64,
            };
            (occ, t)
        });
        Ok(Counted {
            counts,
            offsets,
            total,
            occupancy,
        })
    }

    /// The A-buffer's passes, blended as `blend` says; returns the image buffer. With
    /// diagnostics, the GPU's fragments are read back (front to back within a pixel).
    pub(super) fn abuffer(
        &mut self,
        blend: Blend,
        width: u32,
        height: u32,
    ) -> Result<wgpu::Buffer> {
        let counted = self.count(false)?;
        self.abuffer_counted(counted, blend, width, height)
    }

    /// [`Recording::abuffer`] after its count.
    pub(super) fn abuffer_counted(
        &mut self,
        Counted {
            counts,
            offsets,
            total,
            ..
        }: Counted,
        blend: Blend,
        width: u32,
        height: u32,
    ) -> Result<wgpu::Buffer> {
        let mlab = blend == Blend::Mlab;
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let (fb, enc) = (&mut self.fb, &mut self.enc);
        // The per-pixel sorts (sort and blend, MLAB) report a near loop limit here, and a
        // pixel too deep for any method.
        let status = fb.storage("status", FrameStatus::BYTES, true)?;
        let image = fb.storage("application.image", 16 * px, false)?;
        // The count, read by the prefix sum, serves as the store's cursors.
        enc.clear_buffer(&counts, 0, None);
        // Exact memory: the pool holds what the count found, a capture key each.
        let keys = fb.storage("abuf.keys", 8 * total, true)?;
        // Submission indices for MLAB's order (counted: its pipeline's), and for the tests'
        // readback (not counted, like the readback copies); else an empty binding.
        let none = fb.storage("abuf.no_primitives", 16, true)?;
        let primitives = if mlab || self.passes.opts.diagnostics {
            fb.storage("abuf.primitives", 4 * total, mlab)?
        } else {
            none
        };
        passes.draw(
            enc,
            &p.store,
            &[&offsets, &counts, &keys, &primitives],
            "store",
        );
        let (resolve, name) = match blend {
            Blend::Mlab => (gpu.extras().mlab_resolve(), "mlab blend"),
            Blend::Exact => (&p.abuffer_resolve, "sort and blend"),
        };
        let bufs = [
            passes.params(),
            &offsets,
            &keys,
            &image,
            &status,
            &primitives,
        ];
        passes.resolve(enc, resolve, &bufs, 3, name);
        fb.submit(enc);
        if self.passes.opts.diagnostics {
            let mut fl = FragmentLists {
                width,
                height,
                offsets: u32s(&read_back(gpu, &offsets, 4 * (px + 1))?),
                ..Default::default()
            };
            for key in read_u64s(gpu, &keys, total, false)? {
                fl.depth.push(f32::from_bits((key >> 32) as u32));
                fl.rgba.push(crate::fragment::unpack_rgba8(key as u32));
            }
            fl.primitive = u32s(&read_back(gpu, &primitives, 4 * total)?);
            self.out.fragments = Some(fl);
        }
        self.out.status = Some(status);
        Ok(image)
    }
}
