//! Executable specification of the microfacet BSDFs (`src/bsdf/{microfacet, conductor,
//! rough_dielectric}.rs`; book: "Surface scattering", section "Rough surfaces").
//!
//! The GGX distribution's normalization and Smith's Lambda against it (Walter et al. 2007,
//! eqs. (33), (34); the visible-normal identity of Heitz 2018, eq. 1); each sampler against
//! its density by chi-square over several (wo, alpha); reciprocity of reflection and the
//! generalized (eta^2) relation of refraction with its adjoint; the white furnace of the rough
//! conductor (its single-scattering albedo by two independent quadratures against the
//! sampler's mean weight); the limit alpha -> 0 against the mirror and the smooth dielectric;
//! the conductor's complex Fresnel against the dielectric's. Anisotropic roughness: D against
//! Heitz 2014's eqs. 81, 82, Lambda at the projected roughness (eq. 80) against the visible
//! projected area, the stretched samplers by chi-square, the models' sampling, reciprocity and
//! white furnace in the frame of a tangent that needs Gram-Schmidt.

use crate::common;

use common::stats::Family;
use common::*;
use glam::{Vec2, Vec3};
use pathspace::bsdf::conductor::fresnel_complex;
use pathspace::bsdf::{
    fresnel_dielectric, Anisotropy, Beckmann, Bsdf, ConductorFresnel, Dielectric, Distribution,
    Ggx, Lobe, Microfacet, Mirror, RoughConductor, RoughDielectric, TransportMode,
};
use pathspace::math::distribution::ONE_MINUS_EPSILON;
use pathspace::math::{warp, Frame, Sampler};
use std::f64::consts::{PI, TAU};

const ALPHAS: [f32; 3] = [0.15, 0.4, 1.0];

/// Both distributions: every test of the rough models runs for each.
const DISTRIBUTIONS: [Distribution; 2] = [Distribution::Ggx, Distribution::Beckmann];

/// A tilted normal, so that no axis of the frame is special.
fn normal() -> Vec3 {
    Vec3::new(0.3, -0.4, 0.866).normalize()
}

fn conductor(distribution: Distribution, alpha: f32) -> Bsdf {
    Bsdf::RoughConductor(RoughConductor {
        distribution,
        alpha,
        fresnel: ConductorFresnel::Schlick(Vec3::ONE),
        specular: Vec3::ONE,
        one_sided: false,
        anisotropy: None,
    })
}

fn dielectric(distribution: Distribution, alpha: f32) -> Bsdf {
    Bsdf::RoughDielectric(RoughDielectric {
        ior: 1.5,
        distribution,
        alpha,
        specular: pathspace::bsdf::Specular::ONE,
        anisotropy: None,
    })
}

/// The integral over the whole sphere around `n` of `f`, by Simpson's rule in (cos theta, phi)
/// on each hemisphere.
fn sphere_integral(n: Vec3, f: impl Fn(Vec3) -> f64, n_mu: usize, n_phi: usize) -> f64 {
    let frame = Frame::from_normal(n);
    let hemi = |sign: f64| {
        simpson(
            |mu| simpson(|phi| f(direction(&frame, sign * mu, phi)), 0.0, TAU, n_phi),
            0.0,
            1.0,
            n_mu,
        )
    };
    hemi(1.0) + hemi(-1.0)
}

/// The integral over the hemisphere around `n` (the conductor's side) of `f`.
fn hemisphere_integral(n: Vec3, f: impl Fn(Vec3) -> f64, n_mu: usize, n_phi: usize) -> f64 {
    let frame = Frame::from_normal(n);
    simpson(
        |mu| simpson(|phi| f(direction(&frame, mu, phi)), 0.0, TAU, n_phi),
        0.0,
        1.0,
        n_mu,
    )
}

/// The integral of `g(m)` D(m) over the hemisphere of microfacet normals in the local frame,
/// in the variable y = x / (1 + x), x = tan(theta_m) / alpha, which spreads the lobe evenly at
/// any alpha (written independently of the crate's slope form of D).
fn facet_integral(alpha: f64, g: impl Fn(Vec3) -> f64, n_y: usize, n_phi: usize) -> f64 {
    simpson(
        |y| {
            if y >= 1.0 {
                return 0.0;
            }
            let x = y / (1.0 - y);
            let dx_dy = 1.0 / ((1.0 - y) * (1.0 - y));
            let theta = (alpha * x).atan();
            let dtheta_dx = alpha / (1.0 + alpha * alpha * x * x);
            let c = theta.cos();
            let d = 1.0 / (PI * alpha * alpha * c.powi(4) * (1.0 + x * x).powi(2));
            simpson(
                |phi| {
                    let m = Vec3::new(
                        (theta.sin() * phi.cos()) as f32,
                        (theta.sin() * phi.sin()) as f32,
                        c as f32,
                    );
                    g(m) * d * theta.sin() * dtheta_dx * dx_dy
                },
                0.0,
                TAU,
                n_phi,
            )
        },
        0.0,
        1.0,
        n_y,
    )
}

#[test]
fn ggx_is_normalized_and_smith_lambda_is_its_projected_area() {
    // int D(m) cos(theta_m) dm = 1 (Walter et al. 2007, eq. (4)), and the visible projected
    // area int max(0, v.m) D(m) dm = v.z (1 + Lambda(v)), the identity that defines Smith's
    // Lambda (Heitz 2018, eq. 1 integrates to one exactly then); quadrature in f64
    for alpha in [0.01f32, 0.15, 0.4, 1.0] {
        let ggx = Ggx { alpha };
        let a = alpha as f64;
        for x in [0.0f64, 0.3, 1.0, 3.0, 30.0] {
            // eq. (33) at tan(theta_m) = alpha x, against the crate's slope form
            let theta = (a * x).atan();
            let eq33 = 1.0 / (PI * a * a * theta.cos().powi(4) * (1.0 + x * x).powi(2));
            let m = Vec3::new(theta.sin() as f32, 0.0, theta.cos() as f32);
            let what = format!("alpha {alpha}, x {x}: D");
            assert_close(&what, ggx.d(m) as f64, eq33, 1e-5 * eq33);
        }
        let closed = facet_integral(a, |m| m.z as f64, 2000, 4);
        assert_close(&format!("alpha {alpha}: int D cos"), closed, 1.0, 1e-6);
        for cos_v in [0.95f64, 0.5, 0.1] {
            let v = Vec3::new((1.0 - cos_v * cos_v).sqrt() as f32, 0.0, cos_v as f32);
            let projected = facet_integral(alpha as f64, |m| (v.dot(m) as f64).max(0.0), 2000, 256);
            let smith = cos_v * (1.0 + ggx.lambda(v) as f64);
            assert_close(
                &format!("alpha {alpha}, cos_v {cos_v}: projected area vs Lambda"),
                projected,
                smith,
                2e-4,
            );
            assert_close(
                &format!("alpha {alpha}, cos_v {cos_v}: G1 = 1 / (1 + Lambda)"),
                ggx.g1(v, Vec3::Z) as f64,
                1.0 / (1.0 + ggx.lambda(v) as f64),
                1e-6,
            );
        }
    }
}

