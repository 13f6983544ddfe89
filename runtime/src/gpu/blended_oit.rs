//! The blended methods in an application's own renderer: weighted blended OIT (WBOIT, one
//! geometry pass) and moment-based OIT (MBOIT, two), as engines ship them. They store no
//! fragment: each geometry pass adds into colour targets through the device's blending, so the
//! application's transparent pipeline writes dhoit's targets ([`BlendedOit::color_targets`])
//! in a render pass dhoit's attachments open ([`BlendedOit::color_attachments`]), and its
//! fragment entry returns what dhoit's pass returns: `oit_targets(position, colour)`, from the
//! module dhoit hands it ([`BlendedOit::store_module`]), which is dhoit's own pass
//! (`wboit_accumulate.wgsl`, `mboit_moments.wgsl`, `mboit_accumulate.wgsl`) with its fragment
//! entry made a function. The resolve is `blend_composite.wgsl`'s, over the application's image
//! onto its target. So the image is the one dhoit renders for the same draws: the blending adds
//! in the order the application submits its fragments, at the targets' precision (binary16
//! colour sums, an 8-bit revealage), as an engine's does.

use super::blend::{BlendPass, Target, mboit_fits, mboit_lacks, set_mboit, set_wboit};
use super::buffers::frame_texture;
use super::oit::AppSide;
use crate::composite::{MboitParams, WboitParams};
use crate::error::{Error, GpuError, Result};
use crate::wgsl::{Params, shaders};

/// One geometry pass of a blended method, which the application draws its transparent
/// geometry into (one pipeline a phase).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlendedPhase {
    /// MBOIT's first pass: each pixel's absorbance and its power moments.
    Moments,
    /// WBOIT's one pass, MBOIT's second: the colours, weighted (MBOIT's by the transmittance
    /// the moments admit in front of each fragment).
    Accumulate,
}

/// A phase's pass, its group layout, and where its targets sit among the method's.
struct PhasePass {
    phase: BlendedPhase,
    pass: BlendPass,
    layout: wgpu::BindGroupLayout,
    /// The method's targets this pass writes (indices into `BlendedOit::targets`).
    writes: Vec<usize>,
}

/// WBOIT or MBOIT on an application's device: its targets (each counted, the bytes of the
/// method's layout table, `budget::WBOIT` or `budget::mboit(n)`), the frame's parameters, and
/// the composite onto the application's target.
/// No readback, no wait.
///
/// ```
/// use dhoit_runtime::composite::WboitParams;
/// use dhoit_runtime::gpu::{self, BlendedOit, BlendedPhase};
///
/// let instance = wgpu::Instance::default();
/// let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
/// let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
///     required_features: gpu::required_features(),
///     required_limits: gpu::required_limits(),
///     ..Default::default()
/// }))
/// .unwrap();
/// // McGuire and Bavoil's eq. 10 (of the window depth: no planes needed).
/// let oit = BlendedOit::wboit(&device, &queue, (64, 48), WboitParams::default())?;
/// assert_eq!(oit.phases(), &[BlendedPhase::Accumulate]);
/// // Its transparent fragment shader: dhoit's module at group 1, then its own entry returning
/// // what oit_targets gives.
/// let src = oit.store_module(BlendedPhase::Accumulate, 1)
///     + "@fragment fn fs(@builtin(position) p: vec4<f32>) -> OitTargets {
///            return oit_targets(p, vec4<f32>(0.2, 0.4, 0.6, 0.5));
///        }";
/// let _module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
///     label: None,
///     source: wgpu::ShaderSource::Wgsl(src.into()),
/// });
/// // Its pipeline's fragment targets: oit.color_targets(phase); its layout [.., at 1
/// // oit.bind_group_layout(phase)]. Per frame: its opaque pass; a render pass with
/// // oit.color_attachments(phase) (they clear the targets), oit.bind_group(phase, &depth) at
/// // 1, its transparent draws; oit.resolve(&mut encoder, &under, &target, format, None).
/// assert_eq!(oit.color_targets(BlendedPhase::Accumulate).len(), 2);
/// # Ok::<(), dhoit_runtime::Error>(())
/// ```
pub struct BlendedOit {
    side: AppSide,
    phases: Vec<PhasePass>,
    /// Every target and its view: the first pass's, then the second's.
    targets: Vec<(Target, wgpu::TextureView)>,
    /// The frame's parameters, as last written (set_wboit rewrites them).
    params: std::sync::Mutex<Params>,
    params_buffer: wgpu::Buffer,
    /// MBOIT's absorbance of each 8-bit opacity (composite::mboit_absorbance_table).
    table: Option<wgpu::Buffer>,
    /// The composite's two targets (bindings 2 and 3 of blend_composite.wgsl).
    composite: [usize; 2],
}

