//! Executable specification of `src/bsdf/mod.rs` (book: "Surface scattering").
//!
//! f_s of the local scattering equation (Pauly, Kollig, Keller 2000, eq. 2): Lambert's
//! reciprocity, energy and two-sidedness; the mirror's reflection law; the dielectric's Fresnel
//! reflectance, total internal reflection, Snell's law, the probability of choosing each lobe,
//! and the eta^2 asymmetry of refraction between radiance and importance transport
//! (generalized reciprocity, Kristensen 2010 eq. 2.9, derived again in the book).

use crate::common;

use common::stats::Family;
use common::*;
use glam::{Vec2, Vec3};
use pathspace::bsdf::{
    fresnel_dielectric, reflect, Bsdf, BsdfSample, Dielectric, Lambert, Lobe, Mirror, Null,
    ThinDielectric, TransportMode,
};
use pathspace::math::distribution::ONE_MINUS_EPSILON;
use pathspace::math::{warp, Frame};
use pathspace::spectrum::Rgb;
use std::f64::consts::TAU;

/// Relative tolerance of deterministic f32 quantities (a reflection, a refraction, a Fresnel
/// term): a few roundings of order-one terms, 64 ulps leaves room for the square roots and the
/// renormalization in the refraction formula.
const F32_TOL: f64 = 64.0 * f32::EPSILON as f64;

/// Below this |cos| a direction is too close to grazing for a round trip through refraction to
/// stay within `F32_TOL`: a cosine computed as sqrt(1 - sin^2) loses eps / cos^2 relatively,
/// 25 eps at this limit, and the Fresnel term passes that error on.
const GRAZING_LIMIT: f64 = 0.2;

/// An albedo per channel, each below one, distinct so that a channel mix-up shows.
const ALBEDO: Rgb = Vec3::new(0.2, 0.5, 0.9);

/// Indices of refraction: water, glass, diamond, and below one (an interface seen from inside a
/// denser medium is `1 / ior` of the reverse one).
const IORS: [f32; 4] = [1.33, 1.5, 2.4, 0.75];

/// Surface normals for the tests (the shape's geometric normal, any orientation).
fn normals() -> Vec<Vec3> {
    vec![Vec3::Z, -Vec3::Z, Vec3::new(0.3, -0.4, 0.866).normalize()]
}

/// A direction with cosine `cos` to `n` (either sign), at azimuth `phi` around it.
fn at_cosine(n: Vec3, cos: f64, phi: f64) -> Vec3 {
    direction(&Frame::from_normal(n), cos, phi)
}

fn modes() -> [TransportMode; 2] {
    [TransportMode::Radiance, TransportMode::Importance]
}

// ---------------------------------------------------------------------------------------------
// Lambert

#[test]
fn lambert_is_reciprocal_and_reflects_on_both_sides_only() {
    let bsdf = Bsdf::Lambert(Lambert {
        albedo: ALBEDO,
        one_sided: false,
    });
    let mut s = sampler(10, 0);
    for n in normals() {
        for _ in 0..256 {
            let wo = warp::uniform_sphere(s.next_2d());
            let wi = warp::uniform_sphere(s.next_2d());
            for mode in modes() {
                let f = bsdf.eval(wo, wi, n, mode);
                assert_eq!(f, bsdf.eval(wi, wo, n, mode), "not reciprocal");
                if wo.dot(n) * wi.dot(n) > 0.0 {
                    assert_eq!(f, ALBEDO * std::f32::consts::FRAC_1_PI);
                    assert!(bsdf.pdf(wo, wi, n) > 0.0);
                } else {
                    assert_eq!(f, Rgb::ZERO, "Lambert transmits");
                    assert_eq!(bsdf.pdf(wo, wi, n), 0.0, "Lambert samples transmission");
                }
            }
        }
    }
}

#[test]
fn lambert_directional_albedo_equals_albedo() {
    // rho_hd(wo) = int f_s |cos wi| dsigma(wi) over wo's hemisphere = albedo. The integrand is
    // linear in cos theta and constant in phi, so Simpson in cos and the trapezoid rule in phi
    // are exact and only float rounding remains.
    const N_COS: usize = 64;
    const N_PHI: usize = 16;
    let bsdf = Bsdf::Lambert(Lambert {
        albedo: ALBEDO,
        one_sided: false,
    });
    for n in normals() {
        for cos_o in [0.9, 0.3, -0.5, -0.05] {
            let wo = at_cosine(n, cos_o, 1.0);
            let side = if cos_o > 0.0 { 1.0 } else { -1.0 };
            for c in 0..3 {
                let rho_hd = simpson(
                    |cos_i| {
                        (0..N_PHI)
                            .map(|j| {
                                let wi = at_cosine(n, side * cos_i, TAU * j as f64 / N_PHI as f64);
                                bsdf.eval(wo, wi, n, TransportMode::Radiance)[c] as f64 * cos_i
                            })
                            .sum::<f64>()
                            * (TAU / N_PHI as f64)
                    },
                    0.0,
                    1.0,
                    N_COS,
                );
                assert_close("rho_hd", rho_hd, ALBEDO[c] as f64, F32_TOL);
                assert!(rho_hd <= 1.0 + F32_TOL, "Lambert creates energy");
            }
        }
    }
}

#[test]
fn lambert_sample_record_matches_eval_and_pdf_and_its_weight_is_the_albedo() {
    // the cosine-sampled weight f cos / pdf equals the albedo for every sample: a zero-variance
    // estimator of rho_hd, so its mean is checked with the float allowance only
    let bsdf = Bsdf::Lambert(Lambert {
        albedo: ALBEDO,
        one_sided: false,
    });
    let mut s = sampler(11, 0);
    for n in normals() {
        for wo in test_directions(11, 8) {
            if wo.dot(n) == 0.0 {
                continue;
            }
            for mode in modes() {
                let Some(bs) = bsdf.sample(wo, n, s.next_2d(), s.next_f32(), mode) else {
                    continue;
                };
                assert_eq!(bs.lobe, Lobe::Regular);
                assert!(bs.wi.dot(n) * wo.dot(n) > 0.0, "sampled across the surface");
                assert_eq!(bs.value, bsdf.eval(wo, bs.wi, n, mode));
                assert_close("pdf", bs.pdf as f64, bsdf.pdf(wo, bs.wi, n) as f64, F32_TOL);
                // deterministic: cos / pi over cos / pi cancels up to a few roundings
                let w = bs.weight(n);
                for c in 0..3 {
                    assert_close(
                        "weight",
                        w[c] as f64,
                        ALBEDO[c] as f64,
                        ZERO_VARIANCE_ALLOWANCE,
                    );
                }
            }
        }
    }
}

