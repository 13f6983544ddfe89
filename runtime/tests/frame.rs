//! Whole frames: every method under a full budget is exact, budgets hold, features and VKB.

mod common;

use dhoit_runtime::budget::{Budget, FragmentBudget};
use dhoit_runtime::fragment::FragmentLists;
use dhoit_runtime::frame::{Equal, Method, Options, Renderer};
use dhoit_runtime::importance::{self, VkbParams};
use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::{self, Camera, Opacity};

fn frame(name: &str, size: (u32, u32)) -> FragmentLists {
    let s = scene::load(name, Opacity::default()).unwrap();
    rasterize(&s, &Camera::orbit(&s, 0, scene::DEFAULT_VIEWS, size), size).unwrap()
}

#[test]
fn with_every_fragment_in_budget_the_allocations_are_exact() {
    let mlp = Mlp::random(3);
    for name in ["spheres", "plates"] {
        let fl = frame(name, (64, 48));
        let total = fl.fragment_count() as f64;
        let pixels = fl.pixel_count() as f64;
        let opts = Options {
            weights: Some(&mlp),
            ..Options::new(
                Budget::SlotsPerPixel(total / pixels + 0.01),
                [0.2, 0.3, 0.4],
            )
        };
        let r = Renderer::new(&fl, opts);
        let exact = r.render(Method::Abuffer).unwrap().image;
        // Every k-buffer, FKB too (whose one k is below the deepest pixel): the budget holds
        // every fragment, so each renders the A-buffer, with its memory.
        assert!(((total / pixels + 0.01).floor() as u32) < fl.max_depth_complexity());
        let bytes = dhoit_runtime::budget::ABUFFER.allocated_bytes(pixels as u64, total as u64);
        for m in [
            Method::Fkb,
            Method::Vkb,
            Method::Dkb,
            Method::Optimal,
            Method::GreedyPaper,
            Method::GreedyIncrease,
        ] {
            let f = r.render(m).unwrap();
            assert_eq!(f.k, fl.counts(), "{name} {}: k = n", m.name());
            assert_eq!(f.image, exact, "{name} {}", m.name());
            assert_eq!(
                f.allocated_bytes,
                bytes,
                "{name} {}: the A-buffer's bytes",
                m.name()
            );
        }
    }
}

#[test]
fn allocations_spend_exactly_the_budget_and_never_more_bytes() {
    let mlp = Mlp::random(9);
    let fl = frame("foliage", (80, 60));
    let counts = fl.counts();
    for budget in ["0.05fpp", "1fpp", "2fpp", "3.7fpp", "100fpp", "60KB", "2MB"] {
        let b = Budget::parse(budget).unwrap();
        let opts = Options {
            weights: Some(&mlp),
            ..Options::new(b, [1.0; 3]).always_approximate()
        };
        let r = Renderer::new(&fl, opts);
        for m in [
            Method::Vkb,
            Method::Dkb,
            Method::Optimal,
            Method::GreedyPaper,
            Method::GreedyIncrease,
        ] {
            let a = match r.allocate(m) {
                Ok(a) => a,
                Err(e) => {
                    assert!(budget == "60KB", "{budget} {}: {e}", m.name());
                    continue;
                }
            };
            let sum: u64 = a.k.iter().map(|&k| k as u64).sum();
            assert_eq!(
                sum,
                a.budget_fragments.min(fl.fragment_count() as u64),
                "{budget} {}",
                m.name()
            );
            // VKB and DKB store all of a pixel's fragments where a tail would hold no more
            // (shared::stored_k): never fewer slots than the allocation's, never more bytes.
            let allocated = a.k.clone();
            let f = r.composite(a);
            assert!(f.k.iter().zip(&counts).all(|(&k, &n)| k <= n));
            assert!(f.k.iter().zip(&allocated).all(|(&k, &a)| k >= a));
            assert!(f.allocated_bytes <= f.budget_bytes, "{budget} {}", m.name());
        }
    }
}

