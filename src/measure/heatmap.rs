//! A false-colour image of the per-pixel relative error of an image against a reference: where
//! in the picture an integrator is noisy or biased.
//!
//! * Per pixel: e = sqrt( (1/3) sum_c (a_c - b_c)^2 / (b_c^2 + epsilon) ), the root of the
//!   pixel's share of relMSE (same epsilon), so the mean of e^2 over the image is relMSE.
//! * Colour: viridis (perceptually uniform, readable in greyscale and by the colour-blind;
//!   van der Walt and Smith 2015) of log10 e, linear from `LOG10_MIN` to `LOG10_MAX` and clamped;
//!   non-finite pixels take the top colour.
//!
//! Book: "Measuring a renderer".

use std::path::Path;

use crate::image_io::{self, Image};
use crate::measure::chart::{self, ChartError};
use crate::measure::metrics::RELMSE_EPSILON;
use crate::measure::MeasureError;

/// The darkest colour stands for this relative error (0.1 %) and anything below.
pub const LOG10_MIN: f64 = -3.0;
/// The brightest colour stands for this relative error (100 %) and anything above.
pub const LOG10_MAX: f64 = 0.0;

/// matplotlib's viridis sampled at 0, 1/8, ..., 1; linear in between.
pub const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 45, 123],
    [59, 82, 139],
    [44, 114, 142],
    [33, 145, 140],
    [40, 174, 128],
    [94, 201, 98],
    [173, 220, 48],
    [253, 231, 37],
];

// ANCHOR: relative_error
/// The per-pixel relative error of `a` against the reference `b` (row-major).
pub fn relative_error(a: &Image, b: &Image) -> Result<Vec<f64>, MeasureError> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(MeasureError::SizeMismatch(
            a.width, a.height, b.width, b.height,
        ));
    }
    Ok(a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(pa, pb)| {
            let sum: f64 = (0..3)
                .map(|c| {
                    let (x, y) = (pa[c] as f64, pb[c] as f64);
                    (x - y).powi(2) / (y * y + RELMSE_EPSILON)
                })
                .sum();
            (sum / 3.0).sqrt()
        })
        .collect())
}
// ANCHOR_END: relative_error

/// The colour of a value t in [0, 1] (clamped) on viridis.
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (lo, hi) = (VIRIDIS[i], VIRIDIS[i + 1]);
    [0, 1, 2].map(|c| (lo[c] as f64 + f * (hi[c] as f64 - lo[c] as f64)).round() as u8)
}

/// The colour of a relative error `e` under the documented mapping.
pub fn error_colour(e: f64) -> [u8; 3] {
    if !e.is_finite() {
        return viridis(1.0);
    }
    let l = if e > 0.0 { e.log10() } else { LOG10_MIN };
    viridis((l - LOG10_MIN) / (LOG10_MAX - LOG10_MIN))
}

/// The mapping as text, one stop per line: `#rrggbb  relative error`.
pub fn legend_lines() -> Vec<(String, f64)> {
    (0..VIRIDIS.len())
        .map(|i| {
            let t = i as f64 / (VIRIDIS.len() - 1) as f64;
            let [r, g, b] = VIRIDIS[i];
            (
                format!("#{r:02x}{g:02x}{b:02x}"),
                10f64.powf(LOG10_MIN + t * (LOG10_MAX - LOG10_MIN)),
            )
        })
        .collect()
}

/// Width in pixels of the colour bar's panel right of the heatmap.
pub const BAR_PANEL: u32 = 120;
/// The canvas is at least this tall, so a small image still gets a readable bar.
pub const BAR_MIN_HEIGHT: u32 = 200;
/// The bar's left edge and width within its panel, and its margin to the canvas's top and
/// bottom, in pixels.
pub const BAR_X: u32 = 14;
pub const BAR_W: u32 = 22;
pub const BAR_MARGIN: u32 = 14;

/// Writes the heatmap of `a` against the reference `b` as a PNG: the heatmap pixel for pixel
/// in the top-left `width x height` pixels (so that it can be cropped and laid over the
/// images), and right of it a colour bar labelled at each decade of the relative error.
pub fn write_heatmap(path: &Path, a: &Image, b: &Image) -> Result<(), MeasureError> {
    let errors = relative_error(a, b)?;
    let (w, h) = (a.width + BAR_PANEL, a.height.max(BAR_MIN_HEIGHT));
    let mut canvas = vec![255u8; (w as usize) * (h as usize) * 3];
    for (i, &e) in errors.iter().enumerate() {
        let (x, y) = (i as u32 % a.width, i as u32 / a.width);
        let at = ((y * w + x) * 3) as usize;
        canvas[at..at + 3].copy_from_slice(&error_colour(e));
    }
    let (top, bottom) = (BAR_MARGIN, h - BAR_MARGIN);
    for y in top..bottom {
        let t = (bottom - 1 - y) as f64 / (bottom - 1 - top) as f64;
        for x in a.width + BAR_X..a.width + BAR_X + BAR_W {
            let at = ((y * w + x) * 3) as usize;
            canvas[at..at + 3].copy_from_slice(&viridis(t));
        }
    }
    label_bar(
        &mut canvas,
        (w, h),
        a.width + BAR_X + BAR_W + 6,
        (top, bottom),
    )?;
    Ok(image_io::write_png_rgb8(path, w, h, &canvas)?)
}

/// Writes the decades of the scale beside the bar that spans rows `top..bottom`.
fn label_bar(
    canvas: &mut [u8],
    size: (u32, u32),
    x: u32,
    (top, bottom): (u32, u32),
) -> Result<(), MeasureError> {
    use plotters::prelude::*;
    let font_error = |e: String| MeasureError::Chart(ChartError::Drawing("heatmap", e));
    chart::register_font().map_err(MeasureError::Chart)?;
    let root = BitMapBackend::with_buffer(canvas, size).into_drawing_area();
    let style = (chart::FAMILY, 15).into_font().color(&BLACK);
    let decades = (LOG10_MAX - LOG10_MIN).round() as i32;
    for k in 0..=decades {
        let t = k as f64 / decades as f64;
        let y = bottom as f64 - 1.0 - t * (bottom - 1 - top) as f64;
        let percent = 10f64.powf(LOG10_MIN + t * (LOG10_MAX - LOG10_MIN)) * 100.0;
        let text = format!("{}%", (percent * 1e6).round() / 1e6);
        root.draw_text(&text, &style, (x as i32, y as i32 - 7))
            .map_err(|e| font_error(e.to_string()))?;
    }
    root.present().map_err(|e| font_error(e.to_string()))
}
