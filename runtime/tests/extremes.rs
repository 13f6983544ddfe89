//! The whole pipeline at its extremes, CPU and GPU alike: each frame is rasterized and rendered
//! by the CPU reference and by the GPU from the same scene (each with its own rasterizer), and
//! the images must agree within 1e-5 on every pixel. Needs a GPU adapter (lavapipe in CI);
//! DHOIT_SKIP_GPU=1 skips explicitly.

mod common;

use common::{RenderMethod, gpu, identity, quad};
use dhoit_runtime::budget::{self, Budget, FragmentBudget};
use dhoit_runtime::composite::Image;
use dhoit_runtime::frame::{self, Method, Options};
use dhoit_runtime::gpu::{Gpu, Slots};
use dhoit_runtime::importance::VkbParams;
use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::Scene;
use glam::Vec3;

const BG: [f32; 3] = [0.9, 0.85, 0.8];
const TOLERANCE: f32 = 1e-5;

/// Every method that runs on both sides, CPU frame against GPU frame, on one scene and budget,
/// on `g` and on WebGPU's core device (the portable passes; every method but MBOIT, which needs
/// FLOAT32_BLENDABLE): the largest difference over every pixel of every method.
fn cpu_and_gpu_agree(g: &Gpu, s: &Scene, size: (u32, u32), budget: Budget, what: &str) -> f32 {
    let cam = identity();
    let fl = rasterize(s, &cam, size).unwrap();
    let mlp = Mlp::random(9);
    let opts = Options {
        weights: Some(&mlp),
        ..Options::new(budget, BG)
    };
    let mut worst = 0.0f32;
    let core = common::core().expect("the core device beside the GPU");
    let portable: Vec<Method> = common::CPU_AND_GPU
        .into_iter()
        .filter(|&m| m != Method::Mboit)
        .collect();
    for (device, methods) in [
        ("", &common::CPU_AND_GPU[..]),
        (" (core device)", &portable[..]),
    ] {
        let dev = if device.is_empty() { g } else { core };
        for (m, cpu, gpu) in common::cpu_and_gpu_frames(dev, s, &cam, &fl, opts, methods) {
            let d = gpu.max_abs_diff(&cpu.image);
            assert!(
                d <= common::twin_bound(m, TOLERANCE),
                "{what}{device}, {}: CPU and GPU images differ by {d} (F = {})",
                m.name(),
                cpu.budget_fragments
            );
            worst = worst.max(d);
        }
    }
    eprintln!("{what}: CPU and GPU agree within {worst:e}, on both devices");
    worst
}

#[test]
fn intersecting_and_coplanar_surfaces_render_alike_on_cpu_and_gpu() {
    let Some(g) = gpu() else { return };
    let mut s = Scene::default();
    // Two tilted quads crossing along x = 0.
    quad(
        &mut s,
        (-0.9, -0.9, 0.9, 0.9),
        (0.2, 0.8),
        [0.9, 0.1, 0.1, 0.5],
    );
    quad(
        &mut s,
        (-0.9, -0.6, 0.9, 0.6),
        (0.8, 0.2),
        [0.1, 0.1, 0.9, 0.5],
    );
    // Two coplanar quads at one depth, overlapping: equal keys, one order everywhere.
    quad(
        &mut s,
        (-0.7, -0.7, 0.3, 0.3),
        (0.5, 0.5),
        [0.1, 0.8, 0.1, 0.4],
    );
    quad(
        &mut s,
        (-0.3, -0.3, 0.7, 0.7),
        (0.5, 0.5),
        [0.9, 0.9, 0.1, 0.4],
    );
    // The same quad twice (identical fragments but their primitive).
    quad(
        &mut s,
        (-0.5, 0.2, 0.5, 0.8),
        (0.35, 0.35),
        [0.2, 0.6, 0.9, 0.3],
    );
    quad(
        &mut s,
        (-0.5, 0.2, 0.5, 0.8),
        (0.35, 0.35),
        [0.8, 0.3, 0.5, 0.3],
    );
    for budget in ["2fpp", "50%", "100%"] {
        cpu_and_gpu_agree(
            g,
            &s,
            (96, 72),
            Budget::parse(budget).unwrap(),
            &format!("intersecting + coplanar at {budget}"),
        );
    }
}

