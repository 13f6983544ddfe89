//! `dhoit bench`: throughput of the CPU reference passes, as JSON.

use anyhow::Result;
use clap::Args;
use dhoit_runtime::alloc;
use dhoit_runtime::budget::Budget;
use dhoit_runtime::frame::{Method, Options, Renderer};
use dhoit_runtime::raster::{self, Resolution};
use dhoit_runtime::scene::{self, Camera, Opacity};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct BenchArgs {
    /// Built-in scenes to measure (comma separated); all by default.
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<String>,
    /// Resolution WIDTHxHEIGHT.
    #[arg(long, default_value = "640x480")]
    res: Resolution,
    /// Timed repetitions per measurement: the fastest is reported on the CPU, the median of
    /// the steady frames (after 0.25 s of warm-up) on the GPU.
    #[arg(long, default_value_t = 3, value_parser = crate::args::parse_repeat)]
    repeat: usize,
    /// Budget of every bounded method (F of the k-buffers, MLAB's rows), as `render --budget`
    /// takes it.
    #[arg(long, default_value = "2fpp")]
    budget: Budget,
    /// Also write the JSON here (with --gpu-only, after each scene too, marked "partial": true
    /// until the run ends, so a run stopped early keeps the scenes it finished).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Measure the GPU pipeline only: skip the CPU rasterizer, compositors, optimal allocation
    /// and training throughput (for a short lease on a machine with a real GPU).
    #[arg(long, conflicts_with = "network_only")]
    gpu_only: bool,
    /// Measure the network only: training steps (the fused step at batch 512 beside burn's
    /// autodiff graph, and the regret-loss step) and inference; no renderer, no scene.
    #[arg(long)]
    network_only: bool,
    /// Also render an orbit of this many frames of each scene with every method a renderer
    /// streams, as a real-time renderer draws them (recorded into an encoder with no wait):
    /// frames a second with two frames in flight and one at a time, dhoit's submissions and
    /// waits a frame (none), the frames that held more than their own A-buffer's bytes, and
    /// temporal stability (the mean change of the error image between consecutive frames).
    /// 0: none.
    #[arg(long, default_value_t = 0)]
    sequence: usize,
    /// Also write the GPU tables (Markdown: each method's frame, the portable capture beside
    /// the 64-bit one, the orbit) here, headed by the command and the adapter, written whole
    /// once the run ends. `make frame` writes docs/frame/ so.
    #[arg(long)]
    summary: Option<PathBuf>,
}

/// The methods the GPU bench measures, in the registry's order ([`Method::gpu_timed`]; its
/// variants are of FKB, VKB and DKB).
fn gpu_methods() -> Vec<Method> {
    Method::those(Method::gpu_timed)
}

/// The CPU's allocation for method `m` among `cpu`, one per [`gpu_methods`] in its order (None
/// where the budget refused it).
fn allocation_of(
    cpu: &[Option<dhoit_runtime::frame::Allocation>],
    m: Method,
) -> &Option<dhoit_runtime::frame::Allocation> {
    let i = gpu_methods().iter().position(|&x| x == m);
    &cpu[i.expect("a method the GPU bench times")]
}

/// Fastest of `n` runs of `f`, in seconds, with the last result.
fn best<T>(n: usize, mut f: impl FnMut() -> Result<T>) -> Result<(f64, T)> {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..n.max(1) {
        let t = Instant::now();
        let v = f()?;
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(v);
    }
    Ok((best, last.expect("at least one run")))
}

pub fn run(a: BenchArgs) -> Result<()> {
    if a.network_only {
        if let Some(path) = &a.out {
            dhoit_runtime::tensors::create_parent(path)?;
        }
        let report = serde_json::json!({
            "threads": rayon::current_num_threads(), "repeat": a.repeat,
            "network": network_bench(a.repeat)?,
        });
        return write_report(report, a.out.as_deref());
    }
    let size = a.res.size();
    let budget = a.budget;
    let names: Vec<String> = if a.scenes.is_empty() {
        scene::procedural::BUILTIN
            .iter()
            .map(|s| s.0.to_string())
            .collect()
    } else {
        a.scenes.clone()
    };
    // Every scene loaded before the first measurement (a scene that fails later, on the
    // device, is recorded in the report beside the others).
    let scenes = names
        .iter()
        .map(|name| Ok((name.clone(), scene::load(name, Opacity::default())?)))
        .collect::<Result<Vec<(String, scene::Scene)>>>()?;
    // A budget too small for a method measured is refused before the first measurement (on
    // the GPU it would be recorded as every scene's error). MLAB, measured on the CPU only,
    // needs less than FKB.
    for m in gpu_methods() {
        dhoit_runtime::frame::check_budget(budget, m, size)?;
    }
    // The report's folder too: a run on a lent GPU must not measure for minutes and then fail
    // to write what it measured.
    for path in a.out.iter().chain(&a.summary) {
        dhoit_runtime::tensors::create_parent(path)?;
    }
    if a.gpu_only {
        let report = |gpu: serde_json::Value| {
            serde_json::json!({
                "threads": rayon::current_num_threads(), "gpu": gpu,
                "budget": budget.to_string(), "repeat": a.repeat,
            })
        };
        // After each scene, the report so far (marked partial) replaces the file, so a run
        // stopped by a time limit (a lent GPU's) keeps the scenes it finished.
        let mut partial = |gpu: &serde_json::Value| {
            if let Some(path) = a.out.as_deref() {
                let mut r = report(gpu.clone());
                r["partial"] = true.into();
                let write = || -> Result<()> {
                    let text = serde_json::to_string_pretty(&r)?;
                    dhoit_runtime::tensors::write_atomic(path, text.as_bytes())?;
                    Ok(())
                };
                if let Err(e) = write() {
                    eprintln!("bench: could not write the partial report: {e}");
                }
            }
        };
        let gpu = gpu_bench(&scenes, size, budget, (a.repeat, a.sequence), &mut partial);
        write_summary(&gpu, a.summary.as_deref())?;
        return write_report(report(gpu), a.out.as_deref());
    }
    let results = scenes
        .iter()
        .map(|(name, s)| cpu_scene_bench(name, s, size, budget, a.repeat))
        .collect::<Result<Vec<_>>>()?;
    // The optimal allocation on the deepest scene measured, at two resolutions.
    let deepest = results
        .iter()
        .max_by_key(|r| r["max_depth_complexity"].as_u64().unwrap_or(0))
        .map(|r| r["scene"].as_str().unwrap_or("particles").to_string())
        .unwrap_or_else(|| "particles".into());
    let optimal = optimal_bench(&deepest, budget, a.repeat)?;
    let network = network_bench(a.repeat)?;
    let gpu = gpu_bench(&scenes, size, budget, (a.repeat, a.sequence), &mut |_| {});
    write_summary(&gpu, a.summary.as_deref())?;
    let report = serde_json::json!({
        "threads": rayon::current_num_threads(),
        "gpu": gpu,
        "network": network,
        "budget": budget.to_string(),
        "repeat": a.repeat,
        "cpu": results,
        "optimal_allocation": optimal,
    });
    write_report(report, a.out.as_deref())
}

