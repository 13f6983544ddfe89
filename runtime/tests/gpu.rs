//! The wgpu renderer against its CPU twins. These tests need a GPU adapter (Mesa's lavapipe in
//! CI); without one they fail, unless DHOIT_SKIP_GPU=1 says to skip them (and they say so).

mod common;

use common::{RenderMethod, gpu, max_abs_diff};

use dhoit_runtime::alloc;
use dhoit_runtime::budget::{self, Budget, FragmentBudget};
use dhoit_runtime::composite;
use dhoit_runtime::fragment::FragmentLists;
use dhoit_runtime::gpu::Slots;
use dhoit_runtime::importance;
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::{self, Camera, Opacity, Scene};
use dhoit_runtime::wgsl::shaders;

#[test]
fn every_shader_validates_and_translates_without_a_gpu() {
    use naga::valid::{Capabilities, ValidationFlags, Validator};
    let mut accepted = Vec::new();
    // Every pass as built by default, and each variant of it: each of its switches the other
    // way, its storage target another format.
    let variants = shaders::PASSES.iter().flat_map(|p| {
        let flipped = p.defines.iter().filter_map(|&(d, v)| match v {
            shaders::Value::Bool(b) => Some((d, shaders::Value::Bool(!b))),
            shaders::Value::StorageTexture(_) => {
                Some((d, shaders::Value::StorageTexture("rgba8unorm")))
            }
            _ => None,
        });
        std::iter::once((p.name, None)).chain(flipped.map(move |f| (p.name, Some(f))))
    });
    for (name, variant) in variants {
        let src = shaders::source_with(name, variant.as_slice()).unwrap();
        let label = match variant {
            Some((d, v)) => format!("{name} ({d} {v:?})"),
            None => name.to_string(),
        };
        let module = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{label}: {}", e.emit_to_string(&src)));
        // pack/unpack2x16float (the f16 weights) need SHADER_FLOAT16_IN_FLOAT32, which any
        // device wgpu grants the downlevel flag SHADER_F16_IN_F32 to (every Vulkan one).
        let caps = Capabilities::SHADER_INT64
            | Capabilities::SHADER_INT64_ATOMIC_ALL_OPS
            | Capabilities::SHADER_FLOAT16_IN_FLOAT32;
        // The portable passes without 64-bit integers, as a WebGPU or Metal device without
        // them validates them; every other pass needs them.
        let narrow = caps - Capabilities::SHADER_INT64 - Capabilities::SHADER_INT64_ATOMIC_ALL_OPS;
        let without = Validator::new(ValidationFlags::all(), narrow).validate(&module);
        let portable = shaders::PORTABLE.contains(&name);
        assert_eq!(
            without.is_ok(),
            portable,
            "{name}: validates without 64-bit integers: {}, listed portable: {portable}",
            without.is_ok()
        );
        let caps = if portable { narrow } else { caps };
        let info = Validator::new(ValidationFlags::all(), caps)
            .validate(&module)
            .unwrap_or_else(|e| panic!("{label}: {}", e.emit_to_string(&src)));
        let spv = naga::back::spv::write_vec(&module, &info, &Default::default(), None)
            .unwrap_or_else(|e| panic!("{name}: SPIR-V: {e}"));
        assert!(spv.len() > 100, "{name}");
        // Metal and DX12 compile one entry point at a time, as wgpu asks for them.
        for ep in &module.entry_points {
            let msl = naga::back::msl::PipelineOptions {
                entry_point: Some((ep.stage, ep.name.clone())),
                ..Default::default()
            };
            // MSL 2.4: fragment stages that write storage (1.2) and 64-bit atomics (2.4); the
            // portable passes in MSL 2.1 (every Mac and iPhone wgpu supports).
            let msl_options = naga::back::msl::Options {
                lang_version: if portable { (2, 1) } else { (2, 4) },
                ..Default::default()
            };
            naga::back::msl::write_string(&module, &info, &msl_options, &msl)
                .unwrap_or_else(|e| panic!("{name}::{}: MSL: {e:?}", ep.name));
            let mut hlsl = String::new();
            let pipeline = naga::back::hlsl::PipelineOptions {
                entry_point: Some((ep.stage, ep.name.clone())),
            };
            naga::back::hlsl::Writer::new(&mut hlsl, &Default::default(), &pipeline)
                .write(&module, &info, None)
                .unwrap_or_else(|e| panic!("{name}::{}: HLSL: {e:?}", ep.name));
        }
        accepted.push(label);
    }
    eprintln!(
        "SPIR-V, MSL and HLSL accept every entry point of {accepted:?}; {:?} without 64-bit integers",
        shaders::PORTABLE
    );
}

/// One real scene among the GPU tests: the flight helmet from ../shared/scenes (or
/// $DHOIT_SCENES; see `common::real_or_exported` when there are none).
const REAL: &str = "real:FlightHelmet/glTF/FlightHelmet.gltf";

fn frame(name: &str, view: usize, size: (u32, u32)) -> (Scene, Camera) {
    let s = match name.strip_prefix("real:") {
        Some(rel) => {
            // On a clone with nothing beside it, a textured-looking built-in written as glTF
            // stands in, read through the same loader.
            let path = common::real_or_exported(rel, "statue");
            scene::load(path.to_str().unwrap(), Opacity::default())
                .unwrap_or_else(|e| panic!("the real scene for the GPU tests: {e}"))
        }
        None => scene::load(name, Opacity::default()).unwrap(),
    };
    let cam = Camera::orbit(&s, view, scene::DEFAULT_VIEWS, size);
    (s, cam)
}

const BG: [f32; 3] = [0.9, 0.8, 1.0];

/// VKB at F slots with the paper's parameters.
fn vkb_at(f: u64) -> Slots<'static> {
    Slots::Vkb(Default::default(), f.into())
}

/// The GPU's own fragments of a frame (its A-buffer, read back), which the twins take.
fn gpu_fragments(
    g: &dhoit_runtime::gpu::Gpu,
    s: &Scene,
    cam: &Camera,
    size: (u32, u32),
) -> FragmentLists {
    g.render_method(s, cam, size, BG, dhoit_runtime::gpu::Slots::Exact)
        .unwrap()
        .fragments
        .unwrap()
}

#[test]
fn abuffer_matches_the_cpu_on_its_own_fragments() {
    let Some(g) = gpu() else { return };
    for (name, view) in [("shells", 0), ("plates", 1), ("particles", 2), (REAL, 1)] {
        let size = (96, 72);
        let (s, cam) = frame(name, view, size);
        let f = g
            .render_method(&s, &cam, size, BG, dhoit_runtime::gpu::Slots::Exact)
            .unwrap();
        let gfl = f.fragments.as_ref().unwrap();
        // Coverage against the CPU rasterizer.
        let cpu = rasterize(&s, &cam, size).unwrap();
        let differ = (0..cpu.pixel_count())
            .filter(|&p| cpu.count(p) != gfl.count(p))
            .count();
        let share = differ as f64 / cpu.pixel_count() as f64;
        eprintln!(
            "{name}: {} GPU fragments, {} CPU; coverage differs in {:.3}% of pixels",
            gfl.fragment_count(),
            cpu.fragment_count(),
            100.0 * share
        );
        assert!(
            share < 0.001,
            "{name}: coverage differs in {:.3}% of pixels",
            100.0 * share
        );
        // The CPU twin on the GPU's fragments.
        let twin = composite::composite(gfl, composite::Method::Exact, BG);
        let d = f.image.max_abs_diff(&twin);
        assert!(
            d <= 1e-5,
            "{name}: GPU A-buffer differs from the CPU twin by {d}"
        );
        // Memory: exactly the A-buffer layout with its fragments.
        let expect =
            budget::ABUFFER.allocated_bytes(gfl.pixel_count() as u64, gfl.fragment_count() as u64);
        assert_eq!(f.allocated_bytes, expect, "{name}");
    }
}

/// The CPU twin of the capture pass.
fn twin_capture(fl: &FragmentLists, k: &[u32]) -> (Vec<u64>, Vec<u32>) {
    composite::capture(fl, k)
}

#[test]
fn kbuffers_match_the_cpu_slot_for_slot() {
    let Some(g) = gpu() else { return };
    for (name, view) in [("hair", 0), ("particles", 1), (REAL, 2)] {
        let size = (80, 60);
        let (s, cam) = frame(name, view, size);
        let gfl = gpu_fragments(g, &s, &cam, size);
        let pixels = gfl.pixel_count();
        // FKB with k = 2, and the optimal allocation at 1.5 slots per pixel uploaded as k.
        let curves = alloc::error_curves(&gfl, BG);
        let (opt_k, _) = alloc::optimal(&curves, (1.5 * pixels as f64) as u64);
        for (label, k) in [("fkb", vec![2u32; pixels]), ("optimal", opt_k)] {
            let slots = if label == "fkb" {
                Slots::Uniform(2)
            } else {
                Slots::PerPixel(&k)
            };
            let f = g.render_method(&s, &cam, size, BG, slots).unwrap();
            let (keys, bases, tails) = f.slots.clone().unwrap();
            let (twin_keys, twin_tails) = twin_capture(&gfl, &k);
            assert_eq!(
                bases[pixels] as usize,
                twin_keys.len(),
                "{name} {label}: slot count"
            );
            assert!(keys == twin_keys, "{name} {label}: captured slots differ");
            assert!(tails == twin_tails, "{name} {label}: tail sums differ");
            let twin = composite::composite(&gfl, composite::Method::Hybrid(&k), BG);
            let d = f.image.max_abs_diff(&twin);
            assert!(
                d <= 1e-5,
                "{name} {label}: image differs from the CPU twin by {d}"
            );
            let layout = if label == "fkb" {
                budget::FKB
            } else {
                budget::OPT
            };
            let expect = layout.allocated_bytes(pixels as u64, bases[pixels] as u64);
            assert_eq!(f.allocated_bytes, expect, "{name} {label}: allocated bytes");
        }
    }
}

/// An image's channels as bits, to compare images exactly.
fn image_bits(img: &composite::Image) -> Vec<u32> {
    float_bits(img.data.iter().flatten())
}

fn float_bits<'a>(v: impl IntoIterator<Item = &'a f32>) -> Vec<u32> {
    v.into_iter().map(|x| x.to_bits()).collect()
}

#[test]
fn shuffled_submission_gives_bit_identical_gpu_images() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64, 48);
    let (s, cam) = frame("spheres", 1, (w, h));
    let k: Vec<u32> = (0..w * h).map(|p| 1 + p % 3).collect();
    let mlp = dhoit_runtime::mlp::Mlp::random(4);
    let f = (1.5 * (w * h) as f64) as u64;
    let vkb = dhoit_runtime::importance::VkbParams::default();
    let images = |sc: &Scene| {
        [
            Slots::Exact,
            Slots::Uniform(2),
            Slots::PerPixel(&k),
            Slots::Vkb(vkb, f.into()),
            Slots::Dkb(&mlp, f.into()),
        ]
        .map(|slots| image_bits(&g.render_method(sc, &cam, (w, h), BG, slots).unwrap().image))
    };
    let base = images(&s);
    for seed in 0..10 {
        assert!(images(&s.shuffled(seed)) == base, "shuffle {seed}");
    }
}

/// DKB's records gathered in batches (`Tuning::record_batches`, up to three) or all at once
/// (1, the default) give the same importance and image, bit for bit, from the
/// network run on as many rows, and each frame
/// allocates its layout's bytes for the batches it took: fewer, the more batches, where the
/// records outweigh the slots and tails (particles at 0.05 fpp).
#[test]
fn dkb_s_records_in_batches_or_at_once_give_the_same_frame_in_fewer_bytes() {
    let Some(g) = gpu() else { return };
    let mlp = common::committed_weights();
    let (w, h) = (64, 48);
    let (s, cam) = frame("particles", 1, (w, h));
    let gfl = gpu_fragments(g, &s, &cam, (w, h));
    let counts = gfl.counts();
    let occ = budget::Occupancy::of(&counts);
    let f = (w * h / 20) as u64;
    let mut o = dhoit_runtime::gpu::FrameOptions::default().always_approximate();
    let frames = [1, 2, 3].map(|b| {
        o.decision.record_batches = b;
        let fr = g
            .render_with(&o, &s, &cam, (w, h), BG, Slots::Dkb(&mlp, f.into()))
            .unwrap();
        let layout = budget::DKB.for_network(&mlp).with_record_batches(b);
        let pool = layout.pool_bytes(gfl.pixel_count() as u64, f, &occ);
        let (_, batches) = layout.pool_state.unwrap().batch(pool, occ.deeper);
        assert_eq!(fr.record_batches, Some(batches), "at most {b}");
        assert_eq!(
            fr.allocated_bytes,
            layout.reserved_bytes(gfl.pixel_count() as u64, f, &occ),
            "at most {b}"
        );
        fr
    });
    let (one, most) = (&frames[0], &frames[2]);
    assert_eq!(one.record_batches, Some(1));
    assert!(
        most.record_batches.is_some_and(|b| b > 1) && most.allocated_bytes < one.allocated_bytes,
        "{:?} batches in {} bytes, one in {}",
        most.record_batches,
        most.allocated_bytes,
        one.allocated_bytes
    );
    let bits = |f: &dhoit_runtime::gpu::GpuFrame| -> Vec<u32> {
        f.importance
            .as_ref()
            .unwrap()
            .iter()
            .map(|i| i.to_bits())
            .collect()
    };
    for (b, fr) in frames.iter().enumerate().skip(1) {
        assert!(
            bits(fr) == bits(&frames[0]),
            "{} batches: importance",
            b + 1
        );
        assert!(
            fr.image.data == frames[0].image.data,
            "{} batches: image",
            b + 1
        );
        // The network ran on the same records, whatever the batches (the rows of the batches
        // before the last, BATCH_ROWS_BEFORE, and the last's list).
        assert!(frames[0].network_rows.is_some_and(|r| r > 0));
        assert_eq!(fr.network_rows, frames[0].network_rows, "{} batches", b + 1);
    }
}

