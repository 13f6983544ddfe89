//! glTF loading: the real scenes in ../shared/scenes (or, on a clone with nothing beside it,
//! built-in scenes written as glTF by the exporter), a tiny file written here, broken files.

mod common;

use common::{scenes_dir, temp_dir};
use dhoit_runtime::scene::{self, Camera, Opacity};
use std::path::{Path, PathBuf};

#[test]
fn every_real_scene_loads_with_its_triangle_count() {
    let Some(dir) = scenes_dir() else {
        // No real scenes: the same checks on built-ins written as .glb and read back.
        let out = temp_dir("gltf-standins");
        for name in ["cad", "glass", "statue", "shrub", "spheres"] {
            let built = scene::load(name, Opacity::Material).unwrap();
            let path = out.join(format!("{name}.glb"));
            scene::gltf::export(&built, &path).unwrap();
            let s = load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(s.triangle_count(), built.triangle_count(), "{name}");
            assert!(s.positions.iter().all(|p| p.is_finite()));
        }
        eprintln!(
            "real scenes absent: their loader checks ran on exported built-ins (set DHOIT_SCENES)"
        );
        return;
    };
    let expected = [
        ("GlassVaseFlowers/GlassVaseFlowers.glb", 14_036),
        ("TransmissionTest/TransmissionTest.glb", 128_775),
        ("ToyCar/glTF/ToyCar.gltf", 108_936),
        ("FlightHelmet/glTF/FlightHelmet.gltf", 94_722),
        ("StanfordBunny/StanfordBunny.glb", 3_674),
    ];
    for (file, tris) in expected {
        let path = dir.join(file);
        let s = scene::load(path.to_str().unwrap(), Opacity::Material)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(s.triangle_count(), tris, "{file}");
        assert!(
            s.positions.iter().all(|p| p.is_finite()),
            "{file}: positions finite"
        );
        assert!(
            s.colors
                .iter()
                .flatten()
                .all(|c| c.is_finite() && (0.0..=1.0).contains(c)),
            "{file}: colours in [0, 1]"
        );
    }
    // Uniform opacity overrides every alpha; material alpha keeps the bunny's 0.33 BLEND.
    let bunny = dir.join("StanfordBunny/StanfordBunny.glb");
    let s = scene::load(bunny.to_str().unwrap(), Opacity::Material).unwrap();
    assert_eq!(s.uniform_opacity, None);
    assert!((0..s.triangle_count()).all(|t| {
        let m = s.material_of(t);
        m.coverage == scene::Coverage::Blend && (m.base_color[3] - 0.33).abs() < 1e-6
    }));
    // The scene's own opacity is the material's.
    let native = scene::load(bunny.to_str().unwrap(), Opacity::Native).unwrap();
    assert_eq!(native.uniform_opacity, None);
    let s = scene::load(bunny.to_str().unwrap(), Opacity::Uniform(0.6)).unwrap();
    assert_eq!(s.uniform_opacity, Some(0.6));
    assert!(s.colors.iter().all(|c| c[3] == 0.6));
}

/// A one-triangle glTF with an index buffer, a translated node and a base colour factor.
fn write_tiny(
    dir: &Path,
    indices: [u16; 3],
    bin_len_override: Option<usize>,
    bin_name: &str,
) -> PathBuf {
    let positions: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    bin.extend([0, 0]); // pad to 4
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [10.0, 0.0, 0.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1.0, 0.4]}, "alphaMode": "BLEND"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 6}
        ],
        "buffers": [{"uri": bin_name, "byteLength": bin_len_override.unwrap_or(bin.len())}]
    });
    std::fs::write(dir.join("tiny.bin"), &bin).unwrap();
    let path = dir.join("tiny.gltf");
    std::fs::write(&path, serde_json::to_vec_pretty(&json).unwrap()).unwrap();
    path
}

fn load(path: &Path) -> dhoit_runtime::Result<scene::Scene> {
    scene::load(path.to_str().unwrap(), Opacity::Material)
}

