//! Rasterizer conventions: coverage, watertightness, depth.

use dhoit_runtime::fragment::FragmentLists;
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::rng::Rng;
use dhoit_runtime::scene::{Camera, Scene, perspective_rh};
use glam::{Mat4, Vec3};

const WHITE: [f32; 4] = [1.0, 1.0, 1.0, 0.5];

/// A camera whose view-projection is the identity: positions are clip coordinates with w = 1.
fn ndc_camera() -> Camera {
    Camera {
        view_proj: Mat4::IDENTITY,
        forward: Vec3::NEG_Z,
        eye: Vec3::ZERO,
        near: 0.0,
        far: 0.0,
    }
}

/// NDC point for window coordinates (x right, y down) on a target of `size` (width, height).
fn ndc(x: f32, y: f32, size: (u32, u32), z: f32) -> Vec3 {
    let (w, h) = size;
    Vec3::new(2.0 * x / w as f32 - 1.0, 1.0 - 2.0 * y / h as f32, z)
}

#[test]
fn a_screen_filling_quad_covers_every_pixel_once_per_face() {
    for (w, h) in [(64, 48), (37, 23), (1, 1), (256, 3)] {
        let c = [
            Vec3::new(-1.0, -1.0, 0.5),
            Vec3::new(1.0, -1.0, 0.5),
            Vec3::new(1.0, 1.0, 0.5),
            Vec3::new(-1.0, 1.0, 0.5),
        ];
        let mut s = Scene::default();
        s.push_triangle([c[0], c[1], c[2]], [WHITE; 3]);
        s.push_triangle([c[0], c[2], c[3]], [WHITE; 3]);
        let fl = rasterize(&s, &ndc_camera(), (w, h)).unwrap();
        assert!(fl.counts().iter().all(|&n| n == 1), "{w}x{h}: one face");
        // The same quad wound the other way is its back face: both are rasterized.
        s.push_triangle([c[0], c[2], c[1]], [WHITE; 3]);
        s.push_triangle([c[0], c[3], c[2]], [WHITE; 3]);
        let fl = rasterize(&s, &ndc_camera(), (w, h)).unwrap();
        assert!(fl.counts().iter().all(|&n| n == 2), "{w}x{h}: two faces");
        assert!(fl.depth.iter().all(|&d| (d - 0.5).abs() < 1e-7));
    }
}

/// Exact edge function on the 1/256-pixel grid, as a test-side oracle.
fn orient(a: (i64, i64), b: (i64, i64), p: (i64, i64)) -> i64 {
    (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)
}

#[test]
fn a_triangulated_grid_is_covered_exactly_once_inside() {
    // A 256x64 target, so window coordinates on the 1/256 grid map to NDC without rounding.
    let (w, h) = (256u32, 64u32);
    let mut rng = Rng::new(7);
    for trial in 0..20 {
        // Grid of vertices, jittered on the 1/256 grid; interior vertices often land exactly on
        // pixel centres and edges pass through pixel centres, exercising the tie rule.
        let (nx, ny) = (9usize, 5usize);
        let mut v = vec![(0i64, 0i64); nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                let bx = 3 * 256 + 1 + (i as i64) * 31 * 256;
                let by = 2 * 256 + 1 + (j as i64) * 14 * 256;
                let interior = i > 0 && j > 0 && i + 1 < nx && j + 1 < ny;
                let (jx, jy) = if interior {
                    if rng.f32() < 0.5 {
                        // Snap to a pixel centre near the grid point.
                        ((bx / 256) * 256 + 128 - bx, (by / 256) * 256 + 128 - by)
                    } else {
                        (
                            (rng.below(9 * 256) as i64) - 4 * 256,
                            (rng.below(5 * 256) as i64) - 2 * 256,
                        )
                    }
                } else {
                    (0, 0)
                };
                v[j * nx + i] = (bx + jx, by + jy);
            }
        }
        let mut s = Scene::default();
        let mut tris = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let (a, b, c, d) = (
                    j * nx + i,
                    j * nx + i + 1,
                    (j + 1) * nx + i + 1,
                    (j + 1) * nx + i,
                );
                // Alternate the diagonal and the winding.
                let t = if (i + j + trial) % 2 == 0 {
                    [[a, b, c], [a, c, d]]
                } else {
                    [[a, b, d], [d, c, b]]
                };
                tris.extend(t);
            }
        }
        let to_ndc = |q: (i64, i64)| ndc(q.0 as f32 / 256.0, q.1 as f32 / 256.0, (w, h), 0.25);
        for t in &tris {
            s.push_triangle(
                [to_ndc(v[t[0]]), to_ndc(v[t[1]]), to_ndc(v[t[2]])],
                [WHITE; 3],
            );
        }
        let fl = rasterize(&s, &ndc_camera(), (w, h)).unwrap();
        let (x0, y0) = (v[0].0, v[0].1);
        let (x1, y1) = (v[nx * ny - 1].0, v[nx * ny - 1].1);
        for py in 0..h {
            for px in 0..w {
                let c = (px as i64 * 256 + 128, py as i64 * 256 + 128);
                let inside = c.0 > x0 && c.0 < x1 && c.1 > y0 && c.1 < y1;
                let n = fl.count((py * w + px) as usize);
                assert_eq!(
                    n, inside as u32,
                    "trial {trial}: pixel ({px}, {py}) covered {n} times"
                );
            }
        }
        // The oracle agrees triangle by triangle on pixels strictly inside one triangle.
        for t in &tris {
            let [a, b, c] = [v[t[0]], v[t[1]], v[t[2]]];
            let sign = orient(a, b, c).signum();
            let p = (
                ((a.0 + b.0 + c.0) / 3 / 256) * 256 + 128,
                ((a.1 + b.1 + c.1) / 3 / 256) * 256 + 128,
            );
            let strictly = [orient(b, c, p), orient(c, a, p), orient(a, b, p)]
                .iter()
                .all(|e| e * sign > 0);
            if strictly {
                assert_eq!(fl.count(((p.1 / 256) * w as i64 + p.0 / 256) as usize), 1);
            }
        }
    }
}

