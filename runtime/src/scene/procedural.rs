//! Built-in procedural scenes, generated from a seed with no files.
//!
//! They differ in kind and span maximum depth complexity from about ten fragments per pixel
//! (`shells`) to well over a hundred (`particles`, `hair`). A name may carry a seed, as in
//! `particles:7`; without one each scene uses its default seed.
//!
//! Two kinds: the papers' families ([`BUILTIN`]'s first ten), seen at one uniform opacity
//! (their vertex alpha, set per object, is what `--material-alpha` keeps), and the material
//! families ([`MATERIAL_FAMILIES`]), whose own materials decide, as real scenes' do: opaque
//! parts, glass in opaque frames, transparent covers, alpha-textured cards, soft particles with
//! embers emitting above white, and strands whose textures fade (procedural textures, sampled
//! per fragment).

use super::Scene;
use super::material::{Coverage, Material, Texture, Wrap, pack_texel};
use crate::rng::Rng;
use glam::Vec3;
use std::f32::consts::{PI, TAU};

/// Names of the built-in scenes with a one-line description each.
pub const BUILTIN: &[(&str, &str)] = &[
    ("shells", "six nested spherical shells (low depth, smooth)"),
    ("spheres", "a cloud of 40 overlapping spheres"),
    ("foliage", "a canopy of 900 leaf cards around a trunk"),
    ("plates", "48 stacked CAD-like plates with bolts"),
    ("hair", "3000 curved hair strands from a scalp"),
    ("particles", "12000 billboard particles in a gaussian cloud"),
    (
        "cad",
        "a mechanical assembly: housing, shafts, gears, bolts, pipes",
    ),
    (
        "glass",
        "a few glass vessels with walls, liquid and a glass shelf",
    ),
    (
        "statue",
        "a scanned-looking closed figure with folds, stone texture",
    ),
    ("shrub", "a dense shrub of 5000 small leaves and flowers"),
    (
        "windows",
        "materials: glass panes (clear, stained, frosted, broken) in opaque frames, objects behind",
    ),
    (
        "covers",
        "materials: opaque gears and shafts under transparent plastic covers and inserts",
    ),
    (
        "cards",
        "materials: alpha-textured leaf cards (masked and blended) on opaque branches",
    ),
    (
        "smoke",
        "materials: soft particles with a radial alpha texture around opaque chimneys, and embers glowing above white",
    ),
    (
        "strands",
        "materials: hair strands whose alpha fades to the tips, around an opaque head",
    ),
];

/// The built-in families whose own materials decide (opaque parts, textured and varied
/// opacity); the others are the papers' uniform-opacity families.
pub const MATERIAL_FAMILIES: [&str; 5] = ["windows", "covers", "cards", "smoke", "strands"];

const DEFAULT_SEED: u64 = 1;

/// Builds a built-in scene by name (`name` or `name:seed`); `None` when the name is not built in.
pub fn build(spec: &str) -> Option<Scene> {
    let (name, seed) = match spec.split_once(':') {
        Some((n, s)) => (n, s.parse::<u64>().ok()?),
        None => (spec, DEFAULT_SEED),
    };
    let mut rng = Rng::new(seed.wrapping_mul(0x1000_0000_01B3) ^ name.len() as u64);
    let mut s = Scene {
        name: spec.to_string(),
        ..Scene::default()
    };
    match name {
        "shells" => shells(&mut s, &mut rng),
        "spheres" => spheres(&mut s, &mut rng),
        "foliage" => foliage(&mut s, &mut rng),
        "plates" => plates(&mut s, &mut rng),
        "hair" => hair(&mut s, &mut rng),
        "particles" => particles(&mut s, &mut rng),
        "cad" => cad(&mut s, &mut rng),
        "glass" => glass(&mut s, &mut rng),
        "statue" => statue(&mut s, &mut rng),
        "shrub" => shrub(&mut s, &mut rng),
        "windows" => windows(&mut s, &mut rng),
        "covers" => covers(&mut s, &mut rng),
        "cards" => cards(&mut s, &mut rng),
        "smoke" => smoke(&mut s, &mut rng),
        "strands" => strands(&mut s, &mut rng),
        _ => return None,
    }
    // The papers' families: one uniform opacity unless a caller asks for their vertex alpha.
    if !MATERIAL_FAMILIES.contains(&name) {
        s.uniform_opacity = Some(super::PAPER_OPACITY);
    }
    Some(s)
}

fn hue(rng: &mut Rng, alpha: f32) -> [f32; 4] {
    let h = rng.f32() * 6.0;
    let x = 1.0 - ((h % 2.0) - 1.0).abs();
    let (r, g, b) = match h as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    let s = rng.range(0.5, 0.9);
    let v = rng.range(0.6, 1.0);
    let mix = |c: f32| v * (1.0 - s + s * c);
    [mix(r), mix(g), mix(b), alpha]
}

/// The corners of a card of half-width `w` along `t` and half-height `h` along `b` around
/// `centre`, counter-clockwise from (-w, -h).
fn billboard(centre: Vec3, t: Vec3, b: Vec3, w: f32, h: f32) -> [Vec3; 4] {
    [
        centre - t * w - b * h,
        centre + t * w - b * h,
        centre + t * w + b * h,
        centre - t * w + b * h,
    ]
}

fn quad(s: &mut Scene, p: [Vec3; 4], c: [f32; 4]) {
    s.push_triangle([p[0], p[1], p[2]], [c; 3]);
    s.push_triangle([p[0], p[2], p[3]], [c; 3]);
}

fn sphere(s: &mut Scene, centre: Vec3, radius: f32, slices: u32, stacks: u32, c: [f32; 4]) {
    let point = |i: u32, j: u32| {
        let theta = PI * j as f32 / stacks as f32;
        let phi = TAU * i as f32 / slices as f32;
        centre
            + radius
                * Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                )
    };
    for j in 0..stacks {
        for i in 0..slices {
            let (a, b, cc, d) = (
                point(i, j),
                point(i + 1, j),
                point(i + 1, j + 1),
                point(i, j + 1),
            );
            if j != 0 {
                s.push_triangle([a, b, cc], [c; 3]);
            }
            if j != stacks - 1 {
                s.push_triangle([a, cc, d], [c; 3]);
            }
        }
    }
}