/// One scene's CPU figures at `(w, h)`, view 0: rasterization and every CPU method's frame at
/// `budget` (always approximate), best of `repeat`.
fn cpu_scene_bench(
    name: &str,
    s: &scene::Scene,
    (w, h): (u32, u32),
    budget: Budget,
    repeat: usize,
) -> Result<serde_json::Value> {
    let cam = Camera::orbit(s, 0, scene::DEFAULT_VIEWS, (w, h));
    let (t_raster, fl) = best(repeat, || Ok(raster::rasterize(s, &cam, (w, h))?))?;
    let frags = fl.fragment_count() as f64;
    let mut entry = serde_json::json!({
        "scene": name, "triangles": s.triangle_count(), "width": w, "height": h,
        "fragments": fl.fragment_count(), "max_depth_complexity": fl.max_depth_complexity(),
        "raster_ms": t_raster * 1e3, "raster_fragments_per_s": frags / t_raster,
    });
    for m in [
        Method::Abuffer,
        Method::Fkb,
        Method::Vkb,
        Method::Mlab,
        Method::Wboit,
        Method::Mboit,
    ] {
        let (t, _) = best(repeat, || {
            Ok(
                Renderer::new(&fl, Options::new(budget, [1.0; 3]).always_approximate())
                    .render(m)?,
            )
        })?;
        entry[format!("{}_ms", m.name())] = (t * 1e3).into();
        entry[format!("{}_fragments_per_s", m.name())] = (frags / t).into();
    }
    eprintln!(
        "{name}: {} fragments, raster {:.0} ms",
        fl.fragment_count(),
        t_raster * 1e3
    );
    Ok(entry)
}

/// The optimal allocation's time on `deepest` at 640x480 and 1430x960 (error curves and the
/// solve, best of `repeat`), or why a resolution was skipped.
fn optimal_bench(deepest: &str, budget: Budget, repeat: usize) -> Result<Vec<serde_json::Value>> {
    let mut optimal = Vec::new();
    for (w, h) in [(640u32, 480u32), (1430, 960)] {
        let s = scene::load(deepest, Opacity::default())?;
        let cam = Camera::orbit(&s, 0, scene::DEFAULT_VIEWS, (w, h));
        let fl = raster::rasterize(&s, &cam, (w, h))?;
        let frags = fl.fragment_count() as f64;
        // A byte budget sized for --res may not hold this frame: said, and the rest measured.
        let f = match budget.resolve(
            &dhoit_runtime::budget::OPT,
            (w * h) as u64,
            fl.fragment_count() as u64,
        ) {
            Ok((_, f)) => f,
            Err(e) => {
                eprintln!("optimal allocation, {deepest} {w}x{h}: skipped: {e}");
                optimal.push(serde_json::json!({
                    "scene": deepest, "width": w, "height": h, "error": e.to_string(),
                }));
                continue;
            }
        };
        let (t_curves, curves) = best(repeat, || Ok(alloc::error_curves(&fl, [1.0; 3])))?;
        let (t_opt, (_, rep)) = best(repeat, || Ok(alloc::optimal(&curves, f)))?;
        eprintln!(
            "optimal allocation, {deepest} {w}x{h}: {} fragments, curves {:.0} ms + solve {:.0} ms",
            fl.fragment_count(),
            t_curves * 1e3,
            t_opt * 1e3
        );
        optimal.push(serde_json::json!({
            "scene": deepest, "width": w, "height": h, "fragments": fl.fragment_count(),
            "budget_fragments": f, "error_curves_ms": t_curves * 1e3, "solve_ms": t_opt * 1e3,
            "total_ms": (t_curves + t_opt) * 1e3, "fragments_per_s": frags / (t_curves + t_opt),
            "chosen": rep.chosen, "total_error": rep.total, "lower_bound": rep.lower_bound,
            "gap": rep.gap(), "greedy_paper_total": rep.greedy_paper_total,
            "greedy_increase_total": rep.greedy_increase_total, "hull_total": rep.hull_total,
        }));
    }
    Ok(optimal)
}

/// The network's throughput, in samples a second: training steps (the MSE step at batch 512
/// through the fused step and through burn's autodiff graph, as the peer in the README runs
/// it; the regret-loss step on a frame of 1024 pixels, what `make train` runs), burn
/// inference, the runtime's plain-Rust twin.
fn network_bench(repeat: usize) -> Result<serde_json::Value> {
    // Each the fastest of `repeat` runs, as the CPU figures.
    let fastest = |f: &dyn Fn() -> f64| (0..repeat).map(|_| f()).fold(0.0, f64::max);
    let train_sps = fastest(&|| dhoit_train::trainer::bench_training(512, 200));
    let autodiff_sps = fastest(&|| dhoit_train::trainer::bench_training_autodiff(512, 100));
    let regret_sps = fastest(&|| dhoit_train::trainer::bench_regret_step(1024, 100));
    let burn_sps = fastest(&|| dhoit_train::trainer::bench_inference(200_000));
    let twin = dhoit_runtime::mlp::Mlp::random(3);
    let feats = vec![[0.5f32; 12]; 200_000];
    let counts = vec![1u32; feats.len()];
    let (t_twin, _) = best(repeat, || Ok(twin.importance(&feats, &counts)))?;
    eprintln!(
        "network: training {train_sps:.0} samples/s at batch 512 ({autodiff_sps:.0} through burn's autodiff), regret-loss step {regret_sps:.0} samples/s, burn inference {burn_sps:.0} samples/s"
    );
    Ok(serde_json::json!({
        "training_samples_per_s_batch_512": train_sps,
        "training_autodiff_samples_per_s_batch_512": autodiff_sps,
        "training_regret_samples_per_s_frame_1024": regret_sps,
        "burn_inference_samples_per_s": burn_sps,
        "cpu_twin_inference_samples_per_s": feats.len() as f64 / t_twin,
    }))
}

