//! `dhoit render`: one view of a scene with one method, on the CPU reference or the GPU.

use crate::args::{
    NetworkPrecision, ViewArgs, kmap_rgb8, load_scene, load_weights, rasterize_view,
};
use anyhow::Result;
use clap::{Args, ValueEnum};
use dhoit_runtime::budget::{Budget, format_bytes};
use dhoit_runtime::dump;
use dhoit_runtime::fragment::FragmentLists;
use dhoit_runtime::frame::{Equal, Frame, Method, Options, Renderer};
use dhoit_runtime::gpu::{Capture, FrameOptions, Gpu, Slots};
use dhoit_runtime::image_io;
use dhoit_runtime::scene::Scene;
use dhoit_runtime::tensors;
use std::path::PathBuf;

/// Where a frame is rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Device {
    /// The CPU reference renderer.
    Cpu,
    /// wgpu on the first adapter with the features the passes need.
    Gpu,
}

#[derive(Args)]
pub struct RenderArgs {
    /// Built-in scene name (optionally `name:seed`) or path to a .gltf/.glb file.
    #[arg(long, default_value = "particles")]
    scene: String,
    /// Which orbit view to render.
    #[arg(long, default_value_t = 0)]
    view: usize,
    #[command(flatten)]
    common: ViewArgs,
    #[command(flatten)]
    params: crate::args::MethodParams,
    /// Method (see `dhoit --help`).
    #[arg(long, default_value = "abuffer")]
    method: Method,
    /// Where to run (on the GPU every method runs: optimal and the greedy allocations have
    /// their k computed on the CPU, MLAB blends from the A-buffer).
    #[arg(long, value_enum, default_value_t = Device::Cpu)]
    device: Device,
    /// Memory budget: bytes (20MB, 40MiB), slots per pixel (2fpp) or a share of the frame's
    /// fragments (25%).
    #[arg(long, default_value = "2fpp", allow_hyphen_values = true)]
    budget: Budget,
    /// What the budget fixes: slots (F; bytes follow from the method's layout) or bytes (the
    /// memory M; F follows from the layout, a budget in slots or % sets M to what DKB spends on
    /// that F: its layout's bytes, or the exact A-buffer's where those are no more; WBOIT's and
    /// MBOIT's targets must fit M).
    #[arg(long, default_value = "slots")]
    equal: Equal,
    /// Render the k-buffer's approximation even where the exact A-buffer needs fewer bytes than
    /// the method would at this budget. Without it a k-buffer method never costs more than the
    /// exact answer: such a frame renders the A-buffer, exact, with its memory.
    #[arg(long)]
    always_approximate: bool,
    #[command(flatten)]
    network: NetworkPrecision,
    /// How the k-buffers (fkb, vkb, dkb, optimal, greedy) capture on the GPU: wide (64-bit
    /// atomics, one geometry pass) or portable (32-bit atomics alone, two passes: the capture
    /// a device without 64-bit atomics runs). The images are the same.
    #[arg(long, default_value = "wide", value_parser = parse_capture)]
    capture: Capture,
    /// Output image: sRGB .png, or .jpg (lossy, for sharing), clamped at white; or .exr, linear
    /// and unclamped (colours above white kept: emission).
    #[arg(long)]
    out: PathBuf,
    /// Also write the fragment dump (fragments.safetensors) into this directory.
    #[arg(long)]
    dump: Option<PathBuf>,
    /// Also write a heat map of the per-pixel k actually used (min(k, n)): .png or .jpg.
    #[arg(long)]
    kmap: Option<PathBuf>,
}

fn parse_capture(name: &str) -> std::result::Result<Capture, String> {
    Capture::parse(name).map_err(|e| e.to_string())
}

