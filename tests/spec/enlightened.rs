//! Executable specification of enlightened local path sampling (Kristensen 2010, ch. 5; book
//! chapter "Enlightened local path sampling: the adjoint image and particles").
//!
//! - Particles are unbiased (the thesis's test T16): summed photon weights on a surface patch
//!   reproduce <W_e, L_i> of an irradiance meter on that patch, summed importon weights on the
//!   light reproduce <L_e, W_i> of the same meter, each against an independent path-tracer
//!   estimate of the meter (Welch's test), in an empty room and in fog.
//! - Particle lists are identical whatever the thread count.
//!
//! Standard errors of particle sums come from independent batches (each batch one seed): the
//! particles of one path are correlated, batches are not. A standard error from k batches is
//! Student-t with k - 1 degrees of freedom, so the tests buy many small batches rather than a
//! few large ones. Every test judges its comparisons in one `Family` (Holm at the suite's
//! per-test level).

use crate::common;

use common::stats::{assert_significant, p_welch, runs_mean, Family};
use pathspace::enlightened::metropolis::{trace_metropolis, MetropolisParticleSettings};
use pathspace::enlightened::particles::{
    trace_bidirectional, trace_bidirectional_where, trace_classical, trace_importons,
    trace_photons, ImportonSource, Particle, ParticleSets, Quantity,
};
use pathspace::integrator::bdpt::{Bdpt, Strategies};
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::path::{LocalSampling, PLAIN};
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

/// The path tracer's meter estimate (value, standard error, degrees of freedom), green
/// channel.
fn meter_truth(scene: &Scene, spp: u32) -> (f64, f64, f64) {
    let mut r = Renderer::new(scene, IntegratorKind::Path, 99, None);
    r.pass(spp, &|| {});
    common::meter_mean(&r.meter_estimates()[0], 1)
}

