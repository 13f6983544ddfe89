//! The WGSL passes' sources and everything Rust and WGSL must agree on: the constants of the
//! generated prelude, the layouts of the uniforms the host uploads (`Params`, `Alloc`, the
//! network's weights) and the dispatch grid. None of it needs a GPU, so the trainer builds it
//! without wgpu, and naga tests hold each layout to its WGSL declaration.

use crate::mlp::{self, Mlp, Precision};
pub use crate::shared::{
    ALLOC_CANDIDATES, ALLOC_DISPATCHES, ALLOC_ROUNDS_WORD, ALLOC_STATE_WORDS, DISPATCH_PER_PIXEL,
    DISPATCH_ROUNDS, DISPATCH_SCAN, DISPATCH_WORDS,
};

/// WGSL sources, embedded at build time.
/// Every binding the shaders declare, by shader and variable name (`runtime/build.rs` reads
/// them from `shaders/*.wgsl`): the host binds by these names, so an index is written once, in
/// its shader. Bound by position (`Gpu::bind`) where a shader's bindings run 0, 1, 2, ...
pub mod bindings {
    include!(concat!(env!("OUT_DIR"), "/bindings.rs"));
}

pub mod shaders {
    /// Code every pass starts with (after the prelude), the per-pixel counts' packing
    /// (counts.wgsl) with it.
    pub const COMMON: &str = concat!(
        include_str!("../../shaders/common.wgsl"),
        "\n",
        include_str!("../../shaders/counts.wgsl")
    );
    pub const GEOMETRY: &str = include_str!("../../shaders/geometry.wgsl");
    /// The importance network, prepended to the passes that run it.
    pub const MLP: &str = include_str!("../../shaders/mlp.wgsl");

    /// The A-buffer's per-pixel insertion sort, prepended to the passes that sort.
    pub const SORT: &str = include_str!("../../shaders/sort.wgsl");
    /// What the resolves composite over (the opaque pass's colour, else the background).
    pub const BEHIND: &str = include_str!("../../shaders/behind.wgsl");
    /// MBOIT's depth mapping and reconstruction, prepended to its two geometry passes.
    pub const MBOIT: &str = include_str!("../../shaders/mboit.wgsl");

