//! Structured fuzzing with proptest: valid glTF/GLB, weights, features and dump files, mutated
//! (bytes flipped, set, cut, inserted, chunks repeated), go through their parsers, which must
//! return a value or an error and never panic or hang. A bounded number of cases runs in CI;
//! `make fuzz` runs many more (PROPTEST_CASES). Inputs that once broke a parser are kept in
//! tests/corpus/ and replayed by `the_regression_corpus_parses_without_panicking`.
mod common;
use common::root;

use dhoit_runtime::scene::{self, Opacity};
use proptest::prelude::*;
use std::path::PathBuf;
use std::sync::OnceLock;

/// One edit of a byte string.
#[derive(Clone, Debug)]
enum Edit {
    Flip(usize, u8),
    Set(usize, u8),
    Truncate(usize),
    Insert(usize, Vec<u8>),
    Repeat(usize, usize),
    /// A little-endian u32 or u64 written over the bytes (lengths and offsets live there).
    Word(usize, u64, bool),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), 1u8..=255).prop_map(|(i, b)| Edit::Flip(i, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Edit::Set(i, b)),
        any::<usize>().prop_map(Edit::Truncate),
        (any::<usize>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, v)| Edit::Insert(i, v)),
        (any::<usize>(), 1usize..64).prop_map(|(i, n)| Edit::Repeat(i, n)),
        (
            any::<usize>(),
            prop_oneof![
                Just(0u64),
                Just(u32::MAX as u64),
                Just(u64::MAX),
                any::<u64>(),
                0u64..4096
            ],
            any::<bool>()
        )
            .prop_map(|(i, v, wide)| Edit::Word(i, v, wide)),
    ]
}

fn apply(b: Vec<u8>, edits: &[Edit]) -> Vec<u8> {
    apply_within(b, edits, usize::MAX)
}

/// Where a safetensors file's header ends: its 8-byte length, then the JSON.
fn header_end(b: &[u8]) -> usize {
    match b.get(..8) {
        Some(n) => (8 + u64::from_le_bytes(n.try_into().unwrap()) as usize).min(b.len()),
        None => b.len(),
    }
}

/// [`apply`] with every edit's place taken in the first `limit` bytes.
fn apply_within(mut b: Vec<u8>, edits: &[Edit], limit: usize) -> Vec<u8> {
    for e in edits {
        if b.is_empty() {
            break;
        }
        let span = b.len().min(limit).max(1);
        let at = |i: usize| i % span;
        match e {
            Edit::Flip(i, x) => {
                let i = at(*i);
                b[i] ^= x;
            }
            Edit::Set(i, x) => {
                let i = at(*i);
                b[i] = *x;
            }
            Edit::Truncate(i) => {
                let i = at(*i);
                b.truncate(i);
            }
            Edit::Insert(i, v) => {
                let i = at(*i);
                b.splice(i..i, v.iter().copied());
            }
            Edit::Repeat(i, n) => {
                let i = at(*i);
                let end = (i + n).min(b.len());
                let chunk = b[i..end].to_vec();
                b.splice(end..end, chunk);
            }
            Edit::Word(i, v, wide) => {
                let w = if *wide { 8 } else { 4 };
                if b.len() >= w {
                    let i = (i % span).min(b.len() - w);
                    b[i..i + w].copy_from_slice(&v.to_le_bytes()[..w]);
                }
            }
        }
    }
    b
}

/// Valid seeds, built once: a small built-in scene as GLB, the default weights, the golden
/// features and a fragment dump.
struct Seeds {
    glb: Vec<u8>,
    weights: Vec<u8>,
    features: Vec<u8>,
    dump: Vec<u8>,
}

fn seeds() -> &'static Seeds {
    static S: OnceLock<Seeds> = OnceLock::new();
    S.get_or_init(|| {
        let mut s = scene::load("plates", Opacity::Material).unwrap();
        // Keep the seed small so each case parses quickly.
        s.positions.truncate(3 * 40);
        s.colors.truncate(3 * 40);
        s.uvs.truncate(3 * 40);
        s.triangle_material.truncate(40);
        let glb = scene::gltf::to_glb(&s).unwrap();
        let weights = std::fs::read(root().join("data/weights.safetensors")).unwrap();
        let features = std::fs::read(root().join("data/golden/features.safetensors")).unwrap();
        let dir = common::temp_dir("fuzz");
        let cam = scene::Camera::orbit(&s, 0, 8, (12, 9));
        let fl = dhoit_runtime::raster::rasterize(&s, &cam, (12, 9)).unwrap();
        let frame = dhoit_runtime::frame::render(
            &fl,
            dhoit_runtime::frame::Method::Fkb,
            dhoit_runtime::frame::Options::new(
                dhoit_runtime::budget::Budget::SlotsPerPixel(2.0),
                [1.0; 3],
            ),
        )
        .unwrap();
        let path = dhoit_runtime::dump::write(
            &dir,
            &dhoit_runtime::dump::Dump {
                fragments: fl,
                k: frame.k,
                image: frame.image,
                method: "fkb".into(),
                budget_bytes: frame.budget_bytes,
                budget_fragments: frame.budget_fragments,
                background: [1.0; 3],
            },
        )
        .unwrap();
        let dump = std::fs::read(path).unwrap();
        Seeds {
            glb,
            weights,
            features,
            dump,
        }
    })
}