/// Mean, standard error and degrees of freedom (batches - 1) of batch estimates.
fn batch_stats(x: &[f64]) -> (f64, f64, f64) {
    runs_mean(x)
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

/// A particle estimate `a` agrees with a reference `b` (Welch's test, a comparison of `fam`);
/// a particle estimate without spread cannot be judged and fails at once.
fn agrees(fam: &mut Family, what: &str, a: (f64, f64, f64), b: (f64, f64, f64)) {
    eprintln!("{what}: {} +- {} vs {} +- {}", a.0, a.1, b.0, b.1);
    assert!(a.1 > 0.0, "{what}: the estimate has no spread");
    fam.means_agree(what, a, b);
}

/// Independent batches of the particle tests (each batch one seed).
const BATCHES: u64 = 48;

/// T16 for the classical tracer: photons give <W_e, L_i>, importons give <L_e, W_i>.
#[test]
fn classical_particles_reproduce_the_meter() {
    const PATHS: u64 = 8192;
    let mut fam = Family::new("enlightened: classical particles reproduce the meter");
    for fog in [false, true] {
        let scene = room(fog);
        let bdpt = Bdpt::new(&PLAIN, None, Strategies::All);
        let mut photon = Vec::new();
        let mut importon = Vec::new();
        for b in 0..BATCHES {
            let ph = trace_photons(&scene, &bdpt, PATHS, 1000 + b);
            photon.push(floor_patch_photons(&ph));
            let im = trace_importons(&scene, &bdpt, ImportonSource::Meter(0), PATHS, 2000 + b);
            importon.push(light_importons(&im));
            if fog && b == 0 {
                assert!(
                    ph.iter().any(|p| p.medium.is_some() && p.normal.is_none()),
                    "fog: photons in the medium"
                );
            }
        }
        let truth = meter_truth(&scene, 64);
        let tag = if fog { "fog" } else { "empty" };
        agrees(
            &mut fam,
            &format!("photons ({tag})"),
            batch_stats(&photon),
            truth,
        );
        let importon = batch_stats(&importon);
        agrees(&mut fam, &format!("importons ({tag})"), importon, truth);
    }
    fam.finish();
}

/// T16 for the bidirectional particle sampler (with the three precisions that make it unbiased,
/// see `trace_bidirectional`): photons give <W_e, L_i>, importons give <L_e, W_i>.
#[test]
fn bidirectional_particles_reproduce_the_meter() {
    let mut fam = Family::new("enlightened: bidirectional particles reproduce the meter");
    for fog in [false, true] {
        let scene = room(fog);
        let (photon, importon) = meter_batches(BATCHES, 3000, |seed| {
            trace_bidirectional(&scene, &PLAIN, ImportonSource::Meter(0), 8192, seed)
        });
        let truth = meter_truth(&scene, 64);
        let tag = if fog { "fog" } else { "empty" };
        agrees(
            &mut fam,
            &format!("bidirectional photons ({tag})"),
            photon,
            truth,
        );
        agrees(
            &mut fam,
            &format!("bidirectional importons ({tag})"),
            importon,
            truth,
        );
    }
    fam.finish();
}

/// <W_e, L_i> of the meter from photons: their weights on the floor patch over its area
/// (W_e = 1 / A on the patch's front side).
fn floor_patch_photons(photons: &[Particle]) -> f64 {
    let area = (2.0 * PATCH as f64) * (2.0 * PATCH as f64);
    photons
        .iter()
        .filter(|p| on_floor_patch(p))
        .map(|p| p.weight.y as f64)
        .sum::<f64>()
        / area
}

/// <L_e, W_i> of the meter from importons: their weights on the light times L_e.
fn light_importons(importons: &[Particle]) -> f64 {
    importons
        .iter()
        .filter(|p| on_light(p))
        .map(|p| (p.weight.y * LE) as f64)
        .sum::<f64>()
}

/// Photon and importon batch estimates of the meter from a particle sampler run `batches`
/// times with seeds `seed0 + b`.
fn meter_batches(
    batches: u64,
    seed0: u64,
    mut run: impl FnMut(u64) -> ParticleSets,
) -> ((f64, f64, f64), (f64, f64, f64)) {
    let mut photon = Vec::new();
    let mut importon = Vec::new();
    for b in 0..batches {
        let sets = run(seed0 + b);
        photon.push(floor_patch_photons(&sets.photons));
        importon.push(light_importons(&sets.importons));
    }
    (batch_stats(&photon), batch_stats(&importon))
}

/// Small Metropolis runs for the tests: 2048 bootstrap samples, 64 chains.
fn metropolis_settings(defensive: f64) -> MetropolisParticleSettings {
    MetropolisParticleSettings {
        bootstrap: 2048,
        chains: 64,
        defensive,
        ..Default::default()
    }
}

/// Batches of the Metropolis particle test, Metropolis steps per batch, and each batch's
/// bootstrap samples and chains.
const METRO_BATCHES: u64 = 64;
const METRO_STEPS: u64 = 32_768;
const METRO_BOOTSTRAP: u64 = 4096;
const METRO_CHAINS: u32 = 64;

/// T16 for the Metropolis particle sampler (eq. (5.15) with the defensive floor): photons give
/// <W_e, L_i>, importons give <L_e, W_i>, each batch one independent run (bootstrap and chains).
#[test]
fn metropolis_particles_reproduce_the_meter() {
    let mut fam = Family::new("enlightened: Metropolis particles reproduce the meter");
    for fog in [false, true] {
        let scene = room(fog);
        let settings = MetropolisParticleSettings {
            bootstrap: METRO_BOOTSTRAP,
            chains: METRO_CHAINS,
            ..Default::default()
        };
        let (photon, importon) = meter_batches(METRO_BATCHES, 4000, |seed| {
            let (sets, stats) = trace_metropolis(
                &scene,
                &PLAIN,
                ImportonSource::Meter(0),
                METRO_STEPS,
                seed,
                &settings,
            );
            if seed == 4000 {
                eprintln!("{stats:?}");
            }
            sets
        });
        let truth = meter_truth(&scene, 64);
        let tag = if fog { "fog" } else { "empty" };
        agrees(
            &mut fam,
            &format!("Metropolis photons ({tag})"),
            photon,
            truth,
        );
        agrees(
            &mut fam,
            &format!("Metropolis importons ({tag})"),
            importon,
            truth,
        );
    }
    fam.finish();
}

/// Without the defensive part (delta = 0, eq. (5.15) as printed) the Metropolis particles
/// represent exactly the particles of the samples whose full path carries light: they agree with
/// the bidirectional particles restricted to I(u) > 0 (total photon weight, total importon
/// weight, photons on the floor patch). In this room that part is visibly short of the meter:
/// the floor patch's photons whose connection reaches the meter through its back are lost, and
/// so is every importon on the black light (Kristensen 2010 sec. 5.2.2). That is what the defensive part is for.
#[test]
fn metropolis_particles_without_the_defensive_part_represent_the_connected_paths() {
    let scene = room(false);
    let functionals = |sets: &ParticleSets| {
        [
            sets.photons.iter().map(|p| p.weight.y as f64).sum::<f64>(),
            sets.importons
                .iter()
                .map(|p| p.weight.y as f64)
                .sum::<f64>(),
            floor_patch_photons(&sets.photons),
            light_importons(&sets.importons),
        ]
    };
    let batches = |seed0: u64, run: &dyn Fn(u64) -> ParticleSets| {
        let runs: Vec<[f64; 4]> = (0..BATCHES).map(|b| functionals(&run(seed0 + b))).collect();
        (0..4)
            .map(|j| batch_stats(&runs.iter().map(|r| r[j]).collect::<Vec<_>>()))
            .collect::<Vec<_>>()
    };
    let settings = metropolis_settings(0.0);
    let metro = batches(5000, &|seed| {
        trace_metropolis(
            &scene,
            &PLAIN,
            ImportonSource::Meter(0),
            8192,
            seed,
            &settings,
        )
        .0
    });
    let connected = batches(6000, &|seed| {
        trace_bidirectional_where(&scene, &PLAIN, ImportonSource::Meter(0), 8192, seed, |i| {
            i > 0.0
        })
    });
    let mut fam = Family::new("enlightened: Metropolis without defensive part");
    for (j, what) in ["all photons", "all importons", "floor-patch photons"]
        .iter()
        .enumerate()
    {
        agrees(
            &mut fam,
            &format!("{what}: Metropolis vs connected bidirectional"),
            metro[j],
            connected[j],
        );
    }
    fam.finish();
    assert_eq!(metro[3].0, 0.0, "no importon on the black light");
    assert_eq!(connected[3].0, 0.0, "no importon on the black light");
    let truth = meter_truth(&scene, 64);
    let c = connected[2].0;
    eprintln!(
        "connected floor photons {c} vs meter {}: {:.1}% short",
        truth.0,
        100.0 * (truth.0 - c) / truth.0
    );
    assert!(c < truth.0, "the connected part is brighter than the meter");
    assert_significant(
        "the floor photons the connected part misses (seen only through the meter's back)",
        p_welch(connected[2], truth),
    );
}

/// Particle lists do not depend on the thread count.
#[test]
fn particles_are_identical_with_any_thread_count() {
    let scene = room(true);
    let bdpt = Bdpt::new(&PLAIN, None, Strategies::All);
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
    let settings = metropolis_settings(0.1);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                trace_metropolis(&scene, &PLAIN, ImportonSource::Meter(0), 5000, 5, &settings)
            })
    };
    let (a, b) = (run(1), run(3));
    assert!(!a.0.photons.is_empty() && !a.0.importons.is_empty());
    assert_eq!(a, b, "Metropolis particles");
}

