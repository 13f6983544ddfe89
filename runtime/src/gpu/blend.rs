//! The blended methods, as engines ship them: no slot, no list, no sort; targets the device's
//! blending adds into, then a composite. WBOIT (McGuire and Bavoil): `wboit_accumulate.wgsl`
//! (one geometry pass into an RGBA16F accumulation and an R8 revealage) -> `blend_composite.wgsl`
//! (`wboit`). MBOIT (Munstermann et al.): `mboit_moments.wgsl` (b_0 into R32F, four power
//! moments into RGBA32F) -> `mboit_accumulate.wgsl` (the transmittance-weighted colour into
//! RGBA16F) -> `blend_composite.wgsl` (`mboit`). Each frame creates exactly the targets its
//! layout table lists ([`crate::budget::WBOIT`], [`crate::budget::MBOIT`]), their bytes taken
//! from their formats.
//!
//! Twins: `composite::wboit_blended` and `composite::mboit_blended`, which add in submission
//! order (the order a device blends one draw's fragments in) at the targets' precision: binary16
//! colour sums rounded after each add, an 8-bit revealage product, f32 moments. So the image
//! depends on the submission order by that rounding, as an engine's does.

use super::Recording;
use super::bindings::blend_composite;
use super::passes::{Phase, Resolve, at, view_at};
use crate::composite::{MboitParams, WboitParams};
use crate::error::{GpuError, Result};
use crate::wgsl::Params;

/// A blended method's render target: its label in the layout tables and its format (whose
/// texel size is the bytes a pixel the table counts).
#[derive(Clone, Copy, Debug)]
pub(super) struct Target {
    pub(super) label: &'static str,
    pub(super) format: wgpu::TextureFormat,
}

impl Target {
    pub(super) const WBOIT_ACCUMULATION: Target = Target {
        label: "wboit.accumulation",
        format: wgpu::TextureFormat::Rgba16Float,
    };
    pub(super) const WBOIT_REVEALAGE: Target = Target {
        label: "wboit.revealage",
        format: wgpu::TextureFormat::R8Unorm,
    };
    /// Where the frame's glass is tinted, WBOIT's revealage in A beside the product of the
    /// transmittances per channel in RGB (McGuire and Bavoil's coloured transmission).
    pub(super) const WBOIT_TRANSMITTANCE: Target = Target {
        label: "wboit.transmittance",
        format: wgpu::TextureFormat::Rgba8Unorm,
    };
    pub(super) const MBOIT_B0: Target = Target {
        label: "mboit.b0",
        format: wgpu::TextureFormat::R32Float,
    };
    pub(super) const MBOIT_MOMENTS: Target = Target {
        label: "mboit.moments",
        format: wgpu::TextureFormat::Rgba32Float,
    };
    /// b_5 and b_6 of six power moments.
    pub(super) const MBOIT_EXTRA6: Target = Target {
        label: "mboit.extra",
        format: wgpu::TextureFormat::Rg32Float,
    };
    /// b_5..b_8 of eight power moments.
    pub(super) const MBOIT_EXTRA8: Target = Target {
        label: "mboit.extra",
        format: wgpu::TextureFormat::Rgba32Float,
    };
    /// Where the frame's glass is tinted, the product of the fragments' transmittances per
    /// channel (RGB), which MBOIT sees the background through.
    pub(super) const MBOIT_TRANSMITTANCE: Target = Target {
        label: "mboit.transmittance",
        format: wgpu::TextureFormat::Rgba8Unorm,
    };
    pub(super) const MBOIT_ACCUMULATION: Target = Target {
        label: "mboit.accumulation",
        format: wgpu::TextureFormat::Rgba16Float,
    };
    #[cfg(test)]
    pub(super) const ALL: [Target; 5] = [
        Target::WBOIT_ACCUMULATION,
        Target::WBOIT_REVEALAGE,
        Target::MBOIT_B0,
        Target::MBOIT_MOMENTS,
        Target::MBOIT_ACCUMULATION,
    ];

    /// Bytes of one texel.
    pub(super) fn texel_bytes(self) -> u64 {
        self.format.block_copy_size(None).expect("a colour format") as u64
    }
}

/// Additive blending (`src + dst`) of every channel.
pub(super) const ADD: wgpu::BlendState = wgpu::BlendState {
    color: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    },
    alpha: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    },
};

