//! PNG output: linear images encoded to sRGB, and heat maps of per-pixel values.

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

/// Encodes 8-bit RGB pixels as PNG and writes them atomically.
pub fn write_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| Error::Image {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    write_atomic(path, &png)
}

/// Writes a linear image as an sRGB PNG.
pub fn write_png(path: &Path, img: &Image) -> Result<()> {
    write_rgb8(path, img.width, img.height, &to_srgb8(img))
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
    width: u32,
    height: u32,
    values: &[f32],
    covered: &[bool],
    max: f32,
) -> Result<()> {
    write_rgb8(path, width, height, &heat_rgb8(values, covered, max))
}

/// A grid of equally sized RGB8 tiles, for side-by-side pictures.
pub struct Montage {
    pub tile_w: u32,
    pub tile_h: u32,
    pub cols: u32,
    pub rows: u32,
    pub rgb: Vec<u8>,
}

impl Montage {
    /// A grid with a 4-pixel dark gutter between tiles.
    pub fn new(tile_w: u32, tile_h: u32, cols: u32, rows: u32) -> Montage {
        let (w, h) = (cols * (tile_w + 4) + 4, rows * (tile_h + 4) + 4);
        Montage {
            tile_w,
            tile_h,
            cols,
            rows,
            rgb: vec![40; (w * h * 3) as usize],
        }
    }
    pub fn width(&self) -> u32 {
        self.cols * (self.tile_w + 4) + 4
    }
    pub fn height(&self) -> u32 {
        self.rows * (self.tile_h + 4) + 4
    }
    /// Places a tile of `tile_w * tile_h` RGB8 pixels.
    pub fn put(&mut self, col: u32, row: u32, tile: &[u8]) {
        let w = self.width() as usize;
        let (x0, y0) = (
            (4 + col * (self.tile_w + 4)) as usize,
            (4 + row * (self.tile_h + 4)) as usize,
        );
        let tw = self.tile_w as usize;
        for y in 0..self.tile_h as usize {
            let dst = ((y0 + y) * w + x0) * 3;
            self.rgb[dst..dst + tw * 3].copy_from_slice(&tile[y * tw * 3..(y + 1) * tw * 3]);
        }
    }
    pub fn write(&self, path: &Path) -> Result<()> {
        write_rgb8(path, self.width(), self.height(), &self.rgb)
    }
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
