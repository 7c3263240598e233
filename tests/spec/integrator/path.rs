//! The path tracer with the guide (Kristensen 2010, sec. 5.3) or with the halo cone: its surface
//! and medium vertices sample directions from a mixture, and every MIS weight of its walk
//! evaluates the density it sampled with. The plain path tracer is judged by
//! `oracles::transport` and the agreement matrix (`path`, `path+guide`, `path+halo` columns).
//! Book: "Enlightened local path sampling: guiding", section "The path tracer"; "Sampling
//! toward lights", section "The scattering direction".

use crate::common;

use std::sync::Arc;

use glam::{Vec2, Vec3};
use pathspace::bidir::WalkLimits;
use pathspace::bsdf::TransportMode;
use pathspace::enlightened::guide::{build_guide, scatter_pdf};
use pathspace::enlightened::{Enlightened, GuideKind, GuideSettings};
use pathspace::integrator::bdpt::{Bdpt, Strategies};
use pathspace::integrator::path::{DistanceSampling, PathTracer};
use pathspace::integrator::{IntegratorKind, RenderSettings, Renderer, Setup};
use pathspace::math::Sampler;
use pathspace::path::{LocalSampling, Vertex, VertexKind, PLAIN};
use pathspace::scene::{Scene, SceneSource};

use common::stats::Family;

/// The map's share c of the tests' guides: not 1/2, so that exchanging c and 1 - c shows.
const GUIDE_WEIGHT: f32 = 0.3;

/// The fog box at `w` x `w` pixels.
fn fog_box(w: u32) -> Scene {
    let text = pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{w}, {w}]"),
    );
    Scene::load(&SceneSource::embedded("fog-box", &text)).expect("valid fog box")
}

/// A coarse guide of both kinds of vertices for `scene` (20 000 subpaths of each kind, 64
/// regions, 16x8 maps, map share [`GUIDE_WEIGHT`]).
fn guided(scene: &Scene) -> Enlightened {
    let mut settings = GuideSettings::for_radius(scene.radius);
    settings.c_guide = GUIDE_WEIGHT;
    settings.particles = 20_000;
    settings.regions.regions = 64;
    settings.cols = 16;
    settings.rows = 8;
    guide_of(scene, settings)
}

/// The guide of `settings` for `scene`, guiding both kinds of vertices.
fn guide_of(scene: &Scene, mut settings: GuideSettings) -> Enlightened {
    settings.kind = GuideKind::Both;
    Enlightened {
        guide: Some(Arc::new(build_guide(scene, &PLAIN, settings))),
        adjoint: None,
    }
}

/// Eye-walk vertices of the fog box (surface or medium) that the radiance maps guide, with the
/// direction they were reached from.
fn guided_vertices(
    scene: &Scene,
    tech: &Enlightened,
    medium: bool,
    count: usize,
) -> Vec<(Vertex, Vec3)> {
    let g = tech.guide.as_deref().unwrap();
    let b = Bdpt::new(&PLAIN, Some(4), Strategies::All);
    let cam = scene.camera.as_ref().unwrap();
    let (mut s, mut eye, mut out) = (Sampler::new(41, 0, 0), Vec::new(), Vec::new());
    while out.len() < count {
        let raster = s.next_2d() * Vec2::new(cam.width as f32, cam.height as f32);
        b.camera_subpath(scene, raster, WalkLimits::BDPT, &mut s, &mut eye);
        let found = (1..eye.len()).find(|&i| {
            eye[i].is_medium() == medium
                && g.map_at(scene, &eye[i], TransportMode::Radiance).is_some()
        });
        if let Some(i) = found {
            out.push((eye[i], (eye[i - 1].p - eye[i].p).normalize()));
        }
    }
    out
}

