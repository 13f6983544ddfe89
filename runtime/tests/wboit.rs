//! Weighted blended OIT (McGuire and Bavoil 2013) beside the other methods: its formula by hand,
//! the GPU held to the CPU twin, no dependence on submission order, exact for one fragment and
//! wrong where opacity is high. The GPU tests need an adapter (lavapipe in CI);
//! DHOIT_SKIP_GPU=1 skips them explicitly.

mod common;

use common::{gpu, identity, layer};
use dhoit_runtime::budget::{self, Budget};
use dhoit_runtime::composite::{self, Image, WboitParams, WboitWeight};
use dhoit_runtime::fragment::Fragment;
use dhoit_runtime::frame::{self, Method, Options};
use dhoit_runtime::gpu::Slots;
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::Scene;

const BG: [f32; 3] = [0.9, 0.85, 0.8];
/// The default weight function, eq. 10 (of the window depth: no planes).
const EQ10: WboitParams = WboitParams {
    weight: WboitWeight::Eq10,
    near: 0.0,
    far: 0.0,
};

fn render(fl: &dhoit_runtime::fragment::FragmentLists, m: Method) -> Image {
    common::render_one_fpp(fl, m, BG)
}

#[test]
fn wboit_is_the_papers_formula() {
    // Two fragments by hand (f64), in either order: w = a max(1e-2, 3e3 (1 - z)^3),
    // C = sum(C a w) / sum(a w) (1 - R) + R C_bg, R = prod(1 - a).
    let frags = [
        Fragment {
            tint: dhoit_runtime::fragment::CLEAR,
            depth: 0.25,
            rgba: [1.0, 0.2, 0.0, 0.6],
            primitive: 0,
        },
        Fragment {
            tint: dhoit_runtime::fragment::CLEAR,
            depth: 0.5,
            rgba: [0.0, 0.4, 1.0, 0.3],
            primitive: 1,
        },
    ];
    let w = |f: &Fragment| {
        let d = 1.0 - f.depth as f64;
        f.rgba[3] as f64 * (3e3 * d * d * d).max(1e-2)
    };
    let (w0, w1) = (w(&frags[0]), w(&frags[1]));
    let (a0, a1) = (frags[0].rgba[3] as f64, frags[1].rgba[3] as f64);
    let reveal = (1.0 - a0) * (1.0 - a1);
    let want: Vec<f64> = (0..3)
        .map(|i| {
            let acc = frags[0].rgba[i] as f64 * a0 * w0 + frags[1].rgba[i] as f64 * a1 * w1;
            acc / (a0 * w0 + a1 * w1) * (1.0 - reveal) + reveal * BG[i] as f64
        })
        .collect();
    for order in [[0, 1], [1, 0]] {
        let got = composite::wboit_sorted(&order.map(|i| frags[i]), BG, &EQ10);
        for i in 0..3 {
            assert!(
                (got[i] as f64 - want[i]).abs() < 1e-6,
                "{order:?}: {got:?} {want:?}"
            );
        }
    }
    // The weight at the near and far planes.
    assert!((composite::wboit_weight(&EQ10, 0.0, 0.5) - 1500.0).abs() < 1e-3);
    assert!((composite::wboit_weight(&EQ10, 1.0, 0.5) - 0.005).abs() < 1e-9);
    // Nothing: the background.
    assert_eq!(composite::wboit_sorted(&[], BG, &EQ10), BG);
}