/// A frame the budget truncates with no pixel of three fragments or more (two layers at 25%)
/// has no record to gather, in one batch all the same: every pixel's importance 0 with its
/// pair mark set nowhere (not what a deep frame before it left in the buffers it reuses), the
/// allocation and image the twins'.
#[test]
fn a_truncated_frame_without_records_gathers_one_empty_batch() {
    let Some(g) = gpu() else { return };
    let mlp = common::committed_weights();
    let (w, h) = (48, 36);
    let s = common::layers(2);
    let cam = Camera::orbit(&s, 0, scene::DEFAULT_VIEWS, (w, h));
    let gfl = gpu_fragments(g, &s, &cam, (w, h));
    let counts = gfl.counts();
    assert!(counts.iter().all(|&n| n <= 2) && counts.contains(&2));
    let f = gfl.fragment_count() as u64 / 4;
    // A deep frame of the same size first, so the buffers this frame takes from the device's
    // pool hold its importance: nothing may be left of it.
    let (deep, deep_cam) = frame("particles", 1, (w, h));
    let before = g
        .render_method(&deep, &deep_cam, (w, h), BG, Slots::Dkb(&mlp, 200.into()))
        .unwrap();
    assert!(before.importance.unwrap().iter().any(|i| i.to_bits() != 0));
    let d = g
        .render_method(&s, &cam, (w, h), BG, Slots::Dkb(&mlp, f.into()))
        .unwrap();
    assert_eq!(d.record_batches, Some(1));
    let imp = d.importance.clone().unwrap();
    assert!(
        imp.iter().all(|i| i.to_bits() == 0),
        "importance without records"
    );
    check_allocation_and_capture(&gfl, &d, &imp, f, mlp.target, "two layers at 25%");
}

/// DKB's importance pass with the network's weights staged in workgroup memory
/// (`Tuning::shared_weights`) gives the importance and image of the pass that reads them from the
/// uniform (held to the CPU twin by the other tests): the default network, one whose first
/// layer leaves a tile part empty (20 units in tiles of 16), and one at f16; then the other
/// layouts' frames ([`features_and_network_layouts_give_the_same_frame`]).
#[test]
fn weights_staged_in_workgroup_memory_and_the_other_layouts_give_the_same_frames() {
    let mut o = dhoit_runtime::gpu::FrameOptions::default().always_approximate();
    if gpu().is_none() {
        return;
    }
    // A device of its own: which passes a frame records follows the device's last frame.
    let mut g = dhoit_runtime::gpu::Gpu::new().unwrap();
    let (w, h) = (64, 48);
    let (s, cam) = frame("particles", 1, (w, h));
    let default = common::committed_weights();
    let nets = [
        ("default", default),
        ("20-12", dhoit_runtime::mlp::Mlp::random_sized(3, 20, 12)),
        (
            "16-8 f16",
            dhoit_runtime::mlp::Mlp::random_sized(4, 16, 8)
                .at_precision(dhoit_runtime::mlp::Precision::F16)
                .unwrap(),
        ),
    ];
    let f = (3 * w * h / 2) as u64;
    for (label, mlp) in &nets {
        let mut frames = [false, true].map(|shared| {
            o.tuning.shared_weights = shared;
            g.render_with(&o, &s, &cam, (w, h), BG, Slots::Dkb(mlp, f.into()))
                .unwrap()
        });
        // Each frame ran the network it was asked for.
        assert!(
            frames[0].variants.contains(&"network: written out")
                && frames[1]
                    .variants
                    .contains(&"network: weights in workgroup memory"),
            "{label}: {:?} / {:?}",
            frames[0].variants,
            frames[1].variants
        );
        let (b, a) = (frames[1].clone(), &mut frames[0]);
        let (ia, ib) = (a.importance.take().unwrap(), b.importance.unwrap());
        let d = max_abs_diff(&ia, &ib);
        eprintln!("{label}: |staged - uniform| importance {d:e}");
        assert!(d <= 1e-6, "{label}: importance differs by {d}");
        assert!(ia.iter().any(|&i| i.abs() > 0.0), "{label}: no importance");
        let di = a.image.max_abs_diff(&b.image);
        assert!(di <= 1e-5, "{label}: image differs by {di}");
    }
    // The features pass's and the network's other layouts, on the same device (one device
    // fewer in the test process: lavapipe runs each device's threads) and frame.
    features_and_network_layouts_give_the_same_frame(&mut g, (&s, &cam), (w, h), &nets[0].1);
}

/// The two ways the features pass may take a pixel's nearest key (`Tuning::features_preload`)
/// gather the same statistics, and the network written out for its shape
/// (`Tuning::unrolled_network`) gives the importance of mlp.wgsl's loops: one frame per
/// setting, at a budget that truncates and at one that holds every fragment, the same
/// statistics as the CPU twin's for every pixel of two fragments or more (the pixels with a
/// record) where the features pass drew (only where the budget truncates: `Gpu::render` counts
/// first and knows), the same importance and image bits. Then frames of DKB, VKB and uploaded
/// importance, each the same whatever came before it: the count, its totals and plan and the
/// allocation recorded once, the features and importance only where the budget truncates, the
/// plan exact where it holds every fragment; and the allocation's spread search gives the same
/// slots and images.
fn features_and_network_layouts_give_the_same_frame(
    g: &mut dhoit_runtime::gpu::Gpu,
    (s, cam): (&Scene, &Camera),
    (w, h): (u32, u32),
    mlp: &dhoit_runtime::mlp::Mlp,
) {
    let mut o = dhoit_runtime::gpu::FrameOptions::default().always_approximate();
    let gfl = gpu_fragments(g, s, cam, (w, h));
    // The GPU gathers statistics for the pixels that have a record (two fragments or more).
    let stats = common::recorded_stats(&gfl);
    assert!(stats.iter().any(|st| st.count == 1) && stats.iter().any(|st| st.count >= 2));
    let total = gfl.fragment_count() as u64;
    let (truncates, holds_all) = ((3 * w * h / 2) as u64, total);
    assert!(truncates < total);
    let counted_first = |f: &dhoit_runtime::gpu::GpuFrame| f.passes.contains(&"count");
    let mut images = std::collections::HashMap::new();
    for f in [truncates, holds_all] {
        let holds = f >= total;
        let mut first: Option<dhoit_runtime::gpu::GpuFrame> = None;
        for (preload, unrolled) in [(true, true), (false, true), (true, false), (false, false)] {
            o.tuning.features_preload = preload;
            o.tuning.unrolled_network = unrolled;
            let frame = g
                .render_with(&o, s, cam, (w, h), BG, Slots::Dkb(mlp, f.into()))
                .unwrap();
            let label = format!("F {f} of {total}: preload {preload}, unrolled {unrolled}");
            assert!(counted_first(&frame), "{label}: count pass");
            // The features pass and the network each ran the variant the options ask for.
            let features = if preload {
                "features: preload"
            } else {
                "features: no preload"
            };
            let network = if unrolled {
                "network: written out"
            } else {
                "network: loop over any shape"
            };
            assert!(
                frame.variants.contains(&features) && (holds || frame.variants.contains(&network)),
                "{label}: ran {:?}",
                frame.variants
            );
            let drawn = !holds;
            assert_eq!(frame.features_drawn, Some(drawn), "{label}");
            if drawn {
                assert_eq!(frame.stats.as_ref().unwrap(), &stats, "{label}: statistics");
            } else {
                assert!(frame.stats.is_none(), "{label}: statistics");
            }
            let imp = frame.importance.as_ref().unwrap();
            assert_eq!(
                imp.iter().any(|&i| i.abs() > 0.0),
                !holds,
                "{label}: importance"
            );
            if let Some(a) = &first {
                assert!(
                    float_bits(a.importance.as_ref().unwrap()) == float_bits(imp),
                    "{label}: importance differs"
                );
                assert!(
                    image_bits(&a.image) == image_bits(&frame.image),
                    "{label}: image differs"
                );
            } else {
                images.insert(f, image_bits(&frame.image));
                first = Some(frame);
            }
        }
    }
    o.tuning.features_preload = true;
    o.tuning.unrolled_network = true;
    // DKB's, VKB's and uploaded importance's frames: the references of the frames below.
    let dkb = |f: u64| Slots::Dkb(mlp, f.into());
    let mut rng = dhoit_runtime::rng::Rng::new(11);
    let uploaded: Vec<f32> = (0..w * h).map(|_| rng.f32()).collect();
    let upload = |f: u64| Slots::Importance(&uploaded, alloc::Target::RelativeK, f.into());
    let slots = |method: &str, f: u64| match method {
        "dkb" => dkb(f),
        "vkb" => vkb_at(f),
        _ => upload(f),
    };
    let methods = ["dkb", "vkb", "uploaded"];
    let mut reference = std::collections::HashMap::new();
    for f in [truncates, holds_all] {
        for (method, slots) in methods.map(|m| (m, slots(m, f))) {
            let frame = g.render_with(&o, s, cam, (w, h), BG, slots).unwrap();
            let bits = frame.importance.as_deref().map(float_bits);
            assert!(method != "dkb" || image_bits(&frame.image) == images[&f]);
            reference.insert((method, f), (image_bits(&frame.image), frame.slots, bits));
        }
    }
    // Frames counted first record the passes they run, whatever the frame before: the count,
    // its totals and plan, and the allocation (which gives k = n where every fragment fits);
    // the features and the importance only where the budget truncates. Each frame is its
    // reference, whatever came before it.
    for method in methods {
        for (i, f) in [holds_all, truncates, truncates, holds_all, holds_all]
            .into_iter()
            .enumerate()
        {
            let frame = g
                .render_with(&o, s, cam, (w, h), BG, slots(method, f))
                .unwrap();
            let label = format!("{method}: frame {i}, F {f} of {total}");
            let passes = |name: &str| frame.passes.iter().filter(|&&p| p == name).count();
            let holds = f >= total;
            assert!(counted_first(&frame), "{label}: count pass");
            if method == "dkb" {
                assert_eq!(frame.features_drawn, Some(!holds), "{label}");
            }
            // Uploaded importance has no importance pass.
            let computed = (method != "uploaded" && !holds) as usize;
            for (name, times) in [("totals", 1), ("importance", computed), ("allocation", 1)] {
                assert_eq!(passes(name), times, "{label}: {name}");
            }
            let plan = frame.plan.expect("an allocated frame's plan");
            assert_eq!(plan.exact, holds, "{label}: plan");
            let (image, keys, importance) = &reference[&(method, f)];
            let bits = frame.importance.as_deref().map(float_bits);
            assert!(image_bits(&frame.image) == *image, "{label}: image differs");
            assert!(frame.slots == *keys, "{label}: slots differ");
            assert!(bits == *importance, "{label}: importance differs");
            if holds && method != "uploaded" {
                // Where it was not computed: zeros (k = n needs none).
                assert!(bits.unwrap().iter().all(|&b| b == 0), "{label}: importance");
            }
        }
    }
    // The allocation's search adding into 32 copies of its totals (`Tuning::spread_search`):
    // the same slots and images where the budget truncates.
    o.tuning.spread_search = true;
    for method in methods {
        let frame = g
            .render_with(&o, s, cam, (w, h), BG, slots(method, truncates))
            .unwrap();
        let (image, keys, _) = &reference[&(method, truncates)];
        assert!(
            frame
                .variants
                .contains(&"allocation search: 32 copies of the totals"),
            "{method}: spread search ran {:?}",
            frame.variants
        );
        assert!(
            frame.slots == *keys,
            "{method}: spread search: slots differ"
        );
        assert!(
            image_bits(&frame.image) == *image,
            "{method}: spread search"
        );
    }
}

/// FKB's slots laid out layer-major (`Tuning::layer_major_fkb`) hold the same keys and tails,
/// and draw the same image bits, as pixel-major ones and the CPU twin, in any submission order.
#[test]
fn layer_major_slots_capture_what_pixel_major_ones_do() {
    let mut o = dhoit_runtime::gpu::FrameOptions::default().always_approximate();
    if gpu().is_none() {
        return;
    }
    let g = dhoit_runtime::gpu::Gpu::new().unwrap();
    let size = (80, 60);
    for (name, view) in [("particles", 1), ("hair", 0)] {
        let (s, cam) = frame(name, view, size);
        let gfl = gpu_fragments(&g, &s, &cam, size);
        for k in [1u32, 3] {
            let frames = [false, true].map(|layer_major| {
                o.tuning.layer_major_fkb = layer_major;
                g.render_with(&o, &s, &cam, size, BG, Slots::Uniform(k))
                    .unwrap()
            });
            let (twin_keys, twin_tails) = twin_capture(&gfl, &vec![k; gfl.pixel_count()]);
            for (f, layout) in frames
                .iter()
                .zip(["fkb slots: pixel-major", "fkb slots: layer-major"])
            {
                assert!(
                    f.variants.contains(&layout),
                    "{name} k = {k}: ran {:?}",
                    f.variants
                );
                let (keys, _, tails) = f.slots.clone().unwrap();
                assert!(
                    keys == twin_keys && tails == twin_tails,
                    "{name} k = {k}: capture"
                );
            }
            assert!(
                image_bits(&frames[0].image) == image_bits(&frames[1].image),
                "{name} k = {k}: image"
            );
            // Layer-major, as the last frame.
            let shuffled = g
                .render_with(&o, &s.shuffled(5), &cam, size, BG, Slots::Uniform(k))
                .unwrap();
            assert!(image_bits(&shuffled.image) == image_bits(&frames[1].image));
            o.tuning.layer_major_fkb = false;
        }
    }
}

