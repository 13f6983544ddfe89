//! Regression of the committed default weights: their predictions on the committed golden
//! features must not change, through the runtime's twin, burn, and the `predict` command.

mod common;
use common::{gpu, max_abs_diff, root, temp_dir};
use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::tensors::{self, Entry};
use std::path::Path;
use std::process::Command;

fn golden() -> (Mlp, Vec<[f32; 12]>, Vec<f32>) {
    let mlp =
        Mlp::load(&root().join("data/weights.safetensors")).expect("committed default weights");
    let rows =
        dhoit_train::cli::read_features(&root().join("data/golden/features.safetensors")).unwrap();
    let bytes = std::fs::read(root().join("data/golden/predictions.safetensors")).unwrap();
    let file = tensors::File::parse(&bytes).unwrap();
    let (_, pred) = file.f32("importance", Some(&[rows.len()])).unwrap();
    assert!(
        rows.len() >= 256,
        "a golden set worth the name: {} rows",
        rows.len()
    );
    (mlp, rows, pred)
}

/// Fails, naming the rows that moved beyond `tolerance`, by how much, and how to regenerate the
/// golden files when the change is on purpose.
fn hold_to_golden(what: &str, got: &[f32], golden: &[f32], tolerance: f32) {
    assert_eq!(got.len(), golden.len(), "{what}: row count");
    let moved: Vec<String> = got
        .iter()
        .zip(golden)
        .enumerate()
        .filter(|(_, (g, e))| (*g - *e).abs() > tolerance)
        .map(|(i, (g, e))| format!("row {i}: {e} -> {g} ({:+e})", g - e))
        .collect();
    assert!(
        moved.is_empty(),
        "{what}: {} of {} predictions moved beyond {tolerance:e}:\n  {}\nIf the change is on \
         purpose (new weights or features), regenerate the golden files with `make golden` and \
         commit data/golden/.",
        moved.len(),
        got.len(),
        moved
            .iter()
            .take(10)
            .cloned()
            .collect::<Vec<_>>()
            .join("\n  ")
    );
}

#[test]
fn the_runtime_twin_reproduces_the_golden_predictions() {
    let (mlp, rows, pred) = golden();
    let twin: Vec<f32> = rows.iter().map(|r| mlp.forward(r)).collect();
    hold_to_golden("the runtime twin", &twin, &pred, 1e-6);
    // The predictions are not degenerate: they spread over a range (slot requests over
    // several slots).
    let (lo, hi) = pred
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let spread = match mlp.target {
        dhoit_runtime::alloc::Target::SlotRequest => {
            (hi - lo) * dhoit_runtime::alloc::REQUEST_SLOTS / 4.0
        }
        _ => (hi - lo) / 0.05,
    };
    assert!(spread > 1.0, "golden predictions span {lo}..{hi}");
}

#[test]
fn burn_reproduces_the_golden_predictions() {
    let (mlp, rows, pred) = golden();
    hold_to_golden(
        "burn",
        &dhoit_train::model::predict(&mlp, &rows),
        &pred,
        1e-6,
    );
}

#[test]
fn the_gpu_reproduces_the_golden_predictions() {
    let (mlp, rows, pred) = golden();
    let Some(g) = gpu() else { return };
    hold_to_golden("the GPU", &g.predict(&mlp, &rows).unwrap(), &pred, 1e-5);
}

#[test]
fn a_moved_prediction_is_reported_with_its_rows() {
    let golden = [0.1f32, 0.2, 0.3];
    let moved = [0.1f32, 0.25, 0.3];
    let e = std::panic::catch_unwind(|| hold_to_golden("demo", &moved, &golden, 1e-6)).unwrap_err();
    let msg = e.downcast_ref::<String>().unwrap();
    assert!(msg.contains("1 of 3 predictions moved") && msg.contains("row 1: 0.2 -> 0.25"));
    assert!(msg.contains("make golden"), "{msg}");
}

