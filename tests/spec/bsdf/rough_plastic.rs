//! Executable specification of the rough plastic (`src/bsdf/rough_plastic.rs`; book: "Surface
//! scattering", section "Rough plastic"): its value against Mitsuba 3's own `roughplastic` at
//! fixed angles, its two tables against independent estimates (a fine Simpson quadrature, and
//! the rough dielectric's sampler), its sampler against its density by chi-square, reciprocity,
//! an albedo of at most one, and the sides.

use crate::common;

use common::stats::Family;
use common::*;
use glam::Vec3;
use pathspace::bsdf::microfacet::{reflect_about, refract_about};
use pathspace::bsdf::rough_plastic::{interface_albedo, table_cosine, Albedo, TABLE_SIZE};
use pathspace::bsdf::{
    fresnel_dielectric, Beckmann, Bsdf, BsdfModel, Distribution, Microfacet, RoughDielectric,
    RoughPlastic, TransportMode,
};
use pathspace::math::{warp, Frame};
use std::f64::consts::{PI, TAU};

/// Mitsuba's default index ratio: polypropylene (1.49) over air (1.000277).
const ETA_DEFAULT: f32 = (1.49f64 / 1.000277) as f32;

fn plastic(d: Distribution, alpha: f32, eta: f32, diffuse: Vec3, specular: f32) -> RoughPlastic {
    RoughPlastic::new(
        Microfacet::new(d, alpha),
        eta,
        diffuse,
        Vec3::splat(specular),
        false,
        true,
    )
}

/// The three materials of the Mitsuba fixtures (see `matches_mitsuba_3`).
fn fixture_materials() -> [RoughPlastic; 3] {
    let a = plastic(
        Distribution::Beckmann,
        0.1,
        ETA_DEFAULT,
        Vec3::splat(0.5),
        1.0,
    );
    let mut b = plastic(Distribution::Ggx, 0.3, 1.6, Vec3::new(0.8, 0.4, 0.1), 0.7);
    b = RoughPlastic::new(b.microfacet, b.eta, b.diffuse, b.specular, true, true);
    let c = plastic(Distribution::Beckmann, 0.5, 1.33, Vec3::splat(0.2), 1.0);
    [a, b, c]
}

fn dir(theta: f64, phi: f64) -> Vec3 {
    Vec3::new(
        (theta.sin() * phi.cos()) as f32,
        (theta.sin() * phi.sin()) as f32,
        theta.cos() as f32,
    )
}

/// Mitsuba 3.9.1 (`pip install mitsuba==3.9.1`, variant `scalar_rgb`), material by material:
/// (A) `{'type': 'roughplastic'}`; (B) `distribution` ggx, `alpha` 0.3, `int_ior` 1.6,
/// `diffuse_reflectance` rgb (0.8, 0.4, 0.1), `specular_reflectance` rgb 0.7, `nonlinear` true;
/// (C) `alpha` 0.5, `int_ior` 1.33, `ext_ior` 1.0, `diffuse_reflectance` rgb 0.2. For each
/// (theta_o, theta_i, phi_i): `si = mi.SurfaceInteraction3f(); si.n = [0, 0, 1]; si.sh_frame =
/// mi.Frame3f(si.n); si.wi = d(theta_o, 0)`, then `bsdf.eval(mi.BSDFContext(), si, d(theta_i,
/// phi_i)) / cos(theta_i)` (Mitsuba's eval includes the cosine), with d(theta, phi) = (sin
/// theta cos phi, sin theta sin phi, cos theta); channel 0, and channel 2 for (B).
const MITSUBA: [(usize, f64, f64, f64, f64, f64); 18] = [
    (0, 0.2, 0.3, PI, 4.1339851e-01, 4.1339851e-01),
    (0, 0.7, 0.7, PI, 7.5786009e-01, 7.5786009e-01),
    (0, 1.3, 0.5, 2.0, 1.2366307e-01, 1.2366307e-01),
    (0, 0.0, 1.0, 0.0, 1.4956222e-01, 1.4956222e-01),
    (0, 1.45, 1.45, PI, 2.7580739e+02, 2.7580739e+02),
    (0, 0.9, 0.2, 1.0, 1.5230218e-01, 1.5230218e-01),
    (1, 0.2, 0.3, PI, 1.7344269e-01, 4.4886060e-02),
    (1, 0.7, 0.7, PI, 1.9628259e-01, 7.2196376e-02),
    (1, 1.3, 0.5, 2.0, 1.2343544e-01, 1.5546958e-02),
    (1, 0.0, 1.0, 0.0, 1.3738704e-01, 1.6208846e-02),
    (1, 1.45, 1.45, PI, 6.7207693e+00, 6.6450089e+00),
    (1, 0.9, 0.2, 1.0, 1.3888525e-01, 1.5455291e-02),
    (2, 0.2, 0.3, PI, 5.6914763e-02, 5.6914763e-02),
    (2, 0.7, 0.7, PI, 6.1918985e-02, 6.1918985e-02),
    (2, 1.3, 0.5, 2.0, 5.2453253e-02, 5.2453253e-02),
    (2, 0.0, 1.0, 0.0, 5.4316021e-02, 5.4316021e-02),
    (2, 1.45, 1.45, PI, 3.5351578e+00, 3.5351578e+00),
    (2, 0.9, 0.2, 1.0, 5.3753599e-02, 5.3753599e-02),
];