pub fn run(a: RenderArgs) -> Result<()> {
    let (method, budget) = (a.method, a.budget);
    // The images' formats before any work.
    image_io::encoding(&a.out)?;
    if let Some(k) = &a.kmap {
        image_io::encoding(k)?;
    }
    let weights = load_weights(&a.common, a.network.precision, method == Method::Dkb)?;
    let scene = load_scene(&a.scene, &a.common)?;
    let (fl, _) = rasterize_view(&scene, a.view, &a.common)?;
    if a.device == Device::Cpu {
        dhoit_runtime::frame::check_memory(&[method], &fl)?;
    }
    // Every output's folder before the frame: an output that cannot be written stops the
    // command before any other output is written.
    tensors::create_parent(&a.out)?;
    if let Some(path) = &a.kmap {
        tensors::create_parent(path)?;
    }
    if let Some(dir) = &a.dump {
        tensors::create_folder(dir)?;
    }
    let options = a.params.apply(
        Options {
            weights: weights.as_ref(),
            equal: a.equal,
            decision: dhoit_runtime::budget::Decision {
                exact_when_cheaper: !a.always_approximate,
                ..Default::default()
            },
            ..Options::new(budget, a.common.background)
        },
        &crate::args::view_camera(&scene, a.view, &a.common),
    );
    let renderer = Renderer::new(&fl, options);
    let mut gpu_fragments = None;
    let f = match a.device {
        Device::Cpu => renderer.render(method)?,
        Device::Gpu => {
            let (f, fragments) = render_on_gpu(&a, &scene, &fl, (&renderer, &options))?;
            gpu_fragments = fragments;
            f
        }
    };
    image_io::write_image(&a.out, &f.image)?;
    println!(
        "{}: k up to {}, {:.1}% of {} fragments captured, F(M) = {}, budget {}, allocated {} -> {}",
        method.name(),
        f.k.iter().max().unwrap_or(&0),
        100.0 * f.fragments_captured as f64 / f.fragments_total.max(1) as f64,
        f.fragments_total,
        f.budget_fragments,
        format_bytes(f.budget_bytes),
        format_bytes(f.allocated_bytes),
        a.out.display()
    );
    if f.exact && f.budget_fragments < f.fragments_total {
        println!(
            "{}: rendered the exact A-buffer, which needs {} here, no more than {} at this budget \
             (--always-approximate renders the approximation)",
            method.name(),
            format_bytes(f.allocated_bytes),
            method.name()
        );
    }
    if let Some(rep) = &f.optimal {
        println!(
            "optimal: total error {:.6e} ({}), lower bound {:.6e}, gap {:.3e}; greedy as printed {:.6e}, \
             increase-keyed {:.6e}",
            rep.total,
            rep.chosen,
            rep.lower_bound,
            rep.gap(),
            rep.greedy_paper_total,
            rep.greedy_increase_total
        );
    }
    if let Some(path) = &a.kmap {
        let (rgb, max) = kmap_rgb8(&fl, &f.k);
        image_io::write_rgb8(path, fl.size(), &rgb)?;
        println!("k map (0..{max}) -> {}", path.display());
    }
    if let Some(dir) = &a.dump {
        let d = dump::Dump {
            fragments: gpu_fragments.unwrap_or(fl),
            k: f.k,
            image: f.image,
            method: method.name().into(),
            budget_bytes: f.budget_bytes,
            budget_fragments: f.budget_fragments,
            background: a.common.background,
        };
        let path = dump::write(dir, &d)?;
        println!("dump -> {}", path.display());
    }
    Ok(())
}

/// `a`'s frame on the GPU: the CPU decides only what the GPU cannot (F, and k for FKB, MLAB
/// and the CPU-only allocations), nothing is composited on the CPU. With it, the GPU's
/// fragments where the frame read them back or a dump asks for them.
fn render_on_gpu(
    a: &RenderArgs,
    scene: &Scene,
    fl: &FragmentLists,
    (renderer, options): (&Renderer, &Options),
) -> Result<(Frame, Option<FragmentLists>)> {
    let method = a.method;
    let cpu = renderer.allocate_for_gpu(method)?;
    let gpu = Gpu::new()?;
    eprintln!("GPU: {}", gpu.adapter());
    let size = fl.size();
    let cam = crate::args::view_camera(scene, a.view, &a.common);
    let slots = Slots::for_method(method, &cpu, options)?;
    // The GPU counts first and decides on its own count whether the exact A-buffer is
    // no dearer, as the CPU did (the two counts can differ by an edge's fragment).
    let opts = FrameOptions {
        decision: options.decision,
        capture: a.capture,
        ..FrameOptions::default()
    };
    let g = gpu.render_with(&opts, scene, &cam, size, a.common.background, slots)?;
    match g.pass_ms.is_empty() {
        true => println!(
            "GPU passes: {} (untimed: the device has no timestamps)",
            g.passes.join(", ")
        ),
        false => {
            let passes: Vec<String> = g
                .pass_ms
                .iter()
                .map(|(n, ms)| format!("{n} {ms:.2} ms"))
                .collect();
            println!("GPU passes: {}", passes.join(", "));
        }
    }
    // The GPU's own k (VKB and DKB allocate on the device); what it captures follows.
    let k: Vec<u32> = match &g.slots {
        Some((_, bases, _)) => bases.windows(2).map(|b| b[1] - b[0]).collect(),
        None if g.exact => fl.counts(),
        None => cpu.k.clone(),
    };
    let captured = k.iter().zip(fl.counts()).map(|(&k, n)| k.min(n) as u64);
    let fragments = match g.fragments {
        Some(fr) => Some(fr),
        None if a.dump.is_some() => {
            gpu.render(
                scene,
                &cam,
                size,
                a.common.background,
                dhoit_runtime::gpu::Slots::Exact,
            )?
            .fragments
        }
        None => None,
    };
    let frame = Frame {
        method,
        image: g.image,
        fragments_captured: captured.sum(),
        k,
        budget_bytes: cpu.budget_bytes,
        budget_fragments: cpu.budget_fragments,
        allocated_bytes: g.allocated_bytes,
        fragments_total: fl.fragment_count() as u64,
        allocation_ms: cpu.allocation_ms,
        composite_ms: 0.0,
        optimal: cpu.optimal,
        exact: cpu.exact || g.exact,
    };
    Ok((frame, fragments))
}
