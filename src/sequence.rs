//! `dhoit bench --sequence N`: frames in sequence, as a real-time renderer draws them. Each
//! method renders an orbit of N frames through `gpu::SceneStream` (every frame recorded into
//! an encoder with no wait, sized from the counts of the frames before): once one frame at a
//! time (each submitted and waited for, its image read back between frames, untimed), once
//! with two frames in flight (a frame waits only for the one two before it). Reported per
//! method: frames a second both ways, the GPU time of a frame, the submissions and waits
//! dhoit's recording made (none), how often a frame held more bytes than its own exact
//! A-buffer would, its bytes, and temporal stability: the mean change of the method's error
//! image (against the exact A-buffer's frame) between consecutive frames. DKB runs twice: as a
//! stream does (each frame gathers its statistics with its count, for the pixels the frame
//! before marked: two geometry passes), and as the frame after a cut (a features pass of its
//! own: three). The A-buffer, VKB and both DKBs also turn [`FAST`] times as fast (an orbit of
//! N / 4 frames), one frame at a time: what a fast camera costs the frame-to-frame marks.

use anyhow::Result;
use dhoit_runtime::budget::{self, Budget};
use dhoit_runtime::composite::Image;
use dhoit_runtime::frame::{Method, Options};
use dhoit_runtime::gpu::{FrameReport, Gpu, SceneStream, host_syncs, wgpu};
use dhoit_runtime::scene::{Camera, Scene};
use std::time::Instant;

/// The methods a renderer streams, in the report's order.
pub const STREAMED: [Method; 7] = [
    Method::Abuffer,
    Method::Fkb,
    Method::Vkb,
    Method::Dkb,
    Method::Wboit,
    Method::Mboit,
    Method::LinkedList,
];

/// How many times faster the fast camera turns than the orbit's.
pub const FAST: usize = 4;

/// A method's run of the orbit: its report name, the method, and whether every frame is a cut
/// (DKB's three-pass frame: it marks its own records and draws its features pass).
fn runs() -> Vec<(&'static str, Method, bool)> {
    let mut runs: Vec<_> = STREAMED.iter().map(|&m| (m.name(), m, false)).collect();
    let at = runs.iter().position(|r| r.1 == Method::Dkb).expect("DKB") + 1;
    runs.insert(at, ("dkb_three_pass", Method::Dkb, true));
    runs
}

/// What one lap of the orbit measured.
struct Lap {
    seconds: f64,
    reports: Vec<FrameReport>,
    /// Submissions and waits dhoit's recording made, over the lap.
    syncs: u64,
    images: Vec<Image>,
}

/// One lap of `cams`: one frame at a time (`in_flight` 1: each submitted and waited for, its
/// image read back after the clock stops where `images`), or `in_flight` frames in flight;
/// with `cuts`, every frame a cut ([`SceneStream::cut`]).
fn lap(
    gpu: &Gpu,
    stream: &mut SceneStream,
    cams: &[Camera],
    (in_flight, images, cuts): (usize, bool, bool),
) -> Result<Lap> {
    let mut reports = Vec::new();
    let mut syncs = 0;
    let mut kept = Vec::new();
    let mut seconds = 0.0;
    let mut submitted = std::collections::VecDeque::new();
    let device = gpu.device();
    let mut clock = Instant::now();
    for cam in cams {
        // A frame waits for the one `in_flight` before it, as a renderer's swap chain does.
        if submitted.len() >= in_flight {
            let index = submitted.pop_front().expect("one in flight");
            device.poll(wgpu::PollType::Wait {
                submission_index: Some(index),
                timeout: None,
            })?;
        }
        let mut enc = device.create_command_encoder(&Default::default());
        let before = host_syncs();
        if cuts {
            stream.cut();
        }
        stream.record(&mut enc, cam)?;
        syncs += host_syncs() - before;
        submitted.push_back(gpu.queue().submit([enc.finish()]));
        if in_flight == 1 {
            device.poll(wgpu::PollType::wait_indefinitely())?;
            seconds += clock.elapsed().as_secs_f64();
            if images {
                kept.push(stream.image()?);
            }
            reports.extend(stream.finished(false)?);
            clock = Instant::now();
        } else {
            // What the frames before have finished, without waiting, as a renderer reads its
            // reports (and the stream learns its sizes from them).
            reports.extend(stream.finished(false)?);
        }
    }
    device.poll(wgpu::PollType::wait_indefinitely())?;
    if in_flight > 1 {
        seconds = clock.elapsed().as_secs_f64();
    }
    reports.extend(stream.finished(true)?);
    Ok(Lap {
        seconds,
        reports,
        syncs,
        images: kept,
    })
}