/// A persistent renderer: frames take their buffers from the ones earlier frames left, so a
/// repeated frame creates none, and what an earlier frame left in them never shows: every image
/// is bit for bit the image of the same frame rendered before, whatever came between.
#[test]
fn frames_reuse_the_buffers_of_earlier_frames_and_draw_the_same_images() {
    if gpu().is_none() {
        return;
    }
    // A device of its own: the shared one's pool serves tests running in parallel.
    let g = dhoit_runtime::gpu::Gpu::new().unwrap();
    // Steady frames read back their image only.
    let o = dhoit_runtime::gpu::FrameOptions {
        diagnostics: false,
        ..Default::default()
    }
    .always_approximate();
    let (w, h) = (96, 72);
    let (a, cam_a) = frame("particles", 0, (w, h));
    let (b, cam_b) = frame("shells", 1, (w, h));
    let k: Vec<u32> = (0..w * h).map(|p| 1 + p % 4).collect();
    let mlp = dhoit_runtime::mlp::Mlp::random(7);
    let f = (2 * w * h) as u64;
    let vkb = dhoit_runtime::importance::VkbParams::default();
    let slots = [
        Slots::Exact,
        Slots::Uniform(2),
        Slots::PerPixel(&k),
        Slots::Mlab(4),
        Slots::Vkb(vkb, f.into()),
        Slots::Dkb(&mlp, f.into()),
    ];
    let bits = |g: &dhoit_runtime::gpu::Gpu, s: &Scene, cam: &Camera, slots: Slots| {
        image_bits(&g.render_with(&o, s, cam, (w, h), BG, slots).unwrap().image)
    };
    for (i, &sl) in slots.iter().enumerate() {
        // The first frame of a method may take another path than those after it (a k-buffer
        // frame expected to fit that truncates records its importance and search in a second
        // submission, and times more passes): the stream is steady from the second.
        let first = bits(&g, &a, &cam_a, sl);
        assert!(
            bits(&g, &a, &cam_a, sl) == first,
            "method {i}: the second frame differs"
        );
        let created = g.buffers_created();
        assert!(
            bits(&g, &a, &cam_a, sl) == first,
            "method {i}: the repeated frame differs"
        );
        assert_eq!(
            g.buffers_created(),
            created,
            "method {i}: the repeated frame created buffers"
        );
        // Another scene in the same buffers, then the first again.
        let other = bits(&g, &b, &cam_b, sl);
        assert!(other != first, "method {i}: two scenes, one image");
        assert!(
            bits(&g, &a, &cam_a, sl) == first,
            "method {i}: the last frame showed through"
        );
    }
    // With the readbacks the tests use on (the defaults), the same image again.
    let with = g.render_method(&a, &cam_a, (w, h), BG, slots[5]).unwrap();
    assert!(with.slots.is_some() && with.stats.is_some());
    let bits_with = image_bits(&with.image);
    assert!(bits(&g, &a, &cam_a, slots[5]) == bits_with);
}

#[test]
fn allocated_bytes_never_exceed_the_budget() {
    let Some(g) = gpu() else { return };
    let (s, _) = frame("foliage", 0, (8, 8));
    let mlp = dhoit_runtime::mlp::Mlp::random(2);
    let mut checked = [0usize; 3];
    for (w, h) in [(32u32, 24u32), (50, 37), (64, 48)] {
        let cam = Camera::orbit(&s, 0, scene::DEFAULT_VIEWS, (w, h));
        let px = (w * h) as u64;
        for b in ["30KB", "100KB", "200KB", "1MB", "1fpp", "2.5fpp"] {
            let budget = Budget::parse(b).unwrap();
            if let Ok((m, f)) = budget.resolve(&budget::FKB, px, 0)
                && f >= px
            {
                let frame = g
                    .render_method(&s, &cam, (w, h), BG, Slots::Uniform((f / px) as u32))
                    .unwrap();
                assert!(
                    frame.allocated_bytes <= m,
                    "{w}x{h} {b} fkb: {} > {m}",
                    frame.allocated_bytes
                );
                checked[0] += 1;
            }
            if let Ok((m, f)) = budget.resolve(&budget::VKB, px, 0) {
                let frame = g.render_method(&s, &cam, (w, h), BG, vkb_at(f)).unwrap();
                assert!(
                    frame.allocated_bytes <= m,
                    "{w}x{h} {b} vkb: {} > {m}",
                    frame.allocated_bytes
                );
                checked[1] += 1;
            }
            if let Ok((m, f)) = budget.resolve(&budget::DKB, px, 0) {
                let frame = g
                    .render_method(&s, &cam, (w, h), BG, Slots::Dkb(&mlp, f.into()))
                    .unwrap();
                assert!(
                    frame.allocated_bytes <= m,
                    "{w}x{h} {b} dkb: {} > {m}",
                    frame.allocated_bytes
                );
                checked[2] += 1;
            }
        }
    }
    // Budgets too small for a method are errors before anything is allocated; every method
    // was held to some budgets.
    assert!(
        checked.iter().all(|&c| c >= 6),
        "frames checked (fkb, vkb, dkb): {checked:?}"
    );
}

#[test]
fn mlab_matches_the_cpu_in_submission_order() {
    let Some(g) = gpu() else { return };
    for (name, m) in [("particles", 2u32), ("foliage", 4)] {
        let size = (64, 48);
        let (s, cam) = frame(name, 1, size);
        let gfl = gpu_fragments(g, &s, &cam, size);
        let f = g.render_method(&s, &cam, size, BG, Slots::Mlab(m)).unwrap();
        // The CPU twin takes each pixel's fragments in submission order.
        let twin: Vec<[f32; 3]> = (0..gfl.pixel_count())
            .map(|p| {
                let mut v = gfl.sorted(p);
                v.sort_by_key(|x| x.primitive);
                composite::mlab_pixel(&v, m as usize, BG)
            })
            .collect();
        let d = f
            .image
            .data
            .iter()
            .zip(&twin)
            .flat_map(|(a, b)| (0..3).map(move |i| (a[i] - b[i]).abs()))
            .fold(0.0f32, f32::max);
        assert!(
            d <= 1e-5,
            "{name} m={m}: GPU MLAB differs from the CPU twin by {d}"
        );
    }
    assert!(
        g.render_method(
            &frame("shells", 0, (8, 8)).0,
            &frame("shells", 0, (8, 8)).1,
            (8, 8),
            BG,
            Slots::Mlab(40)
        )
        .is_err()
    );
}

/// The allocation's search brackets its answer around the device's last answer of the same
/// kind (a scale, a level): the same allocation again takes two rounds (the bracket and one),
/// with a frame of the other kind between them too; another budget takes more, at most
/// SEARCH_ROUNDS, and every fragment fitting none; k is always its twin's.
#[test]
fn the_search_brackets_the_last_answer_of_its_kind() {
    use dhoit_runtime::wgsl::SEARCH_ROUNDS;
    if gpu().is_none() {
        return;
    }
    // A device of its own: the last answers are the device's, and the other tests' frames run
    // on the shared one meanwhile.
    let g = &dhoit_runtime::gpu::Gpu::new().unwrap();
    let size = (96, 72);
    let (s, cam) = frame("particles", 1, size);
    let counts = gpu_fragments(g, &s, &cam, size).counts();
    let total: u64 = counts.iter().map(|&n| n as u64).sum();
    let mut rng = dhoit_runtime::rng::Rng::new(8);
    let imp: Vec<f32> = (0..counts.len()).map(|_| rng.f32()).collect();
    let run = |target: alloc::Target, f: u64| {
        let a = g.allocate(&s, &cam, size, &imp, target, f.into()).unwrap();
        assert!(
            a.k == alloc::allocate(&imp, &counts, target, f),
            "{target:?} F {f}: k differs from the twin's"
        );
        a.search_rounds
    };
    let (scale, level) = (alloc::Target::RelativeK, alloc::Target::SlotRequest);
    let f = total / 3;
    let first = [run(scale, f), run(level, f)];
    assert!(
        first.iter().all(|r| (2..=SEARCH_ROUNDS).contains(r)),
        "{first:?}"
    );
    // Again, each kind after the other: its own last answer.
    let again = [run(scale, f), run(level, f), run(scale, f)];
    assert_eq!(again, [2, 2, 2], "the same allocations again");
    let other = [run(scale, total / 2), run(level, total / 5)];
    assert!(
        other.iter().all(|r| (2..=SEARCH_ROUNDS).contains(r)),
        "{other:?}"
    );
    assert_eq!(run(scale, total), 0, "every fragment fits: no search");
    eprintln!("search rounds: first {first:?}, again {again:?}, other budgets {other:?}");
}

#[test]
fn the_allocation_pass_matches_its_cpu_twin() {
    let Some(g) = gpu() else { return };
    let size = (64, 48);
    let (s, cam) = frame("hair", 2, size);
    let gfl = gpu_fragments(g, &s, &cam, size);
    let counts = gfl.counts();
    let pixels = counts.len();
    let covered = counts.iter().filter(|&&n| n > 0).count() as u64;
    let total = gfl.fragment_count() as u64;
    let mut rng = dhoit_runtime::rng::Rng::new(3);
    let random: Vec<f32> = (0..pixels).map(|_| rng.f32()).collect();
    let skewed: Vec<f32> = (0..pixels).map(|_| rng.f32().powi(6) * 3.0).collect();
    let mut one_hot = vec![0.0f32; pixels];
    one_hot[counts.iter().position(|&n| n > 3).unwrap()] = 1.0;
    let odd: Vec<f32> = (0..pixels)
        .map(|p| [f32::NAN, -1.0, 0.5, f32::INFINITY, 1e-9][p % 5])
        .collect();
    // DKB's own importance, from the features of the GPU's fragments, with the pair marks.
    let mlp = dhoit_runtime::mlp::Mlp::random(5);
    let (feats, pairs) = dhoit_runtime::importance::features_and_pairs(&gfl, 2 * pixels as u64);
    assert!(pairs.iter().any(|&p| p), "some pixels end in a pair");
    let dkb: Vec<f32> = mlp
        .importance(&feats, &counts)
        .iter()
        .zip(&pairs)
        .map(|(&i, &p)| alloc::mark_pair(i, p))
        .collect();
    let maps = [
        ("random", random),
        ("skewed", skewed),
        ("one-hot", one_hot),
        ("zero", vec![0.0; pixels]),
        ("odd", odd),
        ("dkb", dkb),
    ];
    let targets = [
        alloc::Target::RelativeK,
        alloc::Target::ShareOfFragments,
        alloc::Target::SlotRequest,
    ];
    for ((label, imp), target) in maps
        .iter()
        .flat_map(|m| targets.iter().map(move |t| (m, *t)))
    {
        for f in [
            covered / 2,
            covered,
            (1.5 * pixels as f64) as u64,
            3 * pixels as u64,
            total,
            total + 100,
        ] {
            let frame = g
                .render_method(&s, &cam, size, BG, Slots::Importance(imp, target, f.into()))
                .unwrap();
            let (keys, bases, tails) = frame.slots.unwrap();
            let k_gpu: Vec<u32> = bases.windows(2).map(|b| b[1] - b[0]).collect();
            // The k the pooled frame stores (shared::stored_k) of the twin's allocation.
            let k_cpu = dhoit_runtime::shared::stored(
                &alloc::allocate_pooled(imp, &counts, target, f),
                &counts,
            );
            assert!(
                k_gpu == k_cpu,
                "{label} {target:?}, F = {f}: GPU allocation differs from the CPU twin"
            );
            let (twin_keys, twin_tails) = twin_capture(&gfl, &k_cpu);
            assert!(
                keys == twin_keys && tails == twin_tails,
                "{label}, F = {f}: capture differs"
            );
            let twin = composite::composite(&gfl, composite::Method::Hybrid(&k_cpu), BG);
            assert!(
                frame.image.max_abs_diff(&twin) <= 1e-5,
                "{label}, F = {f}: image"
            );
        }
    }
}