/// Mitsuba's internal reflectance R_i of materials A, B, C, solved from its diffuse component
/// alone (`ctx.component = 1`) at normal incidence and exitance with `diffuse_reflectance`
/// (0.8, 0.4, 0.1) and `nonlinear` true: the ratio of channels 0 and 2 is 8 (1 - 0.1 R_i) /
/// (1 - 0.8 R_i).
const MITSUBA_RI: [f64; 3] = [0.5746621, 0.4682598, 0.3132670];

/// How far Mitsuba's tables are from the integrals: its T is a 32 x 32 Gauss-Legendre rule over
/// its visible-normal sampler, whose error is up to 7e-5 for Beckmann (values of A and C agree
/// to 5e-5 and 1.2e-4 relative), and 4e-4 for GGX, whose concentric-disk sampler has kinks
/// (pathspace's T agrees with the rough dielectric's own sampler,
/// `tables_match_the_rough_dielectric`, Mitsuba's is 3.7 standard errors from it); the
/// product T_i T_o and the nonlinear term of B make 8e-4.
const REL_BECKMANN: f64 = 2e-4;
const REL_GGX: f64 = 1.5e-3;

#[test]
fn matches_mitsuba_3() {
    let mats = fixture_materials();
    for (k, p) in mats.iter().enumerate() {
        let (ri, rel) = (
            p.tables().internal_reflectance as f64,
            [2e-5, 1e-4, 2e-5][k],
        );
        assert_close(&format!("material {k}: R_i"), ri, MITSUBA_RI[k], rel);
    }
    for (k, t_o, t_i, phi, c0, c2) in MITSUBA {
        let f = mats[k].eval(
            dir(t_o, 0.0),
            dir(t_i, phi),
            Vec3::Z,
            TransportMode::Radiance,
        );
        let rel = if k == 1 { REL_GGX } else { REL_BECKMANN };
        let what = format!("material {k}, theta_o {t_o}, theta_i {t_i}, phi {phi}");
        assert_close(&format!("{what}: ch 0"), f.x as f64, c0, rel * c0);
        assert_close(&format!("{what}: ch 2"), f.z as f64, c2, rel * c2);
    }
}

/// The interface albedo by Simpson's rule over the facet normals (theta_m through x =
/// tan(theta_m) / alpha, y = x / (1 + x); phi_m over the full circle), with the visible-normal
/// density written out here: independent of the crate's adaptive quadrature and its splits.
fn simpson_albedo(g: Microfacet, mu: f64, eta: f64, share: Albedo, n: usize) -> f64 {
    let w = dir(mu.acos(), 0.0);
    let lambda = match g.distribution {
        Distribution::Ggx => {
            let t2 = (1.0 - mu * mu) / (mu * mu) * (g.alpha as f64).powi(2);
            ((1.0 + t2).sqrt() - 1.0) / 2.0
        }
        Distribution::Beckmann => Beckmann { alpha: g.alpha }.lambda(w),
    };
    let a = g.alpha as f64;
    simpson(
        |y| {
            if y >= 1.0 {
                return 0.0;
            }
            let x = y / (1.0 - y);
            let theta = (a * x).atan();
            let jac = a / (1.0 + a * a * x * x) / ((1.0 - y) * (1.0 - y)) * theta.sin();
            simpson(
                |phi| {
                    let m = dir(theta, phi);
                    let c = w.dot(m);
                    if c <= 0.0 {
                        return 0.0;
                    }
                    let f = fresnel_dielectric(c, eta as f32) as f64;
                    let kept = match share {
                        Albedo::Reflection => {
                            let r = reflect_about(w, m);
                            if r.z > 0.0 {
                                f * g.g1(r, m) as f64
                            } else {
                                0.0
                            }
                        }
                        Albedo::Transmission => match refract_about(w, m, (1.0 / eta) as f32) {
                            Some(t) if t.z < 0.0 => (1.0 - f) * g.g1(t, m) as f64,
                            _ => 0.0,
                        },
                    };
                    c as f64 * g.d(m) as f64 * kept * jac
                },
                0.0,
                TAU,
                n,
            )
        },
        0.0,
        1.0,
        n,
    ) / (mu * (1.0 + lambda))
}

