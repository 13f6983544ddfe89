//! The compiled passes: built once per device ([`Pipelines::new`]), the network's passes per
//! network shape, precision and SKIP_FORCED ([`Variant`], on first use), and the passes only
//! some methods draw (MLAB, WBOIT, MBOIT, the list: [`Gpu::extras`], on first use).

use super::Gpu;
use super::allocate::Allocate;
use super::bindings;
use super::blend::{BlendPass, mboit_fits};
use super::shader::{
    blend_json, compute_buffer_entry, compute_pipeline, module, module_from, note_built,
    record_pipeline, webgpu_name,
};
use crate::error::{GpuError, Result};
use crate::mlp::{Mlp, Precision};
use crate::wgsl::shaders;
use std::sync::OnceLock;

pub(super) struct Pipelines {
    /// The application's opaque pass (opaque.wgsl), first in every frame.
    pub(super) opaque: wgpu::RenderPipeline,
    pub(super) count: wgpu::RenderPipeline,
    pub(super) store: wgpu::RenderPipeline,
    /// DKB's features pass (features.wgsl), in a pass of its own and with the count.
    pub(super) features: wgpu::RenderPipeline,
    pub(super) count_features: wgpu::RenderPipeline,
    /// The passes that use 64-bit integers, built where the device has them
    /// ([`super::wide_features`]).
    pub(super) wide: Option<Wide>,
    pub(super) scan_blocks: wgpu::ComputePipeline,
    /// scan.wgsl's per-block scan of a buffer's own values, in place.
    pub(super) scan_blocks_in_place: wgpu::ComputePipeline,
    pub(super) scan_sums: wgpu::ComputePipeline,
    pub(super) scan_add: wgpu::ComputePipeline,
    /// scan.wgsl built for the allocation's marks (a popcount every MARK_BITS pixels): its
    /// in-place block scan, block sums and add.
    pub(super) scan_marks: [wgpu::ComputePipeline; 3],
    pub(super) abuffer_resolve: wgpu::ComputePipeline,
    pub(super) resolve: wgpu::ComputePipeline,
    /// resolve.wgsl built for frames whose budget holds every fragment (k = n).
    pub(super) resolve_fits: wgpu::ComputePipeline,
    /// The passes only some methods draw, built on first use ([`Gpu::extras`]).
    extras: Extras,
    /// The resolves' `onto` entries an application's frames write its target with, built
    /// once a resolve and target format (app.rs).
    pub(super) onto: std::sync::Mutex<
        std::collections::HashMap<
            (super::passes::Resolve, wgpu::TextureFormat),
            wgpu::ComputePipeline,
        >,
    >,
    pub(super) totals: wgpu::ComputePipeline,
    pub(super) allocate: Allocate,
    /// The frame's plan (plan.wgsl), after the totals.
    pub(super) plan: wgpu::ComputePipeline,
    /// DKB's record marks: a bit for each pixel of more than TAIL_WORDS fragments
    /// (totals.wgsl's mark_records; their prefix sums by [`Pipelines::scan_marks`]).
    pub(super) mark_records: wgpu::ComputePipeline,
    /// n into the first batch of DKB's records (totals.wgsl's record_counts).
    pub(super) record_counts: wgpu::ComputePipeline,
    /// A batch of DKB's records after the first emptied, and the batch moved on (totals.wgsl).
    pub(super) init_records: wgpu::ComputePipeline,
    pub(super) next_batch: wgpu::ComputePipeline,
    /// The network's passes (DKB importance, predict), built for one network shape, precision
    /// and SKIP_FORCED each ([`Variant`]): the default network's at f32 at start-up, the others
    /// when first asked for ([`Gpu::network_pass`]).
    pub(super) variants:
        std::sync::Mutex<std::collections::HashMap<Variant, wgpu::ComputePipeline>>,
    pub(super) network_layout: NetworkLayout,
    pub(super) vkb_count: wgpu::RenderPipeline,
    pub(super) importance_vkb: wgpu::ComputePipeline,
    /// A storage buffer bound in a pass's group where one of its entries binds the buffer it
    /// reads its indirect arguments from, writable in the others (the allocation's dispatches,
    /// the network's): never written there, and no other buffer of the group, since WebGPU
    /// binds a buffer writable once in a dispatch.
    pub(super) placeholder: wgpu::Buffer,
}

