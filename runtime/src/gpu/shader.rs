//! Building shader modules and pipelines: each from its WGSL (checked by naga as wgpu builds
//! it), counted ([`pipelines_built`]) and, where [`record_pipelines`] runs, recorded as WebGPU
//! takes it. What [`super::pipelines`] and the allocation's passes build their passes with.

use crate::wgsl::shaders;

pub(super) fn module(device: &wgpu::Device, name: &str) -> wgpu::ShaderModule {
    module_from(device, name, shaders::source(name).expect("known pass"))
}

thread_local! {
    /// Shader modules and pipelines built on this thread ([`pipelines_built`]).
    static BUILT: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Counts one shader module or pipeline built.
pub(super) fn note_built() {
    BUILT.with(|b| b.set(b.get() + 1));
}

/// Shader modules and pipelines dhoit has built on this thread so far, on any device: a
/// renderer made from a [`super::Gpu`] shares its passes ([`super::Gpu::fork`]), so making a
/// second renderer of a method on it builds none.
pub fn pipelines_built() -> u64 {
    BUILT.with(|b| b.get())
}

pub(super) fn module_from(device: &wgpu::Device, label: &str, src: String) -> wgpu::ShaderModule {
    note_built();
    let recorded = RECORDING
        .with(|r| r.borrow().is_some())
        .then(|| src.clone());
    let m = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    });
    if let Some(src) = recorded {
        RECORDING.with(|r| {
            if let Some(r) = r.borrow_mut().as_mut() {
                r.modules.push((m.clone(), src));
            }
        });
    }
    m
}

thread_local! {
    /// What [`record_pipelines`] collects while it runs.
    static RECORDING: std::cell::RefCell<Option<Recording>> = const { std::cell::RefCell::new(None) };
}

#[derive(Default)]
struct Recording {
    modules: Vec<(wgpu::ShaderModule, String)>,
    pipelines: Vec<serde_json::Value>,
}

/// Runs `f` and returns, beside its value, every pipeline dhoit built on this thread meanwhile,
/// as WebGPU's `createComputePipeline` and `createRenderPipeline` take them (JSON: its label,
/// its WGSL, its entry points, depth state and colour targets in WebGPU's names, layout `auto`):
/// what a WebGPU implementation must accept to run what `f` ran (`make webgpu` hands them to
/// Dawn).
pub fn record_pipelines<T>(f: impl FnOnce() -> T) -> (T, Vec<serde_json::Value>) {
    RECORDING.with(|r| *r.borrow_mut() = Some(Recording::default()));
    let out = f();
    let recorded = RECORDING
        .with(|r| r.borrow_mut().take())
        .unwrap_or_default();
    (out, recorded.pipelines)
}

/// Notes a pipeline built from module `m` where [`record_pipelines`] runs: `stages` its entry
/// points and fixed-function state (WebGPU's descriptor less the module and layout).
pub(super) fn record_pipeline(label: &str, m: &wgpu::ShaderModule, stages: serde_json::Value) {
    RECORDING.with(|r| {
        let mut r = r.borrow_mut();
        let Some(r) = r.as_mut() else { return };
        let code = r
            .modules
            .iter()
            .find(|(x, _)| x == m)
            .map(|(_, s)| s.clone());
        r.pipelines
            .push(serde_json::json!({ "label": label, "code": code, "stages": stages }));
    });
}

/// A wgpu enum's WebGPU name: its variant in kebab case (`OneMinusSrcAlpha`:
/// `one-minus-src-alpha`), or for a texture format in lower case (`Rgba16Float`:
/// `rgba16float`).
pub(super) fn webgpu_name(debug: String, format: bool) -> String {
    if format {
        return debug.to_lowercase();
    }
    let mut out = String::new();
    for (i, c) in debug.chars().enumerate() {
        if c.is_uppercase() && i > 0 {
            out.push('-');
        }
        out.push(c.to_ascii_lowercase());
    }
    out
}

pub(super) fn blend_json(b: &wgpu::BlendComponent) -> serde_json::Value {
    let n = |d: String| webgpu_name(d, false);
    serde_json::json!({
        "srcFactor": n(format!("{:?}", b.src_factor)),
        "dstFactor": n(format!("{:?}", b.dst_factor)),
        "operation": n(format!("{:?}", b.operation)),
    })
}

pub(super) fn compute_pipeline(
    device: &wgpu::Device,
    label: &str,
    m: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    note_built();
    record_pipeline(label, m, serde_json::json!({ "compute": entry }));
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: None,
        module: m,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// A buffer binding of a compute pass's explicit layout (the allocation's, the network's).
pub(super) fn compute_buffer_entry(
    binding: u32,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}
