//! Executable specification of `src/medium/phase.rs` (book: "Phase functions").
//!
//! Contracts every phase function f_p of Pauly, Kollig, Keller 2000 eq. (1) must meet:
//! normalization over the sphere, sampling that agrees with `pdf`, `eval == pdf == sample.value`,
//! reciprocity, and the mean deflection cosine (g for Henyey-Greenstein, in the direction
//! convention of `pathspace::conventions`).

use crate::common;

use common::stats::Family;
use common::*;
use glam::{Vec2, Vec3};
use pathspace::conventions::deflection_cosine;
use pathspace::math::Frame;
use pathspace::medium::{Phase, PhaseError};
use std::f64::consts::{PI, TAU};

/// The HG asymmetries of the brief: backward, isotropic, forward, strongly forward.
const HG_G: [f32; 6] = [-0.9, -0.5, 0.0, 0.3, 0.7, 0.95];
/// Schlick parameters on both sides of zero.
const SCHLICK_K: [f32; 5] = [-0.8, -0.3, 0.0, 0.5, 0.9];

/// The phase functions under test, with a label.
fn phases() -> Vec<(String, Phase)> {
    let mut out = vec![("isotropic".to_string(), Phase::Isotropic)];
    for g in HG_G {
        out.push((format!("HG g={g}"), Phase::henyey_greenstein(g).unwrap()));
    }
    for k in SCHLICK_K {
        out.push((format!("Schlick k={k}"), Phase::schlick(k).unwrap()));
    }
    out.push(("mix".to_string(), two_lobe_mix()));
    out
}

/// A forward and a backward HG lobe (the two-term model of Pauly et al.'s scenes).
fn two_lobe_mix() -> Phase {
    Phase::mix(vec![
        (0.7, Phase::henyey_greenstein(0.8).unwrap()),
        (0.3, Phase::henyey_greenstein(-0.4).unwrap()),
    ])
    .unwrap()
}

/// An upper bound of |d^4 f / d mu^4| on [-1, 1] for the density over mu = cos theta,
/// p(mu) = 2 pi f_p(mu), used to bound Simpson's error analytically.
fn fourth_derivative_bound(phase: &Phase) -> f64 {
    match phase {
        Phase::Isotropic => 0.0,
        Phase::HenyeyGreenstein { g } => {
            // p = (1 - g^2) / 2 (a - b mu)^(-3/2), a = 1 + g^2, b = 2g; min(a - b mu) = (1-|g|)^2
            let g = *g as f64;
            let (b, m) = (2.0 * g.abs(), (1.0 - g.abs()).powi(2));
            (1.0 - g * g) / 2.0 * (1.5 * 2.5 * 3.5 * 4.5) * b.powi(4) * m.powf(-5.5)
        }
        Phase::Schlick { k } => {
            // p = (1 - k^2) / 2 (1 - k mu)^(-2); min(1 - k mu) = 1 - |k|
            let k = *k as f64;
            (1.0 - k * k) / 2.0 * (2.0 * 3.0 * 4.0 * 5.0) * k.powi(4) * (1.0 - k.abs()).powi(-6)
        }
        Phase::Mix(lobes) => lobes
            .iter()
            .map(|(w, p)| *w as f64 * fourth_derivative_bound(p))
            .sum(),
    }
}

/// The relative error of one f32 evaluation of f_p: a handful of roundings of order-one terms
/// (the HG denominator, its square root, the division).
const F32_EVAL_REL_ERROR: f64 = 16.0 * f32::EPSILON as f64;

/// A frame whose normal is the forward direction of light leaving along `wo`, i.e. `-wo`
/// (built here with Gram-Schmidt, independently of `Frame::from_normal`).
fn deflection_frame(wo: Vec3) -> Frame {
    let n = -wo;
    let a = if n.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let s = (a - n * n.dot(a)).normalize();
    Frame {
        s,
        t: n.cross(s),
        n,
    }
}

/// The largest |d ln p / d mu| on [-1, 1]: how much a rounding of the deflection cosine
/// changes f_p relatively.
fn log_slope_bound(phase: &Phase) -> f64 {
    match phase {
        Phase::Isotropic => 0.0,
        Phase::HenyeyGreenstein { g } => {
            let g = *g as f64;
            1.5 * 2.0 * g.abs() / (1.0 - g.abs()).powi(2)
        }
        Phase::Schlick { k } => {
            let k = *k as f64;
            2.0 * k.abs() / (1.0 - k.abs())
        }
        Phase::Mix(lobes) => lobes
            .iter()
            .map(|(_, p)| log_slope_bound(p))
            .fold(0.0, f64::max),
    }
}

