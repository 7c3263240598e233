//! The statistics of a convergence study: the order of convergence fitted by least squares on a
//! log-log plot with its standard error, the mean and standard error of a metric over independent
//! runs, and the variance-based noise estimate of a single render without a reference.
//!
//! * Power law: error(t) = C t^s, so log error = log C + s log t, a straight line whose slope s
//!   is fitted by ordinary least squares: s = S_xy / S_xx, se(s) = sqrt(SSR / (n - 2) / S_xx);
//!   over R independent runs, the mean slope with standard error s.d. / sqrt(R).
//! * Plain Monte Carlo: RMSE ~ N^(-1/2), so relMSE and MSE ~ N^(-1) (slope -1), RMSE slope -1/2.
//! * Estimated relMSE: mean over pixels and channels of Var[mean] / (mean^2 + epsilon).
//!
//! Book: "Measuring a renderer".

use crate::image_io::Image;
use crate::measure::metrics::RELMSE_EPSILON;
use crate::measure::MeasureError;

/// A straight line fitted to (log x, log y): y = exp(intercept) x^slope.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PowerLawFit {
    /// The exponent s of y = C x^s: the slope of the log-log line.
    pub slope: f64,
    /// Standard error of the slope from the residuals; NaN with two points (no residual freedom).
    pub slope_stderr: f64,
    /// log C.
    pub intercept: f64,
    /// Number of points fitted.
    pub points: usize,
}

impl PowerLawFit {
    /// The fitted y at `x`.
    pub fn predict(&self, x: f64) -> f64 {
        (self.intercept + self.slope * x.ln()).exp()
    }
}

// ANCHOR: fit_power_law
/// Fits y = C x^s by ordinary least squares on (ln x, ln y).
///
/// Why least squares in log space: a power law is a straight line there, and its slope is the
/// order of convergence whatever the constant C (which depends on the scene and the machine).
/// The standard error is the textbook one for a regression slope,
/// se(s) = sqrt(SSR / (n - 2) / S_xx). It assumes independent residuals: checkpoints of one run
/// share their early samples, so for a convergence curve it is optimistic; with several runs
/// `combine_fits` gives an honest one.
pub fn fit_power_law(x: &[f64], y: &[f64]) -> Result<PowerLawFit, MeasureError> {
    if x.len() != y.len() {
        return Err(MeasureError::FitLengths(x.len(), y.len()));
    }
    if let Some((xi, yi)) = x
        .iter()
        .zip(y)
        .find(|(a, b)| !(**a > 0.0 && **b > 0.0 && a.is_finite() && b.is_finite()))
    {
        return Err(MeasureError::FitNotPositive(*xi, *yi));
    }
    let n = x.len();
    if n < 2 {
        return Err(MeasureError::FitTooFew(n));
    }
    // ASSIGNMENT: fit_power_law
    let lx: Vec<f64> = x.iter().map(|v| v.ln()).collect();
    let ly: Vec<f64> = y.iter().map(|v| v.ln()).collect();
    let mean_x = lx.iter().sum::<f64>() / n as f64;
    let mean_y = ly.iter().sum::<f64>() / n as f64;
    let s_xx: f64 = lx.iter().map(|a| (a - mean_x).powi(2)).sum();
    let s_xy: f64 = lx
        .iter()
        .zip(&ly)
        .map(|(a, b)| (a - mean_x) * (b - mean_y))
        .sum();
    if s_xx <= 0.0 {
        return Err(MeasureError::FitSameX);
    }
    let slope = s_xy / s_xx;
    let intercept = mean_y - slope * mean_x;
    let ssr: f64 = lx
        .iter()
        .zip(&ly)
        .map(|(a, b)| (b - intercept - slope * a).powi(2))
        .sum();
    let slope_stderr = if n > 2 {
        (ssr / (n - 2) as f64 / s_xx).sqrt()
    } else {
        f64::NAN
    };
    Ok(PowerLawFit {
        slope,
        slope_stderr,
        intercept,
        points: n,
    })
    // END ASSIGNMENT
}
// ANCHOR_END: fit_power_law

/// Mean and standard error of the mean of independent values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanStderr {
    pub mean: f64,
    /// sample standard deviation / sqrt(n); 0 for a single value (no spread is known).
    pub stderr: f64,
}

// ANCHOR: combine_fits
/// Combines fits of independent runs: the slope is their mean and its standard error their spread,
/// s.d. / sqrt(R). Unlike the regression error of one run, this one is honest: the checkpoints of a
/// run share their early samples, so its residuals are correlated and understate the uncertainty,
/// while separate runs are independent by construction. Needs R >= 2.
pub fn combine_fits(fits: &[PowerLawFit]) -> Result<PowerLawFit, MeasureError> {
    if fits.len() < 2 {
        return Err(MeasureError::CombineTooFew(fits.len()));
    }
    let slopes: Vec<f64> = fits.iter().map(|f| f.slope).collect();
    let intercepts: Vec<f64> = fits.iter().map(|f| f.intercept).collect();
    let slope = mean_stderr(&slopes);
    Ok(PowerLawFit {
        slope: slope.mean,
        slope_stderr: slope.stderr,
        intercept: mean_stderr(&intercepts).mean,
        points: fits.iter().map(|f| f.points).sum(),
    })
}
// ANCHOR_END: combine_fits

// ANCHOR: mean_stderr
/// The mean of `values` and its standard error s / sqrt(n), with s the unbiased sample standard
/// deviation (n - 1 in the denominator). Independent runs make the values independent.
pub fn mean_stderr(values: &[f64]) -> MeanStderr {
    let n = values.len();
    if n == 0 {
        return MeanStderr {
            mean: f64::NAN,
            stderr: f64::NAN,
        };
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    let stderr = if n > 1 {
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        (var / n as f64).sqrt()
    } else {
        0.0
    };
    MeanStderr { mean, stderr }
}
// ANCHOR_END: mean_stderr

// ANCHOR: estimated_relmse
/// The relMSE a render is expected to have against the (unknown) converged image, estimated from
/// its own samples: mean over pixels and channels of Var[mean] / (mean^2 + epsilon), with
/// Var[mean] the per-pixel sample variance of the mean (`Film::variance_of_mean`).
///
/// For an unbiased estimator E[(mean - truth)^2] = Var[mean], so this is relMSE with the
/// estimate standing in for the reference in the denominator. It sees only variance: bias and
/// rare high-energy paths that were never sampled stay invisible, which is why a reference is
/// still the real test.
pub fn estimated_relmse(mean: &Image, variance_of_mean: &Image) -> Result<f64, MeasureError> {
    if mean.width != variance_of_mean.width || mean.height != variance_of_mean.height {
        return Err(MeasureError::VarianceSizeMismatch(
            mean.width,
            mean.height,
            variance_of_mean.width,
            variance_of_mean.height,
        ));
    }
    let mut sum = 0.0f64;
    for (m, v) in mean.pixels.iter().zip(&variance_of_mean.pixels) {
        for c in 0..3 {
            let mu = m[c] as f64;
            sum += v[c] as f64 / (mu * mu + RELMSE_EPSILON);
        }
    }
    Ok(sum / (mean.pixels.len() * 3).max(1) as f64)
}
// ANCHOR_END: estimated_relmse
