//! The allocation on the device, in one submission (`allocate.wgsl`: weights, a 16-way search
//! for the water level (a bracket of its order of magnitude, then at most 11 rounds), the
//! marks, their prefix sums and the apply; the twin is `alloc::allocate`), from the importance
//! a frame computes (`dkb.rs`, `vkb.rs`) or is given (the count pass and `totals.wgsl` first).
//! [`Gpu::allocate`] runs it alone.

use super::bindings::allocate;
use super::buffers::FrameBuffers;
use super::passes::{Passes, Phase};
use super::scan::Scan;
use super::shader::{compute_buffer_entry, module, module_from};
use super::{Planned, Recording, weight_kind};
use crate::alloc::Target;
use crate::budget;
use crate::error::{Error, Result};
use crate::shared::{TOTALS_WORDS, count_bytes};
use crate::wgsl::{
    ALLOC_GROUP, ALLOC_STATE_WORDS, AllocParams, DISPATCH_PER_PIXEL, DISPATCH_ROUNDS,
    DISPATCH_SCAN, SEARCH_PIXELS, SEARCH_ROUNDS, alloc_dispatches, dispatch_offset, grid, shaders,
};

/// Per-pixel importance on the device and what the allocation needs beside it.
pub(super) struct Importance {
    pub(super) counts: wgpu::Buffer,
    /// Importance in, the allocation's fixed-point weights and k in place, then the slot bases
    /// ([`Recording::pixel_word`]).
    pub(super) importance: wgpu::Buffer,
    /// The frame's totals and its plan (plan.wgsl), which the allocation reads F from.
    pub(super) totals: wgpu::Buffer,
    /// Whether a pass computed the importance (read back with diagnostics; zeros where the
    /// frame keeps every fragment and its client knew it).
    pub(super) computed: bool,
    /// The weight kind (`Alloc.kind`, [`weight_kind`]).
    pub(super) kind: u32,
    /// A buffer no longer needed of at least [`budget::marks_bytes`], to hold the allocation's
    /// marks.
    pub(super) marks: Option<wgpu::Buffer>,
    /// Buffers no longer needed by the capture, for the per-pixel tail it binds unused.
    pub(super) reuse: Option<Reuse>,
}

/// What [`Recording::pixel_word`] holds when it is taken.
pub(super) enum Word<'v> {
    /// These values (uploaded k).
    Holding(&'v [u32]),
    /// Whatever it held: every pixel's word is written before any pass reads it (by the
    /// importance pass, or the uploaded importance), and the last entry by the prefix sum.
    Written,
}

/// Per-pixel buffers whose contents are read by the time of the capture.
pub(super) struct Reuse {
    /// 16 bytes at least.
    pub(super) tail: wgpu::Buffer,
    /// 16 bytes at least.
    pub(super) tail_count: wgpu::Buffer,
    /// The slot pool, made before the capture (DKB's: it holds the records and the marks
    /// first), cleared there; else the allocation makes it at the frame's pool bytes.
    pub(super) pool: Option<wgpu::Buffer>,
}

impl Recording<'_, '_, '_> {
    /// The frame's one word a pixel for the importance, the allocation's weights and k in turn,
    /// then the slot bases (`pixels + 1` entries, `oit.offsets`; k is their difference),
    /// holding what `word` says.
    pub(super) fn pixel_word(&mut self, word: Word) -> Result<wgpu::Buffer> {
        let px = self.px;
        match word {
            Word::Holding(v) => Ok(word_holding(&mut self.fb, v)),
            Word::Written => self.fb.storage_kept("oit.offsets", 4 * (px + 1), true),
        }
    }

    /// The count, totals and plan for importance computed elsewhere, uploaded into the
    /// frame's word (by the queue, before the frame's first command: `Gpu::render` alone).
    pub(super) fn uploaded_importance(
        &mut self,
        imp: &[f32],
        target: Target,
        planned: &Planned,
    ) -> Result<Importance> {
        let (gpu, passes, px) = (self.passes.gpu, self.passes, self.px);
        let p = &gpu.pipelines;
        if imp.len() as u64 != px {
            return Err(Error::Invalid(format!(
                "{} importance values for {px} pixels",
                imp.len()
            )));
        }
        let importance = self.pixel_word(Word::Written)?;
        gpu.queue
            .write_buffer(&importance, 0, bytemuck::cast_slice(imp));
        let fb = &mut self.fb;
        let counts = fb.storage("count", count_bytes(px), true)?;
        let totals = fb.storage("totals", 4 * TOTALS_WORDS as u64, true)?;
        let unused = fb.storage("oit.unused_tail", crate::shared::LEAST_BUFFER_BYTES, true)?;
        let plan = fb.plan_params(&planned.input);
        passes.draw(fb.enc, Phase::Count, &p.count, &[&counts], "count");
        passes.totals_and_plan(fb.enc, &counts, &totals, Some((&plan, &unused)))?;
        Ok(Importance {
            counts,
            importance,
            totals,
            computed: false,
            kind: weight_kind(target),
            marks: None,
            reuse: Some(Reuse {
                tail: unused.clone(),
                tail_count: unused,
                pool: None,
            }),
        })
    }
}