    /// One WGSL pass: its name, its source, and the shared code prepended to it after the
    /// prelude and COMMON: GEOMETRY (the vertex stage) for geometry passes, MLP for the passes
    /// that run the network, SORT for those that sort a pixel's fragments.
    pub struct Pass {
        pub name: &'static str,
        pub source: &'static str,
        pub includes: &'static [&'static str],
        /// The definitions its code reads and no shader file declares: each a WGSL `const` (a
        /// storage texture's type an `alias`) composed in after the prelude, with the value
        /// the pass is built with unless a variant of it gives another ([`source_with`]). A
        /// variant of a pass is its definitions, never an edit of its text.
        pub defines: &'static [(&'static str, Value)],
    }

    /// The network passes' forward where the pass runs mlp.wgsl's loops over any shape; a
    /// pass built for one shape composes the forward written out for it in its place
    /// ([`compose`]).
    pub const MLP_LOOP: &str =
        "fn mlp_forward(f: array<f32, FEATURES>) -> f32 {\n    return mlp_forward_loop(f);\n}\n";

    /// The definitions of the passes that run the network (mlp.wgsl): its weights in f32
    /// words, read from the uniform, its sizes read from the uniform's header (NET_P1 and
    /// NET_P2 0), the second layer's sums as many as the largest network's, the uniform the
    /// default network's size.
    const NETWORK_DEFINES: [(&str, Value); 6] = [
        ("F16_WEIGHTS", Value::Bool(false)),
        ("SHARED_WEIGHTS", Value::Bool(false)),
        ("NET_P1", Value::U32(0)),
        ("NET_P2", Value::U32(0)),
        ("ACC2_VEC4S", Value::U32(crate::mlp::MAX_H2 as u32 / 4)),
        (
            "NET_VEC4S",
            Value::U32((crate::budget::MLP_UNIFORM_BYTES / 16) as u32),
        ),
    ];

    /// What a resolve writes onto (an application's target; dhoit's own is rgba32float).
    const ONTO: (&str, Value) = ("OntoTexture", Value::StorageTexture("rgba32float"));
    /// A capture or resolve in general (the default), or
    const FITS: (&str, Value) = ("EVERY_FRAGMENT_FITS", Value::Bool(false));
    /// the variant built for frames whose budget holds every fragment (dhoit's own pipelines
    /// and an application's capture alike).
    pub const EVERY_FRAGMENT_FITS: (&str, Value) = ("EVERY_FRAGMENT_FITS", Value::Bool(true));
    /// DKB's features pass loads a pixel's nearest words before their atomicMax.
    const PRELOAD: (&str, Value) = ("PRELOAD_NEAREST", Value::Bool(true));

    /// Unsigned 64-bit arithmetic in two 32-bit words, for the passes that run without u64.
    pub const U64: &str = include_str!("../../shaders/u64.wgsl");

    /// Which pixel has which of DKB's records, from their marks (records.wgsl): the passes that
    /// read or write the records include it.
    pub const RECORDS: &str = include_str!("../../shaders/records.wgsl");

    /// Which records DKB's features pass gathers: a batch of its own (features_batch.wgsl), or
    /// with the count, those the frame before marked (features_count.wgsl).
    pub const FEATURES_BATCH: &str = include_str!("../../shaders/features_batch.wgsl");
    pub const FEATURES_COUNT: &str = include_str!("../../shaders/features_count.wgsl");

    /// The k-buffer's Loop64 insertion and tail, which the capture runs (capture.wgsl).
    pub const KBUFFER_INSERT: &str = include_str!("../../shaders/kbuffer_insert.wgsl");
    /// The same with 32-bit atomics alone, in two passes (the portable capture).
    pub const KBUFFER_PORTABLE: &str = include_str!("../../shaders/kbuffer_portable.wgsl");
    /// The tint pass after either, where the frame stores tint words (kbuffer_tint.wgsl).
    pub const KBUFFER_TINT: &str = include_str!("../../shaders/kbuffer_tint.wgsl");

    /// The module an application's transparent fragment shader starts with: `parts` (what
    /// the store module includes, then the module) joined, their bindings at `group`.
    pub fn application_module(parts: &[&str], group: u32) -> String {
        parts.join("\n").replace("OIT_GROUP", &group.to_string())
    }

    /// What an application's fragment shader runs in place of dhoit's own geometry pass
    /// (`gpu::AllocatedOit`, `gpu::BlendedOit`): the parameters, the opaque depth and the
    /// fragment's colour from the application. The pass's code, not a copy.
    pub const OIT_PHASE: &str = include_str!("../../shaders/oit_phase.wgsl");
    /// `oit_store`, for a pass that stores its fragments (`gpu::AllocatedOit`).
    pub const OIT_PHASE_STORE: &str = include_str!("../../shaders/oit_phase_store.wgsl");
    /// `oit_targets`, for a pass that blends into targets (`gpu::BlendedOit`).
    pub const OIT_PHASE_TARGETS: &str = include_str!("../../shaders/oit_phase_targets.wgsl");

    /// The header of geometry pass fragment entry `entry`, up to its return type.
    fn entry_header(entry: &str) -> String {
        format!("@fragment\nfn {entry}(in: VertexOut, @builtin(front_facing) front: bool) -> ")
    }

    /// Geometry pass `name` with its fragment entry `entry` (returning `ret`) made `fn
    /// oit_phase(in, front) -> ret`, its group 1 at `OIT_GROUP`, and its definitions (`given`
    /// where given, [`Pass::defines`]) with the includes it needs beside the vertex stage. None
    /// for a pass that is not a geometry pass, an entry it lacks, or a definition it does not
    /// have.
    fn phase_of(
        name: &str,
        entry: &str,
        ret: &str,
        given: &[(&str, Value)],
    ) -> Option<(String, String)> {
        let p = PASSES.iter().find(|p| p.name == name)?;
        let header = format!("{}{ret} {{", entry_header(entry));
        if !p.includes.contains(&GEOMETRY) || !p.source.contains(&header) {
            return None;
        }
        let definitions = definitions(p, given)?;
        let src = p.source;
        let own = ret.strip_prefix("@location(0) ").unwrap_or(ret);
        let src = src
            .replacen(
                &header,
                &format!("fn oit_phase(in: VertexOut, front: bool) -> {own} {{"),
                1,
            )
            .replace("@group(1)", "@group(OIT_GROUP)");
        let includes: Vec<&str> = p
            .includes
            .iter()
            .copied()
            .filter(|i| *i != GEOMETRY)
            .collect();
        // The includes' group 1 bindings (the tint pass's, DKB's features') move with the pass's.
        let includes = format!("{definitions}\n{}", includes.join("\n"))
            .replace("@group(1)", "@group(OIT_GROUP)");
        Some((src, includes))
    }

    /// Geometry pass `name`'s source with the definitions `given` (a variant of the pass), as
    /// the module an application's transparent fragment shader starts with. Its group 1 moves
    /// to `group`, the parameters and the opaque depth join it at bindings 14 and 15
    /// (oit_phase.wgsl), and its fragment entry becomes the function that
    /// `oit_store(frag_coord, color)` calls. None for a pass that is not a geometry pass, or a
    /// definition the pass does not have.
    pub fn application_pass(name: &str, given: &[(&str, Value)], group: u32) -> Option<String> {
        let (src, includes) = phase_of(name, "fs_main", "@location(0) vec4<f32>", given)?;
        Some(application_module(
            &[
                &prelude(),
                COMMON,
                OIT_PHASE,
                &includes,
                &src,
                OIT_PHASE_STORE,
            ],
            group,
        ))
    }

    /// Blended geometry pass `name`'s fragment entry `entry` (it writes colour targets through
    /// the device's blending: WBOIT's, MBOIT's), as the module an application's transparent
    /// fragment shader starts with: as [`application_pass`], but the entry becomes the function
    /// `oit_targets(frag_coord, color) -> OitTargets` calls, whose value the application's
    /// fragment entry returns (`-> OitTargets`). None for a pass that is not a geometry pass
    /// or an entry it lacks.
    pub fn application_blend_pass(name: &str, entry: &str, group: u32) -> Option<String> {
        let p = PASSES.iter().find(|p| p.name == name)?;
        let header = entry_header(entry);
        let at = p.source.find(&header)? + header.len();
        let ret = &p.source[at..at + p.source[at..].find(" {\n")?];
        let (src, includes) = phase_of(name, entry, ret, &[])?;
        let targets = match ret.strip_prefix("@location(0) ") {
            Some(one) => OIT_PHASE_TARGETS
                .replace(
                    "OIT_TARGETS_TYPE",
                    &format!("struct OitTargets {{\n    @location(0) target0: {one},\n}};"),
                )
                .replace("OIT_TARGETS_OF(", "OitTargets("),
            None => OIT_PHASE_TARGETS
                .replace("OIT_TARGETS_TYPE", &format!("alias OitTargets = {ret};"))
                .replace("OIT_TARGETS_OF(", "("),
        };
        Some(application_module(
            &[&prelude(), COMMON, OIT_PHASE, &includes, &src, &targets],
            group,
        ))
    }

    /// The passes that use no 64-bit integer (no `SHADER_INT64`, no 64-bit atomics): what a
    /// device without them (WebGPU, most of Metal) can build. The others need both features.
    pub const PORTABLE: &[&str] = &[
        "opaque",
        "abuffer_count",
        "scan",
        "capture_depths",
        "capture_colours",
        "capture_tints",
        "wboit_accumulate",
        "mboit_moments",
        "mboit_accumulate",
        "blend_composite",
        "vkb_count",
        "importance_vkb",
        "predict",
        "abuffer_store",
        "abuffer_resolve",
        "resolve",
        "mlab_resolve",
        "list_store",
        "list_resolve",
        "totals",
        "plan",
        "allocate",
        "importance_dkb",
        "features",
        "count_features",
    ];

    pub const PASSES: [Pass; 26] = [
        Pass {
            name: "opaque",
            source: include_str!("../../shaders/opaque.wgsl"),
            includes: &[GEOMETRY],
            defines: &[],
        },
        Pass {
            name: "abuffer_count",
            source: include_str!("../../shaders/abuffer_count.wgsl"),
            includes: &[GEOMETRY],
            defines: &[],
        },
        Pass {
            name: "scan",
            source: include_str!("../../shaders/scan.wgsl"),
            includes: &[],
            defines: &[("SCAN_OF_MARKS", Value::Bool(false))],
        },
        Pass {
            name: "abuffer_store",
            source: include_str!("../../shaders/abuffer_store.wgsl"),
            includes: &[GEOMETRY],
            defines: &[],
        },
        Pass {
            name: "abuffer_resolve",
            source: include_str!("../../shaders/abuffer_resolve.wgsl"),
            includes: &[SORT, BEHIND],
            defines: &[ONTO],
        },
        Pass {
            name: "capture",
            source: include_str!("../../shaders/capture.wgsl"),
            includes: &[GEOMETRY, KBUFFER_INSERT],
            defines: &[FITS],
        },
        Pass {
            name: "capture_depths",
            source: include_str!("../../shaders/capture.wgsl"),
            includes: &[GEOMETRY, KBUFFER_PORTABLE],
            defines: &[FITS, ("CAPTURE_COLOURS", Value::Bool(false))],
        },
        Pass {
            name: "capture_colours",
            source: include_str!("../../shaders/capture.wgsl"),
            includes: &[GEOMETRY, KBUFFER_PORTABLE],
            defines: &[FITS, ("CAPTURE_COLOURS", Value::Bool(true))],
        },
        Pass {
            name: "capture_tints",
            source: include_str!("../../shaders/capture.wgsl"),
            includes: &[GEOMETRY, KBUFFER_TINT],
            defines: &[FITS],
        },
        Pass {
            name: "resolve",
            source: include_str!("../../shaders/resolve.wgsl"),
            includes: &[BEHIND],
            defines: &[FITS, ONTO],
        },
        Pass {
            name: "mlab_resolve",
            source: include_str!("../../shaders/mlab_resolve.wgsl"),
            includes: &[SORT, BEHIND],
            defines: &[ONTO],
        },
        Pass {
            name: "wboit_accumulate",
            source: include_str!("../../shaders/wboit_accumulate.wgsl"),
            includes: &[GEOMETRY],
            defines: &[],
        },
        Pass {
            name: "mboit_moments",
            source: include_str!("../../shaders/mboit_moments.wgsl"),
            includes: &[GEOMETRY, MBOIT],
            defines: &[],
        },
        Pass {
            name: "mboit_accumulate",
            source: include_str!("../../shaders/mboit_accumulate.wgsl"),
            includes: &[GEOMETRY, MBOIT],
            defines: &[],
        },
        Pass {
            name: "blend_composite",
            source: include_str!("../../shaders/blend_composite.wgsl"),
            includes: &[BEHIND],
            defines: &[ONTO],
        },
        Pass {
            name: "list_store",
            source: include_str!("../../shaders/list_store.wgsl"),
            includes: &[GEOMETRY],
            defines: &[],
        },
        Pass {
            name: "list_resolve",
            source: include_str!("../../shaders/list_resolve.wgsl"),
            includes: &[BEHIND],
            defines: &[ONTO],
        },
        Pass {
            name: "allocate",
            source: include_str!("../../shaders/allocate.wgsl"),
            includes: &[U64],
            defines: &[("SEARCH_COPIES", Value::U32(1))],
        },
        Pass {
            name: "features",
            source: include_str!("../../shaders/features.wgsl"),
            includes: &[GEOMETRY, RECORDS, FEATURES_BATCH],
            defines: &[PRELOAD],
        },
        Pass {
            name: "count_features",
            source: include_str!("../../shaders/features.wgsl"),
            includes: &[GEOMETRY, RECORDS, FEATURES_COUNT],
            defines: &[PRELOAD],
        },
        Pass {
            name: "totals",
            source: include_str!("../../shaders/totals.wgsl"),
            includes: &[RECORDS],
            defines: &[],
        },
        Pass {
            name: "plan",
            source: include_str!("../../shaders/plan.wgsl"),
            includes: &[U64],
            defines: &[],
        },
        Pass {
            name: "importance_dkb",
            source: include_str!("../../shaders/importance_dkb.wgsl"),
            includes: &[U64, MLP, MLP_LOOP, RECORDS],
            defines: &[
                ("SKIP_FORCED", Value::Bool(true)),
                NETWORK_DEFINES[0],
                NETWORK_DEFINES[1],
                NETWORK_DEFINES[2],
                NETWORK_DEFINES[3],
                NETWORK_DEFINES[4],
                NETWORK_DEFINES[5],
            ],
        },
        Pass {
            name: "vkb_count",
            source: include_str!("../../shaders/vkb_count.wgsl"),
            includes: &[GEOMETRY],
            defines: &[],
        },
        Pass {
            name: "importance_vkb",
            source: include_str!("../../shaders/importance_vkb.wgsl"),
            includes: &[],
            defines: &[],
        },
        Pass {
            name: "predict",
            source: include_str!("../../shaders/predict.wgsl"),
            includes: &[MLP, MLP_LOOP],
            defines: &NETWORK_DEFINES,
        },
    ];

    /// The full source of a pass as it is built by default: the generated prelude, its
    /// definitions, common code, its includes, the pass.
    pub fn source(name: &str) -> Option<String> {
        source_with(name, &[])
    }

    /// The full source of a variant of pass `name`: its definitions with the values `given`
    /// (the others at their defaults). None for an unknown pass, or a definition it does not
    /// have or of another kind.
    pub fn source_with(name: &str, given: &[(&str, Value)]) -> Option<String> {
        compose(name, given, None)
    }

    /// [`source_with`], and where `forward` is given, it in place of the network's loops over
    /// any shape ([`MLP_LOOP`]: a pass built for one network shape composes the forward written
    /// out for it). None also where `forward` is given to a pass that runs no network.
    pub fn compose(name: &str, given: &[(&str, Value)], forward: Option<&str>) -> Option<String> {
        let p = PASSES.iter().find(|p| p.name == name)?;
        if forward.is_some() && !p.includes.contains(&MLP_LOOP) {
            return None;
        }
        let includes: Vec<&str> = p
            .includes
            .iter()
            .map(|&i| match forward {
                Some(f) if i == MLP_LOOP => f,
                _ => i,
            })
            .collect();
        Some(format!(
            "{}\n{}\n{COMMON}\n{}\n{}",
            prelude(),
            definitions(p, given)?,
            includes.join("\n"),
            p.source
        ))
    }

    /// Pass `p`'s definitions, `given` where given: None where one given is not the pass's or
    /// not of its kind.
    fn definitions(p: &Pass, given: &[(&str, Value)]) -> Option<String> {
        for (name, v) in given {
            let (_, d) = p.defines.iter().find(|(n, _)| n == name)?;
            if std::mem::discriminant(d) != std::mem::discriminant(v) {
                return None;
            }
        }
        let mut s = String::new();
        for &(name, default) in p.defines {
            let v = given
                .iter()
                .rev()
                .find(|(n, _)| *n == name)
                .map_or(default, |g| g.1);
            s += &declaration(name, v);
        }
        Some(s)
    }

    /// The WGSL declaration of constant `name` of value `v`.
    fn declaration(name: &str, v: Value) -> String {
        match v {
            Value::F32(x) => format!("const {name}: f32 = {};\n", f32_literal(x)),
            Value::U32(x) => format!("const {name}: u32 = {x}u;\n"),
            Value::Bool(b) => format!("const {name}: bool = {b};\n"),
            Value::StorageTexture(format) => {
                format!("alias {name} = texture_storage_2d<{format}, write>;\n")
            }
        }
    }

    /// A constant the WGSL passes share with Rust, or a pass's definition ([`Pass::defines`]).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub enum Value {
        U32(u32),
        F32(f32),
        Bool(bool),
        /// A write-only storage texture of this WGSL format (a type: declared as an alias).
        StorageTexture(&'static str),
    }

    /// Every constant Rust and WGSL must agree on, taken from the Rust definitions: the
    /// prelude declares them, so a shader cannot keep a stale copy.
    pub fn shared_constants() -> Vec<(&'static str, Value)> {
        use super::{
            ALLOC_CANDIDATES, ALLOC_GROUP, ALLOC_STATE_WORDS, MLAB_MAX_ROWS, MLP_MEAN_AT,
            MLP_STD_AT, MLP_W1_AT, PIXEL_GROUP, SEARCH_PIXELS,
        };
        use crate::shared::{AMBIENT, MAX_FRAGMENTS_PER_PIXEL, PPM, SCAN_BLOCK, SCAN_GROUP};
        use crate::{alloc, importance, mlp};
        use Value::{F32, U32};
        vec![
            ("AMBIENT", F32(AMBIENT)),
            ("PIXEL_GROUP", U32(PIXEL_GROUP)),
            ("SCAN_BLOCK", U32(SCAN_BLOCK as u32)),
            ("SCAN_GROUP", U32(SCAN_GROUP as u32)),
            ("ALLOC_GROUP", U32(ALLOC_GROUP)),
            ("ALLOC_CANDIDATES", U32(ALLOC_CANDIDATES)),
            ("SEARCH_PIXELS", U32(SEARCH_PIXELS)),
            ("ALLOC_STATE_WORDS", U32(ALLOC_STATE_WORDS)),
            ("SEARCH_ROUNDS", U32(super::SEARCH_ROUNDS)),
            ("SEARCH_SPAN_DIGITS", U32(super::SEARCH_SPAN_DIGITS)),
            ("ALLOC_ROUNDS_WORD", U32(super::ALLOC_ROUNDS_WORD)),
            ("DISPATCH_WORDS", U32(super::DISPATCH_WORDS)),
            ("DISPATCH_PER_PIXEL", U32(super::DISPATCH_PER_PIXEL)),
            ("DISPATCH_ROUNDS", U32(super::DISPATCH_ROUNDS)),
            ("DISPATCH_SCAN", U32(super::DISPATCH_SCAN)),
            ("ALLOC_DISPATCHES", U32(super::ALLOC_DISPATCHES)),
            ("PPM", U32(PPM as u32)),
            ("WEIGHT_BITS", U32(alloc::WEIGHT_BITS)),
            ("WEIGHT_MAX", U32(alloc::WEIGHT_MAX)),
            ("LAMBDA_BITS", U32(alloc::LAMBDA_BITS)),
            ("LEVEL_BITS", U32(alloc::LEVEL_BITS)),
            ("REQUEST_BITS", U32(alloc::REQUEST_BITS)),
            ("REQUEST_SLOTS", F32(alloc::REQUEST_SLOTS)),
            ("PAIR_BIT", U32(alloc::PAIR_BIT)),
            ("IMPORTANCE_SCALE", F32(alloc::IMPORTANCE_SCALE)),
            ("MAX_IMPORTANCE", F32(alloc::MAX_IMPORTANCE)),
            ("LOG_FLOOR", F32(importance::LOG_FLOOR)),
            ("OPTICAL_DEPTH_UNIT", F32(importance::OPTICAL_DEPTH_UNIT)),
            ("NEAR_DEPTH_STEPS", F32(importance::NEAR_DEPTH_STEPS)),
            ("MAX_STANDARDISED", F32(mlp::MAX_STANDARDISED)),
            ("MAX_H2", U32(mlp::MAX_H2 as u32)),
            ("MLP_MEAN_AT", U32(MLP_MEAN_AT as u32)),
            ("MLP_STD_AT", U32(MLP_STD_AT as u32)),
            ("MLP_W1_AT", U32(MLP_W1_AT as u32)),
            ("MLAB_MAX_ROWS", U32(MLAB_MAX_ROWS)),
            ("FEATURES", U32(importance::FEATURES as u32)),
            ("MAX_F32", F32(f32::MAX)),
            ("APPEND_MAX", U32(crate::composite::APPEND_MAX)),
            (
                "MBOIT_MAX_ABSORBANCE",
                F32(crate::composite::MBOIT_MAX_ABSORBANCE),
            ),
            ("MBOIT_MIN_B0", F32(crate::composite::MBOIT_MIN_B0)),
            ("LIST_MAX_SORTED", U32(crate::composite::LIST_MAX_SORTED)),
            ("TAIL_WORDS", U32(crate::shared::TAIL_WORDS)),
            ("HDR_MAX_EXPONENT", U32(crate::shared::HDR_MAX_EXPONENT)),
            ("MARK_BITS", U32(crate::shared::MARK_BITS as u32)),
            ("RECORD_WORDS", U32(crate::shared::RECORD_WORDS)),
            ("NO_RECORD", U32(crate::shared::NO_RECORD)),
            ("TOTALS_WORDS", U32(crate::shared::TOTALS_WORDS)),
            ("TOTAL_FRAGMENTS", U32(crate::shared::TOTAL_FRAGMENTS)),
            ("TOTAL_COVERED", U32(crate::shared::TOTAL_COVERED)),
            ("TOTAL_MAX_COUNT", U32(crate::shared::TOTAL_MAX_COUNT)),
            ("TOTAL_DEEP", U32(crate::shared::TOTAL_DEEP)),
            ("TOTAL_RECORDS", U32(crate::shared::TOTAL_RECORDS)),
            (
                "MOST_RECORD_BATCHES",
                U32(crate::budget::MOST_RECORD_BATCHES as u32),
            ),
            ("TOTAL_DEEPER", U32(crate::shared::TOTAL_DEEPER)),
            ("BATCH_LISTED", U32(crate::shared::BATCH_LISTED)),
            ("BATCH_LO", U32(crate::shared::BATCH_LO)),
            ("BATCH_SIZE", U32(crate::shared::BATCH_SIZE)),
            ("BATCH_ROWS_BEFORE", U32(crate::shared::BATCH_ROWS_BEFORE)),
            ("BATCH_REQUESTS", U32(crate::shared::BATCH_REQUESTS)),
            ("BATCH_WORDS", U32(crate::shared::BATCH_WORDS)),
            ("REQUEST_SUM_BITS", U32(crate::shared::REQUEST_SUM_BITS)),
            ("STATUS_NEAR_LOOP", U32(crate::shared::STATUS_NEAR_LOOP)),
            ("STATUS_POOL_SHORT", U32(crate::shared::STATUS_POOL_SHORT)),
            ("PLAN_F_WORD", U32(crate::shared::PLAN_F_WORD)),
            ("PLAN_FLAGS_WORD", U32(crate::shared::PLAN_FLAGS_WORD)),
            ("PLAN_SHORT_SLOTS", U32(crate::plan::SHORT_SLOTS)),
            ("PLAN_SHORT_RECORDS", U32(crate::plan::SHORT_RECORDS)),
            ("PLAN_NO_SLOT", U32(crate::plan::NO_SLOT)),
            ("MAX_FRAGMENTS_PER_PIXEL", U32(MAX_FRAGMENTS_PER_PIXEL)),
            ("TEXEL_LIMIT", F32(crate::scene::material::TEXEL_LIMIT)),
            ("ALPHA_SCALE", F32(crate::scene::material::ALPHA_SCALE)),
            ("NO_TEXTURE", U32(super::NO_TEXTURE)),
            ("TEXTURE_NEAREST", U32(super::TEXTURE_NEAREST)),
            ("MATERIAL_DOUBLE_SIDED", U32(super::MATERIAL_DOUBLE_SIDED)),
            ("COVERAGE_OPAQUE", U32(super::COVERAGE_OPAQUE)),
            ("COVERAGE_MASK", U32(super::COVERAGE_MASK)),
            ("COVERAGE_BLEND", U32(super::COVERAGE_BLEND)),
            ("SHADED_NONE", U32(super::SHADED_NONE)),
            ("SHADED_OPAQUE", U32(super::SHADED_OPAQUE)),
            ("SHADED_TRANSPARENT", U32(super::SHADED_TRANSPARENT)),
        ]
    }

    /// A WGSL literal of `x`: the shortest decimal that reads back as the same f32 where that
    /// decimal is the f32's value exactly or rounds to it within the f32 range; else (f32::MAX,
    /// whose shortest decimal lies beyond it, which Tint refuses) its exact hexadecimal form.
    pub fn f32_literal(x: f32) -> String {
        let decimal = format!("{x:?}");
        let within = decimal
            .parse::<f64>()
            .is_ok_and(|d| d.abs() <= f32::MAX as f64);
        if within || !x.is_finite() {
            return decimal;
        }
        let bits = x.to_bits();
        let sign = if bits >> 31 == 1 { "-" } else { "" };
        let exp = ((bits >> 23) & 0xff) as i32 - 127;
        format!("{sign}0x1.{:06x}p{exp}f", (bits & 0x7f_ffff) << 1)
    }

    /// The WGSL declarations of [`shared_constants`], prepended to every pass.
    pub fn prelude() -> String {
        let mut s = String::from(
            "// Generated from the Rust constants (wgsl::shaders::shared_constants): edit them \
             there.\n",
        );
        for (name, v) in shared_constants() {
            s += &declaration(name, v);
        }
        s
    }
}