#[test]
fn extreme_opacities_and_depths_render_alike_on_cpu_and_gpu() {
    let Some(g) = gpu() else { return };
    let mut s = Scene::default();
    // Opacities 0, 1e-7 and 1 over a half-transparent backdrop.
    quad(
        &mut s,
        (-1.0, -1.0, 1.0, 1.0),
        (0.6, 0.6),
        [0.3, 0.5, 0.7, 0.5],
    );
    quad(
        &mut s,
        (-0.9, -0.9, -0.3, 0.9),
        (0.4, 0.4),
        [1.0, 0.0, 0.0, 0.0],
    );
    quad(
        &mut s,
        (-0.3, -0.9, 0.3, 0.9),
        (0.3, 0.3),
        [0.0, 1.0, 0.0, 1e-7],
    );
    quad(
        &mut s,
        (0.3, -0.9, 0.9, 0.9),
        (0.2, 0.2),
        [0.0, 0.0, 1.0, 1.0],
    );
    // Depths at the near and far planes, and a layer behind an opaque one.
    quad(
        &mut s,
        (-0.8, -0.2, 0.8, 0.2),
        (0.0, 0.0),
        [0.9, 0.9, 0.2, 0.6],
    );
    quad(
        &mut s,
        (-0.8, -0.5, 0.8, 0.5),
        (1.0, 1.0),
        [0.2, 0.9, 0.9, 0.6],
    );
    quad(
        &mut s,
        (-0.6, -0.6, 0.6, 0.6),
        (0.9995, 0.9995),
        [0.7, 0.2, 0.9, 0.6],
    );
    let cam = identity();
    let fl = rasterize(&s, &cam, (80, 60)).unwrap();
    let depths = &fl.depth;
    assert!(depths.contains(&0.0), "a fragment at depth 0");
    // At the far plane a fragment lies at the depth the opaque pass clears to: as under any
    // LESS depth test, it is not drawn. A fragment of 8-bit opacity 0 adds nothing: none.
    assert!(!depths.contains(&1.0), "no fragment at depth 1");
    assert!(
        depths.iter().any(|&d| d > 0.99),
        "fragments just before the far plane"
    );
    assert!(
        fl.rgba.iter().all(|c| c[3] > 0.0),
        "no fragment of opacity 0"
    );
    for budget in ["1fpp", "3fpp", "100%"] {
        cpu_and_gpu_agree(
            g,
            &s,
            (80, 60),
            Budget::parse(budget).unwrap(),
            &format!("opacities 0, 1e-7, 1 and depths 0, 1 at {budget}"),
        );
    }
    // Opacity 0 leaves no trace, 1 hides what is behind: the exact image says so.
    let exact = frame::render(
        &fl,
        Method::Abuffer,
        Options::new(Budget::Share(1_000_000), BG),
    )
    .unwrap()
    .image;
    let at = |x: u32, y: u32| exact.data[(y * 80 + x) as usize];
    // Column 12 (x = -0.7) at row 50 (y = 0.67): the backdrop and the invisible quad only.
    let mut backdrop_only = Scene::default();
    quad(
        &mut backdrop_only,
        (-1.0, -1.0, 1.0, 1.0),
        (0.6, 0.6),
        [0.3, 0.5, 0.7, 0.5],
    );
    let fb = rasterize(&backdrop_only, &cam, (80, 60)).unwrap();
    let plain = frame::render(
        &fb,
        Method::Abuffer,
        Options::new(Budget::Share(1_000_000), BG),
    )
    .unwrap()
    .image;
    assert_eq!(at(12, 50), plain.data[(50 * 80 + 12) as usize]);
}

