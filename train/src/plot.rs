//! The loss-curve picture written beside the weights: train MSE (blue) and validation MSE
//! (orange) per epoch on a log scale, the best epoch marked by a grey line, with a tiny
//! built-in font for the axis labels (no font files needed).

use crate::trainer::Epoch;
use std::path::Path;

const W: usize = 720;
const H: usize = 420;
const LEFT: usize = 70;
const RIGHT: usize = 20;
const TOP: usize = 30;
const BOTTOM: usize = 40;

/// 3x5 glyphs, one u16 per glyph, rows top to bottom, 3 bits a row (MSB left).
fn glyph(c: char) -> Option<u16> {
    Some(match c {
        '0' => 0b111_101_101_101_111,
        '1' => 0b010_110_010_010_111,
        '2' => 0b111_001_111_100_111,
        '3' => 0b111_001_111_001_111,
        '4' => 0b101_101_111_001_001,
        '5' => 0b111_100_111_001_111,
        '6' => 0b111_100_111_101_111,
        '7' => 0b111_001_010_010_010,
        '8' => 0b111_101_111_101_111,
        '9' => 0b111_101_111_001_111,
        '.' => 0b000_000_000_000_010,
        '-' => 0b000_000_111_000_000,
        'e' => 0b000_111_111_100_111,
        'a' => 0b000_111_011_101_111,
        'i' => 0b010_000_010_010_010,
        'l' => 0b110_010_010_010_111,
        'n' => 0b000_110_101_101_101,
        'r' => 0b000_111_100_100_100,
        't' => 0b010_111_010_010_011,
        'v' => 0b000_101_101_101_010,
        'p' => 0b000_111_101_111_100,
        'o' => 0b000_111_101_101_111,
        'c' => 0b000_111_100_100_111,
        'h' => 0b100_100_111_101_101,
        's' => 0b000_111_110_011_111,
        'b' => 0b100_100_111_101_111,
        'm' => 0b000_110_111_101_101,
        'g' => 0b000_111_101_111_001,
        ' ' => 0,
        _ => return None,
    })
}

struct Canvas(Vec<u8>);

impl Canvas {
    fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < W && (y as usize) < H {
            let i = (y as usize * W + x as usize) * 3;
            self.0[i..i + 3].copy_from_slice(&c);
        }
    }
    fn line(&mut self, (x0, y0): (f64, f64), (x1, y1): (f64, f64), c: [u8; 3], thick: i64) {
        let steps = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as usize).max(1);
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let (x, y) = (
                (x0 + (x1 - x0) * t).round() as i64,
                (y0 + (y1 - y0) * t).round() as i64,
            );
            for dx in 0..thick {
                for dy in 0..thick {
                    self.set(x + dx, y + dy, c);
                }
            }
        }
    }
    /// Text at scale 2 (6x10 pixels a glyph), top-left at (x, y).
    fn text(&mut self, x: i64, y: i64, s: &str, c: [u8; 3]) {
        for (n, ch) in s.chars().enumerate() {
            let Some(g) = glyph(ch) else { continue };
            for row in 0..5 {
                for col in 0..3 {
                    if g >> (14 - (row * 3 + col)) & 1 == 1 {
                        for d in 0..4 {
                            self.set(x + n as i64 * 8 + col * 2 + d % 2, y + row * 2 + d / 2, c);
                        }
                    }
                }
            }
        }
    }
}

/// Writes the loss curves of `history` (best epoch `best`) as a PNG.
pub fn loss_curve(path: &Path, history: &[Epoch], best: usize) -> dhoit_runtime::Result<()> {
    let mut cv = Canvas(vec![255; W * H * 3]);
    let values: Vec<f64> = history
        .iter()
        .flat_map(|e| [e.train_loss, e.validation_loss])
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    let lo = values
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
        .max(1e-12);
    let hi = values.iter().copied().fold(0.0, f64::max).max(lo * 1.0001);
    let (llo, lhi) = (lo.log10(), hi.log10());
    let pw = (W - LEFT - RIGHT) as f64;
    let ph = (H - TOP - BOTTOM) as f64;
    let n = history.len().max(2) - 1;
    let px = |e: usize| LEFT as f64 + pw * e as f64 / n as f64;
    let py = |v: f64| TOP as f64 + ph * (1.0 - (v.max(lo).log10() - llo) / (lhi - llo));
    let axis = [60, 60, 60];
    cv.line(
        (LEFT as f64, TOP as f64),
        (LEFT as f64, (H - BOTTOM) as f64),
        axis,
        1,
    );
    cv.line(
        (LEFT as f64, (H - BOTTOM) as f64),
        ((W - RIGHT) as f64, (H - BOTTOM) as f64),
        axis,
        1,
    );
    if best < history.len() {
        let x = px(best);
        let mut y = TOP as f64;
        while y < (H - BOTTOM) as f64 {
            cv.line((x, y), (x, y + 4.0), [170, 170, 170], 1);
            y += 8.0;
        }
    }
    type Series = (fn(&Epoch) -> f64, [u8; 3]);
    let series: [Series; 2] = [
        (|e| e.train_loss, [31, 119, 180]),
        (|e| e.validation_loss, [255, 127, 14]),
    ];
    for (get, colour) in series {
        for w in history.windows(2) {
            let (a, b) = (get(&w[0]), get(&w[1]));
            if a.is_finite() && b.is_finite() {
                cv.line((px(w[0].epoch), py(a)), (px(w[1].epoch), py(b)), colour, 2);
            }
        }
        if history.len() == 1 && get(&history[0]).is_finite() {
            cv.line(
                (px(0), py(get(&history[0]))),
                (px(0) + 3.0, py(get(&history[0]))),
                colour,
                3,
            );
        }
    }
    // Labels: y range (log scale), epochs, legend.
    cv.text(4, TOP as i64 - 4, &format!("{hi:.2e}"), axis);
    cv.text(4, (H - BOTTOM) as i64 - 10, &format!("{lo:.2e}"), axis);
    cv.text(LEFT as i64 - 4, (H - BOTTOM) as i64 + 8, "0", axis);
    cv.text(
        (W - RIGHT) as i64 - 30,
        (H - BOTTOM) as i64 + 8,
        &format!("{n}"),
        axis,
    );
    cv.text((W / 2) as i64 - 20, (H - BOTTOM) as i64 + 20, "epoch", axis);
    cv.line(
        ((W - 200) as f64, 14.0),
        ((W - 180) as f64, 14.0),
        [31, 119, 180],
        3,
    );
    cv.text((W - 175) as i64, 9, "train", axis);
    cv.line(
        ((W - 110) as f64, 14.0),
        ((W - 90) as f64, 14.0),
        [255, 127, 14],
        3,
    );
    cv.text((W - 85) as i64, 9, "val", axis);
    cv.text(LEFT as i64 + 8, 9, "mse log", axis);
    dhoit_runtime::image_io::write_rgb8(path, W as u32, H as u32, &cv.0)
}
