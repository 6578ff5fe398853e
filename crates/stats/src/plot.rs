//! Figures drawn with plotters, as PNG and SVG. Text uses a font bundled in the binary
//! (Ubuntu Light, from `epaint_default_fonts`), so no system font is needed.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::dataset::{ArrayStats, HISTOGRAM_BINS, LengthStats};
use crate::error::StatsError;
use crate::language::LanguageReport;

const FONT: &str = "sans-serif";

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        if plotters::style::register_font(
            FONT,
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .is_err()
        {
            tracing::warn!("the bundled font could not be loaded; plots will have no text");
        }
    });
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// A picture that can be drawn on any plotters backend.
trait Figure {
    fn size(&self) -> (u32, u32);
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB>;
}

fn text_style(size: f64, color: RGBColor, h: HPos, v: VPos) -> TextStyle<'static> {
    TextStyle {
        font: (FONT, size).into_font(),
        color: color.to_backend_color(),
        pos: Pos::new(h, v),
    }
}

/// Writes a figure as PNG and SVG.
fn save(figure: &impl Figure, png: &Path, svg: &Path) -> Result<(), StatsError> {
    register_font();
    let (w, h) = figure.size();
    let plot_err = |path: &Path, e: &dyn std::fmt::Display| StatsError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut buffer = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        figure.draw(&root).map_err(|e| plot_err(png, &e))?;
        root.present().map_err(|e| plot_err(png, &e))?;
    }
    image::save_buffer_with_format(
        png,
        &buffer,
        w,
        h,
        image::ExtendedColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|e| plot_err(png, &e))?;
    let root = SVGBackend::new(svg, (w, h)).into_drawing_area();
    figure.draw(&root).map_err(|e| plot_err(svg, &e))?;
    root.present().map_err(|e| plot_err(svg, &e))?;
    Ok(())
}

/// A white-to-dark-blue scale for t in [0, 1].
fn blues(t: f64) -> RGBColor {
    const STOPS: [(u8, u8, u8); 5] = [
        (247, 251, 255),
        (198, 219, 239),
        (107, 174, 214),
        (33, 113, 181),
        (8, 48, 107),
    ];
    let t = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f64;
    let mix = |a: u8, b: u8| (f64::from(a) + (f64::from(b) - f64::from(a)) * f).round() as u8;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

struct Heatmap<'a> {
    report: &'a LanguageReport,
    vmax: f64,
}

const CELL_W: i32 = 72;
const CELL_H: i32 = 50;
const LEFT: i32 = 170;
const TOP: i32 = 80;

impl Heatmap<'_> {
    /// One row per instruction: its label, then a cell per output (shaded by its
    /// proportion, the expected one boxed in red).
    fn draw_cells<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let r = self.report;
        for (i, ins) in r.instructions.iter().enumerate() {
            let y = TOP + CELL_H * i as i32;
            let label = format!("\"{}\"  ({})", ins.label, ins.expected);
            root.draw(&Text::new(
                label,
                (LEFT - 10, y + CELL_H / 2),
                text_style(15.0, BLACK, HPos::Right, VPos::Center),
            ))?;
            for (j, out) in r.outputs.iter().enumerate() {
                let x = LEFT + CELL_W * j as i32;
                let p = r.proportions[i][j];
                let t = if self.vmax > 0.0 { p / self.vmax } else { 0.0 };
                root.draw(&Rectangle::new(
                    [(x, y), (x + CELL_W, y + CELL_H)],
                    blues(t).filled(),
                ))?;
                if *out == ins.expected {
                    root.draw(&Rectangle::new(
                        [(x + 1, y + 1), (x + CELL_W - 2, y + CELL_H - 2)],
                        ShapeStyle::from(&RGBColor(214, 39, 40)).stroke_width(2),
                    ))?;
                }
                let color = if t > 0.55 { WHITE } else { BLACK };
                root.draw(&Text::new(
                    format!("{p:.3}"),
                    (x + CELL_W / 2, y + CELL_H / 2),
                    text_style(14.0, color, HPos::Center, VPos::Center),
                ))?;
            }
        }
        Ok(())
    }

    /// The colour bar right of the grid, from the top of the grid to `bottom`, with
    /// five ticks up to the largest proportion.
    fn draw_colour_bar<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        bottom: i32,
    ) -> DrawResult<DB> {
        let r = self.report;
        let bx = LEFT + CELL_W * r.outputs.len() as i32 + 30;
        let steps = 100;
        let height = bottom - TOP;
        for k in 0..steps {
            let y0 = bottom - height * k / steps;
            let y1 = bottom - height * (k + 1) / steps;
            root.draw(&Rectangle::new(
                [(bx, y1), (bx + 18, y0)],
                blues(f64::from(k) / f64::from(steps)).filled(),
            ))?;
        }
        root.draw(&Rectangle::new(
            [(bx, TOP), (bx + 18, bottom)],
            ShapeStyle::from(&RGBColor(120, 120, 120)).stroke_width(1),
        ))?;
        for k in 0..=4 {
            let v = self.vmax * f64::from(k) / 4.0;
            let y = bottom - height * k / 4;
            root.draw(&Text::new(
                format!("{v:.2}"),
                (bx + 24, y),
                text_style(12.0, BLACK, HPos::Left, VPos::Center),
            ))?;
        }
        Ok(())
    }
}