/// The integral of `g(m)` D(m) over the facet normals for Beckmann, in x = tan(theta_m) /
/// alpha (D = exp(-x^2) / (pi alpha^2 cos^4 theta_m), Walter et al. 2007, eq. (25), written
/// here independently of the crate), truncated at x = 8 where exp(-x^2) < 1e-27.
fn beckmann_integral(alpha: f64, g: impl Fn(Vec3) -> f64, n_x: usize, n_phi: usize) -> f64 {
    simpson(
        |x| {
            let theta = (alpha * x).atan();
            let dtheta_dx = alpha / (1.0 + alpha * alpha * x * x);
            let c = theta.cos();
            let d = (-x * x).exp() / (PI * alpha * alpha * c.powi(4));
            simpson(
                |phi| {
                    let m = Vec3::new(
                        (theta.sin() * phi.cos()) as f32,
                        (theta.sin() * phi.sin()) as f32,
                        c as f32,
                    );
                    g(m) * d * theta.sin() * dtheta_dx
                },
                0.0,
                TAU,
                n_phi,
            )
        },
        0.0,
        8.0,
        n_x,
    )
}

/// Smith's Lambda for Beckmann in closed form, (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)),
/// a = 1 / (alpha tan theta) (Walter et al. 2007, eq. (26)), by statrs' erf.
fn beckmann_lambda(alpha: f64, cos_v: f64) -> f64 {
    let a = cos_v / (alpha * (1.0 - cos_v * cos_v).sqrt());
    (statrs::function::erf::erf(a) - 1.0) / 2.0 + (-a * a).exp() / (2.0 * a * PI.sqrt())
}

#[test]
fn beckmann_is_normalized_and_g1_is_walters_rational_approximation() {
    // the projected area of D is 1, the visible projected area is v.z (1 + Lambda(v)) with the
    // closed-form Lambda, and G1 is the rational approximation of eq. (27) Mitsuba 3
    // evaluates: within its stated 0.35% of 1 / (1 + Lambda), exactly 1 from a = 1.6 on
    for alpha in [0.01f32, 0.15, 0.4, 1.0] {
        let b = Beckmann { alpha };
        let a = alpha as f64;
        for x in [0.0f64, 0.3, 1.0, 2.5] {
            let theta = (a * x).atan();
            let eq25 = (-x * x).exp() / (PI * a * a * theta.cos().powi(4));
            let m = Vec3::new(theta.sin() as f32, 0.0, theta.cos() as f32);
            assert_close(
                &format!("alpha {alpha}, x {x}: D"),
                b.d(m) as f64,
                eq25,
                1e-5 * eq25,
            );
        }
        let area = beckmann_integral(a, |m| m.z as f64, 2000, 4);
        assert_close(&format!("alpha {alpha}: int D cos"), area, 1.0, 1e-6);
        for cos_v in [0.95f64, 0.5, 0.1] {
            let v = Vec3::new((1.0 - cos_v * cos_v).sqrt() as f32, 0.0, cos_v as f32);
            let lambda = beckmann_lambda(a, cos_v);
            let what = format!("alpha {alpha}, cos_v {cos_v}");
            let projected = beckmann_integral(a, |m| (v.dot(m) as f64).max(0.0), 2000, 256);
            assert_close(
                &format!("{what}: projected area"),
                projected,
                cos_v * (1.0 + lambda),
                2e-4,
            );
            assert_close(
                &format!("{what}: crate Lambda"),
                b.lambda(v),
                lambda,
                1e-9 + 1e-6 * lambda,
            );
            let exact = 1.0 / (1.0 + lambda);
            let g1 = b.g1(v, Vec3::Z) as f64;
            assert_close(
                &format!("{what}: G1 within 0.35%"),
                g1,
                exact,
                0.0035 * exact,
            );
            let ar = cos_v / (a * (1.0 - cos_v * cos_v).sqrt());
            let rational = if ar >= 1.6 {
                1.0
            } else {
                (3.535 * ar + 2.181 * ar * ar) / (1.0 + 2.276 * ar + 2.577 * ar * ar)
            };
            assert_close(&format!("{what}: G1 is eq. (27)"), g1, rational, 1e-6);
        }
        // either side of the cut at a = 1.6 (the rational form is 0.99976 at a = 1.5 and
        // 1.0000056 at 1.55: the cut is where it crosses 1, not exactly 1 at 1.6)
        for ar in [1.5f64, 1.55, 1.65] {
            let theta = (1.0 / (a * ar)).atan();
            let v = Vec3::new(theta.sin() as f32, 0.0, theta.cos() as f32);
            let what = format!("alpha {alpha}, a {ar}: the cut");
            let exact = (3.535 * ar + 2.181 * ar * ar) / (1.0 + 2.276 * ar + 2.577 * ar * ar);
            let expected = if ar >= 1.6 { 1.0 } else { exact };
            assert_close(&what, b.g1(v, Vec3::Z) as f64, expected, 1e-6);
        }
    }
}