#[test]
fn one_fragment_a_pixel_and_budgets_at_the_edges() {
    let Some(g) = gpu() else { return };
    let (w, h) = (64u32, 48u32);
    let pixels = (w * h) as u64;
    // One full-screen quad: every pixel exactly one fragment.
    let mut one = Scene::default();
    quad(
        &mut one,
        (-1.0, -1.0, 1.0, 1.0),
        (0.5, 0.5),
        [0.4, 0.7, 0.2, 0.6],
    );
    let fl = rasterize(&one, &identity(), (w, h)).unwrap();
    assert!(fl.counts().iter().all(|&n| n == 1));
    for budget in ["1fpp", "0.5fpp", "100%"] {
        cpu_and_gpu_agree(
            g,
            &one,
            (w, h),
            Budget::parse(budget).unwrap(),
            &format!("one fragment a pixel at {budget}"),
        );
    }
    // A layered scene: 24 layers over most pixels (deep enough that DKB's fixed cost is below
    // the exact A-buffer's bytes: a budget that holds the A-buffer renders it).
    let mut s = Scene::default();
    for i in 0..24 {
        let z = 0.05 + 0.035 * i as f32;
        let t = i as f32 / 23.0;
        let c = [0.9 * t, 0.9 - 0.6 * t, 0.5, 0.3 + 0.4 * t];
        quad(
            &mut s,
            (-0.95 + 0.0125 * i as f32, -0.9, 0.9, 0.95),
            (z, z + 0.03),
            c,
        );
    }
    let fl = rasterize(&s, &identity(), (w, h)).unwrap();
    let covered = fl.counts().iter().filter(|&&n| n > 0).count() as u64;
    let total = fl.fragment_count() as u64;
    // A budget of exactly the fixed cost leaves no slot: refused, saying what is needed.
    let fixed = budget::DKB.fixed_bytes(pixels);
    assert!(fixed < budget::ABUFFER.allocated_bytes(pixels, total));
    let mlp = Mlp::random(1);
    let opts = |b| Options {
        weights: Some(&mlp),
        ..Options::new(b, BG).always_approximate()
    };
    let err = frame::render(&fl, Method::Dkb, opts(Budget::Bytes(fixed))).unwrap_err();
    assert!(
        err.to_string().contains("before any fragment slot"),
        "{err}"
    );
    // The least bytes that run: the fixed cost and a pool of the most it holds: a batch of the
    // records (32 bytes for each pixel of three fragments or more, in up to three batches where
    // the bytes do not hold them whole) and the network's list after them (4 bytes a record),
    // the marks (a bit a pixel in words of 32, each word's prefix count, and their total), or
    // one slot and, for each covered pixel (with fewer slots than those, any may have k = 0),
    // the two words of a tail or of the two fragments it would hold, one word for a pixel of
    // one. What the pool holds beyond them is slots: F by hand. A budget of one slot reserves
    // the records whole (one batch, so a frame after it gathers them with its count).
    let occ = budget::Occupancy::of(&fl.counts());
    let (deep, deeper) = (occ.deep, occ.deeper);
    let pool = (36 * deeper.div_ceil(3))
        .max(4 * (2 * pixels.div_ceil(32) + 1))
        .max(8 * (1 + covered + deep).min(total));
    let one = fixed + pool;
    let whole = (36 * deeper).max(pool);
    assert_eq!(fixed + whole, budget::DKB.reserved_bytes(pixels, 1, &occ));
    assert_eq!(
        one,
        budget::DKB
            .with_record_batches(3)
            .reserved_bytes(pixels, 1, &occ)
    );
    let f1 = frame::render(&fl, Method::Dkb, opts(Budget::Bytes(one))).unwrap();
    assert!(frame::render(&fl, Method::Dkb, opts(Budget::Bytes(one - 1))).is_err());
    let by_hand = match (pool / 8).saturating_sub(deep + deeper) {
        f if f >= covered => f,
        _ => pool / 8 - (covered + deep),
    };
    assert!(by_hand >= 1);
    assert_eq!(f1.budget_fragments, by_hand);
    let a1 = frame::Renderer::new(&fl, opts(Budget::Bytes(one)))
        .allocate(Method::Dkb)
        .unwrap();
    assert_eq!(
        a1.k.iter().map(|&k| k as u64).sum::<u64>(),
        by_hand.min(total)
    );
    assert!(f1.allocated_bytes <= one);
    // Fewer slots than covered pixels: the documented behaviour is that k may be 0 (the pixel
    // is all tail), the slots are all handed out, and CPU and GPU agree.
    let few = covered / 3;
    let fr = frame::render(
        &fl,
        Method::Dkb,
        opts(Budget::SlotsPerPixel(few as f64 / pixels as f64)),
    )
    .unwrap();
    assert!(fr.budget_fragments < covered);
    let few_k = frame::Renderer::new(&fl, opts(Budget::SlotsPerPixel(few as f64 / pixels as f64)))
        .allocate(Method::Dkb)
        .unwrap()
        .k;
    assert_eq!(
        few_k.iter().map(|&k| k as u64).sum::<u64>(),
        fr.budget_fragments
    );
    // The frame stores that allocation (all of a pixel's fragments where its tail would hold
    // no more than two), and some pixels are all tail.
    assert_eq!(fr.k, dhoit_runtime::shared::stored(&few_k, &fl.counts()));
    assert!(fr.k.iter().zip(fl.counts()).any(|(&k, n)| n > 0 && k == 0));
    cpu_and_gpu_agree(
        g,
        &s,
        (w, h),
        Budget::SlotsPerPixel(few as f64 / pixels as f64),
        "fewer slots than covered pixels",
    );
    // A budget of every fragment or more: every k-buffer method's image is the A-buffer's,
    // exactly on the CPU, within float rounding on the GPU.
    let exact = frame::render(&fl, Method::Abuffer, opts(Budget::Share(1_000_000))).unwrap();
    let gpu_exact = g
        .render_method(
            &s,
            &identity(),
            (w, h),
            BG,
            dhoit_runtime::gpu::Slots::Exact,
        )
        .unwrap()
        .image;
    for b in [
        Budget::Share(1_000_000),
        Budget::SlotsPerPixel((total + 5) as f64 / pixels as f64),
    ] {
        for m in [Method::Vkb, Method::Dkb, Method::Optimal] {
            let f = frame::render(&fl, m, opts(b)).unwrap();
            assert_eq!(f.image.data, exact.image.data, "{} at {b}: CPU", m.name());
        }
        let fb = FragmentBudget::Slots(b.resolve(&budget::DKB, pixels, total).unwrap().1);
        for slots in [
            Slots::Dkb(&mlp, fb.into()),
            Slots::Vkb(VkbParams::default(), fb.into()),
        ] {
            let img: Image = g
                .render_method(&s, &identity(), (w, h), BG, slots)
                .unwrap()
                .image;
            let d = img.max_abs_diff(&gpu_exact);
            assert!(
                d <= TOLERANCE,
                "{slots:?} at {b}: GPU differs from its A-buffer by {d}"
            );
        }
    }
}

