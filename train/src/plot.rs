//! Every picture dhoit draws, with `plotters`: charts as SVG and PNG (the loss curves, the
//! speed-accuracy trade) and labelled montages as PNG.
//!
//! Text needs a TrueType font: `$DHOIT_FONT`, else the first of the usual system fonts (DejaVu,
//! which `make setup` installs on Debian; Liberation; Arial). Without one a chart is skipped and
//! a montage is drawn without its words, with a warning: a picture never fails the work it
//! illustrates.

use crate::trainer::Epoch;
use dhoit_runtime::image_io;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const FAMILY: &str = "sans-serif";
const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/liberation-sans/LiberationSans-Regular.ttf",
    "/Library/Fonts/Arial.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// Why pictures have no font to draw their text with.
#[derive(Debug, thiserror::Error)]
pub enum NoFont {
    #[error("DHOIT_FONT={} is not a readable TrueType font", .0.display())]
    Unreadable(PathBuf),
    #[error(
        "no TrueType font found: install one (Debian: fonts-dejavu-core) or set DHOIT_FONT to a \
         .ttf file"
    )]
    NoneFound,
}

/// The font text is drawn with (registered once), or why there is none.
pub fn font() -> std::result::Result<&'static Path, &'static NoFont> {
    static FONT: OnceLock<std::result::Result<PathBuf, NoFont>> = OnceLock::new();
    FONT.get_or_init(|| {
        let env = std::env::var_os("DHOIT_FONT").map(PathBuf::from);
        let candidates: Vec<PathBuf> = env
            .iter()
            .cloned()
            .chain(FONT_PATHS.iter().map(PathBuf::from))
            .collect();
        for p in &candidates {
            let registered = std::fs::read(p).is_ok_and(|bytes| {
                // plotters keeps fonts for the life of the process.
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                plotters::style::register_font(FAMILY, FontStyle::Normal, bytes).is_ok()
            });
            if registered {
                // A font asked for by name and not used is said, not passed over in silence.
                if let Some(asked) = env.as_ref().filter(|a| *a != p) {
                    eprintln!(
                        "warning: DHOIT_FONT={} is not a readable TrueType font; text is drawn with {}",
                        asked.display(),
                        p.display()
                    );
                }
                return Ok(p.clone());
            }
        }
        Err(match env {
            Some(p) => NoFont::Unreadable(p),
            None => NoFont::NoneFound,
        })
    })
    .as_ref()
    .map(|p| p.as_path())
}

/// Says once per process that pictures lack their words, and why.
fn warn_no_font(why: &NoFont) {
    static SAID: OnceLock<()> = OnceLock::new();
    SAID.get_or_init(|| eprintln!("warning: pictures drawn without text: {why}"));
}

/// A chart drawn the same way on any plotters backend.
trait Chart {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError>;
}

/// An axis label: plain when readable so, else in scientific notation.
fn short(v: f64) -> String {
    if (0.01..1000.0).contains(&v.abs()) {
        format!("{v:.3}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{v:.2e}")
    }
}

/// Every chart's legend: upper right, on a translucent white box.
fn legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
) -> Result<(), PlotError> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(err)
}

/// Why a chart was not made (charts only warn: they never fail the work).
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error(transparent)]
    NoFont(&'static NoFont),
    #[error("drawing failed: {0}")]
    Draw(String),
    #[error(transparent)]
    Write(#[from] dhoit_runtime::Error),
}

fn err<E: std::fmt::Display>(e: E) -> PlotError {
    PlotError::Draw(e.to_string())
}

/// Writes `chart` as `stem.svg` and `stem.png` (each atomically); the paths written.
fn write_chart(
    chart: &impl Chart,
    stem: &Path,
    (w, h): (u32, u32),
) -> Result<Vec<PathBuf>, PlotError> {
    font().map_err(PlotError::NoFont)?;
    let svg_path = stem.with_extension("svg");
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        chart.draw(&root)?;
        root.present().map_err(err)?;
    }
    dhoit_runtime::tensors::write_atomic(&svg_path, svg.as_bytes())?;
    let png_path = stem.with_extension("png");
    let mut rgb = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        chart.draw(&root)?;
        root.present().map_err(err)?;
    }
    image_io::write_rgb8(&png_path, (w, h), &rgb)?;
    Ok(vec![svg_path, png_path])
}

