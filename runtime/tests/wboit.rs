//! Weighted blended OIT (McGuire and Bavoil 2013) beside the other methods: its formula by hand,
//! the GPU held to the CPU twin, no dependence on submission order, exact for one fragment and
//! wrong where opacity is high. The GPU tests need an adapter (lavapipe in CI);
//! DHOIT_SKIP_GPU=1 skips them explicitly.

mod common;

use common::{gpu, identity, layer};
use dhoit_runtime::composite::{self, Image};
use dhoit_runtime::fragment::Fragment;
use dhoit_runtime::frame::Method;
use dhoit_runtime::gpu::Slots;
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::Scene;

const BG: [f32; 3] = [0.9, 0.85, 0.8];

fn render(fl: &dhoit_runtime::fragment::FragmentLists, m: Method) -> Image {
    common::render_one_fpp(fl, m, BG)
}

#[test]
fn wboit_is_the_papers_formula() {
    // Two fragments by hand (f64), in either order: w = a max(1e-2, 3e3 (1 - z)^3),
    // C = sum(C a w) / sum(a w) (1 - R) + R C_bg, R = prod(1 - a).
    let frags = [
        Fragment {
            depth: 0.25,
            rgba: [1.0, 0.2, 0.0, 0.6],
            primitive: 0,
        },
        Fragment {
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
        let got = composite::wboit_sorted(&order.map(|i| frags[i]), BG);
        for i in 0..3 {
            assert!(
                (got[i] as f64 - want[i]).abs() < 1e-6,
                "{order:?}: {got:?} {want:?}"
            );
        }
    }
    // The weight at the near and far planes.
    assert!((composite::wboit_weight(0.0, 0.5) - 1500.0).abs() < 1e-3);
    assert!((composite::wboit_weight(1.0, 0.5) - 0.005).abs() < 1e-9);
    // Nothing: the background.
    assert_eq!(composite::wboit_sorted(&[], BG), BG);
}

/// One fragment a pixel: WBOIT is exact. Several: the GPU's image is the CPU twin's (on the
/// GPU's own fragments), bit for bit the same under any submission order, and far from exact
/// where near opaque surfaces lie close in depth, close where they are faint.
#[test]
fn wboit_on_the_gpu_is_its_twin_order_free_and_wrong_where_opacity_is_high() {
    let Some(g) = gpu() else { return };
    let cam = identity();
    let (w, h) = (32, 24);
    let mut one = Scene::default();
    layer(&mut one, 0.4, [0.2, 0.6, 0.9, 0.7]);
    let fl = rasterize(&one, &cam, w, h).unwrap();
    let d = render(&fl, Method::Wboit).max_abs_diff(&render(&fl, Method::Abuffer));
    assert!(d < 1e-6, "one fragment: {d}");
    let mut errors = Vec::new();
    // A red surface just in front of a blue one, both near opaque, then both faint: their
    // weights barely differ, so WBOIT averages them where the near one should hide the other.
    for near_alpha in [0.95, 0.1] {
        let mut s = Scene::default();
        layer(&mut s, 0.5, [1.0, 0.0, 0.0, near_alpha]);
        layer(&mut s, 0.52, [0.0, 0.3, 1.0, near_alpha]);
        layer(&mut s, 0.7, [0.1, 0.9, 0.2, 0.2]);
        let fl = rasterize(&s, &cam, w, h).unwrap();
        let gpu = |scene: &Scene| g.render(scene, &cam, w, h, BG, Some(Slots::Wboit)).unwrap();
        let frame = gpu(&s);
        let own = frame
            .fragments
            .as_ref()
            .expect("diagnostics read the fragments back");
        let twin = composite::composite(own, composite::Method::Wboit, BG);
        let diff = frame.image.max_abs_diff(&twin);
        assert!(
            diff <= 1e-5,
            "alpha {near_alpha}: GPU and twin differ by {diff}"
        );
        for seed in [1, 2] {
            assert!(
                gpu(&s.shuffled(seed)).image == frame.image,
                "alpha {near_alpha}: shuffle {seed}"
            );
            let shuffled = rasterize(&s.shuffled(seed), &cam, w, h).unwrap();
            assert!(render(&shuffled, Method::Wboit) == render(&fl, Method::Wboit));
        }
        errors.push(render(&fl, Method::Wboit).mse(&render(&fl, Method::Abuffer)));
    }
    eprintln!(
        "WBOIT MSE: both surfaces at 0.95 {:e}, both at 0.1 {:e}",
        errors[0], errors[1]
    );
    assert!(errors[0] > 100.0 * errors[1], "{errors:?}");
}