#[test]
fn equal_bytes_give_every_method_one_memory_budget() {
    let mlp = Mlp::random(4);
    let (mut held, mut truncated) = (0, 0);
    // A shallow scene, where equal bytes hold the exact A-buffer, and 100 stacked layers, deep
    // enough (N / P above 10) that DKB's layout truncates within them.
    let deep = common::layers(100);
    let cam = Camera::orbit(&deep, 0, scene::DEFAULT_VIEWS, (80, 60));
    let layered = rasterize(&deep, &cam, (80, 60)).unwrap();
    for (name, fl) in [("cad", frame("cad", (80, 60))), ("layers", layered)] {
        let (px, total) = (fl.pixel_count() as u64, fl.fragment_count() as u64);
        let exact = dhoit_runtime::budget::ABUFFER.allocated_bytes(px, total);
        for budget in ["25%", "90%", "0.5fpp", "3fpp"] {
            let opts = Options {
                weights: Some(&mlp),
                equal: Equal::Bytes,
                ..Options::new(Budget::parse(budget).unwrap(), [1.0; 3]).always_approximate()
            };
            let r = Renderer::new(&fl, opts);
            // VKB and DKB run at DKB's M; the optimal allocation's layout (24 bytes a pixel)
            // may need more than DKB spends on a deep frame at a small budget (its records in
            // batches): then it is refused, saying what it needs before any slot.
            let frames: Vec<_> = [Method::Vkb, Method::Dkb, Method::Optimal]
                .into_iter()
                .filter_map(|m| match r.render(m) {
                    Ok(f) => Some(f),
                    Err(e) if m == Method::Optimal => {
                        let m_dkb = r.budget().unwrap();
                        let fixed = opts.layout(m).fixed_bytes(px);
                        assert!(
                            matches!(m_dkb, Budget::Bytes(b) if b < fixed + 8 * px.min(1)),
                            "{name} {budget}: optimal refused at {m_dkb}: {e}"
                        );
                        assert!(e.to_string().contains("before any fragment slot"), "{e}");
                        None
                    }
                    Err(e) => panic!("{name} {budget} {}: {e}", m.name()),
                })
                .collect();
            assert!(frames.len() >= 2, "{name} {budget}");
            let m = frames[0].budget_bytes;
            for f in &frames {
                assert_eq!(
                    f.budget_bytes,
                    m,
                    "{name} {budget} {}: one M",
                    f.method.name()
                );
                assert!(
                    f.allocated_bytes <= m,
                    "{name} {budget} {}",
                    f.method.name()
                );
            }
            if m >= exact {
                // M holds the exact A-buffer: every method renders it, with its bytes.
                for f in &frames {
                    assert_eq!(f.budget_fragments, total, "{name} {budget} {}", f.method);
                    assert_eq!(f.allocated_bytes, exact, "{name} {budget} {}", f.method);
                }
                held += 1;
                continue;
            }
            // M is what DKB's layout reserves for the budget's F (its pool may hold more slots
            // than F in the records' room: F(M) is at least F); every method gets the most
            // slots whose bytes fit M, by its own layout and the frame's occupancy.
            let f_dkb = match Budget::parse(budget).unwrap() {
                Budget::Share(ppm) => dhoit_runtime::budget::share_of(total, ppm),
                Budget::SlotsPerPixel(v) => (v * px as f64) as u64,
                Budget::Bytes(_) => unreachable!(),
            };
            let occ = dhoit_runtime::budget::Occupancy::of(&fl.counts());
            let dkb = opts.layout(Method::Dkb);
            assert_eq!(m, dkb.reserved_bytes(px, f_dkb, &occ), "{name} {budget}: M");
            assert!(
                frames[1].budget_fragments >= f_dkb,
                "{name} {budget}: DKB's F"
            );
            for f in &frames {
                let layout = opts.layout(f.method);
                let fits = |x: u64| layout.reserved_bytes(px, x, &occ) <= m;
                assert!(
                    fits(f.budget_fragments) && !fits(f.budget_fragments + 1),
                    "{name} {budget} {}: the most slots that fit",
                    f.method
                );
            }
            truncated += 1;
        }
    }
    assert!(
        held > 0 && truncated > 0,
        "{held} held, {truncated} truncated"
    );
}