#[test]
fn a_tiny_gltf_written_here_loads() {
    let dir = temp_dir("tiny");
    let s = load(&write_tiny(&dir, [0, 1, 2], None, "tiny.bin")).unwrap();
    assert_eq!(s.triangle_count(), 1);
    assert_eq!(
        s.positions[1],
        glam::Vec3::new(11.0, 0.0, 0.0),
        "node translation applied"
    );
    assert_eq!(s.colors[0], [1.0; 4], "no COLOR_0: white");
    let m = s.material_of(0);
    assert_eq!(
        (m.base_color, m.coverage, m.double_sided),
        ([0.5, 0.25, 1.0, 0.4], scene::Coverage::Blend, false),
        "base colour factor, BLEND, single-sided"
    );
    // The same triangle as a .glb.
    let bin = std::fs::read(dir.join("tiny.bin")).unwrap();
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("tiny.gltf")).unwrap()).unwrap();
    json["buffers"][0] = serde_json::json!({"byteLength": bin.len()});
    let glb = make_glb(&serde_json::to_vec(&json).unwrap(), &bin);
    std::fs::write(dir.join("tiny.glb"), &glb).unwrap();
    let g = load(&dir.join("tiny.glb")).unwrap();
    assert_eq!(g.positions, s.positions);
}

fn make_glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let mut json = json.to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

fn expect_error(path: &Path, needle: &str) {
    match load(path) {
        Ok(_) => panic!("{} loaded but is broken", path.display()),
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.contains(&path.display().to_string()),
                "error names the file: {msg}"
            );
            assert!(
                msg.to_lowercase().contains(needle),
                "error '{msg}' should mention '{needle}'"
            );
        }
    }
}

#[test]
fn broken_files_are_clear_errors() {
    let dir = temp_dir("broken");
    // Wrong magic.
    let bad_magic = dir.join("magic.glb");
    let mut glb = make_glb(br#"{"asset":{"version":"2.0"}}"#, &[0; 4]);
    glb[..4].copy_from_slice(b"gLTx");
    std::fs::write(&bad_magic, &glb).unwrap();
    expect_error(&bad_magic, "not a valid gltf");
    // Truncated .glb.
    let sub = temp_dir("broken-src");
    write_tiny(&sub, [0, 1, 2], None, "tiny.bin");
    let bin = std::fs::read(sub.join("tiny.bin")).unwrap();
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(sub.join("tiny.gltf")).unwrap()).unwrap();
    json["buffers"][0] = serde_json::json!({"byteLength": bin.len()});
    let glb = make_glb(&serde_json::to_vec(&json).unwrap(), &bin);
    let truncated = dir.join("truncated.glb");
    std::fs::write(&truncated, &glb[..glb.len() - 20]).unwrap();
    expect_error(&truncated, "gltf");
    // Missing buffer file.
    let missing = temp_dir("missing");
    let path = write_tiny(&missing, [0, 1, 2], None, "nowhere.bin");
    expect_error(&path, "buffer");
    // Buffer shorter than declared.
    let short = temp_dir("short");
    let path = write_tiny(&short, [0, 1, 2], Some(400), "tiny.bin");
    expect_error(&path, "buffer");
    // Index out of range.
    let oob = temp_dir("oob");
    let path = write_tiny(&oob, [0, 1, 7], None, "tiny.bin");
    expect_error(&path, "out of range");
    // Not a file at all / not JSON.
    let garbage = dir.join("garbage.gltf");
    std::fs::write(&garbage, b"{ this is not json").unwrap();
    expect_error(&garbage, "not a valid gltf");
    expect_error(&dir.join("absent.gltf"), "cannot read");
}

#[test]
fn unknown_names_are_clear_errors() {
    let e = scene::load("no-such-scene", Opacity::default()).unwrap_err();
    assert!(
        e.to_string().contains("unknown scene 'no-such-scene'"),
        "{e}"
    );
}

