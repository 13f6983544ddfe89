//! A corpus of bad inputs, one test per case: broken glTF and GLB files, weights and features
//! files, fragment dumps and command-line arguments. Each must end the command with a non-zero
//! exit and a message naming the problem, never a panic, and leave no output file behind.
mod common;

use dhoit_runtime::mlp::Mlp;
use std::collections::HashMap;
use std::path::Path;

/// A folder of its own for each case.
fn case_dir(name: &str) -> common::TempDir {
    common::temp_dir(&format!("bad-{name}"))
}

/// Runs dhoit with `args` (`{out}` is replaced by an output path in the case's folder) and
/// checks the failure: non-zero exit, `needle` in the message (case-insensitive), no panic,
/// no output left behind.
fn fails(dir: &Path, args: &[&str], needle: &str) {
    fails_with_env(dir, args, &[], needle)
}

/// [`fails`] with environment variables set for the command.
fn fails_with_env(dir: &Path, args: &[&str], env: &[(&str, &str)], needle: &str) {
    let out = dir.join("out.png");
    let args: Vec<String> = args
        .iter()
        .map(|a| a.replace("{out}", out.to_str().unwrap()))
        .collect();
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = common::dhoit_with_env(&args, env);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{args:?} succeeded");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    assert!(
        err.to_lowercase().contains(&needle.to_lowercase()),
        "{args:?}: '{err}' should mention '{needle}'"
    );
    assert!(
        !repeats_itself(&err),
        "{args:?}: '{err}' says the same thing twice"
    );
    assert!(!out.exists(), "{args:?} left {} behind", out.display());
    let left: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "{args:?} left temporary files: {left:?}");
}

/// Whether an error line says one part twice in a row ("weights w: bad: bad"), as a cause
/// printed both inline and as the source of the error (`{:#}` prints the chain) does.
fn repeats_itself(err: &str) -> bool {
    err.lines().any(|line| {
        let parts: Vec<&str> = line.split(": ").collect();
        (1..=parts.len() / 2).any(|len| {
            (0..=parts.len() - 2 * len).any(|i| parts[i..i + len] == parts[i + len..i + 2 * len])
        })
    })
}

#[test]
fn an_error_saying_one_thing_twice_is_caught() {
    assert!(repeats_itself(
        "error: weights w: missing tensor 'x': missing tensor 'x'"
    ));
    assert!(repeats_itself("error: a: b: c: b: c"));
    assert!(!repeats_itself(
        "error: scene s.gltf: cannot load buffers: buffer 0: expected 436 bytes"
    ));
}

/// Renders a scene file: the command every broken scene goes through.
fn render_scene(dir: &Path, scene: &Path, needle: &str) {
    fails(
        dir,
        &[
            "render",
            "--scene",
            scene.to_str().unwrap(),
            "--res",
            "32x24",
            "--out",
            "{out}",
        ],
        needle,
    );
}

// ---------------------------------------------------------------------------------------------
// glTF and GLB

/// A glTF document with one triangle list: positions (and optional colours), the given
/// indices, buffers inline as a data URI unless `bin` names a file.
fn gltf_json(
    positions: &[[f32; 3]],
    indices: Option<&[u32]>,
    extra: serde_json::Value,
) -> (serde_json::Value, Vec<u8>) {
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let pos_len = bin.len();
    let mut accessors = vec![serde_json::json!({
        "bufferView": 0, "componentType": 5126, "count": positions.len(), "type": "VEC3",
        "min": [-1.0, -1.0, -1.0], "max": [1.0, 1.0, 1.0]
    })];
    let mut views = vec![serde_json::json!({"buffer": 0, "byteOffset": 0, "byteLength": pos_len})];
    let mut prim = serde_json::json!({"attributes": {"POSITION": 0}});
    if let Some(ix) = indices {
        bin.extend(ix.iter().flat_map(|i| i.to_le_bytes()));
        views.push(
            serde_json::json!({"buffer": 0, "byteOffset": pos_len, "byteLength": 4 * ix.len()}),
        );
        accessors.push(serde_json::json!({"bufferView": 1, "componentType": 5125, "count": ix.len(), "type": "SCALAR"}));
        prim["indices"] = 1.into();
    }
    let mut json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [prim]}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}]
    });
    if let serde_json::Value::Object(m) = extra {
        for (k, v) in m {
            json[k] = v;
        }
    }
    (json, bin)
}

fn glb(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(b);
    out
}

const TRI: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

fn good_glb() -> Vec<u8> {
    let (j, b) = gltf_json(&TRI, None, serde_json::json!({}));
    glb(&j, &b)
}

/// Writes `bytes` as the case's scene file and renders it.
fn bad_scene(name: &str, file: &str, bytes: &[u8], needle: &str) {
    let dir = case_dir(name);
    let path = dir.join(file);
    std::fs::write(&path, bytes).unwrap();
    render_scene(&dir, &path, needle);
}