/// The absolute error of the deflection cosine -dot(wo, wi) of an f32 direction built from
/// (mu, phi): the f32 casts of the local coordinates, the frame's own rounding, the change of
/// frame and the dot product, a few roundings each of order-one terms.
const MU_ROUNDING: f64 = 8.0 * f32::EPSILON as f64;

/// Simpson sub-intervals over mu; with the fourth-derivative bound the error of the strongest
/// lobe (HG g = 0.95) is about 1e-7.
const N_MU: usize = 1 << 18;

/// Simpson sub-intervals over mu for the (slower) integral over world directions; its bound
/// for HG g = 0.95 is about 1e-4, of the order of the propagated rounding of f32 directions.
const N_MU_SPHERE: usize = 1 << 16;

/// Simpson's error bound (b - a) h^4 max |p^(4)| / 180 on [-1, 1] with `N_MU` intervals.
fn simpson_bound(phase: &Phase) -> f64 {
    simpson_bound_with(phase, N_MU)
}

/// Simpson's error bound with `n` intervals.
fn simpson_bound_with(phase: &Phase, n: usize) -> f64 {
    let h = 2.0 / n as f64;
    2.0 * h.powi(4) * fourth_derivative_bound(phase) / 180.0
}

#[test]
fn every_phase_function_integrates_to_one_over_the_deflection_cosine() {
    // 2 pi int f_p(mu) dmu = 1. The f32 rounding of each mu node is to nearest and averages
    // out over 2^18 nodes, so only the evaluation error and Simpson's bound remain.
    for (name, phase) in phases() {
        let integral = simpson(|mu| TAU * phase.eval_cos(mu as f32) as f64, -1.0, 1.0, N_MU);
        let tol = simpson_bound(&phase) + F32_EVAL_REL_ERROR;
        assert!(
            (integral - 1.0).abs() <= tol,
            "{name}: got integral {integral}, expected 1 (tolerance {tol:e})"
        );
    }
}

#[test]
fn every_phase_function_integrates_to_one_over_the_sphere() {
    // The same integral of eval(wo, wi) over world directions around several wo: Simpson in
    // mu = cos theta relative to -wo, the periodic trapezoid rule in phi (exact for a
    // phi-independent integrand). The directions are f32, so the tolerance adds the
    // propagated rounding of mu, MU_ROUNDING * max |d ln p / d mu|.
    const N_PHI: usize = 4;
    for wo in test_directions(1, 0).into_iter().take(3) {
        let frame = deflection_frame(wo);
        for (name, phase) in phases() {
            let integral = simpson(
                |mu| {
                    (0..N_PHI)
                        .map(|j| {
                            let wi = direction(&frame, mu, TAU * j as f64 / N_PHI as f64);
                            phase.eval(wo, wi) as f64
                        })
                        .sum::<f64>()
                        * (TAU / N_PHI as f64)
                },
                -1.0,
                1.0,
                N_MU_SPHERE,
            );
            let tol = simpson_bound_with(&phase, N_MU_SPHERE)
                + F32_EVAL_REL_ERROR
                + MU_ROUNDING * log_slope_bound(&phase);
            assert!(
                (integral - 1.0).abs() <= tol,
                "{name}, wo {wo}: integral {integral}, tolerance {tol:e}"
            );
        }
    }
}

#[test]
fn eval_equals_pdf_equals_sample_value_and_is_reciprocal() {
    let mut s = sampler(2, 0);
    for (name, phase) in phases() {
        for wo in test_directions(2, 4) {
            for _ in 0..64 {
                let wi = pathspace::math::warp::uniform_sphere(s.next_2d());
                let f = phase.eval(wo, wi);
                assert!(f.is_finite() && f >= 0.0, "{name}: f_p = {f}");
                assert_eq!(f, phase.pdf(wo, wi), "{name}: eval != pdf");
                assert_eq!(f, phase.eval(wi, wo), "{name}: not reciprocal");
                let ps = phase.sample(wo, s.next_2d());
                assert_close(
                    &format!("{name}: |wi|"),
                    ps.wi.length() as f64,
                    1.0,
                    F32_EVAL_REL_ERROR,
                );
                assert_eq!(ps.value, ps.pdf, "{name}: value != pdf");
                assert_eq!(ps.value, phase.eval(wo, ps.wi), "{name}: value != eval");
            }
        }
    }
}