#[test]
fn every_built_in_scene_round_trips_through_the_exporter() {
    let dir = temp_dir("gltf-export");
    for (name, _) in scene::procedural::BUILTIN {
        let built = scene::load(name, Opacity::Material).unwrap();
        let path = dir.join(format!("{name}.glb"));
        scene::gltf::export(&built, &path).unwrap();
        let back = load(&path).unwrap();
        // (assert!, not assert_eq!: a difference is named, not printed whole)
        assert!(back.positions == built.positions, "{name}: positions");
        assert!(back.colors == built.colors, "{name}: colours and alpha");
        assert!(back.uvs == built.uvs, "{name}: texture coordinates");
        assert!(back.materials == built.materials, "{name}: materials");
        assert!(back.textures == built.textures, "{name}: textures");
        assert!(
            back.triangle_material == built.triangle_material,
            "{name}: triangle materials"
        );
        assert_eq!(back.name, *name);
    }
    // A scene with nothing to write is refused, and nothing is left behind.
    let empty = scene::Scene::default();
    let path = dir.join("empty.glb");
    let e = scene::gltf::export(&empty, &path).unwrap_err();
    assert!(e.to_string().contains("whole triangles"), "{e}");
    assert!(!path.exists());
}

/// A file of four quads side by side sharing one texture whose alpha rises from 0 to 1 across
/// it: OPAQUE, MASK at cutoffs 0.25 and 0.75, and BLEND (AlphaBlendModeTest's arrangement),
/// written by the exporter.
fn alpha_modes_file(dir: &Path) -> PathBuf {
    use scene::{Coverage, Material, Texture, Wrap};
    let mut s = scene::Scene {
        name: "alpha-modes".into(),
        materials: Vec::new(),
        ..scene::Scene::default()
    };
    let texels = (0..64 * 4)
        .map(|i| {
            let u = ((i % 64) as f32 + 0.5) / 64.0;
            scene::material::pack_texel([0.8, 0.5, 0.2, u])
        })
        .collect();
    let t = s.add_texture(Texture {
        width: 64,
        height: 4,
        texels,
        wrap: [Wrap::ClampToEdge; 2],
        nearest: false,
    });
    let modes = [
        Coverage::Opaque,
        Coverage::Mask(0.25),
        Coverage::Mask(0.75),
        Coverage::Blend,
    ];
    for (i, coverage) in modes.into_iter().enumerate() {
        let m = s.add_material(Material {
            texture: Some(t),
            coverage,
            ..Material::default()
        });
        let x = -1.0 + 0.5 * i as f32;
        let p = [(0.0, 0.0), (0.45, 0.0), (0.45, 1.0), (0.0, 1.0)]
            .map(|(dx, y)| glam::Vec3::new(x + dx, y, 0.0));
        let uv = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
        s.push_textured([p[0], p[1], p[2]], [[1.0; 4]; 3], [uv[0], uv[1], uv[2]], m);
        s.push_textured([p[0], p[2], p[3]], [[1.0; 4]; 3], [uv[0], uv[2], uv[3]], m);
    }
    let path = dir.join("alpha-modes.glb");
    scene::gltf::export(&s, &path).unwrap();
    path
}

