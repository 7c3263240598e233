//! Phase functions f_p (Pauly, Kollig, Keller 2000, eq. 1; Kristensen 2010 sec. 2.6.2).
//!
//! Convention (see `conventions`): `wo` and `wi` both point away from the scattering point. Light
//! arrives travelling along `-wi` and leaves along `wo`, so the deflection cosine is
//! `cos_theta = -dot(wo, wi)`; with g > 0 Henyey-Greenstein scatters forwards.
//!
//! Every model is sampled exactly (inverse CDF of the deflection cosine, lobe selection for
//! mixtures), so `pdf == eval` and `PhaseSample::value == PhaseSample::pdf`.
//!
//! Book: "Phase functions" (`book/src/phase-functions.md`), with the derivations of the inverse
//! CDFs and of Schlick's mean cosine; executable spec: `tests/spec/medium/phase.rs`.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

use crate::math::{warp, Frame};

/// Why a phase function was rejected.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PhaseError {
    #[error("Henyey-Greenstein g = {0} is outside (-1, 1)")]
    HgOutOfRange(f32),
    #[error("Schlick k = {0} is outside (-1, 1)")]
    SchlickOutOfRange(f32),
    #[error("mix weights must be non-negative with a positive sum, got {0:?}")]
    BadMixWeights(Vec<f32>),
    #[error("a mix needs at least one lobe")]
    EmptyMix,
}

/// A phase function: the closed set the scene format offers.
#[derive(Clone, Debug, PartialEq)]
pub enum Phase {
    /// 1 / (4 pi).
    Isotropic,
    /// Henyey-Greenstein with mean cosine `g`, |g| < 1.
    HenyeyGreenstein { g: f32 },
    /// Schlick's rational approximation of HG, (1 - k^2) / (4 pi (1 - k cos)^2), |k| < 1.
    Schlick { k: f32 },
    /// A convex combination of lobes, the phase model Pauly et al. use; weights sum to 1.
    Mix(Vec<(f32, Phase)>),
}

/// A sampled incident direction with the phase value and the pdf (solid angle) that produced it.
#[derive(Clone, Copy, Debug)]
pub struct PhaseSample {
    pub wi: Vec3,
    /// f_p(wo, wi).
    pub value: f32,
    /// Solid-angle density of `wi`.
    pub pdf: f32,
}

impl Phase {
    /// What `pathspace info` says of it (`Henyey-Greenstein g = 0.5`).
    pub fn describe(&self) -> String {
        match self {
            Phase::Isotropic => "isotropic".into(),
            Phase::HenyeyGreenstein { g } => format!("Henyey-Greenstein g = {g}"),
            Phase::Schlick { k } => format!("Schlick k = {k}"),
            Phase::Mix(lobes) => {
                let parts: Vec<String> = lobes
                    .iter()
                    .map(|(w, l)| format!("{} x {}", crate::spectrum::round3(*w), l.describe()))
                    .collect();
                format!("mix of {}", parts.join(" + "))
            }
        }
    }

    /// Henyey-Greenstein, validated.
    pub fn henyey_greenstein(g: f32) -> Result<Self, PhaseError> {
        if g.is_finite() && g.abs() < 1.0 {
            Ok(Phase::HenyeyGreenstein { g })
        } else {
            Err(PhaseError::HgOutOfRange(g))
        }
    }

    /// Schlick, validated.
    pub fn schlick(k: f32) -> Result<Self, PhaseError> {
        if k.is_finite() && k.abs() < 1.0 {
            Ok(Phase::Schlick { k })
        } else {
            Err(PhaseError::SchlickOutOfRange(k))
        }
    }

    /// A mix (the in-scattering term of [PKK00 eq. 1] with a convex combination of lobes);
    /// weights must be finite and non-negative with a positive sum, and are normalized to one.
    pub fn mix(lobes: Vec<(f32, Phase)>) -> Result<Self, PhaseError> {
        if lobes.is_empty() {
            return Err(PhaseError::EmptyMix);
        }
        let total: f32 = lobes.iter().map(|l| l.0).sum();
        if lobes.iter().any(|l| !l.0.is_finite() || l.0 < 0.0) || total.is_nan() || total <= 0.0 {
            return Err(PhaseError::BadMixWeights(
                lobes.iter().map(|l| l.0).collect(),
            ));
        }
        Ok(Phase::Mix(
            lobes.into_iter().map(|(w, p)| (w / total, p)).collect(),
        ))
    }

    /// The phase function as a function of the deflection cosine mu = cos theta
    /// (Kristensen 2010 sec. 2.6.2 for HG; Schlick's rational approximation of it).
    ///
    /// Both denominators are written so that they never cancel near the lobe's peak: for HG,
    /// 1 + g^2 - 2 g mu = (1 - |g|)^2 + 2 |g| (1 - sign(g) mu), a sum of two non-negative terms
    /// (the textbook form loses the rounding of 1 + g^2, about 1e-7, against a denominator of
    /// (1 - g)^2 = 0.0025 at g = 0.95, a systematic 1e-5 error of the normalization); likewise
    /// 1 - k mu = (1 - |k|) + |k| (1 - sign(k) mu).
    // ANCHOR: phase_eval
    pub fn eval_cos(&self, cos_theta: f32) -> f32 {
        match self {
            Phase::Isotropic => warp::INV_FOUR_PI,
            Phase::HenyeyGreenstein { g } => {
                // ASSIGNMENT: hg_eval
                // 1 + g^2 - 2 g mu, without cancellation
                let a = 1.0 - g.abs();
                let denom = a * a + 2.0 * g.abs() * (1.0 - g.signum() * cos_theta);
                warp::INV_FOUR_PI * (1.0 - g * g) / (denom * denom.max(0.0).sqrt())
                // END ASSIGNMENT
            }
            Phase::Schlick { k } => {
                // 1 - k mu, without cancellation
                let d = (1.0 - k.abs()) + k.abs() * (1.0 - k.signum() * cos_theta);
                warp::INV_FOUR_PI * (1.0 - k * k) / (d * d)
            }
            Phase::Mix(lobes) => lobes.iter().map(|(w, p)| w * p.eval_cos(cos_theta)).sum(),
        }
    }
    // ANCHOR_END: phase_eval