#[test]
fn dkb_and_vkb_run_every_pass_on_the_gpu_like_their_twins() {
    use dhoit_runtime::importance::VkbParams;
    let Some(g) = gpu() else { return };
    // The committed network, which the test is about: a file that does not load fails it.
    let mlp = common::committed_weights();
    for (name, view) in [("particles", 0), ("plates", 3)] {
        let (w, h) = (72, 54);
        let (s, cam) = frame(name, view, (w, h));
        let gfl = gpu_fragments(g, &s, &cam, (w, h));
        let pixels = gfl.pixel_count();
        let total = gfl.fragment_count() as u64;
        let cfl = rasterize(&s, &cam, (w, h)).unwrap();
        let ccounts = cfl.counts();
        // 0.05 (DKB's pool then the size of its records and the network's list after them:
        // larger than its slots and tails would take), 0.5, 1 and 2 fragments a pixel, one
        // slot short of every fragment, and every one.
        let occ = budget::Occupancy::of(&gfl.counts());
        let layout = budget::DKB.for_network(&mlp);
        let budgets = [0.05, 0.5, 1.0, 2.0]
            .map(|fpp| (fpp * pixels as f64) as u64)
            .into_iter()
            .chain([total - 1, total]);
        for f in budgets {
            let fpp = format!("{:.2}", f as f64 / pixels as f64);
            // DKB: the features pass against pixel_stats on the GPU's own fragments, where the
            // device drew it: where the budget truncates (DKB counts first and reads its count
            // back), for each pixel with a record (two fragments or more).
            let d = g
                .render_method(&s, &cam, (w, h), BG, Slots::Dkb(&mlp, f.into()))
                .unwrap();
            let twin = importance::pixel_stats(&gfl);
            let holds = f >= total;
            assert!(d.passes.contains(&"count"), "{name}: count pass");
            let drawn = !holds;
            assert_eq!(d.features_drawn, Some(drawn), "{name} F {f} of {total}");
            // The batches its pool holds the records in: one, the pool holding every record
            // (at 0.05 that pool is larger than its slots and tails would take).
            let pool = layout.pool_bytes(pixels as u64, f, &occ);
            let (per_batch, batches) = layout.pool_state.unwrap().batch(pool, occ.deeper);
            assert_eq!(
                d.record_batches,
                drawn.then_some(batches),
                "{name} {fpp}fpp"
            );
            assert_eq!(batches, 1, "{name} {fpp}fpp");
            if fpp == "0.05" {
                let slots_and_tails = 8 * occ.pool_words_at(f);
                assert!(
                    36 * occ.deeper > slots_and_tails && 36 * per_batch <= pool,
                    "{name}: {per_batch} of {} records in {pool} bytes",
                    occ.deeper
                );
            }
            // Gathered with the count (its marks made with the count first, as a frame after
            // one of the same count has them), the features pass never drawn.
            if drawn {
                assert!(
                    d.variants.contains(&"dkb statistics: with the count")
                        && !d.passes.contains(&"features"),
                    "{name} {fpp}fpp: {:?}",
                    d.passes
                );
            }
            let stats = if !drawn {
                assert!(d.stats.is_none(), "{name}: statistics of an undrawn pass");
                twin
            } else {
                let stats = d.stats.clone().unwrap();
                for (p, (a, b)) in stats.iter().zip(&twin).enumerate() {
                    // Integer statistics: identical, whatever order the fragments came in; none
                    // gathered for a pixel of at most two fragments (its k is forced), nor the
                    // farthest keys (every pooled pixel is a pair).
                    if b.count > dhoit_runtime::shared::TAIL_WORDS {
                        let b = importance::PixelStats {
                            farthest: [0; 2],
                            ..*b
                        };
                        assert_eq!(a, &b, "{name} pixel {p}");
                    } else {
                        assert_eq!(a.count, b.count, "{name} pixel {p}");
                    }
                }
                stats
            };
            // Importance: the network on the GPU's statistics, within 1e-5.
            let (feats, counts) = network_inputs(&stats, f);
            let imp_twin: Vec<f32> = mlp.dkb_importance_pooled(&feats, &counts, f);
            let imp = d.importance.clone().unwrap();
            if holds {
                // k = n whatever the importance: 0 everywhere, unmarked, as the twin's.
                assert!(imp.iter().chain(&imp_twin).all(|i| i.to_bits() == 0));
            }
            // The pair marks (sign bits) exactly, the values within 1e-5.
            assert!(
                imp.iter()
                    .zip(&imp_twin)
                    .all(|(a, b)| a.is_sign_negative() == b.is_sign_negative())
            );
            let diff = max_abs_diff(&imp, &imp_twin);
            assert!(
                diff <= 1e-5,
                "{name} {fpp}fpp: DKB importance differs by {diff}"
            );
            check_allocation_and_capture(
                &gfl,
                &d,
                &imp,
                f,
                mlp.target,
                &format!("{name} dkb {fpp}fpp"),
            );
            let k_of = |f: &dhoit_runtime::gpu::GpuFrame| -> Vec<u32> {
                let bases = &f.slots.as_ref().unwrap().1;
                bases.windows(2).map(|b| b[1] - b[0]).collect()
            };
            let expect =
                common::kbuffer_bytes(&budget::DKB.for_network(&mlp), &k_of(&d), &gfl.counts(), f);
            assert_eq!(d.allocated_bytes, expect, "{name} dkb bytes");
            // VKB.
            let params = VkbParams::default();
            let v = g
                .render_method(&s, &cam, (w, h), BG, Slots::Vkb(params, f.into()))
                .unwrap();
            let (vc, facing) = v.vkb_nearest.clone().unwrap();
            assert_eq!(vc, gfl.counts(), "{name} vkb counts");
            // The count pass keeps the nearest fragment's 32-bit key: its facing, of the
            // fragment the twin picks from the CPU rasterizer's fragments (the GPU's own carry
            // no facing), on every pixel the two rasterizers cover alike.
            let alike: Vec<usize> = (0..pixels)
                .filter(|&p| vc[p] > 0 && vc[p] == ccounts[p])
                .collect();
            assert!(
                alike.len() * 10 >= 9 * vc.iter().filter(|&&n| n > 0).count(),
                "{name}: the rasterizers cover {} pixels alike",
                alike.len()
            );
            for &p in &alike {
                let twin = importance::nearest_facing(&cfl, p);
                assert_eq!(facing[p], twin, "{name}: pixel {p}'s nearest facing");
            }
            let mut imp_twin = importance::vkb_importance_from(&vc, &facing, (w, h), &params);
            let imp = v.importance.clone().unwrap();
            // A frame expected to fit computes no importance (k = n needs none): only where the
            // budget holds every fragment, and then the buffer stays zero.
            if !v.passes.contains(&"importance") {
                assert!(
                    holds,
                    "{name} {fpp}fpp: VKB importance skipped, budget truncates"
                );
                imp_twin = vec![0.0; imp.len()];
            }
            let diff = max_abs_diff(&imp, &imp_twin);
            assert!(
                diff <= 1e-5,
                "{name} {fpp}fpp: VKB importance differs by {diff}"
            );
            check_allocation_and_capture(
                &gfl,
                &v,
                &imp,
                f,
                alloc::Target::RelativeK,
                &format!("{name} vkb {fpp}fpp"),
            );
            let expect = common::kbuffer_bytes(&budget::VKB, &k_of(&v), &gfl.counts(), f);
            assert_eq!(v.allocated_bytes, expect, "{name} vkb bytes");
        }
    }
}

/// What DKB's network reads from a frame's statistics at F = `f`: each pixel's features (zeros
/// where uncovered), its count, and whether its two farthest fragments share one colour.
fn network_inputs(stats: &[importance::PixelStats], f: u64) -> (Vec<[f32; 12]>, Vec<u32>) {
    let t = importance::totals(stats);
    let feats = stats
        .iter()
        .map(|st| {
            if st.count > 0 {
                importance::pixel_features(st, &t, f)
            } else {
                [0.0; 12]
            }
        })
        .collect();
    let counts = stats.iter().map(|st| st.count).collect();
    (feats, counts)
}

/// DKB's importance pass with the network deployed at f16-math (binary16 hidden layers,
/// `Precision::F16Math`): the importance within `mlp::F16_MATH_GPU_BOUND` of the twin's on the
/// GPU's own statistics, the pair marks exact, and the allocation, capture and image its twins'
/// from that importance; against the f32 network's frame the importance moves by at most
/// `mlp::F16_MATH_BOUND`.
#[test]
fn dkb_frames_run_the_f16_math_network_like_its_twin() {
    use dhoit_runtime::mlp::{self, Mlp, Precision};
    let Some(g) = gpu() else { return };
    if !common::has(g, wgpu::Features::SHADER_F16, "DKB's f16-math network") {
        return;
    }
    let f32_net = Mlp::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../data/weights.safetensors"
    )))
    .unwrap();
    let half = f32_net.at_precision(Precision::F16Math).unwrap();
    for (name, view) in [("particles", 0), ("shells", 2)] {
        let size = (72, 54);
        let (s, cam) = frame(name, view, size);
        let gfl = gpu_fragments(g, &s, &cam, size);
        let f = gfl.pixel_count() as u64;
        assert!(
            f < gfl.fragment_count() as u64,
            "{name}: the budget truncates"
        );
        let d = g
            .render_method(&s, &cam, size, BG, Slots::Dkb(&half, f.into()))
            .unwrap();
        let (feats, counts) = network_inputs(&importance::pixel_stats(&gfl), f);
        let twin = half.dkb_importance_pooled(&feats, &counts, f);
        let imp = d.importance.clone().unwrap();
        assert!(imp.iter().any(|i| i.abs() > 0.0), "{name}: no importance");
        assert!(
            imp.iter()
                .zip(&twin)
                .all(|(a, b)| a.is_sign_negative() == b.is_sign_negative())
        );
        let diff = max_abs_diff(&imp, &twin);
        let full = f32_net.dkb_importance_pooled(&feats, &counts, f);
        let moved = max_abs_diff(&imp, &full);
        eprintln!("{name}: f16-math |GPU - twin| {diff:e}, |GPU - f32 network| {moved:e}");
        assert!(
            diff <= mlp::F16_MATH_GPU_BOUND,
            "{name}: f16-math importance differs from its twin by {diff}"
        );
        assert!(
            moved <= mlp::F16_MATH_BOUND,
            "{name}: moved {moved} from f32"
        );
        check_allocation_and_capture(&gfl, &d, &imp, f, half.target, &format!("{name} f16-math"));
    }
}

/// k from the GPU's importance equals the CPU allocation of it; slots, tail and image equal the
/// CPU capture and resolve.
fn check_allocation_and_capture(
    gfl: &FragmentLists,
    f: &dhoit_runtime::gpu::GpuFrame,
    imp: &[f32],
    budget: u64,
    target: alloc::Target,
    label: &str,
) {
    let (keys, bases, tails) = f.slots.clone().unwrap();
    let k: Vec<u32> = bases.windows(2).map(|b| b[1] - b[0]).collect();
    // The k the pooled frame stores: the allocation's, or all of a pixel's fragments where
    // its tail would hold no more (shared::stored_k).
    let counts = gfl.counts();
    let allocated = alloc::allocate_pooled(imp, &counts, target, budget);
    assert!(
        k == dhoit_runtime::shared::stored(&allocated, &counts),
        "{label}: allocation differs"
    );
    let (twin_keys, twin_tails) = twin_capture(gfl, &k);
    assert!(
        keys == twin_keys && tails == twin_tails,
        "{label}: capture differs"
    );
    let twin = composite::composite(gfl, composite::Method::Hybrid(&k), BG);
    let d = f.image.max_abs_diff(&twin);
    assert!(d <= 1e-5, "{label}: image differs by {d}");
}

#[test]
fn the_prefix_sum_is_exact_over_millions_of_pixels() {
    let Some(g) = gpu() else { return };
    // 2100x2100 = 4.41 M pixels: past what one workgroup could loop over on lavapipe, and
    // more blocks (2,154 of 2,048 pixels) than the block totals' scan takes at once, so it
    // carries between rounds.
    let (w, h) = (2100u32, 2100u32);
    let (s, cam) = frame("shells", 0, (64, 64));
    let k: Vec<u32> = (0..w * h)
        .map(|p| (p % 5 == 0) as u32 + (p % 7 == 0) as u32)
        .collect();
    let f = g
        .render_method(&s, &cam, (w, h), BG, Slots::PerPixel(&k))
        .unwrap();
    let (_, bases, _) = f.slots.unwrap();
    let mut acc = 0u32;
    for (p, &kp) in k.iter().enumerate() {
        assert_eq!(bases[p], acc, "offset of pixel {p}");
        acc += kp;
    }
    assert_eq!(bases[k.len()], acc);
}

#[test]
fn a_large_allocation_matches_its_twin() {
    // 1024x768: hundreds of workgroups add each candidate's total; it must still be exact.
    let Some(g) = gpu() else { return };
    let (w, h) = (1024u32, 768u32);
    let (s, cam) = frame("particles", 0, (w, h));
    let gfl = gpu_fragments(g, &s, &cam, (w, h));
    for fpp in [0.5, 1.0] {
        let f = (fpp * (w * h) as f64) as u64;
        let v = g.render_method(&s, &cam, (w, h), BG, vkb_at(f)).unwrap();
        let imp = v.importance.clone().unwrap();
        let (_, bases, _) = v.slots.unwrap();
        let k: Vec<u32> = bases.windows(2).map(|b| b[1] - b[0]).collect();
        let counts = gfl.counts();
        let twin = alloc::allocate_pooled(&imp, &counts, alloc::Target::RelativeK, f);
        assert!(
            k == dhoit_runtime::shared::stored(&twin, &counts),
            "{fpp}fpp: allocation differs"
        );
    }
}

/// The capture's two modes (capture.wgsl) with the tails pooled: pixels that hold all their
/// fragments (k = n, or k within a tail's words of n: `shared::stored_k`) append them and are
/// sorted at resolve, the others insert through their slots (with Loop64's early tests) and
/// push the rest into their two-word tails, and both end in the slots, tail and image of the
/// CPU twin, bit for bit in the image whatever the submission order. A layered scene gives
/// every case: pixels appended, pixels truncated, and pixels deeper than APPEND_MAX that insert
/// although k >= n. Where the budget
/// holds every fragment, the pipeline built for such frames (`Tuning::fits_pipelines`) gives the
/// same slots, tails and image bits as the two-mode one.
#[test]
fn the_two_mode_capture_appends_what_fits_and_inserts_the_rest_like_its_twin() {
    let mut o = dhoit_runtime::gpu::FrameOptions::default().always_approximate();
    if gpu().is_none() {
        return;
    }
    // A device of its own: which passes a frame records follows the device's last frame.
    let g = dhoit_runtime::gpu::Gpu::new().unwrap();
    let mut s = Scene::default();
    let v = glam::Vec3::new;
    // 70 layers over the left half, 3 over the right, 1 over a strip at the top: deep pixels
    // beyond APPEND_MAX, shallow ones, single ones.
    let deep = composite::APPEND_MAX as usize + 6;
    for i in 0..deep + 4 {
        let z = 0.05 + 0.9 * ((i * 37) % (deep + 4)) as f32 / (deep + 4) as f32;
        let (x0, x1) = if i < deep { (-1.0, 0.0) } else { (0.0, 1.0) };
        let y1 = if i == deep + 3 { -0.6 } else { 1.0 };
        let c = [
            (i % 5) as f32 / 4.0,
            (i % 3) as f32 / 2.0,
            0.6,
            0.25 + (i % 4) as f32 * 0.15,
        ];
        s.push_triangle([v(x0, -1.0, z), v(x1, -1.0, z), v(x0, y1, z)], [c; 3]);
        s.push_triangle([v(x1, -1.0, z), v(x1, y1, z), v(x0, y1, z)], [c; 3]);
    }
    let cam = common::identity();
    let size = (48, 32);
    let gfl = gpu_fragments(&g, &s, &cam, size);
    let counts = gfl.counts();
    let total = gfl.fragment_count() as u64;
    let mlp = dhoit_runtime::mlp::Mlp::random(6);
    let wide = common::is_wide(&g, "which capture a frame that fits ran (its own pipeline)");
    for f in [total / 4, total / 2, total - 40, total, total + 100] {
        for (label, slots) in [("dkb", Slots::Dkb(&mlp, f.into())), ("vkb", vkb_at(f))] {
            let frame = g.render_with(&o, &s, &cam, size, BG, slots).unwrap();
            if f >= total {
                o.tuning.fits_pipelines = false;
                let two_mode = g.render_with(&o, &s, &cam, size, BG, slots).unwrap();
                o.tuning.fits_pipelines = true;
                assert!(
                    !wide
                        || frame
                            .variants
                            .contains(&"capture: built for frames that fit")
                            && two_mode.variants.contains(&"capture: general"),
                    "{label} F = {f}: ran {:?} / {:?}",
                    frame.variants,
                    two_mode.variants
                );
                assert!(
                    two_mode.slots == frame.slots
                        && image_bits(&two_mode.image) == image_bits(&frame.image),
                    "{label} F = {f}: the capture for frames that fit differs from the two-mode one"
                );
            }
            let imp = frame.importance.clone().unwrap();
            let target = if label == "dkb" {
                mlp.target
            } else {
                alloc::Target::RelativeK
            };
            let label = format!("{label} F = {f}");
            check_allocation_and_capture(&gfl, &frame, &imp, f, target, &label);
            let (_, bases, _) = frame.slots.clone().unwrap();
            let k: Vec<u32> = bases.windows(2).map(|b| b[1] - b[0]).collect();
            let modes = |pred: &dyn Fn(u32, u32) -> bool| {
                k.iter()
                    .zip(&counts)
                    .filter(|&(&k, &n)| n > 0 && pred(k, n))
                    .count()
            };
            // Which mode each pixel took on the GPU, from the counts the capture left (before
            // the resolve put them back): 0 where it appended (its cursor took the count down),
            // n where it inserted. A pixel appends where it holds all its fragments and no more
            // than APPEND_MAX, in the capture built for frames that fit (k = n everywhere) too.
            let captured = frame.capture_counts.clone().unwrap();
            let fits = frame
                .variants
                .contains(&"capture: built for frames that fit");
            assert_eq!(fits, f >= total && wide, "{label}: {:?}", frame.variants);
            let appends = composite::appends;
            for (p, (&k, &n)) in k.iter().zip(&counts).enumerate() {
                let want = if appends(k, n) { 0 } else { n };
                assert_eq!(
                    captured[p], want,
                    "{label}: pixel {p} (k {k}, n {n}) took the other mode ({:?})",
                    frame.variants
                );
            }
            let appended = modes(&|k, n| appends(k, n));
            // Held whole where the allocation left out a fragment or two (stored_k).
            let raw = alloc::allocate_pooled(&imp, &counts, target, f);
            let upgraded = raw
                .iter()
                .zip(&k)
                .zip(&counts)
                .filter(|&((&r, &k), &n)| r < n && k == n)
                .count();
            let inserted = modes(&|k, n| !appends(k, n));
            let truncated = modes(&|k, n| k < n);
            let deep_whole = modes(&|k, n| k >= n && !appends(k, n));
            eprintln!(
                "{label}: {appended} pixels appended ({upgraded}), {inserted} inserted \
                 ({truncated} truncated, {deep_whole} held whole)"
            );
            assert!(appended > 0 && inserted > 0, "{label}: one mode only");
            if f <= total / 2 {
                assert!(truncated > 0, "{label}: no pixel truncated");
            }
            if f < total {
                assert!(upgraded > 0, "{label}: no truncation held whole");
            }
            if f >= total {
                assert!(deep_whole > 0, "{label}: no deep pixel held whole");
            }
            // Any submission order: the same image bits.
            for seed in 0..3 {
                let shuffled = g
                    .render_method(&s.shuffled(seed), &cam, size, BG, slots)
                    .unwrap();
                assert!(
                    image_bits(&shuffled.image) == image_bits(&frame.image),
                    "{label}: shuffle {seed}"
                );
            }
        }
    }
}

