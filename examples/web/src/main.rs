//! The page's frames rendered natively, on WebGPU's core device (no optional feature,
//! WebGPU's default limits: what a browser gives a page), for `scripts/web.sh test` to hold
//! the wasm build's frames on Dawn to. Writes each method's image into DIR (linear RGB f32
//! and sRGB RGBA8, raw, and a PNG) with a JSON summary.
//!
//!     cargo run --release -p dhoit-web -- DIR [--methods dkb,vkb,abuffer|all] [--scene particles]
//!         [--res 256x192] [--budget 25%]

#[cfg(not(target_arch = "wasm32"))]
fn main() {
    if let Err(e) = native::run() {
        eprintln!("dhoit-web: {e}");
        std::process::exit(1);
    }
}

#[cfg(target_arch = "wasm32")]
fn main() {}

#[cfg(not(target_arch = "wasm32"))]
mod native {
    use dhoit_runtime::frame::Method;
    use dhoit_web::{DEFAULT_BUDGET, Demo, METHODS, PAGE_METHODS, SCENES};
    use std::path::PathBuf;

    pub fn run() -> Result<(), Box<dyn std::error::Error>> {
        let mut args = std::env::args().skip(1);
        let mut methods = METHODS.to_vec();
        let (mut dir, mut scene, mut res, mut budget) = (
            None,
            SCENES[0].to_string(),
            "256x192".to_string(),
            DEFAULT_BUDGET.to_string(),
        );
        while let Some(a) = args.next() {
            let mut value = || args.next().ok_or(format!("{a} needs a value"));
            match a.as_str() {
                "--methods" => {
                    methods = match value()?.as_str() {
                        "all" => PAGE_METHODS.to_vec(),
                        list => list
                            .split(',')
                            .map(str::parse)
                            .collect::<dhoit_runtime::Result<Vec<Method>>>()?,
                    }
                }
                "--scene" => scene = value()?,
                "--res" => res = value()?,
                "--budget" => budget = value()?,
                "-h" | "--help" => {
                    println!(
                        "usage: dhoit-web DIR [--methods LIST|all] [--scene NAME] [--res WxH] [--budget B]\n\
                         renders the web page's frames (by default DKB, VKB and the A-buffer; \
                         `all`: every method a page runs) on WebGPU's core device and writes \
                         them into DIR"
                    );
                    return Ok(());
                }
                d if dir.is_none() && !d.starts_with('-') => dir = Some(PathBuf::from(d)),
                other => return Err(format!("unknown argument {other}").into()),
            }
        }
        let dir = dir.ok_or(
            "usage: dhoit-web DIR [--methods LIST|all] [--scene NAME] [--res WxH] [--budget B]",
        )?;
        let size = dhoit_runtime::raster::parse_resolution(&res)?;
        // WebGPU's core device, as a page gets it (without wgpu's check of indirect
        // dispatches, as dhoit's own devices: its passes write their own arguments).
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.flags
            .remove(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL);
        let instance = wgpu::Instance::new(desc.with_env());
        let adapter = pollster::block_on(instance.request_adapter(&Default::default()))?;
        let (device, queue) =
            pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                label: Some("dhoit (WebGPU core)"),
                required_features: wgpu::Features::empty(),
                required_limits: wgpu::Limits::default(),
                ..Default::default()
            }))?;
        let info = adapter.get_info();
        let adapter = info.name.clone();
        let mut demo = pollster::block_on(Demo::new(
            device, queue, &info, &methods, &scene, size, &budget,
        ))?;
        let views = pollster::block_on(demo.render())?;
        std::fs::create_dir_all(&dir)?;
        let reference = &views.last().expect("the A-buffer").image;
        let geometry: Vec<u8> = demo
            .geometry_bits()
            .iter()
            .flat_map(|w| w.to_le_bytes())
            .collect();
        std::fs::write(dir.join("geometry.u32"), geometry)?;
        let mut summary = Vec::new();
        for v in &views {
            let name = v.method.to_string();
            std::fs::write(dir.join(format!("{name}.rgba")), &v.rgba)?;
            let linear: Vec<u8> = v
                .image
                .data
                .iter()
                .flatten()
                .flat_map(|c| c.to_le_bytes())
                .collect();
            std::fs::write(dir.join(format!("{name}.f32")), linear)?;
            dhoit_runtime::image_io::write_image(&dir.join(format!("{name}.png")), &v.image)?;
            let error = v.image.mse(reference).sqrt();
            println!(
                "{name:>8}: {} B, exact {}, {} frame(s), RMSE vs the A-buffer {error:.5}",
                v.bytes, v.exact, v.frames
            );
            summary.push(serde_json::json!({
                "method": name, "bytes": v.bytes, "exact": v.exact, "frames": v.frames, "rmse": error,
                // The list hands its nodes out first come, first served: past its pool, which
                // fragments it keeps follows the order the GPU runs them in.
                "order_independent": v.method != Method::LinkedList || v.exact,
            }));
        }
        let json = serde_json::json!({
            "adapter": adapter, "scene": scene, "size": [size.0, size.1], "budget": budget,
            "methods": methods.iter().map(|m| m.to_string()).collect::<Vec<_>>(), "views": summary, "camera": demo.camera_bits(),
        });
        std::fs::write(
            dir.join("native.json"),
            serde_json::to_string_pretty(&json)?,
        )?;
        println!(
            "dhoit-web: {} on {adapter} -> {}",
            demo.scene(),
            dir.display()
        );
        Ok(())
    }
}
