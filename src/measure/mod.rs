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
/// estimate converges to the right answer on every scene, however slowly). Today only the path
/// tracer exists; when BDPT lands it will be the better choice for caustics through media.
pub fn reference_integrator(_scene: &Scene) -> IntegratorKind {
    IntegratorKind::Path
}
// ANCHOR_END: reference_integrator
