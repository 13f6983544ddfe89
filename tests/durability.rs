//! Nothing half-written, nothing lost: outputs are written to a temporary file and renamed, so a
//! failed write or a run killed in the middle leaves the previous file as it was.

mod common;
use common::{root, temp_dir};
use dhoit_runtime::tensors;
use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

#[test]
fn a_failed_write_leaves_the_previous_file_intact() {
    let dir = temp_dir("durable-failed-write");
    let path = dir.join("weights.safetensors");
    std::fs::write(&path, b"the previous weights").unwrap();
    // The temporary file's place is taken (a folder): the write fails as a full disk would.
    let blocker = PathBuf::from(format!("{}.{}.tmp", path.display(), std::process::id()));
    std::fs::create_dir_all(blocker.join("inside")).unwrap();
    let e = tensors::write_atomic(&path, &[7u8; 1 << 16]).unwrap_err();
    assert!(
        e.to_string()
            .contains(&format!("cannot write {}", path.display())),
        "{e}"
    );
    assert_eq!(std::fs::read(&path).unwrap(), b"the previous weights");
    std::fs::remove_dir_all(&blocker).unwrap();
    // Then it goes through, whole.
    tensors::write_atomic(&path, &[7u8; 1 << 16]).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), vec![7u8; 1 << 16]);
}

/// What a killed or failing run relies on: while a file is rewritten, a reader (another
/// process, or the user's renderer loading weights) sees the old bytes or the new ones, whole,
/// never a truncated or half-written file. Four MiB a write, so that a write in place would be
/// caught in the middle (checked: with `std::fs::write` in place of the rename, the reader saw
/// partial files).
#[test]
fn a_reader_never_sees_a_half_written_file() {
    let dir = temp_dir("durable-reader");
    let path = dir.join("weights.safetensors");
    let (a, b) = (vec![1u8; 4 << 20], vec![2u8; 4 << 20]);
    tensors::write_atomic(&path, &a).unwrap();
    let done = std::sync::atomic::AtomicBool::new(false);
    let (reads, partial) = std::thread::scope(|s| {
        let reader = s.spawn(|| {
            let (mut reads, mut partial) = (0usize, 0usize);
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                let got = std::fs::read(&path).unwrap();
                reads += 1;
                if got != a && got != b {
                    partial += 1;
                }
            }
            (reads, partial)
        });
        for i in 0..60 {
            tensors::write_atomic(&path, if i % 2 == 0 { &b } else { &a }).unwrap();
        }
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        reader.join().unwrap()
    });
    assert!(reads > 0);
    assert_eq!(partial, 0, "{partial} of {reads} reads saw a partial file");
}

#[test]
fn a_killed_training_run_leaves_the_previous_weights_intact() {
    let dir = temp_dir("durable-killed-train");
    let data = dir.join("ds");
    let o = Command::new(env!("CARGO_BIN_EXE_dhoit"))
        .args([
            "dataset",
            "--scenes",
            "shells:5,particles:5",
            "--views",
            "2",
            "--res",
            "96x72",
        ])
        .args(["--budgets", "10%,50%", "--sample", "1", "--out"])
        .arg(&data)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.join("weights.safetensors");
    let previous = std::fs::read(root().join("data/weights.safetensors")).unwrap();
    std::fs::write(&out, &previous).unwrap();
    std::fs::write(dir.join("config.json"), b"{\"previous\": true}").unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_dhoit"))
        .args([
            "train",
            "--epochs",
            "100000",
            "--validation",
            "shells:5",
            "--data",
        ])
        .arg(&data)
        .arg("--out")
        .arg(&out)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Let it train for a while, then kill it in the middle of an epoch.
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(3) {
        assert!(child.try_wait().unwrap().is_none(), "training ended early");
        std::thread::sleep(Duration::from_millis(100));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(std::fs::read(&out).unwrap(), previous, "weights untouched");
    assert_eq!(
        std::fs::read(dir.join("config.json")).unwrap(),
        b"{\"previous\": true}"
    );
    // The weights still load.
    dhoit_runtime::mlp::Mlp::load(&out).unwrap();
}

#[test]
fn a_failed_render_leaves_a_previous_image_intact() {
    let dir = temp_dir("durable-render");
    let out = dir.join("frame.png");
    std::fs::write(&out, b"previous image").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_dhoit"))
        .args([
            "render", "--scene", "shells", "--res", "32x24", "--budget", "1KB",
        ])
        .args(["--method", "vkb", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert_eq!(std::fs::read(&out).unwrap(), b"previous image");
}

#[test]
fn a_dataset_run_with_a_bad_scene_leaves_the_previous_dataset_intact() {
    let dir = temp_dir("durable-dataset");
    let data = dir.join("ds");
    let dataset = |scenes: &str| {
        Command::new(env!("CARGO_BIN_EXE_dhoit"))
            .args([
                "dataset", "--scenes", scenes, "--views", "1", "--res", "32x24",
            ])
            .args(["--budgets", "50%", "--sample", "1", "--out"])
            .arg(&data)
            .output()
            .unwrap()
    };
    let o = dataset("shells:5");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let manifest = std::fs::read(data.join("manifest.json")).unwrap();
    // A name that does not load, after one that does: refused before the folder is touched
    // (its manifest was removed first, which left the dataset unreadable).
    let o = dataset("shells:5,no-such-scene");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("unknown scene 'no-such-scene'"), "{err}");
    assert_eq!(std::fs::read(data.join("manifest.json")).unwrap(), manifest);
}