fn cylinder(s: &mut Scene, base: Vec3, height: f32, radius: f32, slices: u32, c: [f32; 4]) {
    for i in 0..slices {
        let a0 = TAU * i as f32 / slices as f32;
        let a1 = TAU * (i + 1) as f32 / slices as f32;
        let p0 = base + radius * Vec3::new(a0.cos(), 0.0, a0.sin());
        let p1 = base + radius * Vec3::new(a1.cos(), 0.0, a1.sin());
        let up = Vec3::Y * height;
        quad(s, [p0, p1, p1 + up, p0 + up], c);
    }
}

/// A unit box's faces, each four corners of (x, y, z) in {-1, 1}: z = -1, z = 1, x = -1,
/// x = 1, y = -1 (the open housing's five), then y = 1.
const BOX_FACES: [[(f32, f32, f32); 4]; 6] = [
    [
        (-1., -1., -1.),
        (1., -1., -1.),
        (1., 1., -1.),
        (-1., 1., -1.),
    ],
    [(-1., -1., 1.), (1., -1., 1.), (1., 1., 1.), (-1., 1., 1.)],
    [
        (-1., -1., -1.),
        (-1., 1., -1.),
        (-1., 1., 1.),
        (-1., -1., 1.),
    ],
    [(1., -1., -1.), (1., 1., -1.), (1., 1., 1.), (1., -1., 1.)],
    [
        (-1., -1., -1.),
        (1., -1., -1.),
        (1., -1., 1.),
        (-1., -1., 1.),
    ],
    [(-1., 1., -1.), (1., 1., -1.), (1., 1., 1.), (-1., 1., 1.)],
];

fn boxed(s: &mut Scene, centre: Vec3, half: Vec3, rot: glam::Quat, c: [f32; 4]) {
    let corner = |x: f32, y: f32, z: f32| centre + rot * (half * Vec3::new(x, y, z));
    for f in BOX_FACES {
        let p = f.map(|(x, y, z)| corner(x, y, z));
        quad(s, p, c);
    }
}

fn shells(s: &mut Scene, rng: &mut Rng) {
    for i in 0..6 {
        let r = 0.35 + 0.13 * i as f32;
        let c = hue(rng, 0.25 + 0.1 * i as f32);
        sphere(s, Vec3::ZERO, r, 40, 20, c);
    }
}

fn spheres(s: &mut Scene, rng: &mut Rng) {
    for _ in 0..40 {
        let centre = rng.unit_vector() * rng.f32().cbrt() * 0.8;
        let alpha = rng.range(0.2, 0.6);
        let c = hue(rng, alpha);
        sphere(s, centre, rng.range(0.15, 0.4), 24, 12, c);
    }
}

fn foliage(s: &mut Scene, rng: &mut Rng) {
    let bark = [0.35, 0.22, 0.12, 0.9];
    cylinder(s, Vec3::new(0.0, -1.2, 0.0), 1.2, 0.08, 16, bark);
    for _ in 0..900 {
        let centre = Vec3::new(0.0, 0.25, 0.0) + rng.unit_vector() * rng.f32().sqrt() * 0.9;
        let n = rng.unit_vector();
        let t = n.any_orthonormal_vector();
        let b = n.cross(t);
        let (w, h) = (rng.range(0.06, 0.12), rng.range(0.12, 0.22));
        let green = [
            rng.range(0.1, 0.35),
            rng.range(0.45, 0.8),
            rng.range(0.1, 0.3),
            rng.range(0.5, 0.9),
        ];
        quad(s, billboard(centre, t, b, w, h), green);
    }
}

fn plates(s: &mut Scene, rng: &mut Rng) {
    for i in 0..48 {
        let y = -0.96 + 0.04 * i as f32;
        let rot = glam::Quat::from_rotation_y(rng.range(-0.08, 0.08));
        let alpha = rng.range(0.3, 0.7);
        let c = hue(rng, alpha);
        boxed(
            s,
            Vec3::new(rng.range(-0.05, 0.05), y, 0.0),
            Vec3::new(0.8, 0.006, 0.6),
            rot,
            c,
        );
    }
    let steel = [0.7, 0.7, 0.75, 0.8];
    for (x, z) in [(-0.7, -0.5), (0.7, -0.5), (-0.7, 0.5), (0.7, 0.5)] {
        cylinder(s, Vec3::new(x, -1.0, z), 2.0, 0.04, 12, steel);
    }
}

fn hair(s: &mut Scene, rng: &mut Rng) {
    const SEGMENTS: usize = 10;
    for _ in 0..3000 {
        // Root on the upper half of a unit scalp, growing outwards then falling under gravity.
        let mut d = rng.unit_vector();
        d.y = d.y.abs();
        let mut p = d * 0.5;
        let mut v = d * 0.08;
        let c = {
            let base = rng.range(0.25, 0.5);
            [base * 1.3, base * 0.9, base * 0.5, rng.range(0.3, 0.7)]
        };
        let width = rng.range(0.006, 0.012);
        let side = d.cross(Vec3::Y).normalize_or(Vec3::X) * width;
        for _ in 0..SEGMENTS {
            let next = p + v;
            v = (v + Vec3::new(0.0, -0.035, 0.0) + rng.unit_vector() * 0.01) * 0.98;
            quad(s, [p - side, p + side, next + side, next - side], c);
            p = next;
        }
    }
}

fn particles(s: &mut Scene, rng: &mut Rng) {
    for _ in 0..12000 {
        let centre = Vec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.35;
        let n = rng.unit_vector();
        let t = n.any_orthonormal_vector();
        let b = n.cross(t);
        let r = rng.range(0.05, 0.1);
        let alpha = rng.range(0.05, 0.4);
        let c = hue(rng, alpha);
        quad(s, billboard(centre, t, b, r, r), c);
    }
}

/// A colour with a little per-vertex variation, as a texture sampled per vertex gives.
fn jitter(rng: &mut Rng, c: [f32; 4], amount: f32) -> [f32; 4] {
    let v = 1.0 + rng.range(-amount, amount);
    [
        (c[0] * v).clamp(0.0, 1.0),
        (c[1] * v).clamp(0.0, 1.0),
        (c[2] * v).clamp(0.0, 1.0),
        c[3],
    ]
}

/// A closed cylinder along `axis` (unit) from `base`, with end caps.
fn solid_cylinder(
    s: &mut Scene,
    base: Vec3,
    axis: Vec3,
    length: f32,
    radius: f32,
    slices: u32,
    c: [f32; 4],
) {
    let u = axis.any_orthonormal_vector();
    let v = axis.cross(u);
    let top = base + axis * length;
    for i in 0..slices {
        let a0 = TAU * i as f32 / slices as f32;
        let a1 = TAU * (i + 1) as f32 / slices as f32;
        let r0 = (u * a0.cos() + v * a0.sin()) * radius;
        let r1 = (u * a1.cos() + v * a1.sin()) * radius;
        quad(s, [base + r0, base + r1, top + r1, top + r0], c);
        s.push_triangle([base, base + r1, base + r0], [c; 3]);
        s.push_triangle([top, top + r0, top + r1], [c; 3]);
    }
}

