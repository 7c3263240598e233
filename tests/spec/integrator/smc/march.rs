//! SMC in inhomogeneous media and the safeguards of its adaptive densities (Pegoraro, Wald,
//! Parker 2008, eq. 1, 8, 9; book: "SMC: the estimators", section "Deviations").
//!
//! - The march reads the medium along every step: through an absorbing slab whose density
//!   varies along the ray, it transmits exactly exp(-integral sigma_t), the closed form, and
//!   with scattering it agrees with the path tracer on an inhomogeneous cloud.
//! - The defensive mixture samples what its density says (chi-square over the sphere).
//! - The cache holds no negative radiance, whatever the records.

use crate::common;

use common::stats::Family;
use glam::Vec3;
use pathspace::integrator::smc::cache::RadianceCache;
use pathspace::integrator::smc::{
    defensive_direction, ControlVariate, EstimatorForm, SmcSettings, Variant,
};
use pathspace::integrator::{IntegratorKind, RenderSettings, Renderer};
use pathspace::math::{Frame, Sampler};
use pathspace::medium::Phase;
use pathspace::scene::{Scene, SceneSource};
use pathspace::spectrum::Rgb;

/// A camera looking straight down, through an absorbing slab between z = -1 and z = 0 whose
/// density grows linearly from 0.1 at its bottom to 1 at its top (where rays enter), at an
/// emitter of radiance 1 below it. The optical depth along the axis is sigma_a (1 + 0.1) / 2 =
/// 1.1; the field of view is 1 degree, so every ray's is within 5e-5 of it.
fn absorbing_gradient_slab() -> Scene {
    let text = r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, -2.0]
up = [0.0, 1.0, 0.0]
fov_deg = 1.0
resolution = [4, 4]

[media.slab]
type = "procedural"
density = "linear"
axis = "z"
from = 0.1
to = 1.0
min = [-3.0, -3.0, -1.0]
max = [3.0, 3.0, 0.0]
sigma_a = 2.0
sigma_s = 0.0

[[shapes]]
type = "box"
min = [-3.0, -3.0, -1.0]
max = [3.0, 3.0, 0.0]
material = "null"
interior = "slab"

[[shapes]]
type = "quad"
origin = [-3.0, -3.0, -2.0]
u = [6.0, 0.0, 0.0]
v = [0.0, 6.0, 0.0]
emission = 1.0
"#;
    Scene::load(&SceneSource::embedded("gradient-slab", text)).unwrap()
}

/// Through an absorber the march never scatters and its kappa_t are exact optical depths, so
/// every pixel is exp(-1.1) to rounding. (Reading sigma once where the ray enters the box, where
/// the density is 1, gave exp(-2).) The distance form samples the same transmittance by free
/// flights, so its mean over independent renders is compared by its standard error.
#[test]
fn the_march_transmits_exp_minus_the_optical_depth_of_an_inhomogeneous_absorber() {
    let scene = absorbing_gradient_slab();
    let truth = (-1.1f64).exp();
    let render = |form, seed| {
        let settings = SmcSettings {
            form,
            ..SmcSettings::default()
        };
        let mut r = Renderer::new(&scene, IntegratorKind::Smc, seed, None)
            .with_settings(&RenderSettings {
                smc: settings,
                ..RenderSettings::for_scene(&scene)
            })
            .unwrap();
        for _ in 0..4 {
            r.pass(4, &|| {});
        }
        r.film.as_ref().unwrap().image()
    };
    for step in [1.0, 0.25] {
        let img = render(EstimatorForm::RayMarching { step }, 3);
        for p in &img.pixels {
            assert!(
                (p.x as f64 - truth).abs() < 2e-4 * truth,
                "march step {step}: {} vs exp(-1.1) = {truth}",
                p.x
            );
        }
    }
    let mut fam = Family::new("smc_media: distance form through an inhomogeneous absorber");
    let means: Vec<f64> = (0..8)
        .map(|seed| render(EstimatorForm::Distance, 10 + seed).mean().x as f64)
        .collect();
    fam.runs_are("distance form transmittance", &means, truth);
    fam.finish();
}