/// Digest F10 (Kristensen 2010, Fig. 5.5 and 5.13): the classical tracer's photons stay near
/// the light, the Metropolis sampler's crowd where the camera looks. On the door slit the light
/// is in the far room (x > 0) and the camera looks into its own room (x < 0): the share of the
/// photons (by count) in the camera's room must at least double.
#[test]
fn metropolis_photons_crowd_where_the_camera_looks() {
    let scene = Scene::load(
        &SceneSource::read(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/door-slit-strips.toml"
        )))
        .unwrap(),
    )
    .unwrap();
    let share = |ph: &[Particle]| {
        ph.iter().filter(|p| p.position.x < 0.0).count() as f64 / ph.len().max(1) as f64
    };
    let classical = trace_classical(&scene, &PLAIN, Quantity::Radiance, 20_000, 7);
    let settings = MetropolisParticleSettings {
        bootstrap: 8192,
        chains: 64,
        ..Default::default()
    };
    let (metro, stats) =
        trace_metropolis(&scene, &PLAIN, ImportonSource::Camera, 20_000, 7, &settings);
    let (c, m) = (share(&classical), share(&metro.photons));
    eprintln!(
        "photons in the camera's room: classical {:.3} of {}, Metropolis {:.3} of {} ({stats:?})",
        c,
        classical.len(),
        m,
        metro.photons.len()
    );
    assert!(m > 2.0 * c, "classical {c}, Metropolis {m}");
}