/// A gear: an extruded disc with `teeth` teeth, centred on `centre`, axis `axis`.
fn gear(s: &mut Scene, centre: Vec3, axis: Vec3, radius: f32, width: f32, teeth: u32, c: [f32; 4]) {
    let u = axis.any_orthonormal_vector();
    let v = axis.cross(u);
    let n = teeth * 4;
    let rim = |i: u32| {
        let a = TAU * i as f32 / n as f32;
        let r = if (i / 2).is_multiple_of(2) {
            radius
        } else {
            radius * 0.85
        };
        (u * a.cos() + v * a.sin()) * r
    };
    let (f, b) = (centre - axis * width * 0.5, centre + axis * width * 0.5);
    for i in 0..n {
        let (p0, p1) = (rim(i), rim(i + 1));
        s.push_triangle([f, f + p0, f + p1], [c; 3]);
        s.push_triangle([b, b + p1, b + p0], [c; 3]);
        quad(s, [f + p0, f + p1, b + p1, b + p0], c);
    }
}

/// A torus section (a bent pipe) around `centre` in the plane of `u`, `v`.
fn pipe(s: &mut Scene, centre: Vec3, [u, v]: [Vec3; 2], bend: f32, r: f32, arc: f32, c: [f32; 4]) {
    let (segs, ring) = (24u32, 10u32);
    let point = |i: u32, j: u32| {
        let a = arc * i as f32 / segs as f32;
        let b = TAU * j as f32 / ring as f32;
        let dir = u * a.cos() + v * a.sin();
        let normal = dir.cross(u.cross(v)).normalize();
        centre + dir * (bend + r * b.cos()) + normal * (r * b.sin())
    };
    for i in 0..segs {
        for j in 0..ring {
            quad(
                s,
                [
                    point(i, j),
                    point(i + 1, j),
                    point(i + 1, j + 1),
                    point(i, j + 1),
                ],
                c,
            );
        }
    }
}

/// A thin-walled open box (a housing): outer and inner walls of the four sides and the floor.
fn housing(s: &mut Scene, centre: Vec3, half: Vec3, wall: f32, c: [f32; 4]) {
    for inset in [0.0, wall] {
        let h = half - Vec3::splat(inset);
        let corner = |x: f32, y: f32, z: f32| centre + h * Vec3::new(x, y, z);
        // The four sides and the floor: open at y = 1.
        for f in &BOX_FACES[..5] {
            quad(s, f.map(|(x, y, z)| corner(x, y, z)), c);
        }
    }
}

fn cad(s: &mut Scene, rng: &mut Rng) {
    let steel = |rng: &mut Rng| {
        let g = rng.range(0.45, 0.8);
        [g, g, g * rng.range(1.0, 1.15), rng.range(0.5, 0.9)]
    };
    let c = steel(rng);
    housing(
        s,
        Vec3::new(0.0, -0.1, 0.0),
        Vec3::new(0.9, 0.45, 0.6),
        0.04,
        c,
    );
    let plate = hue(rng, 0.6);
    boxed(
        s,
        Vec3::new(0.0, -0.6, 0.0),
        Vec3::new(1.1, 0.04, 0.8),
        glam::Quat::IDENTITY,
        plate,
    );
    let shafts = 2 + rng.below(3);
    for i in 0..shafts {
        let z = -0.4 + 0.8 * (i as f32 + 0.5) / shafts as f32;
        let y = rng.range(-0.25, 0.15);
        let c = steel(rng);
        solid_cylinder(
            s,
            Vec3::new(-1.1, y, z),
            Vec3::X,
            2.2,
            rng.range(0.04, 0.08),
            16,
            c,
        );
        for _ in 0..1 + rng.below(3) {
            let gc = {
                let a = rng.range(0.4, 0.8);
                hue(rng, a)
            };
            let x = rng.range(-0.7, 0.7);
            gear(
                s,
                Vec3::new(x, y, z),
                Vec3::X,
                rng.range(0.12, 0.3),
                rng.range(0.04, 0.1),
                10 + rng.below(14) as u32,
                gc,
            );
        }
    }
    for _ in 0..12 {
        let c = steel(rng);
        let p = Vec3::new(rng.range(-1.0, 1.0), -0.64, rng.range(-0.7, 0.7));
        solid_cylinder(s, p, Vec3::Y, rng.range(0.15, 0.35), 0.03, 8, c);
    }
    for _ in 0..3 {
        let c = {
            let a = rng.range(0.4, 0.7);
            hue(rng, a)
        };
        let centre = Vec3::new(
            rng.range(-0.6, 0.6),
            rng.range(0.1, 0.5),
            rng.range(-0.4, 0.4),
        );
        let u = rng.unit_vector();
        let v = u.any_orthonormal_vector();
        pipe(
            s,
            centre,
            [u, v],
            rng.range(0.2, 0.4),
            0.04,
            rng.range(1.5, 4.0),
            c,
        );
    }
}

/// A surface of revolution around Y through `profile` (radius, height) points.
fn lathe(s: &mut Scene, base: Vec3, profile: &[(f32, f32)], slices: u32, c: [f32; 4]) {
    let point = |i: u32, (r, y): (f32, f32)| {
        let a = TAU * i as f32 / slices as f32;
        base + Vec3::new(r * a.cos(), y, r * a.sin())
    };
    for w in profile.windows(2) {
        for i in 0..slices {
            quad(
                s,
                [
                    point(i, w[0]),
                    point(i + 1, w[0]),
                    point(i + 1, w[1]),
                    point(i, w[1]),
                ],
                c,
            );
        }
    }
}

