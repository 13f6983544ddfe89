//! Materials per fragment, on the CPU reference and the GPU alike: textured BLEND surfaces with
//! UVs far outside [0, 1] under every wrap mode and both filters, MASK cutoffs, glass whose
//! opacity follows the view angle and its transmission texture, emissive surfaces, and opaque
//! occluders in front of, between and behind transparent layers. Needs a GPU adapter (lavapipe in CI); DHOIT_SKIP_GPU=1 skips explicitly.

mod common;

use common::gpu;
use dhoit_runtime::budget::Budget;
use dhoit_runtime::composite::{self, Image};
use dhoit_runtime::fragment::{CLEAR, FragmentLists, unpack_rgba8};
use dhoit_runtime::frame::{self, Method, Options};
use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::material::pack_texel;
use dhoit_runtime::scene::{Camera, Coverage, Glass, Material, Scene, Texture, Wrap};
use glam::Vec3;

const BG: [f32; 3] = [0.9, 0.85, 0.8];
const SIZE: (u32, u32) = (96, 72);

/// A texture of `n` x `n` texels from a function of the texel's centre (u, v) to linear RGBA.
fn texture(n: u32, wrap: [Wrap; 2], nearest: bool, f: impl Fn(f32, f32) -> [f32; 4]) -> Texture {
    let texels = (0..n * n)
        .map(|i| {
            let (x, y) = (i % n, i / n);
            pack_texel(f((x as f32 + 0.5) / n as f32, (y as f32 + 0.5) / n as f32))
        })
        .collect();
    Texture {
        width: n,
        height: n,
        texels,
        wrap,
        nearest,
    }
}

/// A quad of corners `p` with texture coordinates `uv`, vertex colours `c`, material `m`.
fn quad(s: &mut Scene, p: [Vec3; 4], uv: [[f32; 2]; 4], c: [[f32; 4]; 4], m: u32) {
    s.push_textured(
        [p[0], p[1], p[2]],
        [c[0], c[1], c[2]],
        [uv[0], uv[1], uv[2]],
        m,
    );
    s.push_textured(
        [p[0], p[2], p[3]],
        [c[0], c[2], c[3]],
        [uv[0], uv[2], uv[3]],
        m,
    );
}

/// A tilted quad across the scene at depth `z` (x, y in [-1, 1] scaled by `half`).
fn layer(z: f32, half: f32, tilt: f32) -> [Vec3; 4] {
    [
        Vec3::new(-half, -half, z - tilt),
        Vec3::new(half, -half, z + tilt),
        Vec3::new(half, half, z + tilt),
        Vec3::new(-half, half, z - tilt),
    ]
}

fn empty() -> Scene {
    Scene {
        materials: Vec::new(),
        ..Scene::default()
    }
}

/// Textured BLEND layers: a gradient-and-checker texture of varying alpha under each wrap mode
/// (UVs from -1.5 to 2.5), bilinear and nearest, over interpolated vertex colours.
fn textured_blend() -> Scene {
    let mut s = empty();
    let wraps = [
        [Wrap::Repeat, Wrap::Repeat],
        [Wrap::MirroredRepeat, Wrap::ClampToEdge],
        [Wrap::ClampToEdge, Wrap::MirroredRepeat],
    ];
    for (i, wrap) in wraps.into_iter().enumerate() {
        for nearest in [false, true] {
            let t = s.add_texture(texture(8, wrap, nearest, |u, v| {
                let check = ((u * 4.0) as u32 + (v * 4.0) as u32).is_multiple_of(2);
                [u, 1.0 - v, if check { 0.9 } else { 0.2 }, 0.2 + 0.7 * u * v]
            }));
            s.add_material(Material {
                texture: Some(t),
                coverage: Coverage::Blend,
                base_color: [1.0, 0.95, 0.9, 0.9],
                ..Material::default()
            });
            let m = (s.materials.len() - 1) as u32;
            let z = -0.8 + 0.3 * (2 * i + nearest as usize) as f32;
            let uv = [[-1.5, 2.5], [2.5, 2.5], [2.5, -1.5], [-1.5, -1.5]];
            let c = [
                [1.0, 0.6, 0.6, 1.0],
                [0.6, 1.0, 0.6, 1.0],
                [0.6, 0.6, 1.0, 1.0],
                [1.0, 1.0, 0.6, 1.0],
            ];
            quad(&mut s, layer(z, 0.9 - 0.1 * i as f32, 0.3), uv, c, m);
        }
    }
    s
}

/// MASK cards (texture alpha 0.2 or 0.8 by a stripe pattern, cutoff 0.5) between BLEND layers.
fn masked() -> Scene {
    let mut s = empty();
    let stripes = s.add_texture(texture(16, [Wrap::Repeat, Wrap::Repeat], false, |u, v| {
        let a = if (((u + v) * 4.0) as u32).is_multiple_of(2) {
            0.8
        } else {
            0.2
        };
        [0.3 + 0.6 * u, 0.5, 0.9 - 0.6 * v, a]
    }));
    let mask = s.add_material(Material {
        texture: Some(stripes),
        coverage: Coverage::Mask(0.5),
        ..Material::default()
    });
    let blend = s.add_material(Material {
        base_color: [0.9, 0.4, 0.2, 0.45],
        ..Material::default()
    });
    let white = [[1.0; 4]; 4];
    let uv = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    for (i, z) in [-0.6f32, 0.0, 0.6].into_iter().enumerate() {
        quad(&mut s, layer(z - 0.2, 0.8, 0.1), uv, white, blend);
        let uv2 = uv.map(|[u, v]| [u * (1.0 + i as f32), v * 2.0]);
        quad(&mut s, layer(z, 0.7, -0.15), uv2, white, mask);
    }
    s
}