#[test]
fn beckmann_sampler_draws_d_cos() {
    // the facet sampler of the Beckmann models against D(m) cos theta_m by chi-square
    const N: u64 = 200_000;
    let mut fam = Family::new("microfacet: Beckmann facet sampler vs D cos");
    let frame = Frame::from_normal(Vec3::Z);
    for (i, alpha) in [0.15f32, 0.4, 1.0].into_iter().enumerate() {
        let g = Microfacet::new(Distribution::Beckmann, alpha);
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let mut grid = SphereGrid::new(frame, 40, 16);
        grid.quad_cos = 1024;
        let mut s = sampler(30, i as u64);
        chi_square_sphere(
            &mut fam,
            &format!("alpha {alpha}"),
            &grid,
            || Some(g.sample(wo, s.next_2d())),
            |m| (g.d(m) * m.z.max(0.0)) as f64,
            N,
        );
        // the density a model uses is D cos on the facets wo sees, zero behind
        let m = Vec3::new(-0.8, 0.0, 0.6);
        assert_eq!(g.pdf(wo, m), 0.0);
        let m = Vec3::new(0.28, 0.0, 0.96);
        assert_eq!(g.pdf(wo, m), g.d(m) * m.z);
    }
    fam.finish();
}

/// One sampler against its density: chi-square over the sphere, and the fraction of draws
/// that returned a direction against the density's total mass (binomial).
fn check_sampler(fam: &mut Family, what: &str, bsdf: &Bsdf, wo: Vec3, seed: (u64, u64)) {
    const N: u64 = 200_000;
    let n = normal();
    let mut grid = SphereGrid::new(Frame::from_normal(n), 40, 16);
    grid.quad_phi = 64;
    let mut s = sampler(seed.0, seed.1);
    let mode = TransportMode::Radiance;
    let mut hits = 0u64;
    chi_square_sphere(
        fam,
        what,
        &grid,
        || {
            let bs = bsdf.sample(wo, n, s.next_2d(), s.next_f32(), mode)?;
            assert_eq!(bs.lobe, Lobe::Regular, "{what}: a glossy lobe is regular");
            assert!(bs.pdf > 0.0 && bs.value.is_finite(), "{what}: {bs:?}");
            assert_close(
                &format!("{what}: sample pdf = pdf"),
                bs.pdf as f64,
                bsdf.pdf(wo, bs.wi, n) as f64,
                1e-5 * bs.pdf as f64,
            );
            hits += 1;
            Some(bs.wi)
        },
        |wi| bsdf.pdf(wo, wi, n) as f64,
        N,
    );
    let mass = sphere_integral(n, |wi| bsdf.pdf(wo, wi, n) as f64, 1024, 256);
    assert!(
        mass <= 1.0 + 2e-3,
        "{what}: the density integrates to {mass}"
    );
    fam.binomial(&format!("{what}: mass"), hits, N, mass.min(1.0 - 1e-9));
}

#[test]
fn rough_conductor_samples_its_density() {
    let mut fam = Family::new("microfacet: rough conductor sampling vs pdf");
    let n = normal();
    for (k, dist) in DISTRIBUTIONS.into_iter().enumerate() {
        for (i, alpha) in ALPHAS.into_iter().enumerate() {
            for (j, cos_o) in [0.9f64, 0.5, -0.2].into_iter().enumerate() {
                let wo = direction(&Frame::from_normal(n), cos_o, 1.0);
                let what = format!("conductor {dist:?} alpha {alpha}, cos_o {cos_o}");
                let seed = (1 + 10 * k as u64, (3 * i + j) as u64);
                check_sampler(&mut fam, &what, &conductor(dist, alpha), wo, seed);
            }
        }
    }
    fam.finish();
}

#[test]
fn rough_dielectric_samples_its_density() {
    // from outside, and from inside the denser side (beyond the critical angle at -0.6's
    // facets some light is totally reflected)
    let mut fam = Family::new("microfacet: rough dielectric sampling vs pdf");
    let n = normal();
    for (k, dist) in DISTRIBUTIONS.into_iter().enumerate() {
        for (i, alpha) in ALPHAS.into_iter().enumerate() {
            for (j, cos_o) in [0.8f64, 0.3, -0.6].into_iter().enumerate() {
                let wo = direction(&Frame::from_normal(n), cos_o, 1.0);
                let what = format!("dielectric {dist:?} alpha {alpha}, cos_o {cos_o}");
                let seed = (2 + 10 * k as u64, (3 * i + j) as u64);
                check_sampler(&mut fam, &what, &dielectric(dist, alpha), wo, seed);
            }
        }
    }
    fam.finish();
}

/// Random pairs of directions not within `GRAZING` of the surface.
fn pairs(seed: u64, n: Vec3) -> Vec<(Vec3, Vec3)> {
    const GRAZING: f32 = 0.05;
    let mut s = sampler(seed, 0);
    let mut out = Vec::new();
    while out.len() < 2000 {
        let a = warp::uniform_sphere(s.next_2d());
        let b = warp::uniform_sphere(s.next_2d());
        if a.dot(n).abs() > GRAZING && b.dot(n).abs() > GRAZING {
            out.push((a, b));
        }
    }
    out
}

/// Relative tolerance of f32 BSDF values compared in two argument orders: the half vector and
/// the Fresnel term are computed from the other side, a few hundred ulps of an order-one term.
const REL: f64 = 2e-4;
/// An absolute allowance: values this far below the BSDF's order-one scale come from facets
/// seen within ~1e-6 of grazing, where the facet's cosine (a dot product of unit f32 vectors,
/// absolute error ~6e-8) has no significant digit left and 1 - F even less.
const ABS: f64 = 1e-7;

/// The (distribution, alpha) pairs of the reciprocity tests: Beckmann's Gaussian tail leaves
/// too few random pairs inside a narrow lobe to count (30 of 2000 at alpha 0.01, 418 at
/// 0.05), so its narrowest is 0.15.
fn reciprocity_cases() -> Vec<(Distribution, f32)> {
    let ggx = [0.01f32, 0.15, 0.4, 1.0].map(|a| (Distribution::Ggx, a));
    let beckmann = [0.15f32, 0.4, 1.0].map(|a| (Distribution::Beckmann, a));
    ggx.into_iter().chain(beckmann).collect()
}

