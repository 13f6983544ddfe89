//! glTF loading: the real scenes in ../shared/scenes (or, on a clone with nothing beside it,
//! built-in scenes written as glTF by the exporter), a tiny file written here, broken files.

mod common;

use common::{scenes_dir, temp_dir};
use dhoit_runtime::scene::{self, Opacity};
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
        assert_eq!(back.positions, built.positions, "{name}: positions");
        assert_eq!(back.colors, built.colors, "{name}: colours and alpha");
        assert_eq!(back.name, *name);
    }
    // A scene with nothing to write is refused, and nothing is left behind.
    let empty = scene::Scene::default();
    let path = dir.join("empty.glb");
    let e = scene::gltf::export(&empty, &path).unwrap_err();
    assert!(e.to_string().contains("whole triangles"), "{e}");
    assert!(!path.exists());
}