/// Every feature against its definition, computed here in f64 from the fragment lists: on a
/// scene of one opacity and on one whose opacities vary (strands fading to their tips, around
/// an opaque head).
/// At equal bytes M is what DKB spends: where its layout would reserve at least the exact
/// A-buffer's bytes for the budget, DKB renders the A-buffer (by default), so M is the
/// A-buffer's and no other method gets more memory than that (the list and MLAB were given
/// DKB's larger reservation, up to 1.09x the A-buffer's bytes on the eval's frames). Always
/// approximate, M stays the reservation.
#[test]
fn at_equal_bytes_no_method_gets_more_than_dkb_spends() {
    let mlp = Mlp::random(4);
    let fl = frame("cad", (80, 60));
    let (px, total) = (fl.pixel_count() as u64, fl.fragment_count() as u64);
    let exact = dhoit_runtime::budget::ABUFFER.allocated_bytes(px, total);
    let mut above = 0;
    for budget in ["10%", "50%", "90%", "0.5fpp", "1fpp"] {
        let opts = Options {
            weights: Some(&mlp),
            equal: Equal::Bytes,
            ..Options::new(Budget::parse(budget).unwrap(), [1.0; 3])
        };
        let Budget::Bytes(reserved) = Renderer::new(&fl, opts.always_approximate())
            .budget()
            .unwrap()
        else {
            panic!("{budget}: equal bytes gave no memory")
        };
        let r = Renderer::new(&fl, opts);
        let Budget::Bytes(m) = r.budget().unwrap() else {
            panic!("{budget}: equal bytes gave no memory")
        };
        assert_eq!(m, reserved.min(exact), "{budget}");
        if reserved < exact {
            continue;
        }
        above += 1;
        let dkb = r.render(Method::Dkb).unwrap();
        assert!(
            dkb.exact,
            "{budget}: DKB reserving more than the A-buffer renders it"
        );
        assert_eq!(dkb.allocated_bytes, exact, "{budget}");
        for method in [Method::Mlab, Method::LinkedList, Method::Vkb, Method::Wboit] {
            if let Ok(f) = r.render(method) {
                assert!(
                    f.allocated_bytes <= exact,
                    "{budget} {}: {} bytes above the A-buffer's {exact}",
                    method.name(),
                    f.allocated_bytes
                );
            }
        }
    }
    assert!(
        above > 0,
        "no budget where DKB would reserve the A-buffer's bytes or more"
    );
}