/// One fragment a pixel: WBOIT is exact (to its binary16 accumulation). Several: the GPU's image (an RGBA16F accumulation and
/// an R8 revealage, as engines lay WBOIT out) is the CPU twin's at those targets' precision (on
/// the GPU's own fragments), in every submission order; the order moves it only by the targets'
/// rounding; and it is far from exact where near opaque surfaces lie close in depth, close
/// where they are faint.
#[test]
fn wboit_on_the_gpu_is_its_twin_in_every_order_and_wrong_where_opacity_is_high() {
    let Some(g) = gpu() else { return };
    let cam = identity();
    let (w, h) = (32, 24);
    let mut one = Scene::default();
    layer(&mut one, 0.4, [0.2, 0.6, 0.9, 0.7]);
    let fl = rasterize(&one, &cam, (w, h)).unwrap();
    // Exact but for the binary16 accumulation's rounding of C a w and a w (2^-11 each).
    let d = render(&fl, Method::Wboit).max_abs_diff(&render(&fl, Method::Abuffer));
    assert!(d < 1e-3, "one fragment: {d}");
    let mut errors = Vec::new();
    let mut moved = 0.0f32;
    // A red surface just in front of a blue one, both near opaque, then both faint: their
    // weights barely differ, so WBOIT averages them where the near one should hide the other.
    for near_alpha in [0.95, 0.1] {
        let mut s = Scene::default();
        layer(&mut s, 0.5, [1.0, 0.0, 0.0, near_alpha]);
        layer(&mut s, 0.52, [0.0, 0.3, 1.0, near_alpha]);
        layer(&mut s, 0.7, [0.1, 0.9, 0.2, 0.2]);
        let gpu = |scene: &Scene| {
            g.render(scene, &cam, (w, h), BG, Slots::Wboit(EQ10))
                .unwrap()
        };
        let twin = |scene: &Scene| {
            let own = common::own_fragments(g, scene, &cam, (w, h), BG);
            composite::composite(&own, composite::Method::Wboit(EQ10), BG)
        };
        let fl = rasterize(&s, &cam, (w, h)).unwrap();
        let bound = common::BLENDED_BOUND;
        let frame = gpu(&s);
        // Its memory is its own targets', as its layout table counts them, on both sides.
        let layout_bytes = budget::WBOIT.allocated_bytes(fl.pixel_count() as u64, 0);
        assert_eq!(frame.allocated_bytes, layout_bytes, "GPU bytes");
        let cpu = frame::render(
            &fl,
            Method::Wboit,
            Options::new(Budget::SlotsPerPixel(1.0), BG),
        );
        assert_eq!(cpu.unwrap().allocated_bytes, layout_bytes, "CPU bytes");
        let diff = frame.image.max_abs_diff(&twin(&s));
        eprintln!("alpha {near_alpha}: GPU and twin differ by {diff:e}");
        assert!(
            diff <= bound,
            "alpha {near_alpha}: GPU and twin differ by {diff}"
        );
        for seed in [1, 2] {
            let shuffled = s.shuffled(seed);
            let image = gpu(&shuffled).image;
            let diff = image.max_abs_diff(&twin(&shuffled));
            assert!(diff <= bound, "alpha {near_alpha}, shuffle {seed}: {diff}");
            let d = image.max_abs_diff(&frame.image);
            assert!(d <= ORDER_BOUND, "alpha {near_alpha}, shuffle {seed}: {d}");
            moved = moved.max(d);
        }
        errors.push(render(&fl, Method::Wboit).mse(&render(&fl, Method::Abuffer)));
    }
    eprintln!(
        "WBOIT MSE: both surfaces at 0.95 {:e}, both at 0.1 {:e}; a submission order moves a \
         pixel by up to {moved:e}",
        errors[0], errors[1]
    );
    assert!(errors[0] > 100.0 * errors[1], "{errors:?}");
}

/// The most a submission order moves a WBOIT pixel of three layers: the accumulation's binary16
/// steps and the revealage's 1/255 ones.
const ORDER_BOUND: f32 = 1e-2;

/// WBOIT's targets' precision, against the paper's formula in exact sums: the twin at binary16
/// and 8 bits stays within a few of their steps, and the 8-bit revealage is a product rounded
/// after each fragment (by hand: 255 -> 64 -> 16 for two fragments of opacity 191/255).
#[test]
fn wboit_blended_is_the_formula_at_its_targets_precision() {
    let f = |depth: f32, rgba: [f32; 4], primitive| Fragment {
        tint: dhoit_runtime::fragment::CLEAR,
        depth,
        rgba,
        primitive,
    };
    let frags = [
        f(0.3, [1.0, 0.2, 0.0, 0.6], 1),
        f(0.5, [0.0, 0.4, 1.0, 0.3], 0),
        f(0.9, [0.2, 0.9, 0.4, 0.5], 2),
    ];
    let exact = composite::wboit_sorted(&frags, BG, &EQ10);
    let blended = composite::wboit_blended(&frags, BG, &EQ10);
    for i in 0..3 {
        assert!(
            (exact[i] - blended[i]).abs() < 1e-2,
            "{exact:?} {blended:?}"
        );
    }
    // Revealage by hand: 255 (1 - 191/255) = 64, 64 (1 - 191/255) = 16.06 -> 16.
    let a = 191.0 / 255.0;
    let two = [f(0.5, [1.0, 1.0, 1.0, a], 0), f(0.6, [1.0, 1.0, 1.0, a], 1)];
    let got = composite::wboit_blended(&two, [0.0; 3], &EQ10);
    // White over black: C = (1 - R), R = 16/255.
    assert!((got[0] - (1.0 - 16.0 / 255.0)).abs() < 1e-6, "{got:?}");
    let exact = composite::wboit_sorted(&two, [0.0; 3], &EQ10);
    assert!((exact[0] - (1.0 - (1.0 - a) * (1.0 - a))).abs() < 1e-6);
    assert!(got != exact);
}