#[test]
fn depths_of_a_tilted_plane_match_the_projection() {
    let (w, h) = (80u32, 60u32);
    let (near, far) = (1.0f32, 10.0f32);
    let proj = perspective_rh(60f32.to_radians(), w as f32 / h as f32, near, far);
    let cam = Camera {
        view_proj: proj,
        forward: Vec3::NEG_Z,
        eye: Vec3::ZERO,
        near,
        far,
    };
    // The plane z = -4 - 0.5 x (view space), as a big quad.
    let plane = |x: f32, y: f32| Vec3::new(x, y, -4.0 - 0.5 * x);
    let mut s = Scene::default();
    let q = [
        plane(-3.0, -3.0),
        plane(3.0, -3.0),
        plane(3.0, 3.0),
        plane(-3.0, 3.0),
    ];
    s.push_triangle([q[0], q[1], q[2]], [WHITE; 3]);
    s.push_triangle([q[0], q[2], q[3]], [WHITE; 3]);
    let fl: FragmentLists = rasterize(&s, &cam, (w, h)).unwrap();
    let inv = proj.inverse();
    let mut checked = 0;
    for py in 0..h {
        for px in 0..w {
            let p = (py * w + px) as usize;
            if fl.count(p) == 0 {
                continue;
            }
            // Ray through the pixel centre, intersected with the plane.
            let nx = 2.0 * (px as f32 + 0.5) / w as f32 - 1.0;
            let ny = 1.0 - 2.0 * (py as f32 + 0.5) / h as f32;
            let dir = inv.project_point3(Vec3::new(nx, ny, 0.5)).normalize();
            // Solve t*dir.z = -4 - 0.5 t*dir.x.
            let t = -4.0 / (dir.z + 0.5 * dir.x);
            let hit = dir * t;
            let clip = proj * hit.extend(1.0);
            let expected = clip.z / clip.w;
            let got = fl.depth[fl.range(p).start];
            assert!(
                (got - expected).abs() < 2e-5,
                "pixel ({px},{py}): depth {got}, expected {expected}"
            );
            checked += 1;
        }
    }
    assert!(
        checked > (w * h / 2) as usize,
        "the plane covers most of the image ({checked})"
    );
}

#[test]
fn fragments_keep_submission_order_within_a_pixel() {
    let mut s = Scene::default();
    for i in 0..5 {
        let z = 0.9 - 0.1 * i as f32;
        s.push_triangle(
            [
                Vec3::new(-1.0, -1.0, z),
                Vec3::new(3.0, -1.0, z),
                Vec3::new(-1.0, 3.0, z),
            ],
            [WHITE; 3],
        );
    }
    let fl = rasterize(&s, &ndc_camera(), (8, 8)).unwrap();
    for p in 0..64 {
        let prims: Vec<u32> = fl.range(p).map(|i| fl.primitive[i]).collect();
        assert_eq!(prims, vec![0, 1, 2, 3, 4]);
    }
}

