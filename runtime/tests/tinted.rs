//! Tinted glass (`Glass::Tinted`): per-channel transmittance, held to hand computations in every
//! CPU method: a red pane over white gives red, a red pane over a green one passes almost
//! nothing (in either order), a clear pane is nearly invisible only where its Fresnel says so,
//! and the same panes untinted pass every colour.

use dhoit_runtime::composite::{
    MboitParams, WboitParams, WboitWeight, exact_pixel, hybrid_pixel, mboit_blended, mlab_pixel,
    wboit_blended,
};
use dhoit_runtime::fragment::{CLEAR, Fragment, pack_tint, to_unorm8};
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::material::{Glass, Shaded, shade, srgb_table, tinted_glass};
use dhoit_runtime::scene::{Camera, Coverage, Material, Scene};
use glam::Vec3;

const WHITE: [f32; 3] = [1.0; 3];
const RED: u32 = 0x0000_00ff;
const GREEN: u32 = 0x0000_ff00;

/// A pane of clear glass face-on as the rasterizer stores it: F0 = 0.04 of opacity (8-bit: 10),
/// its colour the reflected white light.
fn pane(depth: f32, tint: u32, primitive: u32) -> Fragment {
    Fragment {
        depth,
        rgba: [1.0, 1.0, 1.0, 10.0 / 255.0],
        tint,
        primitive,
    }
}

/// Every CPU method's pixel for `frags` over `bg`: the A-buffer, the hybrid k-buffer with all,
/// one and none of the fragments in slots, MLAB with one and two rows, WBOIT and MBOIT.
fn every_method(frags: &[Fragment], bg: [f32; 3]) -> Vec<(String, [f32; 3])> {
    let wboit = WboitParams {
        weight: WboitWeight::Eq10,
        ..Default::default()
    };
    let mut out = vec![("exact".to_string(), exact_pixel(frags, bg))];
    for k in 0..=frags.len() {
        out.push((format!("hybrid k={k}"), hybrid_pixel(frags, k, bg)));
    }
    for m in 1..=frags.len() {
        out.push((format!("mlab m={m}"), mlab_pixel(frags, m, bg)));
    }
    out.push(("wboit".into(), wboit_blended(frags, bg, &wboit)));
    out.push((
        "mboit".into(),
        mboit_blended(frags, bg, MboitParams::default()),
    ));
    out
}

fn close(a: [f32; 3], b: [f32; 3], eps: f32) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= eps)
}

#[test]
fn a_red_pane_over_white_passes_red_in_every_method() {
    let a = 10.0 / 255.0;
    // By hand: a x white reflected, (1 - a) x (1, 0, 0) of the white behind.
    let want = [a + (1.0 - a), a, a];
    for (name, got) in every_method(&[pane(0.5, RED, 0)], WHITE) {
        // MBOIT's absorbance table and exp round to about 1e-4.
        let eps = if name == "mboit" { 2e-3 } else { 1e-5 };
        assert!(close(got, want, eps), "{name}: {got:?}, by hand {want:?}");
    }
    // Untinted, the same pane passes every colour.
    for (name, got) in every_method(&[pane(0.5, CLEAR, 0)], WHITE) {
        assert!(close(got, [1.0; 3], 2e-3), "{name} untinted: {got:?}");
    }
}

