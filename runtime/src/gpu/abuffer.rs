//! The exact A-buffer and MLAB: `abuffer_count.wgsl` (geometry) -> `scan.wgsl` (offsets) ->
//! `abuffer_store.wgsl` (geometry, exact memory: the fragment pool is sized from the count) ->
//! `abuffer_resolve.wgsl` (sort and blend; twin `composite::exact_sorted`) or
//! `mlab_resolve.wgsl` (fragments in submission order into m blending rows; twin
//! `composite::mlab_pixel`). Both sorts are `sort.wgsl`.

use super::*;

impl Recording<'_, '_> {
    /// The A-buffer's passes, or MLAB's when `mlab`; returns the image buffer. With
    /// diagnostics, the GPU's fragments are read back (front to back within a pixel).
    pub(super) fn abuffer(&mut self, mlab: bool, width: u32, height: u32) -> Result<wgpu::Buffer> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        let (fb, enc) = (&mut self.fb, &mut self.enc);
        // The per-pixel sorts (sort and blend, MLAB) report a near loop limit here, and a
        // pixel too deep for any method.
        let status = fb.storage("status", FrameStatus::BYTES, true)?;
        let image = fb.storage("oit.image", 16 * px, true)?;
        let counts = fb.storage("abuf.count", 4 * px, true)?;
        let offsets = fb.storage("abuf.offsets", 4 * (px + 1), true)?;
        let cursor = fb.storage("abuf.cursor", 4 * px, true)?;
        passes.draw(enc, &p.count, &[&counts], "count");
        passes.prefix_sum(enc, fb, &counts, &offsets)?;
        fb.submit(enc);
        // Exact memory: the pool holds what the count found.
        let total = read_words(gpu, &[(&offsets, 4 * px)])?[0] as u64;
        let fragments = fb.storage("abuf.fragments", 16 * total, true)?;
        passes.draw(enc, &p.store, &[&offsets, &cursor, &fragments], "store");
        let (resolve, name) = if mlab {
            (&p.mlab_resolve, "mlab blend")
        } else {
            (&p.abuffer_resolve, "sort and blend")
        };
        passes.resolve(
            enc,
            resolve,
            &[passes.params(), &offsets, &fragments, &image, &status],
            name,
        );
        fb.submit(enc);
        if gpu.diagnostics {
            let mut fl = FragmentLists {
                width,
                height,
                offsets: u32s(&read_back(gpu, &offsets, 4 * (px + 1))?),
                ..Default::default()
            };
            for f in u32s(&read_back(gpu, &fragments, 16 * total)?).chunks_exact(4) {
                fl.depth.push(f32::from_bits(f[0]));
                fl.rgba.push(crate::fragment::unpack_rgba8(f[1]));
                fl.primitive.push(f[2]);
            }
            self.out.fragments = Some(fl);
        }
        self.out.status = Some(status);
        Ok(image)
    }
}