/// An allocation's buffers and bind groups (taken whether or not the frame records it, so a
/// frame's memory is the same either way).
pub(super) struct Allocation {
    /// The marks, then their exclusive prefix sums in place.
    flags: wgpu::Buffer,
    dispatches: wgpu::Buffer,
    /// The search's state (allocate.wgsl), kept from frame to frame.
    pub(super) state: wgpu::Buffer,
    setup_group: wgpu::BindGroup,
    group: wgpu::BindGroup,
    grid: (u32, u32),
}

impl<'a> Passes<'a> {
    /// The allocation (allocate.wgsl) of `b` at `budget`: its buffers and bind groups, for
    /// [`Passes::allocate`] to record.
    pub(super) fn allocation(
        &self,
        fb: &mut FrameBuffers<'_, '_>,
        b: AllocBuffers,
        kind: u32,
    ) -> Result<Allocation> {
        let gpu = self.gpu;
        let a = &gpu.pipelines.allocate;
        let ap = AllocParams { kind, _pad: [0; 3] };
        let params = fb.init(
            "alloc.params",
            bytemuck::bytes_of(&ap),
            wgpu::BufferUsages::UNIFORM,
            true,
        );
        // Not cleared: setup writes every word the search reads but the last two, the answers
        // of the last frame (allocate.wgsl's bracket), which a new buffer holds as zeros.
        let state = fb.storage_kept("alloc.state", 8 * ALLOC_STATE_WORDS as u64, true)?;
        // The marks (a bit a pixel and a prefix count every MARK_BITS pixels) are needed only
        // during the allocation: a buffer the frame no longer needs by then holds them where
        // there is one.
        let flags = match b.flags {
            Some(f) => f.clone(),
            None => fb.storage("alloc.flags", budget::marks_bytes(self.pixels as u64), true)?,
        };
        // The grids of the per-pixel weights and marks, the search rounds and the marks'
        // prefix sum, which setup empties when every fragment fits.
        let (gx, gy) = grid(self.pixels, ALLOC_GROUP);
        let (sx, sy) = grid(self.pixels.div_ceil(SEARCH_PIXELS), ALLOC_GROUP);
        let marks = crate::shared::mark_blocks(self.pixels as u64) as u32;
        let (cx, cy) = grid(marks, budget::SCAN_BLOCK as u32);
        // Setup writes every frame's grids (the host's, the same each frame, are its first).
        let dispatches = fb.init(
            "alloc.dispatches",
            bytemuck::cast_slice(&alloc_dispatches([(gx, gy), (sx, sy), (cx, cy)])),
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
            true,
        );
        let bind = |args: &wgpu::Buffer| {
            gpu.bind_at(
                &a.layout,
                &[
                    (allocate::PARAMS, self.params()),
                    (allocate::ALLOC, &params),
                    (allocate::COUNTS, b.counts),
                    (allocate::W, b.weights),
                    (allocate::STATE, &state),
                    (allocate::FLAGS, &flags),
                    (allocate::TOTALS, b.totals),
                    (allocate::DISPATCHES, args),
                ],
            )
        };
        // Setup and choose write the dispatches' arguments; the dispatches that read them bind
        // the device's placeholder in their place.
        Ok(Allocation {
            setup_group: bind(&dispatches),
            group: bind(&gpu.pipelines.placeholder),
            flags,
            dispatches,
            state,
            grid: (gx, gy),
        })
    }

    /// `al` recorded into `enc`: setup, weights, 12 rounds of search and choose, mark (one
    /// timed pass), the prefix of the marks, apply (another). Returns the search's variant
    /// ([`GpuFrame::variants`]).
    pub(super) fn allocate(
        &self,
        fb: &mut FrameBuffers<'_, '_>,
        al: &Allocation,
    ) -> Result<&'static str> {
        let a = &self.gpu.pipelines.allocate;
        let (search, variant) = a.search_for(&self.gpu.device, self.opts.tuning.spread_search);
        let (per_pixel, rounds, scan) = (
            dispatch_offset(DISPATCH_PER_PIXEL),
            dispatch_offset(DISPATCH_ROUNDS),
            dispatch_offset(DISPATCH_SCAN),
        );
        let dispatches = &al.dispatches;
        self.compute(fb.enc, "allocation", |pass| {
            pass.set_bind_group(0, &al.setup_group, &[]);
            pass.set_pipeline(&a.setup);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_bind_group(0, &al.group, &[]);
            pass.set_pipeline(&a.weights);
            pass.dispatch_workgroups_indirect(dispatches, per_pixel);
            // Choose binds the dispatches' arguments, to empty the rounds' grid once the search
            // has found its answer.
            for _ in 0..SEARCH_ROUNDS {
                pass.set_bind_group(0, &al.group, &[]);
                pass.set_pipeline(search);
                pass.dispatch_workgroups_indirect(dispatches, rounds);
                pass.set_bind_group(0, &al.setup_group, &[]);
                pass.set_pipeline(&a.choose);
                pass.dispatch_workgroups(1, 1, 1);
            }
            pass.set_bind_group(0, &al.group, &[]);
            pass.set_pipeline(&a.mark);
            pass.dispatch_workgroups_indirect(dispatches, per_pixel);
        });
        self.prefix_sum_of(fb, Scan::Marks(&al.flags), Some((dispatches, scan)))?;
        let (gx, gy) = al.grid;
        self.compute(fb.enc, "allocation apply", |pass| {
            pass.set_bind_group(0, &al.group, &[]);
            pass.set_pipeline(&a.apply);
            pass.dispatch_workgroups(gx, gy, 1);
        });
        Ok(variant)
    }
}