#[test]
fn a_red_pane_over_a_green_one_passes_almost_nothing_in_either_order() {
    let a = 10.0 / 255.0;
    let front_red = [pane(0.25, RED, 0), pane(0.75, GREEN, 1)];
    let front_green = [pane(0.25, GREEN, 0), pane(0.75, RED, 1)];
    // By hand, red in front: its reflection a, then through red the green pane's reflection in
    // R only, and nothing of the white behind (red passes no G, green no R).
    let want = [a + (1.0 - a) * a, a, a];
    assert!(close(exact_pixel(&front_red, WHITE), want, 1e-6));
    let swapped = [want[1], want[0], want[2]];
    assert!(close(exact_pixel(&front_green, WHITE), swapped, 1e-6));
    for (frags, what) in [
        (&front_red, "red in front"),
        (&front_green, "green in front"),
    ] {
        // Submitted back to front as well: the same image (order independence).
        let reversed: Vec<Fragment> = frags.iter().rev().copied().collect();
        let given = every_method(frags, WHITE);
        for ((name, got), (_, back)) in given.iter().zip(every_method(&reversed, WHITE)) {
            let eps = if name == "mboit" || name == "wboit" {
                1e-2
            } else {
                1e-6
            };
            assert!(
                close(*got, back, eps),
                "{name}, {what}: {got:?} vs {back:?}"
            );
            // No method lets the white background through (each channel at most the two
            // reflections, 2a) but the hybrid whose tail holds both: a tail filters by its mean
            // transmittance, ((1 - a) / 2)^2 in R and G here (a_tinted_tail_filters_per_channel).
            let dark = |c: &f32| *c <= 2.0 * a + 1e-3;
            match name.as_str() {
                "hybrid k=0" => assert!(dark(&got[2]), "{name}, {what}: {got:?}"),
                _ => assert!(got.iter().all(dark), "{name}, {what}: {got:?}"),
            }
        }
    }
    // Untinted, the same two panes pass nearly all of the white.
    let clear = [pane(0.25, CLEAR, 0), pane(0.75, CLEAR, 1)];
    for (name, got) in every_method(&clear, WHITE) {
        assert!(got.iter().all(|&c| c > 0.99), "{name} untinted: {got:?}");
    }
}

#[test]
fn a_tinted_tail_filters_per_channel() {
    // Three panes beyond a one-slot k-buffer: the tail's mean transmittance to the power of its
    // count, per channel. Red, red, clear behind a clear front pane, over white: by hand
    // R = a + (1-a) [tail], the tail over white R: a_tail + t_R, t_R = ((1-a))^3 in R; in G
    // t_G = ((1-a)(0 + 0 + 1)/3)^3.
    let a = 10.0 / 255.0;
    let frags = [
        pane(0.1, CLEAR, 0),
        pane(0.2, RED, 1),
        pane(0.3, RED, 2),
        pane(0.4, CLEAR, 3),
    ];
    let a_tail = 1.0 - (1.0f32 - a).powi(3);
    let t_r = (1.0f32 - a).powi(3);
    let t_g = ((1.0 - a) / 3.0f32).powi(3);
    let tail = [a_tail + t_r, a_tail + t_g, a_tail + t_g];
    let want: [f32; 3] = std::array::from_fn(|i| a + (1.0 - a) * tail[i]);
    let got = hybrid_pixel(&frags, 1, WHITE);
    assert!(close(got, want, 1e-5), "{got:?}, by hand {want:?}");
}