/// WBOIT's and MBOIT's memory is their targets whatever the frame's fragments, so a byte budget
/// (one memory for every method) holds them or they do not run: targets above it are refused,
/// naming what they need, rather than running at their own bytes beside methods held to M.
/// By hand, for 80x60 pixels: WBOIT 9 B a pixel (RGBA16F + R8), MBOIT 28, 36, 44 at 4, 6, 8
/// power moments, each with its parameters and MBOIT its 1 KiB absorbance table.
#[test]
fn a_byte_budget_below_the_blended_targets_is_refused() {
    use dhoit_runtime::budget::{PARAMS_BYTES, mboit_moments_within};
    let fl = frame("spheres", (80, 60));
    let px = fl.pixel_count() as u64;
    let wboit = 9 * px + PARAMS_BYTES;
    let mboit = |per_pixel: u64| per_pixel * px + PARAMS_BYTES + 1024;
    let at = |bytes: u64, moments: u32| {
        let opts = Options::new(Budget::Bytes(bytes), [1.0; 3]);
        let opts = Options {
            mboit: dhoit_runtime::composite::MboitParams::with_moments(moments).unwrap(),
            ..opts
        };
        let r = Renderer::new(&fl, opts);
        (r.render(Method::Wboit), r.render(Method::Mboit))
    };
    let (w, _) = at(wboit - 1, 4);
    let e = w
        .expect_err("WBOIT one byte short of its targets ran")
        .to_string();
    assert!(
        e.contains("wboit needs") && e.contains("9 B a pixel)") && !e.contains("moments"),
        "{e}"
    );
    let (w, m) = at(wboit, 4);
    assert_eq!(w.unwrap().allocated_bytes, wboit);
    assert!(m.is_err(), "MBOIT in WBOIT's bytes");
    for (moments, per_pixel) in [(4, 28), (6, 36), (8, 44)] {
        let (_, m) = at(mboit(per_pixel) - 1, moments);
        let e = m.expect_err("MBOIT one byte short ran").to_string();
        assert!(e.contains(&format!("{per_pixel} B a pixel")), "{e}");
        // The moments asked for, and what the fewest would need where they are more.
        let note = match moments {
            4 => " at 4 power moments, the fewest)".to_string(),
            _ => format!(
                " at {moments} power moments; 4 need {})",
                dhoit_runtime::budget::format_bytes(mboit(28))
            ),
        };
        assert!(e.contains(&note), "{e}");
        let (_, m) = at(mboit(per_pixel), moments);
        assert_eq!(
            m.unwrap().allocated_bytes,
            mboit(per_pixel),
            "{moments} moments"
        );
    }
    // At one memory MBOIT takes the most moments that fit it.
    assert_eq!(mboit_moments_within(px, mboit(28) - 1), None);
    assert_eq!(mboit_moments_within(px, mboit(28)), Some(4));
    assert_eq!(mboit_moments_within(px, mboit(44) - 1), Some(6));
    assert_eq!(mboit_moments_within(px, mboit(44)), Some(8));
    // A budget in slots is not a memory: the targets run whatever it is.
    let r = Renderer::new(&fl, Options::new(Budget::SlotsPerPixel(0.01), [1.0; 3]));
    assert_eq!(r.render(Method::Wboit).unwrap().allocated_bytes, wboit);
}

#[test]
fn features_match_their_definitions() {
    for (name, w, h) in [("shells", 40, 30), ("strands", 48, 36)] {
        features_match_on(name, &frame(name, (w, h)));
    }
}

