//! The contract every surface model of `src/bsdf/` meets (book: "Surface scattering (eq. 2)"),
//! run over one list of models, [`models`], that holds every variant of `Bsdf`
//! (`every_variant_of_bsdf_is_in_the_contract_list` fails when a variant is added without a
//! case here):
//!
//! - `sample` draws its regular directions with the density `pdf` claims (chi-square over the
//!   sphere) and its Dirac lobes with the probabilities it reports (exact binomial tails);
//! - a regular sample's value and density are `eval` and `pdf` at its direction, so its weight
//!   is eval |cos wi| / pdf; its lobe and side agree with what the model declares;
//! - reciprocity in both transport modes: the importance BSDF is the radiance BSDF with its
//!   arguments swapped, f*(wo, wi) = f(wi, wo), and f(wo, wi) / eta_o^2 = f(wi, wo) / eta_i^2
//!   (Kristensen 2010 eq. 2.9); a Dirac lobe is retraced from its end with the same
//!   probability, and its radiance and importance values differ by (eta_o / eta_t)^2 exactly
//!   when it refracts;
//! - energy: the mean importance weight (the fraction of the flux arriving from a direction
//!   that leaves) is at most 1 (a one-sided Student-t bound), the radiance weight at most
//!   max(1, (eta_o / eta_t)^2).
//!
//! A new model passes all of this by being added to [`models`]; its own tests (closed forms,
//! reference values) stay in its own file (`tests/spec/bsdf.rs`, `tests/spec/bsdf/microfacet.rs`, ...).

use crate::common;

use common::stats::{student_two_sided, Family, ZERO_VARIANCE_ALLOWANCE};
use common::*;
use glam::Vec3;
use pathspace::bsdf::{
    plastic, Bsdf, Conductor, ConductorFresnel, Dielectric, Distribution, Lambert, Lobe,
    Microfacet, Mirror, Normals, Null, Plastic, RoughConductor, RoughDielectric, RoughPlastic,
    Specular, ThinDielectric, TransportMode,
};
use pathspace::math::distribution::ONE_MINUS_EPSILON;
use pathspace::math::{warp, Frame};
use pathspace::spectrum::Rgb;
use std::collections::BTreeSet;

/// An albedo per channel, each below one, distinct so that a channel mix-up shows.
const ALBEDO: Rgb = Vec3::new(0.2, 0.5, 0.9);

/// A dielectric's `specular_reflectance` and `specular_transmittance`: distinct channels, and
/// distinct from each other, so that a factor on the wrong lobe or in one mode only shows.
const TINT: Specular = Specular {
    reflectance: Vec3::new(0.9, 0.6, 0.3),
    transmittance: Vec3::new(0.4, 0.7, 1.0),
};