/// glTF's alpha modes as the specification says: OPAQUE surfaces are opaque whatever their
/// alpha, MASK ones opaque where alpha reaches the cutoff and absent elsewhere, BLEND ones
/// transparent with their alpha. AlphaBlendModeTest when the real scenes are there (its masked
/// quads share one alpha texture and UVs), else a file of the same kind written here.
#[test]
fn each_alpha_mode_loads_and_renders_as_the_specification_says() {
    use dhoit_runtime::raster::rasterize;
    use scene::Coverage;
    let dir = temp_dir("alpha-modes");
    let (path, real) = match scenes_dir() {
        Some(d) => (d.join("AlphaBlendModeTest/AlphaBlendModeTest.glb"), true),
        None => (alpha_modes_file(&dir), false),
    };
    let s = load(&path).unwrap();
    let coverages: Vec<Coverage> = s.materials.iter().map(|m| m.coverage).collect();
    assert!(coverages.contains(&Coverage::Opaque), "{coverages:?}");
    assert!(coverages.contains(&Coverage::Blend), "{coverages:?}");
    let mut cutoffs: Vec<f32> = s.materials.iter().filter_map(|m| m.cutoff()).collect();
    cutoffs.sort_by(f32::total_cmp);
    let expected: &[f32] = if real {
        &[0.25, 0.5, 0.75]
    } else {
        &[0.25, 0.75]
    };
    assert_eq!(
        cutoffs, expected,
        "MASK cutoffs, the default 0.5 where none is given"
    );
    // Opaque surfaces never give transparent fragments; blended ones only do.
    for t in 0..s.triangle_count() {
        let m = s.material_of(t);
        assert_eq!(
            s.transparent(t),
            m.coverage == Coverage::Blend,
            "triangle {t}"
        );
    }
    // Each masked material alone: the share of its pixels the cutoff keeps falls as the
    // cutoff rises, between all (alpha ignored) and none.
    let size = (256, 192);
    let mut kept = Vec::new();
    for c in &cutoffs {
        let alone = |coverage: Coverage| {
            let mut one = s.clone();
            let keep: Vec<bool> = (0..one.triangle_count())
                .map(|t| one.material_of(t).cutoff() == Some(*c))
                .collect();
            for m in &mut one.materials {
                if m.cutoff() == Some(*c) {
                    m.coverage = coverage;
                }
            }
            // Move every other triangle out of view (behind the camera's far plane).
            let cam = Camera::orbit(&s, 0, 8, size);
            for (t, k) in keep.iter().enumerate() {
                if !k {
                    for v in 0..3 {
                        one.positions[3 * t + v] -= cam.forward * 1e6;
                    }
                }
            }
            let fl = rasterize(&one, &cam, size).unwrap();
            fl.opaque.iter().filter(|&&o| o >> 24 != 0).count()
        };
        let (all, masked) = (alone(Coverage::Opaque), alone(Coverage::Mask(*c)));
        assert!(all > 100, "cutoff {c}: {all} pixels");
        let share = masked as f64 / all as f64;
        eprintln!("cutoff {c}: {masked} of {all} pixels kept ({share:.3})");
        assert!(share > 0.0 && share < 1.0, "cutoff {c} keeps {share}");
        if !real {
            // Alpha rises linearly across the quad: the cutoff keeps 1 - c of it.
            assert!(
                (share - (1.0 - *c as f64)).abs() < 0.05,
                "cutoff {c} keeps {share}"
            );
        }
        kept.push(share);
    }
    assert!(kept.windows(2).all(|k| k[0] > k[1]), "{kept:?}");
}

/// Texture coordinates outside [0, 1] wrap as the sampler says. TextureSettingsTest's samplers
/// (repeat, mirrored repeat and clamp to edge along S and T, and its UVs beyond [0, 1]) load
/// as written; sampling at texel centres far outside [0, 1] gives the texel the wrap mode
/// names, by hand: texel i repeats every width, mirrors at each edge, clamps to the last.
#[test]
fn textures_wrap_as_their_samplers_say() {
    use scene::{Texture, Wrap};
    if let Some(dir) = scenes_dir() {
        let s = load(&dir.join("TextureSettingsTest/TextureSettingsTest.glb")).unwrap();
        let wraps: std::collections::BTreeSet<String> =
            s.textures.iter().map(|t| format!("{:?}", t.wrap)).collect();
        for w in [
            "[Repeat, Repeat]",
            "[Repeat, ClampToEdge]",
            "[ClampToEdge, Repeat]",
            "[Repeat, MirroredRepeat]",
            "[MirroredRepeat, Repeat]",
        ] {
            assert!(wraps.contains(w), "{w} in {wraps:?}");
        }
        assert!(
            s.uvs.iter().flatten().any(|&c| !(0.0..=1.0).contains(&c)),
            "UVs outside [0, 1]"
        );
    }
    let table = scene::material::srgb_table();
    let n = 4u32;
    let texels: Vec<u32> = (0..n * n).map(|i| 0xff00_0000 | (i * 15)).collect();
    for wrap in [Wrap::Repeat, Wrap::MirroredRepeat, Wrap::ClampToEdge] {
        for nearest in [false, true] {
            let t = Texture {
                width: n,
                height: n,
                texels: texels.clone(),
                wrap: [wrap, Wrap::ClampToEdge],
                nearest,
            };
            for k in -3i32..=3 {
                for i in 0..n as i32 {
                    // Texel i of row 0 repeated k widths away (u = i + 0.5 + k n texels).
                    let u = (i as f32 + 0.5 + (k * n as i32) as f32) / n as f32;
                    let x = k * n as i32 + i;
                    let by_hand = match wrap {
                        Wrap::Repeat => i,
                        // Mirrored: even periods as they are, odd ones reversed.
                        Wrap::MirroredRepeat if k.rem_euclid(2) == 0 => i,
                        Wrap::MirroredRepeat => n as i32 - 1 - i,
                        Wrap::ClampToEdge => x.clamp(0, n as i32 - 1),
                    };
                    let got = t.sample(&table, [u, 0.5 / n as f32]);
                    let want = table[(by_hand as u32 * 15) as usize];
                    assert_eq!(
                        got[0], want,
                        "{wrap:?} nearest {nearest}: u {u} (texel {x})"
                    );
                }
            }
        }
    }
}

