//! A frame's buffers: taken from the renderer's pool and given back ([`FrameBuffers`]), read
//! back through pooled staging buffers, and what a frame reads back for the tests
//! ([`Readback`]).

use super::Gpu;
use crate::error::{Error, GpuError, Result};
use crate::fragment::FragmentLists;
use crate::importance::PixelStats;
use crate::shared::{
    BATCH_LISTED, BATCH_ROWS_BEFORE, BATCH_SIZE, BATCH_WORDS, LEAST_BUFFER_BYTES, count_bytes,
};

pub(super) struct FrameBuffers<'a, 'e> {
    pub(super) gpu: &'a Gpu,
    /// The encoder the frame records into (its client's): a reused buffer is cleared there,
    /// in order, before the pass that takes it.
    pub(super) enc: &'e mut wgpu::CommandEncoder,
    pub(super) allocated: u64,
    /// The prefix sum's block totals, created on first use and shared by every scan.
    pub(super) scan_blocks: Option<wgpu::Buffer>,
    /// The buffers this frame took (pool key, buffer), put back when it ends.
    pub(super) taken: Taken<'a>,
}

/// A frame's buffers, given back to the renderer's pool when dropped: after the client has
/// read what it reads of them (a later frame on the same device takes them again).
pub(super) struct Taken<'a> {
    gpu: &'a Gpu,
    buffers: Vec<(String, wgpu::Buffer)>,
}

impl Taken<'_> {
    /// The buffers stay their holder's, never given back to the pool (a scene streamed frame
    /// after frame keeps its uploaded buffers).
    pub(super) fn keep(mut self) {
        self.buffers.clear();
    }
}

impl Drop for Taken<'_> {
    fn drop(&mut self) {
        for (key, b) in self.buffers.drain(..) {
            self.gpu.release(key, b);
        }
    }
}

impl<'a, 'e> FrameBuffers<'a, 'e> {
    pub(super) fn new(gpu: &'a Gpu, enc: &'e mut wgpu::CommandEncoder) -> Self {
        FrameBuffers {
            gpu,
            enc,
            allocated: 0,
            scan_blocks: None,
            taken: Taken {
                gpu,
                buffers: Vec::new(),
            },
        }
    }

    /// The prefix sums' block totals for a frame of `px` pixels, made on first use and shared
    /// by every scan of the frame.
    pub(super) fn scan_blocks(&mut self, px: u64) -> Result<wgpu::Buffer> {
        if self.scan_blocks.is_none() {
            let groups = px.div_ceil(crate::budget::SCAN_BLOCK);
            self.scan_blocks = Some(self.storage("scan.blocks", 4 * groups, true)?);
        }
        Ok(self.scan_blocks.clone().expect("made above"))
    }