#[test]
fn lambert_sampling_agrees_with_pdf_by_chi_square() {
    // binned over the whole sphere around n: the far hemisphere expects nothing, so a sample
    // leaking through the surface fails the test
    const N_SAMPLES: u64 = 200_000;
    let mut fam = Family::new("bsdf: Lambert sampling vs pdf");
    let bsdf = Bsdf::Lambert(Lambert {
        albedo: ALBEDO,
        one_sided: false,
    });
    for (i, n) in normals().into_iter().enumerate() {
        for (j, cos_o) in [0.7f64, -0.4].into_iter().enumerate() {
            let wo = at_cosine(n, cos_o, 2.0);
            let grid = SphereGrid::new(Frame::from_normal(n), 20, 16);
            let mut s = sampler(12, (2 * i + j) as u64);
            chi_square_sphere(
                &mut fam,
                &format!("Lambert n {n}, cos_o {cos_o}"),
                &grid,
                || {
                    bsdf.sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Radiance)
                        .map(|bs| bs.wi)
                },
                |wi| bsdf.pdf(wo, wi, n) as f64,
                N_SAMPLES,
            );
        }
    }
    fam.finish();
}

// ---------------------------------------------------------------------------------------------
// Mirror

#[test]
fn mirror_reflects_about_the_normal_with_weight_reflectance() {
    let reflectance = Vec3::new(0.9, 0.6, 0.3);
    let bsdf = Bsdf::Mirror(Mirror {
        reflectance,
        one_sided: false,
    });
    let mut s = sampler(20, 0);
    for n in normals() {
        for wo in test_directions(20, 16) {
            let cos_o = wo.dot(n) as f64;
            if cos_o.abs() < 1e-3 {
                continue; // grazing: the reflection is numerically ill-defined
            }
            let bs = bsdf
                .sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Radiance)
                .expect("a mirror always reflects");
            assert_eq!(bs.lobe, Lobe::SingularReflection);
            // equal angles on the same side, in the plane of wo and n, symmetric about n
            assert_close("cos", bs.wi.dot(n) as f64, cos_o, F32_TOL);
            assert_close("coplanar", wo.cross(n).dot(bs.wi) as f64, 0.0, F32_TOL);
            assert_close(
                "symmetric",
                (bs.wi + wo).cross(n).length() as f64,
                0.0,
                F32_TOL,
            );
            assert_close("unit", bs.wi.length() as f64, 1.0, F32_TOL);
            let w = bs.weight(n);
            for c in 0..3 {
                assert_close("weight", w[c] as f64, reflectance[c] as f64, F32_TOL);
            }
            // a Dirac lobe has no value or density at a given direction
            assert_eq!(bsdf.eval(wo, bs.wi, n, TransportMode::Radiance), Rgb::ZERO);
            assert_eq!(bsdf.pdf(wo, bs.wi, n), 0.0);
            assert!(bsdf.only_dirac_lobes() && bsdf.has_dirac_lobe());
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Dielectric

/// Forces the reflection (`uc = 0`) or transmission (`uc` just below 1) lobe.
fn dielectric_lobe(
    ior: f32,
    wo: Vec3,
    n: Vec3,
    transmit: bool,
    mode: TransportMode,
) -> Option<BsdfSample> {
    let uc = if transmit { ONE_MINUS_EPSILON } else { 0.0 };
    Bsdf::Dielectric(Dielectric::new(ior)).sample(wo, n, Vec2::new(0.5, 0.5), uc, mode)
}

/// The indices on wo's side and on the other side of an interface whose inside (behind `n`)
/// has index `ior` and outside 1.
fn etas(ior: f32, wo: Vec3, n: Vec3) -> (f64, f64) {
    if wo.dot(n) > 0.0 {
        (1.0, ior as f64)
    } else {
        (ior as f64, 1.0)
    }
}

/// The Fresnel equations in their angle form (Born and Wolf): with Snell's law
/// sin(theta_t) = sin(theta_i) / eta, R_s = (sin(theta_i - theta_t) / sin(theta_i + theta_t))^2
/// and R_p = (tan(theta_i - theta_t) / tan(theta_i + theta_t))^2, unpolarized F = (R_s + R_p) / 2,
/// in f64, at oblique angles entering and leaving glass and water. Schlick's approximation, or
/// one polarization alone, is off by far more than the tolerance at most of them.
#[test]
fn fresnel_matches_the_fresnel_equations_at_oblique_incidence() {
    for eta in [1.5f64, 1.33, 1.0 / 1.33, 1.0 / 1.5] {
        for cos_i in [0.2f64, 0.5, 0.8, 0.95] {
            let theta_i = cos_i.acos();
            let sin_t = theta_i.sin() / eta;
            if sin_t >= 1.0 {
                continue; // beyond the critical angle: the next test's case
            }
            let theta_t = sin_t.asin();
            let r_s = ((theta_i - theta_t).sin() / (theta_i + theta_t).sin()).powi(2);
            let r_p = ((theta_i - theta_t).tan() / (theta_i + theta_t).tan()).powi(2);
            let expected = 0.5 * (r_s + r_p);
            let got = fresnel_dielectric(cos_i as f32, eta as f32) as f64;
            assert!(
                (got - expected).abs() <= 1e-5,
                "F(cos_i = {cos_i}, eta = {eta:.4}): got {got}, expected {expected}"
            );
        }
    }
}

#[test]
fn fresnel_at_normal_incidence_is_the_squared_index_ratio() {
    for ior in IORS {
        let r0 = ((ior as f64 - 1.0) / (ior as f64 + 1.0)).powi(2);
        assert_close(
            "F(0) entering",
            fresnel_dielectric(1.0, ior) as f64,
            r0,
            F32_TOL,
        );
        assert_close(
            "F(0) leaving",
            fresnel_dielectric(1.0, 1.0 / ior) as f64,
            r0,
            F32_TOL,
        );
        assert_close(
            "F(90)",
            fresnel_dielectric(0.0, ior.max(1.0)) as f64,
            1.0,
            F32_TOL,
        );
    }
}

/// Oblique incidence, against closed forms that do not share the code's formula (Hecht,
/// Optics, 4th ed., eq. 4.42-4.43 write the amplitudes with the angles: r_perp =
/// -sin(theta_i - theta_t) / sin(theta_i + theta_t), r_par = tan(theta_i - theta_t) /
/// tan(theta_i + theta_t)). Normal and grazing incidence cannot tell r_par from r_perp (they
/// are equal there up to sign), so the two polarizations are pinned where they differ most:
///
/// - at Brewster's angle, tan theta_B = eta (eta = eta_t / eta_i), r_par vanishes and
///   F = R_perp / 2 = ((eta^2 - 1) / (eta^2 + 1))^2 / 2 (cos theta_i = 1 / sqrt(1 + eta^2),
///   cos theta_t = eta / sqrt(1 + eta^2)); exchanging cos_i and cos_t in r_par turns r_par
///   into -r_perp and doubles F there;
/// - at 45 degrees R_par = R_perp^2 (Abeles 1950), so F = (R_perp + R_perp^2) / 2 with R_perp
///   from the angle form above; glass (1.5) from outside gives 0.0502399.
#[test]
fn fresnel_at_oblique_incidence_matches_hand_computed_values() {
    for ior in IORS {
        for eta in [ior as f64, 1.0 / ior as f64] {
            // Brewster's angle from either side of the interface
            let cos_b = 1.0 / (1.0 + eta * eta).sqrt();
            let r_perp = (eta * eta - 1.0) / (eta * eta + 1.0);
            assert_close(
                &format!("F at Brewster's angle, eta {eta}"),
                fresnel_dielectric(cos_b as f32, eta as f32) as f64,
                0.5 * r_perp * r_perp,
                F32_TOL,
            );
            // 45 degrees: refraction exists when sin 45 < eta
            let theta_i = std::f64::consts::FRAC_PI_4;
            let sin_t = theta_i.sin() / eta;
            let f = fresnel_dielectric(theta_i.cos() as f32, eta as f32) as f64;
            if sin_t >= 1.0 {
                assert_eq!(f, 1.0, "eta {eta}: total internal reflection at 45 degrees");
                continue;
            }
            let theta_t = sin_t.asin();
            let r_perp = -(theta_i - theta_t).sin() / (theta_i + theta_t).sin();
            let r_par = (theta_i - theta_t).tan() / (theta_i + theta_t).tan();
            let big_r = r_perp * r_perp;
            assert_close("Abeles", r_par * r_par, big_r * big_r, 1e-12);
            assert_close(
                &format!("F at 45 degrees, eta {eta}"),
                f,
                0.5 * (big_r + big_r * big_r),
                F32_TOL,
            );
        }
    }
    // the number itself, for glass seen from outside
    assert_close(
        "F(45 deg), glass",
        fresnel_dielectric(std::f32::consts::FRAC_1_SQRT_2, 1.5) as f64,
        0.050_239_911,
        F32_TOL,
    );
}

#[test]
fn dielectric_reflects_totally_beyond_the_critical_angle() {
    let mut s = sampler(30, 0);
    for ior in IORS {
        let (eta_dense, eta_thin) = (ior.max(1.0 / ior) as f64, 1.0);
        let cos_critical = (1.0 - (eta_thin / eta_dense).powi(2)).sqrt();
        // the dense side is behind n when ior > 1, in front of it otherwise
        let dense_sign = if ior > 1.0 { -1.0 } else { 1.0 };
        let n = Vec3::new(0.2, 0.1, 1.0).normalize();
        for (cos_o, total) in [
            (cos_critical * 0.9, true),
            (cos_critical * 0.5, true),
            ((cos_critical + 1.0) * 0.5, false),
        ] {
            let wo = at_cosine(n, dense_sign * cos_o, 0.3);
            let f = fresnel_dielectric(cos_o as f32, (eta_thin / eta_dense) as f32);
            assert_eq!(
                f == 1.0,
                total,
                "ior {ior}, cos {cos_o} from the dense side: got F = {f}, expected {}",
                if total {
                    "1 (total internal reflection beyond the critical angle)"
                } else {
                    "F < 1 (refraction before the critical angle)"
                }
            );
            for _ in 0..64 {
                let bs = Bsdf::Dielectric(Dielectric::new(ior))
                    .sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Radiance)
                    .unwrap();
                if total {
                    assert_eq!(bs.lobe, Lobe::SingularReflection);
                    assert_close("TIR weight", bs.weight(n).x as f64, 1.0, F32_TOL);
                }
            }
            if !total {
                let bs = dielectric_lobe(ior, wo, n, true, TransportMode::Radiance).unwrap();
                assert_eq!(
                    bs.lobe,
                    Lobe::SingularTransmission,
                    "ior {ior}: no refraction"
                );
            }
        }
    }
}

#[test]
fn dielectric_refraction_obeys_snells_law() {
    for ior in IORS {
        for n in normals() {
            for wo in test_directions(31, 16) {
                let (eta_o, eta_t) = etas(ior, wo, n);
                let cos_o = (wo.dot(n) as f64).abs();
                let sin_o = (1.0 - cos_o * cos_o).sqrt();
                if eta_o * sin_o >= eta_t || cos_o < 1e-3 {
                    continue; // total internal reflection, or grazing
                }
                for mode in modes() {
                    let bs = dielectric_lobe(ior, wo, n, true, mode).unwrap();
                    assert_eq!(bs.lobe, Lobe::SingularTransmission);
                    assert!(bs.wi.dot(n) * wo.dot(n) < 0.0, "refracted to the same side");
                    let cos_t = (bs.wi.dot(n) as f64).abs();
                    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                    // eta_o sin_o = eta_t sin_t, in the plane of wo and n, across the normal
                    assert_close("Snell", eta_t * sin_t, eta_o * sin_o, F32_TOL);
                    assert_close("coplanar", wo.cross(n).dot(bs.wi) as f64, 0.0, F32_TOL);
                    let tangent_o = wo - n * wo.dot(n);
                    let tangent_i = bs.wi - n * bs.wi.dot(n);
                    assert!(tangent_o.dot(tangent_i) <= 0.0, "not across the normal");
                    assert_close("unit", bs.wi.length() as f64, 1.0, F32_TOL);
                }
            }
        }
    }
}

/// A thin sheet (Mitsuba 3's `thindielectric`): light is reflected about the normal or goes on
/// unbent, from either side alike; the reflected part is the sum over the passes inside the
/// sheet, R + T^2 R + T^2 R^3 + ..., summed here term by term (not by the closed form the
/// model uses), and the two lobes' weights, value |cos| / probability, are 1 (every photon
/// leaves by one of the two lobes, none is absorbed), whatever the transport mode.
#[test]
fn thin_dielectric_reflects_the_sum_of_its_inner_passes_and_transmits_unbent() {
    for ior in IORS {
        for n in normals() {
            for wo in test_directions(37, 8) {
                let cos_o = wo.dot(n).abs();
                if cos_o < 1e-3 {
                    continue;
                }
                let r = fresnel_dielectric(cos_o, ior) as f64;
                let t = 1.0 - r;
                let (mut series, mut term) = (r, t * t * r);
                for _ in 0..200 {
                    series += term;
                    term *= r * r;
                }
                for mode in modes() {
                    let thin = Bsdf::ThinDielectric(ThinDielectric::new(ior));
                    let refl = thin.sample(wo, n, Vec2::splat(0.5), 0.0, mode).unwrap();
                    let tran = thin.sample(wo, n, Vec2::splat(0.5), ONE_MINUS_EPSILON, mode);
                    assert_eq!(refl.lobe, Lobe::SingularReflection);
                    assert_close("reflectance", refl.pdf as f64, series, F32_TOL);
                    assert_close("mirror", refl.wi.dot(n) as f64, wo.dot(n) as f64, F32_TOL);
                    assert_close("reflected weight", refl.weight(n).x as f64, 1.0, F32_TOL);
                    if series < 1.0 - 1e-6 {
                        let tran = tran.unwrap();
                        assert_eq!(tran.lobe, Lobe::SingularTransmission);
                        assert!((tran.wi + wo).length() < 1e-6, "not straight through");
                        assert_close("transmittance", tran.pdf as f64, 1.0 - series, F32_TOL);
                        assert_close("passed weight", tran.weight(n).x as f64, 1.0, F32_TOL);
                    }
                }
            }
        }
    }
}

#[test]
fn dielectric_chooses_reflection_with_the_fresnel_probability() {
    const N: u64 = 100_000;
    let mut fam = Family::new("bsdf: dielectric lobe choice");
    let n = Vec3::Z;
    for (i, ior) in IORS.into_iter().enumerate() {
        for (j, cos_o) in [0.95f64, 0.5, 0.15].into_iter().enumerate() {
            for side in [1.0, -1.0] {
                let wo = at_cosine(n, side * cos_o, 0.7);
                let (eta_o, eta_t) = etas(ior, wo, n);
                let f = fresnel_dielectric(cos_o as f32, (eta_t / eta_o) as f32) as f64;
                let mut s = sampler(32, (i * 8 + j * 2) as u64 + (side > 0.0) as u64);
                let mut reflected = 0u64;
                for _ in 0..N {
                    let bs = Bsdf::Dielectric(Dielectric::new(ior))
                        .sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Radiance)
                        .unwrap();
                    if bs.lobe == Lobe::SingularReflection {
                        reflected += 1;
                        assert_close("reflection pdf", bs.pdf as f64, f, F32_TOL);
                    } else {
                        assert_close("transmission pdf", bs.pdf as f64, 1.0 - f, F32_TOL);
                    }
                }
                fam.binomial(&format!("ior {ior}, cos {}", side * cos_o), reflected, N, f);
            }
        }
    }
    fam.finish();
}