impl BlendedOit {
    /// WBOIT for frames of `width` x `height` with weight function and planes `params`
    /// ([`WboitParams::default`]: eq. 10, of the window depth). Refuses a weight of the
    /// view-space distance without planes, a device that lacks what the passes need (named),
    /// and a frame without pixels.
    pub fn wboit(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        size: (u32, u32),
        params: WboitParams,
    ) -> Result<BlendedOit> {
        let side = AppSide::new(device, size, "WBOIT", ("blend_composite", "wboit_onto", 8))?;
        let mut p = frame_params(size);
        set_wboit(&mut p, &params)?;
        // The accumulation and the revealage.
        let passes = vec![(BlendedPhase::Accumulate, BlendPass::WBOIT)];
        Self::build(side, queue, p, passes, [0, 1])
    }

    /// MBOIT for frames of `width` x `height` with `params` (4, 6 or 8 power moments, the
    /// bias and the overestimation; [`MboitParams::default`] is the paper's for four).
    /// Refuses another count of moments, a device that cannot blend 32-bit floats
    /// (`FLOAT32_BLENDABLE`, which the application requests) or whose colour attachments
    /// cannot hold the moments pass's bytes a sample, and what [`BlendedOit::wboit`] refuses.
    pub fn mboit(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        size: (u32, u32),
        params: MboitParams,
    ) -> Result<BlendedOit> {
        let side = AppSide::new(device, size, "MBOIT", ("blend_composite", "mboit_onto", 8))?;
        let [moments, accumulate] = BlendPass::mboit(params.moments)?;
        if !mboit_fits(device, &moments) {
            return Err(GpuError::DeviceLacks {
                adapter: "the application's device".to_string(),
                missing: mboit_lacks(device, params.moments, &moments),
            }
            .into());
        }
        let mut p = frame_params(size);
        set_mboit(&mut p, &params);
        // The accumulation (the second pass's one target) and b_0 (the first's first).
        let accumulation = moments.targets.len();
        let passes = vec![
            (BlendedPhase::Moments, moments),
            (BlendedPhase::Accumulate, accumulate),
        ];
        Self::build(side, queue, p, passes, [accumulation, 0])
    }

    fn build(
        mut side: AppSide,
        queue: &wgpu::Queue,
        params: Params,
        passes: Vec<(BlendedPhase, BlendPass)>,
        composite: [usize; 2],
    ) -> Result<BlendedOit> {
        let mut targets = Vec::new();
        for (_, pass) in &passes {
            for &(t, _, _) in pass.targets {
                side.allocated += side.pixels() * t.texel_bytes();
                let usage =
                    wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
                let texture = frame_texture(&side.device, t.label, side.size(), t.format, usage);
                targets.push((t, texture.create_view(&Default::default())));
            }
        }
        let mboit = passes.iter().any(|(p, _)| *p == BlendedPhase::Moments);
        let table = mboit.then(|| {
            side.uniform(
                queue,
                "mboit.absorbance",
                bytemuck::cast_slice(&crate::composite::mboit_absorbance_table()),
            )
        });
        let params_buffer = side.uniform(queue, "params", bytemuck::bytes_of(&params));
        let mut first = 0;
        let phases = passes
            .into_iter()
            .map(|(phase, pass)| {
                // An accumulation reads every target the passes before it wrote (MBOIT's
                // moments; WBOIT's has none before it).
                let layout = phase_layout(&side.device, phase, first);
                let writes: Vec<usize> = (first..first + pass.targets.len()).collect();
                first += pass.targets.len();
                PhasePass {
                    phase,
                    pass,
                    layout,
                    writes,
                }
            })
            .collect();
        Ok(BlendedOit {
            side,
            phases,
            targets,
            params: std::sync::Mutex::new(params),
            params_buffer,
            table,
            composite,
        })
    }

