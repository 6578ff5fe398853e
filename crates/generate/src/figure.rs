//! The pose-spread figure of a run (`generate_poses.png`): for each placed object, where
//! the sources had it at reset and where the attempts had it (successes and failures),
//! over the spec's placement range, so that one look says whether the generated episodes
//! cover the range. Text uses a font bundled in the binary.

use std::path::Path;
use std::sync::Once;

use dexjoco_core::TaskSpec;
use plotters::prelude::*;

use crate::error::GenerateError;
use crate::record::AttemptRecord;

const FONT: &str = "sans-serif";
const PANEL: (u32, u32) = (420, 400);

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let font = epaint_default_fonts::UBUNTU_LIGHT;
        if plotters::style::register_font(FONT, FontStyle::Normal, font).is_err() {
            tracing::warn!("the bundled font could not be loaded; the figure has no text");
        }
    });
}

/// One placed object's points: (x, y) on its two placement axes.
struct Panel {
    /// `task: object`.
    title: String,
    axes: [String; 2],
    range: [(f64, f64); 2],
    sources: Vec<(f64, f64)>,
    kept: Vec<(f64, f64)>,
    failed: Vec<(f64, f64)>,
}

/// The panels of `spec`'s placed objects from the sources' resets and the attempts'.
fn panels(spec: &TaskSpec, sources: &[Vec<f64>], attempts: &[&AttemptRecord]) -> Vec<Panel> {
    let layout = spec.state_layout();
    spec.placement
        .iter()
        .filter_map(|p| {
            let f = layout.get(&format!("{}.pose", p.object))?;
            let [a, b] = p.axes.map(|x| x.index());
            let at = |s: &[f64]| (s[f.start + a], s[f.start + b]);
            let points = |ok: bool| {
                attempts
                    .iter()
                    .filter(|r| r.success == ok)
                    .map(|r| at(&r.reset))
                    .collect()
            };
            Some(Panel {
                title: format!("{}: {}", spec.id, p.object),
                axes: p.axes.map(|x| format!("{x:?}").to_lowercase()),
                range: [(p.low[0], p.high[0]), (p.low[1], p.high[1])],
                sources: sources.iter().map(|s| at(s)).collect(),
                kept: points(true),
                failed: points(false),
            })
        })
        .collect()
}

/// The extent of a panel's axis: its range and points, with a margin. Points further
/// than twice the range's width from it (a record's nonsense) do not widen it: they are
/// left outside the picture.
fn extent(range: (f64, f64), values: impl Iterator<Item = f64>) -> (f64, f64) {
    let reach = 2.0 * (range.1 - range.0).abs().max(0.01);
    let near = |v: &f64| v.is_finite() && *v >= range.0 - reach && *v <= range.1 + reach;
    let (lo, hi) = values
        .filter(near)
        .fold(range, |(lo, hi), v| (lo.min(v), hi.max(v)));
    let pad = ((hi - lo) * 0.1).max(0.01);
    (lo - pad, hi + pad)
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

fn draw_panel(area: &Area<'_>, p: &Panel) -> Result<(), String> {
    let all = || p.sources.iter().chain(&p.kept).chain(&p.failed);
    let xs = extent(p.range[0], all().map(|q| q.0));
    let ys = extent(p.range[1], all().map(|q| q.1));
    let mut chart = ChartBuilder::on(area)
        .caption(&p.title, (FONT, 16))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(xs.0..xs.1, ys.0..ys.1)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(format!("{} (m)", p.axes[0]))
        .y_desc(format!("{} (m)", p.axes[1]))
        .label_style((FONT, 12))
        .draw()
        .map_err(|e| e.to_string())?;
    let rect = [(p.range[0].0, p.range[1].0), (p.range[0].1, p.range[1].1)];
    chart
        .draw_series([Rectangle::new(rect, BLUE.mix(0.6).stroke_width(1))])
        .map_err(|e| e.to_string())?
        .label("placement range")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], BLUE.mix(0.6)));
    let grey = RGBColor(170, 170, 170);
    chart
        .draw_series(p.failed.iter().map(|&q| Circle::new(q, 3, grey.filled())))
        .map_err(|e| e.to_string())?
        .label(format!("failed ({})", p.failed.len()))
        .legend(move |(x, y)| Circle::new((x + 5, y), 3, grey.filled()));
    let green = RGBColor(40, 160, 60);
    chart
        .draw_series(p.kept.iter().map(|&q| Circle::new(q, 3, green.filled())))
        .map_err(|e| e.to_string())?
        .label(format!("generated ({})", p.kept.len()))
        .legend(move |(x, y)| Circle::new((x + 5, y), 3, green.filled()));
    chart
        .draw_series(
            p.sources
                .iter()
                .map(|&q| Cross::new(q, 6, RED.stroke_width(2))),
        )
        .map_err(|e| e.to_string())?
        .label(format!("sources ({})", p.sources.len()))
        .legend(|(x, y)| Cross::new((x + 5, y), 5, RED.stroke_width(2)));
    chart
        .configure_series_labels()
        .label_font((FONT, 12))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| e.to_string())
}

/// Writes the figure of `spec`'s placed objects as a PNG at `path`; `sources` are the
/// sources' resets (`state[0]`). Nothing is written for a task without placement.
pub fn write_pose_figure(
    path: &Path,
    spec: &TaskSpec,
    sources: &[Vec<f64>],
    attempts: &[&AttemptRecord],
) -> Result<(), GenerateError> {
    let panels = panels(spec, sources, attempts);
    if panels.is_empty() {
        return Ok(());
    }
    register_font();
    let (w, h) = (PANEL.0 * panels.len() as u32, PANEL.1);
    let mut buffer = vec![255u8; (w * h * 3) as usize];
    let err = |e: String| GenerateError::Figure {
        path: path.to_path_buf(),
        message: e,
    };
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        for (area, p) in root.split_evenly((1, panels.len())).iter().zip(&panels) {
            draw_panel(area, p).map_err(err)?;
        }
        root.present().map_err(|e| err(e.to_string()))?;
    }
    let mut png = Vec::new();
    image::write_buffer_with_format(
        &mut std::io::Cursor::new(&mut png),
        &buffer,
        w,
        h,
        image::ExtendedColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|e| err(e.to_string()))?;
    Ok(dexjoco_formats::write_atomic(path, &png)?)
}