#[test]
fn rough_conductor_is_reciprocal() {
    let n = normal();
    for (dist, alpha) in reciprocity_cases() {
        let metal = Bsdf::RoughConductor(RoughConductor {
            distribution: dist,
            alpha,
            fresnel: ConductorFresnel::Complex {
                eta: Vec3::new(0.2, 0.9, 1.1),
                k: Vec3::new(3.9, 2.4, 2.1),
            },
            specular: Vec3::ONE,
            one_sided: false,
            anisotropy: None,
        });
        let mut nonzero = 0;
        for (a, b) in pairs(3, n) {
            for mode in [TransportMode::Radiance, TransportMode::Importance] {
                let (fab, fba) = (metal.eval(a, b, n, mode), metal.eval(b, a, n, mode));
                for c in 0..3 {
                    let (x, y) = (fab[c] as f64, fba[c] as f64);
                    assert_close(
                        &format!("alpha {alpha}: f({a}, {b})"),
                        x,
                        y,
                        REL * x.max(y) + ABS,
                    );
                }
                nonzero += (fab.x > 0.0) as usize;
            }
            if a.dot(n) * b.dot(n) < 0.0 {
                assert_eq!(metal.eval(a, b, n, TransportMode::Radiance), Vec3::ZERO);
            }
        }
        assert!(
            nonzero > 1000,
            "alpha {alpha}: only {nonzero} pairs reflect"
        );
    }
}

/// The index of refraction on `w`'s side of a rough dielectric of index `ior` (inside).
fn eta_of(w: Vec3, n: Vec3, ior: f32) -> f64 {
    if w.dot(n) > 0.0 {
        1.0
    } else {
        ior as f64
    }
}

#[test]
fn rough_dielectric_satisfies_generalized_reciprocity_and_its_adjoint() {
    // f(wo, wi) / eta_o^2 = f(wi, wo) / eta_i^2 for the radiance BSDF (reflection: eta_o =
    // eta_i, plain reciprocity), and the importance BSDF is the radiance BSDF with its
    // arguments swapped: f*(wo, wi) = f(wi, wo)
    let n = normal();
    for ior in [1.5f32, 0.75] {
        for (dist, alpha) in reciprocity_cases() {
            let glass = Bsdf::RoughDielectric(RoughDielectric {
                ior,
                distribution: dist,
                alpha,
                specular: pathspace::bsdf::Specular::ONE,
                anisotropy: None,
            });
            let (mut refracting, mut reflecting) = (0, 0);
            for (a, b) in pairs(4, n) {
                let r_ab = glass.eval(a, b, n, TransportMode::Radiance).x as f64;
                let r_ba = glass.eval(b, a, n, TransportMode::Radiance).x as f64;
                let i_ab = glass.eval(a, b, n, TransportMode::Importance).x as f64;
                let (ea, eb) = (eta_of(a, n, ior), eta_of(b, n, ior));
                let what = format!("ior {ior}, alpha {alpha}, ({a}, {b})");
                let (x, y) = (r_ab / (ea * ea), r_ba / (eb * eb));
                assert_close(&format!("{what}: generalized"), x, y, REL * x.max(y) + ABS);
                assert_close(
                    &format!("{what}: adjoint"),
                    i_ab,
                    r_ba,
                    REL * i_ab.max(r_ba) + ABS,
                );
                if r_ab > 0.0 {
                    if a.dot(n) * b.dot(n) < 0.0 {
                        refracting += 1;
                    } else {
                        reflecting += 1;
                    }
                }
            }
            assert!(
                refracting > 50 && reflecting > 50,
                "{refracting} {reflecting}"
            );
        }
    }
}

/// The rough conductor's directional albedo at normal incidence with F = 1, written as a 1-D
/// integral over the facet angle: seen from the normal, the visible normals are D(m) cos
/// theta_m, the reflection leaves at 2 theta_m (below the horizon beyond 45 degrees) and is
/// shadowed by G1(2 theta_m). Independent of the crate's sampler and of any 2-D quadrature.
fn normal_incidence_albedo(alpha: f64) -> f64 {
    let lambda = |theta: f64| {
        let t2 = theta.tan().powi(2);
        (-1.0 + (1.0 + alpha * alpha * t2).sqrt()) / 2.0
    };
    let d = |theta: f64| {
        let t2 = theta.tan().powi(2);
        1.0 / (PI * alpha * alpha * theta.cos().powi(4) * (1.0 + t2 / (alpha * alpha)).powi(2))
    };
    TAU * simpson(
        |t| d(t) * t.cos() * t.sin() / (1.0 + lambda(2.0 * t)),
        0.0,
        PI / 4.0,
        20_000,
    )
}

/// The error of the albedo's 4096 x 1024 Simpson quadrature, bounded from above.
const QUAD_ERR: f64 = 1e-6;

/// The directional albedo of `bsdf` seen from `wo` (red channel) two ways: by the Simpson
/// quadrature of f |cos| over the sphere (from `eval`), and as the mean of `count` sampled
/// weights (from `sample`) with its standard error.
fn albedo_two_ways(
    bsdf: &Bsdf,
    wo: Vec3,
    n: Vec3,
    s: &mut Sampler,
    count: usize,
) -> (f64, f64, f64) {
    let mode = TransportMode::Radiance;
    let f_cos = |wi: Vec3| bsdf.eval(wo, wi, n, mode).x as f64 * wi.dot(n).abs() as f64;
    let quad = hemisphere_integral(n, f_cos, 4096, 1024);
    let w: Vec<f64> = (0..count)
        .map(|_| {
            bsdf.sample(wo, n, s.next_2d(), s.next_f32(), mode)
                .map_or(0.0, |bs| bs.weight(n).x as f64)
        })
        .collect();
    let (mean, se) = mean_and_stderr(&w);
    (quad, mean, se)
}