/// A pixel's error: the mean of its channels' absolute differences.
fn error_image(a: &Image, exact: &Image) -> Vec<f32> {
    a.data
        .iter()
        .zip(&exact.data)
        .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).abs()).sum::<f32>() / 3.0)
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The mean absolute error of an orbit's frames against its exact ones, and how much that error
/// changes from one frame to the next (the mean absolute difference of consecutive error
/// images): flicker a viewer sees.
fn error_and_change(images: &[Image], exact: &[Image]) -> (f64, f64) {
    let errors: Vec<Vec<f32>> = images
        .iter()
        .zip(exact)
        .map(|(a, e)| error_image(a, e))
        .collect();
    let mean_error = errors
        .iter()
        .map(|e| e.iter().map(|&v| v as f64).sum::<f64>() / e.len().max(1) as f64)
        .sum::<f64>()
        / errors.len().max(1) as f64;
    let changes: Vec<f64> = errors
        .windows(2)
        .map(|p| {
            p[0].iter()
                .zip(&p[1])
                .map(|(a, b)| (a - b).abs() as f64)
                .sum::<f64>()
                / p[0].len().max(1) as f64
        })
        .collect();
    let temporal = changes.iter().sum::<f64>() / changes.len().max(1) as f64;
    (mean_error, temporal)
}

