//! Executable specification of equiangular sampling (Kulla and Fajardo 2012;
//! `src/medium/equiangular.rs`, `src/path/distance.rs`) and of the path tracer's
//! `distance = "equiangular-mis"` (book: "Table 1: homogeneous media", section "Equiangular
//! sampling").
//!
//! - the sampler on one interval against its density, by chi-square with expected counts
//!   integrated from `Equiangular::pdf` (so a wrong density fails as surely as a wrong sampler);
//! - the sampler over a ray's medium spans (two media, a vacuum gap, null boundaries) against
//!   `RayMedia::equiangular_pdf`, and the density it reports equal to that function;
//! - `RayMedia::free_flight_pdf` equal to the density propagation reports for its collisions;
//! - the path tracer's single scattering from two point lights along a ray through both media,
//!   with and without equiangular MIS, against the quadrature of its integral;
//! - in tracked inhomogeneous media (a baked grid, a closed form, an fBm field on the fly):
//!   the free-flight density equal to delta tracking's on a lifted ray, the equiangular
//!   density integrating to one over the boxes' clips, the two weights summing to one, and the
//!   walk with equiangular MIS on every ray agreeing with free flight at depths 1, 2 and 4.

use crate::common;

use common::stats::Family;
use glam::Vec3;
use pathspace::conventions::OptionValue as _;
use pathspace::geometry::Ray;
use pathspace::integrator::path::{DistanceSampling, PathTracer};
use pathspace::math::Sampler;
use pathspace::medium::Equiangular;
use pathspace::path::distance::RayMedia;
use pathspace::scene::{Event, Scene, SceneSource};

/// Bins of the chi-square tests.
const BINS: usize = 40;