#[test]
fn white_furnace_rough_conductor_loses_only_what_single_scattering_drops() {
    // with F = 1 every ray the microsurface does not shadow is reflected, so the directional
    // albedo is the single-scattering albedo E(wo) < 1, and 1 - E(wo) is the energy of the
    // paths that meet a second facet, which the model drops. E by quadrature of f |cos| over
    // the sphere (from eval), by the sampler's mean weight (from sample: its own variance),
    // and at normal incidence by the 1-D integral above.
    const N: usize = 100_000;
    let mut fam = Family::new("microfacet: white furnace of the rough conductor");
    let n = normal();
    let frame = Frame::from_normal(n);
    let mut table = Vec::new();
    let configs = DISTRIBUTIONS
        .into_iter()
        .flat_map(|d| [0.2f32, 0.5, 1.0].map(|a| (d, a)));
    for (i, (dist, alpha)) in configs.enumerate() {
        let bsdf = conductor(dist, alpha);
        for (j, cos_o) in [1.0f64, 0.6, 0.3, 0.1].into_iter().enumerate() {
            let wo = direction(&frame, cos_o, 0.5);
            let (quad, mean, se) =
                albedo_two_ways(&bsdf, wo, n, &mut sampler(5, (4 * i + j) as u64), N);
            let what = format!("{dist:?} alpha {alpha}, cos_o {cos_o}");
            // the quadrature's own error (about 1e-7 here) joins the sampling error: Beckmann's
            // rational G1 is exactly 1 near the normal, so at normal incidence and small alpha
            // nearly every weight is exactly 1 and the standard error nearly 0
            fam.mean_is(
                &format!("{what}: E by sampling"),
                mean,
                (se * se + QUAD_ERR * QUAD_ERR).sqrt(),
                (N - 1) as f64,
                quad,
            );
            assert!(quad <= 1.0 + 1e-4, "{what}: albedo {quad} above 1");
            if cos_o == 1.0 && dist == Distribution::Ggx {
                let exact = normal_incidence_albedo(alpha as f64);
                assert_close(&format!("{what}: 1-D vs 2-D"), quad, exact, 2e-3);
            }
            table.push(format!("alpha {alpha} cos_o {cos_o}: E = {quad:.4}"));
        }
    }
    eprintln!("{}", table.join("\n"));
    fam.finish();
}

/// The angle between two unit vectors, robust near zero.
fn angle(a: Vec3, b: Vec3) -> f64 {
    2.0 * ((a - b).length() as f64 / 2.0).asin()
}

/// Alpha -> 0: the limit of the rough models. The energy the rough models drop and the spread
/// of their lobes are O(alpha^2) and O(alpha) (GGX's slope density has tails ~ alpha^2 /
/// tan^4), so at alpha = 1e-3 the means of the weights may differ from the smooth model's by
/// `LIMIT_BIAS` beyond their own standard error, and the median deviation from the smooth
/// direction is a few alpha.
const ALPHA_SMALL: f32 = 1e-3;
const LIMIT_BIAS: f64 = 100.0 * (ALPHA_SMALL as f64) * (ALPHA_SMALL as f64);

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

#[test]
fn small_alpha_conductor_is_the_mirror() {
    const N: usize = 20_000;
    let n = normal();
    let r0 = Vec3::new(0.9, 0.6, 0.3);
    let mut fam = Family::new("microfacet: alpha -> 0 is the mirror");
    let configs = DISTRIBUTIONS
        .into_iter()
        .flat_map(|d| [0.95f64, 0.5, -0.3].map(|c| (d, c)));
    for (k, (dist, cos_o)) in configs.enumerate() {
        let rough = Bsdf::RoughConductor(RoughConductor {
            distribution: dist,
            alpha: ALPHA_SMALL,
            fresnel: ConductorFresnel::Schlick(r0),
            specular: Vec3::ONE,
            one_sided: false,
            anisotropy: None,
        });
        let wo = direction(&Frame::from_normal(n), cos_o, 2.0);
        // the mirror with the Fresnel reflectance of this angle (Schlick's about r0)
        let schlick = r0 + (Vec3::ONE - r0) * (1.0 - cos_o.abs() as f32).powi(5);
        let mirror = Bsdf::Mirror(Mirror {
            reflectance: schlick,
            one_sided: false,
        });
        let m = mirror
            .sample(wo, n, Vec2::ZERO, 0.0, TransportMode::Radiance)
            .unwrap();
        let mut s = sampler(6, k as u64);
        let (mut dev, mut w) = (Vec::new(), vec![Vec::new(); 3]);
        for _ in 0..N {
            let bs = rough
                .sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Radiance)
                .map(|bs| (bs.wi, bs.weight(n)));
            let (wi, weight) = bs.unwrap_or((-m.wi, Vec3::ZERO));
            dev.push(angle(wi, m.wi));
            for (c, wc) in w.iter_mut().enumerate() {
                wc.push(weight[c] as f64);
            }
        }
        let what = format!("{dist:?} cos_o {cos_o}");
        let med = median(dev);
        assert!(
            med < 4.0 * ALPHA_SMALL as f64,
            "{what}: median angle to the mirror direction {med}"
        );
        for (c, wc) in w.iter().enumerate() {
            let (mean, se) = mean_and_stderr(wc);
            let truth = m.weight(n)[c] as f64;
            fam.mean_is(
                &format!("{what}: weight channel {c}"),
                mean,
                (se * se + LIMIT_BIAS * LIMIT_BIAS).sqrt(),
                (N - 1) as f64,
                truth,
            );
        }
    }
    fam.finish();
}