    /// f_p(wo, wi), both directions pointing away from the vertex.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_cos(-wo.dot(wi))
    }

    /// Every phase function here is sampled exactly, so the pdf equals the value.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval(wo, wi)
    }

    /// Samples `wi` given `wo` with density proportional to f_p.
    pub fn sample(&self, wo: Vec3, u: Vec2) -> PhaseSample {
        let wi = match self {
            Phase::Mix(lobes) => {
                // pick a lobe with u.x, reuse the remainder
                let mut acc = 0.0;
                let mut chosen = &lobes[lobes.len() - 1];
                let mut rem = u.x;
                for lobe in lobes {
                    if u.x < acc + lobe.0 || std::ptr::eq(lobe, &lobes[lobes.len() - 1]) {
                        chosen = lobe;
                        rem = ((u.x - acc) / lobe.0.max(f32::MIN_POSITIVE))
                            .clamp(0.0, crate::math::distribution::ONE_MINUS_EPSILON);
                        break;
                    }
                    acc += lobe.0;
                }
                chosen.1.sample(wo, Vec2::new(rem, u.y)).wi
            }
            _ => {
                let cos_theta = self.sample_cos(u.x);
                let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                // deflection measured from the propagation direction -wo... of the light arriving
                // along -wi: wi = -(direction light continues) rotated; build around -wo.
                let frame = Frame::from_normal(-wo);
                frame.to_world(Vec3::new(
                    sin_theta * phi.cos(),
                    sin_theta * phi.sin(),
                    cos_theta,
                ))
            }
        };
        let value = self.eval(wo, wi);
        PhaseSample {
            wi,
            value,
            pdf: value,
        }
    }

    /// Inverts the CDF of the deflection cosine of a single lobe (derivations in the book,
    /// chapter "Phase functions"). Computed in f64: the HG inverse divides by 2g, so in f32 its
    /// rounding grows as 1/g near g = 0.
    // ANCHOR: phase_sample_cos
    fn sample_cos(&self, u: f32) -> f32 {
        let u = u as f64;
        let cos_theta = match *self {
            Phase::Isotropic => 1.0 - 2.0 * u,
            Phase::HenyeyGreenstein { g } => {
                // ASSIGNMENT: hg_sample
                let g = g as f64;
                if g.abs() < HG_ISOTROPIC_LIMIT {
                    1.0 - 2.0 * u
                } else {
                    // mu = (1 + g^2 - s^2) / (2g), s = (1 - g^2) / (1 - g + 2 g u)
                    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
                    (1.0 + g * g - s * s) / (2.0 * g)
                }
                // END ASSIGNMENT
            }
            Phase::Schlick { k } => {
                // mu = (2u - 1 + k) / (2 k u + 1 - k)
                let k = k as f64;
                (2.0 * u - 1.0 + k) / (2.0 * k * u + 1.0 - k)
            }
            Phase::Mix(_) => unreachable!("mixtures are sampled lobe by lobe"),
        };
        (cos_theta as f32).clamp(-1.0, 1.0)
    }
    // ANCHOR_END: phase_sample_cos

    /// The mean deflection cosine, the integral of mu p(mu) over [-1, 1] (g for HG), per lobe.
    ///
    /// For Schlick's lobe, p(mu) = (1 - k^2) / (2 (1 - k mu)^2) and the substitution
    /// v = 1 - k mu gives 1/k - (1 - k^2) / (2 k^2) ln((1 + k) / (1 - k)), which behaves as
    /// 2k/3 (forward for k > 0, like HG's g). Below `SCHLICK_SERIES_LIMIT` the two terms
    /// cancel, so the series 2k/3 + 2k^3/15 is used.
    // ANCHOR: phase_mean_cosine
    pub fn mean_cosine(&self) -> f32 {
        match self {
            Phase::Isotropic => 0.0,
            Phase::HenyeyGreenstein { g } => *g,
            Phase::Schlick { k } => {
                let k = *k as f64;
                let v = if k.abs() < SCHLICK_SERIES_LIMIT {
                    2.0 * k / 3.0 + 2.0 * k * k * k / 15.0
                } else {
                    1.0 / k - (1.0 - k * k) / (2.0 * k * k) * ((1.0 + k) / (1.0 - k)).ln()
                };
                v as f32
            }
            Phase::Mix(lobes) => lobes.iter().map(|(w, p)| w * p.mean_cosine()).sum(),
        }
    }
    // ANCHOR_END: phase_mean_cosine
}

/// Below this |g| the HG inversion is replaced by the isotropic one. The f64 inversion divides
/// rounding errors of about 1e-16 by 2g, so at this g it is still accurate to 1e-8, below f32
/// resolution near 1 (6e-8); the isotropic sample's density differs from HG's by a relative
/// 3|g| = 3e-8, below f32 resolution too.
const HG_ISOTROPIC_LIMIT: f64 = 1e-8;

/// Below this |k| the closed-form Schlick mean cosine is replaced by its series 2k/3 + 2k^3/15:
/// the closed form subtracts two terms of size 1/|k| in f64 (relative rounding 1e-16 / k^2),
/// while the series' first omitted term, of order k^5, is below 1e-20 here.
const SCHLICK_SERIES_LIMIT: f64 = 1e-4;