/// A transmission texture, an emissive colour brighter than white (its strength) and an
/// emissive texture survive the exporter and the loader: the material read back is the one
/// written (the emission within float rounding of its factor times strength).
#[test]
fn transmission_textures_and_emission_round_trip() {
    use scene::{Coverage, Material, Texture, Wrap};
    let dir = temp_dir("emissive");
    let mut s = scene::Scene {
        name: "glass-and-light".into(),
        materials: Vec::new(),
        ..scene::Scene::default()
    };
    let tex = |r: u32| Texture {
        width: 2,
        height: 2,
        texels: vec![0xff00_0000 | r; 4],
        wrap: [Wrap::Repeat, Wrap::ClampToEdge],
        nearest: true,
    };
    let leads = s.add_texture(tex(0));
    let light = s.add_texture(tex(200));
    let glass = s.add_material(Material {
        base_color: [0.9, 0.2, 0.1, 1.0],
        coverage: Coverage::Opaque,
        transmission: 0.75,
        transmission_texture: Some(leads),
        attenuation: [0.5, 0.8, 1.0],
        ..Material::default()
    });
    let lamp = s.add_material(Material {
        emissive: [4.0, 2.0, 0.5],
        emissive_texture: Some(light),
        coverage: Coverage::Opaque,
        ..Material::default()
    });
    let dim = s.add_material(Material {
        emissive: [0.5, 0.25, 0.0],
        ..Material::default()
    });
    for (i, m) in [glass, lamp, dim].into_iter().enumerate() {
        let x = i as f32;
        let p = [
            glam::Vec3::new(x, 0.0, 0.0),
            glam::Vec3::new(x + 0.5, 0.0, 0.0),
            glam::Vec3::new(x, 0.5, 0.0),
        ];
        s.push_textured(p, [[1.0; 4]; 3], [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], m);
    }
    let path = dir.join("glass-and-light.glb");
    scene::gltf::export(&s, &path).unwrap();
    let back = load(&path).unwrap();
    let m = |t: usize| *back.material_of(t);
    assert_eq!(m(0).transmission, 0.75);
    let t = m(0).transmission_texture.expect("the transmission texture");
    assert_eq!(
        back.textures[t as usize].texels,
        s.textures[leads as usize].texels
    );
    let e = m(1).emissive;
    assert!(
        e.iter()
            .zip([4.0, 2.0, 0.5])
            .all(|(a, b)| (a - b).abs() < 1e-5),
        "emission {e:?}: the factor times its strength"
    );
    let t = m(1).emissive_texture.expect("the emissive texture");
    assert_eq!(
        back.textures[t as usize].texels,
        s.textures[light as usize].texels
    );
    assert_eq!(m(2).emissive, [0.5, 0.25, 0.0], "no strength below white");
    let att = m(0).attenuation;
    assert!(
        att.iter()
            .zip([0.5, 0.8, 1.0])
            .all(|(a, b)| (a - b).abs() < 1e-6),
        "volume attenuation {att:?}"
    );
    // The same file with an attenuation distance of 2 (the exporter writes thickness 1 and
    // distance 0.5): one crossing passes color^(1 / (2 x 2)), 0.5^0.25 = 0.8409 in red.
    let bytes = std::fs::read(&path).unwrap();
    let key = b"\"attenuationDistance\":0.5";
    let at = (bytes.windows(key.len()))
        .position(|w| w == key)
        .expect("the volume is written");
    let mut farther = bytes.clone();
    let digits = at + key.len() - 3;
    farther[digits..digits + 3].copy_from_slice(b"2.0");
    let far = dir.join("farther.glb");
    std::fs::write(&far, farther).unwrap();
    let att = load(&far).unwrap().material_of(0).attenuation;
    let want = [0.5f32.powf(0.25), 0.8f32.powf(0.25), 1.0];
    assert!(
        att.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-6),
        "{att:?}, by hand {want:?}"
    );
    assert_eq!(m(2).emissive_texture, None);
    // The real asset, where present: its labels glow with their texture, its striped spheres
    // read their transmission texture.
    if let Some(dir) = scenes_dir() {
        let t = load(&dir.join("TransmissionTest/TransmissionTest.glb")).unwrap();
        assert!(
            t.materials
                .iter()
                .any(|m| m.emissive == [1.0; 3] && m.emissive_texture.is_some())
        );
        let striped = t
            .materials
            .iter()
            .filter(|m| m.transmission_texture.is_some())
            .count();
        assert_eq!(
            striped, 6,
            "TransmissionTest's materials with a transmission texture"
        );
    }
}

