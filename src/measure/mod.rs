//! The measuring instrument: error metrics, statistics (fitted orders of convergence, standard
//! errors over runs, the variance-based noise estimate), equal-time convergence runs, charts
//! and error heatmaps.
//! Book: "Measuring a renderer".

pub mod chart;
pub mod convergence;
pub mod heatmap;
pub mod metrics;
pub mod stats;
pub mod study;

use crate::integrator::IntegratorKind;
use crate::scene::Scene;

// ANCHOR: reference_integrator
/// The integrator a reference is rendered with: the most robust one available (the one whose
/// estimate converges to the right answer on the scene, however slowly). The path tracer cannot
/// sample light that reaches a Dirac light (point, spot) only through singular surfaces (glass,
/// mirrors; [`crate::integrator::reach`]), so such scenes get BDPT; every other scene gets the
/// path tracer, which is faster per sample and has per-pixel variance estimates.
pub fn reference_integrator(scene: &Scene) -> IntegratorKind {
    match crate::integrator::reach::unreachable_paths(scene, IntegratorKind::Path) {
        Some(_) => IntegratorKind::Bdpt,
        None => IntegratorKind::Path,
    }
}
// ANCHOR_END: reference_integrator

/// CPU seconds used by this process so far (user plus system, all threads): the clock of speed
/// comparisons on a shared machine, where wall-clock time measures the other jobs too.
pub fn cpu_seconds() -> f64 {
    // SAFETY: getrusage only writes the struct it is given.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } != 0 {
        return f64::NAN;
    }
    let t = |tv: libc::timeval| tv.tv_sec as f64 + tv.tv_usec as f64 * 1e-6;
    t(usage.ru_utime) + t(usage.ru_stime)
}

/// Why a measurement cannot be taken: images that do not match, or data no power law fits.
/// The messages are the command line's (`pathspace diff`, `converge`).
#[derive(Debug, thiserror::Error)]
pub enum MeasureError {
    /// An image and its reference differ in size.
    #[error("the images differ in size: {0}x{1} against {2}x{3}")]
    SizeMismatch(u32, u32, u32, u32),
    /// A pixel that is NaN or infinite (which image, the pixel): no metric over it is a number.
    #[error("the pixel ({1}, {2}) of {0} is not finite (NaN or infinity): no error metric over it is a number")]
    NotFinite(&'static str, u32, u32),
    /// The twin renders of `diff --twin` and the reference differ in size.
    #[error("the twin renders and the reference differ in size")]
    TwinSizeMismatch,
    /// An estimate and its variance image differ in size.
    #[error("the estimate is {0}x{1} but its variance image is {2}x{3}")]
    VarianceSizeMismatch(u32, u32, u32, u32),
    /// Unequal numbers of x and y values.
    #[error("cannot fit: {0} x values against {1} y values")]
    FitLengths(usize, usize),
    /// A point a log-log fit cannot take.
    #[error("cannot fit a power law through ({0}, {1}): both must be positive and finite")]
    FitNotPositive(f64, f64),
    /// Fewer than two points.
    #[error("cannot fit a slope through {0} point(s): at least 2 are needed")]
    FitTooFew(usize),
    /// Every x is the same: the slope is undefined.
    #[error("cannot fit a slope: every x is the same")]
    FitSameX,
    /// Fewer than two runs give no spread of slopes.
    #[error("combining fits needs at least 2 independent runs, not {0}")]
    CombineTooFew(usize),
    /// Writing an image failed.
    #[error(transparent)]
    Image(#[from] crate::image_io::ImageError),
    /// Drawing a chart or the heatmap's colour bar failed.
    #[error(transparent)]
    Chart(chart::ChartError),
}

/// The command line reports errors as text.
impl From<MeasureError> for String {
    fn from(e: MeasureError) -> String {
        e.to_string()
    }
}