/// Draws a chart, or warns why it could not be: the paths written.
fn chart_or_warn(chart: &impl Chart, stem: &Path, size: (u32, u32)) -> Vec<PathBuf> {
    match write_chart(chart, stem, size) {
        Ok(p) => p,
        Err(PlotError::NoFont(why)) => {
            warn_no_font(why);
            Vec::new()
        }
        Err(e) => {
            eprintln!("warning: {} not drawn: {e}", stem.display());
            Vec::new()
        }
    }
}

const TRAIN: RGBColor = RGBColor(31, 119, 180);
const VALIDATION: RGBColor = RGBColor(255, 127, 14);
const GREY: RGBColor = RGBColor(150, 150, 150);

struct Loss<'a> {
    history: &'a [Epoch],
    best: usize,
}

impl Chart for Loss<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        root.fill(&WHITE).map_err(err)?;
        let values: Vec<f64> = self
            .history
            .iter()
            .flat_map(|e| [e.train_loss, e.validation_loss])
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let lo = if lo.is_finite() { lo * 0.9 } else { 1e-3 };
        let hi = values.iter().copied().fold(0.0, f64::max).max(lo * 1.5) * 1.1;
        let n = self.history.len().max(2) - 1;
        let mut chart = ChartBuilder::on(root)
            .caption("Training loss (log scale)", (FAMILY, 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            // log10 of the loss on a linear axis, labelled with the loss: evenly spaced labels
            // however narrow the range.
            .build_cartesian_2d(0..n, lo.log10()..hi.log10())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("epoch")
            .y_desc("loss")
            .y_labels(10)
            .y_label_formatter(&|v| short(10f64.powf(*v)))
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(err)?;
        if self.best < self.history.len() {
            let b = self.best;
            chart
                .draw_series(DashedLineSeries::new(
                    [(b, lo.log10()), (b, hi.log10())],
                    5,
                    4,
                    GREY.stroke_width(1),
                ))
                .map_err(err)?
                .label(format!("best epoch {b}"))
                .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], GREY));
        }
        let finite = |v: f64| v.is_finite() && v > 0.0;
        type Get = fn(&Epoch) -> f64;
        let series: [(&str, Get, RGBColor); 2] = [
            ("train", |e| e.train_loss, TRAIN),
            ("validation", |e| e.validation_loss, VALIDATION),
        ];
        for (name, get, colour) in series {
            chart
                .draw_series(LineSeries::new(
                    self.history
                        .iter()
                        .filter(|e| finite(get(e)))
                        .map(|e| (e.epoch, get(e).log10())),
                    colour.stroke_width(2),
                ))
                .map_err(err)?
                .label(name)
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2))
                });
        }
        legend(&mut chart)
    }
}

/// Writes the loss curves of `history` (best epoch `best`) as `stem.svg` and `stem.png`; the
/// paths written (none, with a warning, when no font is at hand).
pub fn loss_curve(stem: &Path, history: &[Epoch], best: usize) -> Vec<PathBuf> {
    chart_or_warn(&Loss { history, best }, stem, (760, 440))
}

/// One configuration on the speed-accuracy trade.
#[derive(Clone, Debug)]
pub struct TradePoint {
    /// What the point is (`32-16 f16`).
    pub label: String,
    /// Importance-pass time, milliseconds.
    pub time_ms: f64,
    pub mse: f64,
    pub flip: f64,
    /// On the Pareto front (no other point is at least as fast and as accurate in both).
    pub front: bool,
}

struct Trade<'a> {
    title: &'a str,
    time_label: &'a str,
    points: &'a [TradePoint],
}