/// Opaque occluders in front of, between and behind transparent layers, and glass (opacity
/// from the view angle) in front of them.
fn occluded() -> Scene {
    let mut s = empty();
    let wall = s.add_material(Material {
        base_color: [0.3, 0.6, 0.4, 1.0],
        coverage: Coverage::Opaque,
        ..Material::default()
    });
    let blend = s.add_material(Material {
        base_color: [0.8, 0.8, 0.2, 0.5],
        ..Material::default()
    });
    let glass = s.add_material(Material {
        base_color: [0.7, 0.9, 1.0, 1.0],
        coverage: Coverage::Opaque,
        transmission: 1.0,
        ior: 1.6,
        double_sided: true,
        ..Material::default()
    });
    let single = s.add_material(Material {
        base_color: [0.9, 0.3, 0.6, 0.6],
        double_sided: false,
        ..Material::default()
    });
    let white = [[1.0; 4]; 4];
    let uv = [[0.0; 2]; 4];
    // A backdrop behind everything; a small occluder between layers; one in front.
    quad(&mut s, layer(0.9, 1.0, 0.0), uv, white, wall);
    for z in [-0.5f32, -0.1, 0.3, 0.6] {
        quad(&mut s, layer(z, 0.85, 0.15), uv, white, blend);
    }
    let between = [
        Vec3::new(-0.7, -0.7, 0.1),
        Vec3::new(0.0, -0.7, 0.1),
        Vec3::new(0.0, 0.0, 0.1),
        Vec3::new(-0.7, 0.0, 0.1),
    ];
    quad(&mut s, between, uv, white, wall);
    let front = between.map(|p| Vec3::new(p.x + 0.9, p.y + 0.9, -0.7));
    quad(&mut s, front, uv, white, wall);
    // A sphere of glass and a single-sided box.
    let n = 16;
    for j in 0..n / 2 {
        for i in 0..n {
            let point = |i: u32, j: u32| {
                let (t, p) = (
                    std::f32::consts::PI * j as f32 / (n / 2) as f32,
                    std::f32::consts::TAU * i as f32 / n as f32,
                );
                Vec3::new(
                    0.3 + 0.35 * t.sin() * p.cos(),
                    0.35 * t.cos(),
                    -0.3 + 0.35 * t.sin() * p.sin(),
                )
            };
            let q = [
                point(i, j),
                point(i + 1, j),
                point(i + 1, j + 1),
                point(i, j + 1),
            ];
            quad(&mut s, q, uv, white, glass);
        }
    }
    let cube = [
        [-1., -1., -1.],
        [1., -1., -1.],
        [1., 1., -1.],
        [-1., 1., -1.],
        [-1., -1., 1.],
        [1., -1., 1.],
        [1., 1., 1.],
        [-1., 1., 1.],
    ]
    .map(|[x, y, z]| Vec3::new(-0.45 + 0.2 * x, 0.45 + 0.2 * y, 0.2 * z));
    // Counter-clockwise seen from outside.
    for f in [
        [0, 3, 2, 1],
        [4, 5, 6, 7],
        [0, 1, 5, 4],
        [3, 7, 6, 2],
        [0, 4, 7, 3],
        [1, 2, 6, 5],
    ] {
        quad(&mut s, f.map(|i| cube[i]), uv, white, single);
    }
    s
}

/// A data texture of `n` x `n` texels whose R byte is `r(x, y)` (no sRGB encoding: what a
/// transmission texture holds).
fn data_texture(n: u32, r: impl Fn(u32, u32) -> u32) -> Texture {
    Texture {
        width: n,
        height: n,
        texels: (0..n * n).map(|i| r(i % n, i / n) | 0xff00_0000).collect(),
        wrap: [Wrap::Repeat; 2],
        nearest: false,
    }
}

