//! Image error metrics over all pixels and channels: RMSE = sqrt(mean (a - b)^2) and
//! relMSE = mean (a - b)^2 / (b^2 + epsilon), b the reference.
//! Book: "Measuring a renderer".

use crate::image_io::Image;
use crate::measure::MeasureError;

/// The offset in relMSE's denominator, (a - b)^2 / (b^2 + RELMSE_EPSILON): keeps black
/// reference pixels from dominating.
pub const RELMSE_EPSILON: f64 = 1e-2;

/// Errors of an image against a reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// sqrt of the mean of (a - b)^2 over pixels and channels.
    pub rmse: f64,
    /// Mean over pixels and channels of (a - b)^2 / (b^2 + 1e-2).
    pub relmse: f64,
    /// Largest |a - b|.
    pub max_abs: f64,
}

// ANCHOR: compare
/// Compares `a` against the reference `b`.
pub fn compare(a: &Image, b: &Image) -> Result<Metrics, MeasureError> {
    if a.width != b.width || a.height != b.height {
        return Err(MeasureError::SizeMismatch(
            a.width, a.height, b.width, b.height,
        ));
    }
    let (mut se, mut rel, mut max_abs) = (0.0f64, 0.0f64, 0.0f64);
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let (x, y) = (pa[c] as f64, pb[c] as f64);
            let d = x - y;
            se += d * d;
            rel += d * d / (y * y + RELMSE_EPSILON);
            max_abs = max_abs.max(d.abs());
        }
    }
    let n = (a.pixels.len() * 3).max(1) as f64;
    Ok(Metrics {
        rmse: (se / n).sqrt(),
        relmse: rel / n,
        max_abs,
    })
}
// ANCHOR_END: compare

/// The variance part of relMSE from two independent renders `a1`, `a2` of the same estimator:
/// mean over pixels and channels of (a1 - a2)^2 / 2 / (r^2 + epsilon), with r only weighting the
/// pixels. E[(a1 - a2)^2] / 2 is the variance of one render whatever the reference's own error,
/// so this separates an estimator's noise from a noisy (or biased) reference; relMSE against the
/// reference minus this is the estimator's squared bias plus the reference's error.
// ANCHOR: twin_variance
pub fn twin_variance(a1: &Image, a2: &Image, r: &Image) -> Result<f64, MeasureError> {
    if a1.width != a2.width
        || a1.height != a2.height
        || a1.width != r.width
        || a1.height != r.height
    {
        return Err(MeasureError::TwinSizeMismatch);
    }
    let mut sum = 0.0f64;
    for ((p, q), w) in a1.pixels.iter().zip(&a2.pixels).zip(&r.pixels) {
        for c in 0..3 {
            let d = p[c] as f64 - q[c] as f64;
            let y = w[c] as f64;
            sum += d * d / 2.0 / (y * y + RELMSE_EPSILON);
        }
    }
    Ok(sum / (a1.pixels.len() * 3).max(1) as f64)
}
// ANCHOR_END: twin_variance