/// A path in a folder without other files, so external buffers a mutated file names are
/// looked up where none exist.
fn phantom(name: &str) -> PathBuf {
    std::env::temp_dir()
        .join(format!("dhoit-fuzz-empty-{}", std::process::id()))
        .join(name)
}

/// One change to a safetensors header's JSON: a tensor's dtype, shape or data offsets, or a
/// metadata value, replaced by one of the values a broken writer or a hostile file would hold;
/// the file is written back with the header's new length.
#[derive(Clone, Debug)]
enum HeaderEdit {
    Dtype(usize, &'static str),
    Shape(usize, Vec<u64>),
    Offsets(usize, u64, u64),
    Metadata(usize, String),
    Drop(usize),
}

fn header_edit() -> impl Strategy<Value = HeaderEdit> {
    let big = prop_oneof![
        0u64..64,
        Just(u32::MAX as u64),
        Just(u64::MAX / 2),
        any::<u64>()
    ];
    prop_oneof![
        (
            any::<usize>(),
            prop::sample::select(vec!["F32", "F16", "F64", "I32", "U8", "BOGUS", ""])
        )
            .prop_map(|(i, d)| HeaderEdit::Dtype(i, d)),
        (any::<usize>(), prop::collection::vec(big.clone(), 0..4))
            .prop_map(|(i, v)| HeaderEdit::Shape(i, v)),
        (any::<usize>(), big.clone(), big).prop_map(|(i, a, b)| HeaderEdit::Offsets(i, a, b)),
        (
            any::<usize>(),
            prop::sample::select(vec![
                "",
                "[]",
                "[1e400]",
                "NaN",
                "-1",
                "{",
                "[0.5, 0.5]",
                "f64"
            ])
        )
            .prop_map(|(i, v)| HeaderEdit::Metadata(i, v.to_string())),
        any::<usize>().prop_map(HeaderEdit::Drop),
    ]
}

fn edit_header(b: &[u8], edits: &[HeaderEdit]) -> Vec<u8> {
    let end = header_end(b);
    let Ok(mut json) = serde_json::from_slice::<serde_json::Value>(&b[8..end]) else {
        return b.to_vec();
    };
    let obj = json.as_object_mut().unwrap();
    let mut tensors: Vec<String> = obj
        .keys()
        .filter(|k| *k != "__metadata__")
        .cloned()
        .collect();
    tensors.sort();
    for e in edits {
        let pick = |i: usize, names: &[String]| names[i % names.len().max(1)].clone();
        if tensors.is_empty() {
            break;
        }
        let name = |i: &usize| pick(*i, &tensors);
        match e {
            HeaderEdit::Dtype(i, d) => obj[&name(i)]["dtype"] = (*d).into(),
            HeaderEdit::Shape(i, v) => obj[&name(i)]["shape"] = v.clone().into(),
            HeaderEdit::Offsets(i, a, z) => obj[&name(i)]["data_offsets"] = vec![*a, *z].into(),
            HeaderEdit::Metadata(i, v) => {
                if let Some(m) = obj.get_mut("__metadata__").and_then(|m| m.as_object_mut()) {
                    let mut keys: Vec<String> = m.keys().cloned().collect();
                    keys.sort();
                    if !keys.is_empty() {
                        m[&pick(*i, &keys)] = v.clone().into();
                    }
                }
            }
            HeaderEdit::Drop(i) => {
                let gone = name(i);
                obj.remove(&gone);
                tensors.retain(|t| *t != gone);
            }
        }
    }
    let text = serde_json::to_vec(&json).unwrap();
    let mut out = (text.len() as u64).to_le_bytes().to_vec();
    out.extend(text);
    out.extend_from_slice(&b[end..]);
    out
}

/// Every parser the project has for files it is handed.
fn parse_all(bytes: &[u8]) {
    if let Ok(s) = scene::gltf::from_slice(bytes, &phantom("x.glb")) {
        // A scene that loads either checks out or says why not.
        let _ = s.check();
    }
    let _ = dhoit_runtime::mlp::Mlp::from_bytes(bytes);
    let _ = dhoit_train::cli::parse_features(bytes, &phantom("f.safetensors"));
    let _ = dhoit_runtime::dump::parse(bytes, &phantom("fragments.safetensors"));
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(128),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn the_gltf_loader_never_panics(edits in prop::collection::vec(edit(), 1..6)) {
        let b = apply(seeds().glb.clone(), &edits);
        if let Ok(s) = scene::gltf::from_slice(&b, &phantom("x.glb")) {
            let _ = s.check();
        }
    }

    #[test]
    fn the_weights_loader_never_panics(edits in prop::collection::vec(edit(), 1..6)) {
        let b = apply(seeds().weights.clone(), &edits);
        if let Ok(m) = dhoit_runtime::mlp::Mlp::from_bytes(&b) {
            // Whatever loads is finite and runs.
            prop_assert!(m.forward(&[0.5; 12]).is_finite());
        }
    }

    #[test]
    fn the_features_reader_never_panics(edits in prop::collection::vec(edit(), 1..6)) {
        let b = apply(seeds().features.clone(), &edits);
        if let Ok(rows) = dhoit_train::cli::parse_features(&b, &phantom("f.safetensors")) {
            prop_assert!(rows.iter().flatten().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn the_dump_reader_never_panics(edits in prop::collection::vec(edit(), 1..6)) {
        let b = apply(seeds().dump.clone(), &edits);
        if let Ok(d) = dhoit_runtime::dump::parse(&b, &phantom("fragments.safetensors")) {
            prop_assert_eq!(d.fragments.offsets.len(), d.fragments.pixel_count() + 1);
        }
    }

    /// Byte edits kept inside the header (the length and the JSON): spread over the whole
    /// file, almost all of them land in the tensors' data.
    #[test]
    fn the_safetensors_readers_never_panic_on_edited_header_bytes(
        which in 0usize..3, edits in prop::collection::vec(edit(), 1..4),
    ) {
        let seed = [&seeds().weights, &seeds().features, &seeds().dump][which];
        parse_all(&apply_within(seed.clone(), &edits, header_end(seed)));
    }

    /// The header's JSON changed as a broken writer would change it, the file otherwise whole.
    #[test]
    fn the_safetensors_readers_never_panic_on_edited_header_fields(
        which in 0usize..3, edits in prop::collection::vec(header_edit(), 1..4),
    ) {
        let seed = [&seeds().weights, &seeds().features, &seeds().dump][which];
        let b = edit_header(seed, &edits);
        parse_all(&b);
        if let Ok(m) = dhoit_runtime::mlp::Mlp::from_bytes(&b) {
            prop_assert!(m.forward(&[0.5; 12]).is_finite());
        }
    }

    #[test]
    fn arbitrary_bytes_never_panic_any_parser(b in prop::collection::vec(any::<u8>(), 0..512)) {
        parse_all(&b);
    }
}

#[test]
fn the_regression_corpus_parses_without_panicking() {
    let dir = root().join("tests/corpus");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "bin") {
            parse_all(&std::fs::read(&path).unwrap());
            n += 1;
        }
    }
    assert!(n > 0, "no regression inputs in {}", dir.display());
}

/// The header edits reach the loaders as meant (a fuzz whose edits were lost on the way would
/// pass vacuously): the unedited round trip loads, and each kind of edit, on the default
/// weights, is refused with a reason about the tensor.
#[test]
fn header_edits_reach_the_loaders() {
    let w = &seeds().weights;
    assert!(dhoit_runtime::mlp::Mlp::from_bytes(&edit_header(w, &[])).is_ok());
    let cases: [(HeaderEdit, &str); 4] = [
        (HeaderEdit::Dtype(0, "F64"), "tensor"),
        (HeaderEdit::Shape(0, vec![3, 3]), "tensor"),
        (HeaderEdit::Offsets(0, 9, 3), "tensor"),
        (HeaderEdit::Drop(0), "tensor"),
    ];
    for (edit, needle) in cases {
        let e = dhoit_runtime::mlp::Mlp::from_bytes(&edit_header(w, std::slice::from_ref(&edit)))
            .unwrap_err()
            .to_string();
        assert!(e.contains(needle), "{edit:?}: {e}");
    }
}