/// The orbit of `frames` frames of `scene` at `(w, h)` for every streamed method at `budget`
/// (DKB with `weights`, as a stream draws it and as cuts), as JSON: one entry a method (an
/// error entry where the method refuses the budget), a fast camera's error and change for the
/// A-buffer, VKB and DKB, and DKB's frame time against the A-buffer's and VKB's.
pub fn sequence_bench(
    gpu: &Gpu,
    (name, scene): (&str, &Scene),
    (w, h): (u32, u32),
    frames: usize,
    budget: Budget,
    weights: &dhoit_runtime::mlp::Mlp,
) -> Result<serde_json::Value> {
    let orbit =
        |n: usize| -> Vec<Camera> { (0..n).map(|v| Camera::orbit(scene, v, n, (w, h))).collect() };
    let (cams, fast_cams) = (orbit(frames), orbit((frames / FAST).max(2)));
    let options = Options {
        weights: Some(weights),
        ..Options::new(budget, [1.0; 3])
    };
    let px = w as u64 * h as u64;
    let (mut exact, mut exact_fast): (Vec<Image>, Vec<Image>) = (Vec::new(), Vec::new());
    let mut methods = serde_json::Map::new();
    for (label, m, cuts) in runs() {
        let mut stream = match SceneStream::new(gpu, scene, (w, h), m, &options) {
            Ok(s) => s,
            Err(e) => {
                methods.insert(label.into(), serde_json::json!({"error": e.to_string()}));
                continue;
            }
        };
        // One frame first, so the pools are sized from a count (the first frame of a stream is
        // sized for two fragments a pixel), and the exact reference holds every fragment.
        lap(gpu, &mut stream, &cams[..1], (1, false, cuts))?;
        let one = lap(gpu, &mut stream, &cams, (1, true, cuts))?;
        let flight = lap(gpu, &mut stream, &cams, (2, false, cuts))?;
        if m == Method::Abuffer {
            exact = one.images.clone();
        }
        let (mean_error, temporal) = error_and_change(&one.images, &exact);
        let fast = match m {
            Method::Abuffer | Method::Vkb | Method::Dkb => {
                lap(gpu, &mut stream, &fast_cams[..1], (1, false, cuts))?;
                let l = lap(gpu, &mut stream, &fast_cams, (1, true, cuts))?;
                if m == Method::Abuffer {
                    exact_fast = l.images.clone();
                }
                let (e, t) = error_and_change(&l.images, &exact_fast);
                serde_json::json!({"frames": fast_cams.len(), "mean_abs_error": e, "temporal_change": t})
            }
            _ => serde_json::Value::Null,
        };
        let gpu_ms: Vec<f64> = flight
            .reports
            .iter()
            .map(|r| r.pass_ms.iter().map(|p| p.1).sum())
            .collect();
        let all: Vec<&FrameReport> = one.reports.iter().chain(&flight.reports).collect();
        // The scene's own A-buffer stores its tint words too.
        let words = scene.tint_words();
        let over_abuffer = all
            .iter()
            .filter(|r| {
                r.fragments
                    .is_some_and(|n| r.allocated_bytes > budget::abuffer_bytes(px, n, words))
            })
            .count();
        let counted = all.iter().filter(|r| r.fragments.is_some()).count();
        let short = all.iter().filter(|r| r.pool_short).count();
        let exact_frames = all.iter().filter(|r| r.exact).count();
        if let Some(e) = all.iter().find_map(|r| r.error.as_ref()) {
            anyhow::bail!("{name} {label}: {e}");
        }
        let fps = |l: &Lap| frames as f64 / l.seconds;
        let entry = serde_json::json!({
            "frames": frames,
            "fps_one_at_a_time": fps(&one),
            "fps_two_in_flight": fps(&flight),
            "in_flight_over_one_at_a_time": fps(&flight) / fps(&one),
            "frame_gpu_ms": median(gpu_ms),
            "sync_waits_per_frame": (one.syncs + flight.syncs) as f64 / (2 * frames) as f64,
            "temporal_change": temporal,
            "mean_abs_error": mean_error,
            "temporal_over_error": temporal / mean_error,
            "frames_counted": counted,
            "frames_over_own_abuffer_bytes": over_abuffer,
            "frames_pool_short": short,
            "frames_exact": exact_frames,
            "allocated_bytes_median": median(all.iter().map(|r| r.allocated_bytes as f64).collect()),
            "fast": fast,
        });
        eprintln!(
            "GPU {name} sequence, {label}: {:.2} fps in flight, {:.2} one at a time, {:.2} ms a frame, {} syncs, temporal change {temporal:.2e} (error {mean_error:.2e}), {over_abuffer} of {counted} frames above their A-buffer's bytes, {short} short, {exact_frames} exact",
            fps(&flight),
            fps(&one),
            entry["frame_gpu_ms"].as_f64().unwrap_or(f64::NAN),
            one.syncs + flight.syncs,
        );
        methods.insert(label.into(), entry);
    }
    let ms = |m: &str| {
        methods
            .get(m)
            .and_then(|v| v["frame_gpu_ms"].as_f64())
            .unwrap_or(f64::NAN)
    };
    let temporal = |m: &str| {
        methods
            .get(m)
            .and_then(|v| v["temporal_change"].as_f64())
            .unwrap_or(f64::NAN)
    };
    let error = |m: &str| {
        methods
            .get(m)
            .and_then(|v| v["mean_abs_error"].as_f64())
            .unwrap_or(f64::NAN)
    };
    Ok(serde_json::json!({
        "frames": frames,
        "methods": methods,
        "dkb_over_abuffer": ms("dkb") / ms("abuffer"),
        "dkb_over_vkb": ms("dkb") / ms("vkb"),
        "dkb_temporal_over_vkb": temporal("dkb") / temporal("vkb"),
        "dkb_error_over_vkb": error("dkb") / error("vkb"),
        "three_pass_over_two_pass": ms("dkb_three_pass") / ms("dkb"),
    }))
}