/// Bytes of [`Pipelines::placeholder`]: the largest binding it stands for (the allocation's
/// dispatches' arguments).
pub(super) const PLACEHOLDER_BYTES: u64 = 256;
const _: () = assert!(
    4 * (crate::shared::ALLOC_DISPATCHES * crate::shared::DISPATCH_WORDS) as u64
        <= PLACEHOLDER_BYTES
);

/// The passes that use 64-bit integers and atomics: the one-pass capture.
pub(super) struct Wide {
    pub(super) capture: wgpu::RenderPipeline,
    /// capture.wgsl built for frames whose budget holds every fragment (k = n).
    pub(super) capture_fits: wgpu::RenderPipeline,
}

/// The opaque pass's depth attachment, which the transparent passes read as their occluder.
pub(super) const OPAQUE_DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The opaque pass's colour in one 32-bit word, as `fragment::pack_opaque` stores it (0 where
/// no opaque surface covers the pixel; behind.wgsl reads it exactly).
pub(super) const OPAQUE_COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

/// A pass that runs the network, with its constants.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) struct Variant {
    /// "importance_dkb" or "predict".
    pub(super) pass: &'static str,
    pub(super) skip_forced: bool,
    pub(super) precision: Precision,
    /// The network's padded layer sizes ([`crate::mlp::padded_units`]), built into the pass so
    /// its loops have known lengths; (0, 0) reads them from the uniform.
    pub(super) shape: (u32, u32),
    /// The first two layers' weights staged in workgroup memory (SHARED_WEIGHTS).
    pub(super) shared_weights: bool,
    /// With a known shape and the weights in the uniform, the forward written out for that
    /// shape ([`unrolled_forward`]) instead of mlp.wgsl's loops.
    pub(super) unrolled: bool,
    /// Vec4s of the network's weights uniform ([`crate::mlp::uniform_bytes`] / 16).
    pub(super) weight_vec4s: u32,
    /// The entry point: "main" (predict), or importance_dkb's "select_pixels", "args",
    /// "network" (sharing [`NetworkLayout`]).
    pub(super) entry: &'static str,
}

/// The explicit layout importance_dkb's four entry points share (each uses some of it):
/// params, weights, the records, the list, totals (read), the shared word, the record marks
/// and the counts (read), the list's length, the indirect dispatch (written), and the weights again (their binary16 view, which only the
/// f16-math pass reads).
pub(super) struct NetworkLayout {
    pub(super) group: wgpu::BindGroupLayout,
    pub(super) pipeline: wgpu::PipelineLayout,
}

impl NetworkLayout {
    pub(super) fn new(device: &wgpu::Device) -> NetworkLayout {
        use bindings::importance_dkb;
        let entry = compute_buffer_entry;
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let uniform = wgpu::BufferBindingType::Uniform;
        let group = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("importance_dkb"),
            entries: &[
                entry(importance_dkb::PARAMS, uniform),
                entry(bindings::mlp::WEIGHTS, uniform),
                // The records (in the slot pool), then each record's importance in its
                // nearest words' place; after them the list of records the network decides.
                entry(importance_dkb::RECORDS, rw),
                entry(importance_dkb::TOTALS, read),
                // The importance: the frame's shared word.
                entry(importance_dkb::SHARED_WORD, rw),
                // Which pixel has which record, and the counts (gather reads them).
                entry(importance_dkb::RECORD_MARKS, read),
                entry(importance_dkb::COUNT, read),
                entry(importance_dkb::LIST_LEN, rw),
                entry(importance_dkb::DISPATCH, rw),
                // The weights again, read as binary16 by the f16-math pass (mlp::Precision).
                entry(WEIGHTS_H, uniform),
            ],
        });
        let pipeline = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("importance_dkb"),
            bind_group_layouts: &[Some(&group)],
            immediate_size: 0,
        });
        NetworkLayout { group, pipeline }
    }
}

