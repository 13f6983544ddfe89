//! Light above white: a fragment's RGB is stored as 8 bits times a power of two, its exponent in
//! its tint word, so emission and HDR colours keep their range through every method. Held to
//! hand computations on the CPU (the encoding against the powers of two it must pick, the
//! composites against the formulas), then the GPU to its twins: every method's image, the
//! k-buffers' slots and tails word for word (their tails' sums saturating), and a fragment of
//! 8.0 read back as 8.0. Needs a GPU adapter (lavapipe in CI); DHOIT_SKIP_GPU=1 skips
//! explicitly.

mod common;

use common::{gpu, identity, layer, quad};
use dhoit_runtime::budget::Budget;
use dhoit_runtime::composite::{self, Image, Tail, exact_pixel, hybrid_pixel, mlab_pixel};
use dhoit_runtime::fragment::{
    CLEAR, Fragment, fragment_key, hdr_exponent, mantissa_rgba8, pack_rgba8, quantize_hdr,
    stored_fragment, tint_word,
};
use dhoit_runtime::frame::{Method, Options};
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::{Material, Scene};
use dhoit_runtime::shared::HDR_MAX_EXPONENT;

const BLACK: [f32; 3] = [0.0; 3];
const SIZE: (u32, u32) = (64, 48);

/// The encoding held to what it must be, over colours from 1e-3 to beyond its top: the
/// exponent is the smallest power of two at or above the brightest channel (none below 1; the
/// top 2^15), each channel within half an 8-bit step of that power of its value, and what is
/// stored decodes to the colour bit for bit. Colours within white are stored as RGBA8 alone,
/// exponent 0, key and all, as they were before there was an exponent.
#[test]
fn colours_above_white_are_stored_as_8_bits_over_a_power_of_two() {
    let top = (1u32 << HDR_MAX_EXPONENT) as f32;
    // By hand: 8.0 is 255/255 x 2^3; 4.0 is 127.5/255 x 2^3, rounded up to 128; 0.5 is
    // 15.94/255 x 2^3, to 16.
    let q = quantize_hdr([8.0, 4.0, 0.5, 0.5], HDR_MAX_EXPONENT);
    assert_eq!(
        q,
        [8.0, 128.0 / 255.0 * 8.0, 16.0 / 255.0 * 8.0, 128.0 / 255.0]
    );
    // Frames that keep no colour above white clamp at 1.
    assert_eq!(
        quantize_hdr([8.0, 4.0, 0.5, 0.5], 0),
        [1.0, 1.0, 128.0 / 255.0, 128.0 / 255.0]
    );
    assert_eq!(quantize_hdr([1e9, 0.0, 0.0, 1.0], HDR_MAX_EXPONENT)[0], top);
    assert_eq!(
        quantize_hdr([-3.0, f32::NAN, 2.0, 1.0], HDR_MAX_EXPONENT),
        [0.0, 0.0, 2.0, 1.0]
    );
    let mut v = 1e-3f32;
    let mut checked = 0;
    while v < 2.0 * top {
        let c = [v, v / 3.0, v / 1000.0, 0.75];
        let q = quantize_hdr(c, HDR_MAX_EXPONENT);
        let e = hdr_exponent([q[0], q[1], q[2]], HDR_MAX_EXPONENT);
        let brightest = v.min(top);
        let power = (1u32 << e) as f32;
        assert!(brightest <= power, "{v}: 2^{e} below it");
        assert!(
            e == 0 || brightest > power / 2.0,
            "{v}: 2^{e} not the smallest"
        );
        for i in 0..3 {
            let want = c[i].min(top);
            let step = power / 255.0;
            assert!(
                (q[i] - want).abs() <= step / 2.0 + want * 1e-6,
                "{v}: channel {i} {} for {want}",
                q[i]
            );
        }
        let word = tint_word(q, CLEAR);
        assert_eq!(word >> 24, e, "{v}: the tint word's exponent");
        assert_eq!(stored_fragment(mantissa_rgba8(q), word), (q, CLEAR), "{v}");
        v *= 1.01;
        checked += 1;
    }
    assert!(checked > 1000);
    for m in 0..=255u32 {
        let c = [m as f32 / 255.0, 1.0 - m as f32 / 255.0, 0.5, 0.25];
        assert_eq!(fragment_key(0.5, c) as u32, pack_rgba8(c), "{m}");
        assert_eq!(tint_word(c, CLEAR), CLEAR);
    }
}