/// The path tracer's density of a direction is the guide's mixture (1 - c) p_local + c p_map
/// (eq. 5.18; the phase function's in a medium), the density `guide::scatter_pdf` gives and
/// `LocalSampling::scatter_pdf` evaluates for BDPT's MIS; each direction it samples carries
/// that density; and the samples weighted by it estimate the local model's integral: the
/// albedo at a Lambertian wall, 1 for the phase function.
#[test]
fn guided_path_tracer_samples_and_weighs_by_the_guides_mixture() {
    let scene = fog_box(8);
    let tech = guided(&scene);
    let g = tech.guide.as_deref().unwrap();
    let pt = PathTracer::new(None).with_guide(&tech);
    assert!(
        pt.guide.is_some(),
        "a guide of both kinds guides the path tracer"
    );
    assert!(PathTracer::new(None)
        .with_guide(&Enlightened::default())
        .guide
        .is_none());
    let radiance = TransportMode::Radiance;
    let mut fam = Family::new("path tracer: guided directions");
    for medium in [false, true] {
        for (k, (v, wo)) in guided_vertices(&scene, &tech, medium, 3)
            .into_iter()
            .enumerate()
        {
            let what = format!("{} vertex {k}", if medium { "medium" } else { "surface" });
            let (map, _) = g.map_at(&scene, &v, radiance).unwrap();
            let local = |wi: Vec3| match v.kind {
                VertexKind::Surface { .. } => v.bsdf(&scene).unwrap().pdf(wo, wi, v.n),
                VertexKind::Medium { medium } => scene.media[medium as usize].phase().pdf(wo, wi),
                _ => unreachable!(),
            };
            let mut guided_somewhere = false;
            for wi in common::test_directions(17 + k as u64, 32) {
                let got = pt.scatter_pdf(&scene, &v, wo, wi);
                let want = (1.0 - GUIDE_WEIGHT) * local(wi) + GUIDE_WEIGHT * map.pdf(wi);
                assert!(
                    (got - want).abs() <= 4.0 * f32::EPSILON * want,
                    "{what}: the path tracer's density {got}, the mixture {want}"
                );
                assert_eq!(got, scatter_pdf(g, &scene, &v, wo, wi, radiance), "{what}");
                guided_somewhere |= (got - local(wi)).abs() > 1e-3 * local(wi).max(1e-3);
            }
            assert!(guided_somewhere, "{what}: the map changes no density");
            // the samples: their densities, and the integral of the local model they estimate
            let truth = match v.kind {
                VertexKind::Surface { .. } => v.bsdf(&scene).unwrap().albedo(1.0).x as f64,
                _ => 1.0,
            };
            let mut s = Sampler::new(53, k as u64, medium as u64);
            let n = 40_000u64;
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let x = match pt.sample_scatter(&scene, &v, wo, &mut s) {
                    Some(ss) => {
                        let p = scatter_pdf(g, &scene, &v, wo, ss.wi, radiance);
                        assert!(
                            (ss.pdf - p).abs() <= 1e-5 * p,
                            "{what}: sampled {} vs {p}",
                            ss.pdf
                        );
                        let cos = if medium { 1.0 } else { ss.wi.dot(v.n).abs() };
                        (ss.value.x * cos / ss.pdf) as f64
                    }
                    None => 0.0,
                };
                sum += x;
                sum2 += x * x;
            }
            let mean = sum / n as f64;
            let var = (sum2 / n as f64 - mean * mean) * n as f64 / (n - 1) as f64;
            fam.samples_are(
                &format!("{what}: f / p integrates the model"),
                mean,
                var,
                n,
                truth,
            );
        }
    }
    fam.finish();
}

/// Single scattering with equiangular MIS, guided against unguided: the equiangular strategy's
/// light sample is weighed against the direction the walk would sample at its point, the guide's
/// mixture. With the map's share at 0.9 the mixture is far from the phase function, so a weight
/// that took the phase function's density would miss the light by several standard errors.
#[test]
fn guided_equiangular_light_sample_is_weighed_against_the_mixture() {
    let scene = fog_box(8);
    let settings = RenderSettings {
        distance: DistanceSampling::EquiangularMis,
        ..RenderSettings::for_scene(&scene)
    };
    let mut sharp = GuideSettings {
        particles: 50_000,
        ..GuideSettings::for_radius(scene.radius)
    };
    sharp.c_guide = 0.9;
    let plain = path_runs_to(&scene, &PLAIN, &settings, 7000, Some(1));
    let guided = path_runs_to(&scene, &guide_of(&scene, sharp), &settings, 9000, Some(1));
    let mut fam = Family::new("single scattering, equiangular-mis: guided vs unguided");
    for c in 0..3 {
        let column = |runs: &[Vec<f64>]| runs.iter().map(|r| r[c]).collect::<Vec<f64>>();
        fam.runs_agree(&format!("channel {c}"), &column(&guided), &column(&plain));
    }
    fam.finish();
}

/// Independent runs of the path tracer's 8 x 8 fog box, each judged by the mean of the lower
/// half of its image per channel: the upper half sees the light, whose edges in its pixels
/// add noise that would hide a bias of a few percent in the scattered light.
const RUNS: u64 = 48;
const SPP: u32 = 256;