/// The paper's four weight functions by hand (f64), at view-space distances the window depths
/// of `scene::perspective_rh` give: the depth a projected point gets is turned back into its
/// distance (held to the projection matrix, outside both twins), and each function's value
/// there is the paper's formula, clamped to [10^-2, 3 10^3]. A function of the distance without
/// the camera's planes is refused.
#[test]
fn wboit_weights_are_the_papers_equations_of_the_distance_or_the_depth() {
    use dhoit_runtime::scene::perspective_rh;
    let (near, far) = (0.5f32, 800.0f32);
    let proj = perspective_rh(1.0, 1.5, near, far);
    for t in [0.5f32, 1.0, 4.0, 12.0, 75.0, 250.0, 799.0] {
        let clip = proj * glam::Vec4::new(0.3, -0.2, -t, 1.0);
        let d = clip.z / clip.w;
        let a = 0.4f64;
        for weight in WboitWeight::ALL {
            let p = WboitParams { weight, near, far };
            let z = p.view_distance(d);
            assert!((z - t).abs() <= 2e-3 * t, "distance {t}: {z} at depth {d}");
            let z = t as f64;
            let by_hand = a * match weight {
                WboitWeight::Eq7 => 10.0 / (1e-5 + (z / 5.0).powi(2) + (z / 200.0).powi(6)),
                WboitWeight::Eq8 => 10.0 / (1e-5 + (z / 10.0).powi(3) + (z / 200.0).powi(6)),
                WboitWeight::Eq9 => 0.03 / (1e-5 + (z / 200.0).powi(4)),
                WboitWeight::Eq10 => 3e3 * (1.0 - d as f64).powi(3),
            }
            .clamp(1e-2, 3e3);
            let got = composite::wboit_weight(&p, d, a as f32) as f64;
            assert!(
                (got - by_hand).abs() <= 5e-3 * by_hand,
                "{} at distance {t}: {got} against {by_hand}",
                weight.name()
            );
        }
    }
    // Eq. 7 weighs a near surface 3000 times a far one here; eq. 10 by the window depth.
    let p7 = WboitParams {
        weight: WboitWeight::Eq7,
        near,
        far,
    };
    let w = |p: &WboitParams, d| composite::wboit_weight(p, d, 1.0);
    assert!(w(&p7, 0.0) > 1e3 * w(&p7, 0.999));
    for weight in [WboitWeight::Eq7, WboitWeight::Eq8, WboitWeight::Eq9] {
        let e = WboitParams {
            weight,
            near: 0.0,
            far: 0.0,
        }
        .check()
        .unwrap_err();
        assert!(e.to_string().contains("near"), "{e}");
        assert_eq!(WboitWeight::parse(weight.name()).unwrap(), weight);
    }
    assert!(EQ10.check().is_ok());
    assert!(WboitWeight::parse("eq11").is_err());
}

/// Each weight function on the GPU is its twin's (wboit_accumulate.wgsl's `weight` against
/// `composite::wboit_weight`, on the GPU's own fragments), and they weigh differently: the
/// images of eqs. 7 and 10 differ where surfaces overlap. (WBOIT divides by the sum of the
/// weights, so a factor common to a pixel's weights never shows: the constants are held by the
/// test by hand above, their shape here.) A weight of the distance without the camera's planes
/// is refused on both.
#[test]
fn every_wboit_weight_function_renders_its_twin_on_the_gpu() {
    let Some(g) = gpu() else { return };
    let cam = identity();
    let size = (32, 24);
    let mut s = Scene::default();
    layer(&mut s, 0.3, [1.0, 0.0, 0.0, 0.6]);
    layer(&mut s, 0.5, [0.0, 0.3, 1.0, 0.6]);
    layer(&mut s, 0.9, [0.1, 0.9, 0.2, 0.5]);
    let own = common::own_fragments(g, &s, &cam, size, BG);
    let mut images = Vec::new();
    for weight in WboitWeight::ALL {
        // The identity camera has no planes: these stand for a camera's (window depths 0.3 to
        // 0.9 at distances 1.4 to 9.9).
        let p = WboitParams {
            weight,
            near: 1.0,
            far: 1000.0,
        };
        let frame = g.render(&s, &cam, size, BG, Slots::Wboit(p)).unwrap();
        let twin = composite::composite(&own, composite::Method::Wboit(p), BG);
        let diff = frame.image.max_abs_diff(&twin);
        eprintln!("{}: GPU and twin differ by {diff:e}", weight.name());
        assert!(diff <= common::BLENDED_BOUND, "{}: {diff}", weight.name());
        images.push(frame.image);
    }
    let d = images[0].max_abs_diff(&images[3]);
    assert!(d > 0.05, "eqs. 7 and 10 render alike: {d}");
    let bad = WboitParams {
        weight: WboitWeight::Eq7,
        near: 0.0,
        far: 0.0,
    };
    assert!(g.render(&s, &cam, size, BG, Slots::Wboit(bad)).is_err());
    let fl = rasterize(&s, &cam, size).unwrap();
    let opts = Options {
        wboit: bad,
        ..Options::new(Budget::SlotsPerPixel(1.0), BG)
    };
    assert!(frame::render(&fl, Method::Wboit, opts).is_err());
}