impl Variant {
    pub(super) fn pipeline(
        self,
        device: &wgpu::Device,
        layout: &NetworkLayout,
    ) -> wgpu::ComputePipeline {
        let label = format!(
            "{} {} {:?} {} {:?} {:?} {:?}",
            self.pass,
            self.entry,
            self.skip_forced,
            self.precision,
            self.shape,
            self.shared_weights,
            self.unrolled
        );
        let m = module_from(device, &label, self.source());
        if self.pass != "importance_dkb" {
            return compute_pipeline(device, &label, &m, self.entry);
        }
        note_built();
        record_pipeline(&label, &m, serde_json::json!({ "compute": self.entry }));
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(&label),
            layout: Some(&layout.pipeline),
            module: &m,
            entry_point: Some(self.entry),
            compilation_options: Default::default(),
            cache: None,
        })
    }

    /// The pass `pass` for network `m`, its sizes built in.
    pub(super) fn for_network(pass: &'static str, m: &Mlp, skip_forced: bool) -> Variant {
        let p = |h| crate::mlp::padded_units(h) as u32;
        Variant {
            pass,
            skip_forced,
            precision: m.precision,
            shape: (p(m.h1), p(m.h2)),
            weight_vec4s: (m.uniform_bytes() / 16) as u32,
            shared_weights: false,
            unrolled: true,
            entry: "main",
        }
    }

    /// The network's form in this pass, as [`Variant::source`] builds it and
    /// [`GpuFrame::variants`] names it: written out for its shape at binary16 (f16-math has
    /// that one form), its weights staged in workgroup memory, written out for its shape, or the
    /// loop over any shape.
    pub(super) fn form(&self) -> &'static str {
        if self.precision == Precision::F16Math {
            "network: written out at binary16"
        } else if self.shared_weights {
            "network: weights in workgroup memory"
        } else if self.unrolled && self.shape.0 != 0 {
            "network: written out"
        } else {
            "network: loop over any shape"
        }
    }

    /// Its source: the pass composed with this variant's definitions and, where it is
    /// written out for its shape, that forward in place of mlp.wgsl's loops.
    pub(super) fn source(self) -> String {
        use shaders::Value::{Bool, U32};
        let form = self.form();
        let half_math = self.precision == Precision::F16Math;
        let (p1, p2) = self.shape;
        assert!(
            !half_math || p1 != 0,
            "the f16-math network pass is built for its network's shape"
        );
        let mut defs = vec![
            ("F16_WEIGHTS", Bool(self.precision.half_weights())),
            (
                "SHARED_WEIGHTS",
                Bool(form == "network: weights in workgroup memory"),
            ),
            // The weights uniform as large as this network's (mlp::uniform_bytes), not the
            // largest network's: the buffer bound is sized to it.
            ("NET_VEC4S", U32(self.weight_vec4s)),
        ];
        if self.pass == "importance_dkb" {
            defs.push(("SKIP_FORCED", Bool(self.skip_forced)));
        }
        if p1 != 0 {
            // Known sizes: the private sums hold exactly p2 floats.
            defs.extend([
                ("NET_P1", U32(p1)),
                ("NET_P2", U32(p2)),
                ("ACC2_VEC4S", U32(p2 / 4)),
            ]);
        }
        // f16-math has one form: written out (the twin's order of sums, at binary16).
        let written = (form == "network: written out at binary16"
            || form == "network: written out")
            .then(|| unrolled_forward(p1, p2, half_math));
        let src = shaders::compose(self.pass, &defs, written.as_deref())
            .expect("a network pass and its definitions");
        if half_math {
            // The directive comes before every declaration, the prelude's included.
            return format!("enable f16;\n{src}");
        }
        src
    }
}