fn glass(s: &mut Scene, rng: &mut Rng) {
    let tint = |rng: &mut Rng| {
        let base = {
            let a = rng.range(0.15, 0.45);
            hue(rng, a)
        };
        let mix = rng.range(0.5, 0.85);
        [
            base[0] * (1.0 - mix) + mix,
            base[1] * (1.0 - mix) + mix,
            base[2] * (1.0 - mix) + mix,
            base[3],
        ]
    };
    let c = tint(rng);
    boxed(
        s,
        Vec3::new(0.0, -0.62, 0.0),
        Vec3::new(1.0, 0.02, 0.5),
        glam::Quat::IDENTITY,
        c,
    );
    let vessels = 2 + rng.below(3);
    for i in 0..vessels {
        let x = -0.7 + 1.4 * (i as f32 + 0.5) / vessels as f32 + rng.range(-0.1, 0.1);
        let z = rng.range(-0.2, 0.2);
        let (belly, neck, height) = (
            rng.range(0.15, 0.3),
            rng.range(0.05, 0.15),
            rng.range(0.6, 1.2),
        );
        let outer: Vec<(f32, f32)> = (0..=12)
            .map(|j| {
                let t = j as f32 / 12.0;
                let r = neck + (belly - neck) * (PI * t.min(0.8) / 0.8).sin().max(0.0);
                (r.max(0.02), t * height)
            })
            .collect();
        let inner: Vec<(f32, f32)> = outer
            .iter()
            .map(|&(r, y)| ((r - 0.015).max(0.01), y))
            .collect();
        let base = Vec3::new(x, -0.6, z);
        let c = tint(rng);
        lathe(s, base, &outer, 32, c);
        lathe(s, base, &inner, 32, c);
        if rng.f32() < 0.6 {
            let level = rng.range(0.2, 0.6);
            let liquid: Vec<(f32, f32)> = inner
                .iter()
                .filter(|p| p.1 <= level * height)
                .map(|&(r, y)| ((r - 0.005).max(0.005), y))
                .collect();
            if liquid.len() >= 2 {
                lathe(s, base, &liquid, 32, {
                    let a = rng.range(0.4, 0.7);
                    hue(rng, a)
                });
            }
        }
    }
}

fn statue(s: &mut Scene, rng: &mut Rng) {
    // A displaced sphere with a few bulges and folds, and two limbs.
    let bumps: Vec<(Vec3, f32, f32)> = (0..10)
        .map(|_| {
            (
                rng.unit_vector(),
                rng.range(-0.25, 0.35),
                rng.range(0.2, 0.6),
            )
        })
        .collect();
    let stone = [
        rng.range(0.55, 0.8),
        rng.range(0.5, 0.7),
        rng.range(0.4, 0.6),
        0.8,
    ];
    let (slices, stacks) = (72u32, 36u32);
    let surface = |i: u32, j: u32| {
        let theta = PI * j as f32 / stacks as f32;
        let phi = TAU * i as f32 / slices as f32;
        let d = Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        );
        let mut r = 0.6;
        for (c, h, w) in &bumps {
            let t = d.dot(*c);
            r += h * (-(1.0 - t) / (w * w)).exp();
        }
        r += 0.04 * (9.0 * phi).sin() * (7.0 * theta).sin();
        d * r * Vec3::new(0.8, 1.3, 0.7)
    };
    for j in 0..stacks {
        for i in 0..slices {
            let p = [
                surface(i, j),
                surface(i + 1, j),
                surface(i + 1, j + 1),
                surface(i, j + 1),
            ];
            let c = [0; 4].map(|_| jitter(rng, stone, 0.15));
            s.push_triangle([p[0], p[1], p[2]], [c[0], c[1], c[2]]);
            s.push_triangle([p[0], p[2], p[3]], [c[0], c[2], c[3]]);
        }
    }
    for side in [-1.0f32, 1.0] {
        let c = jitter(rng, stone, 0.1);
        let start = Vec3::new(0.35 * side, 0.3, rng.range(-0.1, 0.1));
        let dir = Vec3::new(
            side * rng.range(0.3, 0.8),
            rng.range(-0.8, 0.2),
            rng.range(-0.4, 0.4),
        )
        .normalize();
        solid_cylinder(
            s,
            start,
            dir,
            rng.range(0.5, 0.8),
            rng.range(0.07, 0.12),
            16,
            c,
        );
    }
}

fn shrub(s: &mut Scene, rng: &mut Rng) {
    let clusters: Vec<Vec3> = (0..7)
        .map(|_| {
            let d = rng.unit_vector();
            Vec3::new(d.x * 0.5, d.y.abs() * 0.4, d.z * 0.5)
        })
        .collect();
    for c in &clusters {
        cylinder(
            s,
            Vec3::new(0.0, -0.9, 0.0),
            (c.y + 0.9).max(0.1),
            0.02,
            6,
            [0.3, 0.2, 0.1, 0.9],
        );
    }
    for i in 0..5000 {
        let centre = clusters[i % clusters.len()] + rng.unit_vector() * rng.f32().sqrt() * 0.45;
        let n = rng.unit_vector();
        let t = n.any_orthonormal_vector();
        let b = n.cross(t);
        let size = rng.range(0.02, 0.06);
        let c = if rng.f32() < 0.06 {
            {
                let a = rng.range(0.5, 0.9);
                hue(rng, a)
            }
        } else {
            [
                rng.range(0.05, 0.3),
                rng.range(0.3, 0.75),
                rng.range(0.05, 0.25),
                rng.range(0.6, 0.95),
            ]
        };
        let tip = centre + b * size * 2.0;
        s.push_triangle([centre - t * size, centre + t * size, tip], [c; 3]);
        s.push_triangle(
            [centre + t * size, centre - t * size, centre - b * size],
            [c; 3],
        );
    }
}

// ---- The material families ------------------------------------------------------------------

/// Runs `f`, which adds triangles of material 0, and gives the triangles it added material `m`.
fn with_material(s: &mut Scene, m: u32, f: impl FnOnce(&mut Scene)) {
    let first = s.triangle_count();
    f(s);
    for t in &mut s.triangle_material[first..] {
        *t = m;
    }
}

/// A textured quad: corners `p` with texture coordinates `uv`, one colour, material `m`.
fn tquad(s: &mut Scene, p: [Vec3; 4], uv: [[f32; 2]; 4], c: [f32; 4], m: u32) {
    s.push_textured([p[0], p[1], p[2]], [c; 3], [uv[0], uv[1], uv[2]], m);
    s.push_textured([p[0], p[2], p[3]], [c; 3], [uv[0], uv[2], uv[3]], m);
}

const UNIT_UV: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];

fn opaque(c: [f32; 3]) -> Material {
    Material {
        base_color: [c[0], c[1], c[2], 1.0],
        coverage: Coverage::Opaque,
        ..Material::default()
    }
}

fn blend(c: [f32; 3], alpha: f32) -> Material {
    Material {
        base_color: [c[0], c[1], c[2], alpha],
        coverage: Coverage::Blend,
        ..Material::default()
    }
}

