//! Built-in procedural scenes, generated from a seed with no files.
//!
//! They differ in kind and span maximum depth complexity from about ten fragments per pixel
//! (`shells`) to well over a hundred (`particles`, `hair`). A name may carry a seed, as in
//! `particles:7`; without one each scene uses its default seed. Vertex alpha is set per object
//! for the material-alpha mode; the default uniform opacity overrides it.

use super::Scene;
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
];

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
        _ => return None,
    }
    // The papers' families: one uniform opacity unless a caller asks for their vertex alpha.
    s.uniform_opacity = Some(super::PAPER_OPACITY);
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

fn boxed(s: &mut Scene, centre: Vec3, half: Vec3, rot: glam::Quat, c: [f32; 4]) {
    let corner = |x: f32, y: f32, z: f32| centre + rot * (half * Vec3::new(x, y, z));
    let faces = [
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
    for f in faces {
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
        quad(
            s,
            [
                centre - t * w - b * h,
                centre + t * w - b * h,
                centre + t * w + b * h,
                centre - t * w + b * h,
            ],
            green,
        );
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
        quad(
            s,
            [
                centre - t * r - b * r,
                centre + t * r - b * r,
                centre + t * r + b * r,
                centre - t * r + b * r,
            ],
            c,
        );
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
        let faces = [
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
        ];
        for f in faces {
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