/// A glTF file's camera is the scene's viewpoint, and `Camera::asset` sees through it: a point
/// straight ahead of the eye lands in the frame's centre, one up the camera's up above it.
/// Without a camera, the front view frames the bounding box: every vertex in the frame, its
/// centre in the middle. A camera that cannot see is refused by name.
#[test]
fn a_gltf_camera_is_the_asset_viewpoint_and_the_front_view_frames_the_rest() {
    use glam::{Quat, Vec3, Vec4};
    let dir = temp_dir("camera");
    let path = write_tiny(&dir, [0, 1, 2], None, "tiny.bin");
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    // Turned 30 degrees about Y, standing at (1, 2, 5).
    let q = Quat::from_rotation_y(30f32.to_radians());
    json["cameras"] = serde_json::json!([{"type": "perspective",
        "perspective": {"yfov": 0.7, "znear": 0.01, "zfar": 100.0}}]);
    json["nodes"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({
        "camera": 0, "translation": [1.0, 2.0, 5.0], "rotation": q.to_array()}));
    json["scenes"][0]["nodes"] = serde_json::json!([0, 1]);
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let s = load(&path).unwrap();
    let v = s.viewpoint.expect("the file's camera");
    assert_eq!(v.eye, Vec3::new(1.0, 2.0, 5.0));
    assert!(
        (v.forward - q * Vec3::NEG_Z).length() < 1e-6,
        "{:?}",
        v.forward
    );
    assert!((v.yfov - 0.7).abs() < 1e-7);
    let cam = scene::Camera::asset(&s, (200, 100));
    let ndc = |p: Vec3| {
        let c = cam.view_proj * Vec4::new(p.x, p.y, p.z, 1.0);
        (c.x / c.w, c.y / c.w)
    };
    let (x, y) = ndc(v.eye + 3.0 * v.forward);
    assert!(
        x.abs() < 1e-5 && y.abs() < 1e-5,
        "straight ahead: ({x}, {y})"
    );
    // One unit up at distance 3 is tan^-1(1/3) above the axis: NDC y = (1/3) / tan(yfov/2).
    let (x, y) = ndc(v.eye + 3.0 * v.forward + q * Vec3::Y);
    let want = (1.0 / 3.0) / (0.35f32).tan();
    assert!(
        x.abs() < 1e-5 && (y - want).abs() < 1e-4,
        "up: ({x}, {y}) for (0, {want})"
    );

    // Without one: the front view.
    let mut front = s.clone();
    front.viewpoint = None;
    let cam = scene::Camera::asset(&front, (200, 100));
    assert_eq!(cam.forward, Vec3::NEG_Z);
    let ndc = |p: Vec3| {
        let c = cam.view_proj * Vec4::new(p.x, p.y, p.z, 1.0);
        (c.x / c.w, c.y / c.w, c.z / c.w)
    };
    for p in &front.positions {
        let (x, y, z) = ndc(*p);
        assert!(
            x.abs() <= 1.0 && y.abs() <= 1.0 && (0.0..=1.0).contains(&z),
            "{p} at ({x}, {y}, {z})"
        );
    }
    // The triangle (10, 0)-(11, 0)-(10, 1): its box's centre (10.5, 0.5) in the middle, its
    // height the tallest side of the frame's (100 of 200: the vertical fits), 1/1.05 of it.
    let (x, y, _) = ndc(Vec3::new(10.5, 0.5, 0.0));
    assert!(
        x.abs() < 1e-5 && y.abs() < 1e-5,
        "the box's centre: ({x}, {y})"
    );
    let (_, top, _) = ndc(Vec3::new(10.5, 1.0, 0.0));
    assert!((top - 1.0 / 1.05).abs() < 1e-4, "the box's top at {top}");

    // A camera that cannot see: refused, named.
    let mut blind = s.clone();
    blind.viewpoint = Some(scene::Viewpoint { yfov: 0.0, ..v });
    let e = blind.check().unwrap_err().to_string();
    assert!(e.contains("camera cannot see"), "{e}");
    let mut blind = s;
    blind.viewpoint = Some(scene::Viewpoint { up: v.forward, ..v });
    assert!(blind.check().is_err());
}

