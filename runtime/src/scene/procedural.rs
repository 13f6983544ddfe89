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
        _ => return None,
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