#[test]
fn tinted_glass_shades_as_computed_by_hand() {
    let table = srgb_table();
    let red = Material {
        base_color: [1.0, 0.0, 0.0, 1.0],
        coverage: Coverage::Opaque,
        transmission: 1.0,
        ..Material::default()
    };
    let tinted = dhoit_runtime::scene::material::ShadeMode {
        uniform: None,
        glass: Glass::Tinted,
    };
    let at =
        |m: &Material, cos: f32, mode| match shade(m, &[], &table, [1.0; 4], [0.0; 2], cos, mode) {
            Shaded::Transparent(c, g) => (c, g),
            s => panic!("glass is transparent: {s:?}"),
        };
    // Clear red glass face-on: opacity F0 = 0.04, colour the reflected white, tint red.
    let (c, g) = at(&red, 1.0, tinted);
    assert!(close([c[0], c[1], c[2]], [1.0; 3], 1e-6) && (c[3] - 0.04).abs() < 1e-6);
    assert_eq!(g, [1.0, 0.0, 0.0]);
    // Grey: the same opacity, its colour the base colour, no tint.
    let (c, g) = at(&red, 1.0, None.into());
    assert_eq!((c, g), ([1.0, 0.0, 0.0, c[3]], [1.0; 3]));
    // At a grazing angle glass reflects all: opaque, what it lets through does not matter.
    let (c, _) = at(&red, 0.0, tinted);
    assert!((c[3] - 1.0).abs() < 1e-6);
    // Half-transmitting red glass face-on: opacity 1 - 0.5 x 0.96 = 0.52, colour (F white +
    // (1 - T)(1 - F) red) / 0.52 = (1, 0.04 / 0.52, 0.04 / 0.52), tint red.
    let half = Material {
        transmission: 0.5,
        ..red
    };
    let (c, g) = at(&half, 1.0, tinted);
    let k = 0.04 / 0.52;
    assert!(close([c[0], c[1], c[2]], [1.0, k, k], 1e-6), "{c:?}");
    assert!((c[3] - 0.52).abs() < 1e-6 && g == [1.0, 0.0, 0.0]);
    // A volume's attenuation multiplies the tint: white glass of attenuation (1, 0.5, 0.25).
    let attenuated = Material {
        base_color: [1.0; 4],
        attenuation: [1.0, 0.5, 0.25],
        ..red
    };
    assert_eq!(at(&attenuated, 1.0, tinted).1, [1.0, 0.5, 0.25]);
    assert_eq!(
        at(&attenuated, 1.0, None.into()).1,
        [1.0; 3],
        "grey glass reads no volume"
    );
    // BLEND coverage 0.5 of it: the uncovered half passes white, so the tint is
    // (0.5 + 0.5 x 0.48 x base) / (0.5 + 0.5 x 0.48): R 1, G = B = 0.5 / 0.74.
    let (_, g) = tinted_glass(
        0.5,
        0.04,
        0.5,
        [1.0; 4],
        [1.0, 0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
    );
    assert!(close(g, [1.0, 0.5 / 0.74, 0.5 / 0.74], 1e-6), "{g:?}");
}

/// A red glass quad facing the camera, alone.
fn red_window(glass: Glass) -> Scene {
    let mut s = Scene {
        materials: Vec::new(),
        glass,
        ..Scene::default()
    };
    let m = s.add_material(Material {
        base_color: [1.0, 0.0, 0.0, 1.0],
        coverage: Coverage::Opaque,
        transmission: 1.0,
        ..Material::default()
    });
    let p = [
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    let c = [[1.0; 4]; 3];
    s.push_textured([p[0], p[1], p[2]], c, [[0.0; 2]; 3], m);
    s.push_textured([p[0], p[2], p[3]], c, [[0.0; 2]; 3], m);
    s
}

#[test]
fn a_rasterized_red_window_is_red_over_white_only_when_tinted() {
    let (w, h) = (32, 32);
    let centre = (h / 2 * w + w / 2) as usize;
    let tinted = red_window(Glass::Tinted);
    assert!(tinted.tints() && !red_window(Glass::Grey).tints());
    let cam = Camera::asset(&tinted, (w, h));
    let fl = rasterize(&tinted, &cam, (w, h)).unwrap();
    let i = fl.range(centre).start;
    assert_eq!(fl.count(centre), 1);
    assert_eq!(fl.tint(i), pack_tint([1.0, 0.0, 0.0]));
    // Face-on: F = 0.04 (of ior 1.5), 10 in 8 bits.
    assert_eq!(to_unorm8(fl.rgba[i][3]), 10);
    let img =
        dhoit_runtime::composite::composite(&fl, dhoit_runtime::composite::Method::Exact, WHITE);
    let (c, a) = (fl.rgba[i], fl.rgba[i][3]);
    let want = [c[0] * a + (1.0 - a), c[1] * a, c[2] * a];
    assert!(
        close(img.data[centre], want, 1e-6),
        "{:?} vs {want:?}",
        img.data[centre]
    );
    assert!(img.data[centre][1] < 0.1, "red glass over white is red");
    // Grey glass stores no tints and passes the white: the centre is nearly white.
    let grey = red_window(Glass::Grey);
    let fl = rasterize(&grey, &cam, (w, h)).unwrap();
    assert!(fl.tint.is_empty());
    let img =
        dhoit_runtime::composite::composite(&fl, dhoit_runtime::composite::Method::Exact, WHITE);
    assert!(img.data[centre][1] > 0.9, "{:?}", img.data[centre]);
}

/// What the network's opacity features read of a fragment (`importance::filtered_alpha8`): 255
/// times one minus what it lets through in its most transparent channel, held over every 8-bit
/// opacity and a sweep of tints to the compositing's own transmittance
/// (`fragment::transmittance`, in floats) rounded by hand; a clear fragment's is its opacity.
/// The nearest fragment's opacity feature reads it too.
#[test]
fn the_features_read_what_tinted_glass_lets_through() {
    use dhoit_runtime::fragment::transmittance;
    use dhoit_runtime::importance::filtered_alpha8;
    let mut tinted_checked = 0;
    for a8 in 0..=255u32 {
        assert_eq!(filtered_alpha8(a8, CLEAR), a8);
        // The top byte (a colour's exponent in the tint word) is not the tint.
        assert_eq!(filtered_alpha8(a8, CLEAR | 7 << 24), a8);
        for g in (0..=255u32).step_by(3) {
            for (tint, most) in [
                (g, g),
                (g << 8 | 40, g.max(40)),
                (g << 16 | 0x1000, g.max(16)),
            ] {
                let t = transmittance([0.0, 0.0, 0.0, a8 as f32 / 255.0], tint);
                let want = 255 - (255.0 * t[0].max(t[1]).max(t[2])).round() as u32;
                assert_eq!(filtered_alpha8(a8, tint), want, "a8 {a8}, tint {tint:06x}");
                // By hand: (255 - a8) most / 255 let through.
                let through = (255 - a8) * most;
                assert!((255 - want) * 255 <= through + 127 && through <= (255 - want) * 255 + 127);
                tinted_checked += 1;
            }
        }
    }
    assert_eq!(tinted_checked, 256 * 86 * 3);
    // A red pane face-on (opacity 10 of 255, tint red): it lets through 245 of red, so the
    // features see opacity 10; its tint blue instead, the same; a dark grey one (tint 64)
    // lets through 245 x 64 / 255 = 61.5 of each, so they see 255 - 61 = 194.
    assert_eq!(filtered_alpha8(10, RED), 10);
    assert_eq!(filtered_alpha8(10, 0x00ff_0000), 10);
    assert_eq!(filtered_alpha8(10, 0x0040_4040), 194);
    // The rasterized red window: its features' opacity sums are its tint's, not grey glass's
    // (tinted 194 for a grey-tinted pane, 10 for grey glass).
    let mut dark = red_window(Glass::Tinted);
    dark.materials[0].base_color = [0.25, 0.25, 0.25, 1.0];
    let cam = Camera::asset(&dark, (32, 32));
    let centre = (16 * 32 + 16) as usize;
    let stats = |s: &Scene| {
        let fl = rasterize(s, &cam, (32, 32)).unwrap();
        dhoit_runtime::importance::pixel_stats(&fl)[centre]
    };
    let tinted = stats(&dark);
    let grey = stats(&Scene {
        glass: Glass::Grey,
        ..dark.clone()
    });
    assert_eq!(grey.alpha_sum, 10);
    assert_eq!(tinted.alpha_sum, filtered_alpha8(10, pack_tint([0.25; 3])));
    assert!(tinted.alpha_sum > 150);
    assert!(tinted.optical_depth > grey.optical_depth);
    // The nearest fragment's opacity (the network's a_near) is the same filtered opacity: the
    // nearest words the features pass keeps hold it in place of the 8-bit opacity, at the same
    // depth.
    let near_alpha = |s: &dhoit_runtime::importance::PixelStats| {
        dhoit_runtime::importance::near_rgba8(s.nearest) >> 24
    };
    assert_eq!(near_alpha(&grey), 10);
    assert_eq!(near_alpha(&tinted), tinted.alpha_sum);
    assert_eq!(tinted.nearest[0] >> 16, grey.nearest[0] >> 16);
    let t = dhoit_runtime::importance::Totals {
        fragments: 1,
        covered: 1,
        max_count: 1,
    };
    let a_near = |s| dhoit_runtime::importance::pixel_features(s, &t, 1)[5];
    assert_eq!(a_near(&grey), 10.0 / 255.0);
    assert_eq!(a_near(&tinted), tinted.alpha_sum as f32 / 255.0);
}