/// Every model under contract: each variant of `Bsdf` at least once, one-sided and two-sided,
/// both microfacet distributions, and interfaces seen from the rarer and the denser side.
fn models() -> Vec<(&'static str, Bsdf)> {
    let complex = ConductorFresnel::Complex {
        eta: Vec3::new(0.2, 0.9, 1.1),
        k: Vec3::new(3.9, 2.4, 2.1),
    };
    let eta = plastic::default_eta();
    vec![
        ("lambert", Bsdf::Lambert(lambert(false))),
        ("lambert one-sided", Bsdf::Lambert(lambert(true))),
        ("mirror", Bsdf::Mirror(mirror(false))),
        ("mirror one-sided", Bsdf::Mirror(mirror(true))),
        (
            "conductor",
            Bsdf::Conductor(Conductor {
                eta: Vec3::new(0.2, 0.9, 1.1),
                k: Vec3::new(3.9, 2.4, 2.1),
                specular: Vec3::ONE,
                one_sided: false,
            }),
        ),
        (
            "conductor tinted one-sided",
            Bsdf::Conductor(Conductor {
                eta: Vec3::new(1.5, 0.4, 0.0),
                k: Vec3::new(0.0, 1.0, 3.0),
                specular: ALBEDO,
                one_sided: true,
            }),
        ),
        ("dielectric 1.5", Bsdf::Dielectric(Dielectric::new(1.5))),
        ("dielectric 0.75", Bsdf::Dielectric(Dielectric::new(0.75))),
        (
            "thin dielectric",
            Bsdf::ThinDielectric(ThinDielectric::new(1.5)),
        ),
        (
            "dielectric 1.5 tinted",
            Bsdf::Dielectric(Dielectric {
                ior: 1.5,
                specular: TINT,
            }),
        ),
        (
            "thin dielectric tinted",
            Bsdf::ThinDielectric(ThinDielectric {
                ior: 1.5,
                specular: TINT,
            }),
        ),
        (
            "rough dielectric GGX 0.75 tinted",
            Bsdf::RoughDielectric(RoughDielectric {
                ior: 0.75,
                distribution: Distribution::Ggx,
                alpha: 0.3,
                specular: TINT,
                anisotropy: None,
            }),
        ),
        (
            "rough conductor GGX",
            Bsdf::RoughConductor(RoughConductor {
                distribution: Distribution::Ggx,
                alpha: 0.3,
                fresnel: complex,
                specular: Vec3::ONE,
                one_sided: false,
                anisotropy: None,
            }),
        ),
        (
            "rough conductor Beckmann one-sided",
            Bsdf::RoughConductor(RoughConductor {
                distribution: Distribution::Beckmann,
                alpha: 0.4,
                fresnel: ConductorFresnel::Schlick(Rgb::ONE),
                specular: Vec3::ONE,
                one_sided: true,
                anisotropy: None,
            }),
        ),
        (
            "rough dielectric GGX 1.5",
            rough_dielectric(Distribution::Ggx, 1.5),
        ),
        (
            "rough dielectric Beckmann 0.75",
            rough_dielectric(Distribution::Beckmann, 0.75),
        ),
        (
            "plastic",
            Bsdf::Plastic(Plastic {
                diffuse: ALBEDO,
                specular: Rgb::ONE,
                eta,
                nonlinear: false,
                one_sided: false,
            }),
        ),
        (
            "rough plastic nonlinear one-sided",
            Bsdf::RoughPlastic(RoughPlastic::new(
                Microfacet::new(Distribution::Ggx, 0.3),
                eta,
                ALBEDO,
                Rgb::ONE,
                true,
                true,
            )),
        ),
        ("null", Bsdf::Null(Null)),
    ]
}

fn lambert(one_sided: bool) -> Lambert {
    Lambert {
        albedo: ALBEDO,
        one_sided,
    }
}

fn mirror(one_sided: bool) -> Mirror {
    Mirror {
        reflectance: ALBEDO,
        one_sided,
    }
}

fn rough_dielectric(distribution: Distribution, ior: f32) -> Bsdf {
    Bsdf::RoughDielectric(RoughDielectric {
        ior,
        distribution,
        alpha: 0.3,
        specular: pathspace::bsdf::Specular::ONE,
        anisotropy: None,
    })
}

/// The index of refraction on `w`'s side of the surface (1 outside, in front of `n`): what the
/// eta^2 of refraction is made of. The match is exhaustive, so a new model states its indices.
fn eta_of(bsdf: &Bsdf, w: Vec3, n: Vec3) -> f64 {
    let inside = match bsdf {
        Bsdf::Dielectric(d) => d.ior,
        Bsdf::RoughDielectric(d) => d.ior,
        // the sheet's two faces refract back: the same medium on both sides
        Bsdf::ThinDielectric(_) => 1.0,
        Bsdf::Lambert(_)
        | Bsdf::Mirror(_)
        | Bsdf::Conductor(_)
        | Bsdf::RoughConductor(_)
        | Bsdf::Plastic(_)
        | Bsdf::RoughPlastic(_)
        | Bsdf::Null(_) => 1.0,
    };
    if w.dot(n) > 0.0 {
        1.0
    } else {
        inside as f64
    }
}

/// The variant's name as `Bsdf`'s `Debug` spells it (the text before the payload).
fn variant(bsdf: &Bsdf) -> String {
    let debug = format!("{bsdf:?}");
    debug.split('(').next().unwrap().to_string()
}

/// Surface normals: the shape's normal in any orientation.
fn normals() -> [Vec3; 2] {
    [Vec3::Z, Vec3::new(0.3, -0.4, 0.866).normalize()]
}

/// Outgoing directions at these cosines to the normal: in front, near grazing, behind.
const COS_O: [f64; 3] = [0.8, 0.3, -0.6];

/// Directions closer than this to grazing are left out of the deterministic comparisons, as in
/// `tests/spec/bsdf/microfacet.rs`: their cosines have too few significant digits left.
const GRAZING: f32 = 0.05;