/// Invocations a workgroup of every per-pixel pass.
pub const PIXEL_GROUP: u32 = 64;
/// Invocations a workgroup of the allocation's per-pixel entry points.
pub const ALLOC_GROUP: u32 = 256;
// The allocation's mark pass writes its workgroup's marks as whole words of bits.
const _: () = assert!((ALLOC_GROUP as u64).is_multiple_of(crate::shared::MARK_BITS));
/// Pixels each invocation of the allocation's search sums before its workgroup's atomics: a
/// quarter of the shared atomics, and a quarter of the workgroups.
pub const SEARCH_PIXELS: u32 = 4;

/// The allocation's argument buffer for these grids (per pixel, rounds, scan; each as x, y):
/// [`DISPATCH_WORDS`] a dispatch, in the order of [`DISPATCH_PER_PIXEL`] and the others.
pub fn alloc_dispatches(
    grids: [(u32, u32); ALLOC_DISPATCHES as usize],
) -> [u32; (ALLOC_DISPATCHES * DISPATCH_WORDS) as usize] {
    let mut args = [0; (ALLOC_DISPATCHES * DISPATCH_WORDS) as usize];
    for (i, (x, y)) in grids.into_iter().enumerate() {
        let at = i * DISPATCH_WORDS as usize;
        args[at..at + 3].copy_from_slice(&[x, y, 1]);
    }
    args
}