fn features_match_on(name: &str, fl: &FragmentLists) {
    let f_budget = 1234u64;
    let feats = importance::features(fl, f_budget);
    let total = fl.fragment_count() as f64;
    let covered: Vec<usize> = (0..fl.pixel_count()).filter(|&p| fl.count(p) > 0).collect();
    let mean_n = total / covered.len() as f64;
    let close = |a: f32, b: f64, what: &str| {
        assert!(
            (a as f64 - b).abs() <= 1e-5 * (1.0 + b.abs()),
            "{name} {what}: {a} vs {b}"
        );
    };
    let luma = |c: [f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let mut alphas = std::collections::BTreeSet::new();
    for &p in &covered {
        let r = fl.range(p);
        let x = &feats[p];
        let n = r.len() as f64;
        close(x[0], n.log2(), "log2 n");
        close(x[1], n / mean_n, "n / mean n");
        close(x[2], f_budget as f64 / total, "budget share");
        close(
            x[3],
            (f_budget as f64 / covered.len() as f64).log2(),
            "budget per pixel",
        );
        // Colours and opacities as the pipeline stores them (RGBA8), in f64.
        let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5).floor() as f64 / 255.0;
        let rgb = |i: usize| -> [f64; 3] { std::array::from_fn(|c| q(fl.rgba[i][c])) };
        let alpha = |i: usize| q(fl.rgba[i][3]);
        // The nearest fragments: those of the least depth in steps of 1 / 65535 (truncated);
        // their least opacity, the least red of those of that opacity, and their least green,
        // the least blue of those of that green (the two 32-bit words the pass keeps).
        let step = |i: usize| (fl.depth[i].max(0.0) * 65535.0) as u32;
        let front = r.clone().map(step).min().unwrap();
        let tied: Vec<usize> = r.clone().filter(|&i| step(i) == front).collect();
        let q8 = |v: f64| (v * 255.0).round() as u32;
        let (a8, r8) = tied
            .iter()
            .map(|&i| (q8(alpha(i)), q8(rgb(i)[0])))
            .min()
            .unwrap();
        let (g8, b8) = tied
            .iter()
            .map(|&i| (q8(rgb(i)[1]), q8(rgb(i)[2])))
            .min()
            .unwrap();
        assert_eq!(x[4] as f64, front as f64 / 65536.0, "{name} near depth");
        let near = [r8, g8, b8].map(|c| c as f64 / 255.0);
        let mean: [f64; 3] = std::array::from_fn(|c| r.clone().map(|i| rgb(i)[c]).sum::<f64>() / n);
        let var: f64 = r
            .clone()
            .map(|i| (0..3).map(|c| (rgb(i)[c] - mean[c]).powi(2)).sum::<f64>())
            .sum::<f64>()
            / n;
        let dev: f64 = (0..3).map(|c| (near[c] - mean[c]).powi(2)).sum();
        close(x[5], a8 as f64 / 255.0, "nearest opacity");
        close(
            x[6],
            (var + importance::LOG_FLOOR as f64).log2(),
            "log2 var",
        );
        close(
            x[7],
            (dev + importance::LOG_FLOOR as f64).log2(),
            "log2 dev",
        );
        close(x[8], r.clone().map(alpha).sum::<f64>() / n, "mean opacity");
        close(x[9], luma(mean), "mean luma");
        close(x[10], luma(near), "near luma");
        // Optical depth sum -ln(1 - a), an opaque fragment's as a = 254.5 / 255; the pass sums
        // it in 1/256 units rounded per fragment (at most half a unit off each).
        let tau: f64 = r
            .clone()
            .map(|i| -(1.0 - alpha(i).min(254.5 / 255.0)).ln())
            .sum();
        let unit = importance::OPTICAL_DEPTH_UNIT as f64;
        let got = 2f64.powf(x[11] as f64) - unit;
        assert!(
            (got - tau).abs() <= 0.5 * unit * n + 1e-5 * tau,
            "{name} optical depth: {got} vs {tau}"
        );
        for i in r {
            alphas.insert((alpha(i) * 255.0).round() as u32);
        }
    }
    if name == "strands" {
        assert!(
            alphas.len() > 50,
            "{name}: opacities vary ({} values)",
            alphas.len()
        );
    }
}

#[test]
fn vkb_importance_follows_its_factors() {
    let fl = frame("particles", (64, 48));
    let quiet = VkbParams {
        noise: 0.0,
        ..VkbParams::default()
    };
    // Each factor against paper 002's formulas, computed by hand on a 4x4 frame (alpha 0.35,
    // periphery exponent 3, no noise): I = (1 - r^3) (1 - (1 - |n.e|)^5 / 2) (alpha +
    // (1 - alpha) n / max n), r the distance from the centre over half the diagonal.
    let mut counts = vec![1u32; 16];
    let mut facing = vec![1.0f32; 16];
    counts[5] = 2; // (1, 1): r = 0.25
    facing[5] = 0.5;
    counts[6] = 8; // (2, 1): r = 0.25, the deepest pixel
    counts[0] = 8; // (0, 0): r = 0.75
    facing[0] = 0.0;
    counts[15] = 0; // empty
    let by_hand = importance::vkb_importance_from(&counts, &facing, (4, 4), &quiet);
    let expect = [
        (5, 0.984375 * 0.984375 * 0.5125),
        (6, 0.984375),
        (0, 0.2890625),
        (15, 0.0),
    ];
    for (p, want) in expect {
        assert!(
            (by_hand[p] as f64 - want).abs() < 1e-6,
            "pixel {p}: {} against {want} by hand",
            by_hand[p]
        );
    }
    let imp = importance::vkb_importance(&fl, &quiet);
    assert_eq!(imp.len(), fl.pixel_count());
    for (p, &i) in imp.iter().enumerate() {
        if fl.count(p) == 0 {
            assert_eq!(i, 0.0);
        } else {
            assert!(i > 0.0 && i <= 1.0, "{i}");
        }
    }
    // The noise term moves importance by at most lambda / 2.
    let noisy = importance::vkb_importance(&fl, &VkbParams::default());
    let diff = imp
        .iter()
        .zip(&noisy)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(
        diff > 0.0 && diff <= 0.05 + 1e-6,
        "noise within lambda / 2: {diff}"
    );
    // Deterministic, and the noise hash spreads over [0, 1).
    assert_eq!(
        noisy,
        importance::vkb_importance(&fl, &VkbParams::default())
    );
    let xs: Vec<f32> = (0..10_000).map(|p| importance::pixel_noise(p, 0)).collect();
    let mean = xs.iter().sum::<f32>() / xs.len() as f32;
    assert!((mean - 0.5).abs() < 0.02 && xs.iter().all(|x| (0.0..1.0).contains(x)));
}

