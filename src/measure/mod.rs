//! The measuring instrument: error metrics, statistics (fitted orders of convergence, standard
//! errors over runs, the variance-based noise estimate), equal-time convergence runs, charts
//! and error heatmaps.
//! Book: "Measuring a renderer".

pub mod chart;
pub mod convergence;
pub mod heatmap;
pub mod metrics;
pub mod stats;

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
