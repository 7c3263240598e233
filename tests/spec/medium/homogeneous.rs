//! Executable specification of `src/medium/homogeneous.rs` (book: "Table 1: homogeneous media").
//!
//! Free-flight sampling in a homogeneous medium (Pauly, Kollig, Keller 2000, Table 1, left
//! column): collision distances follow sigma_t exp(-sigma_t t), the surface at distance d is
//! reached with probability exp(-sigma_t d), the recorded pdf is the one `free_flight_pdf`
//! recomputes, and for chromatic sigma_t (one channel picked uniformly, pdf averaged over the
//! channels) the weights are unbiased for every channel.

use crate::common;

use common::stats::Family;
use common::*;
use glam::Vec3;
use pathspace::geometry::Ray;
use pathspace::math::Sampler;
use pathspace::medium::{FreeFlight, Homogeneous, Medium, MediumError, Phase};
use pathspace::spectrum::{average, Rgb};

/// A gray medium: the same sigma in every channel.
fn gray(sigma_a: f32, sigma_s: f32) -> Homogeneous {
    Homogeneous::new(Rgb::splat(sigma_a), Rgb::splat(sigma_s), Phase::Isotropic).unwrap()
}

/// The strongly chromatic medium of the brief: sigma_t = (0.2, 1.0, 3.0), albedos
/// (0.5, 0.8, 0.9) so that sigma_s differs from sigma_t in every channel.
fn chromatic() -> Homogeneous {
    let sigma_t = Vec3::new(0.2, 1.0, 3.0);
    let albedo = Vec3::new(0.5, 0.8, 0.9);
    Homogeneous::new(
        sigma_t * (Rgb::ONE - albedo),
        sigma_t * albedo,
        Phase::Isotropic,
    )
    .unwrap()
}

/// A medium whose first channel does not interact at all (sigma_t = 0).
fn with_clear_channel() -> Homogeneous {
    Homogeneous::new(
        Vec3::new(0.0, 0.3, 0.5),
        Vec3::new(0.0, 0.9, 1.5),
        Phase::Isotropic,
    )
    .unwrap()
}

/// One free flight on [0, t_max) with fresh random numbers (channel, then distance).
fn flight(medium: &Homogeneous, t_max: f32, s: &mut Sampler) -> FreeFlight {
    medium.sample_free_flight(t_max, s.next_f32(), s.next_f32())
}

/// Relative tolerance of deterministic f32 quantities (exp, ln, one average).
const F32_TOL: f64 = 16.0 * f32::EPSILON as f64;

#[test]
fn gray_collision_distances_follow_the_exponential_cdf() {
    const N: usize = 50_000;
    let mut fam = Family::new("free flight: gray exponential CDF");
    for (i, sigma_t) in [0.3f32, 1.0, 4.0].into_iter().enumerate() {
        let medium = gray(0.25 * sigma_t, 0.75 * sigma_t);
        let mut s = sampler(100, i as u64);
        let mut t: Vec<f64> = (0..N)
            .map(|_| {
                let ff = flight(&medium, f32::INFINITY, &mut s);
                assert!(
                    ff.scattered,
                    "got a flight that passed to t = {}, expected a collision (an infinite gray \
                     medium always collides)",
                    ff.t
                );
                ff.t as f64
            })
            .collect();
        let sigma = sigma_t as f64;
        fam.ks(&format!("sigma_t {sigma_t}"), &mut t, |t| {
            1.0 - (-sigma * t).exp()
        });
    }
    fam.finish();
}

#[test]
fn collision_distances_before_a_surface_follow_the_truncated_cdf() {
    // conditioned on colliding before d: (1 - exp(-sigma_t t)) / (1 - exp(-sigma_t d))
    const N: usize = 50_000;
    let (sigma_t, d) = (1.3f32, 0.9f32);
    let medium = gray(0.3, 1.0);
    let mut s = sampler(101, 0);
    let mut t = Vec::with_capacity(N);
    while t.len() < N {
        let ff = flight(&medium, d, &mut s);
        if ff.scattered {
            assert!(ff.t < d);
            t.push(ff.t as f64);
        }
    }
    let (sigma, d) = (sigma_t as f64, d as f64);
    let norm = 1.0 - (-sigma * d).exp();
    let mut fam = Family::new("free flight: truncated CDF");
    fam.ks("truncated", &mut t, |t| (1.0 - (-sigma * t).exp()) / norm);
    fam.finish();
}