impl Figure for Heatmap<'_> {
    fn size(&self) -> (u32, u32) {
        let r = &self.report;
        let w = LEFT + CELL_W * r.outputs.len() as i32 + 120;
        let h = TOP + CELL_H * r.instructions.len() as i32 + 70;
        (w.max(520) as u32, h as u32)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let r = self.report;
        root.fill(&WHITE)?;
        let (w, _) = self.size();
        let title = if r.example {
            "Output distribution per instruction (EXAMPLE INPUT, not results)"
        } else {
            "Output distribution per instruction"
        };
        root.draw(&Text::new(
            title,
            (w as i32 / 2, 22),
            text_style(20.0, BLACK, HPos::Center, VPos::Center),
        ))?;
        let sub = format!(
            "{} episodes over {} seed(s); each row sums to 1",
            r.counts.iter().flatten().sum::<u64>(),
            r.seeds.len()
        );
        root.draw(&Text::new(
            sub,
            (w as i32 / 2, 46),
            text_style(14.0, RGBColor(90, 90, 90), HPos::Center, VPos::Center),
        ))?;
        root.draw(&Text::new(
            "instruction (expected)",
            (LEFT - 10, TOP - 12),
            text_style(13.0, RGBColor(90, 90, 90), HPos::Right, VPos::Center),
        ))?;
        self.draw_cells(root)?;
        let bottom = TOP + CELL_H * r.instructions.len() as i32;
        root.draw(&Rectangle::new(
            [
                (LEFT, TOP),
                (LEFT + CELL_W * r.outputs.len() as i32, bottom),
            ],
            ShapeStyle::from(&RGBColor(120, 120, 120)).stroke_width(1),
        ))?;
        for (j, out) in r.outputs.iter().enumerate() {
            let x = LEFT + CELL_W * j as i32 + CELL_W / 2;
            root.draw(&Text::new(
                out.clone(),
                (x, bottom + 16),
                text_style(15.0, BLACK, HPos::Center, VPos::Center),
            ))?;
        }
        let mid = LEFT + CELL_W * r.outputs.len() as i32 / 2;
        root.draw(&Text::new(
            "password entered (red box: the expected one)",
            (mid, bottom + 44),
            text_style(15.0, BLACK, HPos::Center, VPos::Center),
        ))?;
        self.draw_colour_bar(root, bottom)?;
        Ok(())
    }
}

/// Draws the instruction x output heatmap (row proportions; the expected answer of each
/// row boxed in red) as PNG and SVG.
pub fn heatmap(report: &LanguageReport, png: &Path, svg: &Path) -> Result<(), StatsError> {
    let max = report
        .proportions
        .iter()
        .flatten()
        .fold(0.0f64, |a, &b| a.max(b));
    // Round the top of the scale up to a tenth so that colours compare across inputs.
    let vmax = ((max * 10.0).ceil() / 10.0).max(0.1);
    save(&Heatmap { report, vmax }, png, svg)
}

/// One small histogram.
struct Panel {
    title: String,
    counts: Vec<u64>,
    lo: f64,
    hi: f64,
}

struct PanelGrid {
    title: String,
    panels: Vec<Panel>,
    columns: usize,
    panel_w: i32,
    panel_h: i32,
}