#[test]
fn geometry_behind_the_near_plane_is_clipped() {
    let proj = perspective_rh(60f32.to_radians(), 1.0, 1.0, 10.0);
    let cam = Camera {
        view_proj: proj,
        forward: Vec3::NEG_Z,
        eye: Vec3::ZERO,
        near: 1.0,
        far: 10.0,
    };
    let mut s = Scene::default();
    // Entirely behind the eye: nothing. Crossing the near plane: only the visible part, depths in [0, 1].
    s.push_triangle(
        [
            Vec3::new(-1.0, -1.0, 2.0),
            Vec3::new(1.0, -1.0, 2.0),
            Vec3::new(0.0, 1.0, 2.0),
        ],
        [WHITE; 3],
    );
    let fl = rasterize(&s, &cam, (32, 32)).unwrap();
    assert_eq!(fl.fragment_count(), 0);
    s.push_triangle(
        [
            Vec3::new(-1.0, -1.0, 0.5),
            Vec3::new(1.0, -1.0, -5.0),
            Vec3::new(0.0, 1.0, -5.0),
        ],
        [WHITE; 3],
    );
    let fl = rasterize(&s, &cam, (32, 32)).unwrap();
    assert!(fl.fragment_count() > 0);
    assert!(fl.depth.iter().all(|d| (0.0..=1.0).contains(d)));
}

#[test]
fn impossible_resolutions_are_errors() {
    let s = Scene::default();
    assert!(rasterize(&s, &ndc_camera(), (0, 10)).is_err());
    assert!(rasterize(&s, &ndc_camera(), (10, 100_000)).is_err());
    for bad in ["0x10", "640", "axb", "-1x5", "100000x10", ""] {
        assert!(
            dhoit_runtime::raster::parse_resolution(bad).is_err(),
            "{bad}"
        );
    }
    assert_eq!(
        dhoit_runtime::raster::parse_resolution("640x480").unwrap(),
        (640, 480)
    );
}

/// The memory check's fragment estimate (the triangles' area inside the window): exact for a
/// quad that overhangs the window on every side (clipped to it), and within 2% of the
/// rasterized count for every built-in scene at 320x240.
#[test]
fn the_fragment_estimate_clips_to_the_window_and_follows_the_count() {
    use dhoit_runtime::raster::estimate_fragments;
    let (w, h) = (64u32, 48u32);
    let c = [
        ndc(-20.0, -9.0, (w, h), 0.5),
        ndc(90.0, -9.0, (w, h), 0.5),
        ndc(90.0, 70.0, (w, h), 0.5),
        ndc(-20.0, 70.0, (w, h), 0.5),
    ];
    let mut s = Scene::default();
    s.push_triangle([c[0], c[1], c[2]], [WHITE; 3]);
    s.push_triangle([c[0], c[2], c[3]], [WHITE; 3]);
    let e = estimate_fragments(&s, &ndc_camera(), (w, h)).unwrap();
    assert!((e - (w * h) as f64).abs() < 1e-6, "{e}");
    assert_eq!(
        rasterize(&s, &ndc_camera(), (w, h))
            .unwrap()
            .fragment_count(),
        (w * h) as usize
    );
    let size = (320, 240);
    for (name, _) in dhoit_runtime::scene::procedural::BUILTIN {
        let s = dhoit_runtime::scene::load(name, Default::default()).unwrap();
        for view in [0, 3] {
            let cam = Camera::orbit(&s, view, 8, size);
            let e = estimate_fragments(&s, &cam, size).unwrap();
            let n = rasterize(&s, &cam, size).unwrap().fragment_count() as f64;
            if s.uniform_opacity.is_some() {
                assert!(
                    (e / n - 1.0).abs() < 0.02,
                    "{name} view {view}: {e} against {n}"
                );
            } else {
                // With materials, opaque surfaces hide fragments and masks, zero opacity and
                // back faces drop some: the estimate (every triangle's area) bounds the count.
                assert!(e >= n, "{name} view {view}: {e} against {n}");
            }
        }
    }
}