/// Relative tolerance of f32 BSDF values computed two ways (a frame's local cosine against a
/// dot product, a half vector from the other side): a few hundred ulps of an order-one term
/// (`tests/spec/bsdf/microfacet.rs`).
const REL: f64 = 2e-4;
/// The absolute allowance of values from facets seen within ~1e-6 of grazing
/// (`tests/spec/bsdf/microfacet.rs`).
const ABS: f64 = 1e-7;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= REL * a.abs().max(b.abs()) + ABS
}

fn modes() -> [TransportMode; 2] {
    [TransportMode::Radiance, TransportMode::Importance]
}

// ---------------------------------------------------------------------------------------------
// The list

#[test]
fn every_variant_of_bsdf_is_in_the_contract_list() {
    // the variants as src/bsdf/mod.rs declares them, against those the list holds
    let src =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/src/bsdf/mod.rs")).unwrap();
    let body = src
        .split("pub enum Bsdf {")
        .nth(1)
        .and_then(|rest| rest.split("\n}").next())
        .expect("src/bsdf/mod.rs declares `pub enum Bsdf`");
    let declared: BTreeSet<String> = body
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with(|c: char| c.is_ascii_uppercase()))
        .map(|l| l.split(['(', ' ', ',', '{']).next().unwrap().to_string())
        .collect();
    let listed: BTreeSet<String> = models().iter().map(|(_, b)| variant(b)).collect();
    assert!(declared.len() >= 9, "variants not found: {declared:?}");
    assert_eq!(
        declared, listed,
        "every variant of Bsdf needs a case in models()"
    );
}

// ---------------------------------------------------------------------------------------------
// sample against pdf

#[test]
fn sample_draws_the_density_pdf_and_the_dirac_probabilities_it_reports() {
    const N: u64 = 100_000;
    let mut fam = Family::new("bsdf contract: sample vs pdf");
    for (k, (name, bsdf)) in models().into_iter().enumerate() {
        for (i, n) in normals().into_iter().enumerate() {
            for (j, cos_o) in COS_O.into_iter().enumerate() {
                let wo = direction(&Frame::from_normal(n), cos_o, 0.7);
                let what = format!("{name}, n {n}, cos_o {cos_o}");
                let index = (i * COS_O.len() + j) as u64;
                if bsdf.has_regular_lobe() {
                    regular_lobe_by_chi_square(&mut fam, &what, &bsdf, wo, n, (k, index), N);
                }
                dirac_lobes_by_binomial(&mut fam, &what, &bsdf, wo, n, (k, index), N);
            }
        }
    }
    fam.finish();
}

/// The regular samples binned over the sphere against `pdf` (Dirac samples count nowhere: their
/// probability is the mass `pdf` leaves out).
fn regular_lobe_by_chi_square(
    fam: &mut Family,
    what: &str,
    bsdf: &Bsdf,
    wo: Vec3,
    n: Vec3,
    (k, index): (usize, u64),
    samples: u64,
) {
    let grid = SphereGrid::new(Frame::from_normal(n), 20, 16);
    let mut s = sampler(100 + k as u64, index);
    chi_square_sphere(
        fam,
        what,
        &grid,
        || {
            bsdf.sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Radiance)
                .filter(|bs| bs.lobe == Lobe::Regular)
                .map(|bs| bs.wi)
        },
        |wi| bsdf.pdf(wo, wi, n) as f64,
        samples,
    );
}