#[test]
fn small_alpha_dielectric_is_the_smooth_dielectric() {
    // the reflection frequency is the Fresnel reflectance, the refracted direction obeys
    // Snell's law, and each lobe's weight is the smooth one's, (eta_o / eta_t)^2 for
    // refracted radiance and 1 for importance: the eta^2 scaling of both modes
    const N: u64 = 40_000;
    let n = normal();
    let ior = 1.5f32;
    let smooth = Bsdf::Dielectric(Dielectric::new(ior));
    let mut fam = Family::new("microfacet: alpha -> 0 is the smooth dielectric");
    let configs = DISTRIBUTIONS
        .into_iter()
        .flat_map(|d| [0.9f64, 0.4, -0.8, -0.3].map(|c| (d, c)));
    for (k, (dist, cos_o)) in configs.enumerate() {
        let rough = Bsdf::RoughDielectric(RoughDielectric {
            ior,
            distribution: dist,
            alpha: ALPHA_SMALL,
            specular: pathspace::bsdf::Specular::ONE,
            anisotropy: None,
        });
        let wo = direction(&Frame::from_normal(n), cos_o, 0.7);
        for mode in [TransportMode::Radiance, TransportMode::Importance] {
            let r = smooth.sample(wo, n, Vec2::ZERO, 0.0, mode).unwrap();
            let t = smooth
                .sample(wo, n, Vec2::ZERO, ONE_MINUS_EPSILON, mode)
                .filter(|t| t.lobe == Lobe::SingularTransmission);
            let f = fresnel_dielectric(
                cos_o.abs() as f32,
                if cos_o > 0.0 { ior } else { 1.0 / ior },
            );
            let mut s = sampler(7, 2 * k as u64 + (mode == TransportMode::Importance) as u64);
            let (mut hits, mut dev_r, mut dev_t) = (0u64, Vec::new(), Vec::new());
            let (mut w_r, mut w_t) = (Vec::new(), Vec::new());
            for _ in 0..N {
                let Some(bs) = rough.sample(wo, n, s.next_2d(), s.next_f32(), mode) else {
                    continue;
                };
                let w = bs.weight(n).x as f64;
                if bs.wi.dot(n) * wo.dot(n) > 0.0 {
                    hits += 1;
                    dev_r.push(angle(bs.wi, r.wi));
                    w_r.push(w);
                } else {
                    dev_t.push(angle(bs.wi, t.unwrap().wi));
                    w_t.push(w);
                }
            }
            let what = format!("{dist:?} cos_o {cos_o}, {mode:?}");
            fam.binomial(&format!("{what}: P(reflect) = F"), hits, N, f as f64);
            assert!(
                median(dev_r) < 4.0 * ALPHA_SMALL as f64,
                "{what}: reflection"
            );
            // a rough lobe's weight is G1(wi) times the smooth lobe's (1, or (eta_o/eta_t)^2
            // for refracted radiance): the facet's Fresnel choice cancels its Fresnel factor
            let mut lobes = vec![(w_r, r.weight(n).x as f64)];
            if let Some(t) = t {
                assert!(median(dev_t) < 4.0 * ALPHA_SMALL as f64, "{what}: Snell");
                lobes.push((w_t, t.weight(n).x as f64));
            }
            for (i, (w, truth)) in lobes.into_iter().enumerate() {
                let (mean, se) = mean_and_stderr(&w);
                fam.mean_is(
                    &format!("{what}: lobe {i} weight"),
                    mean,
                    (se * se + LIMIT_BIAS * LIMIT_BIAS).sqrt(),
                    (w.len() - 1) as f64,
                    truth,
                );
            }
        }
    }
    fam.finish();
}

#[test]
fn complex_fresnel_is_the_dielectric_for_k_zero_and_exact_at_normal_incidence() {
    for eta in [1.33f32, 1.5, 2.4] {
        for i in 0..=20 {
            let c = i as f32 / 20.0;
            let (a, b) = (fresnel_complex(c, eta, 0.0), fresnel_dielectric(c, eta));
            assert_close(&format!("eta {eta}, cos {c}"), a as f64, b as f64, 1e-5);
        }
    }
    for (eta, k) in [(0.2f32, 3.9f32), (1.1, 2.1), (2.9, 3.0)] {
        let exact = ((eta - 1.0).powi(2) + k * k) / ((eta + 1.0).powi(2) + k * k);
        assert_close(
            "normal incidence",
            fresnel_complex(1.0, eta, k) as f64,
            exact as f64,
            1e-6,
        );
        assert_close("grazing", fresnel_complex(0.0, eta, k) as f64, 1.0, 1e-6);
        let mut last = 1.0;
        // a conductor's reflectance has its minimum near grazing and stays within [0, 1]
        for i in 0..=100 {
            let f = fresnel_complex(i as f32 / 100.0, eta, k);
            assert!((0.0..=1.0).contains(&f), "{f}");
            last = f.min(last);
        }
        assert!(last > 0.0);
    }
    // Schlick at normal incidence is its colour, at grazing 1
    let s = ConductorFresnel::Schlick(Vec3::new(0.9, 0.6, 0.3));
    assert_eq!(s.eval(1.0), Vec3::new(0.9, 0.6, 0.3));
    assert_eq!(s.eval(0.0), Vec3::ONE);
}

#[test]
fn glossy_values_stay_finite_at_grazing_and_degenerate_directions() {
    // no NaN or infinity may reach an image: grazing wo, wi opposite to wo, wi = wo, the
    // normal itself, tiny and full roughness
    let n = Vec3::Z;
    let dirs = [
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 1e-7).normalize(),
        Vec3::new(-1.0, 0.0, 1e-7).normalize(),
        Vec3::Z,
        -Vec3::Z,
        Vec3::new(0.6, 0.0, -0.8),
        Vec3::new(-0.6, 0.0, 0.8),
    ];
    for (dist, alpha) in DISTRIBUTIONS
        .into_iter()
        .flat_map(|d| [1e-3f32, 0.5, 1.0].map(|a| (d, a)))
    {
        for b in [conductor(dist, alpha), dielectric(dist, alpha)] {
            for &wo in &dirs {
                for &wi in &dirs {
                    for mode in [TransportMode::Radiance, TransportMode::Importance] {
                        let f = b.eval(wo, wi, n, mode);
                        assert!(
                            f.is_finite() && f.min_element() >= 0.0,
                            "{b:?} {wo} {wi}: {f}"
                        );
                        let p = b.pdf(wo, wi, n);
                        assert!(p.is_finite() && p >= 0.0, "{b:?} {wo} {wi}: {p}");
                    }
                }
                let mut s = sampler(8, 0);
                for _ in 0..1000 {
                    if let Some(bs) =
                        b.sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Radiance)
                    {
                        let w = bs.weight(n);
                        assert!(w.is_finite() && bs.pdf > 0.0, "{b:?} {wo}: {bs:?}");
                    }
                }
            }
        }
    }
}

// ---- anisotropic roughness (alpha_u along the tangent, alpha_v across it) ----

/// The (alpha_u, alpha_v) pairs of the anisotropic tests: elongated either way.
const ANISO: [(f32, f32); 2] = [(0.15, 0.5), (0.6, 0.2)];

/// A tangent neither unit nor perpendicular to [`normal`], so that the models' Gram-Schmidt
/// is exercised.
fn tangent() -> Vec3 {
    Vec3::new(1.0, 0.5, 0.2)
}

fn anisotropy(alpha_v: f32) -> Option<Anisotropy> {
    Some(Anisotropy {
        alpha_v,
        tangent: tangent(),
    })
}