/// The allocation's entry points (shaders/allocate.wgsl), sharing one explicit layout.
pub(super) struct Allocate {
    pub(super) layout: wgpu::BindGroupLayout,
    pub(super) weights: wgpu::ComputePipeline,
    pub(super) setup: wgpu::ComputePipeline,
    pub(super) search: wgpu::ComputePipeline,
    /// The search adding into 32 copies of the workgroup's totals ([`super::Tuning::spread_search`],
    /// off by default): built on first use.
    search_spread: std::sync::OnceLock<wgpu::ComputePipeline>,
    pipeline_layout: wgpu::PipelineLayout,
    pub(super) choose: wgpu::ComputePipeline,
    pub(super) mark: wgpu::ComputePipeline,
    pub(super) apply: wgpu::ComputePipeline,
}

/// The buffers the allocation reads and writes.
pub(super) struct AllocBuffers<'a> {
    pub(super) counts: &'a wgpu::Buffer,
    /// Importance in; the fixed-point weights in place, then k in place (`pixels + 1` words:
    /// the scan then turns k into the slot bases in place).
    pub(super) weights: &'a wgpu::Buffer,
    pub(super) totals: &'a wgpu::Buffer,
    /// A dead buffer of at least [`budget::marks_bytes`] to hold the marks (else one is
    /// allocated).
    pub(super) flags: Option<&'a wgpu::Buffer>,
}

impl Allocate {
    pub(super) fn new(device: &wgpu::Device) -> Allocate {
        let entry = compute_buffer_entry;
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("allocate"),
            entries: &[
                entry(allocate::PARAMS, wgpu::BufferBindingType::Uniform),
                entry(allocate::ALLOC, wgpu::BufferBindingType::Uniform),
                entry(
                    allocate::COUNTS,
                    wgpu::BufferBindingType::Storage { read_only: true },
                ),
                entry(allocate::W, rw),
                entry(allocate::STATE, rw),
                entry(allocate::FLAGS, rw),
                entry(
                    allocate::TOTALS,
                    wgpu::BufferBindingType::Storage { read_only: true },
                ),
                entry(allocate::DISPATCHES, rw),
            ],
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("allocate"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let m = module(device, "allocate");
        let make = |entry: &str| pipeline(device, &pl, &m, entry);
        Allocate {
            weights: make("weights"),
            setup: make("setup"),
            search: make("search"),
            search_spread: Default::default(),
            choose: make("choose"),
            mark: make("mark"),
            apply: make("apply"),
            layout,
            pipeline_layout: pl,
        }
    }

    /// The search as [`super::Tuning::spread_search`] asks for it, and its variant's name.
    pub(super) fn search_for(
        &self,
        device: &wgpu::Device,
        spread: bool,
    ) -> (&wgpu::ComputePipeline, &'static str) {
        if !spread {
            return (&self.search, "allocation search: one copy of the totals");
        }
        let p = self.search_spread.get_or_init(|| {
            let copies = [("SEARCH_COPIES", shaders::Value::U32(32))];
            let src = shaders::source_with("allocate", &copies).expect("allocate's definition");
            let m = module_from(device, "allocate (spread search)", src);
            pipeline(device, &self.pipeline_layout, &m, "search")
        });
        (p, "allocation search: 32 copies of the totals")
    }
}

/// One of allocate.wgsl's entry points on the allocation's layout.
fn pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    m: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    super::shader::note_built();
    super::shader::record_pipeline(entry, m, serde_json::json!({ "compute": entry }));
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: Some(layout),
        module: m,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// The per-pixel word (`oit.offsets`) holding `values` and one word more (zero), so it can
/// hold the slot bases' `pixels + 1` entries in place.
pub(super) fn word_holding(fb: &mut FrameBuffers<'_, '_>, values: &[u32]) -> wgpu::Buffer {
    let words: Vec<u32> = values.iter().copied().chain([0]).collect();
    fb.init(
        "oit.offsets",
        bytemuck::cast_slice(&words),
        wgpu::BufferUsages::STORAGE,
        true,
    )
}