/// Three fragments whose colours the encoding holds exactly (`m / 255 x 2^e`): a grey pane
/// (0.4, alpha 0.4), a bright one (8, 3.2, 1.6; alpha 0.4), a brighter opaque one behind
/// (16, 3.2, 6.4).
fn bright_panes() -> [Fragment; 3] {
    [
        Fragment::new(0.2, [0.4, 0.4, 0.4, 0.4], 0),
        Fragment::new(0.5, [8.0, 3.2, 1.6, 0.4], 1),
        Fragment::new(0.8, [16.0, 3.2, 6.4, 1.0], 2),
    ]
}

/// The composites of colours above white, by hand: front to back,
/// `0.4 x 0.4 + 0.6 (0.4 x 8) + 0.36 x 16` = 7.84 in red, and so on, for the A-buffer, the k-buffer holding 2 or 3 of them
/// (its tail then the last one alone, exact), MLAB with 3 rows; with one slot the tail is the
/// mean colour (`sum c a / sum a`) under `1 - (1 - mean a)^n`, of the two brightest; with none,
/// of all three. The same panes clamped at white give 0.76.
#[test]
fn light_above_white_composites_as_computed_by_hand() {
    let p = bright_panes();
    for f in p {
        assert_eq!(
            quantize_hdr(f.rgba, HDR_MAX_EXPONENT),
            f.rgba,
            "stored as it is"
        );
    }
    let exact = [7.84, 2.08, 2.848];
    let close = |a: [f32; 3], b: [f32; 3], eps: f32| (0..3).all(|i| (a[i] - b[i]).abs() <= eps);
    for (name, got) in [
        ("exact", exact_pixel(&p, BLACK)),
        ("hybrid k = 3", hybrid_pixel(&p, 3, BLACK)),
        ("hybrid k = 2", hybrid_pixel(&p, 2, BLACK)),
        ("mlab m = 3", mlab_pixel(&p, 3, BLACK)),
    ] {
        assert!(close(got, exact, 1e-5), "{name}: {got:?}");
    }
    // The tail by its formula, on the 8-bit opacities the tail sums (128/255, 1).
    let tail = |frags: &[[f32; 4]]| -> [f32; 3] {
        let a: Vec<f64> = frags
            .iter()
            .map(|f| (f[3] as f64 * 255.0 + 0.5).floor() / 255.0)
            .collect();
        let n = a.len() as f64;
        let sum_a: f64 = a.iter().sum();
        let a_tail = 1.0 - (1.0 - sum_a / n).powf(n);
        std::array::from_fn(|i| {
            let sum_ca: f64 = frags.iter().zip(&a).map(|(f, a)| f[i] as f64 * a).sum();
            (a_tail * sum_ca / sum_a) as f32
        })
    };
    let back = tail(&[p[1].rgba, p[2].rgba]);
    let one: [f32; 3] = std::array::from_fn(|i| 0.16 + 0.6 * back[i]);
    assert!(one[0] > 7.0, "the tail keeps its light: {one:?}");
    let got = hybrid_pixel(&p, 1, BLACK);
    assert!(close(got, one, 1e-4), "k = 1: {got:?}, {one:?}");
    let all = tail(&[p[0].rgba, p[1].rgba, p[2].rgba]);
    let got = hybrid_pixel(&p, 0, BLACK);
    assert!(close(got, all, 1e-4), "k = 0: {got:?}, {all:?}");
    // Stored as a frame that keeps nothing above white stores them.
    let clamped = p.map(|f| Fragment::new(f.depth, quantize_hdr(f.rgba, 0), f.primitive));
    let got = exact_pixel(&clamped, BLACK);
    assert!(close(got, [0.76; 3], 1e-5), "clamped: {got:?}");
}