/// Byte offset of one of the allocation's dispatches in its argument buffer.
pub const fn dispatch_offset(which: u32) -> u64 {
    (which * DISPATCH_WORDS * 4) as u64
}

pub use crate::mlp::{MLP_MEAN_AT, MLP_STD_AT, MLP_W1_AT};

/// The per-frame uniform (matches `Params` in common.wgsl; padded to 256 bytes).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Params {
    pub(crate) view_proj: [[f32; 4]; 4],
    pub(crate) forward: [f32; 4],
    pub(crate) background: [f32; 4],
    /// The eye's world position (w unused): glass's view angle.
    pub(crate) eye: [f32; 4],
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) k_uniform: u32,
    pub(crate) pixels: u32,
    pub(crate) budget_fragments: u32,
    pub(crate) vkb_alpha: f32,
    pub(crate) vkb_exponent: f32,
    pub(crate) vkb_noise: f32,
    pub(crate) vkb_seed: u32,
    /// A relative budget in parts per million (0: F is `budget_fragments`).
    pub(crate) budget_ppm: u32,
    /// 1 when the k-buffer passes have n(p) bound and capture in two modes (capture.wgsl).
    pub(crate) append: u32,
    /// 1 when FKB's slots are laid out layer-major (`slot_at` in common.wgsl).
    pub(crate) layer_major: u32,
    /// The scene's one opacity ([`crate::scene::Scene::uniform_opacity`]), or -1: the
    /// materials decide.
    pub(crate) uniform_alpha: f32,
    /// 1 when the A-buffer's store keeps each fragment's submission index beside its key.
    pub(crate) store_primitives: u32,
    /// MBOIT's moment bias and overestimation ([`crate::composite::MboitParams`]).
    pub(crate) mboit_bias: f32,
    pub(crate) mboit_overestimation: f32,
    /// The linked list's fragments a pixel sorted at resolve.
    pub(crate) list_sorted: u32,
    /// 1 when the k-buffer's tails live in its slot pool, after each pixel's k slots, where
    /// [`crate::shared::has_tail`] says (the allocated k-buffers, which know n(p)); 0: one
    /// tail a pixel in buffers of their own (FKB, an uploaded k).
    pub(crate) pooled_tail: u32,
    /// WBOIT's weight function (`composite::WboitWeight::code`) and the depth range its
    /// weights of the view-space distance read.
    pub(crate) wboit_weight: u32,
    pub(crate) wboit_near: f32,
    pub(crate) wboit_far: f32,
    /// 1 when glass filters per channel ([`crate::scene::Scene::tints`]): the A-buffer stores
    /// each fragment's tint beside its key and its resolves filter per channel.
    pub(crate) tinted: u32,
    /// 1 when the frame's colours keep their range above white ([`crate::scene::Scene::hdr`]):
    /// a transparent fragment's RGB is stored over a power of two, its exponent in the top
    /// byte of its tint word, which the methods that store fragments then store.
    pub(crate) hdr: u32,
    /// DKB's records whose statistics its count pass gathers (features_count.wgsl:
    /// those the frame before marked, as many as the slot pool holds); 0 where the frame draws
    /// a features pass of its own (a frame's first, one after a cut, batches).
    pub(crate) dkb_records: u32,
    pub(crate) _pad: [u32; 12],
}