/// Prints the report and, when asked, writes it whole (never half-written).
fn write_report(report: serde_json::Value, out: Option<&std::path::Path>) -> Result<()> {
    let text = serde_json::to_string_pretty(&report)?;
    println!("{text}");
    if let Some(path) = out {
        dhoit_runtime::tensors::write_atomic(path, text.as_bytes())?;
    }
    Ok(())
}

/// The frame options of one of the bench's runs, by its label: the run's one option away from
/// the default, every other option at its default (any other label: all defaults); steady-state
/// frames read back their image only.
fn configure(label: &str) -> dhoit_runtime::gpu::FrameOptions {
    use dhoit_runtime::gpu::{FrameOptions, Tuning};
    FrameOptions {
        tuning: Tuning {
            skip_forced: label != "dkb_no_skip",
            two_mode_capture: label != "dkb_insertion_only",
            fits_pipelines: label != "dkb_two_mode_where_all_fit",
            spread_search: label == "dkb_spread_search",
            shared_weights: label == "dkb_shared_weights",
            unrolled_network: label != "dkb_array_network",
            features_preload: label != "dkb_features_no_preload",
            layer_major_fkb: label == "fkb_layer_major",
            // The features pass's own options measured where it is drawn: a frame of three
            // geometry passes.
            two_pass_dkb: !matches!(label, "dkb_three_pass" | "dkb_features_no_preload"),
        },
        // The methods themselves, at equal F (the runs are always approximate); every record
        // in the pool at once (one features pass, where the records may outweigh the slots: a
        // small budget on a deep frame) but where the variant batches them.
        decision: dhoit_runtime::budget::Decision {
            exact_when_cheaper: false,
            record_batches: match label {
                "dkb_records_in_batches" => 3,
                _ => dhoit_runtime::budget::RECORD_BATCHES,
            },
        },
        diagnostics: false,
        // FKB, VKB and DKB once more with the capture of 32-bit atomics.
        capture: match label.ends_with("_portable") {
            true => dhoit_runtime::gpu::Capture::Portable,
            false => dhoit_runtime::gpu::Capture::Wide,
        },
    }
}

/// The networks the GPU bench runs: the shipped default (the 128-64) and the smallest shipped
/// network (`mlp::SHIPPED`, built into the binary), and the default at f16-math where the
/// device computes in binary16.
struct BenchNets {
    mlp: dhoit_runtime::mlp::Mlp,
    weights: String,
    small: dhoit_runtime::mlp::Mlp,
    small_weights: String,
    half: Option<dhoit_runtime::mlp::Mlp>,
}

fn bench_nets(gpu: &dhoit_runtime::gpu::Gpu) -> Result<BenchNets> {
    let mlp = dhoit_runtime::mlp::Mlp::shipped("128-64")?;
    // The smallest shipped network, which the trade finds as accurate at one opacity
    // (docs/trade.md).
    let small = dhoit_runtime::mlp::Mlp::shipped("16-8")?;
    // The default network with binary16 hidden layers (mlp::Precision::F16Math), where the
    // device computes in binary16 and the weights fit it.
    let half = mlp
        .at_precision(dhoit_runtime::mlp::Precision::F16Math)
        .ok()
        .filter(|_| gpu.has_half_math());
    if half.is_none() {
        eprintln!("GPU: no f16-math run (the device lacks SHADER_F16 or a weight exceeds f16)");
    }
    Ok(BenchNets {
        mlp,
        weights: "the shipped 128-64 (data/weights.safetensors)".into(),
        small,
        small_weights: "the shipped 16-8 (data/nets/16-8/weights.safetensors)".into(),
        half,
    })
}

/// The runs of one scene: every method as `render --device gpu` runs it, then each one option
/// away from the default. DKB once more with the network run on every covered pixel, even where
/// k is forced, once with every fragment inserted (no append mode in the capture), once with the
/// two-mode capture pipeline where the budget holds every fragment, once with the search's
/// totals spread over 32 copies, and
/// once with the network's weights staged in workgroup memory; FKB once more with its slots
/// laid out layer-major; DKB with its records in one batch (the pool sized for all of them);
/// and DKB with the 16-8 network, and with the default one at f16-math
/// (binary16 hidden layers) where the device has them; FKB, VKB and DKB with the portable
/// capture (32-bit atomics, two passes). `cpu` is in [`gpu_methods`]' order.
/// A method whose allocation the budget refuses (`None`: FKB below a slot a pixel) has no runs.
fn bench_runs(
    cpu: &[Option<dhoit_runtime::frame::Allocation>],
) -> Vec<(&'static str, Method, &dhoit_runtime::frame::Allocation)> {
    let of = |m| allocation_of(cpu, m);
    gpu_methods()
        .iter()
        .zip(cpu)
        .map(|(m, f)| (m.name(), *m, f))
        .chain([
            ("dkb_no_skip", Method::Dkb, of(Method::Dkb)),
            ("dkb_insertion_only", Method::Dkb, of(Method::Dkb)),
            ("dkb_two_mode_where_all_fit", Method::Dkb, of(Method::Dkb)),
            ("dkb_spread_search", Method::Dkb, of(Method::Dkb)),
            ("dkb_shared_weights", Method::Dkb, of(Method::Dkb)),
            ("dkb_array_network", Method::Dkb, of(Method::Dkb)),
            ("dkb_features_no_preload", Method::Dkb, of(Method::Dkb)),
            ("dkb_records_in_batches", Method::Dkb, of(Method::Dkb)),
            ("dkb_three_pass", Method::Dkb, of(Method::Dkb)),
            ("fkb_layer_major", Method::Fkb, of(Method::Fkb)),
            ("dkb_16-8", Method::Dkb, of(Method::Dkb)),
            ("dkb_f16_math", Method::Dkb, of(Method::Dkb)),
            ("fkb_portable", Method::Fkb, of(Method::Fkb)),
            ("vkb_portable", Method::Vkb, of(Method::Vkb)),
            ("dkb_portable", Method::Dkb, of(Method::Dkb)),
        ])
        .filter_map(|(label, m, f)| f.as_ref().map(|f| (label, m, f)))
        .collect()
}