// ---------------------------------------------------------------------------------------------
// The adjoint image (Kristensen 2010, sec. 5.2.1 and 5.3.1)
// ---------------------------------------------------------------------------------------------

use glam::Vec2;
use pathspace::enlightened::adjoint::{AdjointEstimator, AdjointImage, AdjointSettings, LightMap};
use pathspace::enlightened::Enlightened;
use pathspace::geometry::Primitive;
use pathspace::scene::Light;

/// The fog box at `res` x `res` pixels with four more lights: an emitting cube (six quads of
/// equal area), an emitting sphere, a second ceiling quad, and a point light (which the
/// adjoint image does not cover: the area lights get their share of the power selection).
fn many_lights_text(res: u32) -> String {
    pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{res}, {res}]"),
    ) + r#"
[[shapes]]
type = "box"
min = [0.5, -1.0, -0.9]
max = [0.8, -0.7, -0.6]
emission = [1.0, 2.0, 1.0]

[[shapes]]
type = "sphere"
center = [-0.6, -0.6, 0.3]
radius = 0.15
emission = [3.0, 1.0, 1.0]

[[shapes]]
type = "quad"
origin = [0.4, 0.999, 0.3]
u = [0.3, 0.0, 0.0]
v = [0.0, 0.0, 0.3]
emission = [4.0, 4.0, 4.0]

[[lights]]
type = "point"
position = [0.0, 0.5, 0.5]
intensity = 0.5
"#
}

/// [`many_lights_text`], loaded.
fn many_lights(res: u32) -> Scene {
    load(&many_lights_text(res))
}

/// A deliberately lumpy cell estimate with zero cells: a fixed pseudo-random pattern.
fn lumpy_estimate(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let h = pathspace::math::sampler::mix64(i as u64 + 17);
            match h % 5 {
                0 => 0.0,
                1 => 50.0,
                _ => (h % 1000) as f64 / 100.0,
            }
        })
        .collect()
}