#[test]
fn a_pixel_too_deep_for_the_devices_loops_is_refused_not_wrong() {
    // A pixel with 600 fragments needs ~180k insertion-sort steps: beyond lavapipe's loops.
    let Some(g) = gpu() else { return };
    let mut s = Scene::default();
    for i in 0..600 {
        let z = 0.1 + 0.8 * ((i * 7919) % 600) as f32 / 600.0;
        s.push_triangle(
            [
                glam::Vec3::new(-1.0, -1.0, z),
                glam::Vec3::new(3.0, -1.0, z),
                glam::Vec3::new(-1.0, 3.0, z),
            ],
            [[0.5, 0.5, 0.5, 0.2]; 3],
        );
    }
    let cam = common::identity();
    let r = g.render_method(&s, &cam, (4, 4), BG, dhoit_runtime::gpu::Slots::Exact);
    if g.bounded_loops() {
        let Err(e) = r else {
            panic!("lavapipe cannot sort 600 fragments a pixel, yet it returned a frame")
        };
        assert!(e.to_string().contains("loops early"), "{e}");
    } else {
        let f = r.unwrap();
        let twin =
            composite::composite(f.fragments.as_ref().unwrap(), composite::Method::Exact, BG);
        assert!(f.image.max_abs_diff(&twin) <= 1e-5);
    }
}

/// `n` full-frame triangles, each covering every pixel of a small frame: two faint blue ones
/// nearest, opaque yellow ones behind in shuffled depth order (at raster::MAX_FRAGMENTS_PER_PIXEL
/// their tail's sum of r a reaches 2^31, half what its word holds, and their sums of r and g
/// half the features pass's 24-bit fields; one more and each pixel's 16-bit count stops), and
/// the identity camera.
fn deep_pixels(n: usize) -> (Scene, Camera) {
    let mut s = Scene::default();
    for i in 0..n {
        let (z, c) = if i < 2 {
            (0.01 * (i + 1) as f32, [0.0, 0.0, 1.0, 0.1])
        } else {
            (
                0.1 + 0.8 * ((i * 7919) % n) as f32 / n as f32,
                [1.0, 1.0, 0.0, 1.0],
            )
        };
        s.push_triangle(
            [
                glam::Vec3::new(-1.0, -1.0, z),
                glam::Vec3::new(3.0, -1.0, z),
                glam::Vec3::new(-1.0, 3.0, z),
            ],
            [c; 3],
        );
    }
    let cam = common::identity();
    (s, cam)
}

/// What the deep-pixel tests share: always-approximate frames on a device of their own (which
/// passes a frame records follows the device's last frame), the rasterizers' limit of fragments
/// a pixel and the committed weights; None where the GPU tests are skipped explicitly.
fn deep_pixel_setup() -> Option<(
    dhoit_runtime::gpu::FrameOptions,
    dhoit_runtime::gpu::Gpu,
    usize,
    dhoit_runtime::mlp::Mlp,
)> {
    gpu()?;
    Some((
        dhoit_runtime::gpu::FrameOptions::default().always_approximate(),
        dhoit_runtime::gpu::Gpu::new().unwrap(),
        dhoit_runtime::raster::MAX_FRAGMENTS_PER_PIXEL as usize,
        common::committed_weights(),
    ))
}

/// At raster::MAX_FRAGMENTS_PER_PIXEL fragments a pixel, the k-buffers' images are their twins'
/// and DKB's features pass gathers the twin's counts and colour sums (for each pixel with a
/// record: two fragments or more), its fields full, and the importance pass reads them as the
/// twin does; one fragment more, every method refuses the frame as the CPU rasterizer does.
#[test]
fn a_pixel_deeper_than_the_tails_sums_hold_is_refused_by_every_method() {
    let Some((o, g, max, mlp)) = deep_pixel_setup() else {
        return;
    };
    let size = (2, 2);
    // At the limit both rasterizers take the frame and the tails' sums are exact.
    let (s, cam) = deep_pixels(max);
    let fl = rasterize(&s, &cam, size).unwrap();
    assert_eq!(fl.count(0) as usize, max);
    let twin_stats = importance::pixel_stats(&fl);
    let (f, vkb) = (8u64, Slots::Vkb(Default::default(), 8u64.into()));
    {
        let dkb = Slots::Dkb(&mlp, f.into());
        for (name, slots) in [("FKB", Slots::Uniform(2)), ("VKB", vkb), ("DKB", dkb)] {
            let frame = g.render_with(&o, &s, &cam, size, BG, slots).unwrap();
            let bases = &frame.slots.as_ref().unwrap().1;
            let k: Vec<u32> = bases.windows(2).map(|b| b[1] - b[0]).collect();
            let twin = composite::composite(&fl, composite::Method::Hybrid(&k), BG);
            let d = frame.image.max_abs_diff(&twin);
            assert!(
                d <= 1e-5,
                "{name}: {max} fragments a pixel: {d} from the twin"
            );
            if name != "DKB" {
                continue;
            }
            // Counts and colour sums exactly (the keys' depths are the GPU's own).
            let stats = frame.stats.clone().unwrap();
            for (a, b) in stats.iter().zip(&twin_stats) {
                let sums = |s: &importance::PixelStats| (s.count, s.color_sum, s.color_sq_sum);
                if b.count > dhoit_runtime::shared::TAIL_WORDS {
                    assert_eq!(sums(a), sums(b), "statistics");
                } else {
                    assert_eq!(
                        a,
                        &importance::PixelStats {
                            count: b.count,
                            ..Default::default()
                        }
                    );
                }
            }
            assert_eq!(stats[0].color_sum[1], 255 * (max as u32 - 2));
            let (feats, counts) = network_inputs(&stats, f);
            let imp_twin = mlp.dkb_importance_pooled(&feats, &counts, f);
            let d = max_abs_diff(frame.importance.as_ref().unwrap(), &imp_twin);
            assert!(d <= 1e-5, "importance {d} from the twin");
        }
    }
    // One more: the CPU refuses it, and so does every GPU method (not an image whose tail
    // is wrong, or a sort of that length), naming the pixel and its count.
    let (s, cam) = deep_pixels(max + 1);
    let cpu = rasterize(&s, &cam, size).unwrap_err().to_string();
    assert!(cpu.contains(&format!("has {} fragments", max + 1)), "{cpu}");
    let k = vec![3u32; 4];
    let methods: [(&str, Slots); 6] = [
        ("A-buffer", Slots::Exact),
        ("MLAB", Slots::Mlab(4)),
        ("FKB", Slots::Uniform(2)),
        ("uploaded k", Slots::PerPixel(&k)),
        ("VKB", vkb),
        ("DKB", Slots::Dkb(&mlp, f.into())),
    ];
    for (name, slots) in methods {
        let Err(e) = g.render_with(&o, &s, &cam, size, BG, slots) else {
            panic!("{name}: a pixel of {} fragments gave a frame", max + 1)
        };
        let e = e.to_string();
        assert!(
            e.contains(&format!(
                "pixel (1, 1) has more than {max} fragments; at most {max}"
            )),
            "{name}: {e}"
        );
    }
}

/// Two counts share a 32-bit word (counts.wgsl): a pixel of 2^16 + 1 fragments beside a pixel of
/// one, in one word. Its count stops one past raster::MAX_FRAGMENTS_PER_PIXEL, so it never
/// wraps to 1 and carries into its neighbour's half (which would read 2 and leave the frame
/// unrefused): every method that counts refuses the frame and names the deep pixel.
#[test]
fn a_pixel_of_two_to_the_sixteen_fragments_leaves_its_neighbours_count_alone() {
    let Some((o, g, max, mlp)) = deep_pixel_setup() else {
        return;
    };
    // A 2x1 frame: pixel 0 (centre x = -0.5) under every triangle but one, pixel 1 (x = 0.5)
    // under that one only. Both are in count word 0.
    let deep = (1usize << 16) + 1;
    let mut s = Scene::default();
    for i in 0..deep {
        let z = 0.1 + 0.8 * i as f32 / deep as f32;
        s.push_triangle(
            [
                glam::Vec3::new(-1.0, -1.0, z),
                glam::Vec3::new(-0.1, -1.0, z),
                glam::Vec3::new(-1.0, 3.0, z),
            ],
            [[1.0, 0.5, 0.0, 0.3]; 3],
        );
    }
    s.push_triangle(
        [
            glam::Vec3::new(0.1, -1.0, 0.5),
            glam::Vec3::new(1.0, -1.0, 0.5),
            glam::Vec3::new(1.0, 3.0, 0.5),
        ],
        [[0.0, 0.5, 1.0, 0.3]; 3],
    );
    let cam = common::identity();
    let f = 8u64;
    let methods: [(&str, Slots); 3] = [
        ("A-buffer", Slots::Exact),
        ("VKB", vkb_at(f)),
        ("DKB", Slots::Dkb(&mlp, f.into())),
    ];
    for (name, slots) in methods {
        let Err(e) = g.render_with(&o, &s, &cam, (2, 1), BG, slots) else {
            panic!("{name}: a pixel of {deep} fragments gave a frame")
        };
        let e = e.to_string();
        assert!(
            e.contains(&format!("pixel (0, 0) has more than {max} fragments")),
            "{name}: {e}"
        );
    }
}

#[test]
fn relative_budgets_allocate_a_share_of_the_frames_own_fragments() {
    use dhoit_runtime::budget::FragmentBudget;
    use dhoit_runtime::frame::{Method, Options, Renderer};
    let Some(g) = gpu() else { return };
    let mlp = dhoit_runtime::mlp::Mlp::random(4);
    let size = (80, 60);
    for name in ["spheres", "cad"] {
        let (s, cam) = frame(name, 1, size);
        let gfl = gpu_fragments(g, &s, &cam, size);
        let total = gfl.fragment_count() as u64;
        let px = gfl.pixel_count() as u64;
        let sum_n: u64 = gfl.counts().iter().map(|&n| n as u64).sum();
        for pct in ["10%", "37.5%", "90%", "100%"] {
            let Budget::Share(ppm) = Budget::parse(pct).unwrap() else {
                unreachable!()
            };
            let f = budget::share_of(total, ppm);
            let want = f.min(sum_n);
            // The GPU counts the fragments and takes its share itself.
            for (label, slots, layout, target) in [
                (
                    "vkb",
                    Slots::Vkb(Default::default(), FragmentBudget::Share(ppm).into()),
                    budget::VKB,
                    alloc::Target::RelativeK,
                ),
                (
                    "dkb",
                    Slots::Dkb(&mlp, FragmentBudget::Share(ppm).into()),
                    budget::DKB,
                    mlp.target,
                ),
            ] {
                let frame = g.render_method(&s, &cam, size, BG, slots).unwrap();
                let (_, bases, _) = frame.slots.clone().unwrap();
                // The allocation of the frame's importance hands out exactly min(F, sum n)
                // slots, and the frame stores it (shared::stored_k).
                let counts = gfl.counts();
                let raw =
                    alloc::allocate_pooled(frame.importance.as_ref().unwrap(), &counts, target, f);
                assert_eq!(
                    raw.iter().map(|&k| k as u64).sum::<u64>(),
                    want,
                    "{name} {pct} {label}: sum k"
                );
                let stored = dhoit_runtime::shared::stored(&raw, &counts);
                assert_eq!(
                    bases[px as usize] as u64,
                    stored.iter().map(|&k| k as u64).sum::<u64>(),
                    "{name} {pct} {label}: the k stored"
                );
                let k: Vec<u32> = bases.windows(2).map(|b| b[1] - b[0]).collect();
                assert_eq!(
                    frame.allocated_bytes,
                    common::kbuffer_bytes(&layout, &k, &gfl.counts(), f),
                    "{name} {pct} {label}: memory for exactly sum k slots and their tails"
                );
                let imp = frame.importance.clone().unwrap();
                check_allocation_and_capture(
                    &gfl,
                    &frame,
                    &imp,
                    f,
                    target,
                    &format!("{name} {pct} {label}"),
                );
            }
            // The CPU: the same F from the same count, and memory for exactly that.
            let fl = dhoit_runtime::raster::rasterize(&s, &cam, size).unwrap();
            assert_eq!(
                fl.fragment_count() as u64,
                total,
                "{name}: CPU and GPU count alike"
            );
            let opts = Options {
                weights: Some(&mlp),
                ..Options::new(Budget::Share(ppm), BG).always_approximate()
            };
            for m in [Method::Vkb, Method::Dkb, Method::Optimal] {
                let r = Renderer::new(&fl, opts);
                let a = r.allocate(m).unwrap();
                assert_eq!(
                    a.k.iter().map(|&k| k as u64).sum::<u64>(),
                    want,
                    "{name} {pct} {m:?}"
                );
                // VKB and DKB pool their tails: the k they store (shared::stored_k).
                let stored = match m {
                    Method::Optimal => a.k.clone(),
                    _ => dhoit_runtime::shared::stored(&a.k, &fl.counts()),
                };
                let fr = r.composite(a);
                assert_eq!(fr.budget_fragments, f, "{name} {pct} {m:?}: F");
                assert!(fr.exact || fr.k == stored, "{name} {pct} {m:?}: k stored");
                // Where the share holds every fragment, the A-buffer's memory (it renders it).
                let bytes = if f >= total {
                    budget::ABUFFER.allocated_bytes(px, want)
                } else {
                    common::kbuffer_bytes(&opts.layout(m), &fr.k, &fl.counts(), f)
                };
                assert_eq!(fr.allocated_bytes, bytes, "{name} {pct} {m:?}: bytes");
            }
        }
    }
}