/// One run's times: one cold frame (its buffers are created), warm-up frames for a quarter of a
/// second, then `repeat` steady-state frames that reuse them and read back only the image:
/// their medians, and the fastest one's passes.
fn time_run(
    gpu: &dhoit_runtime::gpu::Gpu,
    opts: &dhoit_runtime::gpu::FrameOptions,
    (s, cam): (&scene::Scene, &Camera),
    (w, h): (u32, u32),
    slots: dhoit_runtime::gpu::Slots,
    repeat: usize,
) -> Result<serde_json::Value> {
    let timed = |gpu: &dhoit_runtime::gpu::Gpu| -> Result<(f64, f64, _)> {
        let t = Instant::now();
        let g = gpu.render_with(opts, s, cam, (w, h), [1.0; 3], slots)?;
        let wall = t.elapsed().as_secs_f64() * 1e3;
        let passes: f64 = g.pass_ms.iter().map(|p| p.1).sum();
        Ok((passes, wall, g))
    };
    let (_, cold_wall, _) = timed(gpu)?;
    // Warm-up frames for a quarter of a second at least: a real GPU raises its
    // clocks under load (an H200 timed the same pass up to 2x apart between runs).
    let warm = Instant::now();
    while warm.elapsed().as_secs_f64() < 0.25 {
        timed(gpu)?;
    }
    let created = gpu.buffers_created();
    let mut steady = Vec::new();
    for _ in 0..repeat.max(1) {
        steady.push(timed(gpu)?);
    }
    let created_steady = gpu.buffers_created() - created;
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let gpu_ms = median(steady.iter().map(|f| f.0).collect());
    let wall_ms = median(steady.iter().map(|f| f.1).collect());
    // Host time outside the passes: the scene's upload and the image's readback.
    let host = |name: &str| {
        median(
            steady
                .iter()
                .map(|f| {
                    f.2.host_ms
                        .iter()
                        .find(|h| h.0 == name)
                        .map_or(0.0, |h| h.1)
                })
                .collect(),
        )
    };
    let (upload_ms, readback_ms) = (host("scene upload"), host("image readback"));
    // Per-pass times of the fastest steady frame.
    let fastest = steady
        .into_iter()
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .expect("one frame")
        .2;
    // A pass recorded more than once (the two prefix sums, DKB's features and importance once
    // for each batch of its records) counts its runs' time together.
    let mut per = serde_json::Map::new();
    for (n, ms) in fastest.pass_ms {
        let sum = per.get(n).and_then(|v| v.as_f64()).unwrap_or(0.0) + ms;
        per.insert(n.to_string(), sum.into());
    }
    Ok(serde_json::json!({
        "passes_ms": per, "frame_gpu_ms": gpu_ms, "frame_wall_ms": wall_ms,
        "wall_over_gpu": wall_ms / gpu_ms, "first_frame_wall_ms": cold_wall,
        "scene_upload_ms": upload_ms, "image_readback_ms": readback_ms,
        "wall_over_gpu_plus_readback": wall_ms / (gpu_ms + readback_ms),
        "steady_frames": repeat.max(1),
        "buffers_created_in_steady_frames": created_steady,
        "allocated_bytes": fastest.allocated_bytes,
    }))
}

/// What a bench frame's figures are read against, from the CPU's allocations: whether DKB's
/// budget holds every fragment, and of its covered pixels those its capture appends and those
/// whose k the network does not decide.
struct Shape {
    holds_all: bool,
    appended: usize,
    covered: usize,
    forced: usize,
}

fn frame_shape(
    name: &str,
    fl: &dhoit_runtime::fragment::FragmentLists,
    renderer: &Renderer,
    cpu: &[Option<dhoit_runtime::frame::Allocation>],
) -> Result<Shape> {
    use dhoit_runtime::gpu::Slots;
    let total = fl.fragment_count() as u64;
    let dkb_f = match Slots::for_method(
        Method::Dkb,
        &dhoit_runtime::frame::Allocation {
            exact: false,
            ..allocation_of(cpu, Method::Dkb)
                .clone()
                .ok_or_else(|| anyhow::anyhow!("{name}: DKB has no allocation"))?
        },
        &renderer.options,
    )? {
        Slots::Dkb(_, f) => f.fragments(),
        _ => None,
    };
    let holds_all = dkb_f.is_some_and(|f| f.holds(total));
    // The frame's smallest k (1 where F covers every covered pixel).
    let lo = dkb_f.map_or(0, |f| {
        dhoit_runtime::alloc::min_k(&fl.counts(), f.of(total))
    });
    // Covered pixels DKB's capture appends (k from its CPU twin, which the GPU's equals).
    let dkb_k = renderer.allocate(Method::Dkb)?.k;
    let appended = dkb_k
        .iter()
        .zip(fl.counts())
        .filter(|&(&k, n)| n > 0 && dhoit_runtime::composite::appends(k, n))
        .count();
    // Covered pixels whose k the network does not decide.
    let stats = dhoit_runtime::importance::pixel_stats(fl);
    let covered = stats.iter().filter(|st| st.count > 0).count();
    let forced = stats
        .iter()
        .filter(|st| {
            st.count > 0
                // DKB's tails are pooled: every pixel is a pair (alloc::allocate_pooled).
                && dhoit_runtime::mlp::forced(st.count, true, lo)
        })
        .count();
    Ok(Shape {
        holds_all,
        appended,
        covered,
        forced,
    })
}