impl Figure for PanelGrid {
    fn size(&self) -> (u32, u32) {
        let rows = self.panels.len().div_ceil(self.columns);
        let cols = self.columns.min(self.panels.len());
        (
            (self.panel_w * cols as i32 + 20).max(400) as u32,
            (50 + self.panel_h * rows as i32 + 10) as u32,
        )
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        root.fill(&WHITE)?;
        let (w, _) = self.size();
        root.draw(&Text::new(
            self.title.clone(),
            (w as i32 / 2, 24),
            text_style(18.0, BLACK, HPos::Center, VPos::Center),
        ))?;
        let bar = RGBColor(49, 130, 189);
        for (k, p) in self.panels.iter().enumerate() {
            let x0 = 10 + self.panel_w * (k % self.columns) as i32;
            let y0 = 50 + self.panel_h * (k / self.columns) as i32;
            let (px0, px1) = (x0 + 8, x0 + self.panel_w - 8);
            let (py0, py1) = (y0 + 22, y0 + self.panel_h - 24);
            root.draw(&Text::new(
                p.title.clone(),
                ((px0 + px1) / 2, y0 + 10),
                text_style(12.0, BLACK, HPos::Center, VPos::Center),
            ))?;
            let max = p.counts.iter().copied().max().unwrap_or(0).max(1);
            let n = p.counts.len().max(1) as i32;
            for (b, &c) in p.counts.iter().enumerate() {
                let bx0 = px0 + (px1 - px0) * b as i32 / n;
                let bx1 = px0 + (px1 - px0) * (b as i32 + 1) / n;
                let top = py1 - ((py1 - py0) as f64 * c as f64 / max as f64).round() as i32;
                if c > 0 {
                    root.draw(&Rectangle::new(
                        [(bx0, top), (bx1.max(bx0 + 1), py1)],
                        bar.filled(),
                    ))?;
                }
            }
            root.draw(&PathElement::new(
                vec![(px0, py1), (px1, py1)],
                RGBColor(100, 100, 100),
            ))?;
            let grey = RGBColor(80, 80, 80);
            root.draw(&Text::new(
                short(p.lo),
                (px0, py1 + 4),
                text_style(11.0, grey, HPos::Left, VPos::Top),
            ))?;
            root.draw(&Text::new(
                short(p.hi),
                (px1, py1 + 4),
                text_style(11.0, grey, HPos::Right, VPos::Top),
            ))?;
        }
        Ok(())
    }
}

fn short(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e4 || v.abs() < 1e-2 {
        format!("{v:.2e}")
    } else {
        format!("{v:.3}")
    }
}

/// Draws one histogram per dimension of an array, in a grid, as PNG and SVG.
pub fn array_histograms(
    name: &str,
    stats: &ArrayStats,
    png: &Path,
    svg: &Path,
) -> Result<(), StatsError> {
    let panels = (0..stats.width)
        .map(|d| Panel {
            title: stats.columns[d].clone(),
            counts: stats.histogram[d].clone(),
            lo: stats.min[d],
            hi: stats.max[d],
        })
        .collect();
    let grid = PanelGrid {
        title: format!(
            "{name}: per-dimension distribution over {} frames ({HISTOGRAM_BINS} bins)",
            stats.frames
        ),
        panels,
        columns: 8,
        panel_w: 190,
        panel_h: 120,
    };
    save(&grid, png, svg)
}

/// Draws the histogram of episode lengths as PNG and SVG.
pub fn length_histogram(lengths: &LengthStats, png: &Path, svg: &Path) -> Result<(), StatsError> {
    let bins = 30usize;
    let (lo, hi) = (lengths.min as f64, lengths.max as f64);
    let mut counts = vec![0u64; bins];
    for &n in &lengths.lengths {
        let k = if hi > lo {
            ((n as f64 - lo) / (hi - lo) * bins as f64) as usize
        } else {
            0
        };
        counts[k.min(bins - 1)] += 1;
    }
    let grid = PanelGrid {
        title: format!(
            "Episode length in frames ({} episodes)",
            lengths.lengths.len()
        ),
        panels: vec![Panel {
            title: String::new(),
            counts,
            lo,
            hi,
        }],
        columns: 1,
        panel_w: 600,
        panel_h: 300,
    };
    save(&grid, png, svg)
}