#[test]
fn interface_albedos_match_an_independent_quadrature() {
    // the adaptive Gauss-Kronrod of the tables against Simpson's rule with n and 2n intervals,
    // from outside and from inside (total internal reflection beyond the critical angle).
    // Simpson converges slowly here (the integrand has kinks and jumps no grid line follows:
    // the horizon of visible facets, the square root of 1 - F at the critical angle), but at
    // least as O(h), so its error at 2n is at most its change from n to 2n. (Measured on GGX
    // alpha 0.3, eta 1.6, mu 0.3: 2.7e-5, 1.4e-5, 6.8e-6 off at 2000, 4000, 8000 intervals,
    // halving, and its Richardson limit is the adaptive value to 1e-8.)
    let cases = [
        (Distribution::Beckmann, 0.1f32, ETA_DEFAULT as f64, 0.3),
        (Distribution::Ggx, 0.3, 1.6, 1.0),
        (Distribution::Beckmann, 0.8, 1.33, table_cosine(1)),
    ];
    for (d, alpha, eta, mu) in cases {
        let g = Microfacet::new(d, alpha);
        for (share, e) in [(Albedo::Transmission, eta), (Albedo::Reflection, 1.0 / eta)] {
            let what = format!("{d:?} alpha {alpha}, eta {e}, mu {mu}, {share:?}");
            let table = interface_albedo(g, mu, e, share);
            let (coarse, fine) = (
                simpson_albedo(g, mu, e, share, 1000),
                simpson_albedo(g, mu, e, share, 2000),
            );
            assert_close(&what, table, fine, (fine - coarse).abs() + 1e-6);
        }
    }
}

#[test]
fn tables_match_the_rough_dielectric() {
    // T(mu) is the rough dielectric's transmission albedo from outside, R(mu) its reflection
    // albedo from inside: in both cases the mean weight of its sampler's directions below the
    // surface (importance: no eta^2), times G1_exact(w) / G1(w) for Beckmann, whose tables
    // integrate over the exact visible normals (Mitsuba's sampler) while the BSDF has Walter's
    // rational G1
    const N: usize = 200_000;
    let mut fam = Family::new("rough plastic: tables vs the rough dielectric's sampler");
    let cases = [
        (Distribution::Beckmann, 0.1f32, ETA_DEFAULT),
        (Distribution::Ggx, 0.3, 1.6),
    ];
    for (i, (d, alpha, eta)) in cases.into_iter().enumerate() {
        let glass = Bsdf::RoughDielectric(RoughDielectric {
            ior: eta,
            distribution: d,
            alpha,
            specular: pathspace::bsdf::Specular::ONE,
            anisotropy: None,
        });
        let g = Microfacet::new(d, alpha);
        let p = plastic(d, alpha, eta, Vec3::ONE, 1.0);
        for (j, node) in [63usize, 40, 8].into_iter().enumerate() {
            let mu = table_cosine(node);
            let above = dir(mu.acos(), 0.5);
            let correction = match d {
                Distribution::Ggx => 1.0,
                Distribution::Beckmann => {
                    let exact = 1.0 / (1.0 + Beckmann { alpha }.lambda(above));
                    exact / g.g1(above, Vec3::Z) as f64
                }
            };
            for (k, share) in [Albedo::Transmission, Albedo::Reflection]
                .into_iter()
                .enumerate()
            {
                let w = match share {
                    Albedo::Transmission => above,
                    Albedo::Reflection => above * Vec3::new(1.0, 1.0, -1.0),
                };
                let mut s = sampler(40 + i as u64, (2 * j + k) as u64);
                let mode = TransportMode::Importance;
                let weights: Vec<f64> = (0..N)
                    .map(
                        |_| match glass.sample(w, Vec3::Z, s.next_2d(), s.next_f32(), mode) {
                            Some(bs) if bs.wi.z < 0.0 => bs.weight(Vec3::Z).x as f64 * correction,
                            _ => 0.0,
                        },
                    )
                    .collect();
                let (mean, se) = mean_and_stderr(&weights);
                let truth = match share {
                    Albedo::Transmission => p.tables().transmittance[node] as f64,
                    Albedo::Reflection => interface_albedo(g, mu, 1.0 / eta as f64, share),
                };
                let what = format!("{d:?} mu {mu:.3} {share:?}");
                fam.mean_is(&what, mean, se, (N - 1) as f64, truth);
            }
        }
    }
    fam.finish();
}