fn glass_material(tint: [f32; 3], ior: f32) -> Material {
    Material {
        base_color: [tint[0], tint[1], tint[2], 1.0],
        coverage: Coverage::Opaque,
        transmission: 1.0,
        ior,
        ..Material::default()
    }
}

/// A texture of `size` (width, height) texels from a function of the texel centre's (u, v) in [0, 1] to
/// linear RGBA.
fn texture(size: (u32, u32), wrap: Wrap, f: impl Fn(f32, f32) -> [f32; 4]) -> Texture {
    let (w, h) = size;
    let texels = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| pack_texel(f((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32)))
        .collect();
    Texture {
        width: w,
        height: h,
        texels,
        wrap: [wrap; 2],
        nearest: false,
    }
}

/// Value noise in [0, 1] on a lattice of `cells` a side (wrapping), from a seed.
fn value_noise(seed: u64, cells: u32) -> impl Fn(f32, f32) -> f32 {
    let mut rng = Rng::new(seed);
    let lattice: Vec<f32> = (0..cells * cells).map(|_| rng.f32()).collect();
    move |u: f32, v: f32| {
        let (x, y) = (u * cells as f32, v * cells as f32);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |i: f32, j: f32| {
            let (i, j) = (
                (i as i64).rem_euclid(cells as i64) as u32,
                (j as i64).rem_euclid(cells as i64) as u32,
            );
            lattice[(j * cells + i) as usize]
        };
        let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
        let top = at(x0, y0) * (1.0 - sx) + at(x0 + 1.0, y0) * sx;
        let bottom = at(x0, y0 + 1.0) * (1.0 - sx) + at(x0 + 1.0, y0 + 1.0) * sx;
        top * (1.0 - sy) + bottom * sy
    }
}

/// An opaque floor under the scene, textured with tiles.
fn floor(s: &mut Scene, rng: &mut Rng, y: f32, half: f32) {
    let a = [
        rng.range(0.3, 0.6),
        rng.range(0.3, 0.5),
        rng.range(0.25, 0.45),
    ];
    let b = a.map(|c| c * 0.6);
    let tiles = texture((32, 32), Wrap::Repeat, |u, v| {
        let odd = ((u * 4.0) as u32 + (v * 4.0) as u32) % 2 == 1;
        let c = if odd { a } else { b };
        [c[0], c[1], c[2], 1.0]
    });
    let t = s.add_texture(tiles);
    let m = s.add_material(Material {
        texture: Some(t),
        ..opaque([1.0; 3])
    });
    let r = 3.0;
    tquad(
        s,
        [
            Vec3::new(-half, y, -half),
            Vec3::new(half, y, -half),
            Vec3::new(half, y, half),
            Vec3::new(-half, y, half),
        ],
        [[0.0, 0.0], [r, 0.0], [r, r], [0.0, r]],
        [1.0; 4],
        m,
    );
}

/// Glass panes in opaque frames: a room of two facades and a partition, each a grid of
/// windows (clear and tinted glass with transmission, stained glass blended through a
/// texture, frosted, and broken panes whose holes are masked), with opaque objects, glass
/// vessels and a glass shelf between them.
fn windows(s: &mut Scene, rng: &mut Rng) {
    floor(s, rng, -0.9, 1.3);
    let wood = opaque([rng.range(0.35, 0.55), rng.range(0.22, 0.32), 0.12]);
    let frame = s.add_material(wood);
    let panes = window_panes(s, rng);
    // Three walls of windows at z = -0.8, 0.0 (a partition) and 0.8.
    for (wall, z) in [-0.8f32, 0.0, 0.8].into_iter().enumerate() {
        window_wall(s, rng, (frame, &panes), wall, z);
    }
    between_the_walls(s, rng);
}

/// The windows' pane materials: stained glass (Voronoi cells of colour, leading between them),
/// broken glass (masked holes), frosted, and three tints of clear glass.
fn window_panes(s: &mut Scene, rng: &mut Rng) -> Vec<u32> {
    let stained = {
        let cells: Vec<([f32; 2], [f32; 3])> = (0..14)
            .map(|_| {
                let c = hue(rng, 1.0);
                ([rng.f32(), rng.f32()], [c[0], c[1], c[2]])
            })
            .collect();
        let tex = texture((64, 64), Wrap::Repeat, |u, v| {
            // Voronoi cells of colour, leading (near-opaque dark lines) where two meet.
            let mut d: Vec<(f32, usize)> = cells
                .iter()
                .enumerate()
                .map(|(i, (p, _))| {
                    let dx = (u - p[0]).abs().min(1.0 - (u - p[0]).abs());
                    let dy = (v - p[1]).abs().min(1.0 - (v - p[1]).abs());
                    (dx * dx + dy * dy, i)
                })
                .collect();
            d.sort_by(|a, b| a.0.total_cmp(&b.0));
            let edge = d[1].0.sqrt() - d[0].0.sqrt();
            if edge < 0.02 {
                [0.05, 0.05, 0.05, 0.95]
            } else {
                let c = cells[d[0].1].1;
                [c[0], c[1], c[2], 0.45]
            }
        });
        let t = s.add_texture(tex);
        s.add_material(Material {
            texture: Some(t),
            ..blend([1.0; 3], 1.0)
        })
    };
    let broken = {
        let noise = value_noise(rng.next_u64(), 6);
        let tex = texture((64, 64), Wrap::Repeat, |u, v| {
            let a = if noise(u, v) > 0.62 { 0.0 } else { 1.0 };
            [1.0, 1.0, 1.0, a]
        });
        let t = s.add_texture(tex);
        s.add_material(Material {
            texture: Some(t),
            coverage: Coverage::Mask(0.5),
            ..glass_material([0.8, 0.9, 1.0], 1.5)
        })
    };
    let frosted = s.add_material(blend([0.92, 0.95, 0.97], rng.range(0.45, 0.7)));
    let mut panes = vec![stained, broken, frosted];
    for _ in 0..3 {
        let tint = [
            rng.range(0.7, 1.0),
            rng.range(0.85, 1.0),
            rng.range(0.8, 1.0),
        ];
        panes.push(s.add_material(glass_material(tint, rng.range(1.45, 1.7))));
    }
    panes
}

