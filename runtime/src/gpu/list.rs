//! The budgeted per-pixel linked list, as Bevy ships it: `list_store.wgsl` (geometry: a node a
//! fragment from one atomic counter while the frame's F nodes last, the rest dropped) ->
//! `list_resolve.wgsl` (each pixel's nearest `list_sorted` sorted and blended over the rest's
//! hybrid tail; twin `composite::hybrid_sorted` of the kept fragments). With diagnostics, the
//! fragments the list kept are read back as the frame's fragments, and the counter as the
//! fragments that arrived.

use super::Recording;
use super::bindings::list_resolve;
use super::buffers::{FrameStatus, read_back, read_u64s, read_words, u32s};
use super::passes::{Phase, Resolve, at, entries};
use crate::error::Result;
use crate::fragment::FragmentLists;

impl Recording<'_, '_, '_> {
    /// The list's store of at most `nodes` fragments and its resolve.
    pub(super) fn linked_list(&mut self, nodes: u64, size: (u32, u32)) -> Result<()> {
        let (width, height) = size;
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let fb = &mut self.fb;
        let status = fb.storage("status", FrameStatus::BYTES, true)?;
        let heads = fb.storage("list.heads", 4 * px, true)?;
        // The pool, allocated whole: 12 bytes a node.
        let next = fb.storage("list.next", 4 * nodes, true)?;
        let keys = fb.storage("list.keys", 8 * nodes, true)?;
        let counter = fb.storage("list.counter", crate::shared::LEAST_BUFFER_BYTES, true)?;
        // A tint word a node where the frame stores them (4 bytes more).
        let (tints, tinted) = fb.tints("list", nodes, self.words.any())?;
        let tinted_glass = self.words.tints();
        let (store, resolve) = gpu.extras().list();
        passes.draw(
            fb.enc,
            Phase::ListStore,
            store,
            &[&heads, &next, &keys, &counter, &tints],
            "store",
        );
        let mut group = entries(&[passes.params(), &heads, &next, &keys]);
        group.extend([
            at(list_resolve::STATUS, &status),
            at(list_resolve::TINTS, &tints),
        ]);
        passes.resolve(fb.enc, Resolve::List, resolve, group, "sort and blend");
        self.out.status = Some(status);
        if !passes.opts.diagnostics {
            return Ok(());
        }
        self.out.deferred.push(Box::new(move |gpu, out| {
            let arrived = read_words(gpu, &[(&counter, 0)])?[0] as u64;
            let heads = u32s(&read_back(gpu, &heads, 4 * px)?);
            let stored = arrived.min(nodes);
            let next = u32s(&read_back(gpu, &next, 4 * stored)?);
            let keys = read_u64s(gpu, &keys, stored)?;
            let tints = match tinted {
                true => u32s(&read_back(gpu, &tints, 4 * stored)?),
                false => Vec::new(),
            };
            let mut fl = FragmentLists {
                width,
                height,
                tinted_glass,
                ..Default::default()
            };
            fl.offsets.push(0);
            for &head in &heads {
                let mut node = head;
                // A list longer than the nodes stored is a broken one: stop there.
                let mut left = stored;
                while node != 0 && left > 0 {
                    let key = keys[node as usize - 1];
                    let word = match tinted {
                        true => tints[node as usize - 1],
                        false => crate::fragment::CLEAR,
                    };
                    let (rgba, tint) = crate::fragment::stored_fragment(key as u32, word);
                    fl.depth.push(f32::from_bits((key >> 32) as u32));
                    fl.rgba.push(rgba);
                    if tinted {
                        fl.tint.push(tint);
                    }
                    fl.primitive.push(0);
                    node = next[node as usize - 1];
                    left -= 1;
                }
                fl.offsets.push(fl.depth.len() as u32);
            }
            out.fragments = Some(fl);
            out.list_arrived = Some(arrived);
            Ok(())
        }));
        Ok(())
    }
}