/// The heterogeneous cloud of Pauly et al.'s Fig. 3 (`scenes/cloud.toml` with delta tracking)
/// at 8 x 8: the mean of 16 SMC renders of every variant in the march form against 16 path
/// tracer renders (Welch). Before the march read the medium along its steps, every variant
/// rendered the cloud 16% dark.
#[test]
fn every_variant_of_the_march_agrees_with_the_path_tracer_in_a_cloud() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cloud.toml"))
        .unwrap()
        .replace("resolution = [128, 128]", "resolution = [8, 8]")
        .replace(
            "propagation = \"random-offset\"",
            "propagation = \"delta-tracking\"",
        );
    let scene = Scene::load(&SceneSource::embedded("cloud.toml", &text)).unwrap();
    let image_mean = |r: &Renderer| r.film.as_ref().unwrap().image().mean().x as f64;
    let runs = 16u64;
    let path: Vec<f64> = (0..runs)
        .map(|s| {
            let mut r = Renderer::new(&scene, IntegratorKind::Path, 500 + s, None);
            r.pass(32, &|| {});
            image_mean(&r)
        })
        .collect();
    let mut fam = Family::new("smc_media: the march in the cloud");
    for variant in Variant::ALL {
        let smc: Vec<f64> = (0..runs)
            .map(|s| {
                let settings = SmcSettings {
                    variant,
                    ..SmcSettings::default()
                };
                let mut r = Renderer::new(&scene, IntegratorKind::Smc, 600 + s, None)
                    .with_settings(&RenderSettings {
                        smc: settings,
                        ..RenderSettings::for_scene(&scene)
                    })
                    .unwrap();
                for _ in 0..4 {
                    r.pass(4, &|| {});
                }
                image_mean(&r)
            })
            .collect();
        fam.runs_agree(&format!("cloud {}", variant.name()), &smc, &path);
    }
    fam.finish();
}

/// A cache whose pdf is complete and far from uniform: one cell holds almost all the mass.
fn skewed_cache() -> RadianceCache {
    let mut cache = RadianceCache::root();
    let grid = cache.grid();
    let mut s = Sampler::new(7, 7, 0);
    for i in 0..4000 {
        let wi = pathspace::math::warp::uniform_sphere(s.next_2d());
        let cell = grid.cell_of_direction(wi);
        let radiance = if cell == 0 {
            50.0
        } else {
            0.01 * (1 + i % 3) as f32
        };
        cache.write(wi, Rgb::splat(radiance), 1.0, ControlVariate::Order1);
    }
    assert!(cache.pdf_is_positive());
    cache
}

/// `defensive_direction` draws from (1 - DEFENSIVE) p_cache + DEFENSIVE f_p and returns that
/// density: a chi-square over the sphere for an isotropic and a forward phase function.
#[test]
fn the_defensive_mixture_samples_its_density() {
    let cache = skewed_cache();
    let frame = Frame::from_normal(Vec3::new(0.3, -0.2, 0.9).normalize());
    let wo = -frame.n;
    let grid = common::SphereGrid::new(frame, 16, 16);
    let mut fam = Family::new("smc_media: the defensive mixture's density");
    for phase in [Phase::Isotropic, Phase::henyey_greenstein(0.7).unwrap()] {
        let mut s = Sampler::new(11, 0, 0);
        let n = 400_000;
        let mut bad_pdf = 0u64;
        let observed = grid.observe(
            || {
                let (wi, pdf) = defensive_direction(&cache, &phase, wo, &mut s);
                let expect = (1.0 - pathspace::integrator::smc::DEFENSIVE) * cache.pdf(wi) as f64
                    + pathspace::integrator::smc::DEFENSIVE * phase.pdf(wo, wi) as f64;
                if ((pdf as f64) - expect).abs() > 1e-3 * expect {
                    bad_pdf += 1;
                }
                Some(wi)
            },
            n,
        );
        // a returned density may differ from the formula only on cell borders (rounding)
        assert!(
            bad_pdf * 1000 < n,
            "{bad_pdf} returned densities differ from the mixture"
        );
        let expected = grid.expected(
            |w| {
                (1.0 - pathspace::integrator::smc::DEFENSIVE) * cache.pdf(w) as f64
                    + pathspace::integrator::smc::DEFENSIVE * phase.pdf(wo, w) as f64
            },
            n,
        );
        fam.chi_square(&format!("mixture with {phase:?}"), &observed, &expected);
    }
    fam.finish();
}

/// A negative record (the combined estimator dips below zero where g exceeds f) is written as
/// zero radiance: the cache's reconstruction never goes negative, so it cannot feed the next
/// estimates a negative control variate (the divergence of is1 with control variates behind
/// glass came from that loop).
#[test]
fn the_cache_holds_no_negative_radiance() {
    for cv in [ControlVariate::Order0, ControlVariate::Order1] {
        let mut cache = RadianceCache::root();
        let mut s = Sampler::new(3, 0, 0);
        for i in 0..2000 {
            let wi = pathspace::math::warp::uniform_sphere(s.next_2d());
            let r = if i % 2 == 0 { -1.0e6 } else { 0.5 };
            cache.write(wi, Rgb::splat(r), 1.0, cv);
        }
        for _ in 0..2000 {
            let wi = pathspace::math::warp::uniform_sphere(s.next_2d());
            assert!(cache.radiance(wi, cv).min_element() >= 0.0, "{cv:?}");
        }
        assert!(cache.integral(cv).min_element() >= 0.0);
    }
}