/// One wall of windows at depth `z` (`wall` 1, the partition, leaves some openings empty): its
/// frame's bars in `frame`, a pane of `panes` in each opening.
fn window_wall(s: &mut Scene, rng: &mut Rng, (frame, panes): (u32, &[u32]), wall: usize, z: f32) {
    let (cols, rows) = (2 + rng.below(3), 2 + rng.below(2));
    let (x0, x1, y0, y1) = (-1.2, 1.2, -0.9, 0.9);
    let bar = 0.05;
    with_material(s, frame, |s| {
        for i in 0..=cols {
            let x = x0 + (x1 - x0) * i as f32 / cols as f32;
            let c = [1.0; 4];
            boxed(
                s,
                Vec3::new(x, 0.0, z),
                Vec3::new(bar, (y1 - y0) / 2.0, bar),
                glam::Quat::IDENTITY,
                c,
            );
        }
        for j in 0..=rows {
            let y = y0 + (y1 - y0) * j as f32 / rows as f32;
            boxed(
                s,
                Vec3::new(0.0, y, z),
                Vec3::new((x1 - x0) / 2.0, bar, bar),
                glam::Quat::IDENTITY,
                [1.0; 4],
            );
        }
    });
    for i in 0..cols {
        for j in 0..rows {
            // The partition leaves some openings empty.
            if wall == 1 && rng.f32() < 0.3 {
                continue;
            }
            let xa = x0 + (x1 - x0) * i as f32 / cols as f32 + bar;
            let xb = x0 + (x1 - x0) * (i + 1) as f32 / cols as f32 - bar;
            let ya = y0 + (y1 - y0) * j as f32 / rows as f32 + bar;
            let yb = y0 + (y1 - y0) * (j + 1) as f32 / rows as f32 - bar;
            let m = panes[rng.below(panes.len())];
            let scale = [rng.range(0.8, 1.6), rng.range(0.8, 1.6)];
            tquad(
                s,
                [
                    Vec3::new(xa, ya, z),
                    Vec3::new(xb, ya, z),
                    Vec3::new(xb, yb, z),
                    Vec3::new(xa, yb, z),
                ],
                [
                    [0.0, scale[1]],
                    [scale[0], scale[1]],
                    [scale[0], 0.0],
                    [0.0, 0.0],
                ],
                [1.0; 4],
                m,
            );
        }
    }
}

/// Between the windows' walls: opaque objects, glass vessels on a glass shelf.
fn between_the_walls(s: &mut Scene, rng: &mut Rng) {
    for _ in 0..4 + rng.below(4) {
        let c = hue(rng, 1.0);
        let m = s.add_material(opaque([c[0], c[1], c[2]]));
        let z = if rng.f32() < 0.5 { -0.4 } else { 0.4 };
        let centre = Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-0.8, 0.2),
            z + rng.range(-0.2, 0.2),
        );
        with_material(s, m, |s| {
            if rng.f32() < 0.5 {
                sphere(s, centre, rng.range(0.08, 0.2), 16, 8, [1.0; 4]);
            } else {
                let rot = glam::Quat::from_rotation_y(rng.range(0.0, PI));
                boxed(s, centre, Vec3::splat(rng.range(0.06, 0.15)), rot, [1.0; 4]);
            }
        });
    }
    let shelf = s.add_material(glass_material([0.85, 0.95, 0.9], 1.5));
    let sz = rng.range(0.3, 0.5);
    with_material(s, shelf, |s| {
        boxed(
            s,
            Vec3::new(0.0, -0.3, sz),
            Vec3::new(1.0, 0.015, 0.15),
            glam::Quat::IDENTITY,
            [1.0; 4],
        );
    });
    for i in 0..3 {
        let tint = hue(rng, 1.0);
        let m = s.add_material(glass_material(
            [
                0.6 + 0.4 * tint[0],
                0.6 + 0.4 * tint[1],
                0.6 + 0.4 * tint[2],
            ],
            1.5,
        ));
        let (belly, height) = (rng.range(0.08, 0.14), rng.range(0.25, 0.45));
        let profile: Vec<(f32, f32)> = (0..=8)
            .map(|j| {
                let t = j as f32 / 8.0;
                ((belly * (PI * t).sin()).max(0.03), t * height)
            })
            .collect();
        let x = -0.6 + 0.6 * i as f32 + rng.range(-0.1, 0.1);
        with_material(s, m, |s| {
            lathe(s, Vec3::new(x, -0.285, sz), &profile, 20, [1.0; 4])
        });
    }
}

/// Opaque gears, shafts and a base plate under transparent plastic covers (a housing whose
/// walls are blended, and smaller inserts and a reservoir inside).
fn covers(s: &mut Scene, rng: &mut Rng) {
    let steel = |rng: &mut Rng| {
        let g = rng.range(0.45, 0.8);
        opaque([g, g, g * rng.range(1.0, 1.15)])
    };
    let plate = s.add_material(steel(rng));
    with_material(s, plate, |s| {
        boxed(
            s,
            Vec3::new(0.0, -0.6, 0.0),
            Vec3::new(1.1, 0.04, 0.8),
            glam::Quat::IDENTITY,
            [1.0; 4],
        );
    });
    let shafts = 2 + rng.below(3);
    for i in 0..shafts {
        let z = -0.4 + 0.8 * (i as f32 + 0.5) / shafts as f32;
        let y = rng.range(-0.25, 0.15);
        let m = s.add_material(steel(rng));
        let r = rng.range(0.04, 0.08);
        with_material(s, m, |s| {
            solid_cylinder(s, Vec3::new(-1.1, y, z), Vec3::X, 2.2, r, 16, [1.0; 4])
        });
        for _ in 0..1 + rng.below(3) {
            let c = hue(rng, 1.0);
            let m = s.add_material(opaque([c[0], c[1], c[2]]));
            let x = rng.range(-0.7, 0.7);
            let (radius, width, teeth) = (
                rng.range(0.12, 0.3),
                rng.range(0.04, 0.1),
                10 + rng.below(14) as u32,
            );
            with_material(s, m, |s| {
                gear(
                    s,
                    Vec3::new(x, y, z),
                    Vec3::X,
                    radius,
                    width,
                    teeth,
                    [1.0; 4],
                )
            });
        }
    }
    // The covers: a housing of tinted plastic, a second one around part of it, inserts.
    let tint = {
        let c = hue(rng, 1.0);
        [0.5 + 0.5 * c[0], 0.5 + 0.5 * c[1], 0.5 + 0.5 * c[2]]
    };
    let shell = s.add_material(blend(tint, rng.range(0.15, 0.4)));
    with_material(s, shell, |s| {
        housing(
            s,
            Vec3::new(0.0, -0.1, 0.0),
            Vec3::new(0.9, 0.45, 0.6),
            0.04,
            [1.0; 4],
        );
    });
    let inner = s.add_material(blend([0.9, 0.9, 0.95], rng.range(0.25, 0.5)));
    with_material(s, inner, |s| {
        housing(
            s,
            Vec3::new(rng.range(-0.3, 0.3), -0.25, 0.0),
            Vec3::new(0.35, 0.3, 0.45),
            0.02,
            [1.0; 4],
        );
    });
    for _ in 0..3 + rng.below(3) {
        let c = hue(rng, 1.0);
        let m = s.add_material(blend([c[0], c[1], c[2]], rng.range(0.3, 0.8)));
        let centre = Vec3::new(
            rng.range(-0.7, 0.7),
            rng.range(-0.4, 0.3),
            rng.range(-0.4, 0.4),
        );
        let rot = glam::Quat::from_rotation_y(rng.range(0.0, PI));
        let half = Vec3::new(
            rng.range(0.05, 0.2),
            rng.range(0.05, 0.15),
            rng.range(0.02, 0.1),
        );
        with_material(s, m, |s| boxed(s, centre, half, rot, [1.0; 4]));
    }
    let fluid = s.add_material(blend([rng.range(0.2, 0.9), rng.range(0.3, 0.9), 0.9], 0.6));
    let c = Vec3::new(rng.range(-0.5, 0.5), 0.0, rng.range(-0.3, 0.3));
    with_material(s, fluid, |s| {
        sphere(s, c, rng.range(0.1, 0.2), 20, 10, [1.0; 4])
    });
}