/// The coefficient c of a singular lobe, f_s = c delta(wi - wi_0) / |cos wi|: the value times
/// |cos wi|, i.e. the lobe's weight times its probability.
fn coefficient(bs: &BsdfSample, n: Vec3) -> f64 {
    bs.value.x as f64 * (bs.wi.dot(n) as f64).abs()
}

#[test]
fn dielectric_conserves_flux_for_importance_and_scales_radiance_by_eta_squared() {
    for ior in IORS {
        for n in normals() {
            for wo in test_directions(33, 16) {
                let (eta_o, eta_t) = etas(ior, wo, n);
                let cos_o = (wo.dot(n) as f64).abs();
                if cos_o < 1e-3 || eta_o * (1.0 - cos_o * cos_o).sqrt() >= eta_t {
                    continue; // grazing or total internal reflection (checked elsewhere)
                }
                for mode in modes() {
                    let r = dielectric_lobe(ior, wo, n, false, mode).unwrap();
                    let t = dielectric_lobe(ior, wo, n, true, mode).unwrap();
                    assert_eq!(r.lobe, Lobe::SingularReflection);
                    assert_eq!(t.lobe, Lobe::SingularTransmission);
                    assert_close("lobe probabilities", (r.pdf + t.pdf) as f64, 1.0, F32_TOL);
                    assert_close("reflection weight", r.weight(n).x as f64, 1.0, F32_TOL);
                    let expected_t = match mode {
                        // flux is conserved: nothing but Fresnel splits the particle
                        TransportMode::Importance => 1.0,
                        // radiance is compressed into a narrower cone: (eta_o / eta_t)^2
                        TransportMode::Radiance => (eta_o / eta_t).powi(2),
                    };
                    assert_close(
                        "transmission weight",
                        t.weight(n).x as f64,
                        expected_t,
                        F32_TOL,
                    );
                    // sum over both lobes of weight x probability
                    let total =
                        r.weight(n).x as f64 * r.pdf as f64 + t.weight(n).x as f64 * t.pdf as f64;
                    let expected_total = r.pdf as f64 + t.pdf as f64 * expected_t;
                    assert_close("energy", total, expected_total, F32_TOL);
                    if mode == TransportMode::Importance {
                        assert_close("importance energy", total, 1.0, F32_TOL);
                    }
                }
            }
        }
    }
}

