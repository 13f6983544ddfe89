//! Image output: linear images encoded to sRGB, and heat maps of per-pixel values, as PNG (or
//! JPEG, where the path asks for it); or linear and unclamped as OpenEXR, so colours above
//! white survive.

use crate::composite::Image;
use crate::error::{Error, Result};
use crate::tensors::write_atomic;
use image::ImageEncoder;
use std::path::Path;

pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// How an image path is encoded, by its extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    Png,
    /// Lossy (quality 90): for sharing, not for measuring.
    Jpeg,
    /// OpenEXR, 32-bit float RGB: an image linear and unclamped (light above white kept); a
    /// heat map as its 8-bit colours over 255.
    Exr,
}

/// The encoding `path` asks for (`.png`, `.jpg` / `.jpeg` or `.exr`, any case); anything else
/// is an error naming the path, which a command checks before it renders.
pub fn encoding(path: &Path) -> Result<Encoding> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("png") => Ok(Encoding::Png),
        Some("jpg" | "jpeg") => Ok(Encoding::Jpeg),
        Some("exr") => Ok(Encoding::Exr),
        _ => Err(Error::Image {
            path: path.to_path_buf(),
            message: "images are written as .png (or .jpg, or .exr for linear colours above white); give a path ending in one".into(),
        }),
    }
}

/// Encodes 8-bit RGB pixels as the path's extension asks ([`encoding`]) and writes them
/// atomically.
pub fn write_rgb8(path: &Path, size: (u32, u32), rgb: &[u8]) -> Result<()> {
    let (width, height) = size;
    let mut bytes = Vec::new();
    let encoded = match encoding(path)? {
        Encoding::Png => image::codecs::png::PngEncoder::new(&mut bytes).write_image(
            rgb,
            width,
            height,
            image::ExtendedColorType::Rgb8,
        ),
        Encoding::Jpeg => image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 90)
            .write_image(rgb, width, height, image::ExtendedColorType::Rgb8),
        Encoding::Exr => {
            let linear: Vec<f32> = rgb.iter().map(|&v| v as f32 / 255.0).collect();
            return write_rgb32f(path, size, &linear);
        }
    };
    encoded.map_err(|e| Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    write_atomic(path, &bytes)
}

/// Writes a linear image as its path asks ([`encoding`]): sRGB PNG or JPEG, clamped at white;
/// or OpenEXR, linear, every value as it is.
pub fn write_image(path: &Path, img: &Image) -> Result<()> {
    match encoding(path)? {
        Encoding::Exr => {
            let rgb: Vec<f32> = img.data.iter().flatten().copied().collect();
            write_rgb32f(path, img.size(), &rgb)
        }
        _ => write_rgb8(path, img.size(), &to_srgb8(img)),
    }
}

/// Writes 32-bit float RGB pixels as OpenEXR, atomically.
fn write_rgb32f(path: &Path, size: (u32, u32), rgb: &[f32]) -> Result<()> {
    let (width, height) = size;
    let mut bytes = std::io::Cursor::new(Vec::new());
    image::codecs::openexr::OpenExrEncoder::new(&mut bytes)
        .write_image(
            bytemuck::cast_slice(rgb),
            width,
            height,
            image::ExtendedColorType::Rgb32F,
        )
        .map_err(|e| Error::Image {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    write_atomic(path, &bytes.into_inner())
}

/// A perceptual colour ramp (dark blue -> teal -> yellow) for t in [0, 1].
pub fn ramp(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [0.05, 0.03, 0.25],
        [0.23, 0.32, 0.55],
        [0.13, 0.57, 0.55],
        [0.47, 0.80, 0.32],
        [0.99, 0.91, 0.15],
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    } * (STOPS.len() - 1) as f32;
    let i = (t as usize).min(STOPS.len() - 2);
    let f = t - i as f32;
    std::array::from_fn(|c| ((STOPS[i][c] * (1.0 - f) + STOPS[i + 1][c] * f) * 255.0).round() as u8)
}

/// Writes a heat map of per-pixel values scaled by `max` (pixels with no fragments black).
pub fn write_heatmap(
    path: &Path,
    size: (u32, u32),
    values: &[f32],
    covered: &[bool],
    max: f32,
) -> Result<()> {
    write_rgb8(path, size, &heat_rgb8(values, covered, max))
}

/// An image as sRGB8 pixels.
pub fn to_srgb8(img: &Image) -> Vec<u8> {
    img.data
        .iter()
        .flat_map(|c| c.map(|v| (linear_to_srgb(v) * 255.0).round() as u8))
        .collect()
}

/// A heat map as RGB8 pixels (uncovered pixels black).
pub fn heat_rgb8(values: &[f32], covered: &[bool], max: f32) -> Vec<u8> {
    let max = if max > 0.0 { max } else { 1.0 };
    values
        .iter()
        .zip(covered)
        .flat_map(|(&v, &c)| if c { ramp(v / max) } else { [0, 0, 0] })
        .collect()
}

/// FLIP (NVIDIA's perceptual image difference, LDR, through `nv-flip`) between two sRGB8
/// images of `width * height` pixels viewed at FLIP's default 67 pixels per degree: the mean
/// error in [0, 1] (0: indistinguishable) and the per-pixel error map.
#[cfg(feature = "flip")]
pub fn flip(reference: &[u8], test: &[u8], size: (u32, u32)) -> (f64, Vec<f32>) {
    let (width, height) = size;
    let n = (width * height * 3) as usize;
    assert!(
        reference.len() == n && test.len() == n,
        "flip: images of {width}x{height} RGB8 expected"
    );
    let r = nv_flip::FlipImageRgb8::with_data(width, height, reference);
    let t = nv_flip::FlipImageRgb8::with_data(width, height, test);
    let map = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    let mean = nv_flip::FlipPool::from_image(&map).mean() as f64;
    (mean, map.to_vec())
}

/// A FLIP error map as RGB8 with FLIP's own magma colour scale (black 0 to pale yellow 1).
#[cfg(feature = "flip")]
pub fn flip_rgb8(map: &[f32], size: (u32, u32)) -> Vec<u8> {
    let (width, height) = size;
    let m = nv_flip::FlipImageFloat::with_data(width, height, map);
    m.apply_color_lut(&nv_flip::magma_lut()).to_vec()
}

/// The magma colour of a FLIP value in [0, 1] (for colour-scale legends).
#[cfg(feature = "flip")]
pub fn magma(t: f32) -> [u8; 3] {
    let lut = nv_flip::magma_lut().to_vec();
    let i = ((t.clamp(0.0, 1.0) * 255.0).round() as usize).min(lut.len() / 3 - 1);
    [lut[3 * i], lut[3 * i + 1], lut[3 * i + 2]]
}

/// The width and height of a PNG file.
pub fn png_size(path: &Path) -> Result<(u32, u32)> {
    image::image_dimensions(path).map_err(|e| Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}
