//! Every pipeline dhoit's renderer builds for the methods WebGPU runs (all but MBOIT, which
//! needs float32-blendable), written as JSON for a WebGPU implementation to create (`make
//! webgpu` hands them to Dawn, Chrome's WebGPU: scripts/webgpu_pipelines.mjs). It renders each such method once on WebGPU's core device
//! (`Gpu::portable`: no feature, wgpu's default limits), the k-buffers once more on tinted glass
//! (their tint pass), and records what it built.
//!
//!     cargo run --release --example webgpu_pipelines -- OUT.json

use dhoit_runtime::gpu::{FrameOptions, Gpu, Slots, record_pipelines};
use dhoit_runtime::scene::{self, Camera, Opacity};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .ok_or("usage: webgpu_pipelines OUT.json")?;
    let gpu = Gpu::portable()?;
    eprintln!("WebGPU core device on {}", gpu.adapter());
    let s = scene::load("particles", Opacity::default())?;
    let glass = scene::Scene {
        glass: scene::Glass::Tinted,
        ..scene::load("windows", Opacity::Native)?
    };
    let (w, h) = (64, 48);
    let cam = Camera::orbit(&s, 0, scene::DEFAULT_VIEWS, (w, h));
    let k: Vec<u32> = (0..w * h).map(|p| p % 4).collect();
    let mlp = dhoit_runtime::mlp::Mlp::random(1);
    let methods: [(&str, Slots); 11] = [
        ("dkb", Slots::Dkb(&mlp, 2000u64.into())),
        ("vkb", Slots::Vkb(Default::default(), 2000u64.into())),
        ("abuffer", Slots::Exact),
        ("mlab", Slots::Mlab(4)),
        ("fkb", Slots::Uniform(2)),
        ("uploaded k", Slots::PerPixel(&k)),
        (
            "linked list",
            Slots::LinkedList {
                nodes: 4096,
                sorted: 4,
            },
        ),
        ("wboit", Slots::Wboit(Default::default())),
        ("predict", Slots::Exact),
        // The k-buffers' tint pass, on a scene of tinted glass.
        ("tinted fkb", Slots::Uniform(2)),
        ("tinted dkb", Slots::Dkb(&mlp, 2000u64.into())),
    ];
    let (result, pipelines) = record_pipelines(|| -> dhoit_runtime::Result<Vec<String>> {
        // The renderer's own passes, built with the device.
        let mut ran = vec!["the device's passes".to_string()];
        let g = gpu.fork();
        for (name, slots) in methods {
            if name == "predict" {
                // The network's inference pass (dhoit predict on the GPU).
                g.predict(&mlp, &[[0.5; 12]; 4])?;
            } else {
                // Each method's own passes, even where the exact A-buffer would be no dearer.
                let opts = FrameOptions::default().always_approximate();
                match name.strip_prefix("tinted ") {
                    Some(_) => {
                        let cam = Camera::orbit(&glass, 0, scene::DEFAULT_VIEWS, (w, h));
                        g.render_with(&opts, &glass, &cam, (w, h), [1.0; 3], slots)?
                    }
                    None => g.render_with(&opts, &s, &cam, (w, h), [1.0; 3], slots)?,
                };
            }
            ran.push(name.to_string());
        }
        Ok(ran)
    });
    let ran = result?;
    // Pipelines built before recording began (the device's own, at Gpu::portable) are built
    // again on a fresh device inside the recording.
    let (built, device_pipelines) = record_pipelines(Gpu::portable);
    built?;
    let all: Vec<_> = device_pipelines.into_iter().chain(pipelines).collect();
    let json = serde_json::json!({
        "adapter": gpu.adapter(),
        "methods": ran,
        "pipelines": all,
    });
    std::fs::write(&out, serde_json::to_string_pretty(&json)?)?;
    eprintln!("{} pipelines written to {out}", all.len());
    Ok(())
}