#[test]
fn gpu_faults_are_typed_errors_not_hangs_or_wrong_images() {
    use dhoit_runtime::{Error, GpuError};
    let Some(g) = gpu() else { return };
    // An adapter without a feature the passes need: the error names it and the requirement.
    match dhoit_runtime::gpu::Gpu::requiring(wgpu::Features::EXPERIMENTAL_RAY_QUERY) {
        Err(Error::Gpu(GpuError::MissingFeatures { lacking })) => {
            assert!(lacking.contains("RAY_QUERY"), "{lacking}");
        }
        Err(e) => panic!("expected missing features, got {e}"),
        Ok(_) => eprintln!(
            "this adapter has ray queries: the missing-feature case is not reachable here"
        ),
    }
    let e = Error::Gpu(GpuError::MissingFeatures {
        lacking: "x".into(),
    })
    .to_string();
    assert!(
        e.contains("Vulkan") && e.contains("DX12") && e.contains("Metal"),
        "{e}"
    );
    // A frame whose buffers exceed what the device binds: refused before allocating, with the
    // numbers.
    let (s, cam) = frame("shells", 0, (1024, 1024));
    match g.render_method(&s, &cam, (1024, 1024), BG, Slots::Uniform(20_000)) {
        Err(Error::Gpu(GpuError::BufferTooLarge { label, need, max })) => {
            assert_eq!(label, "oit.slots");
            assert_eq!(need, 1024 * 1024 * 20_000 * 8);
            assert!(need > max);
        }
        Err(e) => panic!("expected a buffer too large, got {e}"),
        Ok(_) => panic!("a 160 GiB slot buffer was accepted"),
    }
    // The device still works after refusing.
    let (s, cam) = frame("shells", 0, (16, 12));
    assert!(
        g.render_method(&s, &cam, (16, 12), BG, dhoit_runtime::gpu::Slots::Exact)
            .is_ok()
    );
}

/// A sparse scene for large frames: eight overlapping triangles in a small cluster (a few
/// thousand pixels at 8K) and two specks far away that widen the camera's framing; each
/// triangle `shift` further off the one before, `scale` times the size (shift 0: eight stacked
/// alike, every covered pixel of the cluster eight fragments deep).
fn sparse_scene_shifted(shift: f32, scale: f32) -> Scene {
    let mut s = Scene {
        name: "sparse".into(),
        ..Default::default()
    };
    let v = glam::Vec3::new;
    for i in 0..8 {
        let z = i as f32 * 0.01;
        let c = [0.1 + 0.1 * i as f32, 0.9 - 0.1 * i as f32, 0.5, 0.33];
        let d = shift * i as f32;
        s.push_triangle(
            [
                v(-0.2 + d, -0.2, z) * scale,
                v(0.2, -0.15 + d, z) * scale,
                v(0.0, 0.25 - d, z) * scale,
            ],
            [c; 3],
        );
    }
    for x in [-6.0, 6.0] {
        s.push_triangle(
            [v(x, 0.0, 0.0), v(x + 0.01, 0.0, 0.0), v(x, 0.01, 0.0)],
            [[1.0, 1.0, 1.0, 0.33]; 3],
        );
    }
    s
}

fn sparse_scene() -> Scene {
    sparse_scene_shifted(0.02, 1.0)
}

#[test]
fn frames_up_to_8k_render_and_allocate_like_their_twins() {
    let Some(g) = gpu() else { return };
    let s = sparse_scene();
    let mlp = common::committed_weights();
    // 2400x2300 needs 86,250 workgroups of 64: a 2-D grid. No buffer takes more than 16 bytes
    // a pixel (the image, DKB's farthest keys and colour sums, the tail's sums), so 4K fits
    // lavapipe's 128 MiB bindings and renders here. 8K needs larger bindings than lavapipe
    // offers: there the frame is refused before anything is allocated, with the numbers; on
    // a device with larger bindings it is checked like the others.
    let limit = g.device().limits().max_storage_buffer_binding_size;
    for (w, h) in [(2400u32, 2300u32), (3840, 2160), (7680, 4320)] {
        let cam = Camera::orbit(&s, 0, scene::DEFAULT_VIEWS, (w, h));
        let px = w as u64 * h as u64;
        if 16 * px > limit {
            match g.render_method(&s, &cam, (w, h), BG, Slots::Dkb(&mlp, 1000.into())) {
                Err(dhoit_runtime::Error::Gpu(dhoit_runtime::GpuError::BufferTooLarge {
                    label,
                    need,
                    max,
                })) => {
                    assert!(need > max && max == limit, "{label}: {need} > {max}");
                    eprintln!("{w}x{h}: {label} needs {need} bytes, the device binds {max}");
                }
                Err(e) => panic!("{w}x{h}: {e}"),
                Ok(_) => panic!("{w}x{h}: a buffer beyond the binding limit was accepted"),
            }
            continue;
        }
        let gfl = gpu_fragments(g, &s, &cam, (w, h));
        let total = gfl.fragment_count() as u64;
        assert!(total > 1000, "{w}x{h}: {total} fragments");
        let f = total / 3;
        // DKB: features, importance, allocation and prefix sums over every pixel, as the twin.
        let d = g
            .render_method(&s, &cam, (w, h), BG, Slots::Dkb(&mlp, f.into()))
            .unwrap();
        let stats = d.stats.clone().unwrap();
        assert_eq!(stats, common::recorded_stats(&gfl), "{w}x{h}: statistics");
        let imp = d.importance.clone().unwrap();
        check_allocation_and_capture(&gfl, &d, &imp, f, mlp.target, &format!("dkb {w}x{h}"));
        let sum: f64 = imp.iter().map(|&i| i.abs() as f64).sum();
        assert!(sum > 0.0, "{w}x{h}: importance sum");
        // The cluster stacked eight deep and eight times the size (about 5% of the frame), at
        // a budget whose pool holds a batch of its records at a time (they outweigh the
        // allocation's marks, a bit every frame pixel, and the slots and tails): every batch's
        // statistics and the allocation as the twin's, on hundreds of thousands of records.
        let stacked = sparse_scene_shifted(0.0, 8.0);
        let sfl = gpu_fragments(g, &stacked, &cam, (w, h));
        let few = sfl.fragment_count() as u64 / 40;
        let mut batched = dhoit_runtime::gpu::FrameOptions::default().always_approximate();
        batched.decision.record_batches = 3;
        let d = g
            .render_with(
                &batched,
                &stacked,
                &cam,
                (w, h),
                BG,
                Slots::Dkb(&mlp, few.into()),
            )
            .unwrap();
        assert!(
            d.record_batches.is_some_and(|b| b > 1),
            "{w}x{h}: {:?} batches",
            d.record_batches
        );
        let batched = common::recorded_stats(&sfl);
        assert_eq!(
            d.stats.clone().unwrap(),
            batched,
            "{w}x{h}: batched statistics"
        );
        let imp = d.importance.clone().unwrap();
        let label = format!("dkb {w}x{h} batched");
        check_allocation_and_capture(&sfl, &d, &imp, few, mlp.target, &label);
        // VKB and FKB too.
        let v = g.render_method(&s, &cam, (w, h), BG, vkb_at(f)).unwrap();
        check_allocation_and_capture(
            &gfl,
            &v,
            &v.importance.clone().unwrap(),
            f,
            alloc::Target::RelativeK,
            &format!("vkb {w}x{h}"),
        );
        let fk = g
            .render_method(&s, &cam, (w, h), BG, Slots::Uniform(1))
            .unwrap();
        let twin = composite::composite(
            &gfl,
            composite::Method::Hybrid(&vec![1; gfl.pixel_count()]),
            BG,
        );
        assert!(fk.image.max_abs_diff(&twin) <= 1e-5, "fkb {w}x{h}");
        // MLAB and the exact A-buffer's image.
        let ml = g
            .render_method(&s, &cam, (w, h), BG, Slots::Mlab(4))
            .unwrap();
        let twin = composite::composite(&gfl, composite::Method::Mlab(4), BG);
        assert!(ml.image.max_abs_diff(&twin) <= 1e-5, "mlab {w}x{h}");
        let a = g
            .render_method(&s, &cam, (w, h), BG, dhoit_runtime::gpu::Slots::Exact)
            .unwrap();
        let twin = composite::composite(&gfl, composite::Method::Exact, BG);
        assert!(a.image.max_abs_diff(&twin) <= 1e-5, "abuffer {w}x{h}");
        eprintln!(
            "{w}x{h}: DKB, VKB, FKB, MLAB and the A-buffer rendered like their twins ({total} fragments; the device binds {limit} bytes)"
        );
    }
}

/// The allocation alone at 7680x4320 (33 M pixels; every buffer 4 bytes a pixel, within
/// lavapipe's bindings where a whole k-buffer frame is not): per pixel the GPU's k equals the
/// twin's on the GPU's own counts, for every weight kind and both kinds of budget, the slot
/// bases are the exact prefix sums of k, and sum k = min(F, sum n).
#[test]
fn an_8k_allocation_matches_its_twin_exactly() {
    let Some(g) = gpu() else { return };
    let s = sparse_scene();
    let (w, h) = (7680u32, 4320u32);
    let cam = Camera::orbit(&s, 0, scene::DEFAULT_VIEWS, (w, h));
    let px = (w * h) as usize;
    // Importance of every kind of value the passes meet: spread, tied, tiny, pair-marked.
    let mut rng = dhoit_runtime::rng::Rng::new(8);
    let imp: Vec<f32> = (0..px)
        .map(|p| {
            let v = match p % 7 {
                0 => 0.5,
                1 => 1e-7,
                _ => rng.f32(),
            };
            alloc::mark_pair(v, p % 11 == 0)
        })
        .collect();
    let mut counts = None;
    for (target, budget) in [
        (
            alloc::Target::RelativeK,
            budget::FragmentBudget::Slots(12_000),
        ),
        (
            alloc::Target::ShareOfFragments,
            budget::FragmentBudget::Share(250_000),
        ),
        (
            alloc::Target::SlotRequest,
            budget::FragmentBudget::Slots(8_000),
        ),
    ] {
        let a = g.allocate(&s, &cam, (w, h), &imp, target, budget).unwrap();
        let n = counts.get_or_insert_with(|| a.counts.clone());
        assert_eq!(&a.counts, n, "the count is the same every time");
        let total: u64 = n.iter().map(|&c| c as u64).sum();
        assert!(total > 10_000, "{total} fragments");
        // Budgets below the frame's fragments, so the allocation has choices to make.
        let f = match budget {
            budget::FragmentBudget::Slots(f) => f,
            budget::FragmentBudget::Share(ppm) => total * ppm as u64 / 1_000_000,
        };
        let twin = alloc::allocate(&imp, n, target, f);
        if let Some(p) = (0..px).find(|&p| a.k[p] != twin[p]) {
            panic!("{target:?}: pixel {p}: GPU k {} twin {}", a.k[p], twin[p]);
        }
        let mut acc = 0u32;
        for p in 0..px {
            assert_eq!(a.bases[p], acc, "{target:?}: base of pixel {p}");
            acc += a.k[p];
        }
        assert_eq!(a.bases[px], acc);
        assert!(f < total, "{target:?}: F {f} holds every fragment");
        assert_eq!(acc as u64, f, "{target:?}: sum k");
        eprintln!("8K {target:?}: F {f}, {total} fragments, k identical to the twin's");
    }
}