#[test]
fn thousands_of_fragments_in_one_pixel_are_captured_or_refused_never_wrong() {
    let Some(g) = gpu() else { return };
    // 3000 layers over a 4x4 frame.
    let mut s = Scene::default();
    for i in 0..3000 {
        let z = 0.05 + 0.9 * ((i * 7919) % 3000) as f32 / 3000.0;
        let c = [
            (i % 7) as f32 / 7.0,
            (i % 5) as f32 / 5.0,
            (i % 3) as f32 / 3.0,
            0.02,
        ];
        s.push_triangle(
            [
                Vec3::new(-1.0, -1.0, z),
                Vec3::new(3.0, -1.0, z),
                Vec3::new(-1.0, 3.0, z),
            ],
            [c; 3],
        );
    }
    let size = (4u32, 4u32);
    let fl = rasterize(&s, &identity(), size).unwrap();
    assert!(fl.counts().iter().all(|&n| n == 3000));
    let mlp = Mlp::random(2);
    // Which frames were compared, and which refused: a test that refused every frame would
    // hold nothing.
    let (mut compared, mut refused) = (Vec::new(), Vec::new());
    for b in ["4fpp", "64fpp", "25%"] {
        let b = Budget::parse(b).unwrap();
        for m in [Method::Fkb, Method::Vkb, Method::Dkb] {
            let cpu = frame::render(
                &fl,
                m,
                Options {
                    weights: Some(&mlp),
                    ..Options::new(b, BG).always_approximate()
                },
            )
            .unwrap();
            let f = FragmentBudget::Slots(cpu.budget_fragments);
            let slots = match m {
                Method::Vkb => Slots::Vkb(VkbParams::default(), f.into()),
                Method::Dkb => Slots::Dkb(&mlp, f.into()),
                _ => Slots::PerPixel(&cpu.k),
            };
            match g.render_method(&s, &identity(), size, BG, slots) {
                Ok(frame) => {
                    let d = frame.image.max_abs_diff(&cpu.image);
                    assert!(d <= TOLERANCE, "{} at {b}: GPU differs by {d}", m.name());
                    compared.push(format!("{} at {b}", m.name()));
                }
                Err(e) => {
                    let msg = e.to_string();
                    assert!(msg.contains("loops early"), "{} at {b}: {msg}", m.name());
                    refused.push(format!("{} at {b}", m.name()));
                }
            }
        }
    }
    eprintln!("3000 deep: compared {compared:?}; refused {refused:?}");
    // FKB's loops are bounded by its k: its frame is compared at every budget.
    for b in ["4fpp", "64fpp", "25%"] {
        assert!(
            compared.contains(&format!("fkb at {b}")),
            "compared {compared:?}; refused {refused:?}"
        );
    }
}

