//! End-to-end checks of the `dhoit` command: dumps, order independence, errors.

mod common;
use common::{dhoit, skip_gpu, temp_dir};
use dhoit_runtime::budget::Budget;
use dhoit_runtime::frame::{self, Method, Options};
use dhoit_runtime::mlp::{Mlp, Precision};
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::{self, Camera, Opacity};
use std::path::{Path, PathBuf};

#[test]
fn the_dump_round_trips() {
    let dir = temp_dir("cli-dump");
    let out = dir.join("img.png");
    let o = dhoit(&[
        "render",
        "--scene",
        "spheres",
        "--res",
        "96x64",
        "--method",
        "fkb",
        "--budget",
        "2fpp",
        "--background",
        "0.1,0.2,0.3",
        "--out",
        out.to_str().unwrap(),
        "--dump",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.is_file());
    let d = dhoit_runtime::dump::read(&dir).unwrap();
    // The same frame computed here.
    let s = scene::load("spheres", Opacity::default()).unwrap();
    let cam = Camera::orbit(&s, 0, scene::DEFAULT_VIEWS, (96, 64));
    let fl = rasterize(&s, &cam, (96, 64)).unwrap();
    let f = frame::render(
        &fl,
        Method::Fkb,
        Options::new(Budget::SlotsPerPixel(2.0), [0.1, 0.2, 0.3]),
    )
    .unwrap();
    assert_eq!(d.fragments.offsets, fl.offsets);
    assert_eq!(d.fragments.depth, fl.depth);
    assert_eq!(d.fragments.rgba, fl.rgba);
    assert_eq!(d.fragments.primitive, fl.primitive);
    assert_eq!(d.k, f.k);
    assert_eq!(d.image, f.image);
    assert_eq!(d.method, "fkb");
    assert_eq!(d.budget_fragments, 2 * 96 * 64);
    assert_eq!(d.budget_bytes, f.budget_bytes);
    assert_eq!(d.background, [0.1, 0.2, 0.3]);
    // Written and read back again, the dump is unchanged.
    let again = temp_dir("cli-dump2");
    dhoit_runtime::dump::write(&again, &d).unwrap();
    assert_eq!(dhoit_runtime::dump::read(&again).unwrap(), d);
}

#[test]
fn a_corrupt_dump_is_a_clear_error() {
    let dir = temp_dir("cli-corrupt");
    let path = dir.join(dhoit_runtime::dump::FILE_NAME);
    std::fs::write(&path, b"\x10\x00\x00\x00\x00\x00\x00\x00{not json}").unwrap();
    let e = dhoit_runtime::dump::read(&dir).unwrap_err().to_string();
    assert!(e.contains("not a safetensors file"), "{e}");
}

#[test]
fn shuffled_submission_gives_bit_identical_images_but_for_blended_targets_rounding() {
    let mlp = Mlp::random(8);
    for name in ["spheres", "particles", "plates"] {
        let s = scene::load(name, Opacity::default()).unwrap();
        let cam = Camera::orbit(&s, 1, scene::DEFAULT_VIEWS, (80, 60));
        let images = |seed: Option<u64>| {
            let sc = seed.map_or_else(|| s.clone(), |x| s.shuffled(x));
            let fl = rasterize(&sc, &cam, (80, 60)).unwrap();
            [
                Method::Abuffer,
                Method::Fkb,
                Method::Vkb,
                Method::Dkb,
                Method::Optimal,
            ]
            .map(|m| {
                let f = frame::render(&fl, m, opts(Budget::SlotsPerPixel(1.5), [1.0; 3], &mlp))
                    .unwrap();
                f.image
                    .data
                    .iter()
                    .flatten()
                    .map(|v| v.to_bits())
                    .collect::<Vec<u32>>()
            })
        };
        let base = images(None);
        for seed in [1, 2] {
            assert_eq!(images(Some(seed)), base, "{name}, shuffle {seed}");
        }
        // WBOIT and MBOIT add into binary16 (and WBOIT's 8-bit revealage) in submission order,
        // as their targets do on a device: the order moves them by that rounding only.
        let blended = |seed: Option<u64>, m| {
            let sc = seed.map_or_else(|| s.clone(), |x| s.shuffled(x));
            let fl = rasterize(&sc, &cam, (80, 60)).unwrap();
            frame::render(&fl, m, opts(Budget::SlotsPerPixel(1.5), [1.0; 3], &mlp))
                .unwrap()
                .image
        };
        for m in [Method::Wboit, Method::Mboit] {
            let base = blended(None, m);
            for seed in [1, 2] {
                let d = blended(Some(seed), m).max_abs_diff(&base);
                assert!(d <= 1e-2, "{name} {m}, shuffle {seed}: {d}");
            }
        }
    }
    // Through the command line too: two seeds, identical PNGs.
    let dir = temp_dir("cli-shuffle");
    for method in ["abuffer", "fkb"] {
        let pngs: Vec<Vec<u8>> = ["3", "4"]
            .iter()
            .map(|seed| {
                let out = dir.join(format!("{method}-{seed}.png"));
                let o = dhoit(&[
                    "render",
                    "--scene",
                    "foliage",
                    "--res",
                    "64x48",
                    "--method",
                    method,
                    "--shuffle",
                    seed,
                    "--out",
                    out.to_str().unwrap(),
                ]);
                assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
                std::fs::read(&out).unwrap()
            })
            .collect();
        assert_eq!(pngs[0], pngs[1], "{method}");
    }
}

/// The methods' own approximations (`--always-approximate` on the command line), which these
/// tests hold to what the command renders.
fn opts<'a>(b: Budget, bg: [f32; 3], mlp: &'a Mlp) -> Options<'a> {
    Options {
        weights: Some(mlp),
        ..Options::new(b, bg).always_approximate()
    }
}

#[test]
fn allocation_methods_render_from_the_command_line() {
    let dir = temp_dir("cli-methods");
    let weights = dir.join("w.safetensors");
    Mlp::random(2).save(&weights, &Default::default()).unwrap();
    for method in [
        "vkb",
        "optimal",
        "dkb",
        "greedy-paper",
        "greedy-increase",
        "mlab",
        "dkb",
    ] {
        let out = dir.join(format!("{method}.png"));
        let kmap = dir.join(format!("{method}-k.png"));
        let o = dhoit(&[
            "render",
            "--scene",
            "hair",
            "--res",
            "64x48",
            "--method",
            method,
            "--budget",
            "1.5fpp",
            "--always-approximate",
            "--weights",
            weights.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--kmap",
            kmap.to_str().unwrap(),
            "--dump",
            dir.to_str().unwrap(),
        ]);
        assert!(
            o.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(out.is_file() && kmap.is_file());
        let d = dhoit_runtime::dump::read(&dir).unwrap();
        assert_eq!(d.method, method);
        if method != "mlab" {
            let counts = d.fragments.counts();
            let sum: u64 = d.k.iter().map(|&k| k as u64).sum();
            let slots = d.budget_fragments.min(d.fragments.fragment_count() as u64);
            if matches!(method, "vkb" | "dkb") {
                // Their tails pooled, they store all of a pixel's fragments where its tail
                // would hold no more than two (shared::stored_k): more slots than F, and no
                // pixel short by one or two.
                assert!(sum >= slots, "{method}: {sum} slots for F {slots}");
                assert!(
                    d.k.iter()
                        .zip(&counts)
                        .all(|(&k, &n)| k == n || dhoit_runtime::shared::has_tail(k, n)),
                    "{method}: a pixel short by one or two"
                );
            } else {
                assert_eq!(sum, slots, "{method}");
            }
            assert!(
                d.k.iter().zip(&counts).all(|(k, n)| k <= n),
                "{method}: k <= n"
            );
        }
    }
    let png = dir.join("o.png");
    let o = dhoit(&hair_render("optimal", &["--out", png.to_str().unwrap()]));
    assert!(String::from_utf8_lossy(&o.stdout).contains("lower bound"));
    // The image and the k map as JPEG where their paths ask for it (and PNG above).
    let (jpg, kjpg) = (dir.join("o.JPG"), dir.join("k.jpeg"));
    let images = [
        "--out",
        jpg.to_str().unwrap(),
        "--kmap",
        kjpg.to_str().unwrap(),
    ];
    let o = dhoit(&hair_render("vkb", &images));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (path, png) in [(&jpg, false), (&kjpg, false), (&png, true)] {
        let bytes = std::fs::read(path).unwrap();
        let magic: &[u8] = if png { b"\x89PNG" } else { b"\xff\xd8\xff" };
        assert!(bytes.starts_with(magic), "{}", path.display());
    }
    // Weights that are not weights: a clear error.
    let bad = dir.join("bad.safetensors");
    std::fs::write(&bad, b"nope").unwrap();
    let out = dir.join("never.png");
    let args = [
        "--weights",
        bad.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    expect_failure(&hair_render("dkb", &args), "not a safetensors file", &out);
}

/// `render` of hair at 64x48 with `method`, then `rest`.
/// `render` of the hair at 64x48, the method's own approximation (at the default 2fpp the
/// exact A-buffer is cheaper on so small a frame).
fn hair_render<'a>(method: &'a str, rest: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "render",
        "--scene",
        "hair",
        "--res",
        "64x48",
        "--method",
        method,
        "--always-approximate",
    ];
    args.extend_from_slice(rest);
    args
}