/// The binding of the weights' binary16 view, which [`unrolled_forward`] declares beside
/// mlp.wgsl's `weights` (the same buffer).
pub(super) const WEIGHTS_H: u32 = 11;

/// `mlp_forward` for one network shape (padded sizes p1, p2), written out (composed in place
/// of [`shaders::MLP_LOOP`]): the second layer's
/// sums in p2 / 4 named vec4s instead of an array (which a GPU compiler may keep in local
/// memory when its loops are not unrolled), every weight's offset within a row a constant.
/// The same sums in the same order as mlp.wgsl's `mlp_forward_loop` and the CPU twin; a first-layer
/// unit at 0 adds its zero products instead of being skipped (no branch that diverges across
/// pixels), which changes no sum (x + 0 = x; a zero's sign is lost by the ReLU and the sigmoid).
///
/// With `half_math` ([`Precision::F16Math`]) the two hidden layers compute in binary16 vec4s
/// (`vec4<f16>`: on GPUs with fast half precision, two multiply-adds an instruction), their
/// weights read as stored (binary16, `param4h`), the standardised inputs rounded to binary16;
/// the output unit sums in f32 (`Mlp::forward_half` is the twin).
fn unrolled_forward(p1: u32, p2: u32, half_math: bool) -> String {
    use std::fmt::Write;
    let q2 = p2 / 4;
    // The hidden layers' vector type, its weights' reader and its zero.
    let (v4, param, zero) = if half_math {
        ("vec4<f16>", "param4h", "0.0h")
    } else {
        ("vec4<f32>", "param4", "0.0")
    };
    let mut f = String::new();
    let w = &mut f;
    let _ = writeln!(
        w,
        "\n// Written out for a {p1}-{p2} network (gpu::pipelines::unrolled_forward)."
    );
    if half_math {
        let _ = writeln!(
            w,
            "// The weights' uniform read as binary16 (the same buffer, bound a second time): a
// vec4 of its 32-bit words is eight binary16 values, the first four in `lo` (a uniform
// array's elements are 16 bytes apart, so vec4<f16> alone cannot be one).
struct HalfWords {{
    lo: vec4<f16>,
    hi: vec4<f16>,
}};
@group(0) @binding({WEIGHTS_H}) var<uniform> weights_h: array<HalfWords, NET_VEC4S>;

// Four binary16 parameters from index `i` (where param4 reads them at F16_WEIGHTS), as they are.
fn param4h(i: u32) -> vec4<f16> {{
    let word = MLP_W1_AT + ((i - MLP_W1_AT) >> 1u);
    let v = weights_h[word >> 2u];
    return select(v.lo, v.hi, (word & 2u) != 0u);
}}"
        );
    }
    let _ = writeln!(w, "fn mlp_forward(f: array<f32, FEATURES>) -> f32 {{");
    for (i, at) in [(0, 0), (1, 4), (2, 8)] {
        let _ = writeln!(
            w,
            "    let x{i} = {v4}(standardised(vec4<f32>(f[{}], f[{}], f[{}], f[{}]), {i}u));",
            at,
            at + 1,
            at + 2,
            at + 3
        );
    }
    let _ = writeln!(w, "    let w1 = MLP_W1_AT;");
    let _ = writeln!(
        w,
        "    let b1 = w1 + {}u;",
        crate::importance::FEATURES as u32 * p1
    );
    let _ = writeln!(w, "    let w2 = b1 + {p1}u;");
    let _ = writeln!(w, "    let b2 = w2 + {}u;", p1 * p2);
    let _ = writeln!(w, "    let w3 = b2 + {p2}u;");
    for j in 0..q2 {
        let _ = writeln!(w, "    var s{j} = {param}(b2 + {}u);", 4 * j);
    }
    let _ = writeln!(w, "    for (var i = 0u; i < {p1}u; i += 4u) {{");
    let _ = writeln!(w, "        var acc = {param}(b1 + i);");
    // add_inputs, written out: input c of x{x} times its four units' weights.
    for x in 0..3 {
        for (c, comp) in ["x", "y", "z", "w"].iter().enumerate() {
            let _ = writeln!(
                w,
                "        acc += x{x}.{comp} * {param}(w1 + {}u + i);",
                (4 * x + c as u32) * p1
            );
        }
    }
    let _ = writeln!(w, "        let a = max(acc, {v4}({zero}));");
    let _ = writeln!(w, "        let row = w2 + i * {p2}u;");
    for (u, c) in ["x", "y", "z", "w"].iter().enumerate() {
        for j in 0..q2 {
            let _ = writeln!(
                w,
                "        s{j} += a.{c} * {param}(row + {}u);",
                u as u32 * p2 + 4 * j
            );
        }
    }
    let _ = writeln!(w, "    }}");
    let _ = writeln!(w, "    var out = param4(w3 + {}u).x;", 4 * q2);
    for j in 0..q2 {
        let _ = writeln!(w, "    let h{j} = vec4<f32>(max(s{j}, {v4}({zero})));");
        let _ = writeln!(w, "    let v{j} = param4(w3 + {}u);", 4 * j);
        for c in ["x", "y", "z", "w"] {
            let _ = writeln!(w, "    out += h{j}.{c} * v{j}.{c};");
        }
    }
    let _ = writeln!(w, "    let s = 1.0 / (1.0 + exp(-out));");
    let _ = writeln!(w, "    return select(0.0, s, s == s);");
    let _ = writeln!(w, "}}");
    f
}