/// A slab of optical thickness `tau` (sigma_t = 1, top at z = 0) and half-width `w` with a
/// Henyey-Greenstein g = 0.8 phase function under a beam at 60 degrees, and a 1 x 1 irradiance
/// meter 0.001 below it (`transmitted`) or above it: the forward-scattering slabs of
/// `tests/oracles/slab.rs` on which is1 was biased low.
fn forward_slab(tau: f64, albedo: f64, w: f64, transmitted: bool) -> Scene {
    let sensor = if transmitted {
        format!(
            "origin = [-0.5, -0.5, {}]\nu = [1.0, 0.0, 0.0]\nv = [0.0, 1.0, 0.0]",
            -tau - 1e-3
        )
    } else {
        "origin = [-0.5, -0.5, 0.001]\nu = [0.0, 1.0, 0.0]\nv = [1.0, 0.0, 0.0]".to_string()
    };
    let text = format!(
        r#"[media.slab]
type = "homogeneous"
sigma_a = {sigma_a}
sigma_s = {albedo}
phase = {{ type = "hg", g = 0.8 }}

[[shapes]]
type = "box"
min = [-{w}, -{w}, -{tau}]
max = [{w}, {w}, 0.0]
material = "null"
interior = "slab"

[[lights]]
type = "directional"
direction = [0.8660254, 0.0, -0.5]
irradiance = 1.0

[[sensors]]
type = "irradiance_meter"
name = "meter"
{sensor}
"#,
        sigma_a = 1.0 - albedo
    );
    Scene::load(&SceneSource::embedded("forward-slab.toml", &text)).unwrap()
}

/// is1 (the cache's pdf, defensively mixed with the phase function) agrees with the path
/// tracer on two forward-scattering slabs (HG g = 0.8, beam at 60 degrees): the reflection of
/// a conservative slab of tau 5 and the transmission of a slab of tau 10, albedo 0.9. Before
/// the cache's pdf was confined to the first [`pathspace::integrator::smc::ADAPTIVE_DEPTH`]
/// vertices (with the phase function before the pdf is complete, and the march's analog choice
/// between Omega_t and Omega_s), is1 multiplied every vertex of these long forward paths by a
/// weight f_p / p of mean one and negative mean logarithm, and 32 runs of 2 passes came out
/// 0.141 +- 0.009 (is1_cv0) against 0.252 for the reflection; with the pdf at every vertex
/// (the rest as now) the transmission came out 0.0148 +- 0.0008 against 0.0230. The standard
/// errors come from the spread of independent runs (the cache adapts between passes).
#[test]
fn is1_agrees_with_the_path_tracer_on_forward_scattering_slabs() {
    const RUNS: u64 = 32;
    const PASSES: u32 = 2;
    const SAMPLES: u64 = 1024;
    const PATH_SAMPLES: u64 = 1 << 16;
    let mut fam = Family::new("smc_media: is1 on forward-scattering slabs");
    for (k, (tau, albedo, w, transmitted)) in [(5.0, 1.0, 8.0, false), (10.0, 0.9, 30.4, true)]
        .into_iter()
        .enumerate()
    {
        let scene = forward_slab(tau, albedo, w, transmitted);
        let mut r = Renderer::new(&scene, IntegratorKind::Path, 700 + k as u64, None);
        r.meter_samples = PATH_SAMPLES;
        r.pass(1, &|| {});
        let e = r.meter_estimates().remove(0);
        let path = (e.value.x as f64, e.stderr.x as f64, (e.samples - 1) as f64);
        for variant in [Variant::ALL[3], Variant::SMC] {
            let runs: Vec<f64> = (0..RUNS)
                .map(|s| {
                    let settings = SmcSettings {
                        variant,
                        ..SmcSettings::default()
                    };
                    let seed = 800 + 100 * k as u64 + s;
                    let mut r = Renderer::new(&scene, IntegratorKind::Smc, seed, None)
                        .with_settings(&RenderSettings {
                            smc: settings,
                            ..RenderSettings::for_scene(&scene)
                        })
                        .unwrap();
                    r.meter_samples = SAMPLES;
                    for _ in 0..PASSES {
                        r.pass(1, &|| {});
                    }
                    assert_eq!(r.nan_count, 0);
                    r.meter_estimates()[0].value.x as f64
                })
                .collect();
            let what = format!(
                "{} tau {tau} albedo {albedo} g 0.8 at 60 degrees: {}",
                variant.name(),
                if transmitted { "T" } else { "R" }
            );
            let smc = common::stats::runs_mean(&runs);
            // shown with --nocapture
            eprintln!(
                "{what}: {:.4e} +- {:.1e} vs path {:.4e} +- {:.1e}",
                smc.0, smc.1, path.0, path.1
            );
            fam.means_agree(&what, smc, path);
        }
    }
    fam.finish();
}