#[test]
fn light_map_round_trips() {
    let scene = many_lights(8);
    let map = LightMap::new(&scene);
    assert_eq!(
        map.len(),
        4,
        "the ceiling quad, the cube, the sphere, the second quad"
    );
    let mut s = common::sampler(31, 0);
    let mut worst_u = 0.0f32;
    let mut worst_x = 0.0f32;
    for _ in 0..20_000 {
        let u = s.next_2d();
        let x = map
            .forward(&scene, u)
            .expect("F is defined on the whole square");
        let back = map
            .inverse(&scene, x.light, x.prim, x.p)
            .expect("F^-1 of a light point");
        // u_2 near 0 or 1 on the sphere (a pole) loses the angle: compare F(F^-1(x)) there
        worst_u = worst_u.max((back - u).abs().max_element());
        let again = map.forward(&scene, back).unwrap();
        assert_eq!(
            (again.light, again.prim),
            (x.light, x.prim),
            "F(F^-1(x)) for x on light {} primitive {} (from u = {u}, F^-1 gave {back}): got \
             light {} primitive {}, expected light {} primitive {}",
            x.light,
            x.prim,
            again.light,
            again.prim,
            x.light,
            x.prim
        );
        worst_x = worst_x.max((again.p - x.p).length());
    }
    eprintln!("F round trip: |F^-1(F(u)) - u| <= {worst_u}, |F(F^-1(x)) - x| <= {worst_x}");
    assert!(worst_x < 1e-4, "F(F^-1(x)) moved a point by {worst_x}");
    assert!(worst_u < 1e-3, "F^-1(F(u)) moved u by {worst_u}");
    // the inverse of every primitive's area sampling
    let prims = [
        Primitive::Quad(
            pathspace::geometry::shape::Quad::new(
                glam::Vec3::new(0.1, 0.2, 0.3),
                glam::Vec3::new(0.5, 0.1, 0.0),
                glam::Vec3::new(-0.2, 0.4, 0.3),
            )
            .unwrap(),
        ),
        Primitive::Triangle(
            pathspace::geometry::shape::Triangle::new(
                glam::Vec3::new(0.0, 0.0, 0.0),
                glam::Vec3::new(1.0, 0.2, 0.0),
                glam::Vec3::new(0.3, 1.0, 0.5),
            )
            .unwrap(),
        ),
        Primitive::Disk(
            pathspace::geometry::Disk::new(
                glam::Vec3::new(0.3, -0.2, 0.1),
                glam::Vec3::new(0.7, 0.1, 0.0),
                glam::Vec3::new(-0.1, 0.3, 0.4),
            )
            .unwrap(),
        ),
    ];
    for prim in prims {
        for _ in 0..2000 {
            let u = s.next_2d();
            let back = prim.sample_area_inverse(prim.sample_area(u).0);
            assert!(
                (back - u).abs().max_element() < 1e-4,
                "{prim:?}: {u} -> {back}"
            );
        }
    }
}

/// The adjoint image's density p(x_0) = P(area) P_j N p_F(x_0), integrated over bins of every
/// light primitive in the primitive's own parametrization, against the frequencies of its
/// sampler (chi-square); and p > 0 wherever light is emitted, zero cells included.
#[test]
fn adjoint_pdf_matches_its_sampler_and_is_positive_where_light_is_emitted() {
    let scene = many_lights(8);
    let m = LightMap::new(&scene).len();
    // 12 columns per light: cell edges fall on the bin edges below for the one-primitive
    // lights and the cube's six faces alike, so the quadrature of the piecewise-constant pdf
    // is exact
    let (cols, rows) = (12 * m as u32, 8);
    let image = AdjointImage::from_estimate(
        &scene,
        cols,
        rows,
        lumpy_estimate((cols * rows) as usize),
        0.01,
    )
    .unwrap();
    assert!(image.stats.zero_cells > 0);
    assert!(image.area_fraction < 1.0 && image.area_fraction > 0.5);
    // bins: per light primitive, 4 x 4 in its sample_area coordinates
    const B: usize = 4;
    // quadrature points per bin and axis: a multiple of the 3 columns and 2 rows per bin
    const Q: usize = 6;
    let mut prims: Vec<(u32, u32)> = Vec::new();
    for (l, light) in scene.lights.iter().enumerate() {
        if let Light::Area { prims: ids, .. } = light {
            prims.extend(ids.iter().map(|&p| (l as u32, p)));
        }
    }
    let bin_of = |prim_index: usize, u: Vec2| -> usize {
        let bx = ((u.x * B as f32) as usize).min(B - 1);
        let by = ((u.y * B as f32) as usize).min(B - 1);
        prim_index * B * B + by * B + bx
    };
    let samples: u64 = 200_000;
    let mut expected = vec![0.0f64; prims.len() * B * B];
    let mut min_pdf = f32::INFINITY;
    for (pi, &(l, p)) in prims.iter().enumerate() {
        let prim = &scene.prims[p as usize];
        let area = prim.area() as f64;
        for by in 0..B {
            for bx in 0..B {
                let mut sum = 0.0f64;
                for qy in 0..Q {
                    for qx in 0..Q {
                        let u = Vec2::new((bx * Q + qx) as f32 + 0.5, (by * Q + qy) as f32 + 0.5)
                            / (B * Q) as f32;
                        let x = prim.sample_area(u).0;
                        let pdf = image.pdf(&scene, l, p, x);
                        min_pdf = min_pdf.min(pdf);
                        sum += pdf as f64;
                    }
                }
                // the sampler is conditional on the area-light category
                expected[pi * B * B + by * B + bx] = samples as f64 * sum / (Q * Q) as f64 * area
                    / (B * B) as f64
                    / image.area_fraction as f64;
            }
        }
    }
    assert!(
        min_pdf > 0.0,
        "the adjoint pdf is zero on a light point: eps must keep it positive"
    );
    let total: f64 = expected.iter().sum();
    assert!(
        (total / samples as f64 - 1.0).abs() < 1e-3,
        "the adjoint pdf integrates to {} over the area lights",
        total / samples as f64
    );
    let mut observed = vec![0u64; expected.len()];
    let mut s = common::sampler(32, 0);
    for _ in 0..samples {
        let st = image
            .sample(&scene, s.next_2d(), s.next_2d())
            .expect("a start point");
        let pi = prims
            .iter()
            .position(|&(l, p)| (l, p) == (st.point.light, st.point.prim))
            .unwrap();
        let u = scene.prims[st.point.prim as usize].sample_area_inverse(st.point.p);
        observed[bin_of(pi, u)] += 1;
    }
    let mut fam = Family::new("enlightened: adjoint pdf vs its sampler");
    fam.chi_square("adjoint image light starts", &observed, &expected);
    fam.finish();
}