#[test]
fn glb_empty_file() {
    bad_scene("glb-empty", "s.glb", b"", "not a valid gltf");
}

#[test]
fn glb_truncated_header() {
    bad_scene("glb-header", "s.glb", &good_glb()[..7], "not a valid gltf");
}

#[test]
fn glb_truncated_body() {
    let g = good_glb();
    bad_scene("glb-body", "s.glb", &g[..g.len() - 12], "gltf");
}

#[test]
fn glb_wrong_magic() {
    let mut g = good_glb();
    g[..4].copy_from_slice(b"gLTx");
    bad_scene("glb-magic", "s.glb", &g, "not a valid gltf");
}

#[test]
fn glb_wrong_version() {
    let mut g = good_glb();
    g[4..8].copy_from_slice(&1u32.to_le_bytes());
    bad_scene("glb-version", "s.glb", &g, "not a valid gltf");
}

#[test]
fn glb_length_beyond_the_file() {
    let mut g = good_glb();
    let len = g.len() as u32 + 1000;
    g[8..12].copy_from_slice(&len.to_le_bytes());
    bad_scene("glb-length", "s.glb", &g, "not a valid gltf");
}

#[test]
fn glb_json_chunk_beyond_the_file() {
    let mut g = good_glb();
    g[12..16].copy_from_slice(&100_000u32.to_le_bytes());
    bad_scene("glb-chunk", "s.glb", &g, "not a valid gltf");
}

/// `train --scene` on a scene whose own materials are all opaque (glTF triangles with no
/// material: glTF's default is opaque) says so, names the scene and --opacity, and writes no
/// weights; with --opacity it trains.
#[test]
fn fine_tuning_on_an_opaque_scene_names_the_problem_and_takes_an_opacity() {
    let dir = case_dir("train-opaque");
    let path = dir.join("opaque.glb");
    // Six triangles, one behind the other: six fragments deep where they overlap (a k the
    // network decides: up to 3 deep it is forced).
    let quads: Vec<[f32; 3]> = (0..6)
        .flat_map(|layer| TRI.map(|p| [p[0], p[1], -0.1 * layer as f32]))
        .collect();
    let (j, b) = gltf_json(&quads, None, serde_json::json!({}));
    std::fs::write(&path, glb(&j, &b)).unwrap();
    let scene = path.to_str().unwrap();
    let weights = dir.join("w.safetensors");
    let w = weights.to_str().unwrap();
    let args = [
        "train", "--scene", scene, "--res", "32x24", "--epochs", "1", "--out", w,
    ];
    fails(&dir, &args, "no transparent surface");
    fails(&dir, &args, "--opacity");
    assert!(!weights.exists(), "weights written for an opaque scene");
    let mut with = args.to_vec();
    with.extend(["--opacity", "0.33"]);
    let o = common::dhoit(&with);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(weights.is_file(), "no weights with --opacity");
    let mut bad = args.to_vec();
    bad.extend(["--opacity", "1.5"]);
    fails(&dir, &bad, "--opacity 1.5");
}

#[test]
fn gltf_not_json() {
    bad_scene(
        "gltf-json",
        "s.gltf",
        b"{ not json at all",
        "not a valid gltf",
    );
}

#[test]
fn gltf_missing_buffer_file() {
    let (mut j, _) = gltf_json(&TRI, None, serde_json::json!({}));
    j["buffers"][0]["uri"] = "nowhere.bin".into();
    bad_scene(
        "gltf-missing-bin",
        "s.gltf",
        &serde_json::to_vec(&j).unwrap(),
        "buffer",
    );
}

#[test]
fn gltf_short_buffer() {
    let dir = case_dir("gltf-short-bin");
    let (mut j, b) = gltf_json(&TRI, None, serde_json::json!({}));
    j["buffers"][0] = serde_json::json!({"uri": "s.bin", "byteLength": b.len() + 400});
    std::fs::write(dir.join("s.bin"), &b).unwrap();
    let path = dir.join("s.gltf");
    std::fs::write(&path, serde_json::to_vec(&j).unwrap()).unwrap();
    render_scene(&dir, &path, "buffer");
}

#[test]
fn gltf_index_out_of_range() {
    let (j, b) = gltf_json(&TRI, Some(&[0, 1, 7]), serde_json::json!({}));
    bad_scene("gltf-oob", "s.glb", &glb(&j, &b), "out of range");
}

#[test]
fn gltf_accessor_beyond_its_view() {
    let (mut j, b) = gltf_json(&TRI, None, serde_json::json!({}));
    j["accessors"][0]["count"] = 300.into();
    bad_scene("gltf-accessor", "s.glb", &glb(&j, &b), "accessor");
}

