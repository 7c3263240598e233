//! Charts of a convergence study, drawn with plotters as SVG and PNG: relMSE against time on
//! log-log axes (one line per integrator, mean over runs with +- one standard error bars, the
//! fitted power law dashed, its slope in the legend, the reference's own noise as a grey floor)
//! and efficiency against time.
//!
//! Text is drawn with ab_glyph from DejaVu Sans embedded in the binary (`assets/fonts/`), so a
//! machine without fonts or fontconfig draws the same PNG; PNGs are encoded with `png` through
//! `image_io::write_png_rgb8`.
//! Book: "Measuring a renderer".

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::image_io;
use crate::measure::convergence::{Curve, CurvePoint};

/// DejaVu Sans (Bitstream Vera licence, see assets/fonts/LICENSE-DejaVu.txt).
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
/// The family name the charts ask plotters for; it resolves to the embedded font.
pub const FAMILY: &str = "sans-serif";

/// Chart size in pixels: large enough for 18 px labels to stay readable when scaled down in
/// the book.
pub const CHART_SIZE: (u32, u32) = (1000, 700);

/// Registers the embedded font with plotters once per process.
pub fn register_font() -> Result<(), ChartError> {
    static REGISTERED: OnceLock<Result<(), ChartError>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            plotters::style::register_font(FAMILY, FontStyle::Normal, FONT)
                .map_err(|_| ChartError::Font)
        })
        .clone()
}

/// Why a chart cannot be drawn or written; the messages are what `pathspace converge` prints.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ChartError {
    /// The embedded font (DejaVu Sans) does not parse.
    #[error("the embedded chart font could not be read")]
    Font,
    /// No positive finite value for a log axis.
    #[error("nothing to chart: no positive finite values")]
    Nothing,
    /// plotters failed (the chart's stem, its message).
    #[error("drawing the {0} chart: {1}")]
    Drawing(&'static str, String),
    /// The SVG or PNG could not be written (the image layer's message).
    #[error("{0}")]
    Png(String),
}

impl From<ChartError> for String {
    fn from(e: ChartError) -> Self {
        e.to_string()
    }
}

/// Which chart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChartKind {
    /// relMSE against seconds, log-log.
    ErrorVsTime,
    /// 1 / (relMSE x seconds) against seconds, log-log.
    Efficiency,
}

impl ChartKind {
    /// File stem: `error-vs-time` or `efficiency`.
    pub fn stem(self) -> &'static str {
        match self {
            ChartKind::ErrorVsTime => "error-vs-time",
            ChartKind::Efficiency => "efficiency",
        }
    }

    fn value(self, p: &CurvePoint) -> (f64, f64) {
        match self {
            ChartKind::ErrorVsTime => (p.relmse.mean, p.relmse.stderr),
            ChartKind::Efficiency => (p.efficiency.mean, p.efficiency.stderr),
        }
    }
}

/// Colours that stay apart for the colour-blind (Okabe and Ito 2008).
const PALETTE: [RGBColor; 7] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
];