// ---------------------------------------------------------------------------------------------
// Renderers with the adjoint image agree with renderers without it
// ---------------------------------------------------------------------------------------------

/// Independent BDPT renders per quadrant comparison (short: the standard error is Student-t
/// over the runs, so many short runs see more than a few long ones at the same cost).
const RUNS: u64 = 64;
/// Samples per pixel of each BDPT run.
const SPP: u32 = 8;
/// Independent MLT renders per quadrant comparison, and their mutations per pixel.
const MLT_RUNS: u64 = 32;
const MLT_MUTATIONS: u64 = 64;
const RES: u32 = 8;
const DEPTH: u32 = 3;

fn bdpt_runs(scene: &Scene, tech: &dyn LocalSampling, seed: u64) -> Vec<Vec<f64>> {
    common::bdpt_quadrant_runs((scene, tech), RUNS, seed, DEPTH, SPP)
}

fn mlt_runs(scene: &Scene, tech: &dyn LocalSampling, seed: u64) -> Vec<Vec<f64>> {
    common::mlt_quadrant_runs_with((scene, tech), MLT_RUNS, seed, DEPTH, MLT_MUTATIONS)
}

/// A lumpy adjoint image (zero cells and 50x contrasts) for `scene`: the starkest test that
/// sampling, 1/p and the MIS densities use one density.
fn lumpy_adjoint(scene: &Scene) -> Enlightened {
    let m = LightMap::new(scene).len() as u32;
    let (cols, rows) = AdjointImage::grid_size((16, 16), m as usize);
    Enlightened {
        adjoint: Some(
            AdjointImage::from_estimate(
                scene,
                cols,
                rows,
                lumpy_estimate((cols * rows) as usize),
                0.01,
            )
            .unwrap(),
        ),
        ..Enlightened::default()
    }
}

fn fog_box(res: u32) -> Scene {
    load(&pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{res}, {res}]"),
    ))
}