/// What one scene's runs show side by side, printed and as the scene's JSON: DKB against VKB
/// and the A-buffer, and what each option saves.
fn scene_figures(
    name: &str,
    fl: &dhoit_runtime::fragment::FragmentLists,
    renderer: &Renderer,
    cpu: &[Option<dhoit_runtime::frame::Allocation>],
    methods: serde_json::Map<String, serde_json::Value>,
) -> Result<serde_json::Value> {
    let has_half = methods.contains_key("dkb_f16_math");
    // A run that did not happen (FKB's, where the budget refuses it) reads NaN.
    let of = |m: &str| methods.get(m).unwrap_or(&serde_json::Value::Null);
    let ms = |m: &str| of(m)["frame_gpu_ms"].as_f64().unwrap_or(f64::NAN);
    let ratio = ms("dkb") / ms("vkb");
    let small_ratio = ms("dkb_16-8") / ms("vkb");
    let over_abuffer = ms("dkb") / ms("abuffer");
    // One pass of one run, in ms (NaN when that run has no such pass).
    let pass = |m: &str, p: &str| of(m)["passes_ms"][p].as_f64().unwrap_or(f64::NAN);
    let imp = |m: &str| pass(m, "importance");
    let (skip, all) = (imp("dkb"), imp("dkb_no_skip"));
    let capture = |m: &str| pass(m, "capture");
    let (two_mode, inserted) = (capture("dkb"), capture("dkb_insertion_only"));
    let two_mode_where_all_fit = capture("dkb_two_mode_where_all_fit");
    let staged = imp("dkb_shared_weights");
    let looped = imp("dkb_array_network");
    let half_ms = if has_half {
        imp("dkb_f16_math")
    } else {
        f64::NAN
    };
    // The features pass where a frame draws it (three geometry passes: a frame after a cut).
    let (features, no_preload) = (
        pass("dkb_three_pass", "features"),
        pass("dkb_features_no_preload", "features"),
    );
    let count_ms = pass("vkb", "count");
    // DKB's geometry passes before its capture: its count (with its statistics) and, in a
    // frame of three, its features pass (not drawn when the budget holds every fragment: a
    // pass the frame did not record costs nothing).
    let geometry = |m: &str| {
        let or_0 = |ms: f64| if ms.is_nan() { 0.0 } else { ms };
        or_0(pass(m, "count")) + or_0(pass(m, "features"))
    };
    let count_first = geometry("dkb");
    let three_pass = geometry("dkb_three_pass");
    let fkb_slots = |m: &str| capture(m) + pass(m, "resolve");
    let (pixel_major, layer_major) = (fkb_slots("fkb"), fkb_slots("fkb_layer_major"));
    let Shape {
        holds_all,
        appended,
        covered,
        forced,
    } = frame_shape(name, fl, renderer, cpu)?;
    let figures = serde_json::json!({
        "scene": name, "fragments": fl.fragment_count(), "dkb_over_vkb": ratio,
        "dkb_16_8_over_vkb": small_ratio,
        "dkb_over_abuffer": over_abuffer, "methods": methods,
        "importance_skip_forced": {
            "forced_share_of_covered": forced as f64 / covered.max(1) as f64,
            "importance_ms": skip, "importance_ms_no_skip": all, "saved": 1.0 - skip / all,
        },
        "shared_weights": {"importance_ms": staged, "importance_ms_uniform": skip},
        "unrolled_network": {"importance_ms": skip, "importance_ms_array_loops": looped},
        "f16_math": {
            "importance_ms": half_ms, "importance_ms_f32": skip,
            "over_f32": half_ms / skip,
            "frame_gpu_ms": if has_half { ms("dkb_f16_math") } else { f64::NAN },
        },
        "features_pass": {
            "features_ms": features, "features_ms_no_preload": no_preload,
            "vkb_count_ms": count_ms, "over_vkb_count": features / count_ms,
            "count_and_features_over_vkb_count": three_pass / count_ms,
            "count_with_features_over_vkb_count": count_first / count_ms,
        },
        "dkb_geometry": {
            "budget_holds_every_fragment": holds_all,
            "geometry_ms": count_first,
            "geometry_ms_three_pass": three_pass,
        },
        "two_pass": {
            "frame_gpu_ms": ms("dkb"), "frame_gpu_ms_three_pass": ms("dkb_three_pass"),
            "three_pass_over_two_pass": ms("dkb_three_pass") / ms("dkb"),
        },
        "fkb_slot_layout": {"capture_resolve_ms_pixel_major": pixel_major, "capture_resolve_ms_layer_major": layer_major},
        "two_mode_capture": {
            "appended_share_of_covered": appended as f64 / covered.max(1) as f64,
            "capture_ms": two_mode, "capture_ms_insertion_only": inserted,
            "saved": 1.0 - two_mode / inserted,
            "capture_ms_two_mode_where_all_fit": two_mode_where_all_fit,
            "abuffer_store_ms": pass("abuffer", "store"),
        },
        "spread_search": {
            "allocation_ms": pass("dkb", "allocation"),
            "allocation_ms_spread": pass("dkb_spread_search", "allocation"),
        },
        "portable_capture": portable_capture(&ms, &pass),
    });
    print_figures(name, &figures);
    Ok(figures)
}