#[test]
fn cpu_and_gpu_rasterizers_agree_on_depth_and_coverage() {
    // The CPU interpolates depth on the plane through the unsnapped window positions, as
    // lavapipe does; coverage is decided on 1/256-pixel snapped positions by both, which can
    // round a vertex differently. On lavapipe depth agrees within 5e-5 (a median of one ulp;
    // interpolating on the snapped positions instead differs by up to 9.2e-4; what remains is
    // the rounding of steep planes' gradients), the same fragments in all but a pixel or so
    // where an edge passes through a pixel centre.
    // Vulkan lets a device interpolate depth from its snapped vertices instead: an NVIDIA H200
    // (driver 580) does, and differs by up to 9.2e-4 on shells and 3.9e-3 on spheres (steep
    // planes at their silhouettes; medians 7.2e-6 and 5.0e-6), what the CPU gave when it
    // interpolated so. There the bounds are the snapping's: 1e-2 for the worst fragment,
    // 1e-3 for all but the worst 1%, and the median within a few ulps.
    let Some(g) = gpu() else { return };
    let (max_bound, p99_bound, median_bound) = if g.adapter().contains("llvmpipe") {
        (5e-5, 5e-5, 5e-5)
    } else {
        (1e-2, 1e-3, 2e-5)
    };
    for (name, view, w, h) in [
        ("shells", 0, 96, 72),
        ("cad", 1, 160, 120),
        ("spheres", 3, 128, 96),
        ("plates", 2, 128, 96),
    ] {
        let (s, cam) = frame(name, view, (w, h));
        let gfl = gpu_fragments(g, &s, &cam, (w, h));
        let cfl = rasterize(&s, &cam, (w, h)).unwrap();
        let (mut diffs, mut other_pixels) = (Vec::new(), 0usize);
        for p in 0..cfl.pixel_count() {
            let mut a: Vec<(u32, f32)> = cfl
                .range(p)
                .map(|i| (cfl.primitive[i], cfl.depth[i]))
                .collect();
            let mut b: Vec<(u32, f32)> = gfl
                .range(p)
                .map(|i| (gfl.primitive[i], gfl.depth[i]))
                .collect();
            a.sort_by_key(|x| x.0);
            b.sort_by_key(|x| x.0);
            if a.iter().map(|x| x.0).ne(b.iter().map(|x| x.0)) {
                other_pixels += 1;
                continue;
            }
            diffs.extend(a.iter().zip(&b).map(|(x, y)| (x.1 - y.1).abs()));
        }
        diffs.sort_by(f32::total_cmp);
        let worst = *diffs.last().unwrap();
        eprintln!(
            "{name}: depth |CPU - GPU| median {:e}, max {:e} over {} fragments; {other_pixels} of {} pixels cover other triangles",
            diffs[diffs.len() / 2],
            worst,
            diffs.len(),
            cfl.pixel_count()
        );
        assert!(worst <= max_bound, "{name}: depth differs by {worst}");
        let median = diffs[diffs.len() / 2];
        assert!(
            median <= median_bound,
            "{name}: median depth difference {median}"
        );
        let p99 = diffs[diffs.len() * 99 / 100];
        assert!(
            p99 <= p99_bound,
            "{name}: 99th percentile depth difference {p99}"
        );
        assert!(
            other_pixels * 1000 <= cfl.pixel_count(),
            "{name}: {other_pixels} pixels differ in coverage"
        );
    }
}

/// DKB's network runs on the compacted list of pixels whose k is not forced, not on every
/// covered pixel with the forced ones zeroed: the list's length is the CPU's count of covered
/// pixels that `mlp::forced` leaves to the network (their n, the frame's smallest k and their
/// two farthest fragments' colours, from the GPU's own fragments), fewer than the covered
/// pixels, in one batch of records or several; with `skip_forced` off it is every pixel with a
/// record.
#[test]
fn the_network_runs_on_the_pixels_whose_k_is_not_forced_and_no_others() {
    let mut o = dhoit_runtime::gpu::FrameOptions::default().always_approximate();
    if gpu().is_none() {
        return;
    }
    // A device of its own: which passes a frame records follows the device's last frame.
    let g = dhoit_runtime::gpu::Gpu::new().unwrap();
    let mlp = dhoit_runtime::mlp::Mlp::random(8);
    let size = (64, 48);
    for (name, view) in [("particles", 1), ("cad", 0)] {
        let (s, cam) = frame(name, view, size);
        let gfl = gpu_fragments(&g, &s, &cam, size);
        let counts = gfl.counts();
        let covered = counts.iter().filter(|&&n| n > 0).count() as u32;
        // A slot for every covered pixel (lo = 1): a pixel of three fragments has a record and
        // its k is forced (every pooled pixel is a pair: it keeps all three from k = 1).
        let f = (gfl.fragment_count() as u64 / 3).max(covered as u64);
        let lo = alloc::min_k(&counts, f);
        assert_eq!(lo, 1);
        let decided = (0..counts.len())
            .filter(|&p| counts[p] > 0 && !dhoit_runtime::mlp::forced(counts[p], true, lo))
            .count() as u32;
        assert!(decided < covered, "{name}: some pixels' k is forced");
        // Without the skip the network runs on every pixel with a record (more than two
        // fragments: a pixel of fewer has no features gathered, and its k is forced).
        let tail = dhoit_runtime::shared::TAIL_WORDS;
        let recorded = counts.iter().filter(|&&n| n > tail).count() as u32;
        assert!(
            decided < recorded && recorded < covered,
            "{name}: {decided} {recorded} {covered}"
        );
        for (skip, want) in [(true, decided), (false, recorded)] {
            o.tuning.skip_forced = skip;
            let frame = g
                .render_with(&o, &s, &cam, size, BG, Slots::Dkb(&mlp, f.into()))
                .unwrap();
            assert_eq!(
                frame.network_rows,
                Some(want),
                "{name}, skip_forced {skip}: pixels the network ran on"
            );
        }
        o.tuning.skip_forced = true;
        // At a slot a covered pixel (lo = 1, some records forced), in up to three batches, the
        // pool holds the records in batches: the rows of each batch's list add up to the
        // pixels left to the network.
        o.decision.record_batches = 3;
        let frame = g
            .render_with(
                &o,
                &s,
                &cam,
                size,
                BG,
                Slots::Dkb(&mlp, (covered as u64).into()),
            )
            .unwrap();
        assert!(frame.record_batches.is_some_and(|b| b > 1), "{name}");
        assert_eq!(frame.network_rows, Some(decided), "{name}, F {covered}");
        // Below a slot a covered pixel (lo = 0) no pixel with a record is forced, and the pool
        // holds a batch of the records at a time: the rows of every batch add up.
        let few = (covered as u64 / 8).max(1);
        assert_eq!(alloc::min_k(&counts, few), 0);
        let frame = g
            .render_with(&o, &s, &cam, size, BG, Slots::Dkb(&mlp, few.into()))
            .unwrap();
        assert!(
            frame.record_batches.is_some_and(|b| b > 1),
            "{name}: {:?} batches",
            frame.record_batches
        );
        assert_eq!(frame.network_rows, Some(recorded), "{name}, F {few}");
        o.decision.record_batches = dhoit_runtime::budget::RECORD_BATCHES;
    }
}

/// dhoit on the application's own device (`Gpu::on_device`): a device opened without 64-bit
/// atomics runs FKB and DKB in the portable passes, to the same images; one opened with `required_features()` and `required_limits()` (wgpu's defaults, 8 storage
/// buffers a stage) builds every pass and renders every method as dhoit's own device does, bit
/// for bit, with the same bytes (MBOIT where the application also asks for
/// `FLOAT32_BLENDABLE`; without it, MBOIT's frames are refused with the feature named).
#[test]
fn the_renderer_runs_on_the_applications_device() {
    let Some(g) = gpu() else { return };
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))
        .expect("the adapter the shared renderer found");
    let info = adapter.get_info();
    let open = |features, limits| {
        pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("the application's"),
            required_features: features,
            required_limits: limits,
            ..Default::default()
        }))
        .unwrap()
    };
    let (features, limits) = (
        dhoit_runtime::gpu::required_features(),
        dhoit_runtime::gpu::required_limits(),
    );
    // Without 64-bit atomics the device runs every method, FKB and DKB with the portable
    // passes, to the images of dhoit's own device; with them, at wgpu's default limits (8
    // storage buffers a stage, what `required_limits` asks), DKB runs as on dhoit's own device.
    let (s, cam) = frame("hair", 1, (32, 24));
    let mlp = dhoit_runtime::mlp::Mlp::random(4);
    let dkb = Slots::Dkb(&mlp, 300u64.into());
    let (d, q) = open(
        wgpu::Features::SHADER_INT64 | wgpu::Features::TIMESTAMP_QUERY,
        limits.clone(),
    );
    let narrow = dhoit_runtime::gpu::Gpu::on_device(d, q, &info).unwrap();
    assert!(!narrow.is_wide());
    let on_narrow = narrow
        .render_method(&s, &cam, (32, 24), [1.0; 3], dkb)
        .unwrap();
    assert!(on_narrow.variants.contains(&"capture: portable"));
    let on_wide = g.render_method(&s, &cam, (32, 24), [1.0; 3], dkb).unwrap();
    assert_eq!(on_narrow.image, on_wide.image);
    assert_eq!(on_narrow.importance, on_wide.importance);
    let fkb = narrow
        .render(&s, &cam, (32, 24), [1.0; 3], Slots::Uniform(2))
        .unwrap();
    let wide = g
        .render(&s, &cam, (32, 24), [1.0; 3], Slots::Uniform(2))
        .unwrap();
    assert!(fkb.variants.contains(&"capture: portable"));
    assert_eq!(fkb.image, wide.image);
    let (d, q) = open(features, wgpu::Limits::default());
    let eight = dhoit_runtime::gpu::Gpu::on_device(d, q, &info).unwrap();
    assert!(eight.is_wide());
    assert_eq!(
        eight.device().limits().max_storage_buffers_per_shader_stage,
        8
    );
    assert_eq!(
        eight
            .render(&s, &cam, (32, 24), [1.0; 3], dkb)
            .unwrap()
            .image,
        g.render(&s, &cam, (32, 24), [1.0; 3], dkb).unwrap().image
    );
    // Without FLOAT32_BLENDABLE every pass builds but MBOIT's, whose frames are refused with
    // the feature named.
    let (d, q) = open(features, limits.clone());
    let plain = dhoit_runtime::gpu::Gpu::on_device(d, q, &info).unwrap();
    let mboit = Slots::Mboit(Default::default());
    let e = plain
        .render(&s, &cam, (32, 24), [1.0; 3], mboit)
        .unwrap_err();
    assert!(e.to_string().contains("FLOAT32_BLENDABLE"), "{e}");
    let wboit = plain.render(
        &s,
        &cam,
        (32, 24),
        [1.0; 3],
        Slots::Wboit(Default::default()),
    );
    assert!(wboit.is_ok());
    let (d, q) = open(features | wgpu::Features::FLOAT32_BLENDABLE, limits);
    let app = dhoit_runtime::gpu::Gpu::on_device(d.clone(), q.clone(), &info).unwrap();
    assert!(*app.device() == d);
    // wgpu's default 32 bytes of colour attachments a sample hold MBOIT's four and six power
    // moments (20 and 28) but not eight (36): those frames are refused, the limit named.
    let (s8, cam8) = frame("hair", 1, (32, 24));
    for moments in [4, 6, 8] {
        let p = dhoit_runtime::composite::MboitParams::with_moments(moments).unwrap();
        let r = app.render(&s8, &cam8, (32, 24), [1.0; 3], Slots::Mboit(p));
        if moments == 8 && app.device().limits().max_color_attachment_bytes_per_sample < 36 {
            let e = r.unwrap_err().to_string();
            assert!(
                e.contains("max_color_attachment_bytes_per_sample 36"),
                "{e}"
            );
        } else {
            assert!(r.is_ok(), "{moments} moments: {:?}", r.err());
        }
    }
    let (s, cam) = frame("particles", 1, (96, 72));
    let fl = rasterize(&s, &cam, (96, 72)).unwrap();
    let mlp = dhoit_runtime::mlp::Mlp::random(4);
    let opts = dhoit_runtime::frame::Options {
        weights: Some(&mlp),
        ..dhoit_runtime::frame::Options::new(Budget::Share(250_000), [1.0; 3]).always_approximate()
    };
    // The linked list keeps what arrives first, and which fragments arrive first moves with
    // the device's threads (lavapipe's too): it is compared where its budget holds every
    // fragment, the others where 25% truncates (runtime/tests/linked_list.rs holds what it
    // keeps under a truncating budget to its twin).
    let every = dhoit_runtime::frame::Options {
        budget: Budget::Share(1_000_000),
        ..opts
    };
    for m in common::CPU_AND_GPU {
        let opts = match m {
            dhoit_runtime::frame::Method::LinkedList => every,
            _ => opts,
        };
        if m == dhoit_runtime::frame::Method::Mboit
            && !common::has(
                g,
                wgpu::Features::FLOAT32_BLENDABLE,
                "MBOIT on the application's device",
            )
        {
            continue;
        }
        let r = dhoit_runtime::frame::Renderer::new(&fl, opts);
        // FKB takes no share of a frame's fragments (its k is fixed before any count): every
        // other method allocates.
        let a = match r.allocate(m) {
            Ok(a) => a,
            Err(dhoit_runtime::Error::Budget(..)) if m == dhoit_runtime::frame::Method::Fkb => {
                continue;
            }
            Err(e) => panic!("{m}: {e}"),
        };
        let slots = || Slots::for_method(m, &a, &opts).unwrap();
        let ours = g
            .render_method(&s, &cam, (96, 72), opts.background, slots())
            .unwrap();
        let theirs = app
            .render_method(&s, &cam, (96, 72), opts.background, slots())
            .unwrap();
        assert_eq!(theirs.image, ours.image, "{m}");
        assert_eq!(theirs.allocated_bytes, ours.allocated_bytes, "{m}");
    }
}