/// `TextureRef.texels` where a material has no such texture.
pub const NO_TEXTURE: u32 = u32::MAX;
/// `TextureRef.sampler`: bits 0-1 the wrap mode along U ([`crate::scene::Wrap::code`]), 2-3
/// along V, then this (magnification NEAREST, else bilinear).
pub const TEXTURE_NEAREST: u32 = 1 << 4;
/// `Material.flags`: bits 4-5 the coverage (`COVERAGE_*`), then this.
pub const MATERIAL_DOUBLE_SIDED: u32 = 1 << 7;
pub const COVERAGE_OPAQUE: u32 = 0;
pub const COVERAGE_MASK: u32 = 1;
pub const COVERAGE_BLEND: u32 = 2;
/// What geometry.wgsl's `shade` makes of a fragment (scene::material::Shaded).
pub const SHADED_NONE: u32 = 0;
pub const SHADED_OPAQUE: u32 = 1;
pub const SHADED_TRANSPARENT: u32 = 2;

/// One of a material's textures as the geometry passes read it (matches `TextureRef` in
/// common.wgsl): where its texels start in the texel buffer (or [`NO_TEXTURE`]), its size, its
/// sampler (wrap modes, [`TEXTURE_NEAREST`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuTexture {
    pub(crate) texels: u32,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) sampler: u32,
}

/// A material as the geometry passes read it (matches `Material` in common.wgsl): 112 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuMaterial {
    pub(crate) factor: [f32; 4],
    pub(crate) base: GpuTexture,
    pub(crate) transmission_texture: GpuTexture,
    pub(crate) emissive_texture: GpuTexture,
    /// `emissiveFactor` times its strength.
    pub(crate) emissive: [f32; 3],
    /// The coverage and [`MATERIAL_DOUBLE_SIDED`].
    pub(crate) flags: u32,
    pub(crate) cutoff: f32,
    pub(crate) transmission: f32,
    /// Schlick's reflectance at normal incidence ([`crate::scene::Material::f0`]).
    pub(crate) f0: f32,
    pub(crate) _pad: u32,
    /// What its volume lets through a crossing ([`crate::scene::Material::attenuation`]).
    pub(crate) attenuation: [f32; 3],
    pub(crate) _pad2: u32,
}

/// A scene's materials as the GPU reads them, and every texture's texels one after another.
#[cfg(feature = "gpu")]
pub(crate) fn gpu_materials(scene: &crate::scene::Scene) -> (Vec<GpuMaterial>, Vec<u32>) {
    use crate::scene::Coverage;
    let mut starts = Vec::with_capacity(scene.textures.len());
    let mut texels = Vec::new();
    for t in &scene.textures {
        starts.push(texels.len() as u32);
        texels.extend_from_slice(&t.texels);
    }
    let texture = |t: Option<u32>| match t {
        Some(t) => {
            let tex = &scene.textures[t as usize];
            let mut sampler = tex.wrap[0].code() | tex.wrap[1].code() << 2;
            if tex.nearest {
                sampler |= TEXTURE_NEAREST;
            }
            GpuTexture {
                texels: starts[t as usize],
                width: tex.width,
                height: tex.height,
                sampler,
            }
        }
        None => GpuTexture {
            texels: NO_TEXTURE,
            ..Default::default()
        },
    };
    let materials = scene
        .materials
        .iter()
        .map(|m| {
            let (coverage, cutoff) = match m.coverage {
                Coverage::Opaque => (COVERAGE_OPAQUE, 0.0),
                Coverage::Mask(c) => (COVERAGE_MASK, c),
                Coverage::Blend => (COVERAGE_BLEND, 0.0),
            };
            let mut flags = coverage << 4;
            if m.double_sided {
                flags |= MATERIAL_DOUBLE_SIDED;
            }
            GpuMaterial {
                factor: m.base_color,
                base: texture(m.texture),
                transmission_texture: texture(m.transmission_texture),
                emissive_texture: texture(m.emissive_texture),
                emissive: m.emissive,
                flags,
                cutoff,
                transmission: m.transmission,
                f0: m.f0(),
                _pad: 0,
                attenuation: m.attenuation,
                _pad2: 0,
            }
        })
        .collect();
    (materials, texels)
}