/// Stained glass and emission: tinted glass panes whose transmission texture has opaque
/// leads (R 0), clear glass (255) and half-transmitting paint (128), bilinear and repeated, in
/// front of an opaque black label lit only by its emissive texture, and a BLEND pane that glows
/// past white (stored clamped).
fn stained_glass_and_emission() -> Scene {
    let mut s = empty();
    let leads = s.add_texture(data_texture(8, |x, y| match (x % 4, y % 4) {
        (0, _) | (_, 0) => 0,
        (1, 1) => 128,
        _ => 255,
    }));
    let letters = s.add_texture(texture(16, [Wrap::ClampToEdge; 2], true, |u, v| {
        let on = ((u * 8.0) as i32 + (v * 4.0) as i32) % 3 == 0;
        if on {
            [1.0, 0.9, 0.2, 1.0]
        } else {
            [0.05, 0.05, 0.1, 1.0]
        }
    }));
    let label = s.add_material(Material {
        base_color: [0.0, 0.0, 0.0, 1.0],
        coverage: Coverage::Opaque,
        emissive: [1.0, 1.0, 1.0],
        emissive_texture: Some(letters),
        ..Material::default()
    });
    let red = s.add_material(Material {
        base_color: [0.9, 0.15, 0.1, 1.0],
        coverage: Coverage::Opaque,
        transmission: 1.0,
        transmission_texture: Some(leads),
        ..Material::default()
    });
    let blue = s.add_material(Material {
        base_color: [0.1, 0.4, 0.9, 1.0],
        coverage: Coverage::Opaque,
        transmission: 0.8,
        transmission_texture: Some(leads),
        ior: 1.4,
        ..Material::default()
    });
    let glow = s.add_material(Material {
        base_color: [0.5, 0.3, 0.1, 0.4],
        emissive: [2.0, 1.5, 0.2],
        ..Material::default()
    });
    let white = [[1.0; 4]; 4];
    let uv = [[-0.5, 1.7], [1.6, 1.7], [1.6, -0.4], [-0.5, -0.4]];
    quad(
        &mut s,
        layer(0.8, 0.9, 0.0),
        [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
        white,
        label,
    );
    quad(&mut s, layer(0.3, 0.8, 0.2), uv, white, red);
    quad(&mut s, layer(-0.1, 0.6, -0.25), uv, white, blue);
    quad(&mut s, layer(-0.4, 0.4, 0.1), uv, white, glow);
    s
}

fn scenes() -> [(&'static str, Scene); 4] {
    [
        ("textured BLEND", textured_blend()),
        ("MASK", masked()),
        ("occluders and glass", occluded()),
        ("stained glass and emission", stained_glass_and_emission()),
    ]
}

/// A transmission texture's R channel, read as data, scales the glass's transmission: where it
/// is 0 the glass is opaque with its base colour, where 255 it is clear glass (opacity its
/// Fresnel reflectance, F0 face-on), where 128 between; an emissive texture adds its light
/// after the headlight's shade, undimmed. Held to hand computations.
#[test]
fn transmission_textures_and_emission_shade_as_computed_by_hand() {
    use dhoit_runtime::scene::material::{Shaded, shade, srgb_table};
    let table = srgb_table();
    // One texel a column: R 0, 128, 255; nearest, so each column's value is its own.
    let data = Texture {
        width: 3,
        height: 1,
        texels: vec![0xff00_0000, 0xff00_0080, 0xff00_00ff],
        wrap: [Wrap::ClampToEdge; 2],
        nearest: true,
    };
    let glass = Material {
        base_color: [0.9, 0.1, 0.1, 1.0],
        coverage: Coverage::Opaque,
        transmission: 1.0,
        transmission_texture: Some(0),
        ..Material::default()
    };
    let textures = [data];
    let at = |u: f32| shade(&glass, &textures, &table, [1.0; 4], [u, 0.5], 1.0, None);
    // F0 of IOR 1.5: ((1.5 - 1) / (1.5 + 1))^2 = 0.04; face-on (cos 1) F = F0.
    let f0 = 0.04f32;
    let expect = [1.0, 1.0 - (128.0 / 255.0) * (1.0 - f0), f0];
    for (i, want) in expect.into_iter().enumerate() {
        let Shaded::Transparent(c, _) = at((i as f32 + 0.5) / 3.0) else {
            panic!("column {i}: glass is a transparent fragment");
        };
        assert!(
            (c[3] - want).abs() < 1e-6,
            "column {i}: opacity {} for {want}",
            c[3]
        );
        assert_eq!(&c[..3], &[0.9, 0.1, 0.1], "column {i}: the base colour");
    }
    // Without the texture, the factor alone: clear glass everywhere.
    let clear = Material {
        transmission_texture: None,
        ..glass
    };
    let Shaded::Transparent(c, _) =
        shade(&clear, &textures, &table, [1.0; 4], [0.1, 0.5], 1.0, None)
    else {
        panic!("clear glass is transparent");
    };
    assert!((c[3] - f0).abs() < 1e-6, "clear glass: {}", c[3]);

    // A black label lit by its emissive texture: sRGB 255 and 0 texels, the headlight at half.
    let letters = Texture {
        width: 2,
        height: 1,
        texels: vec![0xffff_ffff, 0xff00_0000],
        wrap: [Wrap::ClampToEdge; 2],
        nearest: true,
    };
    let label = Material {
        base_color: [0.0, 0.0, 0.0, 1.0],
        coverage: Coverage::Opaque,
        emissive: [0.5, 1.0, 2.0],
        emissive_texture: Some(0),
        ..Material::default()
    };
    let shaded = [0.5, 0.5, 0.5, 1.0];
    let lit = shade(
        &label,
        std::slice::from_ref(&letters),
        &table,
        shaded,
        [0.25, 0.5],
        1.0,
        None,
    );
    assert_eq!(
        lit,
        Shaded::Opaque([0.5, 1.0, 2.0, 1.0]),
        "a lit texel: its emission, undimmed"
    );
    let dark = shade(&label, &[letters], &table, shaded, [0.75, 0.5], 1.0, None);
    assert_eq!(
        dark,
        Shaded::Opaque([0.0, 0.0, 0.0, 1.0]),
        "a dark texel: black"
    );
    // Emission adds to a lit base colour and to a transparent one's straight colour.
    let glow = Material {
        base_color: [0.5, 0.5, 0.5, 0.25],
        emissive: [0.25, 0.0, 1.0],
        ..Material::default()
    };
    assert_eq!(
        shade(&glow, &[], &table, shaded, [0.0; 2], 1.0, None),
        Shaded::Transparent([0.5, 0.25, 1.25, 0.25], [1.0; 3])
    );
}

/// The camera of view `view` of an orbit around `s`.
fn camera(s: &Scene, view: usize) -> Camera {
    Camera::orbit(s, view, 8, (SIZE.0, SIZE.1))
}

/// Pixels where two images differ by more than `eps`, and the largest difference.
fn differing(a: &Image, b: &Image, eps: f32) -> (usize, f32) {
    let mut n = 0;
    let mut worst = 0.0f32;
    for (x, y) in a.data.iter().zip(&b.data) {
        let d = (0..3).map(|i| (x[i] - y[i]).abs()).fold(0.0, f32::max);
        worst = worst.max(d);
        n += (d > eps) as usize;
    }
    (n, worst)
}

/// The bound CPU and GPU are held to. Both rasterizers find the same fragments (coverage,
/// the depth test against the opaque pass, MASK, back faces, zero opacity: per-pixel counts
/// equal), and shade them with the same arithmetic (weights from the clip-space vertices,
/// texture sampling and the sRGB table written out in the shader), so their 8-bit colours are
/// the same but where a value lands within float rounding of a half step: at most one channel
/// in a thousand, by one step. Every method's image is then within 1e-5 of the other's on
/// these scenes (none of whose channels lands there); on real scenes, within [`STEP`] where
/// one does.
const IMAGE_BOUND: f32 = 1e-5;
const CHANNELS_OFF_BY_ONE: f64 = 1e-3;
/// One 8-bit step: where a channel is a step apart, the pixel may be too (by no more: a
/// colour, opacity or opaque channel weighs at most 1 in the composite); on real scenes, at
/// most one pixel in two hundred, where such a channel shows or two fragments lie at one depth
/// within the rasterizers' rounding and blend in the other order.
const STEP: f32 = 1.0 / 255.0;

#[test]
fn materials_render_alike_on_cpu_and_gpu() {
    let Some(g) = gpu() else { return };
    let size = SIZE;
    let mlp = Mlp::random(9);
    let (mut channels, mut off) = (0usize, 0usize);
    for (name, s) in scenes() {
        s.check().unwrap();
        for view in 0..4 {
            let cam = camera(&s, view);
            let fl = rasterize(&s, &cam, size).unwrap();
            let gpu_ab = g
                .render(&s, &cam, size, BG, dhoit_runtime::gpu::Slots::Exact)
                .unwrap();
            let gfl = gpu_ab.fragments.clone().unwrap();
            // The GPU's own fragments (its opaque layer too) through the CPU twin: its image.
            let twin = composite::composite(&gfl, composite::Method::Exact, BG);
            let (_, d) = differing(&twin, &gpu_ab.image, 0.0);
            assert!(
                d <= 1e-5,
                "{name} view {view}: GPU A-buffer against its twin: {d}"
            );
            let differ = |a: &[u32], b: &[u32]| a.iter().zip(b).filter(|(x, y)| x != y).count();
            let counts = differ(&fl.counts(), &gfl.counts());
            assert_eq!(counts, 0, "{name} view {view}: pixels whose counts differ");
            let opaque = differ(&fl.opaque, &gfl.opaque);
            assert_eq!(
                opaque, 0,
                "{name} view {view}: pixels whose opaque colours differ"
            );
            let (c, o) = colours_agree(&fl, &gfl, &format!("{name} view {view}"));
            channels += c;
            off += o;
            for budget in ["50%", "2fpp"] {
                let budget = Budget::parse(budget).unwrap();
                let opts = Options {
                    weights: Some(&mlp),
                    ..Options::new(budget, BG).always_approximate()
                };
                let methods = &common::CPU_AND_GPU;
                for (m, cpu, gpu) in common::cpu_and_gpu_frames(g, &s, &cam, &fl, opts, methods) {
                    let bound = common::twin_bound(m, IMAGE_BOUND);
                    let (n, worst) = differing(&cpu.image, &gpu, bound);
                    assert_eq!(
                        n, 0,
                        "{name} view {view} {budget} {m}: {n} pixels differ by more than \
                         {bound} (worst {worst})"
                    );
                }
            }
        }
    }
    eprintln!("{off} of {channels} fragment channels one 8-bit step apart");
    assert!(
        (off as f64) <= CHANNELS_OFF_BY_ONE * channels as f64,
        "{off} of {channels} fragment channels differ"
    );
}

/// Tinted glass on the GPU: the A-buffer and the linked list store each fragment's tint beside
/// its key, and the A-buffer, MLAB and the list (its tail too) filter per channel, and WBOIT and
/// MBOIT multiply what they let through per channel (an RGBA8 target), as their CPU twins: the same fragments, colours and
/// tints (within one 8-bit step, as above), the GPU's image its own fragments' twin, and within
/// [`STEP`] of the CPU's (a tinted colour is its reflection over its opacity, a division that
/// lands some channels within float rounding of a half step; at most one in a thousand). The
/// tints show (the grey image differs). The k-buffers: `tinted_glass_in_the_gpu_k_buffers_...`.
#[test]
fn tinted_glass_renders_alike_on_cpu_and_gpu() {
    let Some(g) = gpu() else { return };
    let size = SIZE;
    for (name, grey) in [
        ("occluders and glass", occluded()),
        ("stained glass and emission", stained_glass_and_emission()),
    ] {
        let s = Scene {
            glass: Glass::Tinted,
            ..grey.clone()
        };
        assert!(s.tints(), "{name} has glass");
        let (mut tinted_views, mut grey_differ) = (0, 0);
        for view in 0..4 {
            let cam = camera(&s, view);
            let fl = rasterize(&s, &cam, size).unwrap();
            assert!(fl.tinted() || fl.fragment_count() == 0);
            tinted_views += fl.tint.iter().any(|&g| g != CLEAR) as usize;
            let gpu_ab = g
                .render(&s, &cam, size, BG, dhoit_runtime::gpu::Slots::Exact)
                .unwrap();
            let gfl = gpu_ab.fragments.clone().unwrap();
            assert_eq!(
                gfl.tint.len(),
                gfl.fragment_count(),
                "{name}: the GPU's tints"
            );
            let twin = composite::composite(&gfl, composite::Method::Exact, BG);
            let (_, d) = differing(&twin, &gpu_ab.image, 0.0);
            assert!(
                d <= 1e-5,
                "{name} view {view}: GPU A-buffer against its twin: {d}"
            );
            let (c, o) = colours_agree(&fl, &gfl, &format!("{name} view {view} tinted"));
            assert!(
                o as f64 <= CHANNELS_OFF_BY_ONE * c as f64,
                "{name} view {view}: {o} of {c} channels one step apart"
            );
            let grey_ab = g
                .render(&grey, &cam, size, BG, dhoit_runtime::gpu::Slots::Exact)
                .unwrap();
            // Its tints are 4 bytes a fragment beside the grey frame's, on the GPU and in the
            // CPU's count alike (where the grey frame's colours keep their exponent, it stores
            // the words too).
            let n = match grey.tint_words() {
                true => 0,
                false => gfl.fragment_count() as u64,
            };
            assert_eq!(gpu_ab.allocated_bytes, grey_ab.allocated_bytes + 4 * n);
            let cpu_bytes = |s: &Scene| {
                let fl = rasterize(s, &cam, size).unwrap();
                let opts = Options::new(Budget::parse("2fpp").unwrap(), BG);
                frame::render(&fl, Method::Abuffer, opts)
                    .unwrap()
                    .allocated_bytes
            };
            assert_eq!(cpu_bytes(&s), cpu_bytes(&grey) + 4 * n);
            grey_differ += differing(&grey_ab.image, &gpu_ab.image, STEP).0;
            let opts = Options::new(Budget::parse("2fpp").unwrap(), BG).always_approximate();
            let methods = [
                Method::Abuffer,
                Method::Mlab,
                Method::LinkedList,
                Method::Wboit,
                Method::Mboit,
            ];
            for (m, cpu, gpu) in common::cpu_and_gpu_frames(g, &s, &cam, &fl, opts, &methods) {
                let (n, worst) = differing(&cpu.image, &gpu, common::twin_bound(m, STEP));
                assert_eq!(n, 0, "{name} view {view} {m}: {n} pixels (worst {worst})");
            }
            // The list with one fragment a pixel sorted: its tail filters per channel.
            let one = Options {
                list_sorted: 1,
                ..opts
            };
            let list = [Method::LinkedList];
            for (m, cpu, gpu) in common::cpu_and_gpu_frames(g, &s, &cam, &fl, one, &list) {
                let (n, worst) = differing(&cpu.image, &gpu, STEP);
                assert_eq!(
                    n, 0,
                    "{name} view {view} {m} sorting 1: {n} pixels ({worst})"
                );
            }
        }
        assert!(tinted_views > 0, "{name}: no view shows a tinted fragment");
        assert!(grey_differ > 0, "{name}: tinted glass renders as grey");
    }
}

/// The same fragments in every pixel (by their triangles: two of nearly one depth may swap
/// places front to back, where the rasterizers' depths differ by float rounding), with colours
/// no channel of which is more than one 8-bit step apart; returns (channels compared, channels
/// one step apart).
fn colours_agree(cpu: &FragmentLists, gpu: &FragmentLists, what: &str) -> (usize, usize) {
    let (mut channels, mut off) = (0, 0);
    let by_triangle = |fl: &FragmentLists, p: usize| {
        let mut v: Vec<_> = fl.fragments(p).collect();
        v.sort_by_key(|f| f.primitive);
        v
    };
    for p in 0..cpu.pixel_count() {
        for (a, b) in by_triangle(cpu, p).iter().zip(&by_triangle(gpu, p)) {
            assert_eq!(a.primitive, b.primitive, "{what}: pixel {p}'s fragments");
            // Colour and opacity, then the tint's three channels.
            let (ga, gb) = (unpack_rgba8(a.tint), unpack_rgba8(b.tint));
            let pairs = (0..4).map(|i| (a.rgba[i], b.rgba[i]));
            for (x, y) in pairs.chain((0..3).map(|i| (ga[i], gb[i]))) {
                let d = (x - y).abs() * 255.0;
                assert!(
                    d < 1.5,
                    "{what}: pixel {p}: {:?} tint {:#x} against {:?} tint {:#x}",
                    a.rgba,
                    a.tint,
                    b.rgba,
                    b.tint
                );
                channels += 1;
                off += (d > 0.5) as usize;
            }
        }
    }
    (channels, off)
}

/// No fragment at or behind an opaque surface exists: the lists hold, per pixel, exactly the
/// transparent fragments nearer than every opaque one, counted here from a rasterization of
/// the same scene with every surface transparent (so nothing is hidden) by their primitives'
/// materials and depths; the GPU counts the same.
#[test]
fn no_fragment_behind_an_opaque_surface_is_counted() {
    let Some(g) = gpu() else { return };
    let size = SIZE;
    for (name, s) in scenes() {
        let mut all = s.clone();
        for m in &mut all.materials {
            // Everything drawn as a fragment, even the opaque surfaces: nothing hidden, no
            // MASK test (so this only holds for scenes whose masked texels are all kept or
            // dropped by the materials' own alpha, which the check below accounts for).
            *m = Material {
                coverage: Coverage::Blend,
                transmission: 0.0,
                base_color: [m.base_color[0], m.base_color[1], m.base_color[2], 1.0],
                texture: None,
                ..*m
            };
        }
        for view in 0..4 {
            let cam = camera(&s, view);
            let fl = rasterize(&s, &cam, size).unwrap();
            let every = rasterize(&all, &cam, size).unwrap();
            let opaque = |prim: u32| !s.transparent(prim as usize);
            let masked = |prim: u32| s.material_of(prim as usize).cutoff().is_some();
            let mut expected = 0u64;
            let nearest_opaque: Vec<f32> = (0..every.pixel_count())
                .map(|p| {
                    every
                        .fragments(p)
                        .filter(|f| opaque(f.primitive) && !masked(f.primitive))
                        .fold(1.0f32, |d, f| d.min(f.depth))
                })
                .collect();
            for (p, &nearest) in nearest_opaque.iter().enumerate() {
                let visible = every
                    .fragments(p)
                    .filter(|f| !opaque(f.primitive) && f.depth < nearest)
                    .count() as u32;
                // Masked surfaces hide a pixel only where their texel survives the cutoff.
                if !s.materials.iter().any(|m| m.cutoff().is_some()) {
                    assert_eq!(fl.count(p), visible, "{name} view {view} pixel {p}");
                } else {
                    assert!(fl.count(p) <= visible, "{name} view {view} pixel {p}");
                }
                expected += visible as u64;
            }
            let gpu = g
                .render(&s, &cam, size, BG, dhoit_runtime::gpu::Slots::Exact)
                .unwrap()
                .fragments
                .unwrap();
            assert_eq!(
                gpu.fragment_count(),
                fl.fragment_count(),
                "{name} view {view}: sum n on the GPU"
            );
            assert!(fl.fragment_count() as u64 <= expected);
            eprintln!(
                "{name} view {view}: {} visible of {} transparent fragments",
                fl.fragment_count(),
                every.primitive.iter().filter(|&&p| !opaque(p)).count()
            );
        }
    }
}

/// The occluders scene hides fragments (else the test above proves little), and every method
/// composites over the opaque image: a pixel covered by the front occluder shows its colour.
#[test]
fn transparent_layers_are_composited_over_the_opaque_image() {
    let s = occluded();
    let cam = camera(&s, 2);
    let size = SIZE;
    let fl = rasterize(&s, &cam, size).unwrap();
    let mut all = s.clone();
    for m in &mut all.materials {
        m.coverage = Coverage::Blend;
        m.transmission = 0.0;
    }
    let every = rasterize(&all, &cam, size).unwrap();
    assert!(
        every.fragment_count() > 2 * fl.fragment_count(),
        "the occluders hide most fragments: {} of {}",
        fl.fragment_count(),
        every.fragment_count()
    );
    let covered = (0..fl.pixel_count())
        .filter(|&p| fl.opaque[p] >> 24 != 0 && fl.count(p) == 0)
        .collect::<Vec<_>>();
    assert!(!covered.is_empty());
    for m in [Method::Abuffer, Method::Fkb, Method::Vkb, Method::Mlab] {
        let f = frame::render(&fl, m, Options::new(Budget::parse("2fpp").unwrap(), BG)).unwrap();
        for &p in &covered {
            let c = dhoit_runtime::fragment::unpack_opaque(fl.opaque[p]);
            assert_eq!(f.image.data[p], c, "{m} pixel {p}");
        }
    }
}

/// The real scenes with their own materials (AlphaBlendModeTest: every alpha mode with
/// textured cutoffs; TextureSettingsTest: wrap modes, UVs outside [0, 1], single- and
/// double-sided; GlassBrokenWindow: glass with masked holes in an opaque frame), or on a
/// clone with nothing beside it the material families written as glTF: CPU and GPU alike,
/// as above.
#[test]
fn real_scenes_with_their_materials_render_alike_on_cpu_and_gpu() {
    let Some(g) = gpu() else { return };
    let size = SIZE;
    let mlp = Mlp::random(9);
    let (mut channels, mut off) = (0usize, 0usize);
    for (rel, stand_in) in [
        ("AlphaBlendModeTest/AlphaBlendModeTest.glb", "cards"),
        ("TextureSettingsTest/TextureSettingsTest.glb", "windows"),
        ("GlassBrokenWindow/GlassBrokenWindow.glb", "covers"),
    ] {
        let path = common::real_or_exported(rel, stand_in);
        let s = dhoit_runtime::scene::load(path.to_str().unwrap(), Default::default()).unwrap();
        for view in [0, 3] {
            let cam = camera(&s, view);
            let fl = rasterize(&s, &cam, size).unwrap();
            let gpu_ab = g
                .render(&s, &cam, size, BG, dhoit_runtime::gpu::Slots::Exact)
                .unwrap();
            let gfl = gpu_ab.fragments.clone().unwrap();
            let what = format!("{rel} view {view}");
            let differ = |a: &[u32], b: &[u32]| a.iter().zip(b).filter(|(x, y)| x != y).count();
            assert_eq!(differ(&fl.counts(), &gfl.counts()), 0, "{what}: counts");
            let opaque = differ(&fl.opaque, &gfl.opaque);
            let (c, o) = colours_agree(&fl, &gfl, &what);
            eprintln!(
                "{what}: {} fragments, {o} of {c} channels and {opaque} opaque pixels one \
                 step apart",
                fl.fragment_count()
            );
            channels += c + 4 * fl.opaque.len();
            off += o + opaque;
            let opts = Options {
                weights: Some(&mlp),
                ..Options::new(Budget::parse("25%").unwrap(), BG).always_approximate()
            };
            let methods = [Method::Abuffer, Method::Dkb];
            for (m, cpu, gpu) in common::cpu_and_gpu_frames(g, &s, &cam, &fl, opts, &methods) {
                let (n, worst) = differing(&cpu.image, &gpu, STEP);
                // A channel one step apart moves a pixel by at most that step; two fragments at
                // one depth within the rasterizers' rounding may blend in the other order.
                assert!(
                    worst <= STEP + IMAGE_BOUND && n as f64 <= 5e-3 * fl.pixel_count() as f64,
                    "{what} {m}: {n} pixels over {IMAGE_BOUND}, worst {worst}"
                );
            }
        }
    }
    eprintln!("{off} of {channels} channels one 8-bit step apart");
    assert!((off as f64) <= CHANNELS_OFF_BY_ONE * channels as f64);
}

/// Three panes of red, green and blue glass at each of three depths, each three coplanar: at
/// each depth the three fragments have one key (one depth, the same reflected white) and
/// three tints, so which tint a slot keeps, and which goes to the tail, is the tie-break of
/// (key, tint) alone.
fn coplanar_tints() -> Scene {
    let mut s = empty();
    let glass: Vec<u32> = [[0.9, 0.1, 0.1], [0.1, 0.9, 0.2], [0.1, 0.3, 0.9]]
        .map(|c| {
            s.add_material(Material {
                base_color: [c[0], c[1], c[2], 1.0],
                coverage: Coverage::Opaque,
                transmission: 1.0,
                ..Material::default()
            })
        })
        .to_vec();
    let white = [[1.0; 4]; 4];
    let uv = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    for (i, z) in [0.3, 0.0, -0.3].into_iter().enumerate() {
        for j in 0..3 {
            // Submitted in a different order at each depth.
            let m = glass[(i + j) % 3];
            quad(&mut s, layer(z, 0.7 - 0.1 * i as f32, 0.1), uv, white, m);
        }
    }
    Scene {
        glass: Glass::Tinted,
        ..s
    }
}

/// A GPU k-buffer's frame: its label, its k, and the CPU frame whose bytes it allocates (its
/// method and budget).
type KBufferRun<'a> = (
    String,
    dhoit_runtime::gpu::Slots<'a>,
    Option<(Method, Budget)>,
);

/// Tinted glass in the GPU's k-buffers (FKB, an uploaded k, VKB and DKB, each truncating and
/// keeping every fragment; the one-pass capture and the portable one): each slot keeps its
/// fragment's tint (the tint pass), the tail its tints' absorption per channel, and the image
/// is the CPU's hybrid twin (composite::hybrid_sorted) of the GPU's own fragments at the k the
/// frame stored, within float rounding. The portable capture leaves the same slots and image
/// as the one-pass one; the grey frames differ; and the tints are counted
/// (`budget::kbuffer_tint_words`), on the GPU as on the CPU.
/// DKB's features pass reads what tinted glass lets through, as its twin does: its opacity sums
/// on the GPU are `importance::pixel_stats`'s of the GPU's own fragments, tints and all
/// (`importance::filtered_alpha8`), with either capture, and differ from grey glass's sums where
/// the panes filter.
#[test]
fn dkb_s_features_read_tinted_glass_like_their_twin() {
    use dhoit_runtime::gpu::{Capture, FrameOptions, Slots};
    use dhoit_runtime::importance::{PixelStats, pixel_stats};
    use dhoit_runtime::shared::TAIL_WORDS;
    let Some(g) = gpu() else { return };
    let wide_ok = common::is_wide(
        g,
        "DKB's features of tinted glass with the one-pass capture",
    );
    let size = (192, 144);
    let mlp = Mlp::random(6);
    // The built-in windows: tinted and clear panes in front of one another and of vessels.
    let mut s = dhoit_runtime::scene::load("windows", Default::default()).unwrap();
    s.glass = Glass::Tinted;
    let (mut compared, mut filtered, mut frames) = (0, 0, 0);
    for view in [0, 3] {
        let cam = Camera::orbit(&s, view, 8, size);
        let ab = g.render(&s, &cam, size, BG, Slots::Exact).unwrap();
        let gfl = ab.fragments.clone().unwrap();
        assert!(
            gfl.tinted_glass && gfl.tinted(),
            "view {view}: tinted fragments"
        );
        let twin = pixel_stats(&gfl);
        let grey = pixel_stats(&FragmentLists {
            tint: Vec::new(),
            ..gfl.clone()
        });
        let f = gfl.fragment_count() as u64 / 4;
        let captures = [Capture::Portable]
            .into_iter()
            .chain(wide_ok.then_some(Capture::Wide));
        for capture in captures {
            let options = FrameOptions {
                capture,
                ..FrameOptions::default().always_approximate()
            };
            let d = g
                .render_with(&options, &s, &cam, size, BG, Slots::Dkb(&mlp, f.into()))
                .unwrap();
            let stats = d.stats.clone().expect("the features pass drew");
            frames += 1;
            for (p, (a, b)) in stats.iter().zip(&twin).enumerate() {
                if b.count <= TAIL_WORDS {
                    continue;
                }
                let b = PixelStats {
                    farthest: [0; 2],
                    ..*b
                };
                assert_eq!(a, &b, "view {view}, {capture:?}: pixel {p}");
                compared += 1;
                if a.alpha_sum != grey[p].alpha_sum {
                    assert!(
                        a.alpha_sum > grey[p].alpha_sum && a.optical_depth > grey[p].optical_depth
                    );
                    filtered += 1;
                }
            }
        }
    }
    // Over both views, each capture the device has (the portable one alone on WebGPU's core
    // device): 73 deep pixels a frame here, every one behind tinted glass.
    assert!(
        compared >= 50 * frames && filtered >= 50 * frames,
        "{compared} pixels compared, {filtered} filtered, in {frames} frames"
    );
}

#[test]
fn tinted_glass_in_the_gpu_k_buffers_is_their_twins() {
    use dhoit_runtime::gpu::{Capture, FrameOptions, Slots};
    let Some(g) = gpu() else { return };
    let wide_ok = common::is_wide(g, "the one-pass capture of tinted glass");
    let (w, h) = SIZE;
    let px = (w * h) as u64;
    let mlp = Mlp::random(6);
    let grey_of = |s: &Scene| Scene {
        glass: Glass::Grey,
        ..s.clone()
    };
    let (mut truncated, mut grey_differ, mut ties, mut bytes_held) = (0, 0, 0, 0);
    for (name, s) in [
        ("coplanar tints", coplanar_tints()),
        (
            "stained glass",
            Scene {
                glass: Glass::Tinted,
                ..stained_glass_and_emission()
            },
        ),
    ] {
        for view in [0, 3] {
            let cam = camera(&s, view);
            let ab = g
                .render(&s, &cam, (w, h), BG, dhoit_runtime::gpu::Slots::Exact)
                .unwrap();
            let gfl = ab.fragments.clone().unwrap();
            let total = gfl.fragment_count() as u64;
            // Pixels where fragments of one key carry different tints.
            ties += (0..gfl.pixel_count())
                .filter(|&p| {
                    let r = gfl.range(p);
                    r.clone().any(|i| {
                        r.clone().any(|j| {
                            gfl.depth[i] == gfl.depth[j]
                                && gfl.rgba[i] == gfl.rgba[j]
                                && gfl.tint(i) != gfl.tint(j)
                        })
                    })
                })
                .count();
            let k: Vec<u32> = (0..px as u32).map(|p| p % 5).collect();
            let mut runs: Vec<KBufferRun> = vec![
                (
                    "fkb k = 1".into(),
                    Slots::Uniform(1),
                    Some((Method::Fkb, Budget::SlotsPerPixel(1.0))),
                ),
                (
                    "fkb k = 4".into(),
                    Slots::Uniform(4),
                    Some((Method::Fkb, Budget::SlotsPerPixel(4.0))),
                ),
                ("uploaded k".into(), Slots::PerPixel(&k), None),
            ];
            for ppm in [250_000, 500_000, 1_000_000] {
                let f = total * ppm / 1_000_000;
                let cpu = |m| Some((m, Budget::Share(ppm as u32)));
                runs.push((
                    format!("dkb F = {f}"),
                    Slots::Dkb(&mlp, f.into()),
                    cpu(Method::Dkb),
                ));
                runs.push((
                    format!("vkb F = {f}"),
                    Slots::Vkb(Default::default(), f.into()),
                    cpu(Method::Vkb),
                ));
            }
            let portable = FrameOptions {
                capture: Capture::Portable,
                ..FrameOptions::default().always_approximate()
            };
            let wide = FrameOptions::default().always_approximate();
            for (label, slots, cpu) in runs {
                let what = format!("{name} view {view} {label}");
                let frame = |opts: &FrameOptions, s: &Scene| {
                    g.render_with(opts, s, &cam, (w, h), BG, slots)
                        .unwrap_or_else(|e| panic!("{what}: {e}"))
                };
                let b = frame(&portable, &s);
                let (_, bases, tails) = b.slots.clone().unwrap();
                let stored: Vec<u32> = bases.windows(2).map(|b| b[1] - b[0]).collect();
                truncated += tails.chunks_exact(5).filter(|t| t[4] > 0).count();
                let twin = composite::composite(&gfl, composite::Method::Hybrid(&stored), BG);
                let (n, worst) = differing(&twin, &b.image, IMAGE_BOUND);
                assert_eq!(n, 0, "{what}: {n} pixels off the twin (worst {worst})");
                let grey = frame(&portable, &grey_of(&s));
                grey_differ += differing(&grey.image, &b.image, STEP).0;
                // The tints' words: 3 a pixel and 1 a slot, or pooled 2 a pool word, which
                // holds at least the stored slots (none more where the grey frame stores them
                // too, for its colours above white).
                let extra = b.allocated_bytes - grey.allocated_bytes;
                let grey_words = grey_of(&s).tint_words();
                assert!(
                    grey_words || extra >= 4 * stored.iter().map(|&k| k as u64).sum::<u64>(),
                    "{what}: the tints take {extra} bytes"
                );
                // The CPU's count of the same frame's bytes.
                if let Some((m, budget)) = cpu {
                    let opts = Options {
                        weights: Some(&mlp),
                        ..Options::new(budget, BG).always_approximate()
                    };
                    let f = frame::render(&gfl, m, opts).unwrap();
                    // (Where F holds every fragment the CPU's frame is the exact one.)
                    if !f.exact {
                        assert_eq!(f.allocated_bytes, b.allocated_bytes, "{what}: CPU's bytes");
                        bytes_held += 1;
                    }
                }
                if !grey_words && matches!(slots, Slots::Uniform(_) | Slots::PerPixel(_)) {
                    let slots: u64 = match slots {
                        Slots::Uniform(k) => k as u64 * px,
                        _ => k.iter().map(|&k| k as u64).sum(),
                    };
                    assert_eq!(extra, 4 * (3 * px + slots), "{what}: the tints' bytes");
                }
                if wide_ok {
                    let a = frame(&wide, &s);
                    assert!(a.slots == b.slots, "{what}: the captures' slots differ");
                    assert_eq!(differing(&a.image, &b.image, 0.0).0, 0, "{what}: wide");
                }
            }
        }
    }
    assert!(ties > 0, "no pixel holds one key with two tints");
    assert!(truncated > 0, "no pixel kept a tail");
    assert!(
        bytes_held >= 8,
        "{bytes_held} frames' bytes held to the CPU's"
    );
    assert!(grey_differ > 0, "tinted glass renders as grey");
}

/// A byte budget holds a tinted k-buffer's tints too (`Layout::tinted_fragment_budget`), and
/// the linked list's: at budgets up to the tinted A-buffer's bytes, FKB's, VKB's, DKB's, the
/// optimal allocation's and the list's tinted frames allocate no more than M, on fewer slots
/// than the grey frame's where they truncate, and one too small for the tints is refused
/// naming them. At equal bytes DKB's tinted frame gets the F its grey frame gets: the bytes it
/// spends count its tints, as the bytes a share reserves do.
#[test]
fn tinted_k_buffers_stay_within_a_byte_budget() {
    let s = coplanar_tints();
    let grey = Scene {
        glass: Glass::Grey,
        ..s.clone()
    };
    let mlp = Mlp::random(6);
    let (mut held, mut fewer, mut refused) = (0, 0, 0);
    for view in [0, 2] {
        let cam = camera(&s, view);
        let (tinted_fl, grey_fl) = (
            rasterize(&s, &cam, (SIZE.0, SIZE.1)).unwrap(),
            rasterize(&grey, &cam, (SIZE.0, SIZE.1)).unwrap(),
        );
        assert!(tinted_fl.tinted() && !grey_fl.tinted());
        let methods = [
            Method::Fkb,
            Method::Vkb,
            Method::Dkb,
            Method::Optimal,
            Method::LinkedList,
        ];
        // From a fortieth of the tinted A-buffer's bytes to all of them.
        let most = dhoit_runtime::budget::abuffer_bytes(
            tinted_fl.pixel_count() as u64,
            tinted_fl.fragment_count() as u64,
            true,
        );
        for m in methods {
            for step in 1..=40 {
                let bytes = most * step / 40;
                let kib = bytes as f64 / 1024.0;
                let opts = Options {
                    weights: Some(&mlp),
                    ..Options::new(Budget::Bytes(bytes), BG).always_approximate()
                };
                let (t, g) = (
                    frame::render(&tinted_fl, m, opts),
                    frame::render(&grey_fl, m, opts),
                );
                match (t, g) {
                    (Ok(t), Ok(g)) if !t.exact => {
                        assert!(
                            t.allocated_bytes <= bytes,
                            "{m} {kib} KiB: {}",
                            t.allocated_bytes
                        );
                        assert!(t.budget_fragments <= g.budget_fragments, "{m} {kib} KiB");
                        held += 1;
                        fewer += (t.budget_fragments < g.budget_fragments) as usize;
                    }
                    // The grey frame truncates where the tinted one does not fit.
                    (Err(e), Ok(g)) if !g.exact => {
                        let e = e.to_string();
                        assert!(
                            e.contains("tint words (tinted glass, colours above white) take"),
                            "{m} {kib} KiB: {e}"
                        );
                        refused += 1;
                    }
                    _ => {}
                }
            }
        }
    }
    eprintln!("{held} truncated frames, {fewer} on fewer slots, {refused} refused for the tints");
    assert!(held >= 10 && fewer >= 5 && refused > 0);
    let mut equal = 0;
    // Twenty-four panes deep: truncated, DKB takes fewer bytes than the A-buffer.
    let mut deep = coplanar_tints();
    let panes = deep.triangle_count();
    for i in 0..24 {
        let z = -0.6 + 0.05 * i as f32;
        let m = (i % 3) as u32;
        let uv = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
        quad(&mut deep, layer(z, 0.9, 0.02), uv, [[1.0; 4]; 4], m);
    }
    assert!(deep.triangle_count() > panes);
    for ((s, view), ppm) in [(&s, 0), (&deep, 0), (&deep, 3)]
        .into_iter()
        .flat_map(|v| [50_000, 100_000, 250_000, 500_000].map(|p| (v, p)))
    {
        let fl = rasterize(s, &camera(s, view), (SIZE.0, SIZE.1)).unwrap();
        let at = |e| Options {
            weights: Some(&mlp),
            equal: e,
            ..Options::new(Budget::Share(ppm), BG).always_approximate()
        };
        let tinted = frame::render(&fl, Method::Dkb, at(frame::Equal::Bytes)).unwrap();
        // At equal F the bytes it reserves for the share count its tints too.
        for m in [Method::Dkb, Method::Vkb, Method::LinkedList] {
            let f = frame::render(&fl, m, at(frame::Equal::Slots)).unwrap();
            assert!(
                f.exact || f.allocated_bytes <= f.budget_bytes,
                "{m} {ppm} ppm: {} of {}",
                f.allocated_bytes,
                f.budget_bytes
            );
        }
        let g = Scene {
            glass: Glass::Grey,
            ..s.clone()
        };
        let grey_fl = rasterize(&g, &camera(&g, view), (SIZE.0, SIZE.1)).unwrap();
        let grey = frame::render(&grey_fl, Method::Dkb, at(frame::Equal::Bytes)).unwrap();
        if !tinted.exact {
            assert_eq!(tinted.budget_fragments, grey.budget_fragments, "{ppm} ppm");
            assert!(tinted.allocated_bytes <= tinted.budget_bytes);
            assert!(
                tinted.budget_bytes > grey.budget_bytes,
                "{ppm} ppm: the tints' bytes"
            );
            equal += 1;
        }
    }
    assert!(equal > 0);
}

/// A stream of tinted frames (as a renderer draws dhoit's own scene, `SceneStream`) holds a
/// byte budget with its tints: FKB's, VKB's, DKB's and the list's frames report no more bytes
/// than M, and no error.
#[test]
fn a_tinted_stream_holds_its_byte_budget() {
    use dhoit_runtime::gpu::{SceneStream, wgpu};
    let Some(g) = gpu() else { return };
    let s = coplanar_tints();
    let mlp = Mlp::random(6);
    let cams: Vec<Camera> = (0..3).map(|v| camera(&s, v)).collect();
    let fl = rasterize(&s, &cams[0], (SIZE.0, SIZE.1)).unwrap();
    // The tinted A-buffer's bytes.
    let most = dhoit_runtime::budget::abuffer_bytes(
        fl.pixel_count() as u64,
        fl.fragment_count() as u64,
        true,
    );
    let mut truncated = 0;
    for m in [Method::Fkb, Method::Vkb, Method::Dkb, Method::LinkedList] {
        for bytes in [most * 3 / 4, most * 9 / 10] {
            let options = Options {
                weights: Some(&mlp),
                ..Options::new(Budget::Bytes(bytes), BG).always_approximate()
            };
            let mut stream = match SceneStream::new(g, &s, SIZE, m, &options) {
                Ok(st) => st,
                // A budget that leaves no slot beside the tints is refused naming them.
                Err(e) => {
                    let e = e.to_string();
                    assert!(e.contains("budget"), "{m} {bytes}: {e}");
                    continue;
                }
            };
            let device = g.device();
            let mut reports = Vec::new();
            for cam in cams.iter().chain(&cams) {
                let mut enc = device.create_command_encoder(&Default::default());
                stream.record(&mut enc, cam).unwrap();
                g.queue().submit([enc.finish()]);
                device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
                reports.extend(stream.finished(true).unwrap());
            }
            for r in &reports {
                assert!(r.error.is_none(), "{m} {bytes}: {:?}", r.error);
                assert!(
                    r.allocated_bytes <= bytes,
                    "{m} frame {}: {} bytes over {bytes}",
                    r.frame,
                    r.allocated_bytes
                );
                truncated += !r.exact as usize;
            }
        }
    }
    assert!(truncated > 0, "no streamed frame truncated");
}

/// The sRGB decode, bilinear filtering and Schlick's Fresnel, held to numbers computed by hand
/// (the twins share these functions, so the GPU agreeing with the CPU says nothing of them).
#[test]
fn srgb_bilinear_and_fresnel_are_the_formulas_by_hand() {
    use dhoit_runtime::scene::material::{glass_opacity, srgb_table, srgb_to_linear};
    // sRGB: 0.5 -> ((0.5 + 0.055) / 1.055)^2.4 = 0.214041; the linear segment below 0.04045;
    // 1 -> 1, 0 -> 0; 8-bit 128 -> 0.215861.
    assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-6);
    assert!((srgb_to_linear(0.04) - 0.04 / 12.92).abs() < 1e-9);
    let table = srgb_table();
    assert_eq!((table[0], table[255]), (0.0, 1.0));
    assert!((table[128] - 0.215_861).abs() < 1e-6, "{}", table[128]);
    // Bilinear: a 2x2 texture of linear alphas 0, 1/5, 2/5, 3/5 (alpha is not sRGB); at the
    // centre every texel weighs 1/4: 0.3; a quarter of the way from the first texel's centre
    // to the second's along u: 3/4 x 0 + 1/4 x 0.2 = 0.05.
    let t = Texture {
        width: 2,
        height: 2,
        texels: [0u32, 51, 102, 153].map(|a| 0x00ff_ffff | a << 24).to_vec(),
        wrap: [Wrap::ClampToEdge; 2],
        nearest: false,
    };
    let at = |u: f32, v: f32| t.sample(&table, [u, v])[3];
    assert!((at(0.5, 0.5) - 0.3).abs() < 1e-6, "{}", at(0.5, 0.5));
    assert!((at(0.375, 0.25) - 0.05).abs() < 1e-6, "{}", at(0.375, 0.25));
    // Nearest: the texel the point falls in.
    let n = Texture {
        nearest: true,
        ..t.clone()
    };
    assert!((n.sample(&table, [0.9, 0.9])[3] - 0.6).abs() < 1e-6);
    // Fresnel (Schlick, F0 0.04): face-on F = F0; at cos 1/2, F = 0.04 + 0.96 / 32 = 0.07; at
    // grazing F = 1. Clear glass (T = 1) is as opaque as F; T = 0.5 at face-on: 1 - 0.5 x 0.96.
    assert!((glass_opacity(1.0, 0.04, 1.0) - 0.04).abs() < 1e-7);
    assert!((glass_opacity(1.0, 0.04, 0.5) - 0.07).abs() < 1e-7);
    assert!((glass_opacity(1.0, 0.04, 0.0) - 1.0).abs() < 1e-7);
    assert!((glass_opacity(0.5, 0.04, 1.0) - 0.52).abs() < 1e-7);
    // F0 of IOR 1.5 and 1.0.
    let m = |ior| {
        Material {
            ior,
            ..Material::default()
        }
        .f0()
    };
    assert!((m(1.5) - 0.04).abs() < 1e-7 && m(1.0) == 0.0);
}