/// A tail of colours far above white stops at the largest sum rather than wrapping to a small
/// one: three opaque fragments of 2^15 add 255 x 255 x 2^15 each to a 32-bit sum, which holds
/// two. The tail's colour is then below the fragments' (4294967295 / (255 x 765) = 22017), not
/// the tenth of it a wrapped sum gives.
#[test]
fn a_tail_of_colours_far_above_white_saturates() {
    let top = (1u32 << HDR_MAX_EXPONENT) as f32;
    let mut t = Tail::default();
    for _ in 0..3 {
        t.add([top, 0.0, top / 2.0, 1.0], CLEAR);
    }
    // Blue: 2^14 is 127.5 / 255 of 2^15, stored as 128.
    assert_eq!(t.sum_ca, [u32::MAX, 0, (3 * 128 * 255) << 15]);
    let c = t.over(BLACK);
    assert!((c[0] - 4294967295.0 / (255.0 * 765.0)).abs() < 1.0, "{c:?}");
}

/// A scene of light above white: full-frame layers whose vertex colours pass white (a bright
/// one of 8.0, opaque, at the back), smaller ones over them, and a glowing material (base 0.5
/// and emission 2.0, 1.5, 0.2).
fn bright_scene() -> Scene {
    let mut s = Scene::default();
    let glow = s.add_material(Material {
        base_color: [0.5, 0.3, 0.1, 0.4],
        emissive: [2.0, 1.5, 0.2],
        ..Material::default()
    });
    layer(&mut s, 0.9, [8.0, 8.0, 8.0, 1.0]);
    quad(
        &mut s,
        (-1.0, -0.7, 1.0, 1.0),
        (0.6, 0.6),
        [3.0, 0.5, 12.0, 0.5],
    );
    quad(
        &mut s,
        (-0.8, -0.8, 0.4, 0.6),
        (0.3, 0.5),
        [0.2, 0.9, 0.4, 0.4],
    );
    quad(
        &mut s,
        (-0.3, -0.6, 0.9, 0.9),
        (0.2, 0.45),
        [20.0, 6.0, 1.0, 0.3],
    );
    let first = s.triangle_count();
    quad(
        &mut s,
        (-0.5, -0.2, 0.7, 0.4),
        (0.1, 0.15),
        [1.0, 1.0, 1.0, 1.0],
    );
    for t in first..s.triangle_count() {
        s.triangle_material[t] = glow;
    }
    s
}

fn differing(a: &Image, b: &Image, eps: f32) -> (usize, f32) {
    let mut n = 0;
    let mut worst = 0.0f32;
    for (x, y) in a.data.iter().zip(&b.data) {
        // Relative to the value past white, as the colours are.
        let d = (0..3)
            .map(|i| (x[i] - y[i]).abs() / y[i].abs().max(1.0))
            .fold(0.0, f32::max);
        worst = worst.max(d);
        n += (d > eps) as usize;
    }
    (n, worst)
}