impl Trade<'_> {
    fn panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        metric: &str,
        get: fn(&TradePoint) -> f64,
    ) -> Result<(), PlotError> {
        let pts: Vec<&TradePoint> = self
            .points
            .iter()
            .filter(|p| p.time_ms > 0.0 && get(p) > 0.0 && get(p).is_finite())
            .collect();
        // Both axes log10 of the value on a linear axis, labelled with the value: evenly spaced
        // labels however narrow the range (plotters' log axes label only round values).
        let range = |v: &mut dyn Iterator<Item = f64>| {
            let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                (a.min(x.log10()), b.max(x.log10()))
            });
            if lo.is_finite() {
                let pad = ((hi - lo) * 0.15).max(0.05);
                (lo - pad)..(hi + pad)
            } else {
                -3.0..0.0
            }
        };
        let xs = range(&mut pts.iter().map(|p| p.time_ms));
        let ys = range(&mut pts.iter().map(|p| get(p)));
        let mut chart = ChartBuilder::on(area)
            .caption(format!("{metric} against time (log-log)"), (FAMILY, 16))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(xs, ys)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(self.time_label)
            .y_desc(format!("{metric} against the A-buffer"))
            .x_labels(8)
            .y_labels(8)
            .x_label_formatter(&|v| short(10f64.powf(*v)))
            .y_label_formatter(&|v| short(10f64.powf(*v)))
            .draw()
            .map_err(err)?;
        let at = |p: &TradePoint| (p.time_ms.log10(), get(p).log10());
        // The front, by time (the front is non-dominated in time, MSE and FLIP together, so
        // in one metric it need not be monotone).
        let mut front: Vec<(f64, f64)> = pts.iter().filter(|p| p.front).map(|p| at(p)).collect();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(front, VALIDATION.stroke_width(2)))
            .map_err(err)?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], VALIDATION.stroke_width(2)));
        chart
            .draw_series(pts.iter().map(|p| {
                let style = if p.front {
                    VALIDATION.filled()
                } else {
                    TRAIN.filled()
                };
                EmptyElement::at(at(p))
                    + Circle::new((0, 0), 5, style)
                    + Text::new(p.label.clone(), (7, -12), (FAMILY, 12))
            }))
            .map_err(err)?;
        legend(&mut chart)
    }
}

impl Chart for Trade<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        root.fill(&WHITE).map_err(err)?;
        let root = root.titled(self.title, (FAMILY, 20)).map_err(err)?;
        let panels = root.split_evenly((1, 2));
        self.panel(&panels[0], "MSE", |p| p.mse)?;
        self.panel(&panels[1], "FLIP", |p| p.flip)?;
        Ok(())
    }
}

/// Writes one scene's speed-accuracy trade (MSE and FLIP against importance-pass time, the
/// Pareto front joined) as `stem.svg` and `stem.png`; the paths written.
pub fn trade(stem: &Path, title: &str, time_label: &str, points: &[TradePoint]) -> Vec<PathBuf> {
    chart_or_warn(
        &Trade {
            title,
            time_label,
            points,
        },
        stem,
        (1200, 520),
    )
}

/// A colour scale shown beside a row of heat maps.
pub struct Scale {
    pub colour: fn(f32) -> [u8; 3],
    /// What 0 and 1 stand for.
    pub lo: String,
    pub hi: String,
}

/// A labelled grid of equally sized RGB8 tiles: a heading over each column (one string a
/// line), a label before each row, a colour scale after any row that has one.
pub struct Montage {
    pub tile_w: u32,
    pub tile_h: u32,
    /// `tiles[row][col]`, `tile_w * tile_h * 3` bytes each.
    pub tiles: Vec<Vec<Vec<u8>>>,
    pub columns: Vec<Vec<String>>,
    pub rows: Vec<String>,
    pub scales: Vec<Option<Scale>>,
}

const GAP: u32 = 4;
const LINE: u32 = 15;

impl Montage {
    fn layout(&self, text: bool) -> (u32, u32, u32, u32) {
        let lines = self.columns.iter().map(|c| c.len()).max().unwrap_or(0) as u32;
        let left = if text { 96 } else { GAP };
        let top = if text { lines * LINE + 2 * GAP } else { GAP };
        let right = if self.scales.iter().any(|s| s.is_some()) {
            if text { 70 } else { 24 }
        } else {
            0
        };
        let cols = self.tiles.first().map_or(0, |r| r.len()) as u32;
        let w = left + cols * (self.tile_w + GAP) + right;
        let h = top + self.tiles.len() as u32 * (self.tile_h + GAP);
        (left, top, w, h)
    }