#[test]
fn chromatic_collision_distances_follow_the_channel_average_cdf() {
    // picking a channel uniformly makes the distance density the average of the channels'
    // exponential densities, with CDF 1 - average(exp(-sigma_t t))
    const N: usize = 50_000;
    let medium = chromatic();
    let mut s = sampler(102, 0);
    let mut t: Vec<f64> = (0..N)
        .map(|_| flight(&medium, f32::INFINITY, &mut s).t as f64)
        .collect();
    let sigma = medium.sigma_t.as_dvec3();
    let mut fam = Family::new("free flight: chromatic CDF");
    fam.ks("chromatic", &mut t, |t| {
        1.0 - ((-sigma.x * t).exp() + (-sigma.y * t).exp() + (-sigma.z * t).exp()) / 3.0
    });
    fam.finish();
}

#[test]
fn passing_probability_is_the_transmittance() {
    const N: u64 = 100_000;
    let cases = [
        (gray(0.5, 1.5), 0.4f32),
        (gray(0.1, 0.2), 3.0),
        (chromatic(), 0.8),
    ];
    let mut fam = Family::new("free flight: passing probability");
    for (i, (medium, d)) in cases.into_iter().enumerate() {
        let mut s = sampler(103, i as u64);
        let passed = (0..N)
            .filter(|_| !flight(&medium, d, &mut s).scattered)
            .count() as u64;
        // exp(-sigma_t d) per channel, averaged over the uniformly chosen channel
        let p = average((-medium.sigma_t * d).exp()) as f64;
        fam.binomial(&format!("case {i}, d {d}"), passed, N, p);
    }
    fam.finish();
}

#[test]
fn chromatic_weights_are_unbiased_in_every_channel() {
    // E[weight 1{collision}]_c = int_0^d sigma_s,c exp(-sigma_t,c t) dt
    //                          = (sigma_s,c / sigma_t,c) (1 - exp(-sigma_t,c d)),
    // E[weight 1{pass}]_c      = exp(-sigma_t,c d).
    const N: usize = 200_000;
    let mut fam = Family::new("free flight: chromatic weights");
    for (i, (medium, d)) in [(chromatic(), 0.7f32), (with_clear_channel(), 1.5)]
        .into_iter()
        .enumerate()
    {
        let mut s = sampler(104, i as u64);
        let mut collide: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(N));
        let mut pass: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(N));
        for _ in 0..N {
            let ff = flight(&medium, d, &mut s);
            let w = ff.weight();
            assert!(w.is_finite() && w.min_element() >= 0.0, "weight {w}");
            for c in 0..3 {
                let (wc, wp) = if ff.scattered {
                    (w[c] as f64, 0.0)
                } else {
                    (0.0, w[c] as f64)
                };
                collide[c].push(wc);
                pass[c].push(wp);
            }
        }
        for c in 0..3 {
            let (sigma_t, sigma_s, d) =
                (medium.sigma_t[c] as f64, medium.sigma_s[c] as f64, d as f64);
            let collision_truth = if sigma_t > 0.0 {
                sigma_s / sigma_t * (1.0 - (-sigma_t * d).exp())
            } else {
                0.0
            };
            let dof = (N - 1) as f64;
            let (m, se) = mean_and_stderr(&collide[c]);
            let what = format!("medium {i}, channel {c}");
            fam.mean_is(&format!("{what}, collision"), m, se, dof, collision_truth);
            let (m, se) = mean_and_stderr(&pass[c]);
            fam.mean_is(&format!("{what}, pass"), m, se, dof, (-sigma_t * d).exp());
        }
    }
    fam.finish();
}

#[test]
fn free_flight_pdf_matches_the_sampled_pdf() {
    let mut s = sampler(105, 0);
    for medium in [gray(0.2, 0.9), chromatic(), with_clear_channel()] {
        for d in [0.1f32, 1.0, 5.0, f32::INFINITY] {
            for _ in 0..1000 {
                let ff = flight(&medium, d, &mut s);
                let pdf = medium.free_flight_pdf(ff.t, ff.scattered);
                assert_close("pdf", ff.pdf as f64, pdf as f64, F32_TOL);
                let tr = medium.transmittance(ff.t);
                assert_eq!(
                    ff.transmittance, tr,
                    "transmittance to the sampled t = {}: got {}, expected {tr}",
                    ff.t, ff.transmittance
                );
                let expected = if ff.scattered {
                    medium.sigma_s
                } else {
                    Rgb::ZERO
                };
                assert_eq!(
                    ff.sigma_s, expected,
                    "sigma_s of a flight (scattered: {}): got {}, expected {expected}",
                    ff.scattered, ff.sigma_s
                );
            }
        }
    }
}

