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

fn apply(mut b: Vec<u8>, edits: &[Edit]) -> Vec<u8> {
    for e in edits {
        if b.is_empty() {
            break;
        }
        let at = |i: usize| i % b.len();
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
                    let i = at(*i).min(b.len() - w);
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
        let dir = std::env::temp_dir().join(format!("dhoit-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cam = scene::Camera::orbit(&s, 0, 8, 12, 9);
        let fl = dhoit_runtime::raster::rasterize(&s, &cam, 12, 9).unwrap();
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