/// A leaf card texture: `leaves` leaf shapes (veined, darker at the rim) on transparent
/// texels, with soft edges where `soft`.
fn leaf_texture(rng: &mut Rng, leaves: u32, soft: bool) -> Texture {
    let spots: Vec<([f32; 2], f32, f32)> = (0..leaves)
        .map(|i| {
            let (cx, cy) = if leaves == 1 {
                (0.5, 0.5)
            } else {
                ((i % 2) as f32 * 0.5 + 0.25, (i / 2) as f32 * 0.5 + 0.25)
            };
            ([cx, cy], rng.range(0.0, PI), rng.range(0.8, 1.0))
        })
        .collect();
    let scale = if leaves == 1 { 1.0 } else { 0.5 };
    let green = [
        rng.range(0.1, 0.3),
        rng.range(0.4, 0.75),
        rng.range(0.08, 0.25),
    ];
    texture((64, 64), Wrap::ClampToEdge, |u, v| {
        let mut best = [0.0f32; 4];
        for (c, angle, size) in &spots {
            let (dx, dy) = ((u - c[0]) / scale, (v - c[1]) / scale);
            let (sn, cs) = angle.sin_cos();
            let (x, y) = (dx * cs + dy * sn, -dx * sn + dy * cs);
            // An ellipse pointed at both ends: |y| < w(x).
            let t = (x / (0.45 * size)).clamp(-1.0, 1.0);
            let w = 0.2 * size * (1.0 - t * t).max(0.0).powf(0.8);
            let inside = w - y.abs();
            let a = if soft {
                (inside / 0.04).clamp(0.0, 1.0)
            } else if inside > 0.0 {
                1.0
            } else {
                0.0
            };
            if a > best[3] {
                let vein = if y.abs() < 0.012 { 1.3 } else { 1.0 };
                let rim = 0.7 + 0.3 * (inside / (w + 1e-3)).clamp(0.0, 1.0);
                best = [
                    (green[0] * vein * rim).min(1.0),
                    (green[1] * vein * rim).min(1.0),
                    (green[2] * vein * rim).min(1.0),
                    a,
                ];
            }
        }
        best
    })
}

/// Alpha-textured foliage: opaque bark-textured trunk and branches carrying leaf cards, some
/// masked (a cutoff), some blended with soft edges and a card-wide opacity.
fn cards(s: &mut Scene, rng: &mut Rng) {
    floor(s, rng, -1.2, 1.0);
    let bark = {
        let noise = value_noise(rng.next_u64(), 8);
        let tex = texture((32, 32), Wrap::Repeat, |u, v| {
            let n = noise(u * 0.5, v);
            [0.25 + 0.2 * n, 0.16 + 0.12 * n, 0.08 + 0.06 * n, 1.0]
        });
        let t = s.add_texture(tex);
        s.add_material(Material {
            texture: Some(t),
            ..opaque([1.0; 3])
        })
    };
    let trunk_top = Vec3::new(0.0, 0.1, 0.0);
    let mut branch_ends = Vec::new();
    with_material(s, bark, |s| {
        solid_cylinder(
            s,
            Vec3::new(0.0, -1.2, 0.0),
            Vec3::Y,
            1.3,
            0.08,
            16,
            [1.0; 4],
        );
        for _ in 0..6 + rng.below(4) {
            let mut d = rng.unit_vector();
            d.y = d.y.abs() * 0.8 + 0.2;
            let d = d.normalize();
            let len = rng.range(0.4, 0.8);
            let start = trunk_top - Vec3::Y * rng.range(0.0, 0.4);
            solid_cylinder(s, start, d, len, 0.025, 8, [1.0; 4]);
            branch_ends.push((start, d, len));
        }
    });
    let mut kinds = Vec::new();
    for i in 0..4 {
        let soft = i % 2 == 1;
        let tex = leaf_texture(rng, if i < 2 { 1 } else { 4 }, soft);
        let t = s.add_texture(tex);
        let m = if soft {
            Material {
                texture: Some(t),
                ..blend([1.0; 3], rng.range(0.6, 1.0))
            }
        } else {
            Material {
                texture: Some(t),
                coverage: Coverage::Mask(0.5),
                ..opaque([1.0; 3])
            }
        };
        kinds.push(s.add_material(m));
    }
    for _ in 0..900 {
        let (start, d, len) = branch_ends[rng.below(branch_ends.len())];
        let along = start + d * len * rng.range(0.3, 1.0);
        let centre = along + rng.unit_vector() * rng.range(0.05, 0.3);
        let n = rng.unit_vector();
        let t = n.any_orthonormal_vector();
        let b = n.cross(t);
        let size = rng.range(0.08, 0.16);
        let shade = rng.range(0.7, 1.0);
        let c = [shade, shade, shade * rng.range(0.8, 1.0), 1.0];
        let m = kinds[rng.below(kinds.len())];
        tquad(s, billboard(centre, t, b, size, size), UNIT_UV, c, m);
    }
}

