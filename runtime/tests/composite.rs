//! Property tests of exact, hybrid and MLAB compositing on single pixels.

use dhoit_runtime::composite::{exact_pixel, hybrid_pixel, mlab_pixel};
use dhoit_runtime::fragment::Fragment;
use proptest::prelude::*;

/// A channel as the pipeline stores it: 8 bits.
fn unorm8() -> impl Strategy<Value = f32> {
    (0u32..=255).prop_map(|v| v as f32 / 255.0)
}

fn fragment() -> impl Strategy<Value = Fragment> {
    (0.0f32..=1.0, prop::array::uniform4(unorm8()), any::<u32>()).prop_map(
        |(depth, rgba, primitive)| Fragment {
            tint: dhoit_runtime::fragment::CLEAR,
            depth,
            rgba,
            primitive,
        },
    )
}

fn fragments(max: usize) -> impl Strategy<Value = Vec<Fragment>> {
    prop::collection::vec(fragment(), 0..max)
}

fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
}

fn finite_unit(c: [f32; 3]) -> bool {
    c.iter()
        .all(|v| v.is_finite() && (-1e-5..=1.0 + 1e-5).contains(v))
}

const BG: [f32; 3] = [0.2, 0.5, 0.9];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn hybrid_with_all_fragments_in_the_core_is_exact(f in fragments(64)) {
        let n = f.len();
        prop_assert_eq!(hybrid_pixel(&f, n, BG), exact_pixel(&f, BG));
        // A k larger than n is clamped to n.
        prop_assert_eq!(hybrid_pixel(&f, n + 5, BG), exact_pixel(&f, BG));
    }

    #[test]
    fn one_colour_one_opacity_is_exact_for_every_k(
        n in 1usize..300, rgb in prop::array::uniform3(unorm8()), a in unorm8(),
        depths in prop::collection::vec(0.0f32..=1.0, 300),
    ) {
        let f: Vec<Fragment> = (0..n)
            .map(|i| Fragment { tint: dhoit_runtime::fragment::CLEAR, depth: depths[i], rgba: [rgb[0], rgb[1], rgb[2], a], primitive: i as u32 })
            .collect();
        let exact = exact_pixel(&f, BG);
        for k in 0..=n {
            let h = hybrid_pixel(&f, k, BG);
            prop_assert!(close(h, exact, 2e-5), "k = {k}: hybrid {h:?} exact {exact:?}");
        }
    }

    #[test]
    fn exact_does_not_depend_on_input_order(f in fragments(64), seed in any::<u64>()) {
        let mut g = f.clone();
        let perm = dhoit_runtime::rng::Rng::new(seed).permutation(g.len());
        g = perm.iter().map(|&i| f[i]).collect();
        let (a, b) = (exact_pixel(&f, BG), exact_pixel(&g, BG));
        prop_assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits));
    }

    /// Ties on purpose: depths from a few values, -0.0 and 0.0 among them (-0 counts as 0),
    /// colours from a few, primitives from a few, so that fragments share a depth, a whole key,
    /// or everything; the exact and every hybrid composite stay the same bits in any order.
    #[test]
    fn composites_do_not_depend_on_input_order_even_with_ties(
        f in prop::collection::vec(
            (
                prop::sample::select(vec![0.0f32, -0.0, 0.25, 0.5, 1.0]),
                prop::sample::select(vec![[1.0f32, 0.0, 0.0, 0.5], [0.0, 1.0, 0.0, 0.5], [0.2, 0.2, 0.2, 1.0]]),
                0u32..3,
            )
                .prop_map(|(depth, rgba, primitive)| Fragment { tint: dhoit_runtime::fragment::CLEAR, depth, rgba, primitive }),
            0..24,
        ),
        seed in any::<u64>(),
    ) {
        let perm = dhoit_runtime::rng::Rng::new(seed).permutation(f.len());
        let g: Vec<Fragment> = perm.iter().map(|&i| f[i]).collect();
        prop_assert_eq!(exact_pixel(&f, BG).map(f32::to_bits), exact_pixel(&g, BG).map(f32::to_bits));
        for k in 0..=f.len() {
            prop_assert_eq!(
                hybrid_pixel(&f, k, BG).map(f32::to_bits),
                hybrid_pixel(&g, k, BG).map(f32::to_bits),
                "k = {}", k
            );
        }
        // -0.0 is the nearest depth, as 0.0 is (not the farthest, as its bits would order it).
        let zeroed: Vec<Fragment> = f
            .iter()
            .map(|x| Fragment { depth: if x.depth == 0.0 { 0.0 } else { x.depth }, ..*x })
            .collect();
        prop_assert_eq!(exact_pixel(&f, BG).map(f32::to_bits), exact_pixel(&zeroed, BG).map(f32::to_bits));
    }

    #[test]
    fn mlab_with_enough_rows_is_exact(f in fragments(24), extra in 0usize..4) {
        let m = f.len().max(1) + extra;
        let (a, b) = (mlab_pixel(&f, m, BG), exact_pixel(&f, BG));
        prop_assert!(close(a, b, 1e-5), "mlab {a:?} exact {b:?}");
    }

    #[test]
    fn mlab_rows_past_the_fragments_change_nothing(f in fragments(24), extra in 1usize..4) {
        let m = f.len().max(1);
        let a = mlab_pixel(&f, m, BG).map(f32::to_bits);
        prop_assert_eq!(a, mlab_pixel(&f, m + extra, BG).map(f32::to_bits));
        // A budget of gigabytes: as many rows as slots, taken as the fragments.
        prop_assert_eq!(a, mlab_pixel(&f, usize::MAX / 2, BG).map(f32::to_bits));
    }

    #[test]
    fn every_method_stays_finite_at_the_extremes(
        n in 0usize..3000,
        alphas in prop::collection::vec(prop::sample::select(vec![0.0f32, 1e-7, 1.0, 0.5, 1.0 - 1e-7, 1.0 / 255.0]), 3000),
        equal_depths in any::<bool>(), k in 0usize..3000, m in 1usize..8,
    ) {
        let f: Vec<Fragment> = (0..n)
            .map(|i| Fragment { tint: dhoit_runtime::fragment::CLEAR,
                depth: if equal_depths { 0.5 } else { (i % 97) as f32 / 97.0 },
                rgba: [(i % 3) as f32 / 2.0, 0.3, 1.0, alphas[i]],
                primitive: i as u32,
            })
            .collect();
        prop_assert!(finite_unit(exact_pixel(&f, BG)));
        prop_assert!(finite_unit(hybrid_pixel(&f, k, BG)));
        prop_assert!(finite_unit(mlab_pixel(&f, m, BG)));
    }
}