impl Gpu {
    /// The pipeline of a network pass: built at start-up for the default network, else on
    /// first use.
    pub(super) fn network_pass(&self, v: Variant) -> wgpu::ComputePipeline {
        let mut variants = self
            .pipelines
            .variants
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        variants
            .entry(v)
            .or_insert_with(|| v.pipeline(&self.device, &self.pipelines.network_layout))
            .clone()
    }
}

/// A geometry pass's pipeline: the shared vertex stage (vs_main), both faces, `depth` and
/// `targets`, fragment entry `entry`.
fn render_pipeline(
    device: &wgpu::Device,
    (name, entry): (&str, &str),
    m: &wgpu::ShaderModule,
    depth: Option<wgpu::DepthStencilState>,
    targets: &[Option<wgpu::ColorTargetState>],
) -> wgpu::RenderPipeline {
    note_built();
    let depth_json = depth.as_ref().map(|d| {
        serde_json::json!({
            "format": webgpu_name(format!("{:?}", d.format), true),
            "depthWriteEnabled": d.depth_write_enabled.unwrap_or(false),
            "depthCompare": webgpu_name(format!("{:?}", d.depth_compare.unwrap_or(wgpu::CompareFunction::Always)), false),
        })
    });
    let targets_json: Vec<_> = targets
        .iter()
        .map(|t| {
            t.as_ref().map(|t| {
                serde_json::json!({
                    "format": webgpu_name(format!("{:?}", t.format), true),
                    "blend": t.blend.map(|b| serde_json::json!({
                        "color": blend_json(&b.color),
                        "alpha": blend_json(&b.alpha),
                    })),
                })
            })
        })
        .collect();
    record_pipeline(
        name,
        m,
        serde_json::json!({
            "vertex": "vs_main",
            "fragment": entry,
            "depthStencil": depth_json,
            "targets": targets_json,
        }),
    );
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(name),
        layout: None,
        vertex: wgpu::VertexState {
            module: m,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: depth,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: m,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// The transparent passes: no colour target, the opaque depth their one attachment, read-only
/// and never tested (they test it in the shader, where the test comes before their atomics on
/// every device): what a renderer's transparent pass binds anyway.
fn transparent_pipeline(
    device: &wgpu::Device,
    name: &str,
    m: &wgpu::ShaderModule,
) -> wgpu::RenderPipeline {
    let depth = wgpu::DepthStencilState {
        format: OPAQUE_DEPTH_FORMAT,
        depth_write_enabled: Some(false),
        depth_compare: Some(wgpu::CompareFunction::Always),
        stencil: Default::default(),
        bias: Default::default(),
    };
    render_pipeline(device, (name, "fs_main"), m, Some(depth), &[])
}

/// A blended method's pass: its targets written through `blend` (gpu::blend).
fn blend_pipeline(device: &wgpu::Device, b: &BlendPass) -> wgpu::RenderPipeline {
    let targets = b.color_targets();
    render_pipeline(
        device,
        (b.pass, b.entry),
        &module(device, b.pass),
        None,
        &targets,
    )
}

/// The module of a variant of pass `pass`: its definitions `defs` ([`shaders::source_with`]),
/// labelled `label`.
fn module_defining(
    device: &wgpu::Device,
    pass: &str,
    label: &str,
    defs: &[(&str, shaders::Value)],
) -> wgpu::ShaderModule {
    let src = shaders::source_with(pass, defs).expect("a pass and its definitions");
    module_from(device, label, src)
}

/// Pass `name`'s entry `entry`, compute.
fn compute_of(device: &wgpu::Device, name: &str, entry: &str) -> wgpu::ComputePipeline {
    compute_pipeline(device, name, &module(device, name), entry)
}

/// MBOIT's passes for 4, 6 and 8 power moments, each where the device can run them.
type MboitPasses = [Option<(wgpu::RenderPipeline, wgpu::RenderPipeline)>; 3];

/// The passes only some methods draw, each built the first time a frame asks for it, so a
/// renderer that never draws them (an application's DKB or VKB) never compiles them: MLAB's
/// resolve, WBOIT's and MBOIT's passes and composites, the list's, the portable capture, the
/// k-buffers' tint pass, and the bench's features pass without its preload.
#[derive(Default)]
struct Extras {
    mlab_resolve: OnceLock<wgpu::ComputePipeline>,
    wboit: OnceLock<(wgpu::RenderPipeline, wgpu::ComputePipeline)>,
    wboit_tinted: OnceLock<wgpu::RenderPipeline>,
    mboit: OnceLock<(MboitPasses, wgpu::ComputePipeline)>,
    mboit_tinted: OnceLock<MboitPasses>,
    list: OnceLock<(wgpu::RenderPipeline, wgpu::ComputePipeline)>,
    features_no_preload: OnceLock<wgpu::RenderPipeline>,
    portable_capture: OnceLock<[wgpu::RenderPipeline; 2]>,
    capture_tints: OnceLock<[wgpu::RenderPipeline; 2]>,
}

/// The extras' pipelines, as [`Gpu::extras`] hands them out.
#[derive(Clone, Copy)]
pub(super) struct ExtraPipelines<'a> {
    gpu: &'a Gpu,
}

impl<'a> ExtraPipelines<'a> {
    fn device(self) -> &'a wgpu::Device {
        &self.gpu.device
    }
    fn extras(self) -> &'a Extras {
        &self.gpu.pipelines.extras
    }

    /// MLAB's resolve (mlab_resolve.wgsl).
    pub(super) fn mlab_resolve(self) -> &'a wgpu::ComputePipeline {
        self.extras()
            .mlab_resolve
            .get_or_init(|| compute_of(self.device(), "mlab_resolve", "main"))
    }

    /// WBOIT's accumulation pass and composite.
    pub(super) fn wboit(self) -> &'a (wgpu::RenderPipeline, wgpu::ComputePipeline) {
        self.extras().wboit.get_or_init(|| {
            (
                blend_pipeline(self.device(), &BlendPass::WBOIT),
                compute_of(self.device(), "blend_composite", "wboit"),
            )
        })
    }

    /// WBOIT's accumulation pass where the frame's glass is tinted (its composite is
    /// [`ExtraPipelines::wboit`]'s).
    pub(super) fn wboit_tinted(self) -> &'a wgpu::RenderPipeline {
        self.extras()
            .wboit_tinted
            .get_or_init(|| blend_pipeline(self.device(), &BlendPass::WBOIT_TINTED))
    }

    /// MBOIT's moments and accumulation passes for 4, 6 and 8 power moments (6 and 8 add a
    /// third target, RG32F or RGBA32F), each where the device blends 32-bit floats and its
    /// colour attachments hold the moments' bytes a sample (eight take 36; wgpu's default
    /// limit is 32), and its composite.
    pub(super) fn mboit(self) -> &'a (MboitPasses, wgpu::ComputePipeline) {
        self.extras().mboit.get_or_init(|| {
            let device = self.device();
            let passes = [4, 6, 8].map(|moments| {
                let [m, a] = BlendPass::mboit(moments).expect("4, 6 and 8 moments");
                mboit_fits(device, &m)
                    .then(|| (blend_pipeline(device, &m), blend_pipeline(device, &a)))
            });
            (passes, compute_of(device, "blend_composite", "mboit"))
        })
    }

    /// MBOIT's passes where the frame's glass is tinted: the moments pass multiplies the
    /// transmittances into one more target (its composite is [`ExtraPipelines::mboit`]'s).
    pub(super) fn mboit_tinted(self) -> &'a MboitPasses {
        self.extras().mboit_tinted.get_or_init(|| {
            let device = self.device();
            [4, 6, 8].map(|moments| {
                let [m, a] = BlendPass::mboit_for(moments, true).expect("4, 6 and 8 moments");
                mboit_fits(device, &m)
                    .then(|| (blend_pipeline(device, &m), blend_pipeline(device, &a)))
            })
        })
    }

    /// The linked list's store and resolve.
    pub(super) fn list(self) -> &'a (wgpu::RenderPipeline, wgpu::ComputePipeline) {
        self.extras().list.get_or_init(|| {
            let device = self.device();
            let store = transparent_pipeline(device, "list_store", &module(device, "list_store"));
            (store, compute_of(device, "list_resolve", "main"))
        })
    }

    /// The portable capture's depth and colour passes (32-bit atomics alone).
    pub(super) fn portable_capture(self) -> &'a [wgpu::RenderPipeline; 2] {
        self.extras().portable_capture.get_or_init(|| {
            let device = self.device();
            ["capture_depths", "capture_colours"]
                .map(|name| transparent_pipeline(device, name, &module(device, name)))
        })
    }

    /// The k-buffers' tint pass where the frame stores tint words (capture.wgsl with
    /// kbuffer_tint.wgsl, 32-bit atomics alone, after either capture): in general, and built
    /// for frames whose budget holds every fragment (as the capture is).
    pub(super) fn capture_tints(self, fits: bool) -> &'a wgpu::RenderPipeline {
        let [general, all_fit] = self.extras().capture_tints.get_or_init(|| {
            let device = self.device();
            let fits = module_defining(
                device,
                "capture_tints",
                "capture_tints (every fragment fits)",
                &[shaders::EVERY_FRAGMENT_FITS],
            );
            [
                transparent_pipeline(device, "capture_tints", &module(device, "capture_tints")),
                transparent_pipeline(device, "capture_tints", &fits),
            ]
        });
        if fits { all_fit } else { general }
    }

    /// The features pass without the nearest words' load first (PRELOAD_NEAREST false).
    pub(super) fn features_no_preload(self) -> &'a wgpu::RenderPipeline {
        self.extras().features_no_preload.get_or_init(|| {
            let device = self.device();
            let m = module_defining(
                device,
                "features",
                "features (no preload)",
                &[("PRELOAD_NEAREST", shaders::Value::Bool(false))],
            );
            transparent_pipeline(device, "features", &m)
        })
    }
}