/// The frame's plan on the device (plan.wgsl) is its twin's (`plan::plan`, itself held to an
/// exhaustive search over F and to hand computations in its unit tests) for every case of a
/// grid: DKB's and VKB's layouts, budgets of slots, shares and bytes, pools from none to more
/// than every fragment, one to three features passes recorded, exact where cheaper or not, and
/// frames from empty to every pixel three deep.
#[test]
fn the_plan_pass_matches_its_cpu_twin() {
    use dhoit_runtime::budget::Occupancy;
    use dhoit_runtime::plan::{PlanBudget, PlanInput, plan};
    let Some(g) = gpu() else { return };
    let px = 4096u64;
    let dkb = dhoit_runtime::gpu::FrameOptions::default().dkb_layout(&common::committed_weights());
    let mut cases = Vec::new();
    for layout in [dkb, budget::VKB] {
        let fixed = layout.fixed_bytes(px);
        let budgets = [
            PlanBudget::Fragments(FragmentBudget::Slots(0)),
            PlanBudget::Fragments(FragmentBudget::Slots(700)),
            PlanBudget::Fragments(FragmentBudget::Slots(5_000)),
            PlanBudget::Fragments(FragmentBudget::Share(250_000)),
            PlanBudget::Fragments(FragmentBudget::Share(1_000_000)),
            PlanBudget::Bytes(fixed / 2),
            PlanBudget::Bytes(fixed + 30_000),
            PlanBudget::Bytes(fixed + 200_000),
        ];
        for (covered, deep, deeper, extra) in [
            (0u64, 0u64, 0u64, 0u64),
            (1, 0, 0, 0),
            (900, 300, 120, 400),
            (4096, 4096, 4096, 9_000),
            (2000, 1999, 3, 17),
            // 40 million fragments: a share of them in parts per million and the pools past
            // 2^32 bytes below take more than 32 bits (the pass's u64.wgsl words).
            (4096, 4000, 3900, 40_000_000),
        ] {
            let occ = Occupancy {
                fragments: covered + deep + deeper + extra,
                covered,
                deep,
                deeper,
            };
            // Pools and byte budgets around where the fitting F changes branch: at f1 = the
            // covered pixels, at f0 = 0, at every fragment, a word either side.
            let edges: Vec<u64> = [covered + deep + deeper, covered + deep, occ.fragments]
                .iter()
                .flat_map(|&w| [w.saturating_sub(1), w, w + 1])
                .map(|w| 8 * w)
                .collect();
            let byte_edges = edges.iter().map(|&b| PlanBudget::Bytes(fixed + b));
            for budget in budgets.into_iter().chain(byte_edges) {
                let pools = [16, 1_000, 9_000, 40_000, 300_000, 6_000_000_000, 1 << 41];
                for pool_bytes in pools.into_iter().chain(edges.iter().copied()) {
                    for batches in [1, 3] {
                        for exact_when_cheaper in [false, true] {
                            let input = PlanInput {
                                layout,
                                pixels: px,
                                budget,
                                pool_bytes,
                                batches,
                                exact_when_cheaper,
                            };
                            cases.push((input, occ));
                        }
                    }
                }
            }
        }
    }
    let gpu_plans = g.plan(&cases).unwrap();
    let (mut exact, mut short, mut truncated) = (0, 0, 0);
    for ((input, occ), on_gpu) in cases.iter().zip(gpu_plans) {
        let twin = plan(input, occ);
        assert_eq!(
            on_gpu,
            dhoit_runtime::plan::Plan { batches: 0, ..twin },
            "{input:?} {occ:?}"
        );
        exact += twin.exact as u32;
        short += (twin.short != 0) as u32;
        truncated += (!twin.exact && twin.f > 0) as u32;
    }
    // The grid reaches every outcome.
    assert!(
        exact > 0 && short > 0 && truncated > 0,
        "{exact} {short} {truncated}"
    );
}

/// u64.wgsl's 64-bit words (two u32s, for the passes that run without u64) compute what Rust's
/// u64 does: sums, differences, products, quotients, comparisons and the nearest f32 (ties to
/// even) of values across the 32-bit boundary and at the ends of the range, on the device.
#[test]
fn sixty_four_bit_words_compute_what_u64s_do() {
    let Some(g) = gpu() else { return };
    let mut rng = dhoit_runtime::rng::Rng::new(7);
    let edges = [
        0u64,
        1,
        0xffff_ffff,
        1 << 32,
        (1 << 32) + 1,
        0x8000_0000_0000_0000,
        u64::MAX - 1,
        u64::MAX,
    ];
    let mut cases: Vec<(u64, u64, u32)> = Vec::new();
    for &a in &edges {
        for &b in &edges {
            cases.push((a, b, (b as u32).max(1)));
        }
    }
    // Halfway cases of the f32 rounding, both parities, and one past.
    for base in [
        (1u64 << 40) + (1 << 16),
        (1 << 40) + (3 << 16),
        0xff_ffff << 30,
    ] {
        for off in [0u64, 1 << 15, (1 << 15) + 1, 1 << 6] {
            cases.push((base + off, 1, 1));
        }
    }
    for _ in 0..2000 {
        let wide = |r: &mut dhoit_runtime::rng::Rng| {
            let bits = r.below(65) as u32;
            if bits == 0 {
                0
            } else {
                r.next_u64() >> (64 - bits)
            }
        };
        let (a, b) = (wide(&mut rng), wide(&mut rng));
        let d = (rng.next_u64() >> rng.below(32)) as u32;
        cases.push((a, b, d.max(1)));
    }
    let got = g.u64_words(&cases).unwrap();
    for (&(a, b, d), (w, f)) in cases.iter().zip(got) {
        assert_eq!(f.to_bits(), (a as f32).to_bits(), "a {a:#x}: to f32");
        let want = [
            a.wrapping_add(b),
            a.wrapping_sub(b),
            (a as u32 as u64) * (b as u32 as u64),
            a.wrapping_mul(d as u64),
            a / d as u64,
            (a < b) as u64,
            a.min(b),
            a.max(b),
        ];
        assert_eq!(
            w, want,
            "a {a:#x} b {b:#x} d {d:#x}: add sub mul mul_u32 div lt min max"
        );
    }
}

/// The portable capture (32-bit atomics, two passes) leaves the wide capture's slots, tails and
/// image, bit for bit, for every k-buffer (FKB, uploaded k, DKB and VKB at budgets that
/// truncate, append and hold every fragment), on fragments of equal depths too; both are their
/// twin's (composite::capture orders equal depths by colour), and in every submission order
/// each gives the same image.
#[test]
fn the_portable_capture_leaves_the_wide_captures_slots_and_image() {
    use dhoit_runtime::gpu::Capture;
    let Some(g) = gpu() else { return };
    let s = common::tied_layers(composite::APPEND_MAX as usize + 9);
    let cam = common::identity();
    let size = (24, 16);
    let gfl = gpu_fragments(g, &s, &cam, size);
    // Ties: pixels whose fragments share a depth.
    let ties = (0..gfl.pixel_count())
        .filter(|&p| {
            let mut d: Vec<u32> = gfl.fragments(p).map(|f| f.depth.to_bits()).collect();
            let n = d.len();
            d.sort_unstable();
            d.dedup();
            d.len() < n
        })
        .count();
    assert!(ties > 0, "the scene has no equal depths");
    let total = gfl.fragment_count() as u64;
    let mlp = dhoit_runtime::mlp::Mlp::random(6);
    let k: Vec<u32> = (0..gfl.pixel_count()).map(|p| (p % 5) as u32).collect();
    let mut runs: Vec<(String, Slots)> = vec![
        ("fkb k = 1".into(), Slots::Uniform(1)),
        ("fkb k = 4".into(), Slots::Uniform(4)),
        ("uploaded k".into(), Slots::PerPixel(&k)),
    ];
    for f in [total / 4, total / 2, total] {
        runs.push((format!("dkb F = {f}"), Slots::Dkb(&mlp, f.into())));
        runs.push((format!("vkb F = {f}"), vkb_at(f)));
    }
    let wide = dhoit_runtime::gpu::FrameOptions::default().always_approximate();
    let portable = dhoit_runtime::gpu::FrameOptions {
        capture: Capture::Portable,
        ..wide
    };
    if !common::is_wide(g, "the portable capture against the one-pass capture") {
        return;
    }
    for (label, slots) in runs {
        let a = g.render_with(&wide, &s, &cam, size, BG, slots).unwrap();
        let b = g.render_with(&portable, &s, &cam, size, BG, slots).unwrap();
        assert!(
            b.variants.contains(&"capture: portable") && !a.variants.contains(&"capture: portable"),
            "{label}: ran {:?} / {:?}",
            a.variants,
            b.variants
        );
        let (keys, bases, tails) = b.slots.clone().unwrap();
        assert!(a.slots == b.slots, "{label}: the slots or tails differ");
        assert!(
            a.importance == b.importance && a.stats == b.stats,
            "{label}: the statistics or importance differ"
        );
        assert!(
            image_bits(&a.image) == image_bits(&b.image),
            "{label}: the images differ"
        );
        // Both are the twin's capture of the same k.
        let kk: Vec<u32> = bases.windows(2).map(|b| b[1] - b[0]).collect();
        let (twin_keys, twin_tails) = twin_capture(&gfl, &kk);
        assert!(
            keys == twin_keys && tails == twin_tails,
            "{label}: the capture is not its twin's"
        );
        let truncated = kk
            .iter()
            .zip(gfl.counts())
            .filter(|&(&k, n)| (k as usize) < n as usize)
            .count();
        eprintln!("{label}: {truncated} pixels truncated, slots and image equal");
        for seed in 0..2 {
            let shuffled = s.shuffled(seed);
            for (opts, name) in [(&wide, "wide"), (&portable, "portable")] {
                let f = g
                    .render_with(opts, &shuffled, &cam, size, BG, slots)
                    .unwrap();
                assert!(
                    image_bits(&f.image) == image_bits(&a.image),
                    "{label}: {name}, shuffle {seed}: another image"
                );
            }
        }
    }
}

/// One frame of `stream` seen by `cam`, submitted and waited for: its image and report.
fn streamed(
    g: &dhoit_runtime::gpu::Gpu,
    stream: &mut dhoit_runtime::gpu::SceneStream,
    cam: &Camera,
) -> (composite::Image, dhoit_runtime::gpu::FrameReport) {
    let device = stream.gpu().device();
    let mut enc = device.create_command_encoder(&Default::default());
    stream.record(&mut enc, cam).unwrap();
    g.queue().submit([enc.finish()]);
    let image = stream.image().unwrap();
    let mut reports = stream.finished(true).unwrap();
    assert_eq!(reports.len(), 1);
    let report = reports.remove(0);
    assert!(report.error.is_none() && !report.pool_short, "{report:?}");
    (image, report)
}

/// A stream's DKB frame after the first gathers its network's statistics with its count, for
/// the pixels the frame before marked, and draws no features pass (two geometry passes); its
/// first, and the frame after a cut, mark their own records and draw it (three). With the
/// camera still, the two give the same image, bit for bit; with it moved, the frame is its
/// twin's: this frame's fragments' statistics for the pixels the last frame's count marked, the
/// mean request the network gave them for those deeper now and unmarked then
/// (`Mlp::dkb_importance_recorded`), which is not the frame its own marks give.
#[test]
fn a_dkb_stream_gathers_its_statistics_with_its_count_for_the_pixels_the_frame_before_marked() {
    let Some(g) = gpu() else { return };
    let mlp = common::committed_weights();
    let size = (128, 96);
    let s = scene::load("hair", Opacity::default()).unwrap();
    let [a, b] = [0, 1].map(|v| Camera::orbit(&s, v, 24, size));
    let (fa, fb) = (
        gpu_fragments(g, &s, &a, size),
        gpu_fragments(g, &s, &b, size),
    );
    let (ca, cb) = (fa.counts(), fb.counts());
    let tail = dhoit_runtime::shared::TAIL_WORDS;
    // The camera moved enough that some pixels are deeper now than then.
    let newly = (0..ca.len())
        .filter(|&p| cb[p] > tail && ca[p] <= tail)
        .count();
    let gone = (0..ca.len())
        .filter(|&p| ca[p] > tail && cb[p] <= tail)
        .count();
    assert!(
        newly > 20 && gone > 20,
        "{newly} newly deeper, {gone} no longer"
    );
    let budget = Budget::Share(250_000);
    let options = dhoit_runtime::frame::Options {
        weights: Some(&mlp),
        ..dhoit_runtime::frame::Options::new(budget, BG).always_approximate()
    };
    let method = dhoit_runtime::frame::Method::Dkb;
    let mut stream = dhoit_runtime::gpu::SceneStream::new(g, &s, size, method, &options).unwrap();
    // A pool for both frames' records and slots.
    let (oa, ob) = (budget::Occupancy::of(&ca), budget::Occupancy::of(&cb));
    let most = budget::Occupancy {
        fragments: oa.fragments.max(ob.fragments),
        covered: oa.covered.max(ob.covered),
        deep: oa.deep.max(ob.deep),
        deeper: oa.deeper.max(ob.deeper),
    };
    stream.expect(most.scaled(1.5, fa.pixel_count() as u64));
    // The pass that gathers the statistics apart from the count.
    let features = |r: &dhoit_runtime::gpu::FrameReport| r.passes.contains(&"features");
    let (first, r1) = streamed(g, &mut stream, &a);
    assert!(features(&r1), "the first frame: {:?}", r1.passes);
    // Still: no features pass, the same image.
    let (still, r2) = streamed(g, &mut stream, &a);
    assert!(!features(&r2), "a frame after the first: {:?}", r2.passes);
    assert!(
        image_bits(&still) == image_bits(&first),
        "still: the image differs"
    );
    // Moved: the statistics of frame b for the pixels frame a marked.
    let (moved, r3) = streamed(g, &mut stream, &b);
    assert!(!features(&r3), "{:?}", r3.passes);
    let f = FragmentBudget::Share(250_000).of(fb.fragment_count() as u64);
    let (feats, counts) = network_inputs(&common::recorded_stats(&fb), f);
    let recorded: Vec<bool> = ca.iter().map(|&n| n > tail).collect();
    let imp = mlp.dkb_importance_recorded(&feats, &counts, f, &recorded);
    let k = dhoit_runtime::shared::stored(&alloc::allocate_pooled(&imp, &cb, mlp.target, f), &cb);
    let twin = composite::composite(&fb, composite::Method::Hybrid(&k), BG);
    let d = moved.max_abs_diff(&twin);
    assert!(d <= 1e-5, "moved: {d} from its twin");
    // Which the frame b's own marks would not give: the twin tells the two apart.
    let own = mlp.dkb_importance_pooled(&feats, &counts, f);
    let own_k =
        dhoit_runtime::shared::stored(&alloc::allocate_pooled(&own, &cb, mlp.target, f), &cb);
    let own_twin = composite::composite(&fb, composite::Method::Hybrid(&own_k), BG);
    assert!(
        own_twin.max_abs_diff(&twin) > 1e-4,
        "the marks of frame a changed nothing"
    );
    // Its own marks the frame after: the frame b gives alone (its marks made with its count
    // first), and not the moved frame's.
    let (again, _) = streamed(g, &mut stream, &b);
    let alone = g
        .render_with(
            &dhoit_runtime::gpu::FrameOptions::default().always_approximate(),
            &s,
            &b,
            size,
            BG,
            Slots::Dkb(&mlp, FragmentBudget::Share(250_000).into()),
        )
        .unwrap();
    assert!(image_bits(&again) == image_bits(&alone.image), "b again");
    // A cut: the frame marks its own records and draws the features pass.
    stream.cut();
    let (cut, r5) = streamed(g, &mut stream, &b);
    assert!(features(&r5), "after a cut: {:?}", r5.passes);
    assert!(image_bits(&cut) == image_bits(&again), "after a cut");
}