/// Colours above white on the GPU are its twins': the A-buffer's fragments decode to the CPU
/// rasterizer's colours and its image is the exact composite of them; every method's image is
/// its CPU twin's; the k-buffers' slots and tails (FKB k = 1 and 2, VKB and DKB at 25% and 50%;
/// the one-pass and the portable capture) are `composite::capture`'s word for word, their
/// tails' sums saturating where a tail holds more light than 32 bits (four opaque layers of
/// 2^15); and a pixel of the opaque 8.0 layer alone reads back 8.0.
#[test]
fn light_above_white_on_the_gpu_is_its_twins() {
    use dhoit_runtime::gpu::{Capture, FrameOptions, Slots};
    let Some(g) = gpu() else { return };
    let wide_ok = common::is_wide(g, "the one-pass capture of colours above white");
    let (w, h) = SIZE;
    let cam = identity();
    let weights = common::committed_weights();
    let mut bright = bright_scene();
    assert!(bright.hdr() && bright.tint_words());
    let top = (1u32 << HDR_MAX_EXPONENT) as f32;
    let mut blinding = Scene::default();
    for z in [0.2, 0.4, 0.6, 0.8] {
        layer(&mut blinding, z, [top, 1.0, top / 4.0, 1.0]);
    }
    let (mut saturated, mut above, mut counted) = (0, 0.0f32, 0);
    for (name, s) in [("bright", &mut bright), ("blinding", &mut blinding)] {
        let fl = rasterize(s, &cam, (w, h)).unwrap();
        let ab = g.render(s, &cam, (w, h), BLACK, Slots::Exact).unwrap();
        let gfl = ab.fragments.clone().unwrap();
        assert_eq!(gfl.rgba.len(), fl.rgba.len(), "{name}");
        for p in 0..fl.pixel_count() {
            let mut a: Vec<[f32; 4]> = fl.range(p).map(|i| fl.rgba[i]).collect();
            let mut b: Vec<[f32; 4]> = gfl.range(p).map(|i| gfl.rgba[i]).collect();
            let key = |c: &[f32; 4]| c.map(f32::to_bits);
            a.sort_by_key(key);
            b.sort_by_key(key);
            assert_eq!(a, b, "{name}: pixel {p}'s colours");
        }
        let twin = composite::composite(&gfl, composite::Method::Exact, BLACK);
        assert_eq!(differing(&twin, &ab.image, 1e-6).0, 0, "{name}: A-buffer");
        above = above.max(ab.image.data.iter().map(|c| c[0]).fold(0.0, f32::max));
        let opts = Options::new(Budget::parse("2fpp").unwrap(), BLACK).always_approximate();
        let opts = Options {
            weights: Some(&weights),
            ..opts
        };
        // WBOIT's and MBOIT's binary16 sums hold colour times opacity times weight up to
        // 65504: not the blinding layers' 2^15 (inf on the CPU and the GPU alike).
        let methods: &[Method] = match name {
            "bright" => &[
                Method::Abuffer,
                Method::Mlab,
                Method::LinkedList,
                Method::Wboit,
                Method::Mboit,
            ],
            _ => &[Method::Abuffer, Method::Mlab, Method::LinkedList],
        };
        for (m, cpu, gpu) in common::cpu_and_gpu_frames(g, s, &cam, &fl, opts, methods) {
            let bound = common::twin_bound(m, 1e-5);
            let (n, worst) = differing(&cpu.image, &gpu, bound);
            assert_eq!(n, 0, "{name} {m}: {n} pixels (worst {worst})");
        }
        let total = gfl.fragment_count() as u64;
        let px = gfl.pixel_count() as u64;
        let mut runs = vec![
            ("fkb k = 1".to_string(), Slots::Uniform(1), None),
            ("fkb k = 2".to_string(), Slots::Uniform(2), None),
        ];
        for ppm in [250_000, 500_000] {
            let f = total * ppm / 1_000_000;
            let share = Some(Budget::Share(ppm as u32));
            let dkb = Slots::Dkb(&weights, f.into());
            runs.push((format!("dkb F = {f}"), dkb, share.map(|b| (Method::Dkb, b))));
            let vkb = Slots::Vkb(Default::default(), f.into());
            runs.push((format!("vkb F = {f}"), vkb, share.map(|b| (Method::Vkb, b))));
        }
        let portable = FrameOptions {
            capture: Capture::Portable,
            ..FrameOptions::default().always_approximate()
        };
        let wide = FrameOptions::default().always_approximate();
        for (label, slots, cpu) in runs {
            let what = format!("{name} {label}");
            let frame = |opts: &FrameOptions| {
                g.render_with(opts, s, &cam, (w, h), BLACK, slots)
                    .unwrap_or_else(|e| panic!("{what}: {e}"))
            };
            let b = frame(&portable);
            let (keys, bases, tails) = b.slots.clone().unwrap();
            let stored: Vec<u32> = bases.windows(2).map(|b| b[1] - b[0]).collect();
            let (twin_keys, twin_tails) = composite::capture(&gfl, &stored);
            assert!(keys == twin_keys, "{what}: the slots' keys");
            assert!(tails == twin_tails, "{what}: the tails' sums");
            saturated += tails
                .chunks_exact(5)
                .filter(|t| t[..3].contains(&u32::MAX))
                .count();
            let twin = composite::composite(&gfl, composite::Method::Hybrid(&stored), BLACK);
            let (n, worst) = differing(&twin, &b.image, 1e-5);
            assert_eq!(n, 0, "{what}: {n} pixels off the twin (worst {worst})");
            // The words: a word a slot (or pool word), no tail sums (grey glass), on the GPU
            // and in the CPU's count alike.
            if let Slots::Uniform(k) = slots {
                let slots = k as u64 * px;
                let grey = dhoit_runtime::budget::FKB.allocated_bytes(px, slots);
                assert_eq!(b.allocated_bytes, grey + 4 * slots, "{what}: bytes by hand");
            }
            if let Some((m, budget)) = cpu {
                let opts = Options {
                    weights: Some(&weights),
                    ..Options::new(budget, BLACK).always_approximate()
                };
                let f = dhoit_runtime::frame::render(&gfl, m, opts).unwrap();
                if !f.exact {
                    assert_eq!(f.allocated_bytes, b.allocated_bytes, "{what}: CPU's bytes");
                    counted += 1;
                }
            }
            if wide_ok {
                let a = frame(&wide);
                assert!(a.slots == b.slots, "{what}: the captures' slots differ");
                assert_eq!(differing(&a.image, &b.image, 0.0).0, 0, "{what}: wide");
            }
        }
    }
    assert!(saturated > 0, "no tail held more light than its sums");
    assert!(counted >= 4, "{counted} frames' bytes held to the CPU's");
    assert!(above > 4.0, "nothing above white: {above}");
    // A corner of the bright scene, where the opaque 8.0 layer is alone.
    let ab = g
        .render(&bright, &cam, (w, h), BLACK, Slots::Exact)
        .unwrap();
    assert_eq!(
        ab.image.data[(h as usize - 1) * w as usize + w as usize - 1],
        [8.0; 3]
    );
}