#[test]
fn gltf_nan_positions() {
    let p = [[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let (j, b) = gltf_json(&p, None, serde_json::json!({}));
    bad_scene("gltf-nan", "s.glb", &glb(&j, &b), "not finite");
}

#[test]
fn gltf_huge_positions() {
    let p = [[3e38, 0.0, 0.0], [-3e38, 0.0, 0.0], [0.0, 3e38, 0.0]];
    let (j, b) = gltf_json(&p, None, serde_json::json!({}));
    bad_scene("gltf-huge", "s.glb", &glb(&j, &b), "too large");
}

#[test]
fn gltf_zero_triangles() {
    let (j, b) = gltf_json(&TRI[..0], None, serde_json::json!({}));
    bad_scene("gltf-zero", "s.glb", &glb(&j, &b), "no triangles");
}

#[test]
fn gltf_only_degenerate_triangles() {
    let p = [[0.5, 0.5, 0.5]; 6];
    let (j, b) = gltf_json(&p, None, serde_json::json!({}));
    bad_scene("gltf-degenerate", "s.glb", &glb(&j, &b), "degenerate");
}

#[test]
fn gltf_position_names_a_missing_accessor() {
    // Found by tests/fuzz.rs: the gltf crate panicked on it.
    let (mut j, b) = gltf_json(&TRI, None, serde_json::json!({}));
    j["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 5.into();
    bad_scene(
        "gltf-position-accessor",
        "s.glb",
        &glb(&j, &b),
        "names accessor 5",
    );
}

#[test]
fn gltf_no_scene() {
    let (mut j, b) = gltf_json(&TRI, None, serde_json::json!({}));
    j.as_object_mut().unwrap().remove("scene");
    j["scenes"] = serde_json::json!([]);
    bad_scene("gltf-no-scene", "s.glb", &glb(&j, &b), "no scene");
}

/// A GLB of one triangle textured from the image file `uri`, with texture coordinates `uv`.
fn textured_glb(uv: [[f32; 2]; 3], uri: &str) -> Vec<u8> {
    let uv: Vec<u8> = uv.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    let (mut j, mut b) = gltf_json(&TRI, None, serde_json::json!({}));
    let off = b.len();
    b.extend(&uv);
    j["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"buffer": 0, "byteOffset": off, "byteLength": uv.len()}));
    j["accessors"].as_array_mut().unwrap().push(
        serde_json::json!({"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}),
    );
    j["buffers"][0]["byteLength"] = b.len().into();
    j["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = 1.into();
    j["meshes"][0]["primitives"][0]["material"] = 0.into();
    j["materials"] =
        serde_json::json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    j["textures"] = serde_json::json!([{"source": 0}]);
    j["images"] = serde_json::json!([{ "uri": uri }]);
    glb(&j, &b)
}

const UV: [[f32; 2]; 3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];

#[test]
fn gltf_texture_that_is_not_an_image() {
    let dir = case_dir("gltf-texture");
    std::fs::write(dir.join("tex.png"), b"this is not a PNG").unwrap();
    let path = dir.join("s.glb");
    std::fs::write(&path, textured_glb(UV, "tex.png")).unwrap();
    // The message names the image's file, so a user knows which of a scene's textures is bad.
    render_scene(&dir, &path, "cannot decode image 0 (tex.png)");
}

#[test]
fn gltf_texture_file_missing() {
    bad_scene(
        "gltf-texture-missing",
        "s.glb",
        &textured_glb(UV, "missing.png"),
        "image 0 (missing.png)",
    );
}

#[test]
fn gltf_texture_coordinates_not_finite() {
    let dir = case_dir("gltf-texture-nan");
    // A good image, so only the coordinates are wrong.
    let mut tex = dhoit_runtime::composite::Image::new((2, 2));
    tex.data.fill([1.0, 0.5, 0.25]);
    dhoit_runtime::image_io::write_image(&dir.join("tex.png"), &tex).unwrap();
    let path = dir.join("s.glb");
    let uv = [[0.0, 0.0], [f32::NAN, 0.0], [0.0, f32::INFINITY]];
    std::fs::write(&path, textured_glb(uv, "tex.png")).unwrap();
    render_scene(&dir, &path, "texture coordinates that are not finite");
}

#[test]
fn gltf_colours_and_positions_disagree() {
    let (mut j, mut b) = gltf_json(&TRI, None, serde_json::json!({}));
    let off = b.len();
    b.extend([1.0f32; 8].iter().flat_map(|v| v.to_le_bytes()));
    j["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"buffer": 0, "byteOffset": off, "byteLength": 32}));
    j["accessors"].as_array_mut().unwrap().push(
        serde_json::json!({"bufferView": 1, "componentType": 5126, "count": 2, "type": "VEC4"}),
    );
    j["buffers"][0]["byteLength"] = b.len().into();
    j["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = 1.into();
    bad_scene("gltf-colours", "s.glb", &glb(&j, &b), "count");
}

#[test]
fn scene_file_missing() {
    let dir = case_dir("scene-missing");
    render_scene(&dir, &dir.join("absent.glb"), "cannot read");
}

#[test]
fn scene_is_a_folder() {
    let dir = case_dir("scene-folder");
    let sub = dir.join("folder.glb");
    std::fs::create_dir_all(&sub).unwrap();
    render_scene(&dir, &sub, "cannot read");
}

// ---------------------------------------------------------------------------------------------
// Weights and features (safetensors)

/// One tensor of a hand-made safetensors file: name, dtype, shape, raw bytes.
type RawTensor = (&'static str, &'static str, Vec<usize>, Vec<u8>);
/// Its metadata entries.
type RawMeta = Vec<(&'static str, String)>;

/// A safetensors file from raw parts: (name, dtype, shape, bytes) and metadata.
fn safetensors(tensors: &[RawTensor], meta: &[(&str, String)]) -> Vec<u8> {
    let mut header = serde_json::Map::new();
    let mut data: Vec<u8> = Vec::new();
    for (name, dtype, shape, bytes) in tensors {
        header.insert(
            name.to_string(),
            serde_json::json!({"dtype": dtype, "shape": shape, "data_offsets": [data.len(), data.len() + bytes.len()]}),
        );
        data.extend(bytes);
    }
    if !meta.is_empty() {
        let m: serde_json::Map<String, serde_json::Value> = meta
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone().into()))
            .collect();
        header.insert("__metadata__".into(), m.into());
    }
    let mut h = serde_json::to_vec(&header).unwrap();
    while !h.len().is_multiple_of(8) {
        h.push(b' ');
    }
    let mut out = (h.len() as u64).to_le_bytes().to_vec();
    out.extend(h);
    out.extend(data);
    out
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The parts of a valid weights file of hidden sizes h1, h2 (random weights).
fn weight_parts(h1: usize, h2: usize) -> (Vec<RawTensor>, RawMeta) {
    let m = Mlp::random_sized(1, h1.min(128), h2.min(128));
    let rnd = |n: usize| f32s(&vec![0.01; n]);
    let tensors = vec![
        ("fc1.weight", "F32", vec![12, h1], rnd(12 * h1)),
        ("fc1.bias", "F32", vec![h1], rnd(h1)),
        ("fc2.weight", "F32", vec![h1, h2], rnd(h1 * h2)),
        ("fc2.bias", "F32", vec![h2], rnd(h2)),
        ("out.weight", "F32", vec![h2, 1], rnd(h2)),
        ("out.bias", "F32", vec![1], rnd(1)),
    ];
    let meta = vec![
        ("format", dhoit_runtime::mlp::FORMAT.to_string()),
        ("layout", dhoit_runtime::mlp::LAYOUT.to_string()),
        ("target", "slot_request".to_string()),
        (
            "features",
            serde_json::to_string(&dhoit_runtime::importance::FEATURE_NAMES).unwrap(),
        ),
        ("input_mean", serde_json::to_string(&m.mean).unwrap()),
        ("input_std", serde_json::to_string(&m.std).unwrap()),
    ];
    (tensors, meta)
}

/// Renders DKB with the given weights file bytes; and predicts with them.
fn bad_weights(name: &str, bytes: &[u8], needle: &str) {
    let dir = case_dir(name);
    let w = dir.join("w.safetensors");
    std::fs::write(&w, bytes).unwrap();
    let w = w.to_str().unwrap();
    fails(
        &dir,
        &[
            "render",
            "--scene",
            "shells",
            "--res",
            "32x24",
            "--method",
            "dkb",
            "--weights",
            w,
            "--out",
            "{out}",
        ],
        needle,
    );
    let feats = dir.join("f.safetensors");
    std::fs::write(
        &feats,
        safetensors(&[("features", "F32", vec![2, 12], f32s(&[0.5; 24]))], &[]),
    )
    .unwrap();
    fails(
        &dir,
        &[
            "predict",
            "--weights",
            w,
            "--input",
            feats.to_str().unwrap(),
            "--output",
            "{out}",
        ],
        needle,
    );
}

fn weights_with(edit: impl FnOnce(&mut Vec<RawTensor>, &mut RawMeta)) -> Vec<u8> {
    let (mut t, mut m) = weight_parts(128, 64);
    edit(&mut t, &mut m);
    safetensors(&t, &m)
}

#[test]
fn weights_valid_parts_load() {
    // The builder itself makes a file the runtime accepts, so the cases below fail for their
    // one defect.
    let bytes = weights_with(|_, _| {});
    Mlp::from_bytes(&bytes).unwrap();
}

#[test]
fn weights_truncated() {
    let b = weights_with(|_, _| {});
    bad_weights("w-truncated", &b[..b.len() / 2], "weights");
}

#[test]
fn weights_not_safetensors() {
    bad_weights(
        "w-garbage",
        b"definitely not tensors",
        "not a safetensors file",
    );
}

#[test]
fn weights_huge_header_length() {
    let mut b = weights_with(|_, _| {});
    b[..8].copy_from_slice(&(1u64 << 60).to_le_bytes());
    bad_weights("w-header", &b, "not a safetensors file");
}

#[test]
fn weights_wrong_dtype() {
    let b = weights_with(|t, _| {
        t[1] = ("fc1.bias", "F64", vec![64], vec![0; 512]);
    });
    bad_weights("w-dtype", &b, "fc1.bias");
}

#[test]
fn weights_missing_tensor() {
    let b = weights_with(|t, _| {
        t.remove(3);
    });
    bad_weights("w-missing", &b, "fc2.bias");
}

#[test]
fn weights_wrong_shape() {
    let b = weights_with(|t, _| {
        t[0] = (
            "fc1.weight",
            "F32",
            vec![11, 128],
            f32s(&vec![0.0; 11 * 128]),
        );
    });
    bad_weights("w-shape", &b, "fc1.weight");
}

#[test]
fn weights_non_finite() {
    let b = weights_with(|t, _| {
        let mut v = vec![0.01f32; 64];
        v[7] = f32::INFINITY;
        t[3] = ("fc2.bias", "F32", vec![64], f32s(&v));
    });
    bad_weights("w-inf", &b, "non-finite");
}

#[test]
fn weights_nan() {
    let b = weights_with(|t, _| {
        t[5] = ("out.bias", "F32", vec![1], f32s(&[f32::NAN]));
    });
    bad_weights("w-nan", &b, "non-finite");
}

#[test]
fn weights_beyond_the_largest_magnitude() {
    // Found by tests/fuzz.rs: finite but huge weights made the output NaN.
    let b = weights_with(|t, _| {
        let mut v = vec![0.01f32; 128 * 64];
        v[100] = 3.4e38;
        t[2] = ("fc2.weight", "F32", vec![128, 64], f32s(&v));
    });
    bad_weights("w-huge", &b, "largest magnitude");
}

#[test]
fn gltf_colours_of_a_type_gltf_does_not_allow() {
    // Found by tests/fuzz.rs: the gltf crate's reader reached unreachable!() on it.
    let bytes = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/glb-color-of-signed-bytes.bin"),
    )
    .unwrap();
    bad_scene("gltf-colour-type", "s.glb", &bytes, "COLOR_0 is I8 Vec4");
}

#[test]
fn weights_missing_metadata() {
    let b = weights_with(|_, m| m.clear());
    bad_weights("w-meta", &b, "metadata");
}

#[test]
fn weights_wrong_format() {
    let b = weights_with(|_, m| m[0].1 = "dhoit-mlp-0".into());
    bad_weights("w-format", &b, "format");
}

#[test]
fn weights_other_features() {
    let b = weights_with(|_, m| m[3].1 = r#"["a","b"]"#.into());
    bad_weights("w-features", &b, "features");
}

#[test]
fn weights_zero_std() {
    let b = weights_with(|_, m| m[5].1 = serde_json::to_string(&[0.0f32; 12]).unwrap());
    bad_weights("w-std", &b, "input_std");
}

#[test]
fn weights_hidden_layer_too_large() {
    let (t, m) = weight_parts(8, 256);
    bad_weights("w-hidden", &safetensors(&t, &m), "at most");
}

#[test]
fn weights_unknown_target() {
    let b = weights_with(|_, m| m[2].1 = "k_squared".into());
    bad_weights("w-target", &b, "target");
}

#[test]
fn weights_unknown_precision() {
    let b = weights_with(|_, m| m.push(("precision", "f64".into())));
    bad_weights("w-precision", &b, "metadata 'precision': 'f64'");
}

#[test]
fn weights_at_f16_beyond_its_range() {
    // A file that says f16 but holds a weight binary16 cannot store.
    let b = weights_with(|t, m| {
        let mut v = vec![0.01f32; 128 * 64];
        v[7] = 1e5;
        t[2] = ("fc2.weight", "F32", vec![128, 64], f32s(&v));
        m.push(("precision", "f16".into()));
    });
    bad_weights(
        "w-f16-range",
        &b,
        "fc2.weight[7] = 100000 is beyond f16's range",
    );
}

/// Predicts with the committed weights on a features file.
fn bad_features(name: &str, bytes: &[u8], needle: &str) {
    let dir = case_dir(name);
    let f = dir.join("f.safetensors");
    std::fs::write(&f, bytes).unwrap();
    let w = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/weights.safetensors");
    fails(
        &dir,
        &[
            "predict",
            "--weights",
            w.to_str().unwrap(),
            "--input",
            f.to_str().unwrap(),
            "--output",
            "{out}",
        ],
        needle,
    );
}

#[test]
fn features_truncated() {
    let b = safetensors(&[("features", "F32", vec![4, 12], f32s(&[0.5; 48]))], &[]);
    bad_features("f-truncated", &b[..b.len() - 10], "not a safetensors file");
}

#[test]
fn features_wrong_dtype() {
    let b = safetensors(&[("features", "U32", vec![4, 12], vec![0; 192])], &[]);
    bad_features("f-dtype", &b, "features");
}

#[test]
fn features_wrong_shape() {
    let b = safetensors(&[("features", "F32", vec![4, 11], f32s(&[0.5; 44]))], &[]);
    bad_features("f-shape", &b, "expected [N, 12]");
}

#[test]
fn features_wrong_name() {
    let b = safetensors(&[("inputs", "F32", vec![4, 12], f32s(&[0.5; 48]))], &[]);
    bad_features("f-name", &b, "features");
}

#[test]
fn features_non_finite() {
    let mut v = vec![0.5f32; 48];
    v[13] = f32::NEG_INFINITY;
    let b = safetensors(&[("features", "F32", vec![4, 12], f32s(&v))], &[]);
    bad_features("f-inf", &b, "non-finite feature at row 1, column 1");
}

#[test]
fn features_missing_file() {
    let dir = case_dir("f-missing");
    let w = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/weights.safetensors");
    fails(
        &dir,
        &[
            "predict",
            "--weights",
            w.to_str().unwrap(),
            "--input",
            dir.join("absent").to_str().unwrap(),
            "--output",
            "{out}",
        ],
        "cannot read",
    );
}

#[test]
fn dump_corrupt() {
    let dir = case_dir("dump");
    std::fs::write(dir.join("fragments.safetensors"), b"\x10\0\0\0\0\0\0\0{}").unwrap();
    let e = dhoit_runtime::dump::read(&dir).unwrap_err().to_string();
    assert!(e.contains("fragments.safetensors"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Command-line arguments

fn bad_render(name: &str, extra: &[&str], needle: &str) {
    let dir = case_dir(name);
    let mut args = vec!["render", "--scene", "shells", "--out", "{out}"];
    args.extend_from_slice(extra);
    fails(&dir, &args, needle);
}

#[test]
fn resolution_zero() {
    bad_render("res-zero", &["--res", "0x48"], "invalid resolution");
}

#[test]
fn resolution_negative() {
    bad_render("res-negative", &["--res", "-64x48"], "invalid resolution");
}

#[test]
fn resolution_enormous() {
    bad_render(
        "res-enormous",
        &["--res", "100000x100000"],
        "invalid resolution",
    );
}

#[test]
fn resolution_unparsable() {
    bad_render("res-text", &["--res", "wide"], "invalid resolution");
}

#[test]
fn budget_unparsable() {
    bad_render(
        "budget-text",
        &["--res", "32x24", "--budget", "12 parsecs"],
        "invalid budget",
    );
}

#[test]
fn budget_negative() {
    bad_render(
        "budget-negative",
        &["--res", "32x24", "--budget", "-2fpp"],
        "invalid budget",
    );
}

#[test]
fn budget_zero_share() {
    bad_render(
        "budget-share",
        &["--res", "32x24", "--budget", "0%"],
        "invalid budget",
    );
}

#[test]
fn budget_over_everything() {
    bad_render(
        "budget-150",
        &["--res", "32x24", "--budget", "150%"],
        "at most 100%",
    );
}

#[test]
fn budget_below_the_fixed_cost() {
    bad_render(
        "budget-small",
        &["--res", "32x24", "--method", "vkb", "--budget", "1KB"],
        "needs",
    );
}

/// `bench` measures FKB, the optimal allocation, VKB and DKB at one budget: one too small for
/// any of them is refused before the first measurement, as `render` refuses it (with
/// `--gpu-only` too, not recorded as every scene's error with the run exiting 0); so is a
/// report it could not write (refused before measuring, not after).
#[test]
fn bench_refuses_a_budget_or_report_it_cannot_use_before_measuring() {
    let dir = case_dir("bench-budget");
    for (budget, needle) in [
        ("1KB", "fkb needs"),
        ("0.5fpp", "fkb needs one slot for every pixel"),
    ] {
        for gpu_only in [true, false] {
            let mut args = vec![
                "bench", "--scenes", "cad", "--res", "32x24", "--budget", budget, "--out", "{out}",
            ];
            if gpu_only {
                args.push("--gpu-only");
            }
            fails(&dir, &args, needle);
        }
    }
    // A report that cannot be written is found before the first measurement (the GPU part
    // names its adapter when it starts).
    std::fs::write(dir.join("file"), b"x").unwrap();
    let report = dir.join("file/bench.json");
    let report = report.to_str().unwrap();
    let o = common::dhoit(&[
        "bench",
        "--gpu-only",
        "--scenes",
        "cad",
        "--res",
        "32x24",
        "--out",
        report,
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "an unwritable report succeeded");
    assert!(err.contains("cannot create the folder"), "{err}");
    assert!(!err.contains("GPU:"), "measured before refusing: {err}");
}

#[test]
fn no_repetitions() {
    let dir = case_dir("repeat");
    for cmd in ["bench", "trade"] {
        fails(
            &dir,
            &[cmd, "--repeat", "0", "--out", "{out}"],
            "at least one repetition",
        );
    }
}

#[test]
fn opacity_not_a_number() {
    bad_render(
        "opacity",
        &["--res", "32x24", "--opacity", "NaN"],
        "opacity",
    );
}

#[test]
fn view_out_of_range() {
    bad_render(
        "view",
        &["--res", "32x24", "--view", "99"],
        "view 99 does not exist",
    );
}

#[test]
fn no_views() {
    bad_render(
        "views",
        &["--res", "32x24", "--views", "0"],
        "an orbit needs at least one view",
    );
}

#[test]
fn unknown_method() {
    bad_render(
        "method",
        &["--res", "32x24", "--method", "magic"],
        "unknown method",
    );
}

#[test]
fn unwritable_output() {
    let dir = case_dir("unwritable");
    // A path below a file cannot be created.
    std::fs::write(dir.join("file"), b"x").unwrap();
    let out = dir.join("file/out.png");
    fails(
        &dir,
        &[
            "render",
            "--scene",
            "shells",
            "--res",
            "32x24",
            "--out",
            out.to_str().unwrap(),
        ],
        "cannot",
    );
}

/// A dump or k map that cannot be written stops `render` before its image is written
/// (`fails` checks that `{out}` is not there).
#[test]
fn unwritable_dump_or_kmap_leaves_no_image() {
    let dir = case_dir("unwritable-extra");
    std::fs::write(dir.join("file"), b"x").unwrap();
    let below_a_file = dir.join("file/sub");
    let kmap = below_a_file.join("k.png");
    for extra in [
        ["--dump", below_a_file.to_str().unwrap()],
        ["--kmap", kmap.to_str().unwrap()],
    ] {
        let mut args = vec![
            "render", "--scene", "cad", "--res", "32x24", "--out", "{out}",
        ];
        args.extend(extra);
        fails(&dir, &args, "cannot create the folder");
    }
}

/// `fit` scores every shipped network before it writes one: a weights path it cannot write is
/// refused before the first is scored.
#[test]
fn fit_to_an_unwritable_path() {
    let dir = case_dir("fit-unwritable");
    std::fs::write(dir.join("file"), b"x").unwrap();
    let weights = dir.join("file/w.safetensors");
    let weights = weights.to_str().unwrap();
    let o = common::dhoit(&[
        "fit", "--scene", "cad", "--res", "32x24", "--target", "100", "--out", weights,
    ]);
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(!o.status.success(), "fit to {weights} succeeded");
    assert!(err.contains("cannot create the folder"), "{err}");
    assert!(
        !out.contains("MSE / optimal"),
        "scored before refusing: {out}"
    );
}

#[test]
fn export_without_a_glb_name() {
    let dir = case_dir("export-name");
    fails(
        &dir,
        &["export", "--scene", "cad", "--out", "{out}"],
        ".glb",
    );
}

#[test]
fn dataset_sample_out_of_range() {
    let dir = case_dir("dataset-sample");
    fails(
        &dir,
        &[
            "dataset",
            "--scenes",
            "shells",
            "--views",
            "1",
            "--sample",
            "0",
            "--out",
            dir.join("ds").to_str().unwrap(),
        ],
        "sample",
    );
}

/// A training setting that cannot work is refused before the dataset is read (or generated,
/// which takes minutes): here the dataset does not exist either, and the setting is named.
#[test]
fn training_settings_that_cannot_work_are_refused_before_the_dataset_is_read() {
    let dir = case_dir("train-epochs");
    let data = dir.join("absent");
    let data = data.to_str().unwrap();
    for (setting, value, needle) in [
        ("--epochs", "0", "epochs and batch must be positive"),
        ("--lr", "NaN", "lr NaN must be a positive number"),
        ("--l2", "inf", "l2 inf finite and non-negative"),
        ("--momentum", "1", "momentum 1 must be in [0, 1)"),
        ("--hidden", "8,256", "hidden sizes 8,256"),
    ] {
        let args = ["train", "--data", data, setting, value, "--out", "{out}"];
        fails(&dir, &args, needle);
    }
    // So is a weights file whose folder cannot be made (before the first epoch, not after the
    // last).
    std::fs::write(dir.join("file"), b"x").unwrap();
    let weights = dir.join("file/w.safetensors");
    let args = ["train", "--data", data, "--out", weights.to_str().unwrap()];
    fails(&dir, &args, "cannot create the folder");
}

#[test]
fn train_on_a_folder_without_a_dataset() {
    let dir = case_dir("train-nodata");
    let _ = HashMap::<u8, u8>::new();
    fails(
        &dir,
        &["train", "--data", dir.to_str().unwrap(), "--out", "{out}"],
        "manifest",
    );
}

#[test]
fn gpu_without_an_adapter() {
    // No Metal adapter exists on this machine: the GPU path says what it needs.
    let dir = case_dir("no-adapter");
    fails_with_env(
        &dir,
        &[
            "render", "--scene", "shells", "--res", "32x24", "--device", "gpu", "--out", "{out}",
        ],
        &[(
            "WGPU_BACKEND",
            if cfg!(target_os = "macos") {
                "dx12"
            } else {
                "metal"
            },
        )],
        "no GPU adapter found: dhoit needs a Vulkan, Metal or DX12 device",
    );
}

#[test]
fn trade_and_fit_refuse_what_they_cannot_do() {
    let dir = case_dir("trade-fit");
    fails(
        &dir,
        &[
            "fit",
            "--scene",
            "cad",
            "--weights",
            "w.safetensors",
            "--out",
            "{out}",
        ],
        "--networks",
    );
    fails(
        &dir,
        &["fit", "--scene", "cad", "--target", "0.5", "--out", "{out}"],
        "at least 1",
    );
    fails(
        &dir,
        &[
            "fit",
            "--scene",
            "cad",
            "--networks",
            "missing.safetensors",
            "--out",
            "{out}",
        ],
        "missing.safetensors",
    );
    fails(
        &dir,
        &[
            "trade",
            "--scene",
            "cad",
            "--precision",
            "f8",
            "--out",
            "{out}",
        ],
        "offers f32",
    );
    fails(
        &dir,
        &[
            "trade", "--scene", "cad", "--timing", "tpu", "--out", "{out}",
        ],
        "expected gpu, cpu or auto",
    );
}

/// The commands that render several scenes, views or budgets check every one before the first
/// frame: a bad name late in the list stops the command before it renders or writes anything
/// (`fails` checks that `{out}` was not created).
#[test]
fn a_bad_scene_or_view_late_in_a_list_stops_the_command_before_its_first_frame() {
    let dir = case_dir("late-in-a-list");
    let scenes = "cad,no-such-scene";
    for cmd in ["compare", "trade"] {
        let args = [cmd, "--scene", scenes, "--res", "32x24", "--out", "{out}"];
        fails(&dir, &args, "unknown scene 'no-such-scene'");
        let args = [
            cmd, "--scene", "cad", "--res", "32x24", "--view", "0,8", "--out", "{out}",
        ];
        fails(&dir, &args, "view 8 does not exist");
    }
    let args = [
        "bench",
        "--gpu-only",
        "--res",
        "32x24",
        "--scenes",
        scenes,
        "--out",
        "{out}",
    ];
    fails(&dir, &args, "unknown scene 'no-such-scene'");
    let args = [
        "fit", "--scene", "cad", "--res", "32x24", "--view", "1,8", "--target", "2", "--out",
        "{out}",
    ];
    fails(&dir, &args, "view 8 does not exist");
    let args = [
        "score", "--scene", scenes, "--res", "32x24", "--json", "{out}",
    ];
    fails(&dir, &args, "unknown scene 'no-such-scene'");
    let args = [
        "score",
        "--scene",
        "cad",
        "--orbit-views",
        "0",
        "--json",
        "{out}",
    ];
    fails(&dir, &args, "an orbit needs at least one view");
}

/// A view whose fragments would not fit in memory is refused before it is rasterized, with the
/// numbers (here under a cap set by DHOIT_MAX_MEMORY, as on a small machine).
#[test]
fn a_view_too_large_for_memory_is_refused_before_rasterizing() {
    let dir = case_dir("memory");
    let args = [
        "render", "--scene", "plates", "--res", "320x240", "--out", "{out}",
    ];
    fails_with_env(
        &dir,
        &args,
        &[("DHOIT_MAX_MEMORY", "4MiB")],
        "rasterizing them on the CPU takes about",
    );
    fails_with_env(
        &dir,
        &args,
        &[("DHOIT_MAX_MEMORY", "plenty")],
        "DHOIT_MAX_MEMORY='plenty'",
    );
    // Under 8 MiB, cad's view at 320x240 rasterizes (about 5 MiB at the peak), and then what
    // each method adds is checked: DKB's features and importance do not fit (about 11 MiB),
    // the A-buffer's image does (about 5 MiB), and is written.
    let cap = [("DHOIT_MAX_MEMORY", "8MiB")];
    let args = [
        "render", "--scene", "cad", "--res", "320x240", "--out", "{out}",
    ];
    let dkb = [&args[..], &["--method", "dkb"]].concat();
    fails_with_env(&dir, &dkb, &cap, "dkb needs about");
    let out = dir.join("abuffer.png");
    let abuffer = [&args[..args.len() - 1], &[out.to_str().unwrap()]].concat();
    let o = common::dhoit_with_env(&abuffer, &cap);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.is_file());
}

#[test]
fn scenes_under_a_folder_that_is_not_there() {
    let dir = case_dir("scenes-folder");
    let missing = dir.join("no-such-folder");
    let env = [("DHOIT_SCENES", missing.to_str().unwrap())];
    fails_with_env(&dir, &["scenes"], &env, "no-such-folder: not a folder");
}