#[test]
fn the_predict_command_reproduces_them_and_refuses_bad_features() {
    let (_, rows, pred) = golden();
    let dir = temp_dir("golden-predict");
    let out = dir.join("pred.safetensors");
    let run = |input: &Path, out: &Path| {
        Command::new(env!("CARGO_BIN_EXE_dhoit"))
            .args(["predict", "--weights"])
            .arg(root().join("data/weights.safetensors"))
            .arg("--input")
            .arg(input)
            .arg("--output")
            .arg(out)
            .args(["--device", "cpu"])
            .output()
            .unwrap()
    };
    let o = run(&root().join("data/golden/features.safetensors"), &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&out).unwrap();
    let (_, got) = tensors::File::parse(&bytes)
        .unwrap()
        .f32("importance", Some(&[rows.len()]))
        .unwrap();
    assert!(max_abs_diff(&got, &pred) <= 1e-6);
    // Non-finite and misshapen features: a clear error, no output.
    let mut flat: Vec<f32> = rows.iter().flatten().copied().collect();
    flat[5] = f32::NAN;
    let nan = dir.join("nan.safetensors");
    tensors::write(
        &nan,
        &[Entry::f32("features", vec![rows.len(), 12], &flat)],
        Default::default(),
    )
    .unwrap();
    let never = dir.join("never.safetensors");
    let o = run(&nan, &never);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("non-finite feature at row 0, column 5"));
    let shape = dir.join("shape.safetensors");
    tensors::write(
        &shape,
        &[Entry::f32("features", vec![rows.len() * 2, 6], &flat)],
        Default::default(),
    )
    .unwrap();
    let o = run(&shape, &never);
    assert!(String::from_utf8_lossy(&o.stderr).contains("expected [N, 12]"));
    assert!(!never.exists());
}

#[test]
fn dkb_renders_with_the_default_weights() {
    let dir = temp_dir("golden-dkb");
    let out = dir.join("dkb.png");
    let o = Command::new(env!("CARGO_BIN_EXE_dhoit"))
        .current_dir(root())
        .args([
            "render",
            "--scene",
            "hair",
            "--res",
            "96x72",
            "--method",
            "dkb",
            "--budget",
            "1fpp",
            "--always-approximate",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.is_file());
}

/// `predict --precision f16` on every device: burn, the twin and the GPU's f16 pass write the
/// same predictions (within 1e-5), the golden ones (the default weights deploy at f16, their
/// file says so, and are stored rounded); and rounding a network's f32 weights to binary16
/// moves its predictions, within `mlp::F16_BOUND`.
#[test]
fn f16_predictions_agree_on_every_device_and_stay_near_the_golden_ones() {
    let weights = root().join("data/weights.safetensors");
    let committed = Mlp::load(&weights).unwrap();
    assert_eq!(committed.precision, dhoit_runtime::mlp::Precision::F16);
    let (_, rows, pred) = golden();
    let f32_net = Mlp::random(3);
    let ones = vec![1; rows.len()];
    let at_f32 = f32_net.importance(&rows, &ones);
    let at_f16 = f32_net
        .at_precision(dhoit_runtime::mlp::Precision::F16)
        .unwrap()
        .importance(&rows, &ones);
    let d = max_abs_diff(&at_f16, &at_f32);
    assert!(
        d <= dhoit_runtime::mlp::F16_BOUND,
        "f16 moved an f32 network by {d}"
    );
    assert!(d > 0.0, "f16 changed nothing in an f32 network");
    let dir = temp_dir("golden-f16");
    let mut devices = vec!["cpu", "twin"];
    if !common::skip_gpu("f16 predictions on the GPU") {
        devices.push("gpu");
    }
    let mut outs = Vec::new();
    for device in devices {
        let out = dir.join(format!("{device}.safetensors"));
        let o = Command::new(env!("CARGO_BIN_EXE_dhoit"))
            .args([
                "predict",
                "--precision",
                "f16",
                "--device",
                device,
                "--weights",
            ])
            .arg(&weights)
            .arg("--input")
            .arg(root().join("data/golden/features.safetensors"))
            .arg("--output")
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let bytes = std::fs::read(&out).unwrap();
        let file = tensors::File::parse(&bytes).unwrap();
        assert_eq!(file.meta("precision").unwrap(), "f16");
        let (_, got) = file.f32("importance", Some(&[rows.len()])).unwrap();
        let d = max_abs_diff(&got, &pred);
        assert!(d <= 1e-5, "{device}: {d} from the golden predictions");
        outs.push((device, got));
    }
    for (device, got) in &outs[1..] {
        let d = max_abs_diff(got, &outs[0].1);
        assert!(d <= 1e-5, "{device} and burn differ by {d} at f16");
    }
}