fn expect_failure(args: &[&str], needle: &str, out: &Path) {
    let o = dhoit(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{args:?} should fail");
    assert!(
        err.contains(needle),
        "{args:?}: stderr '{err}' should contain '{needle}'"
    );
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    assert!(!out.exists(), "{args:?} left {} behind", out.display());
}

#[test]
fn bad_input_fails_cleanly_and_writes_nothing() {
    let dir = temp_dir("cli-bad");
    let out = dir.join("never.png");
    let o = out.to_str().unwrap();
    let base = |extra: &[&'static str]| {
        let mut v = vec!["render", "--res", "64x48", "--out"];
        v.push(o);
        v.extend_from_slice(extra);
        v
    };
    expect_failure(&base(&["--scene", "no-such-scene"]), "unknown scene", &out);
    expect_failure(
        &base(&["--scene", "/nonexistent/x.glb"]),
        "cannot read /nonexistent/x.glb",
        &out,
    );
    expect_failure(
        &base(&["--scene", "shells", "--budget", "12 parsecs"]),
        "invalid budget",
        &out,
    );
    expect_failure(
        &base(&["--scene", "shells", "--budget", "0fpp"]),
        "invalid budget",
        &out,
    );
    expect_failure(
        &base(&["--scene", "shells", "--method", "fkb", "--budget", "1KB"]),
        "needs",
        &out,
    );
    expect_failure(
        &base(&["--scene", "shells", "--method", "magic"]),
        "unknown method",
        &out,
    );
    expect_failure(
        &base(&[
            "--scene",
            "shells",
            "--method",
            "mboit",
            "--mboit-bias",
            "1",
        ]),
        "is not in [0, 1)",
        &out,
    );
    expect_failure(
        &base(&[
            "--scene",
            "shells",
            "--method",
            "mboit",
            "--mboit-moments",
            "5",
        ]),
        "MBOIT takes 4, 6 or 8 power moments, not 5",
        &out,
    );
    expect_failure(
        &base(&[
            "--scene",
            "shells",
            "--method",
            "linked-list",
            "--list-sorted",
            "0",
        ]),
        "sorts 1 to 16 fragments a pixel",
        &out,
    );
    expect_failure(
        &base(&["--scene", "shells", "--view", "9"]),
        "view 9 does not exist",
        &out,
    );
    expect_failure(
        &base(&["--scene", "shells", "--opacity", "1.5"]),
        "opacity",
        &out,
    );
    expect_failure(
        &base(&["--scene", "shells", "--device", "tpu"]),
        "invalid value 'tpu' for '--device",
        &out,
    );
    // A format dhoit does not write, named before any work (a JPEG is written below).
    let bmp = out.with_extension("bmp");
    expect_failure(
        &[
            "render",
            "--scene",
            "shells",
            "--res",
            "64x48",
            "--out",
            bmp.to_str().unwrap(),
        ],
        "images are written as .png (or .jpg, or .exr",
        &bmp,
    );
    let kmap = ["--scene", "shells", "--kmap", "k.tiff", "--method", "vkb"];
    expect_failure(&base(&kmap), "k.tiff", &out);
    let o2 = dhoit(&["render", "--scene", "shells", "--res", "0x48", "--out", o]);
    assert!(
        !o2.status.success() && String::from_utf8_lossy(&o2.stderr).contains("invalid resolution")
    );
    assert!(!out.exists());
}

#[test]
fn compare_prints_a_table_and_writes_a_report() {
    let dir = temp_dir("cli-compare");
    let o = dhoit(&[
        "compare",
        "--scene",
        "shells",
        "--res",
        "64x48",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    for m in [
        "abuffer",
        "fkb",
        "vkb",
        "optimal",
        "optimal-pooled",
        "greedy-paper",
        "greedy-increase",
        "mlab",
        "wboit",
        "mboit",
        "linked-list",
        "dkb",
    ] {
        assert!(stdout.contains(m), "{stdout}");
        assert!(dir.join(format!("shells_v0_2fpp_{m}.png")).is_file(), "{m}");
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    let records = report.as_array().unwrap();
    assert_eq!(
        records.len(),
        12,
        "every method, dkb with the committed default weights"
    );
    assert!(dir.join("report.md").is_file());
    assert!(std::fs::read_dir(&dir).unwrap().any(|e| {
        e.unwrap()
            .file_name()
            .to_string_lossy()
            .ends_with("montage.png")
    }));
    assert_eq!(records[0]["method"], "abuffer");
    assert_eq!(records[0]["mse"], 0.0);
    assert!(records.iter().all(|r| r["mse"].as_f64().unwrap() >= 0.0));
    // No k-buffer allocates more than the exact A-buffer; at 2fpp on this shallow frame some
    // render it, exact, and the table says so.
    let bytes = |r: &serde_json::Value, k: &str| r[k].as_u64().unwrap();
    assert!(
        records
            .iter()
            .all(|r| r["method"] == "mlab"
                || bytes(r, "allocated_bytes") <= bytes(r, "abuffer_bytes"))
    );
    let capped: Vec<_> = records.iter().filter(|r| r["exact"] == true).collect();
    assert!(!capped.is_empty(), "{stdout}");
    assert!(capped.iter().all(|r| r["mse"] == 0.0));
    assert!(stdout.contains("(exact)"), "{stdout}");
}

/// The A-buffer bytes every frame of `compare` is measured against are the A-buffer frame's own,
/// tint words included, on tinted glass (the command line's default) as on grey; and there too
/// no k-buffer allocates more.
#[test]
fn compare_measures_bytes_against_the_frames_own_abuffer() {
    for glass in ["tinted", "grey"] {
        let dir = temp_dir(&format!("cli-compare-{glass}"));
        let o = dhoit(&[
            "compare",
            "--scene",
            "windows",
            "--res",
            "64x48",
            "--glass",
            glass,
            "--methods",
            "abuffer,fkb,vkb,dkb",
            "--out",
            dir.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
        let records = report.as_array().unwrap();
        let bytes = |r: &serde_json::Value, k: &str| r[k].as_u64().unwrap();
        let exact = records.iter().find(|r| r["method"] == "abuffer").unwrap();
        assert_eq!(
            bytes(exact, "allocated_bytes"),
            bytes(exact, "abuffer_bytes"),
            "{glass}"
        );
        for r in records {
            assert!(
                bytes(r, "allocated_bytes") <= bytes(r, "abuffer_bytes"),
                "{glass}: {r}"
            );
        }
    }
}

/// `render` takes the exact A-buffer where it needs no more bytes than the method at its budget,
/// and says so; `--always-approximate` renders the method's own approximation.
#[test]
fn render_takes_the_exact_abuffer_where_it_is_cheaper() {
    let dir = temp_dir("cli-cap");
    let run = |extra: &[&str], out: &Path| {
        let mut args = vec![
            // VKB at 60% needs 42.33 KiB on this frame, the A-buffer 42.30 (at 55%, VKB 41.1;
            // from 65% on it keeps every fragment).
            "render", "--scene", "cad", "--res", "64x48", "--method", "vkb", "--budget", "60%",
            "--out",
        ];
        args.push(out.to_str().unwrap());
        args.extend_from_slice(extra);
        let o = dhoit(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).to_string()
    };
    let (capped, own) = (dir.join("capped.png"), dir.join("own.png"));
    let said = run(&[], &capped);
    assert!(said.contains("rendered the exact A-buffer"), "{said}");
    assert!(said.contains("100.0% of"), "{said}");
    let said = run(&["--always-approximate"], &own);
    assert!(!said.contains("rendered the exact A-buffer"), "{said}");
    assert!(!said.contains("100.0% of"), "{said}");
    let exact = dir.join("exact.png");
    let o = dhoit(&[
        "render",
        "--scene",
        "cad",
        "--res",
        "64x48",
        "--method",
        "abuffer",
        "--out",
        exact.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let read = |p: &Path| std::fs::read(p).unwrap();
    assert_eq!(read(&capped), read(&exact));
    assert_ne!(read(&own), read(&exact));
}

/// A font asked for by DHOIT_FONT that cannot be used is named, whether another font draws
/// the text instead or none does; the pictures are still written.
#[test]
fn a_font_that_cannot_be_read_is_named() {
    let dir = temp_dir("cli-font");
    let args = [
        "compare",
        "--scene",
        "cad",
        "--res",
        "32x24",
        "--budget",
        "2fpp",
        "--out",
        dir.to_str().unwrap(),
    ];
    let o = common::dhoit_with_env(&args, &[("DHOIT_FONT", "/no/such/font.ttf")]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("DHOIT_FONT=/no/such/font.ttf is not a readable TrueType font"),
        "{err}"
    );
    assert!(dir.join("cad_v0_2fpp_montage.png").is_file());
}

#[test]
fn the_gpu_renders_from_the_command_line() {
    if skip_gpu("GPU command-line test") {
        return;
    }
    let dir = temp_dir("cli-gpu");
    // plates at 64x48 on the GPU with `method`, then `more` arguments.
    let render = |method: &str, more: &[&str]| {
        let mut args = vec![
            "render",
            "--scene",
            "plates",
            "--res",
            "64x48",
            "--method",
            method,
            "--device",
            "gpu",
            "--always-approximate",
        ];
        args.extend_from_slice(more);
        dhoit(&args)
    };
    for method in ["abuffer", "fkb", "optimal", "mlab", "vkb", "dkb"] {
        let out = dir.join(format!("{method}.png"));
        let dump_dir = dir.join(method);
        let o = render(
            method,
            &[
                "--out",
                out.to_str().unwrap(),
                "--dump",
                dump_dir.to_str().unwrap(),
            ],
        );
        assert!(
            o.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(String::from_utf8_lossy(&o.stdout).contains("GPU passes"));
        let d = dhoit_runtime::dump::read(&dump_dir).unwrap();
        assert_eq!(
            (d.fragments.width, d.fragments.height, d.method.as_str()),
            (64, 48, method)
        );
        // The passes' names, in order.
        let names = |o: &std::process::Output| {
            let out = String::from_utf8_lossy(&o.stdout).to_string();
            let line = out.lines().find(|l| l.starts_with("GPU passes:")).unwrap();
            // "name 1.23 ms" each, or the names alone where the device has no timestamps.
            let line = line.trim_start_matches("GPU passes: ");
            let (line, untimed) = match line.split_once(" (untimed") {
                Some((names, _)) => (names, true),
                None => (line, false),
            };
            line.split(", ")
                .map(|p| match untimed {
                    true => p.to_string(),
                    false => p.rsplitn(3, ' ').nth(2).unwrap_or("").to_string(),
                })
                .collect::<Vec<_>>()
        };
        if method == "fkb" || method == "dkb" {
            // The portable capture: its two passes, the same picture.
            let portable = dir.join(format!("{method}-portable.png"));
            let p = render(
                method,
                &["--capture", "portable", "--out", portable.to_str().unwrap()],
            );
            assert!(p.status.success(), "{}", String::from_utf8_lossy(&p.stderr));
            let n = names(&p);
            assert!(
                n.iter().any(|x| x == "capture depths")
                    && n.iter().any(|x| x == "capture colours")
                    && !n.iter().any(|x| x == "capture"),
                "{method} --capture portable: {n:?}"
            );
            assert!(
                std::fs::read(&portable).unwrap() == std::fs::read(&out).unwrap(),
                "{method}: the portable capture's picture differs"
            );
            let bad = render(
                method,
                &["--capture", "narrow", "--out", portable.to_str().unwrap()],
            );
            assert!(
                !bad.status.success()
                    && String::from_utf8_lossy(&bad.stderr).contains("no capture 'narrow'"),
                "{}",
                String::from_utf8_lossy(&bad.stderr)
            );
        }
        if method == "vkb" || method == "dkb" {
            // One allocation (no second submission) and the importance pass where the budget
            // truncates: the CPU counted the frame's fragments.
            let n = names(&o);
            let times = |p: &str| n.iter().filter(|x| *x == p).count();
            assert_eq!((times("allocation"), times("importance")), (1, 1), "{n:?}");
        }
        if method == "dkb" {
            // Its frame counts first and reads its count back (its slot pool is sized from it,
            // its record marks made from it), gathers its statistics with its frame's count
            // (no features pass of their own, on any device) and runs its network only where the
            // budget truncates: at 2 fpp plates truncates, at 100% nothing does.
            let passes = |o: &std::process::Output, pass: &str| names(o).iter().any(|p| p == pass);
            let features = |o: &std::process::Output| passes(o, "features");
            assert!(d.fragments.fragment_count() > 2 * 64 * 48);
            assert!(
                passes(&o, "count") && !features(&o) && passes(&o, "importance"),
                "dkb: {:?}",
                names(&o)
            );
            let all_png = dir.join("dkb-all.png");
            let all = render(
                "dkb",
                &["--budget", "100%", "--out", all_png.to_str().unwrap()],
            );
            assert!(
                all.status.success(),
                "{}",
                String::from_utf8_lossy(&all.stderr)
            );
            assert!(
                passes(&all, "count") && !features(&all) && !passes(&all, "record marks"),
                "dkb marked its records where every fragment fits"
            );
            // Where every fragment fits, k = n: no importance pass.
            assert!(!names(&all).iter().any(|p| p == "importance"));
        }
        assert!(
            d.image
                .data
                .iter()
                .flatten()
                .all(|v| v.is_finite() && (0.0..=1.0 + 1e-6).contains(v))
        );
    }
}

/// `--record-batches` trades DKB's memory for geometry passes: on shells at 10% (64x48, on the
/// GPU) its records are more than its slots and tails need, so with one batch (the default)
/// the frame allocates more than with three, and gathers its statistics with its count (no
/// features pass), with three draws its features pass more than once; the images are the same
/// bytes. A count outside 1 to 3 is refused, naming the range. `bench` at that relative budget
/// measures every method but FKB, which it cannot run (its error is its row), DKB with its
/// records whole in more bytes than batched.
#[test]
fn record_batches_trade_dkb_s_memory_for_passes_from_the_command_line() {
    if skip_gpu("GPU record-batches test") {
        return;
    }
    let dir = temp_dir("cli-batches");
    let render = |batches: &str| {
        let out = dir.join(format!("b{batches}.png"));
        let o = dhoit(&[
            "render",
            "--scene",
            "shells",
            "--res",
            "64x48",
            "--budget",
            "10%",
            "--opacity",
            "0.33",
            "--method",
            "dkb",
            "--device",
            "gpu",
            "--always-approximate",
            "--record-batches",
            batches,
            "--out",
            out.to_str().unwrap(),
        ]);
        let text = String::from_utf8_lossy(&o.stdout).to_string();
        assert!(
            o.status.success(),
            "{batches}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let passes = text
            .lines()
            .find(|l| l.starts_with("GPU passes:"))
            .unwrap()
            .to_string();
        // A batch's features pass: one.
        let features = passes.matches("features ").count();
        let allocated: f64 = text
            .split("allocated ")
            .nth(1)
            .and_then(|r| r.split_whitespace().next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{text}"));
        (features, allocated, std::fs::read(out).unwrap())
    };
    let (one, three) = (render("1"), render("3"));
    assert_eq!(one.0, 0, "one batch: gathered with the count");
    assert!(three.0 > 1, "three at most: {} features passes", three.0);
    assert!(
        three.1 < one.1,
        "batched {} against whole {}",
        three.1,
        one.1
    );
    assert!(one.2 == three.2, "the images differ");
    for bad in ["0", "4", "two"] {
        let o = dhoit(&["render", "--scene", "shells", "--record-batches", bad]);
        assert!(!o.status.success());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains("1 to 3 batches"), "{bad}: {e}");
    }
    let out = dir.join("bench.json");
    let o = dhoit(&[
        "bench",
        "--gpu-only",
        "--scenes",
        "shells",
        "--res",
        "64x48",
        "--budget",
        "10%",
        "--repeat",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let m = &report["gpu"]["scenes"][0]["methods"];
    let e = m["fkb"]["error"].as_str().unwrap_or_default();
    assert!(e.contains("one slot for every pixel"), "{m}");
    let bytes = |k: &str| m[k]["allocated_bytes"].as_u64().unwrap();
    assert!(bytes("dkb_records_in_batches") < bytes("dkb"), "{m}");
    assert!(m["vkb"]["frame_gpu_ms"].as_f64().is_some_and(|t| t > 0.0));
}

/// `bench --network-only` reports the training steps (the fused step and burn's autodiff at
/// batch 512, the regret-loss step) and inference as samples a second, and nothing else.
#[test]
fn the_network_bench_reports_each_training_step() {
    let dir = temp_dir("cli-bench-network");
    let out = dir.join("network.json");
    let o = dhoit(&[
        "bench",
        "--network-only",
        "--repeat",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    for section in ["gpu", "cpu", "optimal_allocation"] {
        assert!(
            report.get(section).is_none(),
            "--network-only ran {section}"
        );
    }
    for key in [
        "training_samples_per_s_batch_512",
        "training_autodiff_samples_per_s_batch_512",
        "training_regret_samples_per_s_frame_1024",
        "burn_inference_samples_per_s",
        "cpu_twin_inference_samples_per_s",
    ] {
        let v = report["network"][key].as_f64().unwrap_or(f64::NAN);
        assert!(v.is_finite() && v > 0.0, "{key}: {v}");
    }
}

/// `bench --gpu-only` (what scripts/device.sh runs on a lent GPU) writes every method's
/// steady frames and passes, DKB's ratios and the measured options, and no CPU section.
#[test]
fn the_gpu_bench_reports_every_method_and_option() {
    if skip_gpu("GPU bench test") {
        return;
    }
    let dir = temp_dir("cli-bench");
    let out = dir.join("bench.json");
    let o = dhoit(&[
        "bench",
        "--gpu-only",
        "--scenes",
        "cad",
        "--res",
        "48x32",
        "--repeat",
        "1",
        "--sequence",
        "3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert!(
        report.get("cpu").is_none(),
        "--gpu-only ran the CPU section"
    );
    // The orbit as a real-time renderer draws it: every streamed method, its frames a second
    // both ways, and no submission or wait of dhoit's own while recording a frame.
    let sequence = &report["gpu"]["scenes"][0]["sequence"];
    let streamed: Vec<String> = Method::those(Method::at_equal_bytes)
        .iter()
        .map(|m| m.to_string())
        .chain(["dkb_three_pass".to_string()])
        .collect();
    for m in &streamed {
        let e = &sequence["methods"][m];
        for key in ["fps_two_in_flight", "fps_one_at_a_time", "frame_gpu_ms"] {
            let v = e[key].as_f64();
            assert!(
                v.is_some_and(|v| v > 0.0 && v.is_finite()),
                "{m} {key}: {e}"
            );
        }
        assert_eq!(e["sync_waits_per_frame"].as_f64(), Some(0.0), "{m}: {e}");
        assert_eq!(e["frames"], 3, "{m}");
        assert!(
            e["temporal_change"].as_f64().is_some_and(|t| t >= 0.0),
            "{m}: {e}"
        );
    }
    // The exact A-buffer against itself: no error, none changing; the fast camera's figures
    // for the A-buffer, VKB and both DKBs.
    assert_eq!(
        sequence["methods"]["abuffer"]["mean_abs_error"].as_f64(),
        Some(0.0)
    );
    for m in ["abuffer", "vkb", "dkb", "dkb_three_pass"] {
        let fast = &sequence["methods"][m]["fast"];
        assert!(
            fast["temporal_change"].as_f64().is_some_and(|t| t >= 0.0),
            "{m}: {fast}"
        );
    }
    // The reports written after each scene are marked partial; the last one is not.
    assert!(
        report.get("partial").is_none(),
        "the final report is marked partial"
    );
    let scene = &report["gpu"]["scenes"][0];
    assert_eq!(scene["scene"], "cad", "{scene}");
    // The methods it times are the registry's (`Method::gpu_timed`), each once, and no other
    // method's name; the rest of its entries are named variants of them.
    let timed = Method::those(Method::gpu_timed);
    let named: Vec<Method> = scene["methods"]
        .as_object()
        .unwrap()
        .keys()
        .filter_map(|k| Method::parse(k).ok())
        .collect();
    assert_eq!(
        named
            .iter()
            .copied()
            .collect::<std::collections::HashSet<_>>(),
        timed.iter().copied().collect(),
        "the methods the GPU bench timed"
    );
    for m in timed.iter().map(|m| m.name()).chain([
        "dkb_no_skip",
        "dkb_insertion_only",
        "dkb_two_mode_where_all_fit",
        "dkb_spread_search",
        "dkb_shared_weights",
        "dkb_array_network",
        "dkb_features_no_preload",
        "dkb_records_in_batches",
        "dkb_three_pass",
        "fkb_layer_major",
        "dkb_16-8",
        // lavapipe computes in binary16 (SHADER_F16); a device without it has no such run.
        "dkb_f16_math",
    ]) {
        let ms = scene["methods"][m]["frame_gpu_ms"].as_f64();
        assert!(ms.is_some_and(|t| t > 0.0 && t.is_finite()), "{m}: {ms:?}");
        assert_eq!(
            scene["methods"][m]["buffers_created_in_steady_frames"], 0,
            "{m}"
        );
    }
    let pass_ms = |m: &str, pass: &str| scene["methods"][m]["passes_ms"][pass].as_f64();
    // Where the budget holds every fragment DKB renders the A-buffer (its passes, its memory);
    // else its own capture and resolve.
    let holds = scene["dkb_geometry"]["budget_holds_every_fragment"].as_bool();
    let own = if holds == Some(true) {
        ["store", "sort and blend"]
    } else {
        ["capture", "resolve"]
    };
    for pass in own {
        assert!(pass_ms("dkb", pass).is_some_and(|t| t >= 0.0), "dkb {pass}");
    }
    for pass in own {
        assert!(pass_ms("vkb", pass).is_some_and(|t| t >= 0.0), "vkb {pass}");
    }
    // DKB's frames record the importance and allocation passes only where the budget
    // truncates (where it holds every fragment, the frame is the A-buffer's), and the features
    // pass only there in a frame of three geometry passes (in the others the count gathers).
    for (m, pass) in [
        ("dkb", "importance"),
        ("dkb", "allocation"),
        ("dkb_three_pass", "features"),
        ("dkb_three_pass", "importance"),
    ] {
        let recorded = pass_ms(m, pass).is_some();
        assert_eq!(recorded, holds == Some(false), "{m} {pass}: {scene}");
    }
    assert!(pass_ms("dkb", "features").is_none(), "{scene}");
    // DKB counts first, a pass of its own.
    let ms = scene["methods"]["dkb"]["passes_ms"]["count"].as_f64();
    assert!(ms.is_some_and(|t| t > 0.0), "dkb count: {ms:?}");
    for ratio in ["dkb_over_vkb", "dkb_over_abuffer", "dkb_16_8_over_vkb"] {
        let r = scene[ratio].as_f64();
        assert!(
            r.is_some_and(|r| r > 0.0 && r.is_finite()),
            "{ratio}: {r:?}"
        );
    }
    let over_count = scene["features_pass"]["count_and_features_over_vkb_count"].as_f64();
    assert!(over_count.is_some_and(|r| r > 0.0 && r.is_finite()));
    assert!(holds.is_some(), "{scene}");
    let half = scene["f16_math"]["frame_gpu_ms"].as_f64();
    assert!(half.is_some_and(|t| t > 0.0), "f16_math: {half:?}");
}

/// `train --scene` fine-tunes the default network on one scene's orbit views; the weights load
/// in the renderer (CPU and GPU) and beat the default on views of that scene no training view
/// saw, in the held-out report and in rendered images.
#[test]
fn fine_tuning_on_a_scene_beats_the_default_on_its_held_out_views() {
    let dir = temp_dir("cli-finetune");
    let w = dir.join("weights.safetensors");
    let o = dhoit(&[
        "train",
        "--scene",
        "glass:9",
        "--res",
        "160x120",
        "--epochs",
        "6",
        "--out",
        w.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("held_out.json")).unwrap()).unwrap();
    let start = report["start_over_optimal"].as_f64().unwrap();
    let trained = report["trained_over_optimal"].as_f64().unwrap();
    assert!(
        trained < start,
        "held-out error / optimal: fine-tuned {trained} against the default's {start}"
    );
    assert_eq!(report["views"], serde_json::json!([1, 5, 7, 11]));
    // The same held-out views rendered on the CPU with both networks, each frame's MSE floored
    // at what an 8-bit display adds itself (its rounding's variance, (1/255)^2 / 12): below it
    // the two networks' frames look alike, and a ratio of two invisible errors (1e-11 against
    // 1e-14) would outweigh every visible frame.
    let display_floor = (1.0 / 255.0f64).powi(2) / 12.0;
    let tuned = Mlp::load(&w).unwrap();
    let default = Mlp::load(Path::new("data/weights.safetensors")).unwrap();
    let s = scene::load("glass:9", Opacity::default()).unwrap();
    let mut log_ratio = 0.0;
    let mut frames = 0;
    for view in [1, 5, 7, 11] {
        let cam = Camera::orbit(&s, view, 12, (160, 120));
        let fl = rasterize(&s, &cam, (160, 120)).unwrap();
        for share in ["10%", "25%", "50%", "75%", "90%"] {
            let b = Budget::parse(share).unwrap();
            let exact = frame::render(&fl, Method::Abuffer, Options::new(b, [1.0; 3])).unwrap();
            let mse = |m: &Mlp| {
                let f = frame::render(&fl, Method::Dkb, opts(b, [1.0; 3], m)).unwrap();
                f.image.mse(&exact.image).max(display_floor)
            };
            log_ratio += (mse(&tuned) / mse(&default)).ln();
            frames += 1;
        }
    }
    let ratio = (log_ratio / frames as f64).exp();
    assert!(
        ratio < 1.0,
        "rendered MSE fine-tuned / default on held-out views: {ratio}"
    );
    if !skip_gpu("the fine-tuned weights rendered on the GPU") {
        let out = dir.join("gpu.png");
        let o = dhoit(&[
            "render",
            "--scene",
            "glass:9",
            "--res",
            "160x120",
            "--views",
            "12",
            "--view",
            "5",
            "--method",
            "dkb",
            "--budget",
            "25%",
            "--device",
            "gpu",
            "--weights",
            w.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(out.is_file());
    }
}

/// Two random networks of other sizes in `dir`, a 16-8 and a 32-16: (small, large).
fn two_networks(dir: &Path) -> (PathBuf, PathBuf) {
    let small = dir.join("small.safetensors");
    let large = dir.join("large.safetensors");
    Mlp::random_sized(3, 16, 8)
        .save(&small, &Default::default())
        .unwrap();
    Mlp::random_sized(4, 32, 16)
        .save(&large, &Default::default())
        .unwrap();
    (small, large)
}

/// `dhoit trade` reports every network, precision and budget asked for, each with its weights'
/// bytes, with a front that no point dominates in time, bytes, MSE and FLIP; `dhoit fit` picks
/// the network and precision with the fewest bytes that meets the target, records the
/// precision in the file it writes, and writes nothing when none does.
#[test]
fn trade_reports_every_network_and_a_non_dominated_front_and_fit_picks_the_fewest_bytes() {
    let dir = temp_dir("cli-trade");
    let (small, large) = two_networks(&dir);
    let nets = format!("{},{}", large.display(), small.display());
    let timing = if skip_gpu("trade timed on the GPU (timed on the CPU instead)") {
        "cpu"
    } else {
        "gpu"
    };
    let out = dir.join("out");
    let o = dhoit(&[
        "trade",
        "--scene",
        "spheres,plates",
        "--res",
        "64x48",
        "--time-res",
        "64x48",
        "--budget",
        "25%,50%,1fpp",
        "--view",
        "1",
        "--networks",
        &nets,
        "--precision",
        "f32,f16",
        "--timing",
        timing,
        "--repeat",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("trade.json")).unwrap()).unwrap();
    assert!(r["timing"].as_str().unwrap().starts_with(timing));
    let scenes = r["scenes"].as_array().unwrap();
    let names: Vec<&str> = scenes
        .iter()
        .map(|s| s["scene"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["spheres", "plates", "all"]);
    for s in scenes {
        let points = s["points"].as_array().unwrap();
        let mut nets: Vec<(&str, &str)> = points
            .iter()
            .map(|p| {
                (
                    p["network"].as_str().unwrap(),
                    p["precision"].as_str().unwrap(),
                )
            })
            .collect();
        nets.sort();
        assert_eq!(
            nets,
            [
                ("16-8", "f16"),
                ("16-8", "f32"),
                ("32-16", "f16"),
                ("32-16", "f32")
            ],
            "{}",
            s["scene"]
        );
        // Weights by hand: 28 header words, then the padded parameters (16-8: 356; 32-16:
        // 964), one a word at f32 and two at f16, in whole vec4s.
        for p in points {
            let want = match (
                p["network"].as_str().unwrap(),
                p["precision"].as_str().unwrap(),
            ) {
                ("16-8", "f32") => 1_536,
                ("16-8", "f16") => 832,
                ("32-16", "f32") => 3_968,
                _ => 2_048,
            };
            assert_eq!(p["weight_bytes"].as_u64().unwrap(), want, "{p}");
        }
        let key = |p: &serde_json::Value| {
            ["time_ms", "weight_bytes", "mse", "flip"].map(|k| p[k].as_f64().unwrap())
        };
        for p in points {
            let dominated = points.iter().any(|o| {
                let (a, b) = (key(o), key(p));
                a.iter().zip(&b).all(|(x, y)| x <= y) && a.iter().zip(&b).any(|(x, y)| x < y)
            });
            assert_eq!(p["front"].as_bool().unwrap(), !dominated, "{}", s["scene"]);
            assert!(key(p).iter().all(|v| v.is_finite() && *v >= 0.0));
            assert!(p["time_ms"].as_f64().unwrap() > 0.0);
            if s["scene"] != "all" {
                let budgets: Vec<&str> = p["frames"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|f| f["budget"].as_str().unwrap())
                    .collect();
                assert_eq!(budgets, ["25%", "50%", "1fpp"]);
            }
        }
        // The fewest bytes alone put a point on the front.
        let least = points
            .iter()
            .min_by_key(|p| p["weight_bytes"].as_u64().unwrap())
            .unwrap();
        assert!(least["front"].as_bool().unwrap(), "{}", s["scene"]);
    }
    // fit: any network meets a loose target, the one with the fewest bytes is written: the
    // small one at f16 (its precision recorded), or at f32 where only f32 is allowed (the same
    // file); none meets 1.0.
    let fitted = dir.join("fitted.safetensors");
    let fit = |precisions: &str, target: &str, out: &Path| {
        dhoit(&[
            "fit",
            "--scene",
            "spheres",
            "--res",
            "64x48",
            "--budget",
            "25%,50%",
            "--view",
            "1",
            "--networks",
            &nets,
            "--precision",
            precisions,
            "--target",
            target,
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let o = fit("f32,f16", "1000", &fitted);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let chosen = Mlp::load(&fitted).unwrap();
    let want = Mlp::load(&small)
        .unwrap()
        .at_precision(Precision::F16)
        .unwrap();
    assert_eq!(chosen.precision, Precision::F16);
    assert_eq!(
        chosen.parameters().collect::<Vec<_>>(),
        want.parameters().collect::<Vec<_>>()
    );
    let o = fit("f32", "1000", &fitted);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read(&fitted).unwrap(),
        std::fs::read(&small).unwrap()
    );
    let never = dir.join("never.safetensors");
    let o = fit("f32,f16", "1", &never);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no network meets"));
    assert!(!never.exists());
}

/// `dhoit trade` measures each network against VKB at equal bytes with its own weights in the
/// memory: on a frame whose M is below the exact A-buffer's bytes, two networks' M differ by
/// exactly their weights' bytes (by hand: the same F, the same pool, only the uniform differs),
/// M never exceeds the A-buffer's bytes, and DKB's and VKB's MSE at M are what `compare --equal
/// bytes` renders with that network.
#[test]
fn trade_at_equal_bytes_counts_each_network_s_weights_in_the_memory_both_methods_get() {
    let dir = temp_dir("cli-trade-bytes");
    let (small, large) = two_networks(&dir);
    let args = ["--scene", "spheres", "--res", "64x48", "--view", "1"];
    // trade on spheres at these budgets with these networks: its trade.json.
    let trade = |budgets: &str, networks: &str, out: &Path| -> serde_json::Value {
        let o = dhoit(
            &[
                &["trade"][..],
                &args,
                &[
                    "--budget",
                    budgets,
                    "--networks",
                    networks,
                    "--timing",
                    "cpu",
                    "--repeat",
                    "1",
                    "--out",
                    out.to_str().unwrap(),
                ],
            ]
            .concat(),
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&std::fs::read(out.join("trade.json")).unwrap()).unwrap()
    };
    let r = trade(
        "10%,25%,50%",
        &format!("{},{}", large.display(), small.display()),
        &dir.join("out"),
    );
    let points = r["scenes"][0]["points"].as_array().unwrap();
    let by_net = |net: &str| {
        points
            .iter()
            .find(|p| p["network"] == net)
            .unwrap_or_else(|| panic!("no {net} in {points:?}"))
    };
    let (p16, p32) = (by_net("16-8"), by_net("32-16"));
    let weights = |p: &serde_json::Value| p["weight_bytes"].as_u64().unwrap();
    assert_eq!((weights(p16), weights(p32)), (1_536, 3_968));
    let frames = |p: &serde_json::Value| p["frames"].as_array().unwrap().clone();
    let mut below = 0;
    for (f16, f32) in frames(p16).iter().zip(&frames(p32)) {
        assert_eq!(f16["budget"], f32["budget"]);
        let a = f16["abuffer_bytes"].as_u64().unwrap();
        let (m16, m32) = (
            f16["bytes"].as_u64().unwrap(),
            f32["bytes"].as_u64().unwrap(),
        );
        assert!(
            m16 <= a && m32 <= a,
            "M above the A-buffer's {a}: {m16}, {m32}"
        );
        if m32 < a {
            below += 1;
            assert_eq!(m32 - m16, 3_968 - 1_536, "{}", f16["budget"]);
        }
        for f in [f16, f32] {
            let mse = f["bytes_mse"].as_f64().unwrap();
            assert!(mse.is_finite() && mse >= 0.0);
        }
    }
    assert!(
        below > 0,
        "no frame below the A-buffer's bytes: nothing held"
    );
    let ratio = p32["mse_over_vkb_equal_bytes"].as_f64().unwrap();
    assert!(ratio.is_finite() && ratio > 0.0);
    // The same frames through compare, with the large network.
    let cmp = dir.join("cmp");
    let o = dhoit(
        &[
            &["compare"][..],
            &args,
            &[
                "--budget",
                "10%,25%,50%",
                "--equal",
                "bytes",
                "--methods",
                "vkb,dkb",
                "--weights",
                large.to_str().unwrap(),
                "--no-images",
                "--out",
                cmp.to_str().unwrap(),
            ],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows: Vec<serde_json::Value> =
        serde_json::from_slice(&std::fs::read(cmp.join("report.json")).unwrap()).unwrap();
    for f in frames(p32) {
        let row = |m: &str| {
            rows.iter()
                .find(|r| r["method"] == m && r["budget"] == f["budget"])
                .unwrap_or_else(|| panic!("compare has no {m} at {}", f["budget"]))
        };
        assert_eq!(row("dkb")["budget_bytes"], f["bytes"], "{}", f["budget"]);
        assert_eq!(row("dkb")["mse"], f["bytes_mse"], "{}", f["budget"]);
        assert_eq!(row("vkb")["mse"], f["bytes_vkb_mse"], "{}", f["budget"]);
    }
    // A budget that holds every fragment tells no allocation apart: no ratio (null, `-`).
    let all = dir.join("all");
    let r = trade("100%", small.to_str().unwrap(), &all);
    let p = &r["scenes"][0]["points"][0];
    for k in [
        "mse_over_optimal",
        "mse_over_vkb",
        "mse_over_vkb_equal_bytes",
    ] {
        assert!(p[k].is_null(), "{k}: {}", p[k]);
    }
    assert_eq!(p["bytes_over_abuffer"], 1.0);
    let md = std::fs::read_to_string(all.join("trade.md")).unwrap();
    assert!(md.contains("| - | - | - | 1.000 |"), "{md}");
}

/// `dhoit versus --networks` runs DKB once for each network, each with its own weights in the
/// same M: labelled by its sizes after DKB's own, exact where M holds the A-buffer, and (two
/// random networks, two allocations) not the same image below it; two networks of one size,
/// or a missing file, are refused with what is wrong.
#[test]
fn versus_runs_dkb_once_for_each_network_with_its_own_weights_in_the_memory() {
    if skip_gpu("versus times GPU frames") {
        return;
    }
    let dir = temp_dir("cli-versus-nets");
    let (small, large) = two_networks(&dir);
    let out = dir.join("out");
    let run = |networks: &str| {
        dhoit(&[
            "versus",
            "--scene",
            "particles",
            "--res",
            "64x48",
            "--opacity",
            "0.33",
            "--memory",
            "0.5,1",
            "--methods",
            "vkb,dkb",
            "--repeat",
            "1",
            "--weights",
            large.to_str().unwrap(),
            "--networks",
            networks,
            "--precision",
            "f16",
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let o = run(small.to_str().unwrap());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("versus.json")).unwrap()).unwrap();
    for b in r["budgets"].as_array().unwrap() {
        let points = b["points"].as_array().unwrap();
        let labels: Vec<&str> = points
            .iter()
            .map(|p| p["method"].as_str().unwrap())
            .collect();
        assert_eq!(labels, ["vkb", "dkb", "dkb 16-8"], "{}", b["budget"]);
        let mse = |i: usize| points[i]["frames"][0]["mse"].as_f64().unwrap();
        if b["memory"].as_f64() == Some(1.0) {
            for p in &points[1..] {
                assert_eq!(p["frames"][0]["exact"], true, "{}", p["method"]);
            }
            assert_eq!((mse(1), mse(2)), (0.0, 0.0));
        } else {
            assert_eq!(points[1]["frames"][0]["exact"], false);
            assert_ne!(
                mse(1),
                mse(2),
                "two networks, one image: one network ran twice"
            );
        }
    }
    assert!(
        std::fs::read_to_string(out.join("versus.md"))
            .unwrap()
            .contains("| dkb 16-8 |")
    );
    let twice = format!("{},{}", small.display(), small.display());
    let o = run(&twice);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("two networks of 16-8"));
    let missing = dir.join("missing.safetensors");
    let o = run(missing.to_str().unwrap());
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("missing.safetensors"));
}

/// `dhoit versus` measures every method at one memory: a method whose memory does not fit in M
/// does not run there, a k-buffer at the A-buffer's own bytes renders it exactly, every method
/// that ran every frame and is not on the front is dominated by one that is, and each memory
/// has its plot.
#[test]
fn versus_puts_every_method_at_one_memory_and_marks_the_front() {
    if skip_gpu("versus times GPU frames") {
        return;
    }
    let dir = temp_dir("cli-versus");
    let out = dir.join("out");
    let o = dhoit(&[
        "versus",
        "--scene",
        "particles,hair",
        "--res",
        "64x48",
        "--opacity",
        "0.33",
        "--memory",
        "0.5,1",
        "--repeat",
        "1",
        "--weights",
        "data/weights.safetensors",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("versus.json")).unwrap()).unwrap();
    let budgets = r["budgets"].as_array().unwrap();
    assert_eq!(budgets.len(), 2);
    // M of each frame: x times the A-buffer's bytes of that frame (it runs at 1x).
    let frame_key = |f: &serde_json::Value| format!("{} {}", f["scene"], f["view"]);
    let abuffer: std::collections::HashMap<String, f64> = budgets
        .iter()
        .filter(|b| b["memory"].as_f64() == Some(1.0))
        .flat_map(|b| b["points"].as_array().unwrap())
        .filter(|p| p["method"] == "abuffer")
        .flat_map(|p| p["frames"].as_array().unwrap())
        .map(|f| (frame_key(f), f["bytes_per_pixel"].as_f64().unwrap()))
        .collect();
    assert_eq!(abuffer.len(), 2, "the A-buffer's frames at 1x: {abuffer:?}");
    let mut held = 0;
    for b in budgets {
        let points = b["points"].as_array().unwrap();
        let x = b["memory"].as_f64().unwrap();
        for p in points {
            let frames = p["frames"].as_array().unwrap();
            for f in frames {
                // What ran fits in M.
                let m = x * abuffer[&frame_key(f)];
                let bpp = f["bytes_per_pixel"].as_f64().unwrap();
                assert!(
                    bpp > 0.0 && bpp <= m * (1.0 + 1e-9),
                    "{} {}: {bpp} bytes a pixel in M = {m}",
                    p["method"],
                    frame_key(f)
                );
                held += 1;
            }
            let method = p["method"].as_str().unwrap();
            if x == 1.0 && ["fkb", "vkb", "dkb"].contains(&method) {
                assert!(frames.iter().all(|f| f["exact"] == true), "{method} at 1x");
                assert!(frames.iter().all(|f| f["mse"].as_f64() == Some(0.0)));
            }
            if x < 1.0 {
                assert_ne!(
                    method, "abuffer",
                    "the A-buffer does not fit in half its bytes"
                );
            }
        }
        let full: Vec<&serde_json::Value> = points
            .iter()
            .filter(|p| p["frames"].as_array().unwrap().len() == 2)
            .collect();
        let key = |p: &serde_json::Value| ["gpu_ms", "mse", "flip"].map(|k| p[k].as_f64().unwrap());
        for p in &full {
            let dominated = full.iter().any(|o| {
                let (a, b) = (key(o), key(p));
                a.iter().zip(&b).all(|(x, y)| x <= y) && a.iter().zip(&b).any(|(x, y)| x < y)
            });
            assert_eq!(p["front"].as_bool().unwrap(), !dominated, "{}", p["method"]);
        }
        assert!(full.iter().any(|p| p["front"] == true));
    }
    assert!(held >= 20, "{held} frames held to M");
    // By default, every method at equal bytes of the registry (`Method::at_equal_bytes`).
    let ran: std::collections::HashSet<&str> = budgets
        .iter()
        .flat_map(|b| b["points"].as_array().unwrap())
        .map(|p| p["method"].as_str().unwrap())
        .collect();
    let registry: std::collections::HashSet<&str> = Method::those(Method::at_equal_bytes)
        .iter()
        .map(|m| m.name())
        .collect();
    assert_eq!(ran, registry, "the methods versus put at equal bytes");
    assert!(out.join("versus_0p5x.svg").is_file() && out.join("versus_1x.png").is_file());
    assert!(
        std::fs::read_to_string(out.join("versus.md"))
            .unwrap()
            .contains("| linked-list |")
    );
}

/// `compare --camera asset --beside PICTURE`: the scene from its own viewpoint (a built-in has
/// none: its front), the picture in the montage's first column (the montage one tile wider than
/// without it); a picture that is not there is refused before anything renders, named.
#[test]
fn compare_puts_a_picture_beside_the_methods_from_the_assets_viewpoint() {
    let dir = temp_dir("cli-beside");
    // A 40x20 picture, red: what the first tile shows, scaled to fit 64x48.
    let picture = dir.join("shot.png");
    let red = image::RgbImage::from_pixel(40, 20, image::Rgb([255, 0, 0]));
    red.save(&picture).unwrap();
    let run = |beside: Option<&Path>, out: &str| {
        let out = dir.join(out);
        let mut args = vec![
            "compare", "--scene", "plates", "--res", "64x48", "--camera", "asset",
        ];
        args.extend([
            "--methods",
            "vkb",
            "--budget",
            "50%",
            "--out",
            out.to_str().unwrap(),
        ]);
        if let Some(b) = beside {
            args.extend(["--beside", b.to_str().unwrap()]);
        }
        let o = dhoit(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        image::open(out.join("plates_v0_50%_montage.png"))
            .unwrap()
            .to_rgb8()
    };
    let with = run(Some(&picture), "with");
    let without = run(None, "without");
    assert_eq!(with.height(), without.height());
    assert!(
        with.width() > without.width() + 60,
        "{} against {}",
        with.width(),
        without.width()
    );
    let reds = with.pixels().filter(|p| p.0 == [255, 0, 0]).count();
    // Scaled to 64x32 (its aspect), less the edges the filter blends with the white.
    assert!(reds >= 62 * 30, "{reds} red pixels");
    assert!(without.pixels().all(|p| p.0 != [255, 0, 0]));
    // The front view is not orbit view 0.
    let orbit = dir.join("orbit");
    let o = dhoit(&[
        "compare",
        "--scene",
        "plates",
        "--res",
        "64x48",
        "--methods",
        "vkb",
        "--budget",
        "50%",
        "--out",
        orbit.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let a = std::fs::read(dir.join("without/plates_v0_50%_abuffer.png")).unwrap();
    let b = std::fs::read(orbit.join("plates_v0_50%_abuffer.png")).unwrap();
    assert!(a != b, "--camera asset rendered orbit view 0");
    // A missing picture: refused before rendering, named.
    let missing = dir.join("nowhere.png");
    let o = dhoit(&[
        "compare",
        "--scene",
        "plates",
        "--res",
        "64x48",
        "--beside",
        missing.to_str().unwrap(),
        "--out",
        dir.join("x").to_str().unwrap(),
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("nowhere.png"), "{e}");
    assert!(!dir.join("x").exists(), "nothing written");
    let o = dhoit(&["render", "--scene", "plates", "--camera", "above"]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("above"));
}

/// `--glass tinted`, the default, renders the windows family's glass filtering per channel: on
/// the CPU an image other than the grey glass's (`--glass grey`); on the GPU the A-buffer's is
/// the CPU's, byte for byte, and VKB's and DKB's are their own, other than the grey glass's.
#[test]
fn tinted_glass_renders_on_the_cpu_and_the_gpu() {
    let dir = temp_dir("cli-tinted");
    let png = |name: &str| dir.join(name);
    let render = |glass: Option<&str>, device: &str, method: &str, out: &Path| {
        let mut args = vec![
            "render", "--scene", "windows", "--res", "64x48", "--method", method, "--device",
            device, "--out",
        ];
        args.push(out.to_str().unwrap());
        if let Some(g) = glass {
            args.extend(["--glass", g]);
        }
        args.iter().map(|a| a.to_string()).collect::<Vec<String>>()
    };
    let run = |args: Vec<String>| {
        let args: Vec<&str> = args.iter().map(|a| a.as_str()).collect();
        let o = dhoit(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run(render(None, "cpu", "abuffer", &png("default.png")));
    run(render(Some("grey"), "cpu", "abuffer", &png("grey.png")));
    run(render(Some("tinted"), "cpu", "abuffer", &png("tinted.png")));
    let read = |name: &str| std::fs::read(png(name)).unwrap();
    assert_eq!(read("default.png"), read("tinted.png"));
    assert_ne!(read("grey.png"), read("tinted.png"));
    if skip_gpu("tinted glass on the GPU") {
        return;
    }
    run(render(Some("tinted"), "gpu", "abuffer", &png("gpu.png")));
    assert_eq!(read("gpu.png"), read("tinted.png"));
    for method in ["vkb", "dkb"] {
        let frame = |glass: &str| {
            let out = png(&format!("{method}-{glass}.png"));
            let mut args = render(Some(glass), "gpu", method, &out);
            args.extend(["--budget", "25%", "--always-approximate"].map(String::from));
            run(args);
            std::fs::read(&out).unwrap()
        };
        assert_ne!(frame("tinted"), frame("grey"), "{method}");
    }
}

/// Light above white from the command line: a glTF file whose emissive panes pass white
/// (`KHR_materials_emissive_strength`), rendered to `.exr`, keeps colours above 1, the same on
/// the CPU and the GPU, for the A-buffer and VKB at 25% of the fragments (tails of light above
/// white); its `.png` clamps them at white.
#[test]
fn light_above_white_renders_to_exr_on_the_cpu_and_the_gpu() {
    use dhoit_runtime::scene::{Material, Scene};
    use glam::Vec3;
    let dir = temp_dir("cli-hdr");
    let mut s = Scene {
        materials: Vec::new(),
        ..Scene::default()
    };
    let panes = [
        (0.5, [6.0, 3.0, 1.5]),
        (0.3, [0.5, 4.0, 9.0]),
        (0.1, [2.0, 2.0, 2.0]),
        (-0.1, [0.2, 0.1, 0.0]),
        (-0.3, [12.0, 1.0, 0.5]),
        (-0.5, [1.0, 1.0, 1.0]),
    ];
    for (i, (z, e)) in panes.into_iter().enumerate() {
        let m = s.add_material(Material {
            base_color: [0.3, 0.2, 0.1, 0.5],
            emissive: e,
            ..Material::default()
        });
        let h = 0.9 - 0.1 * i as f32;
        let p = [
            Vec3::new(-h, -h, z),
            Vec3::new(h, -h, z),
            Vec3::new(h, h, z),
            Vec3::new(-h, h, z),
        ];
        let white = [[1.0; 4]; 3];
        s.push_textured([p[0], p[1], p[2]], white, [[0.0; 2]; 3], m);
        s.push_textured([p[0], p[2], p[3]], white, [[0.0; 2]; 3], m);
    }
    assert!(s.hdr());
    let glb = dir.join("bright.glb");
    scene::gltf::export(&s, &glb).unwrap();
    let render = |device: &str, method: &str, out: &str| {
        let out = dir.join(out);
        let o = dhoit(&[
            "render",
            "--scene",
            glb.to_str().unwrap(),
            "--res",
            "64x48",
            "--method",
            method,
            "--budget",
            "25%",
            "--always-approximate",
            "--device",
            device,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out
    };
    let read = |p: &Path| image::open(p).unwrap().to_rgb32f().into_raw();
    let cpu = read(&render("cpu", "abuffer", "cpu.exr"));
    let brightest = cpu.iter().copied().fold(0.0, f32::max);
    assert!(brightest > 2.0, "nothing above white: {brightest}");
    let png = image::open(render("cpu", "abuffer", "cpu.png"))
        .unwrap()
        .to_rgb8();
    assert!(png.pixels().any(|p| p.0 == [255; 3]), "the PNG clamps");
    if skip_gpu("light above white on the GPU") {
        return;
    }
    let mut frames = Vec::new();
    for method in ["abuffer", "vkb"] {
        let cpu = read(&render("cpu", method, &format!("{method}-cpu.exr")));
        let gpu = read(&render("gpu", method, &format!("{method}-gpu.exr")));
        let worst = cpu
            .iter()
            .zip(&gpu)
            .map(|(a, b)| (a - b).abs() / a.abs().max(1.0))
            .fold(0.0, f32::max);
        assert!(worst <= 1e-5, "{method}: CPU and GPU differ by {worst}");
        frames.push(gpu);
    }
    assert_ne!(frames[0], frames[1], "VKB's tails left the image exact");
}

/// `generalise` leaves each family out in turn: no fold's network trains or validates on a
/// scene of the family it is scored on, each is scored on that family's seed-1 scene (fine-tuned
/// on it too), and no allocation beats the optimal one; with two seeds each figure is the mean
/// of two different networks'; the table and the JSON are written; an unknown family is
/// refused by name.
#[test]
fn generalise_leaves_each_family_out_of_its_fold_s_training() {
    let dir = temp_dir("cli-generalise");
    let data = dir.join("data");
    let o = dhoit(&[
        "dataset",
        "--out",
        data.to_str().unwrap(),
        "--scenes",
        "shells:2,spheres:2,plates:2,shells:4,spheres:4,plates:4",
        "--res",
        "64x48",
        "--views",
        "2",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (md, json) = (dir.join("g.md"), dir.join("g.json"));
    let run = |families: &str| {
        dhoit(&[
            "generalise",
            "--data",
            data.to_str().unwrap(),
            "--families",
            families,
            "--epochs",
            "1",
            "--res",
            "64x48",
            "--opacity",
            "0.33",
            "--seeds",
            "2",
            "--out",
            md.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ])
    };
    let o = run("shells,spheres");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let folds = r["folds"].as_array().unwrap();
    assert_eq!(folds.len(), 2);
    for f in folds {
        let family = f["family"].as_str().unwrap();
        let prefix = format!("{family}:");
        let scenes = |k: &str| -> Vec<String> {
            f[k].as_array()
                .unwrap()
                .iter()
                .map(|s| s.as_str().unwrap().to_string())
                .collect()
        };
        let (train, validation) = (scenes("train_scenes"), scenes("validation_scenes"));
        assert!(!train.is_empty(), "{family}: trained on nothing");
        assert!(
            !train
                .iter()
                .chain(&validation)
                .any(|s| s.starts_with(&prefix)),
            "{family}'s fold saw its own family: {train:?} {validation:?}"
        );
        assert_eq!(f["scored"], format!("{family}:1"));
        assert!(
            f["frames"].as_u64().unwrap() > 0,
            "{family}: no frame counted"
        );
        for k in [
            "left_out_over_optimal",
            "in_distribution_over_optimal",
            "fine_tuned_over_optimal",
            "vkb_over_optimal",
        ] {
            let v = f[k].as_f64().unwrap();
            assert!(v.is_finite() && v >= 0.999, "{family} {k}: {v}");
        }
        // Two seeds a network: each seed's figure, and the fold's their geometric mean (the
        // same frames counted for each).
        for (k, mean) in [
            ("left_out_by_seed", "left_out_over_optimal"),
            ("in_distribution_by_seed", "in_distribution_over_optimal"),
        ] {
            let v: Vec<f64> = f[k]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            assert_eq!(v.len(), 2, "{family} {k}: {v:?}");
            let m = f[mean].as_f64().unwrap();
            assert!(
                (m - (v[0] * v[1]).sqrt()).abs() < 1e-9,
                "{family} {mean}: {m} from {v:?}"
            );
        }
    }
    // The seeds train different networks: over both folds and both kinds, some seed's figure
    // differs from seed 0's.
    let differ = folds.iter().any(|f| {
        ["left_out_by_seed", "in_distribution_by_seed"]
            .iter()
            .any(|k| f[*k][0] != f[*k][1])
    });
    assert!(differ, "both seeds scored alike everywhere: {folds:?}");
    assert_eq!(r["seeds"], 2);
    let table = std::fs::read_to_string(&md).unwrap();
    assert!(
        table.contains("| shells |") && table.contains("| spheres |"),
        "{table}"
    );
    let o = run("shells,nosuch");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("'nosuch'"), "{err}");
}

/// `dhoit --help` lists every method of the registry (`Method::ALL`) with what it is, and a
/// method it does not know is refused naming every one.
#[test]
fn the_help_lists_every_method_of_the_registry() {
    let o = dhoit(&["--help"]);
    assert!(o.status.success());
    let help = String::from_utf8_lossy(&o.stdout);
    let listed = help
        .lines()
        .find(|l| l.trim_start().starts_with("Methods: "))
        .unwrap_or_else(|| panic!("no list of methods in\n{help}"));
    for m in Method::ALL {
        assert!(
            listed.contains(&format!("{m} ({})", m.summary())),
            "{m} is not listed with its summary: {listed}"
        );
    }
    // Every item of the list is a method of the registry.
    let items = listed.matches(" (").count();
    assert_eq!(items, Method::ALL.len(), "{listed}");
    let o = dhoit(&["render", "--scene", "cad", "--method", "kbuffer"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    for m in Method::ALL {
        assert!(err.contains(m.name()), "{m} not named in: {err}");
    }
}