/// A byte budget holds the words of colours above white: at budgets from the fixed bytes to
/// the frame's own A-buffer's (its words included), FKB, VKB, DKB and the list allocate no
/// more than M; each truncating frame keeps fewer fragments than the same budget keeps of the
/// scene clamped at white (which stores no words); and at equal F a k-buffer's bytes are its
/// layout's and a word a slot (FKB) or pool word.
#[test]
fn a_byte_budget_holds_the_words_of_light_above_white() {
    let size = SIZE;
    let weights = common::committed_weights();
    let s = bright_scene();
    let fl = rasterize(&s, &identity(), size).unwrap();
    let mut clamped = fl.clone();
    clamped.tint.clear();
    clamped
        .rgba
        .iter_mut()
        .for_each(|c| *c = quantize_hdr(*c, 0));
    assert_eq!(fl.words(), dhoit_runtime::budget::Words::Exponents);
    let px = fl.pixel_count() as u64;
    let exact = dhoit_runtime::budget::abuffer_bytes(px, fl.fragment_count() as u64, true);
    let (mut held, mut fewer) = (0, 0);
    for m in [Method::Fkb, Method::Vkb, Method::Dkb, Method::LinkedList] {
        for i in 1..=10u64 {
            let bytes = exact * i / 10;
            let opts = Options {
                weights: Some(&weights),
                ..Options::new(Budget::Bytes(bytes), BLACK).always_approximate()
            };
            let (Ok(f), Ok(g)) = (
                dhoit_runtime::frame::render(&fl, m, opts),
                dhoit_runtime::frame::render(&clamped, m, opts),
            ) else {
                continue;
            };
            assert!(
                f.allocated_bytes <= bytes,
                "{m} at {bytes}: {}",
                f.allocated_bytes
            );
            held += 1;
            if f.fragments_captured < f.fragments_total {
                fewer += (f.budget_fragments < g.budget_fragments) as usize;
            }
        }
    }
    assert!(
        held >= 15 && fewer >= 5,
        "{held} frames held, {fewer} on fewer slots"
    );
    // FKB at k = 2: its layout and a word a slot.
    let opts = Options::new(Budget::SlotsPerPixel(2.0), BLACK).always_approximate();
    let f = dhoit_runtime::frame::render(&fl, Method::Fkb, opts).unwrap();
    let layout = dhoit_runtime::budget::FKB.allocated_bytes(px, 2 * px);
    assert_eq!(f.allocated_bytes, layout + 4 * 2 * px);
}