#[test]
fn dielectric_refraction_satisfies_generalized_reciprocity_and_its_adjoint() {
    // For the transmitted pair (wo, wi), wi = T(wo), and its reverse (wi, wo):
    //   generalized reciprocity  f(wi -> wo) / eta_o^2 = f(wo -> wi) / eta_i^2, which for the
    //   Dirac coefficients reads c_R(wo, wi) eta_i^4 = c_R(wi, wo) eta_o^4 (the étendue
    //   eta^2 dsigma_perp is preserved, see the book), and the adjoint f*(wo, wi) = f(wi, wo),
    //   which reads c_I(wo, wi) = c_R(wi, wo) eta_o^2 / eta_i^2.
    for ior in IORS {
        for n in normals() {
            for wo in test_directions(34, 16) {
                let (eta_o, eta_i) = etas(ior, wo, n);
                let cos_o = (wo.dot(n) as f64).abs();
                if cos_o < GRAZING_LIMIT || eta_o * (1.0 - cos_o * cos_o).sqrt() >= eta_i {
                    continue;
                }
                let fwd = dielectric_lobe(ior, wo, n, true, TransportMode::Radiance).unwrap();
                let wi = fwd.wi;
                if (wi.dot(n) as f64).abs() < GRAZING_LIMIT {
                    continue;
                }
                let rev = dielectric_lobe(ior, wi, n, true, TransportMode::Radiance).unwrap();
                assert_close("T(T(wo)) = wo", (rev.wi - wo).length() as f64, 0.0, F32_TOL);
                let adj = dielectric_lobe(ior, wo, n, true, TransportMode::Importance).unwrap();
                let (c_fwd, c_rev, c_adj) = (
                    coefficient(&fwd, n),
                    coefficient(&rev, n),
                    coefficient(&adj, n),
                );
                assert_close(
                    "generalized reciprocity",
                    c_fwd * eta_i.powi(4),
                    c_rev * eta_o.powi(4),
                    F32_TOL,
                );
                assert_close("adjoint", c_adj, c_rev * (eta_o / eta_i).powi(2), F32_TOL);
            }
        }
    }
}