/// The network's weights as the uniform `mlp.wgsl` reads, in 32-bit words: h1, h2, 0, 0,
/// mean, std (f32), then fc1 weight and bias, fc2 weight and bias, out weight and bias, each
/// layer's units padded with zeros to a multiple of four ([`mlp::padded_units`]: fc1 weight
/// `[12][p1]`, fc1 bias `[p1]`, fc2 weight `[p1][p2]`, fc2 bias `[p2]`, out weight `[p2]`, out
/// bias and three zeros), so every group of four units starts on a vec4 (f32) or half a vec4
/// (f16): f32 words, or at [`Precision::F16`] and [`Precision::F16Math`] binary16 values two
/// to a word (the first in the low half, as `unpack2x16float` reads them); zero-padded to a
/// whole vec4 ([`Mlp::uniform_bytes`]: sized to the network and its precision, as the network
/// pass built for it declares).
pub fn mlp_uniform(m: &Mlp) -> Vec<u32> {
    let mut v: Vec<u32> = [m.h1 as f32, m.h2 as f32, 0.0, 0.0]
        .iter()
        .map(|x| x.to_bits())
        .collect();
    debug_assert_eq!(v.len(), MLP_MEAN_AT);
    v.extend(m.mean.map(f32::to_bits));
    debug_assert_eq!(v.len(), MLP_STD_AT);
    v.extend(m.std.map(f32::to_bits));
    debug_assert_eq!(v.len(), MLP_W1_AT);
    let params = padded_parameters(m);
    match m.precision {
        Precision::F32 => v.extend(params.iter().map(|x| x.to_bits())),
        Precision::F16 | Precision::F16Math => {
            let halves: Vec<u32> = params
                .iter()
                .map(|&x| half::f16::from_f32(x).to_bits() as u32)
                .collect();
            v.extend(halves.chunks(2).map(|p| p[0] | p[1] << 16));
        }
    }
    v.resize((m.uniform_bytes() / 4) as usize, 0);
    v
}

/// The parameters in the uniform's order, each layer padded to [`mlp::padded_units`]
/// ([`mlp::uniform_parameter_count`] of them, a multiple of four).
fn padded_parameters(m: &Mlp) -> Vec<f32> {
    let (p1, p2) = (mlp::padded_units(m.h1), mlp::padded_units(m.h2));
    let mut v = Vec::with_capacity(mlp::uniform_parameter_count(m.h1, m.h2));
    let mut pad = |row: &[f32], to: usize| {
        v.extend_from_slice(row);
        v.resize(v.len() + to - row.len(), 0.0);
    };
    for row in m.w1.chunks(m.h1) {
        pad(row, p1);
    }
    pad(&m.b1, p1);
    for row in m.w2.chunks(m.h2) {
        pad(row, p2);
    }
    pad(&[], (p1 - m.h1) * p2);
    pad(&m.b2, p2);
    pad(&m.w3, p2);
    pad(&[m.b3], 4);
    debug_assert_eq!(v.len(), mlp::uniform_parameter_count(m.h1, m.h2));
    v
}

/// Most MLAB rows the GPU blends (a private array in the shader).
pub const MLAB_MAX_ROWS: u32 = 16;

/// The allocation parameters (matches `Alloc` in allocate.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct AllocParams {
    /// The weights' kind ([`crate::alloc::Target`]); F is the frame's plan's
    /// ([`crate::plan`], in its totals).
    pub(crate) kind: u32,
    pub(crate) _pad: [u32; 3],
}

/// The frame's plan's parameters (matches `PlanParams` in plan.wgsl; [`crate::plan::PlanInput`]
/// as the pass reads it).
#[repr(C)]
#[derive(Clone, Copy, Default, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PlanParams {
    pub(crate) kind: u32,
    pub(crate) budget: u32,
    pub(crate) exact_when_cheaper: u32,
    pub(crate) batches: u32,
    pub(crate) bytes_lo: u32,
    pub(crate) bytes_hi: u32,
    pub(crate) pool_lo: u32,
    pub(crate) pool_hi: u32,
    pub(crate) record_bytes: u32,
    pub(crate) layout_batches: u32,
    pub(crate) marks_lo: u32,
    pub(crate) marks_hi: u32,
    pub(crate) _pad: [u32; 4],
}

impl PlanParams {
    /// What plan.wgsl reads of `input`.
    #[cfg(feature = "gpu")]
    pub(crate) fn of(input: &crate::plan::PlanInput) -> PlanParams {
        use crate::budget::FragmentBudget;
        use crate::plan::PlanBudget;
        let split = |v: u64| (v as u32, (v >> 32) as u32);
        let (kind, budget, bytes) = match input.budget {
            PlanBudget::Fragments(FragmentBudget::Slots(f)) => {
                (0, f.min(u32::MAX as u64) as u32, 0)
            }
            PlanBudget::Fragments(FragmentBudget::Share(ppm)) => (1, ppm, 0),
            // The bytes beside the layout's fixed ones; all ones where there are none.
            PlanBudget::Bytes(m) => (
                2,
                0,
                m.checked_sub(input.layout.fixed_bytes(input.pixels))
                    .unwrap_or(u64::MAX),
            ),
        };
        let (bytes_lo, bytes_hi) = split(bytes);
        let (pool_lo, pool_hi) = split(input.pool_bytes);
        let (marks_lo, marks_hi) = split(crate::budget::marks_bytes(input.pixels));
        let (record_bytes, layout_batches) = match input.layout.pool_state {
            Some(ps) => ((ps.record_bytes + ps.list_bytes) as u32, ps.batches as u32),
            None => (0, 1),
        };
        PlanParams {
            kind,
            budget,
            exact_when_cheaper: input.exact_when_cheaper as u32,
            batches: input.batches.min(u32::MAX as u64) as u32,
            bytes_lo,
            bytes_hi,
            pool_lo,
            pool_hi,
            record_bytes,
            layout_batches,
            marks_lo,
            marks_hi,
            _pad: [0; 4],
        }
    }
}

/// Hexadecimal digits of the allocation's search interval: t lies in [0, 2^44) (16^11).
pub const SEARCH_SPAN_DIGITS: u32 = 11;
/// Rounds of the allocation's 16-way search recorded: the bracket (t's binary order of
/// magnitude) and at most [`SEARCH_SPAN_DIGITS`] more (allocate.wgsl's `choose`); the rounds
/// after the one that finds t dispatch no workgroup.
pub const SEARCH_ROUNDS: u32 = SEARCH_SPAN_DIGITS + 1;