/// A bench scene's lines on stderr, from its figures ([`scene_figures`]'s JSON).
fn print_figures(name: &str, v: &serde_json::Value) {
    let f = |path: &[&str]| {
        path.iter()
            .fold(v, |v, k| &v[*k])
            .as_f64()
            .unwrap_or(f64::NAN)
    };
    let ms = |m: &str| f(&["methods", m, "frame_gpu_ms"]);
    let pass = |m: &str, p: &str| f(&["methods", m, "passes_ms", p]);
    let share = |x: f64| 100.0 * x;
    let skip = f(&["importance_skip_forced", "importance_ms"]);
    let importance_note = if skip.is_nan() {
        "importance pass not recorded (the budget holds every fragment)".to_string()
    } else {
        format!(
            "importance pass {skip:.2} ms skipping {:.1}% forced pixels, {:.2} ms without",
            share(f(&["importance_skip_forced", "forced_share_of_covered"])),
            f(&["importance_skip_forced", "importance_ms_no_skip"]),
        )
    };
    eprintln!(
        "GPU {name}: DKB/VKB frame time {:.2}, DKB/A-buffer {:.2}; DKB wall/GPU {:.2} steady (first frame {:.0} ms wall); {importance_note}",
        f(&["dkb_over_vkb"]),
        f(&["dkb_over_abuffer"]),
        f(&["methods", "dkb", "wall_over_gpu"]),
        f(&["methods", "dkb", "first_frame_wall_ms"]),
    );
    let capture = |k: &str| f(&["two_mode_capture", k]);
    eprintln!(
        "GPU {name}: DKB capture {:.2} ms appending {:.1}% of covered pixels, {:.2} ms inserting every fragment",
        capture("capture_ms"),
        share(capture("appended_share_of_covered")),
        capture("capture_ms_insertion_only"),
    );
    eprintln!(
        "GPU {name}: DKB importance {skip:.2} ms reading the weights from the uniform, {:.2} ms staging them in workgroup memory, {:.2} ms with mlp.wgsl's loops over an array",
        f(&["shared_weights", "importance_ms"]),
        f(&["unrolled_network", "importance_ms_array_loops"]),
    );
    eprintln!(
        "GPU {name}: DKB/VKB frame time with the 16-8 network {:.2}",
        f(&["dkb_16_8_over_vkb"])
    );
    let bytes = |m: &str| f(&["methods", m, "allocated_bytes"]);
    let features = f(&["features_pass", "features_ms"]);
    eprintln!(
        "GPU {name}: DKB frame {:.2} ms in {:.0} bytes with all its records in the pool at once, {:.2} ms in {:.0} bytes with them in up to 3 batches (features {:.2} ms)",
        ms("dkb"),
        bytes("dkb"),
        ms("dkb_records_in_batches"),
        bytes("dkb_records_in_batches"),
        pass("dkb_records_in_batches", "features"),
    );
    eprintln!(
        "GPU {name}: DKB frame {:.2} ms gathering its statistics with its count (two geometry passes), {:.2} ms in a features pass of its own (three: a frame after a cut; features {features:.2} ms)",
        ms("dkb"),
        ms("dkb_three_pass"),
    );
    eprintln!(
        "GPU {name}: DKB importance {:.2} ms with binary16 hidden layers (f16-math), {skip:.2} ms in f32",
        f(&["f16_math", "importance_ms"]),
    );
    eprintln!(
        "GPU {name}: DKB features {features:.2} ms ({:.2}x VKB's count) with the nearest words' load, {:.2} ms without",
        f(&["features_pass", "over_vkb_count"]),
        f(&["features_pass", "features_ms_no_preload"]),
    );
    let holds_all = v["dkb_geometry"]["budget_holds_every_fragment"] == true;
    eprintln!(
        "GPU {name}: DKB count with its statistics {:.2} ms, count and features pass {:.2} ms ({})",
        f(&["dkb_geometry", "geometry_ms"]),
        f(&["dkb_geometry", "geometry_ms_three_pass"]),
        if holds_all {
            "the budget holds every fragment: no statistics gathered"
        } else {
            "the budget truncates: statistics gathered"
        },
    );
    if holds_all {
        eprintln!(
            "GPU {name}: DKB capture {:.2} ms with the pipeline built for frames whose fragments all fit, {:.2} ms with the two-mode one (A-buffer store {:.2} ms)",
            capture("capture_ms"),
            capture("capture_ms_two_mode_where_all_fit"),
            capture("abuffer_store_ms"),
        );
    }
    eprintln!(
        "GPU {name}: FKB capture and resolve {:.2} ms pixel-major, {:.2} ms layer-major",
        f(&["fkb_slot_layout", "capture_resolve_ms_pixel_major"]),
        f(&["fkb_slot_layout", "capture_resolve_ms_layer_major"]),
    );
}

/// The k-buffers' frames and captures with 64-bit atomics (one pass) and with 32-bit ones (two
/// passes, the portable capture), from one scene's runs: `ms` a run's frame, `pass` one of its
/// passes (NaN where it has none).
fn portable_capture(
    ms: &dyn Fn(&str) -> f64,
    pass: &dyn Fn(&str, &str) -> f64,
) -> serde_json::Value {
    let mut out = serde_json::Map::new();
    for m in ["fkb", "vkb", "dkb"] {
        let portable = format!("{m}_portable");
        let two = pass(&portable, "capture depths") + pass(&portable, "capture colours");
        out.insert(
            m.into(),
            serde_json::json!({
                "frame_gpu_ms_wide": ms(m), "frame_gpu_ms_portable": ms(&portable),
                "frame_portable_over_wide": ms(&portable) / ms(m),
                "capture_ms_wide": pass(m, "capture"),
                "capture_ms_portable": two,
            }),
        );
    }
    serde_json::Value::Object(out)
}