/// BDPT with the adjoint image (lumpy, and estimated by the pre-pass) against plain BDPT: the
/// fog box, and the fog box with four area lights and a point light.
#[test]
fn bdpt_with_the_adjoint_image_agrees_with_bdpt() {
    let mut fam = Family::new("enlightened: bdpt with the adjoint image");
    for (name, scene) in [("fog box", fog_box(RES)), ("many lights", many_lights(RES))] {
        let plain = bdpt_runs(&scene, &PLAIN, 100);
        let lumpy = if name == "fog box" {
            fog_box(RES)
        } else {
            many_lights(RES)
        };
        common::quadrants_agree(
            &mut fam,
            &format!("{name}: bdpt + lumpy adjoint"),
            &bdpt_runs(&lumpy, &lumpy_adjoint(&lumpy), 200),
            &plain,
        );
        let estimated = scene;
        let settings = AdjointSettings {
            samples_per_cell: 4,
            ..AdjointSettings::default()
        };
        let image = AdjointImage::render(&estimated, &PLAIN, &settings, 7, Some(DEPTH)).unwrap();
        assert!(image.estimate.iter().sum::<f64>() > 0.0);
        let technique = Enlightened {
            adjoint: Some(image),
            ..Enlightened::default()
        };
        common::quadrants_agree(
            &mut fam,
            &format!("{name}: bdpt + adjoint"),
            &bdpt_runs(&estimated, &technique, 300),
            &plain,
        );
    }
    fam.finish();
}

/// MLT's initialization and bidirectional mutation regenerate light vertices from the adjoint
/// image and its transition density evaluates the same density: MLT with a lumpy adjoint image
/// renders what BDPT renders. (With the transition density left at the power-and-area density
/// while the light vertex is drawn from the adjoint image, quadrant 0 comes out 0.22 +- 0.017
/// against BDPT's 0.32 +- 0.002: the test sees the mistake this guards against.)
#[test]
fn mlt_with_the_adjoint_image_agrees_with_bdpt() {
    let plain = bdpt_runs(&many_lights(RES), &PLAIN, 400);
    let scene = many_lights(RES);
    let lumpy = lumpy_adjoint(&scene);
    let mut fam = Family::new("enlightened: mlt with the adjoint image");
    common::quadrants_agree(
        &mut fam,
        "many lights: mlt + lumpy adjoint",
        &mlt_runs(&scene, &lumpy, 500),
        &plain,
    );
    fam.finish();
}