/// An opaque surface above white keeps its light: the opaque pass stores its colour as 8 bits
/// over a power of two in its one word (by hand: 8, 1 and 0 as RGB8 255, 32, 0 over 2^3, top
/// byte 255 - 3; within white the RGBA8 it always was; NaN, negative and beyond 2^15 as the
/// transparent fragments' encoding takes them), every method composites over that light on the
/// CPU (a pane of 8-bit opacity 128/255 over it lets 127/255 through), and the GPU's opaque
/// pass and resolves are the twin's (every method both run): a pixel of the surface alone reads
/// back 8.0.
#[test]
fn an_opaque_surface_above_white_keeps_its_light() {
    use dhoit_runtime::fragment::{pack_opaque, unpack_opaque};
    use dhoit_runtime::scene::Coverage;
    assert_eq!(
        pack_opaque([8.0, 1.0, 0.0]),
        0xff | 32 << 8 | (255 - 3) << 24
    );
    assert_eq!(
        unpack_opaque(pack_opaque([8.0, 1.0, 0.0])),
        [8.0, 32.0 * 8.0 / 255.0, 0.0]
    );
    for c in [[0.2, 0.4, 0.6], [0.0; 3], [1.0; 3]] {
        assert_eq!(pack_opaque(c), pack_rgba8([c[0], c[1], c[2], 1.0]), "{c:?}");
    }
    let top = (1u32 << HDR_MAX_EXPONENT) as f32;
    assert_eq!(
        unpack_opaque(pack_opaque([1e9, f32::NAN, -1.0])),
        [top, 0.0, 0.0]
    );

    let (w, h) = SIZE;
    let mut s = Scene::default();
    let wall = s.add_material(Material {
        coverage: Coverage::Opaque,
        base_color: [1.0; 4],
        ..Material::default()
    });
    layer(&mut s, 0.8, [8.0, 1.0, 0.0, 1.0]);
    for t in 0..s.triangle_count() {
        s.triangle_material[t] = wall;
    }
    quad(
        &mut s,
        (-1.0, -1.0, 0.0, 1.0),
        (0.3, 0.3),
        [0.0, 0.0, 0.0, 0.5],
    );
    let cam = identity();
    let fl = rasterize(&s, &cam, (w, h)).unwrap();
    let lit = [8.0, 32.0 * 8.0 / 255.0, 0.0];
    let through = lit.map(|c| c * 127.0 / 255.0);
    let (left, right) = (w as usize / 4, 3 * w as usize / 4);
    let row = (h as usize / 2) * w as usize;
    let close =
        |a: [f32; 3], b: [f32; 3]| (0..3).all(|i| (a[i] - b[i]).abs() <= 1e-5 * b[i].max(1.0));
    let opts = Options::new(Budget::parse("1fpp").unwrap(), BLACK).always_approximate();
    let weights = common::committed_weights();
    let opts = Options {
        weights: Some(&weights),
        ..opts
    };
    for m in Method::ALL {
        let f = dhoit_runtime::frame::render(&fl, m, opts).unwrap();
        assert!(
            close(f.image.data[row + right], lit),
            "{m}: the surface alone"
        );
        let got = f.image.data[row + left];
        // The blended methods' approximations of one fragment are exact but for rounding.
        assert!(
            (0..3).all(|i| (got[i] - through[i]).abs() <= 2e-3 * through[i].max(1.0)),
            "{m}: through the pane {got:?}, {through:?}"
        );
    }
    let Some(g) = gpu() else { return };
    let ab = g
        .render(&s, &cam, (w, h), BLACK, dhoit_runtime::gpu::Slots::Exact)
        .unwrap();
    assert_eq!(ab.image.data[row + right], lit, "the GPU's surface alone");
    assert!(
        close(ab.image.data[row + left], through),
        "{:?}",
        ab.image.data[row + left]
    );
    for (m, cpu, gpu) in common::cpu_and_gpu_frames(g, &s, &cam, &fl, opts, &common::CPU_AND_GPU) {
        let (n, worst) = differing(&cpu.image, &gpu, common::twin_bound(m, 1e-5));
        assert_eq!(n, 0, "{m}: {n} pixels (worst {worst})");
    }
}