/// Per-pass GPU times (timestamp queries) and whole-frame times per method: one cold frame,
/// warm-up frames for 0.25 s, then the medians of `repeat` steady-state frames (buffers reused,
/// the image read back); an error entry when no suitable adapter exists.
/// `partial` sees the report so far after each scene.
fn gpu_bench(
    loaded: &[(String, scene::Scene)],
    (w, h): (u32, u32),
    budget: Budget,
    (repeat, sequence): (usize, usize),
    partial: &mut dyn FnMut(&serde_json::Value),
) -> serde_json::Value {
    use dhoit_runtime::gpu::{Gpu, Slots};
    let gpu = match Gpu::new() {
        Ok(g) => g,
        Err(e) => {
            eprintln!("GPU bench skipped: {e}");
            return serde_json::json!({ "error": e.to_string() });
        }
    };
    eprintln!("GPU: {}", gpu.adapter());
    let nets = match bench_nets(&gpu) {
        Ok(n) => n,
        Err(e) => return serde_json::json!({ "error": e.to_string() }),
    };
    let summary = |scenes: &[serde_json::Value]| serde_json::json!({"adapter": gpu.adapter(), "width": w, "height": h, "budget": budget.to_string(), "weights": nets.weights, "weights_16_8": nets.small_weights, "scenes": scenes});
    let mut scenes = Vec::new();
    for (name, s) in loaded {
        let run = || -> Result<serde_json::Value> {
            let cam = Camera::orbit(s, 0, scene::DEFAULT_VIEWS, (w, h));
            let fl = raster::rasterize(s, &cam, (w, h))?;
            // Each method's k and F as `render --device gpu` gives them (Slots::for_method on
            // the CPU's allocation), so a byte budget benches the k render uses.
            let options = Options {
                weights: Some(&nets.mlp),
                // The methods' own passes are what the bench times.
                ..Options::new(budget, [1.0; 3]).always_approximate()
            };
            let renderer = Renderer::new(&fl, options);
            // A relative budget below a slot a pixel refuses FKB on this frame (a budget in
            // slots or bytes was refused before the first measurement): its error is its row,
            // and the other methods are measured. DKB and VKB must run.
            let mut methods = serde_json::Map::new();
            let mut cpu = Vec::new();
            for m in gpu_methods() {
                match renderer.allocate_for_gpu(m) {
                    Ok(a) => cpu.push(Some(a)),
                    Err(e) if m == Method::Fkb => {
                        methods
                            .insert(m.name().into(), serde_json::json!({"error": e.to_string()}));
                        cpu.push(None);
                    }
                    Err(e) => return Err(e.into()),
                }
            }
            for (label, method, frame) in bench_runs(&cpu) {
                if label == "dkb_f16_math" && nets.half.is_none() {
                    continue;
                }
                // The experiments measure the method's own pipeline even where the budget holds
                // every fragment (the method itself then renders the A-buffer).
                let unrouted = dhoit_runtime::frame::Allocation {
                    exact: frame.exact && label == method.name(),
                    ..frame.clone()
                };
                let slots = match Slots::for_method(method, &unrouted, &options)? {
                    Slots::Dkb(_, f) if label == "dkb_16-8" => Slots::Dkb(&nets.small, f),
                    Slots::Dkb(_, f) if label == "dkb_f16_math" => nets
                        .half
                        .as_ref()
                        .map_or(Slots::Exact, |m| Slots::Dkb(m, f)),
                    s => s,
                };
                let run = time_run(&gpu, &configure(label), (s, &cam), (w, h), slots, repeat)?;
                methods.insert(label.into(), run);
            }
            let mut figures = scene_figures(name, &fl, &renderer, &cpu, methods)?;
            if sequence > 0 {
                figures["sequence"] = crate::sequence::sequence_bench(
                    &gpu,
                    (name, s),
                    (w, h),
                    sequence,
                    budget,
                    &nets.mlp,
                )?;
            }
            Ok(figures)
        };
        match run() {
            Ok(v) => scenes.push(v),
            Err(e) => scenes.push(serde_json::json!({"scene": name, "error": e.to_string()})),
        }
        partial(&summary(&scenes));
    }
    eprint!("{}", frame_tables(&scenes));
    summary(&scenes)
}