#[test]
fn dkb_without_weights_is_a_clear_error() {
    let fl = frame("shells", (16, 12));
    let e = Renderer::new(&fl, Options::new(Budget::SlotsPerPixel(2.0), [1.0; 3]))
        .render(Method::Dkb)
        .unwrap_err();
    assert!(e.to_string().contains("weights"), "{e}");
}

/// `render` is `allocate` then `composite`; what the GPU path asks of the CPU has the same
/// budget and F, with k left to the device for VKB and DKB and computed for everything else.
#[test]
fn the_gpu_path_gets_the_cpus_budget_without_its_composite() {
    let fl = frame("foliage", (64, 48));
    let mlp = Mlp::random(3);
    for budget in ["1.5fpp", "30%", "40KiB"] {
        let options = Options {
            weights: Some(&mlp),
            ..Options::new(Budget::parse(budget).unwrap(), [1.0; 3]).always_approximate()
        };
        let r = Renderer::new(&fl, options);
        for m in Method::ALL {
            let (Ok(full), Ok(gpu)) = (r.allocate(m), r.allocate_for_gpu(m)) else {
                // FKB and MLAB refuse a budget without a slot a pixel, both ways alike.
                assert!(r.allocate(m).is_err() && r.allocate_for_gpu(m).is_err());
                continue;
            };
            assert_eq!(gpu.budget_fragments, full.budget_fragments, "{m} {budget}");
            assert_eq!(gpu.budget_bytes, full.budget_bytes, "{m} {budget}");
            // A share at equal F stays a share for the device to resolve from its own count;
            // at equal bytes (and for bytes or slots a pixel) the device gets the CPU's F.
            let want = match Budget::parse(budget).unwrap() {
                Budget::Share(ppm) => FragmentBudget::Share(ppm),
                _ => FragmentBudget::Slots(full.budget_fragments),
            };
            assert_eq!(gpu.fragment_budget, want, "{m} {budget}");
            let eq = Renderer::new(
                &fl,
                Options {
                    equal: Equal::Bytes,
                    ..options
                },
            );
            if let Ok(a) = eq.allocate_for_gpu(m) {
                assert_eq!(a.fragment_budget, FragmentBudget::Slots(a.budget_fragments));
            }
            if matches!(m, Method::Vkb | Method::Dkb) {
                assert!(gpu.k.is_empty(), "{m}: k is the device's to compute");
            } else {
                assert_eq!(gpu.k, full.k, "{m} {budget}");
            }
            let rendered = r.render(m).unwrap();
            let composed = r.composite(full);
            assert_eq!(rendered.image, composed.image, "{m} {budget}");
            assert_eq!(rendered.k, composed.k);
        }
    }
}