/// `dst (1 - src)`: the revealage's product of `1 - alpha`.
pub(super) const MULTIPLY_BY_ONE_MINUS: wgpu::BlendState = wgpu::BlendState {
    color: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::Zero,
        dst_factor: wgpu::BlendFactor::OneMinusSrc,
        operation: wgpu::BlendOperation::Add,
    },
    alpha: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::Zero,
        dst_factor: wgpu::BlendFactor::OneMinusSrc,
        operation: wgpu::BlendOperation::Add,
    },
};

/// Cleared to 0, or to 1 (the revealage).
const ZERO: wgpu::Color = wgpu::Color::TRANSPARENT;
const ONE: wgpu::Color = wgpu::Color::WHITE;

/// One of a blended method's geometry passes: its WGSL pass and fragment entry, and the
/// targets it writes in the order of its entry's locations, each with its blend and the value
/// it is cleared to. dhoit's own frames and an application's ([`super::BlendedOit`]) draw
/// through the same.
#[derive(Clone, Copy, Debug)]
pub(super) struct BlendPass {
    pub(super) pass: &'static str,
    pub(super) entry: &'static str,
    pub(super) targets: &'static [(Target, wgpu::BlendState, wgpu::Color)],
}

impl BlendPass {
    /// WBOIT's one pass: the accumulation adds, the revealage multiplies by `1 - alpha`.
    pub(super) const WBOIT: BlendPass = BlendPass {
        pass: "wboit_accumulate",
        entry: "fs_main",
        targets: &[
            (Target::WBOIT_ACCUMULATION, ADD, ZERO),
            (Target::WBOIT_REVEALAGE, MULTIPLY_BY_ONE_MINUS, ONE),
        ],
    };

    /// WBOIT's pass where the frame's glass is tinted: the revealage (A) and the product of the
    /// transmittances (RGB) multiply in one RGBA8 target ([`Target::WBOIT_TRANSMITTANCE`]).
    pub(super) const WBOIT_TINTED: BlendPass = BlendPass {
        pass: "wboit_accumulate",
        entry: "fs_tinted",
        targets: &[
            (Target::WBOIT_ACCUMULATION, ADD, ZERO),
            (Target::WBOIT_TRANSMITTANCE, MULTIPLY_BY_ONE_MINUS, ONE),
        ],
    };

    /// MBOIT's moments pass and its accumulation for `moments` power moments (4, 6 or 8; six
    /// and eight add a third target of the moments pass). Another count is refused.
    pub(super) fn mboit(moments: u32) -> Result<[BlendPass; 2]> {
        Self::mboit_for(moments, false)
    }

    /// [`BlendPass::mboit`], and where `tinted` (the frame's glass tinted) the moments pass
    /// multiplying the product of the transmittances into one more target, RGBA8, last
    /// ([`Target::MBOIT_TRANSMITTANCE`]).
    pub(super) fn mboit_for(moments: u32, tinted: bool) -> Result<[BlendPass; 2]> {
        type Out = (Target, wgpu::BlendState, wgpu::Color);
        const B0: Out = (Target::MBOIT_B0, ADD, ZERO);
        const MOMENTS: Out = (Target::MBOIT_MOMENTS, ADD, ZERO);
        const E6: Out = (Target::MBOIT_EXTRA6, ADD, ZERO);
        const E8: Out = (Target::MBOIT_EXTRA8, ADD, ZERO);
        const T: Out = (Target::MBOIT_TRANSMITTANCE, MULTIPLY_BY_ONE_MINUS, ONE);
        let (targets, entry): (&'static [_], _) = match (moments, tinted) {
            (4, false) => (&[B0, MOMENTS], "fs_main"),
            (6, false) => (&[B0, MOMENTS, E6], "fs_main6"),
            (8, false) => (&[B0, MOMENTS, E8], "fs_main8"),
            (4, true) => (&[B0, MOMENTS, T], "fs_main"),
            (6, true) => (&[B0, MOMENTS, E6, T], "fs_main6"),
            (8, true) => (&[B0, MOMENTS, E8, T], "fs_main8"),
            (n, _) => {
                return Err(crate::error::Error::Invalid(format!(
                    "MBOIT takes 4, 6 or 8 power moments, not {n}"
                )));
            }
        };
        let moments_entry = match (moments == 4, tinted) {
            (true, false) => "fs_main",
            (false, false) => "fs_extra",
            (true, true) => "fs_tinted",
            (false, true) => "fs_extra_tinted",
        };
        Ok([
            BlendPass {
                pass: "mboit_moments",
                entry: moments_entry,
                targets,
            },
            BlendPass {
                pass: "mboit_accumulate",
                entry,
                targets: &[(Target::MBOIT_ACCUMULATION, ADD, ZERO)],
            },
        ])
    }