impl Gpu {
    /// The passes only some methods draw, built on first use.
    pub(super) fn extras(&self) -> ExtraPipelines<'_> {
        ExtraPipelines { gpu: self }
    }
}

impl Pipelines {
    /// Every pass; with `wide`, also those that use 64-bit integers ([`Wide`]). Built at once;
    /// the future waits only for the device's verdict on them (its validation errors).
    pub(super) async fn new(device: &wgpu::Device, wide: bool) -> Result<Pipelines> {
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let render = |name: &str,
                      m: &wgpu::ShaderModule,
                      depth: Option<wgpu::DepthStencilState>,
                      targets: &[Option<wgpu::ColorTargetState>]| {
            render_pipeline(device, (name, "fs_main"), m, depth, targets)
        };
        let geometry_from =
            |name: &str, m: wgpu::ShaderModule| transparent_pipeline(device, name, &m);
        let geometry = |name: &str| geometry_from(name, module(device, name));
        let opaque = render(
            "opaque",
            &module(device, "opaque"),
            Some(wgpu::DepthStencilState {
                format: OPAQUE_DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            &[Some(wgpu::ColorTargetState {
                format: OPAQUE_COLOR_FORMAT,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        );
        // capture.wgsl and resolve.wgsl for frames whose budget holds every fragment.
        let fits = |pass: &str| {
            module_defining(
                device,
                pass,
                &format!("{pass} (every fragment fits)"),
                &[shaders::EVERY_FRAGMENT_FITS],
            )
        };
        let compute_entry = |name: &str, entry: &str| compute_of(device, name, entry);
        let marks = module_defining(
            device,
            "scan",
            "scan (the allocation's marks)",
            &[("SCAN_OF_MARKS", shaders::Value::Bool(true))],
        );
        let scan_marks = ["scan_blocks_in_place", "scan_sums", "scan_add"]
            .map(|entry| compute_pipeline(device, "scan (the allocation's marks)", &marks, entry));
        let compute = |name: &str| compute_entry(name, "main");
        let network_layout = NetworkLayout::new(device);
        let p = Pipelines {
            opaque,
            count: geometry("abuffer_count"),
            store: geometry("abuffer_store"),
            features: geometry("features"),
            count_features: geometry("count_features"),
            wide: wide.then(|| Wide {
                capture: geometry("capture"),
                capture_fits: geometry_from("capture", fits("capture")),
            }),
            scan_blocks: compute_entry("scan", "scan_blocks"),
            scan_blocks_in_place: compute_entry("scan", "scan_blocks_in_place"),
            scan_sums: compute_entry("scan", "scan_sums"),
            scan_add: compute_entry("scan", "scan_add"),
            scan_marks,
            abuffer_resolve: compute("abuffer_resolve"),
            resolve: compute("resolve"),
            resolve_fits: compute_pipeline(device, "resolve", &fits("resolve"), "main"),
            extras: Extras::default(),
            onto: Default::default(),
            totals: compute("totals"),
            allocate: Allocate::new(device),
            plan: compute("plan"),
            mark_records: compute_entry("totals", "mark_records"),
            record_counts: compute_entry("totals", "record_counts"),
            init_records: compute_entry("totals", "init_records"),
            next_batch: compute_entry("totals", "next_batch"),
            variants: std::sync::Mutex::new(
                [
                    ("importance_dkb", "select_pixels"),
                    ("importance_dkb", "args"),
                    ("importance_dkb", "network"),
                    ("importance_dkb", "gather"),
                    ("predict", "main"),
                ]
                .map(|(pass, entry)| {
                    let p = crate::mlp::padded_units;
                    let v = Variant {
                        pass,
                        skip_forced: true,
                        precision: Precision::F32,
                        shape: (p(crate::mlp::H1) as u32, p(crate::mlp::H2) as u32),
                        weight_vec4s: (crate::budget::MLP_UNIFORM_BYTES / 16) as u32,
                        shared_weights: false,
                        unrolled: true,
                        entry,
                    };
                    (v, v.pipeline(device, &network_layout))
                })
                .into_iter()
                .collect(),
            ),
            network_layout,
            vkb_count: geometry("vkb_count"),
            importance_vkb: compute("importance_vkb"),
            placeholder: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("placeholder"),
                size: PLACEHOLDER_BYTES,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            }),
        };
        if let Some(e) = scope.pop().await {
            return Err(GpuError::Pipeline(e.to_string()).into());
        }
        Ok(p)
    }
}
