//! Entry points that run one stage of the frame alone on the device, for the tests that hold
//! it to its CPU twin: the allocation ([`Gpu::allocate`]), the plan ([`Gpu::plan`]) and
//! u64.wgsl's words ([`Gpu::u64_words`]). Not part of a frame, nor of the documented surface
//! (`#[doc(hidden)]`).

use super::allocate::{AllocBuffers, word_holding};
use super::bindings::plan;
use super::buffers::{
    FrameBuffers, read_back, read_counts, read_plan, read_u64s, read_words, u32s,
};
use super::passes::{Passes, Phase};
use super::scan::Scan;
use super::scene::SceneDraws;
use super::shader::module_from;
use super::timer::Timer;
use super::{FrameOptions, Gpu, frame_params, weight_kind};
use crate::alloc::Target;
use crate::budget;
use crate::budget::FragmentBudget;
use crate::error::{Error, Result};
use crate::plan::{PlanBudget, PlanInput};
use crate::scene::{Camera, Scene};
use crate::shared::{TOTALS_WORDS, count_bytes};
use crate::wgsl::{ALLOC_ROUNDS_WORD, Params, PlanParams};

/// What [`Gpu::allocate`] read back.
#[doc(hidden)]
#[derive(Clone, Debug)]
pub struct GpuAllocation {
    /// n(p), the GPU's own count.
    pub counts: Vec<u32>,
    /// k(p): the bases' differences (k is not stored beside them on the device).
    pub k: Vec<u32>,
    /// Exclusive prefix sums of k (`pixels + 1` entries): the slot bases.
    pub bases: Vec<u32>,
    pub pass_ms: Vec<(&'static str, f64)>,
    /// Rounds the search took (0 when every fragment fits; at most [`crate::wgsl::SEARCH_ROUNDS`]): its
    /// bracket centres on the device's last answer of the same kind, so a frame allocated like
    /// the one before takes 2.
    pub search_rounds: u32,
}

impl Gpu {
    #[doc(hidden)]
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

impl Gpu {
    #[doc(hidden)]
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

    #[doc(hidden)]
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
        let p = super::shader::compute_pipeline(&self.device, "u64 words", &m, "main");
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