    /// The buffers taken, held until dropped; the encoder is the client's again.
    pub(super) fn into_taken(self) -> Taken<'a> {
        self.taken
    }

    /// A pooled buffer; a label asked for twice in one frame gets two buffers.
    pub(super) fn take(
        &mut self,
        label: &str,
        size: u64,
        usage: wgpu::BufferUsages,
        zero: bool,
    ) -> wgpu::Buffer {
        let nth = self
            .taken
            .buffers
            .iter()
            .filter(|(k, _)| k.rsplit_once('#').map(|(l, _)| l) == Some(label))
            .count();
        let key = format!("{label}#{nth}");
        let (b, reused) = self.gpu.acquire(&key, size, usage);
        if zero && reused {
            self.enc.clear_buffer(&b, 0, None);
        }
        self.taken.buffers.push((key, b.clone()));
        b
    }

    /// A storage buffer of `size` bytes (at least 16), counted in the frame's allocation when
    /// `counted`; an error naming the buffer when the device cannot bind one that large.
    pub(super) fn storage(
        &mut self,
        label: &str,
        size: u64,
        counted: bool,
    ) -> Result<wgpu::Buffer> {
        self.storage_with(label, size, counted, true)
    }

    /// Where the frame stores tint words (`tinted`: its glass tinted, or its colours above
    /// white), a word (tint RGB8, colour exponent above it) for each of `count` fragments,
    /// counted (`{owner}.tints`); else an empty binding, uncounted. Returns it and whether it
    /// holds tints.
    pub(super) fn tints(
        &mut self,
        owner: &str,
        count: u64,
        tinted: bool,
    ) -> Result<(wgpu::Buffer, bool)> {
        let holds = tinted && count > 0;
        Ok(match holds {
            true => (
                self.storage(&format!("{owner}.tints"), 4 * count, true)?,
                true,
            ),
            false => (
                self.storage(&format!("{owner}.no_tints"), LEAST_BUFFER_BYTES, false)?,
                false,
            ),
        })
    }

    /// [`FrameBuffers::storage`], not cleared: it holds what the last frame left in it (zeros
    /// when new), for state a pass carries from frame to frame.
    pub(super) fn storage_kept(
        &mut self,
        label: &str,
        size: u64,
        counted: bool,
    ) -> Result<wgpu::Buffer> {
        self.storage_with(label, size, counted, false)
    }

    fn storage_with(
        &mut self,
        label: &str,
        size: u64,
        counted: bool,
        clear: bool,
    ) -> Result<wgpu::Buffer> {
        let size = size.max(LEAST_BUFFER_BYTES).next_multiple_of(4);
        let limits = self.gpu.device.limits();
        let max = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if size > max {
            return Err(GpuError::BufferTooLarge {
                label: label.to_string(),
                need: size,
                max,
            }
            .into());
        }
        if counted {
            self.allocated += size;
        }
        let usage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST;
        Ok(self.take(label, size, usage, clear))
    }

    /// A buffer holding `bytes` (zero-padded to at least 16 bytes, a multiple of 4).
    /// The uniform of a frame's plan pass (plan.wgsl) for `input`, counted.
    pub(super) fn plan_params(&mut self, input: &crate::plan::PlanInput) -> wgpu::Buffer {
        self.init(
            "plan.params",
            bytemuck::bytes_of(&crate::wgsl::PlanParams::of(input)),
            wgpu::BufferUsages::UNIFORM,
            true,
        )
    }

    pub(super) fn init(
        &mut self,
        label: &str,
        bytes: &[u8],
        usage: wgpu::BufferUsages,
        counted: bool,
    ) -> wgpu::Buffer {
        if counted {
            self.allocated += bytes.len() as u64;
        }
        let size = (bytes.len() as u64)
            .max(LEAST_BUFFER_BYTES)
            .next_multiple_of(4);
        let usage = usage | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let b = self.take(label, size, usage, false);
        if bytes.len() as u64 == size {
            self.gpu.queue.write_buffer(&b, 0, bytes);
        } else {
            let mut padded = bytes.to_vec();
            padded.resize(size as usize, 0);
            self.gpu.queue.write_buffer(&b, 0, &padded);
        }
        b
    }

    /// A render target `label` of format `format` (a colour format, `texel_bytes` a texel)
    /// and the frame's size that later passes read, counted in the frame's allocation (its
    /// texels' bytes); a view of it.
    pub(super) fn target(
        &mut self,
        (label, format, texel_bytes): (&str, wgpu::TextureFormat, u64),
        (width, height): (u32, u32),
    ) -> wgpu::TextureView {
        self.allocated += width as u64 * height as u64 * texel_bytes;
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        let texture = frame_texture(&self.gpu.device, label, (width, height), format, usage);
        texture.create_view(&Default::default())
    }
}