/// A point of a plume rising from `chimney`, `h` above its top (which is 0.6 above its
/// base): spread sideways by `spread` (two normal draws, x then z) and drifting `drift h^2`
/// along x.
fn plume_point(rng: &mut Rng, chimney: Vec3, h: f32, spread: f32, drift: f32) -> Vec3 {
    let x = rng.normal() * spread + drift * h * h;
    let z = rng.normal() * spread;
    chimney + Vec3::new(x, 0.6 + h, z)
}

/// The tangent and bitangent of a billboard facing a random direction.
fn random_facing(rng: &mut Rng) -> (Vec3, Vec3) {
    let n = rng.unit_vector();
    let t = n.any_orthonormal_vector();
    (t, n.cross(t))
}

/// Soft particles: billboards of a radial alpha texture (smoke and embers, blended) in
/// plumes rising from opaque chimneys and around an opaque ball; the embers emit 2 to 6 times
/// an orange, above white.
fn smoke(s: &mut Scene, rng: &mut Rng) {
    floor(s, rng, -1.0, 1.1);
    let puff = texture((32, 32), Wrap::ClampToEdge, |u, v| {
        let (x, y) = (2.0 * u - 1.0, 2.0 * v - 1.0);
        let r2 = x * x + y * y;
        let a = (-(r2 * 3.5)).exp() * (1.0 - r2).max(0.0);
        [1.0, 1.0, 1.0, a]
    });
    let t = s.add_texture(puff);
    let brick = s.add_material(opaque([rng.range(0.4, 0.6), 0.25, 0.2]));
    let chimneys: Vec<Vec3> = (0..2 + rng.below(2))
        .map(|_| Vec3::new(rng.range(-0.8, 0.8), -1.0, rng.range(-0.5, 0.5)))
        .collect();
    with_material(s, brick, |s| {
        for c in &chimneys {
            boxed(
                s,
                *c + Vec3::Y * 0.3,
                Vec3::new(0.1, 0.3, 0.1),
                glam::Quat::IDENTITY,
                [1.0; 4],
            );
        }
    });
    let ball = s.add_material(opaque([0.3, 0.35, rng.range(0.4, 0.7)]));
    let bc = Vec3::new(
        rng.range(-0.4, 0.4),
        rng.range(-0.3, 0.3),
        rng.range(-0.3, 0.3),
    );
    with_material(s, ball, |s| {
        sphere(s, bc, rng.range(0.15, 0.3), 24, 12, [1.0; 4])
    });
    let mut mats = Vec::new();
    for _ in 0..6 {
        let grey = rng.range(0.35, 0.9);
        let warm = rng.f32() < 0.3;
        let c = if warm {
            [1.0, rng.range(0.4, 0.7), 0.15]
        } else {
            [grey, grey, grey * rng.range(0.95, 1.05)]
        };
        mats.push(s.add_material(Material {
            texture: Some(t),
            ..blend(c, rng.range(0.2, 0.9))
        }));
    }
    for _ in 0..6000 {
        let c = chimneys[rng.below(chimneys.len())];
        let h = rng.f32().powf(0.7) * 1.8;
        let centre = plume_point(rng, c, h, 0.08 + 0.35 * h, 0.3);
        let (tt, b) = random_facing(rng);
        let r = rng.range(0.05, 0.12) * (1.0 + h);
        let m = mats[rng.below(mats.len())];
        let fade = (1.0 - h / 2.0).clamp(0.2, 1.0);
        tquad(
            s,
            billboard(centre, tt, b, r, r),
            UNIT_UV,
            [1.0, 1.0, 1.0, fade],
            m,
        );
    }
    // Embers: small glowing particles rising from the chimneys, emissive above white (2 to 6
    // times an orange), so their frames keep light above white.
    let mut embers = Vec::new();
    for _ in 0..3 {
        let strength = rng.range(2.0, 6.0);
        let glow = [1.0, rng.range(0.3, 0.6), rng.range(0.02, 0.1)];
        embers.push(s.add_material(Material {
            texture: Some(t),
            emissive: glow.map(|c| c * strength),
            ..blend([0.2, 0.08, 0.02], rng.range(0.5, 0.95))
        }));
    }
    for _ in 0..800 {
        let c = chimneys[rng.below(chimneys.len())];
        let h = rng.f32().powf(1.5) * 1.4;
        let centre = plume_point(rng, c, h, 0.05 + 0.25 * h, 0.2);
        let (tt, b) = random_facing(rng);
        let r = rng.range(0.01, 0.03);
        let m = embers[rng.below(embers.len())];
        tquad(s, billboard(centre, tt, b, r, r), UNIT_UV, [1.0; 4], m);
    }
}

/// Hair strands whose alpha fades along the strand (a texture in v) and across it (in u),
/// growing from an opaque head.
fn strands(s: &mut Scene, rng: &mut Rng) {
    const SEGMENTS: usize = 8;
    let skin = s.add_material(opaque([
        rng.range(0.6, 0.9),
        rng.range(0.45, 0.65),
        rng.range(0.35, 0.5),
    ]));
    with_material(s, skin, |s| sphere(s, Vec3::ZERO, 0.48, 32, 16, [1.0; 4]));
    let falloff = rng.range(0.5, 1.2);
    let strand = texture((8, 64), Wrap::ClampToEdge, |u, v| {
        let across = 1.0 - (2.0 * u - 1.0).powi(2);
        let along = (1.0 - v).powf(falloff);
        [1.0, 1.0, 1.0, (across * along).clamp(0.0, 1.0)]
    });
    let t = s.add_texture(strand);
    let hair = s.add_material(Material {
        texture: Some(t),
        ..blend([1.0; 3], rng.range(0.6, 1.0))
    });
    let base = rng.range(0.2, 0.5);
    for _ in 0..2500 {
        let mut d = rng.unit_vector();
        d.y = d.y.abs();
        let mut p = d * 0.5;
        let mut v = d * 0.08;
        let tone = base * rng.range(0.8, 1.2);
        let c = [(tone * 1.3).min(1.0), tone * 0.9, tone * 0.5, 1.0];
        let width = rng.range(0.008, 0.016);
        let side = d.cross(Vec3::Y).normalize_or(Vec3::X) * width;
        for k in 0..SEGMENTS {
            let next = p + v;
            v = (v + Vec3::new(0.0, -0.035, 0.0) + rng.unit_vector() * 0.01) * 0.98;
            let (v0, v1) = (k as f32 / SEGMENTS as f32, (k + 1) as f32 / SEGMENTS as f32);
            tquad(
                s,
                [p - side, p + side, next + side, next - side],
                [[0.0, v0], [1.0, v0], [1.0, v1], [0.0, v1]],
                c,
                hair,
            );
            p = next;
        }
    }
}