    /// The pipeline's colour targets.
    pub(super) fn color_targets(&self) -> Vec<Option<wgpu::ColorTargetState>> {
        self.targets
            .iter()
            .map(|&(t, blend, _)| {
                Some(wgpu::ColorTargetState {
                    format: t.format,
                    blend: Some(blend),
                    write_mask: wgpu::ColorWrites::ALL,
                })
            })
            .collect()
    }

    /// Bytes a sample of its colour attachments (a device's
    /// `max_color_attachment_bytes_per_sample` must hold them).
    pub(super) fn bytes_per_sample(&self) -> u64 {
        self.targets.iter().map(|t| t.0.texel_bytes()).sum()
    }
}

/// What `device` lacks for MBOIT with `moments` power moments: blending into 32-bit floats,
/// or colour attachments that hold the moments pass's bytes a sample.
pub(super) fn mboit_lacks(device: &wgpu::Device, moments: u32, pass: &BlendPass) -> String {
    if !device
        .features()
        .contains(wgpu::Features::FLOAT32_BLENDABLE)
    {
        "FLOAT32_BLENDABLE (MBOIT adds its moments into 32-bit float targets)".to_string()
    } else {
        format!(
            "max_color_attachment_bytes_per_sample {} for {moments} power moments (it has \
             {}; open the device with the adapter's limits)",
            pass.bytes_per_sample(),
            device.limits().max_color_attachment_bytes_per_sample
        )
    }
}

/// Whether `device` can draw MBOIT's moments pass `pass`.
pub(super) fn mboit_fits(device: &wgpu::Device, pass: &BlendPass) -> bool {
    device
        .features()
        .contains(wgpu::Features::FLOAT32_BLENDABLE)
        && pass.bytes_per_sample() <= device.limits().max_color_attachment_bytes_per_sample as u64
}

/// WBOIT's weight function and planes in the frame's parameters, refused where the function
/// reads a distance the planes cannot give (`WboitParams::check`).
pub(super) fn set_wboit(params: &mut Params, w: &WboitParams) -> Result<()> {
    w.check()?;
    params.wboit_weight = w.weight.code();
    params.wboit_near = w.near;
    params.wboit_far = w.far;
    Ok(())
}

/// MBOIT's bias and overestimation in the frame's parameters.
pub(super) fn set_mboit(params: &mut Params, m: &MboitParams) {
    params.mboit_bias = m.bias;
    params.mboit_overestimation = m.overestimation;
}

