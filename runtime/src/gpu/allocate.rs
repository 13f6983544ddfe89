//! The allocation on the device, in one submission (`allocate.wgsl`: weights, a 16-way search
//! for the water level (a bracket of its order of magnitude, then at most 11 rounds), the
//! marks, their prefix sums and the apply; the twin is `alloc::allocate`), from the importance
//! a frame computes (`dkb.rs`, `vkb.rs`) or is given (the count pass and `totals.wgsl` first).
//! [`Gpu::allocate`] runs it alone.

use super::bindings::{allocate, plan};
use super::buffers::{
    FrameBuffers, read_back, read_counts, read_plan, read_u64s, read_words, u32s,
};
use super::passes::{Passes, Phase};
use super::pipelines::{compute_buffer_entry, module, module_from, redeclare};
use super::scan::Scan;
use super::scene::SceneDraws;
use super::timer::Timer;
use super::{FrameOptions, Gpu, Planned, Recording, frame_params, weight_kind};
use crate::alloc::Target;
use crate::budget;
use crate::budget::FragmentBudget;
use crate::error::{Error, Result};
use crate::plan::{PlanBudget, PlanInput};
use crate::scene::{Camera, Scene};
use crate::shared::{TOTALS_WORDS, count_bytes};
use crate::wgsl::{
    ALLOC_GROUP, ALLOC_ROUNDS_WORD, ALLOC_STATE_WORDS, AllocParams, DISPATCH_PER_PIXEL,
    DISPATCH_ROUNDS, DISPATCH_SCAN, Params, PlanParams, SEARCH_PIXELS, SEARCH_ROUNDS,
    alloc_dispatches, dispatch_offset, grid, shaders,
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
    state: wgpu::Buffer,
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

/// What [`Gpu::allocate`] read back.
#[derive(Clone, Debug)]
pub struct GpuAllocation {
    /// n(p), the GPU's own count.
    pub counts: Vec<u32>,
    /// k(p): the bases' differences (k is not stored beside them on the device).
    pub k: Vec<u32>,
    /// Exclusive prefix sums of k (`pixels + 1` entries): the slot bases.
    pub bases: Vec<u32>,
    pub pass_ms: Vec<(&'static str, f64)>,
    /// Rounds the search took (0 when every fragment fits; at most [`SEARCH_ROUNDS`]): its
    /// bracket centres on the device's last answer of the same kind, so a frame allocated like
    /// the one before takes 2.
    pub search_rounds: u32,
}

impl Gpu {
    /// The allocation alone, on the GPU: the count pass, totals, the allocation of k from
    /// `importance` (one value a pixel, meaning what `target` says) at `budget`, and the
    /// prefix sums of k; no capture. The twin is `alloc::allocate` on the returned counts.
    /// Two buffers of 4 bytes a pixel (the count, and one word for the importance, the weights,
    /// k and the slot bases in turn) and the marks (a quarter byte a pixel), so a 7680x4320
    /// frame fits a device whose bindings hold 133 MB (lavapipe's 128 MiB do), where a whole
    /// k-buffer frame does not.
    pub fn allocate(
        &self,
        scene: &Scene,
        cam: &Camera,
        (width, height): (u32, u32),
        importance: &[f32],
        target: Target,
        budget: FragmentBudget,
    ) -> Result<GpuAllocation> {
        let scopes = self.begin_frame((width, height))?;
        let pixels = width * height;
        let px = pixels as u64;
        if importance.len() != pixels as usize {
            return Err(Error::Invalid(format!(
                "{} importance values for {pixels} pixels",
                importance.len()
            )));
        }
        let params = Params {
            uniform_alpha: scene.uniform_opacity.unwrap_or(-1.0),
            ..frame_params(Some(cam), (width, height), [1.0; 3])
        };
        let (inputs, scene_buffers) = self.frame_inputs(scene, &params, false)?;
        let draws = SceneDraws::new(&inputs);
        let timer = Timer::new(self);
        let mut enc = self.device.create_command_encoder(&Default::default());
        draws.opaque(self, &mut enc, Some(&timer));
        let mut fb = FrameBuffers::new(self, &mut enc);
        let uniform = fb.init(
            "params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
            true,
        );
        let opts = FrameOptions::default();
        let passes = Passes::new(self, &timer, uniform, pixels, opts, &draws);
        let p = &self.pipelines;
        let counts = fb.storage("count", count_bytes(px), true)?;
        let base = word_holding(&mut fb, bytemuck::cast_slice(importance));
        let totals = fb.storage("totals", 4 * TOTALS_WORDS as u64, true)?;
        let unused = fb.storage("oit.unused_tail", crate::shared::LEAST_BUFFER_BYTES, true)?;
        // The plan with a pool that holds every fragment: F is the budget's.
        let input = PlanInput {
            layout: budget::VKB,
            pixels: px,
            budget: PlanBudget::Fragments(budget),
            pool_bytes: u64::MAX,
            batches: 1,
            exact_when_cheaper: false,
        };
        let plan = fb.plan_params(&input);
        passes.draw(fb.enc, Phase::Count, &p.count, &[&counts], "count");
        passes.totals_and_plan(fb.enc, &counts, &totals, Some((&plan, &unused)))?;
        let al = passes.allocation(
            &mut fb,
            AllocBuffers {
                counts: &counts,
                weights: &base,
                totals: &totals,
                flags: None,
            },
            weight_kind(target),
        )?;
        passes.allocate(&mut fb, &al)?;
        passes.prefix_sum_of(&mut fb, Scan::InPlace(&base), None)?;
        timer.resolve(fb.enc);
        let taken = fb.into_taken();
        self.submit(enc.finish());
        let bases = u32s(&read_back(self, &base, 4 * (px + 1))?);
        let out = GpuAllocation {
            counts: read_counts(self, &counts, px)?,
            k: bases.windows(2).map(|b| b[1] - b[0]).collect(),
            bases,
            pass_ms: timer.read()?,
            search_rounds: read_words(self, &[(&al.state, 8 * ALLOC_ROUNDS_WORD as u64)])?[0],
        };
        drop((taken, scene_buffers));
        scopes.end()?;
        Ok(out)
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
            let mut src = shaders::source("allocate").expect("known pass");
            redeclare(
                &mut src,
                "allocate",
                "const SEARCH_COPIES: u32 = 1u;",
                "const SEARCH_COPIES: u32 = 32u;",
            );
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
    super::pipelines::note_built();
    super::pipelines::record_pipeline(entry, m, serde_json::json!({ "compute": entry }));
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
fn word_holding(fb: &mut FrameBuffers<'_, '_>, values: &[u32]) -> wgpu::Buffer {
    let words: Vec<u32> = values.iter().copied().chain([0]).collect();
    fb.init(
        "oit.offsets",
        bytemuck::cast_slice(&words),
        wgpu::BufferUsages::STORAGE,
        true,
    )
}

impl Gpu {
    /// The frame's plan (plan.wgsl) for each of `cases`, an input and a frame's occupancy,
    /// run on the device alone: what the tests hold to its twin, [`crate::plan::plan`]. Each
    /// plan as the pass writes it ([`crate::plan::Plan::from_words`]: its `batches` 0, the
    /// host's to know).
    pub fn plan(
        &self,
        cases: &[(PlanInput, crate::budget::Occupancy)],
    ) -> Result<Vec<crate::plan::Plan>> {
        let scopes = self.begin_frame((1, 1))?;
        let storage = |label: &str, words: &[u32]| {
            let b = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 4 * words.len() as u64,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.queue.write_buffer(&b, 0, bytemuck::cast_slice(words));
            b
        };
        let p = &self.pipelines.plan;
        let mut enc = self.device.create_command_encoder(&Default::default());
        let mut outputs = Vec::new();
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(p);
            for (input, occ) in cases {
                let w = |v: u64| v.min(u32::MAX as u64) as u32;
                // The count's totals, and as many records marked as deeper pixels (a frame that
                // marks its own).
                let mut words = [0; crate::shared::TOTALS_WORDS as usize];
                for (at, v) in [
                    (crate::shared::TOTAL_FRAGMENTS, occ.fragments),
                    (crate::shared::TOTAL_COVERED, occ.covered),
                    (crate::shared::TOTAL_DEEP, occ.deep),
                    (crate::shared::TOTAL_DEEPER, occ.deeper),
                    (crate::shared::TOTAL_RECORDS, occ.deeper),
                ] {
                    words[at as usize] = w(v);
                }
                let totals = storage("plan.totals", &words);
                let batch = storage("plan.batch", &[0; crate::shared::BATCH_WORDS as usize]);
                let params = self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("plan.params"),
                    size: std::mem::size_of::<PlanParams>() as u64,
                    usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                self.queue
                    .write_buffer(&params, 0, bytemuck::bytes_of(&PlanParams::of(input)));
                let g = self.bind_at(
                    &p.get_bind_group_layout(0),
                    &[
                        (plan::TOTALS, &totals),
                        (plan::BATCH, &batch),
                        (plan::PLAN, &params),
                    ],
                );
                pass.set_bind_group(0, &g, &[]);
                pass.dispatch_workgroups(1, 1, 1);
                outputs.push((totals, batch));
            }
        }
        self.submit(enc.finish());
        let mut plans = Vec::with_capacity(cases.len());
        for (totals, batch) in &outputs {
            plans.push(read_plan(self, totals, batch, 0)?);
        }
        scopes.end()?;
        Ok(plans)
    }

    /// u64.wgsl's 64-bit words on the device, for each (a, b, d) of `cases` (d > 0): a + b,
    /// a - b (wrapping), the whole product of their low words, a * d (wrapping), a / d,
    /// a < b (1 or 0), min and max; and a as the nearest f32: what the tests hold to Rust's u64.
    pub fn u64_words(&self, cases: &[(u64, u64, u32)]) -> Result<Vec<([u64; 8], f32)>> {
        const ENTRY: &str = "
@group(0) @binding(0) var<storage, read> ab: array<vec4<u32>>;
@group(0) @binding(1) var<storage, read> divisor: array<u32>;
@group(0) @binding(2) var<storage, read_write> out: array<W>;
@group(0) @binding(3) var<storage, read_write> floats: array<f32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&divisor)) {
        return;
    }
    let a = ab[i].xy;
    let b = ab[i].zw;
    let d = divisor[i];
    out[8u * i] = w_add(a, b);
    out[8u * i + 1u] = w_sub(a, b);
    out[8u * i + 2u] = w_mul(a.x, b.x);
    out[8u * i + 3u] = w_mul_u32(a, d);
    out[8u * i + 4u] = w_div_u32(a, d);
    out[8u * i + 5u] = w_of(select(0u, 1u, w_lt(a, b)));
    out[8u * i + 6u] = w_min(a, b);
    out[8u * i + 7u] = w_max(a, b);
    floats[i] = w_to_f32(a);
}
";
        if cases.is_empty() || cases.iter().any(|c| c.2 == 0) {
            return Err(Error::Invalid(
                "u64_words takes cases with divisors above 0".into(),
            ));
        }
        let scopes = self.begin_frame((1, 1))?;
        let src = format!("{}\n{ENTRY}", crate::wgsl::shaders::U64);
        let m = module_from(&self.device, "u64 words", src);
        let p = super::pipelines::compute_pipeline(&self.device, "u64 words", &m, "main");
        let init = |label: &str, words: &[u32], usage: wgpu::BufferUsages| {
            let b = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 4 * words.len() as u64,
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.queue.write_buffer(&b, 0, bytemuck::cast_slice(words));
            b
        };
        let split = |v: u64| [v as u32, (v >> 32) as u32];
        let ab: Vec<u32> = cases
            .iter()
            .flat_map(|&(a, b, _)| [split(a), split(b)].concat())
            .collect();
        let d: Vec<u32> = cases.iter().map(|c| c.2).collect();
        let storage = wgpu::BufferUsages::STORAGE;
        let ab = init("u64.ab", &ab, storage);
        let d = init("u64.divisor", &d, storage);
        let n = cases.len() as u64;
        let out = init(
            "u64.out",
            &vec![0u32; 16 * n as usize],
            storage | wgpu::BufferUsages::COPY_SRC,
        );
        let floats = init(
            "u64.floats",
            &vec![0u32; n as usize],
            storage | wgpu::BufferUsages::COPY_SRC,
        );
        let g = self.bind(&p.get_bind_group_layout(0), &[&ab, &d, &out, &floats]);
        let mut enc = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&p);
            pass.set_bind_group(0, &g, &[]);
            pass.dispatch_workgroups(n.div_ceil(64) as u32, 1, 1);
        }
        self.submit(enc.finish());
        let words = read_u64s(self, &out, 8 * n)?;
        let floats = u32s(&read_back(self, &floats, 4 * n)?);
        scopes.end()?;
        Ok(words
            .chunks_exact(8)
            .zip(floats)
            .map(|(c, f)| (c.try_into().expect("8"), f32::from_bits(f)))
            .collect())
    }
}
