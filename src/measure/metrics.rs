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
    /// Largest distance in f32 values (0: the images are equal, 1: every channel equal or a
    /// neighbour): how a merge of shards compares with the single run.
    pub max_steps: u64,
}

/// How many f32 values lie from `a` to `b` on the ordered line of floats (0: equal, 1:
/// neighbours; -0 and +0 are one value).
pub fn f32_steps(a: f32, b: f32) -> u64 {
    let ordered = |x: f32| {
        let bits = x.to_bits() as i64;
        if bits < 0x8000_0000 {
            bits
        } else {
            0x8000_0000 - bits
        }
    };
    ordered(a).abs_diff(ordered(b))
}

// ANCHOR: compare
/// Compares `a` against the reference `b`.
pub fn compare(a: &Image, b: &Image) -> Result<Metrics, MeasureError> {
    if a.width != b.width || a.height != b.height {
        return Err(MeasureError::SizeMismatch(
            a.width, a.height, b.width, b.height,
        ));
    }
    for (img, which) in [(a, "the image"), (b, "the reference")] {
        if let Some(i) = img.pixels.iter().position(|p| !p.is_finite()) {
            let (x, y) = (i as u32 % img.width, i as u32 / img.width);
            return Err(MeasureError::NotFinite(which, x, y));
        }
    }
    let (mut se, mut rel, mut max_abs) = (0.0f64, 0.0f64, 0.0f64);
    let mut max_steps = 0;
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            max_steps = max_steps.max(f32_steps(pa[c], pb[c]));
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
        max_steps,
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