#[test]
fn collision_density_and_passing_probability_sum_to_one() {
    // int_0^d p(t) dt + P(pass) = 1: the outcome space is collisions in [0, d) plus the surface.
    // Simpson's error for a sum of exponentials exp(-sigma t) on [0, d] is bounded by
    // d h^4 max(sigma)^5 / 180, below 1e-12 here.
    const N_T: usize = 4096;
    for medium in [gray(0.2, 0.9), chromatic(), with_clear_channel()] {
        for d in [0.1f32, 1.0, 5.0] {
            let collide = simpson(
                |t| medium.free_flight_pdf(t as f32, true) as f64,
                0.0,
                d as f64,
                N_T,
            );
            let pass = medium.free_flight_pdf(d, false) as f64;
            assert_close("total probability", collide + pass, 1.0, F32_TOL);
        }
    }
}

#[test]
fn transmittance_is_exp_minus_sigma_t_d() {
    let medium = chromatic();
    for d in [0.0f32, 0.5, 2.0] {
        let tr = medium.transmittance(d);
        for c in 0..3 {
            let truth = (-(medium.sigma_t[c] as f64) * d as f64).exp();
            assert_close("transmittance", tr[c] as f64, truth, F32_TOL);
        }
    }
    let got = medium.transmittance(f32::INFINITY);
    assert_eq!(
        got,
        Rgb::ZERO,
        "transmittance to infinity: got {got}, expected 0 in every channel"
    );
    let got = with_clear_channel().transmittance(f32::INFINITY);
    assert_eq!(
        got,
        Vec3::new(1.0, 0.0, 0.0),
        "transmittance to infinity with sigma_t = 0 in channel 0: got {got}, expected (1, 0, 0)"
    );
}

#[test]
fn a_channel_without_extinction_passes_to_infinity() {
    // with t_max infinite, only the clear channel reaches "the surface at infinity"; it is
    // picked with probability 1/3 and weighted 3, so its expected pass weight is exactly 1
    const N: u64 = 10_000;
    let medium = with_clear_channel();
    let mut s = sampler(106, 0);
    let mut passes = 0;
    for _ in 0..N {
        let ff = flight(&medium, f32::INFINITY, &mut s);
        let w = ff.weight();
        assert!(w.is_finite(), "weight {w}");
        if !ff.scattered {
            passes += 1;
            assert_eq!(w, Vec3::new(3.0, 0.0, 0.0));
        } else {
            assert!(ff.t.is_finite());
            assert_eq!(w.x, 0.0, "the clear channel scatters");
        }
    }
    // the flight passes exactly when the clear channel is picked
    let mut fam = Family::new("free flight: the clear channel passes");
    fam.binomial("passes", passes, N, 1.0 / 3.0);
    fam.finish();
    // a medium that is entirely vacuum never collides and passes with weight one
    let vacuum = gray(0.0, 0.0);
    let ff = flight(&vacuum, 2.0, &mut s);
    assert!(!ff.scattered);
    assert_eq!(ff.weight(), Rgb::ONE);
}

#[test]
fn the_medium_wrapper_draws_channel_then_distance() {
    // Medium::sample_free_flight consumes (u_channel, u) from the sampler in this order
    let h = chromatic();
    let medium = Medium::Homogeneous(h.clone());
    let ray = Ray::new(Vec3::ZERO, Vec3::Z);
    for i in 0..100 {
        let mut a = sampler(107, i);
        let mut b = sampler(107, i);
        let x = medium.sample_free_flight(&ray, 1.0, &mut a);
        let y = flight(&h, 1.0, &mut b);
        assert_eq!((x.t, x.scattered, x.pdf), (y.t, y.scattered, y.pdf));
        assert_eq!(medium.free_flight_pdf(&ray, x.t, x.scattered), x.pdf);
    }
}

#[test]
fn constructor_rejects_negative_or_non_finite_coefficients() {
    for bad in [-0.1f32, f32::NAN, f32::INFINITY] {
        for (sa, ss) in [(bad, 1.0), (1.0, bad)] {
            let r = Homogeneous::new(Vec3::new(0.5, sa, 0.5), Rgb::splat(ss), Phase::Isotropic);
            assert!(
                matches!(r, Err(MediumError::NegativeCoefficient { .. })),
                "accepted sigma_a {sa}, sigma_s {ss}"
            );
        }
    }
    let ok = gray(0.25, 0.75);
    assert_eq!(ok.sigma_t, Rgb::ONE);
    assert_eq!(ok.albedo(), Rgb::splat(0.75));
    assert_eq!(with_clear_channel().albedo().x, 0.0);
}