/// A wrong importance-to-k mapping shared by the twin and the WGSL would pass every
/// equivalence test: held to a quality ordering instead. On held-out frames (the built-ins'
/// plain names are seed 1, which no training saw) with the committed weights, at equal F: the
/// optimal allocation is at most FKB's error and its optimum for pooled tails
/// (`ErrorCurves::pooled`, what VKB and DKB store) at most theirs, DKB and VKB beat FKB's one
/// k for every pixel, and DKB stays within a band of its measured distance from the pooled
/// optimum (1.5x the ratio measured with these weights) and of VKB on `particles` at 1 fpp.
/// With the network's requests inverted (`1 - r`, `alloc::slot_request`) the ordering alone
/// still held, as the caps decide much of the allocation; the bands do not (hair 1 fpp: DKB
/// over the pooled optimum 84 against 32; particles: DKB/VKB 0.65 against 0.50).
#[test]
fn on_held_out_frames_the_allocations_keep_their_quality_order() {
    let weights =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/weights.safetensors");
    let mlp = Mlp::load(&weights).unwrap();
    // (scene, budget, DKB over the pooled optimum measured, the most DKB/VKB may be)
    for (name, budget, dkb_opt, dkb_vkb) in [
        ("particles", Budget::SlotsPerPixel(1.0), 2.53, 0.7),
        ("hair", Budget::SlotsPerPixel(1.0), 31.7, 1.0),
        ("foliage", Budget::SlotsPerPixel(2.0), 4.35, 1.0),
        ("particles", Budget::SlotsPerPixel(2.0), 2.46, 1.0),
    ] {
        let s = scene::load(name, Opacity::default()).unwrap();
        let size = (96, 72);
        let fl = rasterize(&s, &Camera::orbit(&s, 1, scene::DEFAULT_VIEWS, size), size).unwrap();
        let opts = Options {
            weights: Some(&mlp),
            ..Options::new(budget, [0.2, 0.3, 0.4]).always_approximate()
        };
        let r = Renderer::new(&fl, opts);
        let exact = r.render(Method::Abuffer).unwrap().image;
        let mse = |m: Method| r.render(m).unwrap().image.mse(&exact);
        let [plain, dkb, vkb, fkb] =
            [Method::Optimal, Method::Dkb, Method::Vkb, Method::Fkb].map(mse);
        // The optimum with pooled tails, by hand: the optimal k of the pooled curves, stored.
        let f = r.allocate(Method::Dkb).unwrap().budget_fragments;
        let (k, _) = dhoit_runtime::alloc::optimal(&r.curves().pooled(), f);
        let stored = dhoit_runtime::shared::stored(&k, &fl.counts());
        let opt = dhoit_runtime::composite::composite(
            &fl,
            dhoit_runtime::composite::Method::Hybrid(&stored),
            [0.2, 0.3, 0.4],
        )
        .mse(&exact);
        // The method that renders it (what compare and make eval score against) is this.
        let method = r.render(Method::OptimalPooled).unwrap();
        assert_eq!(method.k, stored, "{name} {budget}: optimal-pooled's k");
        assert_eq!(
            method.image.mse(&exact),
            opt,
            "{name} {budget}: optimal-pooled's image"
        );
        eprintln!(
            "{name} {budget}: optimal {plain:.3e}, pooled {opt:.3e}; dkb {dkb:.3e} vkb {vkb:.3e} \
             fkb {fkb:.3e}"
        );
        assert!(
            plain <= fkb && opt <= plain && opt <= dkb && opt <= vkb,
            "{name} {budget}: optimal {plain}, pooled {opt} not the least"
        );
        assert!(
            dkb < fkb && vkb < fkb,
            "{name} {budget}: DKB {dkb}, VKB {vkb} against FKB {fkb}"
        );
        assert!(
            dkb <= 1.5 * dkb_opt * opt,
            "{name} {budget}: DKB/pooled optimum {} (measured {dkb_opt})",
            dkb / opt
        );
        assert!(
            dkb <= dkb_vkb * vkb,
            "{name} {budget}: DKB/VKB {} above {dkb_vkb}",
            dkb / vkb
        );
    }
}
