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
/// mirrors), so scenes with both get BDPT; every other scene gets the path tracer, which is
/// faster per sample and has per-pixel variance estimates.
pub fn reference_integrator(scene: &Scene) -> IntegratorKind {
    let delta_light = scene.lights.iter().any(|l| l.is_delta());
    let singular = scene.shapes.iter().any(|s| {
        s.bsdf
            .as_ref()
            .is_some_and(|b| b.is_singular() && !b.is_null())
    });
    if delta_light && singular {
        IntegratorKind::Bdpt
    } else {
        IntegratorKind::Path
    }
}
// ANCHOR_END: reference_integrator