/// Bad adjoint settings are reported at their line and key; the image refuses scenes it cannot
/// serve instead of panicking.
#[test]
fn bad_adjoint_settings_are_clear_errors() {
    let base = pathspace::scene::FOG_BOX;
    let base_lines = base.lines().count();
    for (extra, key, word) in [
        (
            "[render.adjoint]\nepsilon = 0.0\n",
            "render.adjoint.epsilon",
            "positive",
        ),
        (
            "[render.adjoint]\nresolution = [0, 64]\n",
            "render.adjoint.resolution",
            "1..=4096",
        ),
        (
            "[render.adjoint]\nsamples_per_cell = 0\n",
            "render.adjoint.samples_per_cell",
            "at least 1",
        ),
        (
            "[render.adjoint]\nestimator = \"mlt\"\n",
            "render.adjoint.estimator",
            "metropolis",
        ),
    ] {
        let text = format!("{base}\n{extra}");
        let e = match pathspace::integrator::settings::load(&SceneSource::embedded(
            "bad.toml", &text,
        )) {
            Ok(_) => panic!("loaded with {extra}"),
            Err(e) => e,
        };
        assert_eq!(e.key, key, "{e}");
        assert_eq!(e.line, Some(base_lines + 3), "{e}");
        assert!(e.message.contains(word), "{e}");
    }
    // the command line's overrides (render and converge share them)
    let d = AdjointSettings::default();
    use clap::Parser;
    let e =
        pathspace::cli::Cli::try_parse_from(["pathspace", "render", "--adjoint-estimator", "mlt"])
            .unwrap_err()
            .to_string();
    assert!(
        e.contains("--adjoint-estimator") && e.contains("metropolis"),
        "{e}"
    );
    let e = d
        .overridden(None, Some(0), None, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("samples per cell"), "{e}");
    let ok = d
        .overridden(
            Some((18, 9)),
            Some(3),
            Some(0.25),
            Some(AdjointEstimator::Metropolis),
        )
        .unwrap();
    assert_eq!(
        (ok.resolution, ok.samples_per_cell, ok.epsilon),
        ((18, 9), 3, 0.25)
    );
    // a scene without area lights, and one without a camera
    let point_only = load(&format!(
        "{}\n[[lights]]\ntype = \"point\"\nposition = [0.0, 0.0, 0.0]\nintensity = 1.0\n",
        &base[..base.find("# ceiling light").unwrap()]
    ));
    let e = AdjointImage::render(&point_only, &PLAIN, &AdjointSettings::default(), 1, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no area light"), "{e}");
    let e = AdjointImage::render(&room(false), &PLAIN, &AdjointSettings::default(), 1, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("camera"), "{e}");
}

/// Independent runs of each estimator of the adjoint image, and its samples per cell.
const ADJOINT_RUNS: u64 = 24;
const ADJOINT_SAMPLES_PER_CELL: u32 = 6000;

/// The thesis's way of estimating the adjoint image, as a by-product of Metropolis sampling
/// (each state of a chain over full paths deposits its weight at F^-1(x_0)), estimates the same
/// I* as the BDPT pre-pass: per light (strip of cells), over independent runs each (Welch). The scene is the many-lights fog box made gray, because the BDPT pre-pass
/// deposits the channel mean and the chains the luminance (equal for gray light); it has no
/// mirror or glass, which the bidirectional sampler's paths do not cross. The chains' I(u) is
/// the mean pixel's, the BDPT estimate the sum over pixels: the test scales by the pixel count.
#[test]
fn metropolis_adjoint_image_estimates_the_same_light_shares_as_the_bdpt_prepass() {
    let gray = |s: String| {
        s.replace("[0.63, 0.065, 0.05]", "[0.5, 0.5, 0.5]")
            .replace("[0.14, 0.45, 0.091]", "[0.3, 0.3, 0.3]")
            .replace("emission = [1.0, 2.0, 1.0]", "emission = [1.5, 1.5, 1.5]")
            .replace("emission = [3.0, 1.0, 1.0]", "emission = [2.0, 2.0, 2.0]")
    };
    let text = gray(many_lights_text(8));
    let scene = load(&text);
    let m = LightMap::new(&scene).len();
    assert!(m >= 4, "{m} area lights");
    let n_pix = 64.0;
    let strips = |estimator, seed: u64| -> Vec<f64> {
        let settings = AdjointSettings {
            resolution: (m as u32, 1),
            samples_per_cell: ADJOINT_SAMPLES_PER_CELL,
            estimator,
            ..AdjointSettings::default()
        };
        let image = AdjointImage::render(&scene, &PLAIN, &settings, seed, None).unwrap();
        let scale = match estimator {
            AdjointEstimator::Metropolis => n_pix,
            AdjointEstimator::Bdpt => 1.0,
        };
        image.estimate.iter().map(|v| v * scale).collect()
    };
    let runs = |estimator, seed0: u64| -> Vec<Vec<f64>> {
        (0..ADJOINT_RUNS)
            .map(|r| strips(estimator, seed0 + r))
            .collect()
    };
    let bdpt = runs(AdjointEstimator::Bdpt, 800);
    let metro = runs(AdjointEstimator::Metropolis, 900);
    let mut fam = Family::new("enlightened: Metropolis adjoint image vs BDPT pre-pass");
    for j in 0..m {
        let column = |rs: &[Vec<f64>]| batch_stats(&rs.iter().map(|r| r[j]).collect::<Vec<_>>());
        agrees(
            &mut fam,
            &format!("light {j}: Metropolis vs BDPT pre-pass"),
            column(&metro),
            column(&bdpt),
        );
    }
    fam.finish();
}

// The modules of `src/enlightened/` (the layout: tests/repository/index.rs).
mod guide;