/// Skipping the network where k is forced changes the time of the importance pass, never the
/// frame: the importance map, k and the image are the same with the skip and without it.
#[test]
fn skipping_forced_pixels_leaves_the_frame_unchanged() {
    let Some(g) = gpu() else { return };
    let mut o = dhoit_runtime::gpu::FrameOptions::default().always_approximate();
    let mut s = Scene::default();
    // One fragment and two (forced: all kept whatever k), three (forced where every covered
    // pixel has a slot) and deeper pixels.
    quad(
        &mut s,
        (-1.0, -1.0, 0.0, 1.0),
        (0.3, 0.3),
        [0.8, 0.2, 0.2, 0.5],
    );
    quad(
        &mut s,
        (-0.5, -1.0, 0.5, 0.0),
        (0.5, 0.5),
        [0.2, 0.2, 0.8, 0.5],
    );
    quad(
        &mut s,
        (-0.5, -1.0, 0.5, 0.0),
        (0.6, 0.6),
        [0.2, 0.2, 0.8, 0.5],
    );
    quad(
        &mut s,
        (0.0, -0.8, 1.0, 0.8),
        (0.2, 0.7),
        [0.2, 0.8, 0.2, 0.4],
    );
    quad(
        &mut s,
        (0.2, -0.6, 0.9, 0.9),
        (0.4, 0.45),
        [0.9, 0.9, 0.2, 0.4],
    );
    let mlp = Mlp::random(6);
    let size = (64u32, 48u32);
    // 75% holds a slot for every covered pixel (lo = 1): a pixel of three fragments has a
    // record and its k is forced (a pooled pixel keeps all three from k = 1).
    for f in [
        FragmentBudget::Share(750_000),
        FragmentBudget::Share(1_000_000),
    ] {
        let mut frames = Vec::new();
        for skip in [true, false] {
            o.tuning.skip_forced = skip;
            let fr = g
                .render_with(&o, &s, &identity(), size, BG, Slots::Dkb(&mlp, f.into()))
                .unwrap();
            frames.push(fr);
        }
        let (a, b) = (&frames[0], &frames[1]);
        assert_eq!(
            a.slots.as_ref().unwrap().1,
            b.slots.as_ref().unwrap().1,
            "{f:?}: k"
        );
        assert_eq!(a.image.data, b.image.data, "{f:?}: image");
        let (ia, ib) = (
            a.importance.as_ref().unwrap(),
            b.importance.as_ref().unwrap(),
        );
        let differ = ia.iter().zip(ib).filter(|(x, y)| x != y).count();
        // The skipped pixels read 0 instead of the network's output: some differ, yet k does not.
        if f == FragmentBudget::Share(750_000) {
            assert!(differ > 0, "some pixels were skipped");
        }
    }
}