fn aniso_conductor(distribution: Distribution, (alpha_u, alpha_v): (f32, f32)) -> Bsdf {
    Bsdf::RoughConductor(RoughConductor {
        distribution,
        alpha: alpha_u,
        fresnel: ConductorFresnel::Complex {
            eta: Vec3::new(0.2, 0.9, 1.1),
            k: Vec3::new(3.9, 2.4, 2.1),
        },
        specular: Vec3::ONE,
        one_sided: false,
        anisotropy: anisotropy(alpha_v),
    })
}

fn aniso_dielectric(distribution: Distribution, (alpha_u, alpha_v): (f32, f32)) -> Bsdf {
    Bsdf::RoughDielectric(RoughDielectric {
        ior: 1.5,
        distribution,
        alpha: alpha_u,
        specular: pathspace::bsdf::Specular::ONE,
        anisotropy: anisotropy(alpha_v),
    })
}

/// The anisotropic D of Heitz 2014, eqs. 81 (Beckmann) and 82 (GGX), in spherical
/// coordinates of the facet normal, written independently of the crate's slope form.
fn aniso_d(dist: Distribution, (au, av): (f64, f64), theta: f64, phi: f64) -> f64 {
    let t2 = theta.tan().powi(2);
    let e = t2 * (phi.cos().powi(2) / (au * au) + phi.sin().powi(2) / (av * av));
    let c4 = theta.cos().powi(4);
    match dist {
        Distribution::Ggx => 1.0 / (PI * au * av * c4 * (1.0 + e).powi(2)),
        Distribution::Beckmann => (-e).exp() / (PI * au * av * c4),
    }
}

/// The exact Smith Lambda at projected roughness alpha(phi)^2 = cos^2 phi a_u^2 + sin^2 phi
/// a_v^2 (Heitz 2014, eqs. 72, 80 and the Beckmann form of eq. 26 of Walter et al. 2007).
fn aniso_lambda(dist: Distribution, (au, av): (f64, f64), cos_v: f64, phi: f64) -> f64 {
    let alpha = (phi.cos().powi(2) * au * au + phi.sin().powi(2) * av * av).sqrt();
    let tan = (1.0 - cos_v * cos_v).sqrt() / cos_v;
    match dist {
        Distribution::Ggx => (-1.0 + (1.0 + alpha * alpha * tan * tan).sqrt()) / 2.0,
        Distribution::Beckmann => beckmann_lambda(alpha, cos_v),
    }
}

/// The integral of g(m) D(m) over the facet normals for the anisotropic D of [`aniso_d`], in
/// y = x / (1 + x), x = tan(theta_m) / min(a_u, a_v), as [`facet_integral`].
fn aniso_integral(
    dist: Distribution,
    alphas: (f64, f64),
    g: impl Fn(Vec3) -> f64,
    n_y: usize,
    n_phi: usize,
) -> f64 {
    let a = alphas.0.min(alphas.1);
    simpson(
        |y| {
            if y >= 1.0 {
                return 0.0;
            }
            let x = y / (1.0 - y);
            let theta = (a * x).atan();
            let jac = a / (1.0 + a * a * x * x) / ((1.0 - y) * (1.0 - y));
            simpson(
                |phi| {
                    let m = Vec3::new(
                        (theta.sin() * phi.cos()) as f32,
                        (theta.sin() * phi.sin()) as f32,
                        theta.cos() as f32,
                    );
                    g(m) * aniso_d(dist, alphas, theta, phi) * theta.sin() * jac
                },
                0.0,
                TAU,
                n_phi,
            )
        },
        0.0,
        1.0,
        n_y,
    )
}

#[test]
fn anisotropic_distributions_are_normalized_and_lambda_is_their_projected_area() {
    // D against Heitz 2014's closed forms (which axis is alpha_u), the projected area of D is
    // 1, and the visible projected area from v is v.z (1 + Lambda(v)) with the projected
    // roughness (Heitz 2014, eq. 80), so that GGX's visible-normal density integrates to 1;
    // Beckmann's G1 is eq. (27) of Walter et al. 2007 within its stated 0.35%
    for dist in DISTRIBUTIONS {
        for (au, av) in ANISO {
            let g = Microfacet::anisotropic(dist, au, av);
            let al = (au as f64, av as f64);
            let what = format!("{dist:?} ({au}, {av})");
            for (theta, phi) in [(0.3f64, 0.0f64), (0.3, PI / 2.0), (0.6, 1.0), (1.1, 4.0)] {
                let m = Vec3::new(
                    (theta.sin() * phi.cos()) as f32,
                    (theta.sin() * phi.sin()) as f32,
                    theta.cos() as f32,
                );
                let want = aniso_d(dist, al, theta, phi);
                let got = g.d(m) as f64;
                assert_close(
                    &format!("{what}: D at ({theta}, {phi})"),
                    got,
                    want,
                    1e-5 * want,
                );
            }
            let area = aniso_integral(dist, al, |m| m.z as f64, 2000, 512);
            assert_close(&format!("{what}: int D cos"), area, 1.0, 1e-5);
            for (cos_v, phi) in [(0.9f64, 0.4f64), (0.5, 1.3), (0.2, 2.5)] {
                let v = direction(&Frame::from_normal(Vec3::Z), cos_v, phi);
                let lambda = aniso_lambda(dist, al, cos_v, phi);
                let w = format!("{what}, cos_v {cos_v}, phi {phi}");
                let projected = aniso_integral(dist, al, |m| (v.dot(m) as f64).max(0.0), 2000, 512);
                assert_close(
                    &format!("{w}: projected area"),
                    projected,
                    cos_v * (1.0 + lambda),
                    2e-4,
                );
                let exact = 1.0 / (1.0 + lambda);
                let tol = match dist {
                    Distribution::Ggx => 1e-5,
                    Distribution::Beckmann => 0.0035,
                };
                assert_close(
                    &format!("{w}: G1"),
                    g.g1(v, Vec3::Z) as f64,
                    exact,
                    tol * exact,
                );
                if dist == Distribution::Ggx {
                    let mass =
                        aniso_integral(dist, al, |m| g.pdf(v, m) as f64 / g.d(m) as f64, 2000, 512);
                    // Simpson across the kink of max(0, v.m): a few 1e-4 of quadrature error
                    assert_close(&format!("{w}: visible-normal density"), mass, 1.0, 5e-4);
                }
            }
        }
    }
}