/// Simpson's rule of `f` over [a, b] with `n` (even) intervals.
fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let h = (b - a) / n as f64;
    let mut s = f(a) + f(b);
    for k in 1..n {
        s += f(a + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

#[test]
fn equiangular_samples_follow_their_pdf() {
    const N: usize = 100_000;
    let mut fam = Family::new("equiangular: one interval against its pdf");
    // (delta, h, a, b): the foot inside, before and after the interval, a near and a far point
    for (c, (delta, h, a, b)) in [
        (1.0f32, 0.2f32, 0.0f32, 3.0f32),
        (-0.5, 1.0, 0.0, 2.0),
        (5.0, 0.5, 1.0, 4.0),
        (2.0, 0.01, 0.0, 4.0),
    ]
    .into_iter()
    .enumerate()
    {
        let eq = Equiangular { delta, h };
        let mut s = Sampler::new(11, c as u64, 0);
        let mut counts = vec![0u64; BINS];
        let width = (b - a) / BINS as f32;
        for _ in 0..N {
            let t = eq.sample(a, b, s.next_f32());
            let k = (((t - a) / width) as usize).min(BINS - 1);
            counts[k] += 1;
        }
        let expected: Vec<f64> = (0..BINS)
            .map(|k| {
                let (lo, hi) = (a + k as f32 * width, a + (k + 1) as f32 * width);
                let pdf = |t: f64| eq.pdf(a, b, t as f32) as f64;
                N as f64 * simpson(pdf, lo as f64, hi as f64, 2000)
            })
            .collect();
        fam.chi_square(&format!("config {c}"), &counts, &expected);
    }
    fam.finish();
}

/// Two media along the x axis, separated by a vacuum gap, each inside a null box; a non-scattering
/// medium between; two point lights, one in each scattering medium.
const SPANS_SCENE: &str = r#"
[camera]
type = "pinhole"
eye = [-1.9, 0.05, -0.02]
look_at = [0.0, 0.05, -0.02]
fov_deg = 30.0
resolution = [8, 8]

[media.a]
type = "homogeneous"
sigma_a = 0.1
sigma_s = [0.5, 0.3, 0.2]
phase = { type = "isotropic" }

[media.b]
type = "homogeneous"
sigma_a = [0.3, 0.1, 0.05]
sigma_s = 0.2
phase = { type = "hg", g = 0.5 }

[media.ink]
type = "homogeneous"
sigma_a = 0.4
sigma_s = 0.0
phase = { type = "isotropic" }

[[shapes]]
type = "box"
min = [-2.0, -1.0, -1.0]
max = [-0.2, 1.0, 1.0]
material = "null"
interior = "a"

[[shapes]]
type = "box"
min = [-0.1, -1.0, -1.0]
max = [0.2, 1.0, 1.0]
material = "null"
interior = "ink"

[[shapes]]
type = "box"
min = [0.3, -1.0, -1.0]
max = [2.0, 1.0, 1.0]
material = "null"
interior = "b"

[[lights]]
type = "point"
position = [0.5, 0.4, 0.1]
intensity = [1.0, 2.0, 3.0]

[[lights]]
type = "point"
position = [-1.2, -0.3, 0.25]
intensity = 2.0
"#;

/// The boxes of [`SPANS_SCENE`] with their media's index in the scene.
const BOXES: [([f32; 3], [f32; 3]); 3] = [
    ([-2.0, -1.0, -1.0], [-0.2, 1.0, 1.0]),
    ([-0.1, -1.0, -1.0], [0.2, 1.0, 1.0]),
    ([0.3, -1.0, -1.0], [2.0, 1.0, 1.0]),
];

fn spans_scene() -> Scene {
    Scene::load(&SceneSource::embedded("equiangular spans", SPANS_SCENE)).unwrap()
}

/// The test ray: starts inside medium a, leaves medium b into vacuum.
fn test_ray(scene: &Scene) -> (Ray, Option<u32>) {
    let o = Vec3::new(-1.9, 0.05, -0.02);
    (Ray::new(o, Vec3::X), scene.medium_at(o))
}

#[test]
fn spans_sampler_follows_its_pdf() {
    const N: usize = 100_000;
    let mut fam = Family::new("equiangular: a ray's spans against its pdf");
    let scene = spans_scene();
    let (ray, medium) = test_ray(&scene);
    let media = RayMedia::collect(&scene, ray, medium);
    assert_eq!(media.spans().len(), 3, "{:?}", media.spans());
    let end = media.spans()[2].t1;
    for (c, y) in [Vec3::new(0.5, 0.4, 0.1), Vec3::new(-1.2, -0.3, 0.25)]
        .into_iter()
        .enumerate()
    {
        let mut s = Sampler::new(12, c as u64, 0);
        let mut counts = vec![0u64; BINS];
        let width = end / BINS as f32;
        for _ in 0..N {
            let (i, t, pdf) = media.sample_equiangular(y, s.next_f32()).unwrap();
            let again = media.equiangular_pdf(y, i, t);
            assert!(
                (pdf - again).abs() <= 1e-6 * pdf,
                "reported pdf {pdf} against equiangular_pdf {again} at t = {t}"
            );
            counts[((t / width) as usize).min(BINS - 1)] += 1;
        }
        let pdf = |t: f64| {
            let t = t as f32;
            (0..3)
                .find(|&i| {
                    let sp = media.spans()[i];
                    sp.t0 <= t && t < sp.t1
                })
                .map_or(0.0, |i| media.equiangular_pdf(y, i, t) as f64)
        };
        let expected: Vec<f64> = (0..BINS)
            .map(|k| {
                let (lo, hi) = (k as f64 * width as f64, (k + 1) as f64 * width as f64);
                N as f64 * simpson(pdf, lo, hi, 4000)
            })
            .collect();
        fam.chi_square(&format!("light point {c}"), &counts, &expected);
    }
    fam.finish();
}

#[test]
fn free_flight_pdf_is_propagations() {
    let scene = spans_scene();
    let (ray, medium) = test_ray(&scene);
    let media = RayMedia::collect(&scene, ray, medium);
    let mut s = Sampler::new(13, 0, 0);
    let mut collisions = 0;
    for _ in 0..20_000 {
        let prop = scene.propagate(ray, 0.0, medium, &mut s);
        if let Event::Medium { t, medium: m, .. } = prop.event {
            let i = media.locate(t, m).expect("a collision lies in a span");
            let pdf = media.free_flight_pdf(&scene, i, t);
            assert!(
                (pdf - prop.pdf).abs() <= 1e-5 * prop.pdf,
                "free_flight_pdf {pdf} against propagation's {} at t = {t}",
                prop.pdf
            );
            collisions += 1;
        }
    }
    assert!(collisions > 5_000, "{collisions} collisions");
}

/// Length of the segment p -> q inside the box [lo, hi] (slab clipping).
fn inside(p: Vec3, q: Vec3, (lo, hi): ([f32; 3], [f32; 3])) -> f64 {
    let d = q - p;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..3 {
        let (pk, dk) = (p[k] as f64, d[k] as f64);
        if dk.abs() < 1e-12 {
            if pk < lo[k] as f64 || pk > hi[k] as f64 {
                return 0.0;
            }
            continue;
        }
        let (a, b) = ((lo[k] as f64 - pk) / dk, (hi[k] as f64 - pk) / dk);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t1 - t0).max(0.0) * d.length() as f64
}

/// Single scattering along the test ray, channel `c`, by quadrature: the sum over both point
/// lights of the integral of T(t) sigma_s f_p I T(x_t, light) / d^2 over every span.
fn single_scattering(scene: &Scene, ray: Ray, media: &RayMedia, c: usize) -> f64 {
    let sigma_t = |m: usize| scene.media[m].sigma_t(Vec3::ZERO)[c] as f64;
    let mut total = 0.0;
    for light in &scene.lights {
        let pathspace::scene::Light::Point {
            position,
            intensity,
        } = light
        else {
            unreachable!()
        };
        for sp in media.spans() {
            let m = sp.medium as usize;
            let f = |t: f64| {
                let x = ray.at(t as f32);
                let to = *position - x;
                let wi = to.normalize();
                // optical depths box by box, from the boxes' geometry alone
                let depth = |from: Vec3, to: Vec3| -> f64 {
                    (0..3)
                        .map(|b| {
                            let medium = scene.medium_at(Vec3::from(BOXES[b].0) + 0.01).unwrap();
                            sigma_t(medium as usize) * inside(from, to, BOXES[b])
                        })
                        .sum()
                };
                let shadow = depth(x, *position);
                let before = (-depth(ray.o, x)).exp();
                let f_p = scene.media[m].phase().eval(-ray.d, wi) as f64;
                before
                    * scene.media[m].sigma_s(x)[c] as f64
                    * f_p
                    * intensity[c] as f64
                    * (-shadow).exp()
                    / to.length_squared() as f64
            };
            total += simpson(f, sp.t0 as f64, sp.t1 as f64, 20_000);
        }
    }
    total
}

#[test]
fn single_scattering_is_unbiased_with_and_without_equiangular_mis() {
    const N: u64 = 200_000;
    let mut fam = Family::new("equiangular: single scattering against quadrature");
    let scene = spans_scene();
    let (ray, medium) = test_ray(&scene);
    let media = RayMedia::collect(&scene, ray, medium);
    for (k, distance) in [
        DistanceSampling::FreeFlight,
        DistanceSampling::EquiangularMis,
    ]
    .into_iter()
    .enumerate()
    {
        // one scattering vertex: a point light cannot be hit, so this is single scattering
        let pt = PathTracer::new(Some(1)).with_distance(distance);
        let (mut sum, mut sum_sq) = ([0.0f64; 3], [0.0f64; 3]);
        for n in 0..N {
            let mut s = Sampler::new(14, n, k as u64);
            let l = pt.radiance(&scene, ray, medium, &mut s);
            for c in 0..3 {
                sum[c] += l[c] as f64;
                sum_sq[c] += (l[c] as f64).powi(2);
            }
        }
        for c in 0..3 {
            let mean = sum[c] / N as f64;
            let var = (sum_sq[c] / N as f64 - mean * mean) * N as f64 / (N - 1) as f64;
            let truth = single_scattering(&scene, ray, &media, c);
            fam.samples_are(
                &format!("{} channel {c}", distance.name()),
                mean,
                var,
                N,
                truth,
            );
        }
    }
    fam.finish();
}

/// Tracked inhomogeneous media along the x axis: an fBm cloud baked onto a grid (exact optical
/// depth), a linear gradient (closed form) and an fBm plume evaluated on the fly (the fixed
/// quadrature), each in a null box, over a diffuse floor, a point light between them.
const TRACKED_SCENE: &str = r#"
[camera]
type = "pinhole"
eye = [-1.9, 0.05, -0.02]
look_at = [0.0, 0.05, -0.02]
fov_deg = 30.0
resolution = [8, 8]

[materials.white]
type = "lambert"
albedo = 0.7

[media.cloud]
type = "procedural"
density = "cloud"
octaves = 3
frequency = 2.0
seed = 5
resolution = 16
min = [-2.0, -0.5, -0.5]
max = [-0.9, 0.5, 0.5]
sigma_a = 0.3
sigma_s = [3.0, 2.0, 1.0]
phase = { type = "hg", g = 0.4 }
propagation = "delta-tracking"

[media.gradient]
type = "procedural"
density = "linear"
axis = "y"
from = 1.0
to = 0.2
min = [-0.8, -0.5, -0.5]
max = [0.2, 0.5, 0.5]
sigma_a = 0.2
sigma_s = 1.5
propagation = "delta-tracking"

[media.plume]
type = "procedural"
density = "plume"
octaves = 2
frequency = 3.0
seed = 2
min = [0.3, -0.5, -0.5]
max = [1.3, 0.5, 0.5]
sigma_a = 0.5
sigma_s = 4.0
propagation = "delta-tracking"

[[shapes]]
type = "quad"
origin = [-3.0, -0.6, -3.0]
u = [0.0, 0.0, 6.0]
v = [6.0, 0.0, 0.0]
material = "white"

[[shapes]]
type = "box"
min = [-2.0, -0.5, -0.5]
max = [-0.9, 0.5, 0.5]
material = "null"
interior = "cloud"

[[shapes]]
type = "box"
min = [-0.8, -0.5, -0.5]
max = [0.2, 0.5, 0.5]
material = "null"
interior = "gradient"

[[shapes]]
type = "box"
min = [0.3, -0.5, -0.5]
max = [1.3, 0.5, 0.5]
material = "null"
interior = "plume"

[[lights]]
type = "point"
position = [-0.3, 0.3, 0.1]
intensity = [2.0, 3.0, 4.0]
"#;

fn tracked_scene() -> Scene {
    Scene::load(&SceneSource::embedded("equiangular tracked", TRACKED_SCENE)).unwrap()
}

/// A ray from the floor up through all three boxes, lifted off the floor by `LEAD` as a walk
/// lifts it (its spans then start at t = -LEAD).
const LEAD: f32 = 1e-3;

fn tracked_ray(scene: &Scene) -> (Ray, Option<u32>) {
    let d = Vec3::new(1.0, 0.32, 0.03).normalize();
    let o = Vec3::new(-2.3, -0.6, -0.05) + LEAD * d;
    (Ray::new(o, d), scene.medium_at(o))
}

/// In tracked media the free-flight density the MIS weights use is the one delta tracking
/// draws with (Table 1: sigma_t(x) exp(-tau)), on a ray lifted off a surface; and the
/// equiangular density integrates to one over the stretches where the media have density.
#[test]
fn tracked_free_flight_pdf_is_propagations() {
    let scene = tracked_scene();
    let (ray, medium) = tracked_ray(&scene);
    let media = RayMedia::collect_from(&scene, ray, LEAD, medium);
    assert_eq!(media.spans().len(), 3, "{:?}", media.spans());
    let mut s = Sampler::new(15, 0, 0);
    let mut collisions = [0u32; 3];
    for _ in 0..20_000 {
        let prop = scene.propagate(ray, LEAD, medium, &mut s);
        if let Event::Medium { t, medium: m, .. } = prop.event {
            let i = media.locate(t, m).expect("a collision lies in a span");
            let pdf = media.free_flight_pdf(&scene, i, t);
            assert!(
                (pdf - prop.pdf).abs() <= 1e-4 * prop.pdf,
                "free_flight_pdf {pdf} against propagation's {} at t = {t} (span {i})",
                prop.pdf
            );
            collisions[i] += 1;
        }
    }
    assert!(collisions.iter().all(|&c| c > 100), "{collisions:?}");
    let y = scene.lights[0].sample_point(&scene.prims, glam::Vec2::ZERO, 0.0);
    let y = y.expect("a point light has its point").p;
    let total: f64 = media
        .spans()
        .iter()
        .enumerate()
        .map(|(i, sp)| {
            let pdf = |t: f64| media.equiangular_pdf(y, i, t as f32) as f64;
            simpson(pdf, sp.lo as f64, sp.hi as f64, 20_000)
        })
        .sum();
    assert!((total - 1.0).abs() < 1e-4, "the pdf integrates to {total}");
    // the stretches are the boxes' clips: nothing outside them
    for (i, sp) in media.spans().iter().enumerate() {
        let outside = [sp.t0 + 0.5 * (sp.lo - sp.t0), sp.hi + 0.5 * (sp.t1 - sp.hi)];
        for t in outside.into_iter().filter(|&t| t < sp.lo || t > sp.hi) {
            assert_eq!(media.equiangular_pdf(y, i, t), 0.0, "span {i} at t = {t}");
        }
    }
}

/// The two distance strategies' weights (the balance heuristic) sum to one wherever either
/// density is positive, and give the whole estimate to the only strategy that can draw a point.
#[test]
fn distance_weights_sum_to_one() {
    use pathspace::integrator::path::distance_mis;
    let scene = tracked_scene();
    let (ray, medium) = tracked_ray(&scene);
    let media = RayMedia::collect_from(&scene, ray, LEAD, medium);
    let y = Vec3::new(-0.3, 0.3, 0.1);
    let mut s = Sampler::new(16, 0, 0);
    for _ in 0..2_000 {
        let (i, t, pdf_eq) = media.sample_equiangular(y, s.next_f32()).unwrap();
        let pdf_ff = media.free_flight_pdf(&scene, i, t);
        let sum = distance_mis(pdf_ff, pdf_eq) + distance_mis(pdf_eq, pdf_ff);
        assert!((sum - 1.0).abs() <= 1e-6, "{pdf_ff} {pdf_eq}: {sum}");
    }
    assert_eq!(distance_mis(0.0, 2.0), 0.0);
    assert_eq!(distance_mis(2.0, 0.0), 1.0);
    assert_eq!(distance_mis(f32::INFINITY, 1.0), 1.0);
}

/// The path tracer through tracked media, lit by a point light that only next-event estimation
/// reaches: with equiangular MIS on every ray of the walk (after the floor and after medium
/// vertices) its estimate equals free flight's, depth by depth (1: single scattering; 2 and 4:
/// rays that leave surface and medium vertices), by Welch's test on independent samples.
#[test]
fn tracked_walk_agrees_with_and_without_equiangular_mis() {
    const N: u64 = 40_000;
    let mut fam = Family::new("equiangular: tracked media, with and without MIS");
    let scene = tracked_scene();
    let (ray, medium) = tracked_ray(&scene);
    let eye = Ray::new(
        Vec3::new(-1.9, 0.05, -0.02),
        Vec3::new(1.0, -0.25, 0.02).normalize(),
    );
    let eye_medium = scene.medium_at(eye.o);
    for depth in [1u32, 2, 4] {
        let mut est = Vec::new();
        for (k, distance) in [
            DistanceSampling::FreeFlight,
            DistanceSampling::EquiangularMis,
        ]
        .into_iter()
        .enumerate()
        {
            let pt = PathTracer::new(Some(depth)).with_distance(distance);
            let (mut sum, mut sum_sq) = ([0.0f64; 3], [0.0f64; 3]);
            for n in 0..N {
                let mut s = Sampler::new(17, n, (depth as u64) * 2 + k as u64);
                // half the samples from the floor's lifted ray, half from the eye
                let (r, m) = if n % 2 == 0 {
                    (ray, medium)
                } else {
                    (eye, eye_medium)
                };
                let l = pt.radiance(&scene, r, m, &mut s);
                for c in 0..3 {
                    sum[c] += l[c] as f64;
                    sum_sq[c] += (l[c] as f64).powi(2);
                }
            }
            let stats: Vec<(f64, f64, f64)> = (0..3)
                .map(|c| {
                    let mean = sum[c] / N as f64;
                    let var = (sum_sq[c] / N as f64 - mean * mean) * N as f64 / (N - 1) as f64;
                    (mean, (var / N as f64).sqrt(), (N - 1) as f64)
                })
                .collect();
            est.push(stats);
        }
        for (c, (ff, eq)) in est[0].iter().zip(&est[1]).enumerate() {
            fam.means_agree(&format!("depth {depth} channel {c}"), *ff, *eq);
        }
    }
    fam.finish();
}