impl Recording<'_, '_, '_> {
    /// WBOIT's accumulation and composite.
    pub(super) fn wboit(&mut self, size: (u32, u32)) -> Result<()> {
        let passes = self.passes;
        let pass = match self.words.tints() {
            true => BlendPass::WBOIT_TINTED,
            false => BlendPass::WBOIT,
        };
        let targets: Vec<_> = pass
            .targets
            .iter()
            .map(|&(t, _, clear)| {
                (
                    self.fb.target((t.label, t.format, t.texel_bytes()), size),
                    clear,
                )
            })
            .collect();
        let fb = &mut self.fb;
        let attachments: Vec<_> = targets.iter().map(|(v, c)| (v, *c)).collect();
        let (accumulate, composite) = passes.gpu.extras().wboit();
        let accumulate = match self.words.tints() {
            true => passes.gpu.extras().wboit_tinted(),
            false => accumulate,
        };
        passes.blend(
            fb.enc,
            Phase::WboitAccumulate,
            accumulate,
            Vec::new(),
            &attachments,
            "accumulate",
        );
        let group = composite_group(passes.params(), [&targets[0].0, &targets[1].0]);
        passes.resolve(fb.enc, Resolve::Wboit, composite, group, "wboit composite");
        Ok(())
    }

    /// MBOIT's two passes and composite with `moments` power moments (4, 6 or 8). A device
    /// that cannot blend 32-bit floats is refused.
    pub(super) fn mboit(&mut self, size: (u32, u32), moments: u32) -> Result<()> {
        let passes = self.passes;
        let gpu = passes.gpu;
        let tinted = self.words.tints();
        let [moments_blend, accumulate_blend] = BlendPass::mboit_for(moments, tinted)?;
        let at = (moments as usize - 4) / 2;
        let (mboit, composite) = gpu.extras().mboit();
        let mboit = match tinted {
            true => gpu.extras().mboit_tinted(),
            false => mboit,
        };
        let Some((moments_pass, accumulate_pass)) = &mboit[at] else {
            return Err(GpuError::DeviceLacks {
                adapter: gpu.adapter().to_string(),
                missing: mboit_lacks(&gpu.device, moments, &moments_blend),
            }
            .into());
        };
        // b_0, the moments (and six or eight moments' third target), then the accumulation:
        // the targets the passes describe.
        let written: Vec<(wgpu::TextureView, wgpu::Color)> = moments_blend
            .targets
            .iter()
            .chain(accumulate_blend.targets)
            .map(|&(t, _, clear)| {
                (
                    self.fb.target((t.label, t.format, t.texel_bytes()), size),
                    clear,
                )
            })
            .collect();
        let (read, accumulation) = written.split_at(moments_blend.targets.len());
        let (b0, accumulation) = (&read[0].0, &accumulation[0]);
        // The transmittance, last where tinted, is the composite's alone.
        let (moments_read, through) = match tinted {
            true => (&read[..read.len() - 1], &read[read.len() - 1].0),
            false => (read, b0),
        };
        let fb = &mut self.fb;
        // The absorbance of each 8-bit opacity (composite::mboit_absorbance_table).
        let table = fb.init(
            "mboit.absorbance",
            bytemuck::cast_slice(&crate::composite::mboit_absorbance_table()),
            wgpu::BufferUsages::UNIFORM,
            true,
        );
        let attachments: Vec<_> = read.iter().map(|(v, c)| (v, *c)).collect();
        passes.blend(
            fb.enc,
            Phase::MboitMoments,
            moments_pass,
            super::passes::entries(&[&table]),
            &attachments,
            "moments",
        );
        // The accumulation reads every target the moments pass wrote, at bindings 0...
        let views = moments_read
            .iter()
            .enumerate()
            .map(|(binding, (view, _))| view_at(binding as u32, view))
            .collect();
        let attachments = [(&accumulation.0, accumulation.1)];
        passes.blend(
            fb.enc,
            Phase::MboitAccumulate,
            accumulate_pass,
            views,
            &attachments,
            "accumulate",
        );
        let mut group = composite_group(passes.params(), [&accumulation.0, b0]);
        // What the background is seen through per channel where tinted (else b_0 again,
        // unread).
        group.push(view_at(blend_composite::THIRD_TARGET, through));
        passes.resolve(fb.enc, Resolve::Mboit, composite, group, "mboit composite");
        Ok(())
    }
}

/// A blended method's composite's group (blend_composite.wgsl) without its image: the
/// parameters, `targets` as its first and second.
fn composite_group<'b>(
    params: &'b wgpu::Buffer,
    targets: [&'b wgpu::TextureView; 2],
) -> Vec<wgpu::BindGroupEntry<'b>> {
    vec![
        at(blend_composite::PARAMS, params),
        view_at(blend_composite::FIRST_TARGET, targets[0]),
        view_at(blend_composite::SECOND_TARGET, targets[1]),
    ]
}

#[cfg(test)]
mod tests {
    use super::{BlendPass, Target};

    /// Each target's texel is the bytes a pixel its method's layout table counts under its
    /// label, so the tables and the textures the frames create cannot drift apart.
    #[test]
    fn blended_targets_are_the_layout_tables_entries() {
        for t in Target::ALL {
            let method = t.label.split('.').next().unwrap();
            let layout = crate::budget::layout(method).unwrap();
            let counted = layout.per_pixel.iter().find(|(l, _)| *l == t.label);
            assert_eq!(counted, Some(&(t.label, t.texel_bytes())), "{}", t.label);
        }
        // WBOIT's frames and MBOIT's of 4, 6 and 8 moments create exactly their layouts'
        // targets: those their passes describe.
        let mut frames = vec![(crate::budget::WBOIT, vec![BlendPass::WBOIT])];
        for moments in [4, 6, 8] {
            let passes = BlendPass::mboit(moments).unwrap().to_vec();
            frames.push((crate::budget::mboit(moments), passes));
        }
        for (layout, passes) in frames {
            let mut counted: Vec<_> = layout.per_pixel.to_vec();
            let mut made: Vec<_> = passes
                .iter()
                .flat_map(|p| p.targets.iter().map(|t| (t.0.label, t.0.texel_bytes())))
                .collect();
            counted.sort();
            made.sort();
            assert_eq!(counted, made, "{}", layout.method);
        }
        // Every per-pixel entry of both tables is one of them.
        for method in ["wboit", "mboit"] {
            for (label, _) in crate::budget::layout(method).unwrap().per_pixel {
                assert!(Target::ALL.iter().any(|t| t.label == *label), "{label}");
            }
        }
    }
}