/// Workgroups of `size` invocations covering `pixels`, as a 2-D grid when one dimension cannot
/// hold them (the passes compute `(y * width + x) * size + local index`, `grid_index` in
/// common.wgsl): frames up to 8K and beyond in one dispatch.
pub fn grid(pixels: u32, size: u32) -> (u32, u32) {
    let groups = pixels.div_ceil(size).max(1);
    let x = groups.min(65_535);
    (x, groups.div_ceil(x))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::budget;
    use std::mem::{offset_of, size_of};

    /// A struct of a parsed pass: its size and (member, offset) list.
    fn wgsl_struct(module: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
        module
            .types
            .iter()
            .find_map(|(_, t)| match &t.inner {
                naga::TypeInner::Struct { members, span } if t.name.as_deref() == Some(name) => {
                    let m = members.iter().map(|m| (m.name.clone().unwrap(), m.offset));
                    Some((*span, m.collect()))
                }
                _ => None,
            })
            .unwrap_or_else(|| panic!("no struct {name} in the WGSL"))
    }

    fn parse(pass: &str) -> naga::Module {
        naga::front::wgsl::parse_str(&shaders::source(pass).unwrap())
            .unwrap_or_else(|e| panic!("{pass}: {e}"))
    }

    macro_rules! offsets {
        ($t:ty; $($f:ident),*) => {
            vec![$((stringify!($f).to_string(), offset_of!($t, $f) as u32)),*]
        };
    }

    /// The passes spell the sizes Rust owns by the prelude's names, not as numbers a change
    /// on the Rust side would leave stale: the feature count (12), the relative budget's parts
    /// per million, MLAB's rows and the indirect dispatches' argument layout. Checked on every pass's source after the prelude, and held
    /// to the values: the generated network (`unrolled_forward`) and the passes still build.
    /// f32::MAX's shortest decimal (3.4028235e38) lies beyond f32's range, which Tint refuses:
    /// it is written in hexadecimal, which naga reads back as the same f32; other values as
    /// the shortest decimal.
    #[test]
    fn f32_literals_are_within_range_and_read_back_exactly() {
        assert_eq!(shaders::f32_literal(f32::MAX), "0x1.fffffep127f");
        assert_eq!(shaders::f32_literal(-f32::MAX), "-0x1.fffffep127f");
        assert_eq!(shaders::f32_literal(0.25), "0.25");
        for x in [f32::MAX, -f32::MAX, 0.25, 1e-3, 3.0e38] {
            let src = format!("const X: f32 = {};", shaders::f32_literal(x));
            let m = naga::front::wgsl::parse_str(&src).unwrap();
            let (_, c) = m.constants.iter().next().unwrap();
            match m.global_expressions[c.init] {
                naga::Expression::Literal(naga::Literal::F32(v)) => assert_eq!(v, x, "{src}"),
                ref e => panic!("{src}: {e:?}"),
            }
        }
    }

    /// Every binding `runtime/build.rs` names from a shader's text is the one naga reads from
    /// each module built with that shader (dhoit's passes, and the modules an application's
    /// fragment shader starts with), and every named binding is in such a module.
    #[test]
    fn the_named_bindings_are_the_ones_naga_reads() {
        let mut modules: Vec<(String, naga::Module, Vec<&str>)> = Vec::new();
        for p in shaders::PASSES {
            let mut parts = vec![p.source];
            parts.extend(p.includes);
            modules.push((p.name.to_string(), parse(p.name), parts));
            if let Some(app) = shaders::application_pass(p.name, &[], 1) {
                let m = naga::front::wgsl::parse_str(&app).unwrap_or_else(|e| panic!("{e}"));
                modules.push((
                    format!("application {}", p.name),
                    m,
                    vec![shaders::OIT_PHASE],
                ));
            }
        }
        let mut unchecked = Vec::new();
        let mut texts = std::collections::HashMap::new();
        for &(file, name, binding) in bindings::ALL {
            let text = texts.entry(file).or_insert_with(|| {
                let path = format!("{}/../shaders/{file}.wgsl", env!("CARGO_MANIFEST_DIR"));
                std::fs::read_to_string(path).unwrap()
            });
            let var = name.to_ascii_lowercase();
            let mut checked = 0;
            for (label, m, _) in modules
                .iter()
                .filter(|(_, _, parts)| parts.contains(&text.as_str()))
            {
                let read = m
                    .global_variables
                    .iter()
                    .find(|(_, g)| g.name.as_deref() == Some(var.as_str()))
                    .and_then(|(_, g)| g.binding.as_ref())
                    .map(|b| b.binding);
                assert_eq!(
                    read,
                    Some(binding),
                    "{file}.wgsl's `{var}` in the {label} module"
                );
                checked += 1;
            }
            if checked == 0 {
                unchecked.push(format!("{file}.{name}"));
            }
        }
        assert!(unchecked.is_empty(), "in no module: {unchecked:?}");
    }

    #[test]
    fn the_passes_spell_the_shared_sizes_by_name() {
        assert_eq!(crate::importance::FEATURES, 12);
        for p in shaders::PASSES {
            let src = shaders::source(p.name).unwrap();
            let body = &src[shaders::prelude().len()..];
            for stale in [
                "array<f32, 12>",
                "12u * ",
                "i < 12u",
                "1000000",
                "array<Row, 17>",
                "array<u32, 12>",
                "array<u32, 4>",
                "dispatches[0]",
                "dispatches[4]",
                "dispatches[8]",
            ] {
                assert!(!body.contains(stale), "{}: spells '{stale}'", p.name);
            }
        }
    }

    #[test]
    fn uploaded_structs_have_the_layout_of_their_wgsl_declarations() {
        let module = parse("allocate");
        let (span, wgsl) = wgsl_struct(&module, "Params");
        let rust = offsets!(Params; view_proj, forward, background, eye, width, height,
            k_uniform, pixels, budget_fragments, vkb_alpha, vkb_exponent, vkb_noise, vkb_seed,
            budget_ppm, append, layer_major, uniform_alpha, store_primitives, mboit_bias,
            mboit_overestimation, list_sorted, pooled_tail, wboit_weight, wboit_near, wboit_far,
            tinted, hdr, dkb_records);
        assert_eq!(
            wgsl, rust,
            "Params: WGSL (left) and Rust (right) members and offsets"
        );
        assert!(
            span as usize <= size_of::<Params>(),
            "Params: WGSL {span} bytes"
        );
        assert_eq!(size_of::<Params>() as u64, crate::shared::PARAMS_BYTES);

        let (span, wgsl) = wgsl_struct(&parse("capture"), "Material");
        let rust = offsets!(GpuMaterial; factor, base, transmission_texture, emissive_texture,
            emissive, flags, cutoff, transmission, f0, attenuation);
        assert_eq!(wgsl, rust, "Material: WGSL (left) and Rust (right)");
        assert_eq!(span as usize, size_of::<GpuMaterial>());
        let (span, wgsl) = wgsl_struct(&parse("capture"), "TextureRef");
        let rust = offsets!(GpuTexture; texels, width, height, sampler);
        assert_eq!(wgsl, rust, "TextureRef: WGSL (left) and Rust (right)");
        assert_eq!(span as usize, size_of::<GpuTexture>());

        let (span, wgsl) = wgsl_struct(&module, "Alloc");
        let rust = offsets!(AllocParams; kind, _pad);
        assert_eq!(
            &wgsl[..1],
            &rust[..1],
            "Alloc: WGSL (left) and Rust (right)"
        );
        assert_eq!(span as usize, size_of::<AllocParams>());

        let (span, wgsl) = wgsl_struct(&parse("plan"), "PlanParams");
        let rust = offsets!(PlanParams; kind, budget, exact_when_cheaper, batches, bytes_lo,
            bytes_hi, pool_lo, pool_hi, record_bytes, layout_batches, marks_lo, marks_hi);
        assert_eq!(
            &wgsl[..rust.len()],
            &rust[..],
            "PlanParams: WGSL (left) and Rust (right)"
        );
        assert_eq!(span as usize, size_of::<PlanParams>());
        assert_eq!(
            size_of::<PlanParams>() as u64,
            crate::shared::PLAN_PARAMS_BYTES
        );

        // The search state holds what the host allocates for it.
        assert_eq!(global_size(&module, "state"), 8 * ALLOC_STATE_WORDS as u64);
        // The dispatches' arguments: as many bytes as the host writes, laid out by hand.
        let args = alloc_dispatches([(3, 4), (5, 6), (7, 8)]);
        assert_eq!(args, [3, 4, 1, 0, 5, 6, 1, 0, 7, 8, 1, 0]);
        assert_eq!(global_size(&module, "dispatches"), 4 * args.len() as u64);
        assert_eq!(
            [DISPATCH_PER_PIXEL, DISPATCH_ROUNDS, DISPATCH_SCAN].map(dispatch_offset),
            [0, 16, 32]
        );
        assert_eq!(global_size(&parse("importance_dkb"), "dispatch"), 16);
    }

    #[test]
    fn the_weights_uniform_is_as_large_as_what_mlp_uniform_writes() {
        // The passes as written declare the largest network's uniform, the default's at f32.
        for pass in ["predict", "importance_dkb"] {
            let module = parse(pass);
            assert_eq!(
                global_size(&module, "weights"),
                budget::MLP_UNIFORM_BYTES,
                "{pass}"
            );
        }
        let m = Mlp::random(1);
        assert_eq!(
            crate::mlp::uniform_parameter_count(m.h1, m.h2),
            crate::mlp::MAX_PARAMETERS
        );
        let v = mlp_uniform(&m);
        assert_eq!(4 * v.len() as u64, budget::MLP_UNIFORM_BYTES);
        assert_eq!(&v[MLP_MEAN_AT..MLP_STD_AT], &m.mean.map(f32::to_bits));
        assert_eq!(&v[MLP_STD_AT..MLP_W1_AT], &m.std.map(f32::to_bits));
        assert_eq!(v[MLP_W1_AT], m.w1[0].to_bits());
        // At f16: the header as before, then two rounded values a word, low half first, in
        // half the words.
        let h = m.at_precision(Precision::F16).unwrap();
        let v16 = mlp_uniform(&h);
        assert_eq!(4 * v16.len() as u64, h.uniform_bytes());
        assert_eq!(&v16[..MLP_W1_AT], &v[..MLP_W1_AT]);
        let params: Vec<f32> = h.parameters().collect();
        for (i, &p) in params.iter().enumerate() {
            let word = v16[MLP_W1_AT + i / 2];
            let bits = (word >> (16 * (i % 2))) & 0xffff;
            assert_eq!(
                half::f16::from_bits(bits as u16).to_f32(),
                p,
                "parameter {i}"
            );
        }
        assert!(
            v16[MLP_W1_AT + params.len().div_ceil(2)..]
                .iter()
                .all(|&w| w == 0)
        );
    }

    /// Bytes of a module's global variable `name` (a binding's declared size).
    fn global_size(module: &naga::Module, name: &str) -> u64 {
        let var = module
            .global_variables
            .iter()
            .find(|(_, g)| g.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("no global '{name}' in the WGSL"))
            .1;
        module.types[var.ty].inner.size(module.to_ctx()) as u64
    }

    #[test]
    fn a_network_s_weights_take_what_its_sizes_and_precision_need_and_no_more() {
        // By hand: 28 header words, then the padded parameters (12 p1 + p1 + p1 p2 + p2 + p2
        // + 4), one a word at f32 and two at f16, in whole vec4s.
        let cases = [
            (128, 64, Precision::F32, 40_064),
            (128, 64, Precision::F16, 20_096),
            (16, 8, Precision::F32, 1_536),
            (16, 8, Precision::F16, 832),
            // 5 and 3 units pad to 8 and 4: 96 + 8 + 32 + 4 + 4 + 4 = 148 parameters.
            (5, 3, Precision::F32, 704),
            (5, 3, Precision::F16Math, 416),
        ];
        for (h1, h2, p, bytes) in cases {
            let m = Mlp::random_sized(3, h1, h2).at_precision(p).unwrap();
            assert_eq!(m.uniform_bytes(), bytes, "{h1}-{h2} {p}");
            // What the host writes is that size, and every parameter is in it.
            let v = mlp_uniform(&m);
            assert_eq!(4 * v.len() as u64, bytes, "{h1}-{h2} {p}");
            let words =
                crate::mlp::uniform_parameter_count(h1, h2) / if p.half_weights() { 2 } else { 1 };
            assert!(MLP_W1_AT + words <= v.len() && v.len() < MLP_W1_AT + words + 4);
            // The pass built for the network declares exactly that many bytes.
            #[cfg(feature = "gpu")]
            for pass in ["predict", "importance_dkb"] {
                let src = crate::gpu::network_pass_source(pass, &m);
                let module = naga::front::wgsl::parse_str(&src)
                    .unwrap_or_else(|e| panic!("{pass} {h1}-{h2} {p}: {e}"));
                assert_eq!(
                    global_size(&module, "weights"),
                    bytes,
                    "{pass} {h1}-{h2} {p}"
                );
            }
        }
    }

    #[test]
    fn a_variant_of_a_pass_is_its_definitions_declared_once_and_never_in_a_shader_file() {
        let mut defined = 0;
        for p in shaders::PASSES.iter() {
            for &(name, default) in p.defines {
                let declared = [format!("const {name}:"), format!("alias {name} =")];
                // No shader file declares it: the composition does, once.
                for src in p.includes.iter().chain([&p.source]) {
                    for d in &declared {
                        assert!(
                            !src.contains(d.as_str()),
                            "{}: a file declares {name}",
                            p.name
                        );
                    }
                }
                let full = shaders::source(p.name).unwrap();
                let count: usize = declared
                    .iter()
                    .map(|d| full.matches(d.as_str()).count())
                    .sum();
                assert_eq!(count, 1, "{}: {name} declared {count} times", p.name);
                // A variant's value is the one declared; another kind is refused.
                let other = match default {
                    shaders::Value::Bool(b) => shaders::Value::Bool(!b),
                    shaders::Value::U32(x) => shaders::Value::U32(x + 1),
                    shaders::Value::F32(x) => shaders::Value::F32(x + 1.0),
                    shaders::Value::StorageTexture(_) => {
                        shaders::Value::StorageTexture("rgba8unorm")
                    }
                };
                let variant = shaders::source_with(p.name, &[(name, other)]).unwrap();
                let expected = match other {
                    shaders::Value::Bool(b) => format!("const {name}: bool = {b};"),
                    shaders::Value::U32(x) => format!("const {name}: u32 = {x}u;"),
                    shaders::Value::F32(_) => format!("const {name}: f32 ="),
                    shaders::Value::StorageTexture(f) => {
                        format!("alias {name} = texture_storage_2d<{f}, write>;")
                    }
                };
                assert!(variant.contains(&expected), "{}: {expected}", p.name);
                let wrong = match default {
                    shaders::Value::Bool(_) => shaders::Value::U32(1),
                    _ => shaders::Value::Bool(true),
                };
                assert!(shaders::source_with(p.name, &[(name, wrong)]).is_none());
                defined += 1;
            }
            assert!(
                shaders::source_with(p.name, &[("NO_SUCH", shaders::Value::Bool(true))]).is_none(),
                "{}: a definition it does not have",
                p.name
            );
        }
        assert!(defined >= 20, "{defined} definitions");
        // The network's forward: composed in place of the loops, only where a pass runs one.
        let written = "fn mlp_forward(f: array<f32, FEATURES>) -> f32 { return 0.0; }\n";
        let src = shaders::compose("predict", &[], Some(written)).unwrap();
        assert!(src.contains(written) && !src.contains(shaders::MLP_LOOP));
        assert!(
            shaders::source("predict")
                .unwrap()
                .contains(shaders::MLP_LOOP)
        );
        assert!(shaders::compose("resolve", &[], Some(written)).is_none());
    }

    #[test]
    fn the_prelude_declares_every_shared_constant_once_and_no_pass_redeclares_one() {
        let prelude = shaders::prelude();
        for (name, _) in shaders::shared_constants() {
            let decl = format!("const {name}:");
            assert_eq!(prelude.matches(&decl).count(), 1, "{name}");
            let others = [
                shaders::COMMON,
                shaders::GEOMETRY,
                shaders::MLP,
                shaders::SORT,
                shaders::BEHIND,
            ];
            for src in others
                .iter()
                .chain(shaders::PASSES.iter().map(|p| &p.source))
            {
                assert!(!src.contains(&decl), "{name} is declared again in a shader");
            }
        }
        // Every pass parses with the prelude, and its values are the Rust ones.
        let module = parse("allocate");
        let value = |name: &str| {
            let (_, c) = module
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some(name))
                .unwrap_or_else(|| panic!("{name}"));
            match module.global_expressions[c.init] {
                naga::Expression::Literal(l) => l,
                ref e => panic!("{name}: {e:?}"),
            }
        };
        assert_eq!(value("AMBIENT"), naga::Literal::F32(crate::raster::AMBIENT));
        // counts.wgsl declares its own (an application's A-buffer module has no prelude).
        assert_eq!(
            value("COUNT_SATURATED"),
            naga::Literal::U32(crate::shared::COUNT_SATURATED)
        );
        assert_eq!(
            value("PAIR_BIT"),
            naga::Literal::U32(crate::alloc::PAIR_BIT)
        );
        assert_eq!(value("MAX_F32"), naga::Literal::F32(f32::MAX));
    }
}