/// A tilted normal, so that no axis of the frame is special.
fn normal() -> Vec3 {
    Vec3::new(0.3, -0.4, 0.866).normalize()
}

/// Materials for the sampler, reciprocity and energy tests: Mitsuba's default, a rough GGX
/// one, a white nonlinear one, a black-based one (specular only in effect) and a dim coating.
/// (The albedo's quadrature resolves lobes down to alpha 0.1 at cos_o 0.08; alpha 0.05 needs
/// four times the grid.)
fn materials() -> Vec<(String, Bsdf)> {
    let white = RoughPlastic::new(
        Microfacet::new(Distribution::Beckmann, 0.2),
        1.8,
        Vec3::ONE,
        Vec3::ONE,
        true,
        false,
    );
    [
        plastic(
            Distribution::Beckmann,
            0.1,
            ETA_DEFAULT,
            Vec3::splat(0.5),
            1.0,
        ),
        plastic(Distribution::Ggx, 0.6, 1.33, Vec3::new(0.9, 0.5, 0.1), 1.0),
        white,
        plastic(Distribution::Ggx, 0.15, 1.5, Vec3::ZERO, 1.0),
        plastic(Distribution::Beckmann, 1.0, 2.0, Vec3::splat(1.0), 0.3),
    ]
    .into_iter()
    .map(|p| {
        let name = format!(
            "{:?} alpha {} eta {} diffuse {}",
            p.microfacet.distribution, p.microfacet.alpha, p.eta, p.diffuse
        );
        // two-sided, so that the back side is exercised too
        let p = RoughPlastic::new(
            p.microfacet,
            p.eta,
            p.diffuse,
            p.specular,
            p.nonlinear,
            false,
        );
        (name, Bsdf::RoughPlastic(p))
    })
    .collect()
}

#[test]
fn sampler_matches_its_density() {
    const N: u64 = 200_000;
    let mut fam = Family::new("rough plastic: sampling vs pdf");
    let n = normal();
    for (i, (name, bsdf)) in materials().into_iter().enumerate() {
        for (j, cos_o) in [0.9f64, 0.35, -0.6].into_iter().enumerate() {
            let wo = direction(&Frame::from_normal(n), cos_o, 1.0);
            let what = format!("{name}, cos_o {cos_o}");
            let mut grid = SphereGrid::new(Frame::from_normal(n), 40, 16);
            grid.quad_phi = 64;
            let mut s = sampler(50 + i as u64, j as u64);
            let mode = TransportMode::Radiance;
            let mut hits = 0u64;
            chi_square_sphere(
                &mut fam,
                &what,
                &grid,
                || {
                    let bs = bsdf.sample(wo, n, s.next_2d(), s.next_f32(), mode)?;
                    let (f, p) = (bsdf.eval(wo, bs.wi, n, mode), bsdf.pdf(wo, bs.wi, n));
                    assert!(bs.value == f && bs.pdf == p && p > 0.0, "{what}: {bs:?}");
                    hits += 1;
                    Some(bs.wi)
                },
                |wi| bsdf.pdf(wo, wi, n) as f64,
                N,
            );
            // the density's mass: one minus the specular draws reflected under the surface
            let frame = Frame::from_normal(n);
            let side = cos_o.signum();
            let mass = simpson(
                |mu| {
                    simpson(
                        |phi| bsdf.pdf(wo, direction(&frame, side * mu, phi), n) as f64,
                        0.0,
                        TAU,
                        256,
                    )
                },
                0.0,
                1.0,
                1024,
            );
            assert!(
                mass <= 1.0 + 2e-3,
                "{what}: the density integrates to {mass}"
            );
            fam.binomial(&format!("{what}: mass"), hits, N, mass.min(1.0 - 1e-9));
        }
    }
    fam.finish();
}