    fn phase(&self, phase: BlendedPhase) -> &PhasePass {
        self.phases
            .iter()
            .find(|p| p.phase == phase)
            .unwrap_or_else(|| panic!("{phase:?} is not a pass of {}", self.side.name()))
    }

    /// The geometry passes the application draws its transparent geometry into, in order:
    /// WBOIT's accumulation; MBOIT's moments, then its accumulation.
    pub fn phases(&self) -> &'static [BlendedPhase] {
        if self.phases.len() == 2 {
            &[BlendedPhase::Moments, BlendedPhase::Accumulate]
        } else {
            &[BlendedPhase::Accumulate]
        }
    }

    /// The WGSL the application's fragment shader for `phase` starts with: dhoit's pass, its
    /// bindings at `group`, the type `OitTargets` and `fn oit_targets(frag_coord: vec4<f32>,
    /// color: vec4<f32>) -> OitTargets`, which the application's fragment entry (`->
    /// OitTargets`) returns with its fragment's `@builtin(position)` and straight colour (it
    /// discards the fragments dhoit's pass discards: behind the opaque depth, or of zero 8-bit
    /// opacity). It declares dhoit's names (`Params`, `VertexOut`, `params`, `Targets`,
    /// `fs_main` among them): the application's own must differ. Panics for a phase the method
    /// lacks ([`BlendedOit::phases`]).
    pub fn store_module(&self, phase: BlendedPhase, group: u32) -> String {
        let pass = &self.phase(phase).pass;
        shaders::application_blend_pass(pass.pass, pass.entry, group).expect("a blended pass")
    }

    /// The layout of `phase`'s group, for the application's pipeline layout of that phase.
    pub fn bind_group_layout(&self, phase: BlendedPhase) -> &wgpu::BindGroupLayout {
        &self.phase(phase).layout
    }

    /// The colour targets of the application's pipeline for `phase`: dhoit's formats and
    /// blend states, at the locations `OitTargets` writes.
    pub fn color_targets(&self, phase: BlendedPhase) -> Vec<Option<wgpu::ColorTargetState>> {
        self.phase(phase).pass.color_targets()
    }

    /// The colour attachments of the application's render pass for `phase`: dhoit's targets,
    /// cleared (the revealage to 1, the rest to 0) and stored. The pass needs no depth
    /// attachment (the module tests the opaque depth); it may have one, read-only.
    pub fn color_attachments(
        &self,
        phase: BlendedPhase,
    ) -> Vec<Option<wgpu::RenderPassColorAttachment<'_>>> {
        let p = self.phase(phase);
        p.writes
            .iter()
            .zip(p.pass.targets)
            .map(|(&i, &(_, _, clear))| {
                Some(wgpu::RenderPassColorAttachment {
                    view: &self.targets[i].1,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(clear),
                        store: wgpu::StoreOp::Store,
                    },
                })
            })
            .collect()
    }

    /// The group the application sets for `phase`'s draws, with its opaque depth (a depth
    /// texture of the frame's size with `TEXTURE_BINDING` usage, written by its opaque pass;
    /// cleared to 1 where it has none) as the occluder. Made once and kept while the depth
    /// texture lives.
    pub fn bind_group(
        &self,
        phase: BlendedPhase,
        opaque_depth: &wgpu::TextureView,
    ) -> wgpu::BindGroup {
        let p = self.phase(phase);
        let mut entries = vec![
            wgpu::BindGroupEntry {
                binding: 14,
                resource: self.params_buffer.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 15,
                resource: wgpu::BindingResource::TextureView(opaque_depth),
            },
        ];
        match (phase, &self.table) {
            (BlendedPhase::Moments, Some(table)) => entries.push(wgpu::BindGroupEntry {
                binding: 0,
                resource: table.as_entire_binding(),
            }),
            (BlendedPhase::Accumulate, Some(_)) => {
                // The moments pass's targets, read.
                let moments = &self.phase(BlendedPhase::Moments).writes;
                entries.extend(
                    moments
                        .iter()
                        .enumerate()
                        .map(|(b, &i)| wgpu::BindGroupEntry {
                            binding: b as u32,
                            resource: wgpu::BindingResource::TextureView(&self.targets[i].1),
                        }),
                );
            }
            _ => {}
        }
        self.side
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(&format!("dhoit {} {phase:?}", self.side.name())),
                layout: &p.layout,
                entries: &entries,
            })
    }

    /// WBOIT's weight function and planes for the frames submitted after it (the
    /// application's camera may move its planes: eqs. 7-9 read the view-space distance),
    /// refused as [`BlendedOit::wboit`] refuses them, and by MBOIT.
    pub fn set_wboit(&self, queue: &wgpu::Queue, params: WboitParams) -> Result<()> {
        if self.table.is_some() {
            return Err(Error::Invalid(
                "MBOIT has no weight function: set_wboit is WBOIT's".to_string(),
            ));
        }
        let mut p = self.params.lock().unwrap_or_else(|e| e.into_inner());
        set_wboit(&mut p, &params)?;
        queue.write_buffer(&self.params_buffer, 0, bytemuck::bytes_of(&*p));
        Ok(())
    }

    /// Bytes of what the method created: its layout table's (`budget::WBOIT`,
    /// `budget::mboit(n)`).
    pub fn allocated_bytes(&self) -> u64 {
        self.side.allocated
    }

    /// Composites the frame's targets over the application's image `under` (a float-sampled
    /// texture of the frame's size: its opaque pass) onto `target`, a storage texture of the
    /// frame's size in one of [`super::TARGET_FORMATS`], recorded after its last phase's draws.
    /// `timestamps`, where given, time the composite's compute pass.
    pub fn resolve(
        &self,
        enc: &mut wgpu::CommandEncoder,
        under: &wgpu::TextureView,
        target: &wgpu::TextureView,
        format: wgpu::TextureFormat,
        timestamps: Option<wgpu::ComputePassTimestampWrites>,
    ) -> Result<()> {
        let [first, second] = self.composite.map(|i| &self.targets[i].1);
        self.side.resolve_with(
            enc,
            &[(0, &self.params_buffer)],
            &[(2, first), (3, second)],
            (under, target, format),
            timestamps,
        )
    }
}

/// The frame's parameters as the blended passes and the composite read them: its size.
fn frame_params((width, height): (u32, u32)) -> Params {
    let mut p: Params = bytemuck::Zeroable::zeroed();
    p.width = width;
    p.height = height;
    p.pixels = width * height;
    p
}

/// A phase's group layout: the parameters (14) and the opaque depth (15); the moments pass its
/// absorbance table (0), an accumulation the `reads` targets written before it (0..), as
/// textures.
fn phase_layout(device: &wgpu::Device, phase: BlendedPhase, reads: usize) -> wgpu::BindGroupLayout {
    let uniform = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let texture = |binding, sample_type| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    };
    let mut entries = vec![uniform(14), texture(15, wgpu::TextureSampleType::Depth)];
    match phase {
        BlendedPhase::Moments => entries.push(uniform(0)),
        BlendedPhase::Accumulate => {
            let float = wgpu::TextureSampleType::Float { filterable: false };
            entries.extend((0..reads as u32).map(|b| texture(b, float)));
        }
    }
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(&format!("dhoit {phase:?}")),
        entries: &entries,
    })
}