/// A 2-D texture of the frame's size, one level, one sample.
pub(super) fn frame_texture(
    device: &wgpu::Device,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

thread_local! {
    /// Submissions and waits dhoit made on this thread ([`host_syncs`]).
    static HOST_SYNCS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Submissions of its own and waits on the device dhoit has made on this thread so far: a
/// frame recorded into its client's encoder makes none (`Oit::record`, `SceneStream::record`);
/// `Gpu::render` submits its frame and waits for it, and counts first.
pub fn host_syncs() -> u64 {
    HOST_SYNCS.with(|c| c.get())
}

impl Gpu {
    /// Submits `commands` on the queue (counted: [`host_syncs`]).
    pub(super) fn submit(&self, commands: wgpu::CommandBuffer) -> wgpu::SubmissionIndex {
        HOST_SYNCS.with(|c| c.set(c.get() + 1));
        self.queue.submit([commands])
    }

    /// Waits for every submission so far (counted: [`host_syncs`]).
    pub(super) fn wait(&self, doing: &'static str) -> Result<()> {
        HOST_SYNCS.with(|c| c.set(c.get() + 1));
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Lost {
                doing,
                message: e.to_string(),
            })?;
        Ok(())
    }
}

pub(super) fn read_back(gpu: &Gpu, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>> {
    read_back_with(gpu, buffer, bytes, <[u8]>::to_vec)
}

/// The first `bytes` of `buffer`, as `read` makes of them straight from the mapped staging
/// buffer (no copy of the bytes first: a frame's image is read in one pass).
pub(super) fn read_back_with<T>(
    gpu: &Gpu,
    buffer: &wgpu::Buffer,
    bytes: u64,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T> {
    let (size, copy) = first_bytes(buffer, bytes);
    staged(gpu, size, copy, |mapped| read(&mapped[..bytes as usize]))
}

/// [`read_back_with`] without blocking ([`staged_async`]).
pub(super) async fn read_back_with_async<T>(
    gpu: &Gpu,
    buffer: &wgpu::Buffer,
    bytes: u64,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T> {
    let (size, copy) = first_bytes(buffer, bytes);
    staged_async(gpu, size, copy, |mapped| read(&mapped[..bytes as usize])).await
}

/// The staging size (whole words) and the copy that read `buffer`'s first `bytes`.
fn first_bytes(
    buffer: &wgpu::Buffer,
    bytes: u64,
) -> (
    u64,
    impl FnOnce(&mut wgpu::CommandEncoder, &wgpu::Buffer) + '_,
) {
    let size = bytes.max(4).next_multiple_of(4);
    let copy = move |enc: &mut wgpu::CommandEncoder, staging: &wgpu::Buffer| {
        enc.copy_buffer_to_buffer(buffer, 0, staging, 0, size)
    };
    (size, copy)
}

/// What a frame's resolve reports in its status buffer (four 32-bit words, common.wgsl's
/// `STATUS_WORDS`): whether a pixel's loops came close to the device's limit, and the pixels
/// over [`crate::raster::MAX_FRAGMENTS_PER_PIXEL`] fragments, if any.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct FrameStatus {
    pub(super) near_loop_limit: bool,
    /// Whether the frame's pool, sized before its count, held fewer of its fragments than it
    /// has (the A-buffer's: the pixels past its end hold none).
    pub(super) pool_short: bool,
    /// (n, pixel index): the largest count of such a pixel, and the largest index of one
    /// (with 32-bit atomics, not always the same pixel's).
    pub(super) too_deep: Option<(u32, u32)>,
}

impl FrameStatus {
    pub(super) const BYTES: u64 = 16;

    pub(super) fn parse(bytes: &[u8]) -> FrameStatus {
        let word = |i: usize| u64::from_le_bytes(bytes[8 * i..8 * i + 8].try_into().expect("8"));
        let deepest = word(1);
        FrameStatus {
            near_loop_limit: word(0) & crate::shared::STATUS_NEAR_LOOP as u64 != 0,
            pool_short: word(0) & crate::shared::STATUS_POOL_SHORT as u64 != 0,
            too_deep: (deepest != 0).then_some(((deepest >> 32) as u32, deepest as u32)),
        }
    }

    /// The frame's error, if it has one: a pixel too deep for any method (as the CPU
    /// rasterizer refuses it), or loops cut short where the device cuts them (`bounded_loops`).
    pub(super) fn check(self, gpu: &Gpu, width: u32) -> Result<()> {
        if let Some((n, p)) = self.too_deep {
            let (x, y) = (p % width, p / width);
            let max = crate::raster::MAX_FRAGMENTS_PER_PIXEL;
            // A count that stopped (counts.wgsl) says only that a pixel had more; a larger one
            // may be another pixel's.
            let deepest = match n <= crate::shared::COUNT_SATURATED {
                true => String::new(),
                false => format!(" (the deepest {n})"),
            };
            return Err(Error::Invalid(format!(
                "pixel ({x}, {y}) has more than {max} fragments{deepest}; at most {max} fit one pixel"
            )));
        }
        if self.near_loop_limit && gpu.bounded_loops {
            return Err(GpuError::LoopLimit {
                adapter: gpu.adapter.clone(),
            }
            .into());
        }
        Ok(())
    }
}

/// A frame's image (its first `bytes`, as `read` makes of them straight from the mapped
/// buffer), read in one copy and one map with its status, which may refuse the frame
/// ([`FrameStatus::check`]; `width` names the pixel): then the image is not read.
pub(super) fn read_frame<T>(
    gpu: &Gpu,
    image: &wgpu::Buffer,
    bytes: u64,
    status: Option<&wgpu::Buffer>,
    width: u32,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T> {
    let at = bytes.next_multiple_of(4);
    let size = at + FrameStatus::BYTES;
    let copy = |enc: &mut wgpu::CommandEncoder, staging: &wgpu::Buffer| {
        enc.copy_buffer_to_buffer(image, 0, staging, 0, at);
        match status {
            Some(s) => enc.copy_buffer_to_buffer(s, 0, staging, at, FrameStatus::BYTES),
            // No status: a frame with nothing to report.
            None => enc.clear_buffer(staging, at, Some(FrameStatus::BYTES)),
        }
    };
    staged(gpu, size, copy, |mapped| {
        FrameStatus::parse(&mapped[at as usize..])
            .check(gpu, width)
            .map(|()| read(&mapped[..bytes as usize]))
    })?
}

/// The plan plan.wgsl wrote: its F and flags in `totals`, the records a batch holds in `batch`;
/// `batches` are the host's to know ([`crate::plan::Plan::from_words`]).
pub(super) fn read_plan(
    gpu: &Gpu,
    totals: &wgpu::Buffer,
    batch: &wgpu::Buffer,
    batches: u64,
) -> Result<crate::plan::Plan> {
    use crate::shared::{PLAN_F_WORD, PLAN_FLAGS_WORD};
    let at = |word: u32| 4 * word as u64;
    let w = read_words(
        gpu,
        &[
            (totals, at(PLAN_F_WORD)),
            (totals, at(PLAN_FLAGS_WORD)),
            (batch, at(BATCH_SIZE)),
        ],
    )?;
    Ok(crate::plan::Plan::from_words([w[0], w[1], w[2]], batches))
}

/// Single words of device buffers (each a buffer and a byte offset, a multiple of 4), read in
/// one copy and one map: a frame's sizes without reading back the buffers they end.
pub(super) fn read_words(gpu: &Gpu, words: &[(&wgpu::Buffer, u64)]) -> Result<Vec<u32>> {
    let size = 4 * words.len().max(1) as u64;
    let copy = |enc: &mut wgpu::CommandEncoder, staging: &wgpu::Buffer| {
        for (i, (buffer, offset)) in words.iter().enumerate() {
            enc.copy_buffer_to_buffer(buffer, *offset, staging, 4 * i as u64, 4);
        }
    };
    staged(gpu, size, copy, |mapped| u32s(&mapped[..4 * words.len()]))
}

/// A pooled staging buffer of `size` bytes that `copy` fills, mapped and given to `read`.
fn staged<T>(
    gpu: &Gpu,
    size: u64,
    copy: impl FnOnce(&mut wgpu::CommandEncoder, &wgpu::Buffer),
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T> {
    let (key, staging) = stage(gpu, size, copy);
    staging.slice(..).map_async(wgpu::MapMode::Read, |_| {});
    gpu.wait("waiting for a submission")?;
    unstage(gpu, key, staging, read)
}

/// [`staged`] without blocking: the future resolves when the staging buffer is mapped (on a
/// page's WebGPU, by the browser's event loop; natively it waits for the submission).
async fn staged_async<T>(
    gpu: &Gpu,
    size: u64,
    copy: impl FnOnce(&mut wgpu::CommandEncoder, &wgpu::Buffer),
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T> {
    let (key, staging) = stage(gpu, size, copy);
    let (tx, rx) = futures_channel::oneshot::channel();
    staging.slice(..).map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    #[cfg(not(target_arch = "wasm32"))]
    gpu.wait("waiting for a submission")?;
    let lost = |message: String| GpuError::Lost {
        doing: "reading back",
        message,
    };
    rx.await
        .map_err(|e| lost(e.to_string()))?
        .map_err(|e| lost(e.to_string()))?;
    unstage(gpu, key, staging, read)
}

/// A pooled staging buffer of `size` bytes, `copy` recorded into it and submitted.
fn stage(
    gpu: &Gpu,
    size: u64,
    copy: impl FnOnce(&mut wgpu::CommandEncoder, &wgpu::Buffer),
) -> (String, wgpu::Buffer) {
    // Staging buffers are pooled by size (the image's is the same every frame).
    let key = format!("readback {size}");
    let usage = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
    let (staging, _) = gpu.acquire(&key, size, usage);
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    copy(&mut enc, &staging);
    gpu.submit(enc.finish());
    (key, staging)
}

/// The mapped staging buffer given to `read`, then unmapped and pooled.
fn unstage<T>(
    gpu: &Gpu,
    key: String,
    staging: wgpu::Buffer,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T> {
    let data = {
        let mapped = staging
            .slice(..)
            .get_mapped_range()
            .map_err(|e| GpuError::Lost {
                doing: "reading back",
                message: e.to_string(),
            })?;
        read(&mapped)
    };
    staging.unmap();
    gpu.release(key, staging);
    Ok(data)
}

/// A 32-bit-a-texel texture's texels (R32 or Depth32Float), row-major, read in one copy.
pub(super) fn read_texture(gpu: &Gpu, texture: &wgpu::Texture) -> Result<Vec<u32>> {
    let (w, h) = (texture.width(), texture.height());
    let row = (4 * w).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let copy = |enc: &mut wgpu::CommandEncoder, staging: &wgpu::Buffer| {
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: Some(h),
                },
            },
            texture.size(),
        )
    };
    staged(gpu, row as u64 * h as u64, copy, |mapped| {
        mapped
            .chunks_exact(row as usize)
            .flat_map(|r| u32s(&r[..4 * w as usize]))
            .collect()
    })
}

/// The per-pixel counts of a frame of `px` pixels in `buffer`, two to a word as the GPU packs
/// them (`shared::count_word`), one a pixel.
pub(super) fn read_counts(gpu: &Gpu, buffer: &wgpu::Buffer, px: u64) -> Result<Vec<u32>> {
    let words = u32s(&read_back(gpu, buffer, count_bytes(px))?);
    Ok(crate::shared::unpack_counts(&words, px))
}

pub(super) fn u32s(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// The first `n` 64-bit words of `b`, read back.
pub(super) fn read_u64s(gpu: &Gpu, b: &wgpu::Buffer, n: u64) -> Result<Vec<u64>> {
    Ok(read_back(gpu, b, 8 * n)?
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().expect("8")))
        .collect())
}

/// A read a frame's pass leaves for after the frame has run, into the frame's readback.
pub(super) type Deferred = Box<dyn FnOnce(&Gpu, &mut Readback) -> Result<()>>;

#[derive(Default)]
pub(super) struct Readback {
    /// Reads left for after the frame has run (the A-buffer's fragments, the slots and tails,
    /// the list's), in order.
    pub(super) deferred: Vec<Deferred>,
    /// The A-buffer's offsets and where in them its fragment total is (the last entry).
    pub(super) counted: Option<(wgpu::Buffer, u64)>,
    /// An allocated k-buffer's totals (its plan's F and flags, plan.wgsl) and its batch words
    /// (the records a batch, DKB's).
    pub(super) plan_buf: Option<(wgpu::Buffer, wgpu::Buffer)>,
    pub(super) fragments: Option<FragmentLists>,
    /// The resolve's status words ([`FrameStatus`]).
    pub(super) status: Option<wgpu::Buffer>,
    pub(super) slots: Option<(Vec<u64>, Vec<u32>, Vec<u32>)>,
    pub(super) counts_buf: Option<wgpu::Buffer>,
    pub(super) importance_buf: Option<wgpu::Buffer>,
    /// DKB: the record marks that place its records (records.wgsl), and the records
    /// (features.wgsl).
    pub(super) stats_bufs: Option<[wgpu::Buffer; 2]>,
    /// DKB: whether its features pass drew, where the host knows it (not recorded: false).
    pub(super) features_drawn: Option<bool>,
    pub(super) vkb_nearest_buf: Option<wgpu::Buffer>,
    /// The pass variants chosen where a layout option chooses ([`GpuFrame::variants`]).
    pub(super) variants: Vec<&'static str>,
    /// DKB: the length of the list of pixels its network ran on.
    pub(super) network_rows_buf: Option<wgpu::Buffer>,
    /// k-buffers: each pixel's tail count after the capture, before the resolve.
    pub(super) capture_counts: Option<Vec<u32>>,
    /// The linked list: the fragments that arrived at its store, kept or dropped.
    pub(super) list_arrived: Option<u64>,
    /// DKB: the batches its records were gathered in, where its features pass drew.
    pub(super) record_batches: Option<u64>,
}

/// What [`GpuFrame`] reports besides the image: importance, DKB's statistics and whether its
/// features pass drew, VKB's nearest facing.
#[derive(Default)]
pub(super) struct Statistics {
    pub(super) importance: Option<Vec<f32>>,
    pub(super) stats: Option<Vec<PixelStats>>,
    pub(super) features_drawn: Option<bool>,
    pub(super) vkb_nearest: Option<(Vec<u32>, Vec<f32>)>,
    pub(super) network_rows: Option<u32>,
    pub(super) plan: Option<crate::plan::Plan>,
}

impl Readback {
    /// Importance, DKB statistics and VKB nearest facing, where the frame computed them (DKB's
    /// statistics where its features pass drew).
    pub(super) fn statistics(&self, gpu: &Gpu, px: u64) -> Result<Statistics> {
        let importance = match &self.importance_buf {
            Some(b) => Some(
                u32s(&read_back(gpu, b, 4 * px)?)
                    .into_iter()
                    .map(f32::from_bits)
                    .collect(),
            ),
            None => None,
        };
        let features_drawn = self.features_drawn;
        let plan = match &self.plan_buf {
            Some((totals, batch)) => {
                let batches = self.record_batches.unwrap_or(1);
                Some(read_plan(gpu, totals, batch, batches)?)
            }
            None => None,
        };
        let network_rows = match &self.network_rows_buf {
            // This batch's list and the batches' before it (totals.wgsl's next_batch).
            Some(b) => {
                let w = u32s(&read_back(gpu, b, 4 * BATCH_WORDS as u64)?);
                Some(w[BATCH_LISTED as usize] + w[BATCH_ROWS_BEFORE as usize])
            }
            None => None,
        };
        let Some(counts) = &self.counts_buf else {
            return Ok(Statistics {
                importance,
                features_drawn,
                network_rows,
                plan,
                ..Default::default()
            });
        };
        let counts = read_counts(gpu, counts, px)?;
        let stats = match &self.stats_bufs {
            Some([marks, records]) if features_drawn != Some(false) => {
                let marks = u32s(&read_back(gpu, marks, crate::budget::marks_bytes(px))?);
                let record = crate::importance::record_indices(&marks, px);
                let words = crate::shared::RECORD_WORDS as usize;
                let held = records.size() / (8 * words as u64);
                let marked = record.iter().flatten().count() as u64;
                let records = read_u64s(gpu, records, words as u64 * marked.min(held))?;
                Some(
                    (0..px as usize)
                        .map(|q| {
                            let Some(r) = record[q].filter(|&r| (r as u64) < marked.min(held))
                            else {
                                // No record (TAIL_WORDS fragments or fewer, or past those the
                                // pool held): nothing gathered.
                                return PixelStats {
                                    count: counts[q],
                                    ..Default::default()
                                };
                            };
                            let w = &records[words * r as usize..words * (r as usize + 1)];
                            let lo = |v: u64| (v & 0xffff_ffff) as u32;
                            PixelStats {
                                count: counts[q],
                                // features.wgsl's nearest words, complemented.
                                nearest: [!lo(w[0]), !((w[0] >> 32) as u32)],
                                // features.wgsl's packing: r and g 24 bits each, then n; b and
                                // the squares; the optical depth and the opacity.
                                color_sum: [
                                    (w[1] & 0xff_ffff) as u32,
                                    ((w[1] >> 24) & 0xff_ffff) as u32,
                                    lo(w[2]),
                                ],
                                color_sq_sum: (w[2] >> 32) as u32,
                                optical_depth: lo(w[3]),
                                alpha_sum: (w[3] >> 32) as u32,
                                // Not gathered: the tails pooled, every pixel is a pair.
                                farthest: [0; 2],
                            }
                        })
                        .collect(),
                )
            }
            _ => None,
        };
        let vkb_nearest = match &self.vkb_nearest_buf {
            Some(b) => {
                let facing = u32s(&read_back(gpu, b, 4 * px)?)
                    .iter()
                    .zip(&counts)
                    .map(|(&v, &c)| {
                        if c > 0 {
                            crate::importance::vkb_key_facing(!v)
                        } else {
                            1.0
                        }
                    })
                    .collect();
                Some((counts.clone(), facing))
            }
            None => None,
        };
        Ok(Statistics {
            importance,
            stats,
            features_drawn,
            vkb_nearest,
            network_rows,
            plan,
        })
    }
}
