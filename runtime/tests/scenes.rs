//! Built-in scenes: deterministic, and spanning depth complexity from about 10 to over 100.

use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::{self, Camera, Opacity, procedural};

#[test]
fn built_in_scenes_span_shallow_to_very_deep() {
    assert!(procedural::BUILTIN.len() >= 6);
    let mut depths = Vec::new();
    for (name, _) in procedural::BUILTIN {
        let s = scene::load(name, Opacity::default()).unwrap();
        assert!(s.triangle_count() > 0, "{name}");
        let mut max = 0;
        let material = procedural::MATERIAL_FAMILIES.contains(name);
        assert_eq!(
            s.uniform_opacity.is_none(),
            material,
            "{name}: its own opacity"
        );
        for view in 0..2 {
            let cam = Camera::orbit(&s, view, scene::DEFAULT_VIEWS, (320, 240));
            let fl = rasterize(&s, &cam, (320, 240)).unwrap();
            let shown = (0..fl.pixel_count())
                .filter(|&p| fl.count(p) > 0 || fl.opaque.get(p).is_some_and(|&o| o >> 24 != 0))
                .count();
            assert!(shown > 320 * 240 / 20, "{name} view {view} fills the frame");
            if material {
                // Opaque parts, and transparent fragments of many opacities.
                assert!(
                    !fl.opaque.is_empty() && fl.fragment_count() > 500,
                    "{name} view {view}"
                );
                let alphas: std::collections::BTreeSet<u32> = fl
                    .rgba
                    .iter()
                    .map(|c| (c[3] * 255.0).round() as u32)
                    .collect();
                assert!(
                    alphas.len() >= 4,
                    "{name} view {view}: opacities {alphas:?}"
                );
            } else {
                max = max.max(fl.max_depth_complexity());
            }
        }
        if !material {
            depths.push((name, max));
        }
    }
    let lo = depths.iter().map(|d| d.1).min().unwrap();
    let hi = depths.iter().map(|d| d.1).max().unwrap();
    assert!((6..=16).contains(&lo), "shallowest scene: {depths:?}");
    assert!(hi >= 150, "deepest scene: {depths:?}");
}

#[test]
fn scenes_are_deterministic_and_seeded() {
    for (name, _) in procedural::BUILTIN {
        let a = procedural::build(name).unwrap();
        let b = procedural::build(name).unwrap();
        assert_eq!(a.positions, b.positions, "{name}");
        let c = procedural::build(&format!("{name}:9")).unwrap();
        assert!(
            a.positions != c.positions || a.colors != c.colors,
            "{name}: another seed, another scene"
        );
    }
    assert!(procedural::build("particles:x").is_none());
}

#[test]
fn shuffling_keeps_every_triangle() {
    let s = procedural::build("plates").unwrap();
    let t = s.shuffled(5);
    assert_eq!(s.triangle_count(), t.triangle_count());
    assert_ne!(s.positions, t.positions);
    let key = |sc: &scene::Scene| {
        let mut v: Vec<[u32; 9]> = sc
            .positions
            .chunks(3)
            .map(|p| {
                let f = [p[0].to_array(), p[1].to_array(), p[2].to_array()].concat();
                std::array::from_fn(|i| f[i].to_bits())
            })
            .collect();
        v.sort();
        v
    };
    assert_eq!(key(&s), key(&t));
}
