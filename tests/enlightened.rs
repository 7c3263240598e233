//! Executable specification of enlightened local path sampling (Kristensen 2010, ch. 5; book
//! chapter "Enlightened local path sampling: the adjoint image and particles").
//!
//! - Particles are unbiased (the thesis's test T16): summed photon weights on a surface patch
//!   reproduce <W_e, L_i> of an irradiance meter on that patch, summed importon weights on the
//!   light reproduce <L_e, W_i> of the same meter, each within 4 standard errors of an
//!   independent path-tracer estimate of the meter, in an empty room and in fog.
//! - Particle lists are identical whatever the thread count.
//!
//! Standard errors of particle sums come from independent batches (each batch one seed): the
//! particles of one path are correlated, batches are not.

mod common;

use pathspace::enlightened::particles::{trace_importons, trace_photons, ImportonSource, Particle};
use pathspace::integrator::bdpt::{Bdpt, Strategies};
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::scene::{Scene, SceneSource};

fn load(text: &str) -> Scene {
    Scene::load(&SceneSource::embedded("test.toml", text)).unwrap_or_else(|e| panic!("{e}"))
}

/// The patch of the floor (y = -1) the test meter covers: x, z in [-PATCH, PATCH].
const PATCH: f32 = 0.4;
/// The meter floats this far above the floor (meters are virtual and must not coincide with
/// geometry); the irradiance changes by O(1e-3) relative over this gap, below the test's error.
const METER_LIFT: f32 = 1e-3;
/// Emitted radiance of the ceiling light (x, z in [-0.25, 0.25] at y = 0.999, facing down).
const LE: f32 = 10.0;

/// A closed box room lit by a ceiling quad, with a meter over the floor patch, optionally
/// filled with fog (the fog box's geometry and medium).
fn room(fog: bool) -> Scene {
    let mut text = pathspace::scene::FOG_BOX.replace("[camera]", "[unused_camera]");
    // drop the camera table: only the meter is measured
    let start = text.find("[unused_camera]").unwrap();
    let end = text[start..].find("[materials.white]").unwrap() + start;
    text.replace_range(start..end, "");
    if !fog {
        text = text.replace(
            "sigma_a = 0.1\nsigma_s = 0.4",
            "sigma_a = 0.0\nsigma_s = 0.0",
        );
    }
    text.push_str(&format!(
        "\n[[sensors]]\ntype = \"irradiance_meter\"\nname = \"floor\"\n\
         origin = [{p0}, {y}, {p0}]\nu = [0.0, 0.0, {s}]\nv = [{s}, 0.0, 0.0]\n",
        p0 = -PATCH,
        y = -1.0 + METER_LIFT,
        s = 2.0 * PATCH
    ));
    load(&text)
}

/// The path tracer's meter estimate (value, standard error), green channel.
fn meter_truth(scene: &Scene, spp: u32) -> (f64, f64) {
    let mut r = Renderer::new(scene, IntegratorKind::Path, 99, None);
    r.pass(spp, &|| {});
    let m = &r.meter_estimates()[0];
    (m.value.y as f64, m.stderr.y as f64)
}

/// Mean and standard error of batch estimates.
fn batch_stats(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

fn on_floor_patch(p: &Particle) -> bool {
    p.normal.is_some()
        && (p.position.y + 1.0).abs() < 1e-4
        && p.position.x.abs() <= PATCH
        && p.position.z.abs() <= PATCH
        && p.direction.y > 0.0
}

fn on_light(p: &Particle) -> bool {
    p.normal.is_some()
        && (p.position.y - 0.999).abs() < 1e-4
        && p.position.x.abs() <= 0.25
        && p.position.z.abs() <= 0.25
        && p.direction.y < 0.0
}

fn assert_agrees(what: &str, (a, sa): (f64, f64), (b, sb): (f64, f64)) {
    let tol = common::SIGMA_BOUND * (sa * sa + sb * sb).sqrt();
    eprintln!("{what}: particles {a} +- {sa}, path tracer {b} +- {sb}");
    assert!(
        (a - b).abs() <= tol && sa > 0.0,
        "{what}: particle estimate {a} +- {sa} vs meter {b} +- {sb} (tolerance {tol})"
    );
}

/// T16 for the classical tracer: photons give <W_e, L_i>, importons give <L_e, W_i>.
#[test]
fn classical_particles_reproduce_the_meter() {
    const BATCHES: u64 = 24;
    const PATHS: u64 = 16_384;
    for fog in [false, true] {
        let scene = room(fog);
        let bdpt = Bdpt::new(&scene, None, Strategies::All);
        let area = (2.0 * PATCH as f64) * (2.0 * PATCH as f64);
        let mut photon = Vec::new();
        let mut importon = Vec::new();
        for b in 0..BATCHES {
            let ph = trace_photons(&scene, &bdpt, PATHS, 1000 + b);
            // W_e = 1 / A on the patch's front side
            photon.push(
                ph.iter()
                    .filter(|p| on_floor_patch(p))
                    .map(|p| p.weight.y as f64)
                    .sum::<f64>()
                    / area,
            );
            let im = trace_importons(&scene, &bdpt, ImportonSource::Meter(0), PATHS, 2000 + b);
            importon.push(
                im.iter()
                    .filter(|p| on_light(p))
                    .map(|p| (p.weight.y * LE) as f64)
                    .sum::<f64>(),
            );
            if fog && b == 0 {
                assert!(
                    ph.iter().any(|p| p.medium.is_some() && p.normal.is_none()),
                    "fog: photons in the medium"
                );
            }
        }
        let truth = meter_truth(&scene, 64);
        let tag = if fog { "fog" } else { "empty" };
        assert_agrees(&format!("photons ({tag})"), batch_stats(&photon), truth);
        assert_agrees(&format!("importons ({tag})"), batch_stats(&importon), truth);
    }
}

/// Particle lists do not depend on the thread count.
#[test]
fn particles_are_identical_with_any_thread_count() {
    let scene = room(true);
    let bdpt = Bdpt::new(&scene, None, Strategies::All);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| trace_photons(&scene, &bdpt, 10_000, 5))
    };
    let (a, b) = (run(1), run(3));
    assert!(!a.is_empty());
    assert_eq!(a, b);
}