    fn draw(&self, rgb: &mut [u8], text: bool) -> Result<(), PlotError> {
        let (left, top, w, h) = self.layout(text);
        let root = BitMapBackend::with_buffer(rgb, (w, h)).into_drawing_area();
        root.fill(&RGBColor(40, 40, 40)).map_err(err)?;
        let style = (FAMILY, 13).into_font().color(&RGBColor(235, 235, 235));
        let cols = self.tiles.first().map_or(0, |r| r.len()) as u32;
        for (r, row) in self.tiles.iter().enumerate() {
            let y = (top + r as u32 * (self.tile_h + GAP)) as i32;
            for (c, tile) in row.iter().enumerate() {
                let x = (left + c as u32 * (self.tile_w + GAP)) as i32;
                let el = BitMapElement::with_ref((x, y), (self.tile_w, self.tile_h), tile)
                    .ok_or_else(|| err("montage: a tile of the wrong size"))?;
                root.draw(&el).map_err(err)?;
            }
            if text && let Some(label) = self.rows.get(r) {
                for (i, part) in label.split('\n').enumerate() {
                    root.draw_text(part, &style, (6, y + 4 + (i as u32 * LINE) as i32))
                        .map_err(err)?;
                }
            }
            if let Some(Some(scale)) = self.scales.get(r) {
                let x0 = (left + cols * (self.tile_w + GAP)) as i32 + 4;
                let bar_h = self.tile_h as i32 - 8;
                for i in 0..bar_h {
                    let t = 1.0 - i as f32 / (bar_h - 1).max(1) as f32;
                    let [cr, cg, cb] = (scale.colour)(t);
                    root.draw(&Rectangle::new(
                        [(x0, y + 4 + i), (x0 + 12, y + 5 + i)],
                        RGBColor(cr, cg, cb).filled(),
                    ))
                    .map_err(err)?;
                }
                if text {
                    root.draw_text(&scale.hi, &style, (x0 + 16, y + 2))
                        .map_err(err)?;
                    root.draw_text(&scale.lo, &style, (x0 + 16, y + bar_h - 8))
                        .map_err(err)?;
                }
            }
        }
        if text {
            for (c, lines) in self.columns.iter().enumerate() {
                let x = (left + c as u32 * (self.tile_w + GAP)) as i32 + 2;
                for (i, line) in lines.iter().enumerate() {
                    root.draw_text(line, &style, (x, (GAP + i as u32 * LINE) as i32))
                        .map_err(err)?;
                }
            }
        }
        root.present().map_err(err)?;
        Ok(())
    }

    /// Writes the montage as a PNG (atomically): with its words when a font is at hand,
    /// without them (and a warning) otherwise.
    pub fn write(&self, path: &Path) -> dhoit_runtime::Result<()> {
        let text = match font() {
            Ok(_) => true,
            Err(why) => {
                warn_no_font(why);
                false
            }
        };
        let (_, _, w, h) = self.layout(text);
        let mut rgb = vec![0u8; (w * h * 3) as usize];
        self.draw(&mut rgb, text)
            .map_err(|e| dhoit_runtime::Error::Image {
                path: path.to_path_buf(),
                message: e.to_string(),
            })?;
        image_io::write_rgb8(path, (w, h), &rgb)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn history() -> Vec<Epoch> {
        (0..5)
            .map(|e| Epoch {
                epoch: e,
                train_loss: 1.0 / (e + 1) as f64,
                train_reg: 0.0,
                validation_loss: 1.2 / (e + 1) as f64,
                seconds: 0.1,
            })
            .collect()
    }

    #[test]
    fn loss_curve_writes_svg_and_png_with_words() {
        let dir = std::env::temp_dir().join(format!("dhoit-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let written = loss_curve(&dir.join("loss"), &history(), 3);
        match font() {
            Ok(_) => {
                assert_eq!(written.len(), 2, "both SVG and PNG");
                let svg = std::fs::read_to_string(dir.join("loss.svg")).unwrap();
                assert!(svg.contains("validation") && svg.contains("best epoch 3"));
                let png = image_io::png_size(&dir.join("loss.png")).unwrap();
                assert_eq!(png, (760, 440));
            }
            Err(why) => {
                assert!(written.is_empty(), "no font ({why}), nothing written");
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn montage_puts_each_tile_where_it_belongs() {
        let (tw, th) = (8u32, 6u32);
        let tile = |v: u8| vec![v; (tw * th * 3) as usize];
        let m = Montage {
            tile_w: tw,
            tile_h: th,
            tiles: vec![vec![tile(10), tile(20)], vec![tile(30), tile(40)]],
            columns: vec![vec!["a".into()], vec!["b".into()]],
            rows: vec!["one".into(), "two".into()],
            scales: vec![None, None],
        };
        for text in [false, true] {
            if text && font().is_err() {
                continue;
            }
            let (left, top, w, h) = m.layout(text);
            let mut rgb = vec![0u8; (w * h * 3) as usize];
            m.draw(&mut rgb, text).unwrap();
            for (r, c, v) in [(0, 0, 10), (0, 1, 20), (1, 0, 30), (1, 1, 40)] {
                // The tile's centre pixel.
                let x = left + c * (tw + GAP) + tw / 2;
                let y = top + r * (th + GAP) + th / 2;
                let i = ((y * w + x) * 3) as usize;
                assert_eq!(rgb[i], v, "tile ({r}, {c}) with text {text}");
            }
        }
    }
}