/// How often each Dirac lobe is taken against the probability its samples report (the same
/// for every sample of one lobe from one `wo`).
fn dirac_lobes_by_binomial(
    fam: &mut Family,
    what: &str,
    bsdf: &Bsdf,
    wo: Vec3,
    n: Vec3,
    (k, index): (usize, u64),
    samples: u64,
) {
    let mut s = sampler(200 + k as u64, index);
    let lobes = [Lobe::SingularReflection, Lobe::SingularTransmission];
    let mut hits = [0u64; 2];
    let mut reported: [Option<f32>; 2] = [None; 2];
    for _ in 0..samples {
        let Some(bs) = bsdf.sample(wo, n, s.next_2d(), s.next_f32(), TransportMode::Radiance)
        else {
            continue;
        };
        let Some(l) = lobes.iter().position(|&l| l == bs.lobe) else {
            continue;
        };
        hits[l] += 1;
        let p = *reported[l].get_or_insert(bs.pdf);
        assert_eq!(p, bs.pdf, "{what}: one lobe, one probability");
    }
    for l in 0..2 {
        if let Some(p) = reported[l] {
            let lobe = format!("{what}: {:?} taken", lobes[l]);
            fam.binomial(&lobe, hits[l], samples, p as f64);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// eval, pdf and the sample record

#[test]
fn a_sample_is_eval_and_pdf_at_its_direction_and_keeps_the_declared_lobes() {
    for (k, (name, bsdf)) in models().into_iter().enumerate() {
        let mut s = sampler(300 + k as u64, 0);
        let mut regular = 0;
        for n in normals() {
            for cos_o in COS_O {
                let wo = direction(&Frame::from_normal(n), cos_o, 1.9);
                for mode in modes() {
                    for _ in 0..2000 {
                        let (u, uc) = (s.next_2d(), s.next_f32());
                        let Some(bs) = bsdf.sample(wo, n, u, uc, mode) else {
                            continue;
                        };
                        let what = format!("{name}, n {n}, wo {wo}, {mode:?}: wi {}", bs.wi);
                        check_record(&what, &bsdf, wo, n, mode, &bs);
                        regular += (bs.lobe == Lobe::Regular) as usize;
                    }
                }
            }
        }
        if bsdf.has_regular_lobe() {
            assert!(regular > 1000, "{name}: only {regular} regular samples");
        }
    }
}

/// One sample record against the model's declarations, `eval` and `pdf`.
fn check_record(
    what: &str,
    bsdf: &Bsdf,
    wo: Vec3,
    n: Vec3,
    mode: TransportMode,
    bs: &pathspace::bsdf::BsdfSample,
) {
    let weight = bs.weight(n);
    assert!(
        bs.pdf > 0.0 && weight.is_finite() && weight.min_element() >= 0.0,
        "{what}: pdf {}, weight {weight}",
        bs.pdf
    );
    let across = wo.dot(n) * bs.wi.dot(n) < 0.0;
    assert!(!across || bsdf.transmits(), "{what}: crossed a reflector");
    match bs.lobe {
        Lobe::Regular => assert!(bsdf.has_regular_lobe(), "{what}: undeclared regular lobe"),
        Lobe::SingularReflection => {
            assert!(bsdf.has_dirac_lobe() && !across, "{what}: Dirac reflection")
        }
        Lobe::SingularTransmission => {
            assert!(
                bsdf.has_dirac_lobe() && across,
                "{what}: Dirac transmission"
            )
        }
    }
    if bs.lobe != Lobe::Regular || bs.wi.dot(n).abs() < GRAZING {
        return;
    }
    let (f, pdf) = (bsdf.eval(wo, bs.wi, n, mode), bsdf.pdf(wo, bs.wi, n) as f64);
    assert!(close(bs.pdf as f64, pdf), "{what}: pdf {} vs {pdf}", bs.pdf);
    let cos = bs.wi.dot(n).abs() as f64;
    for c in 0..3 {
        let (v, e) = (bs.value[c] as f64, f[c] as f64);
        assert!(close(v, e), "{what}: value {v} vs eval {e} (channel {c})");
        let w = e * cos / pdf;
        assert!(
            close(weight[c] as f64, w),
            "{what}: weight {} vs eval cos / pdf {w}",
            weight[c]
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Reciprocity in both transport modes

#[test]
fn eval_is_reciprocal_and_its_adjoint_is_the_importance_bsdf() {
    let n = normals()[1];
    for (k, (name, bsdf)) in models().into_iter().enumerate() {
        let mut s = sampler(400 + k as u64, 0);
        let mut nonzero = 0;
        for _ in 0..4000 {
            let (a, b) = (
                warp::uniform_sphere(s.next_2d()),
                warp::uniform_sphere(s.next_2d()),
            );
            if a.dot(n).abs() < GRAZING || b.dot(n).abs() < GRAZING {
                continue;
            }
            let r_ab = bsdf.eval(a, b, n, TransportMode::Radiance);
            let r_ba = bsdf.eval(b, a, n, TransportMode::Radiance);
            let i_ab = bsdf.eval(a, b, n, TransportMode::Importance);
            let (ea, eb) = (eta_of(&bsdf, a, n), eta_of(&bsdf, b, n));
            for c in 0..3 {
                let what = format!("{name}: ({a}, {b}), channel {c}");
                let (x, y) = (r_ab[c] as f64 / (ea * ea), r_ba[c] as f64 / (eb * eb));
                assert!(close(x, y), "{what}: f/eta^2 {x} vs reversed {y}");
                let (i, r) = (i_ab[c] as f64, r_ba[c] as f64);
                assert!(
                    close(i, r),
                    "{what}: importance {i} vs reversed radiance {r}"
                );
            }
            nonzero += (r_ab.max_element() > 0.0) as usize;
        }
        if bsdf.has_regular_lobe() {
            assert!(nonzero > 200, "{name}: only {nonzero} pairs scatter");
        } else {
            assert_eq!(nonzero, 0, "{name}: a Dirac-only model has no value");
        }
    }
}

#[test]
fn a_dirac_lobe_is_retraced_with_its_probability_and_refracts_with_eta_squared() {
    for (k, (name, bsdf)) in models().into_iter().enumerate() {
        let mut s = sampler(500 + k as u64, 0);
        for n in normals() {
            for cos_o in COS_O {
                let wo = direction(&Frame::from_normal(n), cos_o, 0.4);
                for _ in 0..200 {
                    let (u, uc) = (s.next_2d(), s.next_f32());
                    let radiance = bsdf.sample(wo, n, u, uc, TransportMode::Radiance);
                    let importance = bsdf.sample(wo, n, u, uc, TransportMode::Importance);
                    let (Some(r), Some(i)) = (radiance, importance) else {
                        assert!(radiance.is_none() && importance.is_none(), "{name}");
                        continue;
                    };
                    if r.lobe == Lobe::Regular || r.wi.dot(n).abs() < 0.2 {
                        continue;
                    }
                    let what = format!("{name}, n {n}, wo {wo}: {:?} to {}", r.lobe, r.wi);
                    assert_eq!((r.wi, r.pdf, r.lobe), (i.wi, i.pdf, i.lobe), "{what}");
                    let ratio = (eta_of(&bsdf, wo, n) / eta_of(&bsdf, r.wi, n)).powi(2);
                    for c in 0..3 {
                        let (vr, vi) = (r.value[c] as f64, i.value[c] as f64);
                        assert!(close(vr, vi * ratio), "{what}: {vr} vs {vi} * {ratio}");
                    }
                    retrace(&what, &bsdf, wo, n, &r);
                }
            }
        }
    }
}

/// Sampling the same Dirac lobe from its end returns to `wo` with the same probability.
fn retrace(what: &str, bsdf: &Bsdf, wo: Vec3, n: Vec3, bs: &pathspace::bsdf::BsdfSample) {
    // the lobe choices compare uc against the lobe's probability: 0 takes the first (the
    // reflection), just below 1 the last (the transmission)
    let uc = match bs.lobe {
        Lobe::SingularReflection => 0.0,
        _ => ONE_MINUS_EPSILON,
    };
    let back = bsdf
        .sample(
            bs.wi,
            n,
            glam::Vec2::splat(0.5),
            uc,
            TransportMode::Radiance,
        )
        .unwrap_or_else(|| panic!("{what}: no way back"));
    assert_eq!(back.lobe, bs.lobe, "{what}: the way back");
    assert!(
        (back.wi - wo).length() as f64 <= REL,
        "{what}: back to {} instead of {wo}",
        back.wi
    );
    assert!(
        close(back.pdf as f64, bs.pdf as f64),
        "{what}: probability {} back, {} forth",
        back.pdf,
        bs.pdf
    );
}

// ---------------------------------------------------------------------------------------------
// Energy

#[test]
fn no_model_scatters_more_light_than_arrives() {
    const N: usize = 50_000;
    let mut fam = Family::new("bsdf contract: albedo at most one");
    for (k, (name, bsdf)) in models().into_iter().enumerate() {
        for (i, n) in normals().into_iter().enumerate() {
            for (j, cos_o) in COS_O.into_iter().enumerate() {
                let wo = direction(&Frame::from_normal(n), cos_o, 2.5);
                let bound = |mode| match mode {
                    // the flux arriving from wo that leaves: at most all of it
                    TransportMode::Importance => 1.0,
                    // radiance is compressed by (eta_o / eta_t)^2 where it refracts
                    TransportMode::Radiance => (eta_of(&bsdf, wo, n) / eta_of(&bsdf, -wo, n))
                        .powi(2)
                        .max(1.0),
                };
                for (m, mode) in modes().into_iter().enumerate() {
                    let mut s = sampler(600 + k as u64, ((i * 3 + j) * 2 + m) as u64);
                    let w: Vec<Rgb> = (0..N)
                        .map(|_| {
                            bsdf.sample(wo, n, s.next_2d(), s.next_f32(), mode)
                                .map_or(Rgb::ZERO, |bs| bs.weight(n))
                        })
                        .collect();
                    for c in 0..3 {
                        let x: Vec<f64> = w.iter().map(|v| v[c] as f64).collect();
                        let what = format!("{name}, n {n}, cos_o {cos_o}, {mode:?}, channel {c}");
                        at_most(&mut fam, &what, &x, bound(mode));
                    }
                }
            }
        }
    }
    fam.finish();
}

/// One-sided Student-t test of "the mean of `x` is at most `bound`" (a zero-variance estimator,
/// such as the weights of glass, is allowed the float allowance).
fn at_most(fam: &mut Family, what: &str, x: &[f64], bound: f64) {
    let (mean, se) = mean_and_stderr(x);
    let excess = mean - bound * (1.0 + ZERO_VARIANCE_ALLOWANCE);
    let p = if excess <= 0.0 {
        1.0
    } else if se == 0.0 || !mean.is_finite() {
        0.0
    } else {
        0.5 * student_two_sided(excess / se, (x.len() - 1) as f64)
    };
    fam.p_value(what, p, format!("mean {mean} (se {se:.2e}), bound {bound}"));
}

// ---------------------------------------------------------------------------------------------
// Shading normals (Veach 1997 sec. 5.3)

/// A shading normal `angle` radians away from `ng`, turned about the frame's second axis.
fn tilted(ng: Vec3, angle: f32) -> Vec3 {
    let f = Frame::from_normal(ng);
    (ng * angle.cos() + f.s * angle.sin()).normalize()
}

/// The two normals of the shading tests: the geometric one and tilts of 0.3 and 0.7 radians.
fn shading_cases() -> Vec<Normals> {
    let ng = normals()[1];
    [0.3f32, 0.7]
        .map(|a| Normals {
            ng,
            ns: tilted(ng, a),
        })
        .to_vec()
}

/// Mitsuba 3's rule: a direction that sees different sides under the two normals is a leak.
fn same_sides(nn: Normals, w: Vec3) -> bool {
    w.dot(nn.ng) * w.dot(nn.ns) > 0.0
}

/// The pair radiance and importance transport use is one path contribution: with the cosine
/// of the geometric normal the geometry term carries, f*_shaded(a, b) |b . ng| (importance
/// arriving along a, leaving along b) equals f_shaded(b, a) |b . ng| (radiance leaving along
/// b, arriving along a), and radiance sees Mitsuba's f(b, a; ns) |a . ns| per |a . ng|.
#[test]
fn the_shaded_bsdf_and_its_adjoint_are_one_path_contribution() {
    for (k, (name, bsdf)) in models().into_iter().enumerate() {
        let mut s = sampler(700 + k as u64, 0);
        let mut nonzero = 0;
        for nn in shading_cases() {
            for _ in 0..3000 {
                let (a, b) = (
                    warp::uniform_sphere(s.next_2d()),
                    warp::uniform_sphere(s.next_2d()),
                );
                // twice the plain cut: the rough dielectric's f32 reciprocity holds to REL only
                // from about 0.1 to grazing in its (here tilted) frame
                let grazing = |w: Vec3| w.dot(nn.ng).abs().min(w.dot(nn.ns).abs()) < 2.0 * GRAZING;
                if grazing(a) || grazing(b) {
                    continue;
                }
                let imp = bsdf.eval_shaded(a, b, nn, TransportMode::Importance);
                let rad = bsdf.eval_shaded(b, a, nn, TransportMode::Radiance);
                let plain = bsdf.eval(b, a, nn.ns, TransportMode::Radiance);
                let leak = !(same_sides(nn, a) && same_sides(nn, b));
                let factor = if leak {
                    0.0
                } else {
                    (a.dot(nn.ns) / a.dot(nn.ng)).abs() as f64
                };
                for c in 0..3 {
                    let what = format!("{name}, ns {}: ({a}, {b}), channel {c}", nn.ns);
                    let (i, r) = (imp[c] as f64, rad[c] as f64);
                    assert!(close(i, r), "{what}: adjoint {i} vs radiance {r}");
                    let m = plain[c] as f64 * factor;
                    assert!(
                        close(r, m),
                        "{what}: radiance {r} vs f(ns) |a.ns|/|a.ng| {m}"
                    );
                }
                nonzero += (rad.max_element() > 0.0) as usize;
            }
        }
        if bsdf.has_regular_lobe() {
            assert!(nonzero > 200, "{name}: only {nonzero} pairs scatter");
        }
    }
}

/// A shaded sample is the shading frame's sample with Mitsuba 3's weights: in radiance mode
/// f |wi . ns| / pdf, in importance mode times |wo . ns| |wi . ng| / (|wo . ng| |wi . ns|)
/// (its particle tracer's correction), and no sample where either direction leaks.
#[test]
fn a_shaded_sample_carries_mitsubas_weights() {
    for (k, (name, bsdf)) in models().into_iter().enumerate() {
        let mut s = sampler(800 + k as u64, 0);
        for nn in shading_cases() {
            for cos_o in COS_O {
                let wo = direction(&Frame::from_normal(nn.ns), cos_o, 1.3);
                for mode in modes() {
                    for _ in 0..500 {
                        let (u, uc) = (s.next_2d(), s.next_f32());
                        let shaded = bsdf.sample_shaded(wo, nn, u, uc, mode);
                        let Some(own) = bsdf.sample(wo, nn.ns, u, uc, mode) else {
                            assert!(shaded.is_none(), "{name}: a sample from nothing");
                            continue;
                        };
                        let what = format!("{name}, {mode:?}, wo {wo}: wi {}", own.wi);
                        if !(same_sides(nn, wo) && same_sides(nn, own.wi)) {
                            assert!(shaded.is_none(), "{what}: a leak kept");
                            continue;
                        }
                        let bs = shaded.expect("a sample on the right sides");
                        assert_eq!((bs.wi, bs.pdf, bs.lobe), (own.wi, own.pdf, own.lobe));
                        let (o_s, o_g) = (wo.dot(nn.ns).abs(), wo.dot(nn.ng).abs());
                        let (i_s, i_g) = (own.wi.dot(nn.ns).abs(), own.wi.dot(nn.ng).abs());
                        let correction = match mode {
                            TransportMode::Radiance => 1.0,
                            TransportMode::Importance => (o_s * i_g / (o_g * i_s)) as f64,
                        };
                        let (got, mitsuba) = (bs.weight(nn.ng), own.weight(nn.ns));
                        for c in 0..3 {
                            let m = mitsuba[c] as f64 * correction;
                            let g = got[c] as f64;
                            assert!(close(g, m), "{what}: weight {g} vs Mitsuba's {m}");
                        }
                    }
                }
            }
        }
    }
}

/// Where the two normals are one, the shaded calls are the plain ones, bit for bit: a flat
/// scene renders as it did.
#[test]
fn flat_normals_leave_every_value_as_it_was() {
    for (k, (name, bsdf)) in models().into_iter().enumerate() {
        let mut s = sampler(900 + k as u64, 0);
        let n = normals()[1];
        let nn = Normals::flat(n);
        for _ in 0..500 {
            let (a, b) = (
                warp::uniform_sphere(s.next_2d()),
                warp::uniform_sphere(s.next_2d()),
            );
            let (u, uc) = (s.next_2d(), s.next_f32());
            for mode in modes() {
                let e = (bsdf.eval(a, b, n, mode), bsdf.eval_shaded(a, b, nn, mode));
                assert_eq!(e.0.to_array(), e.1.to_array(), "{name}");
                assert_eq!(
                    bsdf.pdf(a, b, n).to_bits(),
                    bsdf.pdf_shaded(a, b, nn).to_bits()
                );
                let pair = (
                    bsdf.sample(a, n, u, uc, mode),
                    bsdf.sample_shaded(a, nn, u, uc, mode),
                );
                assert_eq!(format!("{:?}", pair.0), format!("{:?}", pair.1), "{name}");
            }
        }
    }
}