#[test]
fn null_boundary_never_scatters() {
    let bsdf = Bsdf::Null(Null);
    assert!(bsdf.is_null() && !bsdf.has_regular_lobe() && !bsdf.has_dirac_lobe());
    let mut s = sampler(40, 0);
    for wo in test_directions(40, 8) {
        let wi = warp::uniform_sphere(s.next_2d());
        assert!(bsdf
            .sample(
                wo,
                Vec3::Z,
                s.next_2d(),
                s.next_f32(),
                TransportMode::Radiance
            )
            .is_none());
        assert_eq!(
            bsdf.eval(wo, wi, Vec3::Z, TransportMode::Radiance),
            Rgb::ZERO
        );
        assert_eq!(bsdf.pdf(wo, wi, Vec3::Z), 0.0);
    }
}

#[test]
fn reflect_is_an_involution() {
    let mut s = sampler(41, 0);
    for n in normals() {
        for _ in 0..64 {
            let w = warp::uniform_sphere(s.next_2d());
            let r = reflect(reflect(w, n), n);
            assert_close("reflect twice", (r - w).length() as f64, 0.0, F32_TOL);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// One-sided opaque models (Mitsuba's `diffuse` and `conductor` without `twosided`)

/// A one-sided model is black behind its normal (no value, no density, no sample) and is the
/// two-sided model on the normal's side, bit for bit.
#[test]
fn one_sided_models_are_black_behind_and_two_sided_in_front() {
    use pathspace::bsdf::{ConductorFresnel, RoughConductor};
    let pair = |one_sided: bool| {
        [
            Bsdf::Lambert(Lambert {
                albedo: ALBEDO,
                one_sided,
            }),
            Bsdf::Mirror(Mirror {
                reflectance: ALBEDO,
                one_sided,
            }),
            Bsdf::RoughConductor(RoughConductor {
                distribution: pathspace::bsdf::Distribution::Ggx,
                alpha: 0.3,
                fresnel: ConductorFresnel::Schlick(ALBEDO),
                specular: Vec3::ONE,
                one_sided,
                anisotropy: None,
            }),
            Bsdf::Plastic(Plastic {
                diffuse: ALBEDO,
                specular: Rgb::ONE,
                eta: 1.5,
                nonlinear: false,
                one_sided,
            }),
        ]
    };
    let mut s = sampler(30, 0);
    for (one, two) in pair(true).iter().zip(pair(false).iter()) {
        for n in normals() {
            for k in 0..64 {
                let cos_o = if k % 2 == 0 { 0.7 } else { -0.7 };
                let wo = at_cosine(n, cos_o, k as f64);
                let wi = at_cosine(n, cos_o.signum() * 0.4, 2.0 + k as f64);
                let (u, uc) = (Vec2::new(s.next_f32(), s.next_f32()), s.next_f32());
                let mode = TransportMode::Radiance;
                let (a, b) = (
                    one.sample(wo, n, u, uc, mode),
                    two.sample(wo, n, u, uc, mode),
                );
                if cos_o > 0.0 {
                    assert_eq!(one.eval(wo, wi, n, mode), two.eval(wo, wi, n, mode));
                    assert_eq!(one.pdf(wo, wi, n), two.pdf(wo, wi, n));
                    assert_eq!(
                        a.map(|x| (x.wi, x.value, x.pdf)),
                        b.map(|x| (x.wi, x.value, x.pdf))
                    );
                } else {
                    assert_eq!(one.eval(wo, wi, n, mode), Rgb::ZERO, "{one:?}");
                    assert_eq!(one.pdf(wo, wi, n), 0.0, "{one:?}");
                    assert!(a.is_none(), "{one:?} sampled behind its normal");
                    let may_fail = matches!(two, Bsdf::RoughConductor(_) | Bsdf::Plastic(_));
                    assert!(b.is_some() || may_fail);
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Smooth plastic (Mitsuba 3's `plastic`): a Dirac coat over a diffuse base

use pathspace::bsdf::plastic::fresnel_diffuse_reflectance;
use pathspace::bsdf::Plastic;

/// A plastic of base `diffuse` (coat reflectance `specular`) and index `eta`, one-sided.
fn plastic(diffuse: Rgb, specular: Rgb, eta: f32, nonlinear: bool) -> Bsdf {
    Bsdf::Plastic(Plastic {
        diffuse,
        specular,
        eta,
        nonlinear,
        one_sided: true,
    })
}

/// The dielectric Fresnel reflectance in f64, written out again (Born and Wolf sec. 1.5.2):
/// the test's own reference for the crate's f32 one.
fn fresnel64(c: f64, eta: f64) -> f64 {
    let s2 = (1.0 - c * c) / (eta * eta);
    let ct = (1.0 - s2).sqrt();
    let rp = (eta * c - ct) / (eta * c + ct);
    let rs = (c - eta * ct) / (c + eta * ct);
    0.5 * (rp * rp + rs * rs)
}

/// The probability of the coat's Dirac from cosine `c`: F w / (F w + (1 - F)(1 - w)), w the
/// specular sampling weight mean(R_s) / (mean(rho) + mean(R_s)) (Mitsuba's plastic.cpp).
fn coat_probability(diffuse: Rgb, specular: Rgb, eta: f64, c: f64) -> f64 {
    let mean = |v: Rgb| (v.x + v.y + v.z) as f64 / 3.0;
    let w = mean(specular) / (mean(diffuse) + mean(specular));
    let f = fresnel64(c, eta);
    f * w / (f * w + (1.0 - f) * (1.0 - w))
}

#[test]
fn plastic_diffuse_lobe_equals_the_closed_form_at_hand_computed_angles() {
    // rho = 0.5, eta = 1.5: F_dr_int = F_dr(1/1.5) = -1.4399 / 2.25 + 0.7099 / 1.5 + 0.6681
    // + 0.0636 * 1.5 = 0.596811 (Egan and Hilgeman's fit), F(1) = 0.04, and
    // f = rho / (1 - F_dr_int) (1 - F_o)(1 - F_i) / eta^2 / pi, computed by hand (in f64):
    let n = Vec3::Z;
    let cases = [
        (1.0, 1.0, 0.5, false, 0.16168566765341938),
        (0.5, 0.8, 0.5, false, 0.15277916254638585),
        (0.2, 0.9, 0.5, false, 0.11125325931382654),
        // nonlinear, rho = 0.8: rho / (1 - F_dr_int rho) instead
        (0.5, 0.8, 0.8, true, 0.1886096406117238),
    ];
    assert_close(
        "F_dr(1/1.5)",
        fresnel_diffuse_reflectance(1.0 / 1.5) as f64,
        0.5968111111111112,
        F32_TOL,
    );
    for (co, ci, rho, nonlinear, expected) in cases {
        let b = plastic(Rgb::splat(rho), Rgb::ONE, 1.5, nonlinear);
        let (wo, wi) = (at_cosine(n, co, 0.3), at_cosine(n, ci, 2.9));
        let f = b.eval(wo, wi, n, TransportMode::Radiance);
        for c in 0..3 {
            assert_close("plastic f_d", f[c] as f64, expected, F32_TOL);
        }
    }
}

#[test]
fn plastic_is_reciprocal_and_black_across_and_behind() {
    let b = plastic(ALBEDO, Rgb::new(1.0, 0.8, 0.6), 1.6, false);
    let two = Bsdf::Plastic(Plastic {
        one_sided: false,
        ..match &b {
            Bsdf::Plastic(p) => p.clone(),
            _ => unreachable!(),
        }
    });
    let mut s = sampler(40, 0);
    for n in normals() {
        for _ in 0..256 {
            let wo = warp::uniform_sphere(s.next_2d());
            let wi = warp::uniform_sphere(s.next_2d());
            for mode in modes() {
                for m in [&b, &two] {
                    let f = m.eval(wo, wi, n, mode);
                    assert_eq!(f, m.eval(wi, wo, n, mode), "not reciprocal");
                    let front = wo.dot(n) > 0.0 || std::ptr::eq(m, &two);
                    if wo.dot(n) * wi.dot(n) > 0.0 && front {
                        assert!(f.min_element() > 0.0 && m.pdf(wo, wi, n) > 0.0);
                    } else {
                        assert_eq!(f, Rgb::ZERO, "plastic transmits or lights its back");
                        assert_eq!(m.pdf(wo, wi, n), 0.0);
                    }
                }
            }
        }
    }
}

#[test]
fn plastic_coat_is_a_dirac_of_weight_fresnel_over_its_probability() {
    let (rho, rs) = (ALBEDO, Rgb::new(0.9, 0.7, 0.5));
    let b = plastic(rho, rs, 1.5, false);
    for n in normals() {
        for co in [0.95, 0.6, 0.3, 0.05] {
            let wo = at_cosine(n, co, 1.3);
            // uc = 0 takes the coat whenever its probability is positive
            let bs = b
                .sample(wo, n, Vec2::new(0.3, 0.6), 0.0, TransportMode::Radiance)
                .unwrap();
            assert_eq!(bs.lobe, Lobe::SingularReflection);
            let mirror = reflect(wo, n);
            assert!((bs.wi - mirror).length() < 1e-5, "not the mirror direction");
            let p = coat_probability(rho, rs, 1.5, co);
            assert_close("P(coat)", bs.pdf as f64, p, F32_TOL);
            let w = bs.weight(n);
            for c in 0..3 {
                let expected = fresnel64(co, 1.5) * rs[c] as f64 / p;
                assert_close("coat weight F R_s / P", w[c] as f64, expected, F32_TOL);
            }
            // the regular lobe's density carries the probability of the other choice
            let wi = at_cosine(n, 0.5, 0.2);
            let expected = (1.0 - p) * 0.5 / std::f64::consts::PI;
            assert_close("pdf", b.pdf(wo, wi, n) as f64, expected, F32_TOL);
        }
    }
}

#[test]
fn plastic_chooses_its_coat_with_the_stated_probability() {
    // the fraction of Dirac samples against F w / (F w + (1 - F)(1 - w)), a binomial mean
    const N: u64 = 100_000;
    let mut fam = Family::new("bsdf: plastic lobe choice");
    let (rho, rs) = (ALBEDO, Rgb::new(0.9, 0.7, 0.5));
    let b = plastic(rho, rs, 1.5, false);
    let n = Vec3::Z;
    for (k, co) in [0.9f64, 0.4, 0.1].into_iter().enumerate() {
        let wo = at_cosine(n, co, 0.7);
        let mut s = sampler(41, k as u64);
        let mut hits = 0u64;
        for _ in 0..N {
            let bs = b.sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Radiance);
            if bs.is_some_and(|x| x.lobe.is_singular()) {
                hits += 1;
            }
        }
        let p = coat_probability(rho, rs, 1.5, co);
        let mean = hits as f64 / N as f64;
        fam.samples_are(
            &format!("P(coat) at cos {co}"),
            mean,
            mean * (1.0 - mean),
            N,
            p,
        );
    }
    fam.finish();
}

#[test]
fn plastic_regular_sampling_agrees_with_pdf_by_chi_square() {
    // the Dirac samples are missing mass: the density integrates to 1 - P(coat), and the
    // chi-square compares every bin with it (a pdf without that factor fails)
    const N_SAMPLES: u64 = 200_000;
    let mut fam = Family::new("bsdf: plastic sampling vs pdf");
    for (i, n) in normals().into_iter().enumerate() {
        for (j, (cos_o, one_sided)) in [(0.7f64, true), (0.15, true), (-0.4, false)]
            .into_iter()
            .enumerate()
        {
            let b = Bsdf::Plastic(Plastic {
                diffuse: ALBEDO,
                specular: Rgb::splat(0.8),
                eta: 1.7,
                nonlinear: false,
                one_sided,
            });
            let wo = at_cosine(n, cos_o, 2.0);
            let grid = SphereGrid::new(Frame::from_normal(n), 20, 16);
            let mut s = sampler(42, (3 * i + j) as u64);
            chi_square_sphere(
                &mut fam,
                &format!("plastic n {n}, cos_o {cos_o}"),
                &grid,
                || {
                    b.sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Radiance)
                        .filter(|bs| bs.lobe == Lobe::Regular)
                        .map(|bs| bs.wi)
                },
                |wi| b.pdf(wo, wi, n) as f64,
                N_SAMPLES,
            );
        }
    }
    fam.finish();
}

/// The directional albedo F_o R_s + int f_d |cos| (Simpson in cos; f_d does not depend on the
/// azimuth) of a plastic seen at cosine `co`.
fn plastic_albedo(b: &Bsdf, eta: f64, rs: f64, co: f64, c: usize) -> f64 {
    let n = Vec3::Z;
    let wo = at_cosine(n, co, 0.0);
    let diffuse = simpson(
        |ci| {
            let wi = at_cosine(n, ci.max(1e-9), 1.0);
            b.eval(wo, wi, n, TransportMode::Radiance)[c] as f64 * ci * TAU
        },
        0.0,
        1.0,
        256,
    );
    fresnel64(co, eta) * rs + diffuse
}

#[test]
fn plastic_albedo_is_the_closed_form_and_at_most_one_up_to_the_fits() {
    // int (1 - F_i) |cos| / pi = 1 - F_dr,ext exactly, and (1 - F_dr,ext) / eta^2 =
    // 1 - F_dr,int (reciprocity), so with exact F_dr the albedo is F_o R_s + (1 - F_o) rho:
    // at most one. Mitsuba's F_dr is a fit: the ratio r = (1 - F_dr,ext) / (eta^2 (1 -
    // fit(1/eta))) is 1 within the fit's error (below 0.2% for eta in [1.1, 2]; 1.0012 at the
    // default 1.49 / 1.000277), and rho = R_s = 1 then reflects r - F_o (r - 1) > 1.
    for eta in [1.1f64, 1.33, 1.49 / 1.000277, 2.0] {
        let one_minus_fdr_ext = simpson(|c| (1.0 - fresnel64(c, eta)) * 2.0 * c, 0.0, 1.0, 4096);
        let r = one_minus_fdr_ext
            / (eta * eta * (1.0 - fresnel_diffuse_reflectance((1.0 / eta) as f32) as f64));
        assert!((r - 1.0).abs() < 2e-3, "the F_dr fit at eta {eta}: r = {r}");
        for nonlinear in [false, true] {
            let (rho, rs) = (Rgb::new(1.0, 0.6, 0.2), Rgb::new(1.0, 0.5, 0.0));
            let b = plastic(rho, rs, eta as f32, nonlinear);
            for co in [0.99, 0.6, 0.2] {
                let fo = fresnel64(co, eta);
                for c in 0..3 {
                    let albedo = plastic_albedo(&b, eta, rs[c] as f64, co, c);
                    let rho = rho[c] as f64;
                    let fdr = fresnel_diffuse_reflectance((1.0 / eta) as f32) as f64;
                    // the internal bounces: 1 / (1 - F_dr rho) or 1 / (1 - F_dr)
                    let bounce = if nonlinear {
                        1.0 - fdr * rho
                    } else {
                        1.0 - fdr
                    };
                    let expected = fo * rs[c] as f64 + (1.0 - fo) * rho * r * (1.0 - fdr) / bounce;
                    assert_close("plastic albedo", albedo, expected, 1e-4);
                    assert!(albedo <= r.max(1.0) + 1e-4, "albedo {albedo} at eta {eta}");
                }
            }
        }
    }
}

#[test]
fn plastic_sample_weights_estimate_its_albedo() {
    // the mean of value |cos| / pdf over both lobes is the albedo of the quadrature: the Dirac
    // weight, the regular weight and the lobe choice together
    const N: u64 = 50_000;
    let mut fam = Family::new("bsdf: plastic sample weights");
    let eta = 1.49f64 / 1.000277;
    let (rho, rs) = (Rgb::new(0.8, 0.5, 0.2), Rgb::new(1.0, 0.7, 0.4));
    for nonlinear in [false, true] {
        let b = plastic(rho, rs, eta as f32, nonlinear);
        for (k, co) in [0.9f64, 0.3].into_iter().enumerate() {
            let n = Vec3::Z;
            let wo = at_cosine(n, co, 0.0);
            let mut s = sampler(43, k as u64 + 2 * nonlinear as u64);
            let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
            for _ in 0..N {
                let w = b
                    .sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Importance)
                    .map_or(Rgb::ZERO, |bs| bs.weight(n));
                for c in 0..3 {
                    sum[c] += w[c] as f64;
                    sum2[c] += (w[c] as f64).powi(2);
                }
            }
            for c in 0..3 {
                let mean = sum[c] / N as f64;
                let var = sum2[c] / N as f64 - mean * mean;
                let truth = plastic_albedo(&b, eta, rs[c] as f64, co, c);
                let what = format!("plastic weight, nonlinear {nonlinear}, cos {co}, channel {c}");
                fam.samples_are(&what, mean, var, N, truth);
            }
        }
    }
    fam.finish();
}

// The modules of `src/bsdf/` (the layout: tests/repository/index.rs).
mod conductor;
mod contract;
mod microfacet;
mod rough_plastic;

// ---------------------------------------------------------------------------------------------
// Tinted dielectrics (Mitsuba 3's `specular_reflectance` and `specular_transmittance`)

/// The two factors of [`tinted`]: distinct channels, distinct from each other.
const REFLECTANCE: Rgb = Vec3::new(0.9, 0.6, 0.3);
const TRANSMITTANCE: Rgb = Vec3::new(0.4, 0.7, 1.0);

/// The three dielectrics clear and tinted, with their names.
fn tinted() -> Vec<(&'static str, Bsdf, Bsdf)> {
    use pathspace::bsdf::{Distribution, RoughDielectric, Specular};
    let tint = Specular {
        reflectance: REFLECTANCE,
        transmittance: TRANSMITTANCE,
    };
    let rough = |specular| {
        Bsdf::RoughDielectric(RoughDielectric {
            ior: 1.5,
            distribution: Distribution::Ggx,
            alpha: 0.3,
            specular,
            anisotropy: None,
        })
    };
    vec![
        (
            "dielectric",
            Bsdf::Dielectric(Dielectric::new(1.5)),
            Bsdf::Dielectric(Dielectric {
                ior: 1.5,
                specular: tint,
            }),
        ),
        (
            "thin dielectric",
            Bsdf::ThinDielectric(ThinDielectric::new(1.5)),
            Bsdf::ThinDielectric(ThinDielectric {
                ior: 1.5,
                specular: tint,
            }),
        ),
        ("rough dielectric", rough(Specular::ONE), rough(tint)),
    ]
}

/// `Bsdf::radiance_scale` is the part of a sample's value that radiance carries and importance
/// does not: for every lobe of the smooth and rough dielectrics (ior 1.5 and 1.33) and the thin
/// sheet, from both sides at many angles, the radiance-mode value over the importance-mode
/// value of the same direction is the scale, (eta_o / eta_t)^2 for a refraction and 1 for a
/// reflection and for the sheet. Russian roulette divides it out (path tracer and the
/// bidirectional walks); with the indices swapped, entering glass would read as leaving it.
#[test]
fn radiance_scale_is_the_ratio_of_radiance_to_importance() {
    use pathspace::bsdf::{Distribution, RoughDielectric};
    let mut models = Vec::new();
    for ior in [1.5f32, 1.33] {
        models.push(Bsdf::Dielectric(Dielectric::new(ior)));
        models.push(Bsdf::ThinDielectric(ThinDielectric::new(ior)));
        models.push(Bsdf::RoughDielectric(RoughDielectric {
            ior,
            distribution: Distribution::Ggx,
            alpha: 0.3,
            specular: pathspace::bsdf::Specular::ONE,
            anisotropy: None,
        }));
    }
    use rand::{Rng, SeedableRng};
    let mut r = rand_pcg::Pcg64Mcg::seed_from_u64(215);
    let (mut refractions, mut scaled) = (0, 0);
    for bsdf in &models {
        for n in normals() {
            for _ in 0..200 {
                let wo = at_cosine(n, r.random_range(-1.0..1.0), r.random_range(0.0..TAU));
                let (u, uc) = (Vec2::new(r.random(), r.random()), r.random::<f32>());
                let Some(bs) = bsdf.sample(wo, n, u, uc, TransportMode::Radiance) else {
                    continue;
                };
                let radiance = bsdf.eval(wo, bs.wi, n, TransportMode::Radiance);
                let importance = bsdf.eval(wo, bs.wi, n, TransportMode::Importance);
                let (radiance, importance) = match bs.lobe {
                    // a Dirac lobe's value is its sample's (eval is 0)
                    Lobe::Regular => (radiance, importance),
                    _ => {
                        let imp = bsdf.sample(wo, n, u, uc, TransportMode::Importance);
                        (bs.value, imp.expect("the same lobe in either mode").value)
                    }
                };
                if importance.max_element() <= 0.0 {
                    continue;
                }
                let scale = bsdf.radiance_scale(wo, bs.wi, n) as f64;
                let ratio = radiance.x as f64 / importance.x as f64;
                assert!(
                    (ratio - scale).abs() <= 1e-4 * scale,
                    "{bsdf:?}: wo {wo:?} wi {:?}: radiance / importance {ratio}, scale {scale}",
                    bs.wi
                );
                refractions += (bs.wi.dot(n) * wo.dot(n) < 0.0) as usize;
                scaled += (scale != 1.0) as usize;
            }
        }
    }
    assert!(
        refractions > 1000 && scaled > 500,
        "{refractions} refractions, {scaled} scaled"
    );
}

/// Mitsuba 3's `dielectric.cpp`, `roughdielectric.cpp` and `thindielectric.cpp`: the factors
/// multiply the value of the lobe taken (reflection by `specular_reflectance`, transmission by
/// `specular_transmittance`), in both transport modes, and leave the direction, the lobe and its
/// probability (Fresnel's choice) as the clear glass has them.
#[test]
fn tinted_glass_scales_each_lobe_by_its_factor_and_keeps_the_choice() {
    let mut s = sampler(77, 0);
    for (name, clear, tinted) in tinted() {
        for n in normals() {
            let mut lobes = [0usize; 2];
            for _ in 0..400 {
                let wo = warp::uniform_sphere(s.next_2d());
                let (u, uc) = (s.next_2d(), s.next_f32());
                for mode in modes() {
                    let (a, b) = (
                        clear.sample(wo, n, u, uc, mode),
                        tinted.sample(wo, n, u, uc, mode),
                    );
                    let (Some(a), Some(b)) = (a, b) else {
                        assert!(a.is_none() && b.is_none(), "{name}: one sample only");
                        continue;
                    };
                    assert_eq!((a.wi, a.pdf, a.lobe), (b.wi, b.pdf, b.lobe), "{name}");
                    let reflects = a.wi.dot(n) * wo.dot(n) > 0.0;
                    lobes[reflects as usize] += 1;
                    let factor = if reflects { REFLECTANCE } else { TRANSMITTANCE };
                    let want = a.value * factor;
                    for c in 0..3 {
                        let (x, y) = (b.value[c] as f64, want[c] as f64);
                        assert!(
                            (x - y).abs() <= F32_TOL * y.abs(),
                            "{name} {mode:?}: {x} vs {y}"
                        );
                    }
                    let wi = a.wi;
                    let (ea, eb) = (clear.eval(wo, wi, n, mode), tinted.eval(wo, wi, n, mode));
                    assert_eq!(clear.pdf(wo, wi, n), tinted.pdf(wo, wi, n), "{name}");
                    for c in 0..3 {
                        let (x, y) = (eb[c] as f64, (ea * factor)[c] as f64);
                        assert!(
                            (x - y).abs() <= F32_TOL * y.abs(),
                            "{name} eval: {x} vs {y}"
                        );
                    }
                }
            }
            assert!(lobes.iter().all(|&k| k > 20), "{name}: lobes {lobes:?}");
        }
    }
}