#[test]
fn is_reciprocal_and_reflects_on_wos_side_only() {
    let n = normal();
    let mut s = sampler(60, 0);
    for (name, bsdf) in materials() {
        let mut nonzero = 0;
        for _ in 0..2000 {
            let (a, b) = (
                warp::uniform_sphere(s.next_2d()),
                warp::uniform_sphere(s.next_2d()),
            );
            if a.dot(n).abs() < 0.05 || b.dot(n).abs() < 0.05 {
                continue;
            }
            let (fab, fba) = (
                bsdf.eval(a, b, n, TransportMode::Radiance),
                bsdf.eval(b, a, n, TransportMode::Importance),
            );
            for c in 0..3 {
                let (x, y) = (fab[c] as f64, fba[c] as f64);
                assert_close(
                    &format!("{name}: f({a}, {b})"),
                    x,
                    y,
                    2e-4 * x.max(y) + 1e-7,
                );
            }
            if a.dot(n) * b.dot(n) < 0.0 {
                assert_eq!(fab, Vec3::ZERO, "{name}: no transmission");
            } else {
                nonzero += (fab.max_element() > 0.0) as usize;
            }
        }
        assert!(nonzero > 500, "{name}: {nonzero}");
    }
}

#[test]
fn albedo_is_at_most_one_and_the_sampler_weights_estimate_it() {
    // the directional albedo by quadrature of f cos over the hemisphere, at most 1, and the
    // mean sample weight against it (its own variance)
    const N: usize = 100_000;
    let mut fam = Family::new("rough plastic: albedo by sampling vs quadrature");
    let n = normal();
    let frame = Frame::from_normal(n);
    let mut table = Vec::new();
    for (i, (name, bsdf)) in materials().into_iter().enumerate() {
        for (j, cos_o) in [1.0f64, 0.7, 0.3, 0.08].into_iter().enumerate() {
            let wo = direction(&frame, cos_o, 0.3);
            let mode = TransportMode::Radiance;
            let f_cos = |mu: f64, phi: f64| {
                let wi = direction(&frame, mu, phi);
                bsdf.eval(wo, wi, n, mode).max_element() as f64 * mu
            };
            let quad = simpson(
                |mu| simpson(|phi| f_cos(mu, phi), 0.0, TAU, 1024),
                0.0,
                1.0,
                2048,
            );
            let what = format!("{name}, cos_o {cos_o}");
            assert!(quad <= 1.0, "{what}: albedo {quad}");
            table.push(format!("{what}: {quad:.4}"));
            let mut s = sampler(70 + i as u64, j as u64);
            let w: Vec<f64> = (0..N)
                .map(|_| {
                    bsdf.sample(wo, n, s.next_2d(), s.next_f32(), mode)
                        .map_or(0.0, |bs| bs.weight(n).max_element() as f64)
                })
                .collect();
            let (mean, se) = mean_and_stderr(&w);
            fam.mean_is(&what, mean, se, (N - 1) as f64, quad);
        }
    }
    eprintln!("{}", table.join("\n"));
    fam.finish();
}

#[test]
fn one_sided_is_black_behind() {
    let one = Bsdf::RoughPlastic(plastic(
        Distribution::Beckmann,
        0.1,
        ETA_DEFAULT,
        Vec3::splat(0.5),
        1.0,
    ));
    let (front, back) = (dir(0.4, 0.0), dir(0.4, 2.0) * Vec3::new(1.0, 1.0, -1.0));
    let mode = TransportMode::Radiance;
    assert_eq!(one.eval(back, -front, Vec3::Z, mode), Vec3::ZERO);
    assert_eq!(one.pdf(back, -front, Vec3::Z), 0.0);
    assert!(one
        .sample(back, Vec3::Z, glam::Vec2::splat(0.3), 0.5, mode)
        .is_none());
    assert!(one.eval(front, dir(0.3, 1.0), Vec3::Z, mode).x > 0.0);
    // the table: 64 cosines, T within (0, 1)
    assert_eq!(TABLE_SIZE, 64);
    if let Bsdf::RoughPlastic(p) = &one {
        assert!(p
            .tables()
            .transmittance
            .iter()
            .all(|t| *t > 0.0 && *t < 1.0));
    }
}