#[test]
fn sampling_agrees_with_pdf_by_chi_square() {
    const N_SAMPLES: u64 = 200_000;
    const N_COS: usize = 40;
    const N_PHI: usize = 16;
    let wos = [Vec3::Z, -Vec3::Z, Vec3::new(0.3, -0.5, 0.8).normalize()];
    let mut fam = Family::new("phase: sampling vs pdf");
    for (i, (name, phase)) in phases().into_iter().enumerate() {
        for (j, &wo) in wos.iter().enumerate() {
            let mut grid = SphereGrid::new(deflection_frame(wo), N_COS, N_PHI);
            // f_p does not depend on phi in this frame: Simpson's rule in phi is exact
            grid.quad_phi = 2;
            grid.quad_cos = 128;
            let mut s = sampler(3, (i * wos.len() + j) as u64);
            chi_square_sphere(
                &mut fam,
                &format!("{name}, wo {wo}"),
                &grid,
                || Some(phase.sample(wo, s.next_2d()).wi),
                |wi| phase.pdf(wo, wi) as f64,
                N_SAMPLES,
            );
        }
    }
    fam.finish();
}

#[test]
fn hg_with_zero_asymmetry_is_isotropic() {
    let hg = Phase::henyey_greenstein(0.0).unwrap();
    let mut s = sampler(4, 0);
    for wo in test_directions(4, 8) {
        for _ in 0..64 {
            let u = s.next_2d();
            let a = hg.sample(wo, u);
            let b = Phase::Isotropic.sample(wo, u);
            assert_eq!(a.value, Phase::Isotropic.eval(wo, a.wi));
            assert!((a.wi - b.wi).length() <= F32_EVAL_REL_ERROR as f32);
        }
    }
}

/// The mean deflection cosine of `n` samples equals `truth` (a comparison of `fam`).
fn sampled_mean_cosine_is(
    fam: &mut Family,
    what: &str,
    phase: &Phase,
    wo: Vec3,
    seed: u64,
    n: usize,
    truth: f64,
) {
    let mut s = sampler(seed, 0);
    let cosines: Vec<f64> = (0..n)
        .map(|_| deflection_cosine(wo, phase.sample(wo, s.next_2d()).wi) as f64)
        .collect();
    let (mean, se) = mean_and_stderr(&cosines);
    fam.mean_is(what, mean, se, (n - 1) as f64, truth);
}

#[test]
fn hg_mean_deflection_cosine_is_g() {
    const N: usize = 200_000;
    let wo = Vec3::new(-0.2, 0.9, 0.1).normalize();
    let mut fam = Family::new("phase: HG mean cosine");
    for (i, g) in HG_G.into_iter().enumerate() {
        let phase = Phase::henyey_greenstein(g).unwrap();
        let what = format!("HG g={g}");
        sampled_mean_cosine_is(&mut fam, &what, &phase, wo, 50 + i as u64, N, g as f64);
        assert_eq!(phase.mean_cosine(), g);
    }
    fam.finish();
}

/// Mean cosine by quadrature of mu p(mu), p(mu) = 2 pi f_p(mu), in f64 on f32 evaluations.
fn quadrature_mean_cosine(phase: &Phase) -> f64 {
    const N_MU: usize = 1 << 16;
    simpson(
        |mu| mu * 2.0 * PI * phase.eval_cos(mu as f32) as f64,
        -1.0,
        1.0,
        N_MU,
    )
}

#[test]
fn schlick_and_mix_mean_cosine_matches_quadrature_and_samples() {
    const N: usize = 200_000;
    // quadrature tolerance: the Simpson bound for mu p(mu) is of the same order as the
    // normalization test's; with 2^16 intervals and |k| <= 0.9 it is below 1e-6.
    const QUAD_TOL: f64 = 1e-5;
    let wo = Vec3::new(0.5, 0.5, -0.7).normalize();
    let mut cases: Vec<(String, Phase)> = SCHLICK_K
        .into_iter()
        .map(|k| (format!("Schlick k={k}"), Phase::schlick(k).unwrap()))
        .collect();
    cases.push(("mix".into(), two_lobe_mix()));
    // a near-zero k exercises the series branch of the closed form
    cases.push(("Schlick k=1e-5".into(), Phase::schlick(1e-5).unwrap()));
    let mut fam = Family::new("phase: Schlick and mix mean cosine");
    for (i, (name, phase)) in cases.into_iter().enumerate() {
        let closed = phase.mean_cosine() as f64;
        assert_close(
            &format!("{name}: mean_cosine() vs quadrature"),
            closed,
            quadrature_mean_cosine(&phase),
            QUAD_TOL,
        );
        sampled_mean_cosine_is(&mut fam, &name, &phase, wo, 70 + i as u64, N, closed);
    }
    fam.finish();
}