/// `--summary`: the GPU bench's tables ([`frame_tables`]) under the command that ran and the
/// adapter, written whole (nothing where the GPU bench did not run).
fn write_summary(gpu: &serde_json::Value, path: Option<&std::path::Path>) -> Result<()> {
    let Some(path) = path else { return Ok(()) };
    let Some(scenes) = gpu["scenes"].as_array() else {
        anyhow::bail!(
            "no GPU tables for {}: {}",
            path.display(),
            gpu["error"].as_str().unwrap_or("the GPU bench did not run")
        );
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    let text = format!(
        "# GPU frames at {}x{}, budget {}\n\nWritten by `dhoit {}` on {}. GPU ms a frame, \
         medians of the steady frames (timestamps on that adapter: compare methods within a \
         run, as ratios).\n\n{}",
        gpu["width"],
        gpu["height"],
        gpu["budget"].as_str().unwrap_or("?"),
        args.join(" "),
        gpu["adapter"].as_str().unwrap_or("?"),
        frame_tables(scenes)
    );
    dhoit_runtime::tensors::write_atomic(path, text.as_bytes())?;
    Ok(())
}

/// The GPU bench's scenes as Markdown tables: each method's frame (GPU ms, median of the steady
/// frames) and DKB's against the A-buffer's and VKB's; where the scenes ran `--sequence`, each
/// method's orbit too.
fn frame_tables(scenes: &[serde_json::Value]) -> String {
    use std::fmt::Write;
    let ms = |v: &serde_json::Value, m: &str| v["methods"][m]["frame_gpu_ms"].as_f64();
    let cell = |x: Option<f64>, digits: usize| x.map_or("-".into(), |x| format!("{x:.digits$}"));
    let mut t = String::from(
        "| scene | A-buffer | VKB | DKB | DKB, 3 passes | DKB 16-8 | WBOIT | DKB/A-buffer | DKB/VKB | DKB 16-8/A-buffer | DKB 16-8/VKB |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for v in scenes {
        let Some(name) = v["scene"].as_str() else {
            continue;
        };
        if let Some(err) = v["error"].as_str() {
            let _ = writeln!(t, "| {name} | {err} | | | | | | | | | |");
            continue;
        }
        let (a, k, d, small) = (
            ms(v, "abuffer"),
            ms(v, "vkb"),
            ms(v, "dkb"),
            ms(v, "dkb_16-8"),
        );
        let ratio = |d: Option<f64>, x: Option<f64>| d.zip(x).map(|(d, x)| d / x);
        let _ = writeln!(
            t,
            "| {name} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            cell(a, 0),
            cell(k, 0),
            cell(d, 0),
            cell(ms(v, "dkb_three_pass"), 0),
            cell(small, 0),
            cell(ms(v, "wboit"), 0),
            cell(ratio(d, a), 2),
            cell(ratio(d, k), 2),
            cell(ratio(small, a), 2),
            cell(ratio(small, k), 2),
        );
    }
    let portable: Vec<_> = scenes
        .iter()
        .filter(|v| v["portable_capture"].is_object())
        .collect();
    if !portable.is_empty() {
        t.push_str(
            "\n| scene | method | frame ms, 64-bit atomics | frame ms, portable | portable/64-bit | capture ms, 64-bit | capture ms, portable (2 passes) |\n|---|---|---:|---:|---:|---:|---:|\n",
        );
        for v in portable {
            let name = v["scene"].as_str().unwrap_or("?");
            for m in ["fkb", "vkb", "dkb"] {
                let e = &v["portable_capture"][m];
                let f = |k: &str| e[k].as_f64();
                let _ = writeln!(
                    t,
                    "| {name} | {m} | {} | {} | {} | {} | {} |",
                    cell(f("frame_gpu_ms_wide"), 0),
                    cell(f("frame_gpu_ms_portable"), 0),
                    cell(f("frame_portable_over_wide"), 2),
                    cell(f("capture_ms_wide"), 1),
                    cell(f("capture_ms_portable"), 1),
                );
            }
        }
    }
    let orbits: Vec<_> = scenes
        .iter()
        .filter(|v| v["sequence"].is_object())
        .collect();
    if !orbits.is_empty() {
        t.push_str(
            "\n| scene | method | fps, 2 in flight | fps, 1 at a time | GPU ms | waits/frame | KiB | error | temporal change | error, fast camera | change, fast camera | over own A-buffer | exact |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for v in orbits {
            let name = v["scene"].as_str().unwrap_or("?");
            let Some(methods) = v["sequence"]["methods"].as_object() else {
                continue;
            };
            for (m, e) in methods {
                if let Some(err) = e["error"].as_str() {
                    let _ = writeln!(t, "| {name} | {m} | {err} | | | | | | | | | | |");
                    continue;
                }
                let f = |k: &str| e[k].as_f64();
                let n = |k: &str| e[k].as_u64().unwrap_or(0);
                let sci = |x: Option<f64>| x.map_or("-".into(), |x| format!("{x:.2e}"));
                let _ = writeln!(
                    t,
                    "| {name} | {m} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {}/{} | {}/{} |",
                    cell(f("fps_two_in_flight"), 2),
                    cell(f("fps_one_at_a_time"), 2),
                    cell(f("frame_gpu_ms"), 1),
                    cell(f("sync_waits_per_frame"), 0),
                    cell(f("allocated_bytes_median").map(|b| b / 1024.0), 0),
                    sci(f("mean_abs_error")),
                    sci(f("temporal_change")),
                    sci(e["fast"]["mean_abs_error"].as_f64()),
                    sci(e["fast"]["temporal_change"].as_f64()),
                    n("frames_over_own_abuffer_bytes"),
                    n("frames_counted"),
                    n("frames_exact"),
                    2 * n("frames"),
                );
            }
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::{frame_tables, write_summary};

    /// `--summary` writes the adapter, the frame and the tables under one heading, and where
    /// the GPU bench did not run it fails naming why, writing nothing.
    #[test]
    fn the_summary_is_the_tables_under_the_adapter() {
        let dir = std::env::temp_dir().join(format!("dhoit-bench-summary-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("frame.md");
        let gpu = serde_json::json!({"adapter": "a GPU", "width": 64, "height": 48,
            "budget": "25%", "scenes": [{"scene": "shells", "methods": {
                "abuffer": {"frame_gpu_ms": 10.0}, "vkb": {"frame_gpu_ms": 20.0},
                "dkb": {"frame_gpu_ms": 30.0}}}]});
        write_summary(&gpu, Some(&path)).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.starts_with("# GPU frames at 64x48, budget 25%\n"),
            "{text}"
        );
        assert!(text.contains(" on a GPU. "), "{text}");
        assert!(
            text.ends_with(&frame_tables(gpu["scenes"].as_array().unwrap())),
            "{text}"
        );
        let none = dir.join("none.md");
        let e = write_summary(&serde_json::json!({"error": "no adapter"}), Some(&none));
        assert!(e.unwrap_err().to_string().contains("no adapter"));
        assert!(!none.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The tables carry each scene's frame times and DKB's ratios as the JSON gives them, a
    /// dash where a method has no time, and a row per method of an orbit.
    #[test]
    fn frame_tables_hold_the_ratios_and_the_orbit() {
        let scenes = [
            serde_json::json!({"scene": "shells", "methods": {
                "abuffer": {"frame_gpu_ms": 200.0}, "vkb": {"frame_gpu_ms": 250.0},
                "dkb": {"frame_gpu_ms": 300.0}, "dkb_three_pass": {"frame_gpu_ms": 420.0},
                "dkb_16-8": {"frame_gpu_ms": 240.0}, "wboit": {"frame_gpu_ms": 50.0}},
                "portable_capture": {"fkb": {"frame_gpu_ms_wide": 100.0,
                    "frame_gpu_ms_portable": 130.0, "frame_portable_over_wide": 1.3,
                    "capture_ms_wide": 40.0, "capture_ms_portable": 70.0}},
                "sequence": {"methods": {"dkb": {"fps_two_in_flight": 3.5,
                    "fps_one_at_a_time": 3.25, "frame_gpu_ms": 280.0,
                    "sync_waits_per_frame": 0.0, "mean_abs_error": 0.001,
                    "temporal_change": 0.0002, "frames_over_own_abuffer_bytes": 3,
                    "frames_counted": 240, "frames_exact": 0, "frames": 120,
                    "allocated_bytes_median": 2048.0,
                    "fast": {"mean_abs_error": 0.002, "temporal_change": 0.0005}},
                    "mboit": {"error": "no FLOAT32_BLENDABLE"}}}}),
            serde_json::json!({"scene": "hair", "error": "refused"}),
        ];
        let t = frame_tables(&scenes);
        assert!(
            t.contains("| shells | 200 | 250 | 300 | 420 | 240 | 50 | 1.50 | 1.20 | 1.20 | 0.96 |"),
            "{t}"
        );
        assert!(t.contains("| hair | refused |"), "{t}");
        assert!(
            t.contains("| shells | fkb | 100 | 130 | 1.30 | 40.0 | 70.0 |")
                && t.contains("| shells | dkb | - | - | - | - | - |"),
            "{t}"
        );
        assert!(
            t.contains(
                "| shells | dkb | 3.50 | 3.25 | 280.0 | 0 | 2 | 1.00e-3 | 2.00e-4 | 2.00e-3 | 5.00e-4 | 3/240 | 0/240 |"
            ),
            "{t}"
        );
        assert!(
            t.contains("| shells | mboit | no FLOAT32_BLENDABLE |"),
            "{t}"
        );
    }
}