#[test]
fn empty_and_zero_opacity_tails_show_the_background() {
    assert_eq!(hybrid_pixel(&[], 0, BG), BG);
    let clear = Fragment {
        tint: dhoit_runtime::fragment::CLEAR,
        depth: 0.3,
        rgba: [1.0, 0.0, 0.0, 0.0],
        primitive: 0,
    };
    assert_eq!(hybrid_pixel(&[clear; 5], 0, BG), BG);
    assert_eq!(hybrid_pixel(&[clear; 5], 2, BG), BG);
    assert_eq!(mlab_pixel(&[clear; 5], 1, BG), BG);
}

#[test]
fn an_opaque_front_fragment_hides_everything_behind() {
    let f = [
        Fragment {
            tint: dhoit_runtime::fragment::CLEAR,
            depth: 0.9,
            rgba: [0.0, 1.0, 0.0, 0.5],
            primitive: 0,
        },
        Fragment {
            tint: dhoit_runtime::fragment::CLEAR,
            depth: 0.1,
            rgba: [1.0, 0.0, 0.0, 1.0],
            primitive: 1,
        },
        Fragment {
            tint: dhoit_runtime::fragment::CLEAR,
            depth: 0.5,
            rgba: [0.0, 0.0, 1.0, 0.7],
            primitive: 2,
        },
    ];
    assert_eq!(exact_pixel(&f, BG), [1.0, 0.0, 0.0]);
    for k in 1..=3 {
        assert_eq!(hybrid_pixel(&f, k, BG), [1.0, 0.0, 0.0]);
    }
    assert_eq!(mlab_pixel(&f, 1, BG), [1.0, 0.0, 0.0]);
}

#[test]
fn two_layer_exact_value_by_hand() {
    // Front red at 0.4 over back blue at 0.4 over black (0.4 = 102/255, exact in 8 bits):
    // 0.4 red + 0.6 x 0.4 = 0.24 blue.
    let f = [
        Fragment {
            tint: dhoit_runtime::fragment::CLEAR,
            depth: 0.8,
            rgba: [0.0, 0.0, 1.0, 0.4],
            primitive: 0,
        },
        Fragment {
            tint: dhoit_runtime::fragment::CLEAR,
            depth: 0.2,
            rgba: [1.0, 0.0, 0.0, 0.4],
            primitive: 1,
        },
    ];
    assert!(close(exact_pixel(&f, [0.0; 3]), [0.4, 0.0, 0.24], 1e-6));
    // With k = 0 the tail averages the colours: C_tail = (0.5, 0, 0.5), a_tail = 1 - 0.6^2.
    let h = hybrid_pixel(&f, 0, [0.0; 3]);
    assert!(close(h, [0.32, 0.0, 0.32], 1e-6), "{h:?}");
}