/// A tick label: plain decimals in the middle decades, powers of ten outside.
fn tick(v: &f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (0.01..10_000.0).contains(&a) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// A log-axis range snapped outwards to whole decades, so every axis has at least two labelled
/// powers of ten (plotters labels a log axis only at its decades).
fn log_range(values: impl Iterator<Item = f64>) -> Result<std::ops::Range<f64>, ChartError> {
    let (lo, hi) = values
        .filter(|v| *v > 0.0 && v.is_finite())
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !(lo.is_finite() && hi > 0.0) {
        return Err(ChartError::Nothing);
    }
    let (lo_decade, mut hi_decade) = (lo.log10().floor(), hi.log10().ceil());
    if hi_decade <= lo_decade {
        hi_decade = lo_decade + 1.0;
    }
    Ok(10f64.powf(lo_decade)..10f64.powf(hi_decade))
}

/// A number with three significant digits, in plain decimals where they read well.
fn sig3(v: f64) -> String {
    if (0.01..10_000.0).contains(&v.abs()) {
        let decimals = (2 - v.abs().log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.2e}")
    }
}

/// The legend text of a curve.
fn legend(kind: ChartKind, c: &Curve) -> String {
    match kind {
        ChartKind::ErrorVsTime => match &c.relmse_vs_time {
            Some(f) if f.slope_stderr.is_finite() => {
                format!(
                    "{}: slope {:.2} ± {:.2}",
                    c.integrator, f.slope, f.slope_stderr
                )
            }
            Some(f) => format!("{}: slope {:.2}", c.integrator, f.slope),
            None => c.integrator.clone(),
        },
        ChartKind::Efficiency => match c.last() {
            Some(p) => format!(
                "{}: {} /s at {} s",
                c.integrator,
                sig3(p.efficiency.mean),
                sig3(p.seconds.mean)
            ),
            None => c.integrator.clone(),
        },
    }
}

// ANCHOR: draw_chart
/// Draws one chart on any plotters backend.
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    kind: ChartKind,
    curves: &[Curve],
    reference_relmse: Option<f64>,
) -> Result<(), ChartError> {
    let e =
        |e: DrawingAreaErrorKind<DB::ErrorType>| ChartError::Drawing(kind.stem(), e.to_string());
    root.fill(&WHITE).map_err(e)?;
    let all = || curves.iter().flat_map(|c| c.points.iter());
    let x_range = log_range(all().map(|p| p.seconds.mean))?;
    // the reference's own noise is drawn on the error chart: no curve can fall below it
    let floor =
        reference_relmse.filter(|f| kind == ChartKind::ErrorVsTime && *f > 0.0 && f.is_finite());
    let y_range = log_range(
        all()
            .flat_map(|p| {
                let (m, s) = kind.value(p);
                [m, m + s, m - s]
            })
            .chain(floor),
    )?;
    let (caption, y_desc) = match kind {
        ChartKind::ErrorVsTime => (
            "relMSE against render time (equal-time, log-log)",
            "relMSE (dimensionless)",
        ),
        ChartKind::Efficiency => ("Efficiency 1/(relMSE × time)", "efficiency (1/s)"),
    };
    let mut chart = ChartBuilder::on(root)
        .caption(caption, (FAMILY, 26))
        .margin(16)
        .x_label_area_size(60)
        .y_label_area_size(90)
        .build_cartesian_2d(x_range.clone().log_scale(), y_range.log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("render time, metrics excluded (s)")
        .y_desc(y_desc)
        .axis_desc_style((FAMILY, 22))
        .label_style((FAMILY, 18))
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .draw()
        .map_err(e)?;
    for (i, c) in curves.iter().enumerate() {
        draw_curve(&mut chart, kind, PALETTE[i % PALETTE.len()], c)?;
    }
    if let Some(f) = floor {
        let grey = RGBColor(110, 110, 110);
        let style = ShapeStyle::from(&grey).stroke_width(2);
        chart
            .draw_series(DashedLineSeries::new(
                [(x_range.start, f), (x_range.end, f)],
                4,
                6,
                style,
            ))
            .map_err(e)?
            .label(format!("reference noise: relMSE {f:.2e}"))
            .legend(move |(x, y)| PathElement::new(vec![(x - 4, y), (x + 16, y)], style));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FAMILY, 20))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)
}