#[test]
fn anisotropic_facet_samplers_draw_their_density() {
    // GGX's stretched visible normals against G1 max(0, wo.m) D / wo.z, Beckmann's scaled
    // Gaussian slopes against D cos, by chi-square over the facet normals
    const N: u64 = 200_000;
    let mut fam = Family::new("microfacet: anisotropic facet samplers vs density");
    let frame = Frame::from_normal(Vec3::Z);
    for (k, dist) in DISTRIBUTIONS.into_iter().enumerate() {
        for (i, (au, av)) in ANISO.into_iter().enumerate() {
            for (j, (cos_o, phi)) in [(0.9f64, 0.3f64), (0.3, 2.0)].into_iter().enumerate() {
                let g = Microfacet::anisotropic(dist, au, av);
                let wo = direction(&frame, cos_o, phi);
                let mut grid = SphereGrid::new(frame, 40, 32);
                grid.quad_cos = 1024;
                let mut s = sampler(31 + k as u64, (2 * i + j) as u64);
                let density = |m: Vec3| match dist {
                    Distribution::Ggx => g.pdf(wo, m) as f64,
                    Distribution::Beckmann => (g.d(m) * m.z.max(0.0)) as f64,
                };
                chi_square_sphere(
                    &mut fam,
                    &format!("{dist:?} ({au}, {av}), wo ({cos_o}, {phi})"),
                    &grid,
                    || Some(g.sample(wo, s.next_2d())),
                    density,
                    N,
                );
            }
        }
    }
    fam.finish();
}

#[test]
fn anisotropic_rough_models_sample_their_density() {
    // the models' directions against their densities, in the frame of a tangent that is
    // neither unit nor perpendicular to the normal (the models make it so)
    let mut fam = Family::new("microfacet: anisotropic models' sampling vs pdf");
    let n = normal();
    for (k, dist) in DISTRIBUTIONS.into_iter().enumerate() {
        for (i, alphas) in ANISO.into_iter().enumerate() {
            for (j, cos_o) in [0.8f64, -0.4].into_iter().enumerate() {
                let wo = direction(&Frame::from_normal(n), cos_o, 1.0);
                let seed = (40 + 10 * k as u64, (2 * i + j) as u64);
                let what = format!("{dist:?} {alphas:?}, cos_o {cos_o}");
                let metal = aniso_conductor(dist, alphas);
                check_sampler(&mut fam, &format!("conductor {what}"), &metal, wo, seed);
                let glass = aniso_dielectric(dist, alphas);
                let seed = (seed.0 + 5, seed.1);
                check_sampler(&mut fam, &format!("dielectric {what}"), &glass, wo, seed);
            }
        }
    }
    fam.finish();
}

#[test]
fn anisotropic_rough_models_are_reciprocal() {
    // reflection: f(a, b) = f(b, a); refraction: f(a, b) / eta_a^2 = f(b, a) / eta_b^2, and
    // the importance BSDF is the radiance BSDF with its arguments swapped
    let n = normal();
    for dist in DISTRIBUTIONS {
        for alphas in ANISO {
            let (metal, glass) = (
                aniso_conductor(dist, alphas),
                aniso_dielectric(dist, alphas),
            );
            let mut nonzero = 0;
            for (a, b) in pairs(6, n) {
                let what = format!("{dist:?} {alphas:?} ({a}, {b})");
                let (fab, fba) = (
                    metal.eval(a, b, n, TransportMode::Radiance).x as f64,
                    metal.eval(b, a, n, TransportMode::Radiance).x as f64,
                );
                assert_close(
                    &format!("{what}: conductor"),
                    fab,
                    fba,
                    REL * fab.max(fba) + ABS,
                );
                nonzero += (fab > 0.0) as usize;
                let r_ab = glass.eval(a, b, n, TransportMode::Radiance).x as f64;
                let r_ba = glass.eval(b, a, n, TransportMode::Radiance).x as f64;
                let i_ab = glass.eval(a, b, n, TransportMode::Importance).x as f64;
                let (ea, eb) = (eta_of(a, n, 1.5), eta_of(b, n, 1.5));
                let (x, y) = (r_ab / (ea * ea), r_ba / (eb * eb));
                assert_close(&format!("{what}: generalized"), x, y, REL * x.max(y) + ABS);
                assert_close(
                    &format!("{what}: adjoint"),
                    i_ab,
                    r_ba,
                    REL * i_ab.max(r_ba) + ABS,
                );
            }
            assert!(
                nonzero > 500,
                "{dist:?} {alphas:?}: only {nonzero} pairs reflect"
            );
        }
    }
}

#[test]
fn white_furnace_anisotropic_conductor() {
    // with F = 1 the albedo by quadrature of f |cos| (from eval) equals the sampler's mean
    // weight (from sample), at most 1
    const N: usize = 100_000;
    let mut fam = Family::new("microfacet: white furnace of the anisotropic conductor");
    let n = normal();
    let frame = Frame::from_normal(n);
    for (k, dist) in DISTRIBUTIONS.into_iter().enumerate() {
        for (i, (au, av)) in ANISO.into_iter().enumerate() {
            let bsdf = Bsdf::RoughConductor(RoughConductor {
                distribution: dist,
                alpha: au,
                fresnel: ConductorFresnel::Schlick(Vec3::ONE),
                specular: Vec3::ONE,
                one_sided: false,
                anisotropy: anisotropy(av),
            });
            for (j, cos_o) in [0.9f64, 0.3].into_iter().enumerate() {
                let wo = direction(&frame, cos_o, 0.5);
                let mut s = sampler(50 + k as u64, (2 * i + j) as u64);
                let (quad, mean, se) = albedo_two_ways(&bsdf, wo, n, &mut s, N);
                let what = format!("{dist:?} ({au}, {av}), cos_o {cos_o}");
                fam.mean_is(
                    &format!("{what}: E by sampling"),
                    mean,
                    (se * se + QUAD_ERR * QUAD_ERR).sqrt(),
                    (N - 1) as f64,
                    quad,
                );
                assert!(quad <= 1.0 + 1e-4, "{what}: albedo {quad} above 1");
            }
        }
    }
    fam.finish();
}