fn path_runs(
    scene: &Scene,
    tech: &dyn LocalSampling,
    settings: &RenderSettings,
    seed: u64,
) -> Vec<Vec<f64>> {
    path_runs_to(scene, tech, settings, seed, None)
}

/// [`path_runs`] with at most `max_depth` scattering vertices.
fn path_runs_to(
    scene: &Scene,
    tech: &dyn LocalSampling,
    settings: &RenderSettings,
    seed: u64,
    max_depth: Option<u32>,
) -> Vec<Vec<f64>> {
    (0..RUNS)
        .map(|r| {
            let setup = Setup {
                scene,
                technique: tech,
                settings,
                seed: seed + r,
                max_depth,
            };
            let mut rd = Renderer::prepared(IntegratorKind::Path, &setup).unwrap();
            rd.pass(SPP, &|| {});
            let q = common::quadrant_means(&rd.film.as_ref().unwrap().image());
            (0..3).map(|c| (q[6 + c] + q[9 + c]) / 2.0).collect()
        })
        .collect()
}

/// The guided path tracer agrees with the unguided one on the fog box (unlimited depth): the
/// guided walk, with guided Russian roulette (sec. 5.3.4), and with equiangular MIS, whose
/// light sample is weighed against the guided mixture at its point.
#[test]
fn guided_path_tracer_agrees_with_path_tracer() {
    let scene = fog_box(8);
    let settings = RenderSettings::for_scene(&scene);
    let plain = path_runs(&scene, &PLAIN, &settings, 1000);
    let mut fam = Family::new("path tracer: guided vs unguided");
    let equiangular = RenderSettings {
        distance: DistanceSampling::EquiangularMis,
        ..settings.clone()
    };
    // the default maps and share (sharp maps, c = 1/2), where a density of the walk that
    // misses the map's share biases the image most
    let sharp = GuideSettings {
        particles: 50_000,
        ..GuideSettings::for_radius(scene.radius)
    };
    let roulette = GuideSettings {
        roulette: Some(2.0),
        ..sharp
    };
    for (name, tech, s) in [
        ("guided", guide_of(&scene, sharp), &settings),
        ("guided roulette", guide_of(&scene, roulette), &settings),
        (
            "guided, equiangular-mis",
            guide_of(&scene, sharp),
            &equiangular,
        ),
    ] {
        let guided = path_runs(&scene, &tech, s, 5000);
        for c in 0..3 {
            let column = |runs: &[Vec<f64>]| runs.iter().map(|r| r[c]).collect::<Vec<f64>>();
            let what = format!("{name}: lower half, channel {c}");
            fam.runs_agree(&what, &column(&guided), &column(&plain));
        }
    }
    fam.finish();
}

/// With the halo cone the path tracer agrees with the plain one on the fog box, path by path
/// length: single scattering (where the light sample and the direction that finds the lamp
/// share every path by MIS), paths of at most two vertices, and two vertices with equiangular
/// MIS, whose light sample is weighed against the mixture at its point. A share of 0.7 makes
/// a wrong weight show: with the light sample weighed against the phase function's and the
/// BSDF's own density instead of the mixture's, the lower half's single scattering comes out
/// 13% too bright (over 100 standard errors), where the agreement matrix's column, at 0.3 and
/// its sample counts, does not see the 1.3% it makes of the whole image.
#[test]
fn halo_cone_path_tracer_agrees_with_path_tracer() {
    let scene = fog_box(8);
    let settings = RenderSettings::for_scene(&scene);
    let halo = RenderSettings {
        halo_cone: 0.7,
        ..settings.clone()
    };
    let equiangular = RenderSettings {
        distance: DistanceSampling::EquiangularMis,
        ..halo.clone()
    };
    let mut fam = Family::new("path tracer: halo cone vs plain");
    for (name, s, depth) in [
        ("single scattering", &halo, 1),
        ("two vertices", &halo, 2),
        ("two vertices, equiangular-mis", &equiangular, 2),
    ] {
        let plain = path_runs_to(&scene, &PLAIN, &settings, 1000, Some(depth));
        let cone = path_runs_to(&scene, &PLAIN, s, 5000, Some(depth));
        for c in 0..3 {
            let column = |runs: &[Vec<f64>]| runs.iter().map(|r| r[c]).collect::<Vec<f64>>();
            let what = format!("{name}: lower half, channel {c}");
            fam.runs_agree(&what, &column(&cone), &column(&plain));
        }
    }
    fam.finish();
}