/// Draws one curve of a chart: its line (with its legend entry), its points, +- one standard
/// error over runs and, on the error chart, its fitted power law.
fn draw_curve<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>,
    kind: ChartKind,
    colour: RGBColor,
    c: &Curve,
) -> Result<(), ChartError> {
    let e =
        |e: DrawingAreaErrorKind<DB::ErrorType>| ChartError::Drawing(kind.stem(), e.to_string());
    let style = ShapeStyle::from(&colour).stroke_width(3);
    let pts: Vec<(f64, f64)> = c
        .points
        .iter()
        .map(|p| (p.seconds.mean, kind.value(p).0))
        .filter(|(x, y)| *x > 0.0 && *y > 0.0 && y.is_finite())
        .collect();
    chart
        .draw_series(LineSeries::new(pts.clone(), style))
        .map_err(e)?
        .label(legend(kind, c))
        .legend(move |(x, y)| PathElement::new(vec![(x - 4, y), (x + 16, y)], style));
    chart
        .draw_series(pts.iter().map(|&p| Circle::new(p, 5, colour.filled())))
        .map_err(e)?;
    // +- one standard error over runs
    let bars = c.points.iter().filter_map(|p| {
        let (m, s) = kind.value(p);
        (s > 0.0 && m - s > 0.0).then(|| {
            PathElement::new(
                vec![(p.seconds.mean, m - s), (p.seconds.mean, m + s)],
                ShapeStyle::from(&colour).stroke_width(2),
            )
        })
    });
    chart.draw_series(bars).map_err(e)?;
    if let (ChartKind::ErrorVsTime, Some(fit), Some(first), Some(last)) =
        (kind, c.relmse_vs_time, c.points.first(), c.points.last())
    {
        let ends = [first.seconds.mean, last.seconds.mean].map(|t| (t, fit.predict(t)));
        chart
            .draw_series(DashedLineSeries::new(
                ends,
                10,
                8,
                ShapeStyle::from(&colour.mix(0.6)).stroke_width(2),
            ))
            .map_err(e)?;
    }
    Ok(())
}
// ANCHOR_END: draw_chart

/// Writes `DIR/<stem>.svg` and `DIR/<stem>.png` for both charts; returns the files written.
/// `reference_relmse`, the reference's own estimated relMSE, is drawn as the floor of the error
/// chart when known.
pub fn write_charts(
    dir: &Path,
    curves: &[Curve],
    reference_relmse: Option<f64>,
) -> Result<Vec<PathBuf>, ChartError> {
    let mut written = Vec::new();
    for kind in [ChartKind::ErrorVsTime, ChartKind::Efficiency] {
        let [svg, png] = chart_files(dir, kind);
        write_svg(&svg, kind, curves, reference_relmse)?;
        write_png(&png, kind, curves, reference_relmse)?;
        written.push(svg);
        written.push(png);
    }
    Ok(written)
}

/// The SVG and PNG of a chart in `dir`.
fn chart_files(dir: &Path, kind: ChartKind) -> [PathBuf; 2] {
    ["svg", "png"].map(|ext| dir.join(format!("{}.{ext}", kind.stem())))
}

/// Every file [`write_charts`] writes into `dir`, to be checked before the study runs.
pub fn chart_paths(dir: &Path) -> Vec<PathBuf> {
    [ChartKind::ErrorVsTime, ChartKind::Efficiency]
        .into_iter()
        .flat_map(|kind| chart_files(dir, kind))
        .collect()
}

/// Draws a chart as SVG.
pub fn write_svg(
    path: &Path,
    kind: ChartKind,
    curves: &[Curve],
    reference_relmse: Option<f64>,
) -> Result<(), ChartError> {
    register_font()?;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, CHART_SIZE).into_drawing_area();
        draw(&root, kind, curves, reference_relmse)?;
    }
    // drawn in memory, then written through a temporary file: a full disk is reported, and
    // leaves an earlier chart whole
    image_io::write_file_replacing(path, text.as_bytes())
        .map_err(|e| ChartError::Png(e.to_string()))
}

/// Draws a chart as PNG.
pub fn write_png(
    path: &Path,
    kind: ChartKind,
    curves: &[Curve],
    reference_relmse: Option<f64>,
) -> Result<(), ChartError> {
    register_font()?;
    let (w, h) = CHART_SIZE;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, CHART_SIZE).into_drawing_area();
        draw(&root, kind, curves, reference_relmse)?;
    }
    image_io::write_png_rgb8(path, w, h, &buf).map_err(|e| ChartError::Png(e.to_string()))
}