#[test]
fn constructors_reject_invalid_parameters() {
    for g in [1.0, -1.0, 1.5, f32::NAN, f32::INFINITY] {
        assert!(
            matches!(
                Phase::henyey_greenstein(g),
                Err(PhaseError::HgOutOfRange(_))
            ),
            "g = {g} accepted"
        );
    }
    for k in [1.0, -1.0, -2.0, f32::NAN, f32::NEG_INFINITY] {
        assert!(
            matches!(Phase::schlick(k), Err(PhaseError::SchlickOutOfRange(_))),
            "k = {k} accepted"
        );
    }
    assert_eq!(Phase::mix(vec![]), Err(PhaseError::EmptyMix));
    for weights in [
        vec![-0.5, 1.5],
        vec![0.0, 0.0],
        vec![f32::NAN, 1.0],
        vec![f32::INFINITY, 1.0],
    ] {
        let lobes = weights.iter().map(|&w| (w, Phase::Isotropic)).collect();
        assert!(
            matches!(Phase::mix(lobes), Err(PhaseError::BadMixWeights(_))),
            "weights {weights:?} accepted"
        );
    }
    // accepted values, and mix weights normalized to sum to one
    assert!(Phase::henyey_greenstein(0.999).is_ok());
    assert!(Phase::schlick(-0.999).is_ok());
    let Phase::Mix(lobes) =
        Phase::mix(vec![(2.0, Phase::Isotropic), (6.0, Phase::Isotropic)]).unwrap()
    else {
        panic!("mix() did not build a Mix")
    };
    assert_eq!(lobes[0].0, 0.25);
    assert_eq!(lobes[1].0, 0.75);
}

#[test]
fn mix_with_a_zero_weight_lobe_never_samples_it() {
    // the zero-weight lobe is a strongly backward HG; samples must follow the forward lobe only
    let forward = Phase::henyey_greenstein(0.9).unwrap();
    let mix = Phase::mix(vec![
        (0.0, Phase::henyey_greenstein(-0.9).unwrap()),
        (1.0, forward.clone()),
    ])
    .unwrap();
    let mut s = sampler(9, 0);
    let wo = Vec3::Z;
    // u.x = 0 is where a first zero-weight lobe's interval [0, 0) begins and ends: an
    // inclusive bound there would pick it. Every HG and Schlick lobe maps u = 0 to the same
    // backward direction, the isotropic lobe to the forward one, so a zero-weight isotropic
    // lobe in front shows the choice.
    let iso_first = Phase::mix(vec![(0.0, Phase::Isotropic), (1.0, forward.clone())]).unwrap();
    for i in 0..=8 {
        let u = Vec2::new(0.0, i as f32 / 8.0 * 0.999);
        let (a, b) = (iso_first.sample(wo, u), forward.sample(wo, u));
        assert!(
            (a.wi - b.wi).length() < 1e-5,
            "u = {u}: {:?} vs {:?}",
            a.wi,
            b.wi
        );
    }
    for u in (0..10_000).map(|_| s.next_2d()) {
        let a = mix.sample(wo, u);
        let b = forward.sample(wo, Vec2::new(u.x, u.y));
        assert!((a.wi - b.wi).length() < 1e-5, "{:?} vs {:?}", a.wi, b.wi);
    }
}

/// The convention of `conventions.rs`: wo and wi both point away from the vertex, so light that
/// arrives along -wi and leaves along wo is undeflected when wo = -wi (cosine 1) and sent back
/// when wo = wi (cosine -1); in general the cosine is that of the angle between -wi and wo.
#[test]
fn the_deflection_cosine_follows_the_convention() {
    for (k, wo) in test_directions(0xdef1, 32).into_iter().enumerate() {
        let wi = test_directions(0xdef2 + k as u64, 1)[0];
        assert_close("forward", deflection_cosine(wo, -wo) as f64, 1.0, 1e-6);
        assert_close("backward", deflection_cosine(wo, wo) as f64, -1.0, 1e-6);
        let propagation_before = -wi;
        assert_close(
            "general",
            deflection_cosine(wo, wi) as f64,
            propagation_before.dot(wo) as f64,
            1e-6,
        );
    }
}

/// Henyey-Greenstein against its textbook form, evaluated in f64:
/// p(mu) = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2)), forward (mu = 1) for g > 0.
#[test]
fn hg_matches_its_closed_form() {
    for g in [-0.9f64, -0.3, 0.0, 0.2, 0.7, 0.95] {
        let phase = Phase::henyey_greenstein(g as f32).unwrap();
        for i in 0..=40 {
            let mu = -1.0 + 2.0 * i as f64 / 40.0;
            let truth = (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5));
            let value = phase.eval_cos(mu as f32) as f64;
            assert!(
                (value - truth).abs() <= 1e-5 * truth,
                "HG g = {g}, mu = {mu}: got {value}, expected {truth}"
            );
        }
    }
}