/// `KHR_texture_transform`'s example from its specification, by hand: offset (0, 1), rotation
/// 90 degrees, scale 0.5 maps the quad's UV corners onto the texture's lower left quadrant,
/// turned: (0, 0) -> (0, 1), (1, 0) -> (0, 0.5), (1, 1) -> (0.5, 0.5), (0, 1) -> (0.5, 1).
#[test]
fn texture_transforms_map_uvs_as_the_specification_example_says() {
    use scene::{Material, Texture, Wrap};
    let dir = temp_dir("transform");
    let mut s = scene::Scene {
        name: "transform".into(),
        materials: Vec::new(),
        ..scene::Scene::default()
    };
    let t = s.add_texture(Texture {
        width: 2,
        height: 2,
        texels: vec![0xffff_ffff; 4],
        wrap: [Wrap::Repeat; 2],
        nearest: false,
    });
    let m = s.add_material(Material {
        texture: Some(t),
        ..Material::default()
    });
    let p = |x: f32, y: f32| glam::Vec3::new(x, y, 0.0);
    let corners = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    s.push_textured(
        [p(0.0, 1.0), p(1.0, 1.0), p(1.0, 0.0)],
        [[1.0; 4]; 3],
        [corners[0], corners[1], corners[2]],
        m,
    );
    s.push_textured(
        [p(0.0, 1.0), p(1.0, 0.0), p(0.0, 0.0)],
        [[1.0; 4]; 3],
        [corners[0], corners[2], corners[3]],
        m,
    );
    let plain = dir.join("plain.glb");
    scene::gltf::export(&s, &plain).unwrap();
    // The file again, its base colour texture transformed.
    let glb = std::fs::read(&plain).unwrap();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut json: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin = &glb[20 + json_len + 8..];
    json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] = serde_json::json!({
        "KHR_texture_transform": {"offset": [0.0, 1.0], "rotation": std::f64::consts::FRAC_PI_2, "scale": [0.5, 0.5]}
    });
    json["extensionsUsed"] = serde_json::json!(["KHR_texture_transform"]);
    let turned = dir.join("turned.glb");
    std::fs::write(&turned, make_glb(&serde_json::to_vec(&json).unwrap(), bin)).unwrap();
    let a = load(&plain).unwrap();
    let b = load(&turned).unwrap();
    let by_hand = |uv: [f32; 2]| match uv {
        [0.0, 0.0] => [0.0, 1.0],
        [1.0, 0.0] => [0.0, 0.5],
        [1.0, 1.0] => [0.5, 0.5],
        [0.0, 1.0] => [0.5, 1.0],
        other => panic!("a corner {other:?}"),
    };
    assert_eq!(a.uvs.len(), 6);
    for (plain, turned) in a.uvs.iter().zip(&b.uvs) {
        let want = by_hand(*plain);
        assert!(
            (turned[0] - want[0]).abs() < 1e-6 && (turned[1] - want[1]).abs() < 1e-6,
            "{plain:?} -> {turned:?}, by hand {want:?}"
        );
    }
}
