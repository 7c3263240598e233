//! The rough plastic: a diffuse base under a rough dielectric coating, as Mitsuba 3's
//! `roughplastic` evaluates it. Two regular lobes on the normal's side:
//!
//! * the coating's glossy reflection, Walter et al. 2007, eq. (20), with the dielectric
//!   Fresnel term F(wo.h, eta) of the half vector h, scaled by `specular`;
//! * the base's diffuse reflection, rho T(cos_o) T(cos_i) / (pi eta^2 (1 - R_i)) (R_i rho with
//!   `nonlinear`), where T(mu) is the fraction of light arriving at cosine mu that the rough
//!   interface transmits (its directional albedo of transmission, single scattering), and R_i
//!   the interface's reflection albedo seen from inside, averaged over the cosine-weighted
//!   hemisphere: light the base sends up is reflected back down R_i of the time, and the
//!   geometric series of those bounces gives 1 / (1 - R_i). The 1 / eta^2 is the radiance
//!   compression of the light leaving the denser side.
//!
//! T and R_i have no closed form. Mitsuba tabulates T at 64 cosines mu_j = max(1e-6, j / 63),
//! interpolated linearly, and takes R_i as twice the plain mean of R(mu_j) mu_j over the same
//! 64 cosines; that table and that mean are part of the model it renders, so pathspace keeps
//! them and computes each node's integral by adaptive Gauss-Kronrod quadrature (error well
//! below 1e-6) where Mitsuba uses a 32 x 32 (T) or 128 x 128 (R) Gauss-Legendre rule over
//! its visible-normal sampler. The exact cosine-weighted integral of R differs from the
//! 64-node mean by about 1e-2 (`tests/spec/bsdf/rough_plastic.rs` prints both).
//!
//! Sampling: a mixture of the coating's facet sampler (`Microfacet::sample`, reflected) and the
//! cosine-weighted hemisphere, with Mitsuba's lobe probability (1 - T(cos_o)) s / ((1 -
//! T(cos_o)) s + T(cos_o) d), s and d the mean specular and diffuse colours, and the exact
//! mixture density. Reflection only, so it is reciprocal; two-sided unless `one_sided`
//! (Mitsuba's plugin is one-sided: black behind the normal).

use std::f64::consts::PI as PI64;
use std::sync::Arc;

use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

use super::microfacet::{reflect_about, refract_about, Beckmann, Distribution, Ggx, Microfacet};
use super::{fresnel_dielectric, BsdfModel, BsdfSample, Lobe, TransportMode};
use crate::math::{warp, Frame};
use crate::spectrum::Rgb;

/// The number of cosines of Mitsuba's tables (its `MI_ROUGH_TRANSMITTANCE_RES`).
pub const TABLE_SIZE: usize = 64;

/// The coating's two integrals, computed once per material.
#[derive(Clone, Debug, PartialEq)]
pub struct Tables {
    /// T(mu_j), the interface's transmission albedo from outside, at mu_j = max(1e-6, j / 63).
    pub transmittance: [f32; TABLE_SIZE],
    /// R_i: twice the mean of R(mu_j) mu_j, R the reflection albedo from inside.
    pub internal_reflectance: f32,
}

/// A rough plastic; build it with [`RoughPlastic::new`], which computes its tables.
#[derive(Clone, Debug, PartialEq)]
pub struct RoughPlastic {
    pub microfacet: Microfacet,
    /// Index inside over outside (Mitsuba's int_ior / ext_ior).
    pub eta: f32,
    pub diffuse: Rgb,
    pub specular: Rgb,
    /// Divide by 1 - rho R_i rather than 1 - R_i (Mitsuba's `nonlinear`).
    pub nonlinear: bool,
    /// Black behind the normal (see `Bsdf::black_behind`).
    pub one_sided: bool,
    tables: Arc<Tables>,
    /// The specular lobe's share s / (s + d) of the sampling weights.
    specular_weight: f32,
}

impl RoughPlastic {
    pub fn new(
        microfacet: Microfacet,
        eta: f32,
        diffuse: Rgb,
        specular: Rgb,
        nonlinear: bool,
        one_sided: bool,
    ) -> Self {
        let (s, d) = (specular.element_sum() / 3.0, diffuse.element_sum() / 3.0);
        let specular_weight = if s + d > 0.0 { s / (s + d) } else { 0.5 };
        RoughPlastic {
            microfacet,
            eta,
            diffuse,
            specular,
            nonlinear,
            one_sided,
            tables: Arc::new(tables(microfacet, eta as f64)),
            specular_weight,
        }
    }

    pub fn tables(&self) -> &Tables {
        &self.tables
    }

    /// T(mu), linearly interpolated between the table's cosines as Mitsuba does.
    pub fn transmittance(&self, mu: f32) -> f32 {
        let x = mu.clamp(0.0, 1.0) * (TABLE_SIZE - 1) as f32;
        let j = (x as usize).min(TABLE_SIZE - 2);
        let t = &self.tables.transmittance;
        let s = x - j as f32;
        t[j] + (t[j + 1] - t[j]) * s
    }

    /// `wo` and `wi` in the frame of the normal on `wo`'s side, both above it, or `None`.
    fn local(wo: Vec3, wi: Vec3, n: Vec3) -> Option<(Vec3, Vec3)> {
        let nf = if wo.dot(n) >= 0.0 { n } else { -n };
        let frame = Frame::from_normal(nf);
        let (lo, li) = (frame.to_local(wo), frame.to_local(wi));
        (lo.z > 0.0 && li.z > 0.0).then_some((lo, li))
    }

    /// The probability of the specular lobe at `cos_o` (Mitsuba's choice).
    fn specular_probability(&self, cos_o: f32) -> f32 {
        let t = self.transmittance(cos_o);
        let s = (1.0 - t) * self.specular_weight;
        let d = t * (1.0 - self.specular_weight);
        if s + d > 0.0 {
            s / (s + d)
        } else {
            0.5
        }
    }
}

impl BsdfModel for RoughPlastic {
    fn albedo(&self, cos: f32) -> Rgb {
        super::coated_albedo(self.diffuse, self.specular, self.eta, cos)
    }

    fn describe(&self) -> String {
        format!(
            "rough plastic, diffuse {}, specular {}, ior {}, {} alpha {}{} (internal reflectance {:.4}, transmittance at normal incidence {:.4})",
            crate::spectrum::show(self.diffuse),
            crate::spectrum::show(self.specular),
            self.eta,
            self.microfacet.distribution.name(),
            self.microfacet.alpha,
            if self.nonlinear { ", nonlinear" } else { "" },
            self.tables().internal_reflectance,
            self.transmittance(1.0)
        )
    }

    fn has_regular_lobe(&self) -> bool {
        true
    }
    fn has_dirac_lobe(&self) -> bool {
        false
    }
    fn transmits(&self) -> bool {
        false
    }
    fn one_sided(&self) -> bool {
        self.one_sided
    }

    /// f_s(wo, wi): the coating's reflection plus the base seen through it (module note).
    // ANCHOR: rough_plastic_eval
    fn eval(&self, wo: Vec3, wi: Vec3, n: Vec3, _mode: TransportMode) -> Rgb {
        let Some((lo, li)) = Self::local(wo, wi, n) else {
            return Rgb::ZERO;
        };
        let mut value = Rgb::ZERO;
        let h = (lo + li).normalize_or_zero();
        if h != Vec3::ZERO {
            let g = self.microfacet;
            let f = fresnel_dielectric(lo.dot(h), self.eta);
            let spec = f * g.d(h) * g.g(lo, li, h) / (4.0 * lo.z * li.z);
            if spec.is_finite() {
                value += self.specular * spec;
            }
        }
        let r_i = self.tables.internal_reflectance;
        let kept = if self.nonlinear {
            Rgb::ONE - self.diffuse * r_i
        } else {
            Rgb::splat(1.0 - r_i)
        };
        let through = self.transmittance(lo.z) * self.transmittance(li.z);
        value + self.diffuse / kept * (through * FRAC_1_PI / (self.eta * self.eta))
    }
    // ANCHOR_END: rough_plastic_eval

    /// The density of `wi` under [`RoughPlastic::sample`]: p_s times the facet density over
    /// the reflection's Jacobian 4 wo.h (Walter et al. 2007, eq. (14)), plus (1 - p_s) cos_i /
    /// pi.
    fn pdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        let Some((lo, li)) = Self::local(wo, wi, n) else {
            return 0.0;
        };
        let p_s = self.specular_probability(lo.z);
        let h = (lo + li).normalize_or_zero();
        let c = lo.dot(h);
        let facet = if c > 0.0 {
            self.microfacet.pdf(lo, h) / (4.0 * c)
        } else {
            0.0
        };
        let facet = if facet.is_finite() { facet } else { 0.0 };
        p_s * facet + (1.0 - p_s) * li.z * FRAC_1_PI
    }

    /// The specular lobe when `uc` < p_s (a facet normal from `u`, `wo` reflected about it),
    /// else the cosine-weighted hemisphere; value and density from the pair, so that they are
    /// `eval` and `pdf` exactly. `None` when the reflection points under the surface.
    fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        u: Vec2,
        uc: f32,
        mode: TransportMode,
    ) -> Option<BsdfSample> {
        let nf = if wo.dot(n) >= 0.0 { n } else { -n };
        let frame = Frame::from_normal(nf);
        let lo = frame.to_local(wo);
        if lo.z <= 0.0 {
            return None;
        }
        let li = if uc < self.specular_probability(lo.z) {
            let m = self.microfacet.sample(lo, u);
            // a facet seen from behind reflects nowhere (its mass is missing from the
            // density, which counts only the facets `wo` sees)
            if lo.dot(m) <= 0.0 {
                return None;
            }
            reflect_about(lo, m)
        } else {
            warp::cosine_hemisphere(u)
        };
        if li.z <= 0.0 {
            return None;
        }
        let wi = frame.to_world(li);
        let pdf = self.pdf(wo, wi, n);
        let value = self.eval(wo, wi, n, mode);
        (pdf > 0.0 && value.is_finite()).then_some(BsdfSample {
            wi,
            value,
            pdf,
            lobe: Lobe::Regular,
        })
    }
}

/// The cosine of table node `j`.
pub fn table_cosine(j: usize) -> f64 {
    (j as f64 / (TABLE_SIZE - 1) as f64).max(1e-6)
}

/// Both tables of a coating with index ratio `eta` (inside over outside).
fn tables(g: Microfacet, eta: f64) -> Tables {
    let mut transmittance = [0.0f32; TABLE_SIZE];
    let mut sum = 0.0;
    for (j, t) in transmittance.iter_mut().enumerate() {
        let mu = table_cosine(j);
        *t = interface_albedo(g, mu, eta, Albedo::Transmission) as f32;
        sum += interface_albedo(g, mu, 1.0 / eta, Albedo::Reflection) * mu;
    }
    Tables {
        transmittance,
        internal_reflectance: (2.0 * sum / TABLE_SIZE as f64) as f32,
    }
}

/// Smith's exact G1 of `w` at the macro normal, 1 / (1 + Lambda(w)): the visible-normal
/// density's normalization (Heitz 2018, eq. 1). Beckmann's is the erf form, not the rational
/// approximation the BSDF evaluates, because Mitsuba's tables integrate over its exact
/// visible-normal sampler.
fn g1_exact(g: Microfacet, w: Vec3) -> f64 {
    let lambda = match g.distribution {
        Distribution::Ggx => Ggx { alpha: g.alpha }.lambda(w) as f64,
        Distribution::Beckmann => Beckmann { alpha: g.alpha }.lambda(w),
    };
    1.0 / (1.0 + lambda)
}

/// Which share of the light an interface albedo counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Albedo {
    Reflection,
    Transmission,
}

/// The directional albedo of a rough dielectric interface (single scattering, Smith's
/// separable masking) for light arriving at cosine `mu` on the side of index ratio `eta`
/// (far side over near side): its reflection or its transmission share, the integral over the visible normals m of F(w.m) G1(w_r,
/// m) or (1 - F(w.m)) G1(w_t, m). Adaptive Gauss-Kronrod in (theta_m, phi_m), split where
/// the integrand has kinks (the visibility horizon w.m = 0, the critical angle), so that
/// each piece is smooth.
pub fn interface_albedo(g: Microfacet, mu: f64, eta: f64, share: Albedo) -> f64 {
    let sin_w = (1.0 - mu * mu).max(0.0).sqrt();
    let w = Vec3::new(sin_w as f32, 0.0, mu as f32);
    let norm = g1_exact(g, w) / mu;
    let theta_w = mu.acos();
    // the critical angle (facets seen beyond it reflect totally) when eta < 1
    let critical = (eta < 1.0).then(|| eta.asin());
    let integrand = |m: Vec3| -> f64 {
        let c = w.dot(m);
        if c <= 0.0 {
            return 0.0;
        }
        let f = fresnel_dielectric(c, eta as f32) as f64;
        let kept = match share {
            Albedo::Reflection => {
                let wr = reflect_about(w, m);
                if wr.z <= 0.0 {
                    return 0.0;
                }
                f * g.g1(wr, m) as f64
            }
            Albedo::Transmission => match refract_about(w, m, (1.0 / eta) as f32) {
                Some(wt) if wt.z < 0.0 => (1.0 - f) * g.g1(wt, m) as f64,
                _ => 0.0,
            },
        };
        c as f64 * g.d(m) as f64 * kept
    };
    // theta_m through y = x / (1 + x), x = tan(theta_m) / alpha: the lobe's width at any alpha
    let alpha = g.alpha as f64;
    let to_y = |theta: f64| {
        let x = theta.tan() / alpha;
        x / (1.0 + x)
    };
    let mut breaks = vec![0.0, 1.0];
    let mut angles = vec![PI64 / 2.0 - theta_w];
    if let Some(tc) = critical {
        angles.extend([tc - theta_w, theta_w - tc, theta_w + tc]);
    }
    breaks.extend(
        angles
            .into_iter()
            .filter(|a| *a > 0.0 && *a < PI64 / 2.0)
            .map(to_y),
    );
    let outer = |y: f64| {
        if y >= 1.0 {
            return 0.0;
        }
        let x = y / (1.0 - y);
        let theta = (alpha * x).atan();
        let dtheta_dy = alpha / (1.0 + alpha * alpha * x * x) / ((1.0 - y) * (1.0 - y));
        let (st, ct) = theta.sin_cos();
        let phi_at = |c: f64| {
            let cos_phi = (c - mu * ct) / (sin_w * st);
            (cos_phi > -1.0 && cos_phi < 1.0).then(|| cos_phi.acos())
        };
        let mut phis = vec![0.0, PI64];
        phis.extend(phi_at(0.0));
        if let Some(tc) = critical {
            phis.extend(phi_at(tc.cos()));
        }
        let inner = |phi: f64| {
            let (sp, cp) = phi.sin_cos();
            integrand(Vec3::new((st * cp) as f32, (st * sp) as f32, ct as f32))
        };
        // both halves of the azimuth, by symmetry about the plane of w
        2.0 * piecewise(&inner, phis, INNER_DEPTH) * st * dtheta_dy
    };
    norm * piecewise(&outer, breaks, OUTER_DEPTH)
}

/// The nested quadrature's tolerance, relative to the piece's integral (the Kronrod-Gauss
/// difference, a pessimistic bound of the Kronrod rule's error; the integrand is evaluated in
/// f32 like the BSDF, whose rounding, about 1e-7, a tighter tolerance could not get under),
/// and the deepest bisection of the outer (theta) and inner (phi) pieces: at most 2^DEPTH
/// pieces each, which bounds the work of a table whatever the roughness and index.
const REL_TOL: f64 = 1e-6;
const ABS_TOL: f64 = 1e-10;
const OUTER_DEPTH: u32 = 8;
const INNER_DEPTH: u32 = 6;

/// The integral of `f` over the span of `points` (sorted here), piece by piece.
fn piecewise(f: &impl Fn(f64) -> f64, mut points: Vec<f64>, depth: u32) -> f64 {
    points.sort_by(f64::total_cmp);
    points
        .windows(2)
        .filter(|p| p[1] > p[0])
        .map(|p| adaptive(f, p[0], p[1], None, depth))
        .sum()
}

/// Adaptive 15-point Gauss-Kronrod: bisect until the 7-point Gauss and the Kronrod estimate
/// agree to the tolerance (relative to the first estimate of the whole piece, `scale`) or
/// `depth` is spent.
fn adaptive(f: &impl Fn(f64) -> f64, a: f64, b: f64, scale: Option<f64>, depth: u32) -> f64 {
    let (k, g) = kronrod(f, a, b);
    let scale = scale.unwrap_or(k.abs());
    if (k - g).abs() <= ABS_TOL + REL_TOL * scale || depth == 0 {
        return k;
    }
    let m = 0.5 * (a + b);
    adaptive(f, a, m, Some(scale / 2.0), depth - 1)
        + adaptive(f, m, b, Some(scale / 2.0), depth - 1)
}

/// The 15-point Kronrod and embedded 7-point Gauss rules on [a, b] (nodes and weights of the
/// Gauss-Kronrod pair, Kronrod 1965; as tabulated in QUADPACK's QK15).
fn kronrod(f: &impl Fn(f64) -> f64, a: f64, b: f64) -> (f64, f64) {
    const X: [f64; 8] = [
        0.991_455_371_120_812_6,
        0.949_107_912_342_758_5,
        0.864_864_423_359_769_1,
        0.741_531_185_599_394_4,
        0.586_087_235_467_691_1,
        0.405_845_151_377_397_2,
        0.207_784_955_007_898_5,
        0.0,
    ];
    const WK: [f64; 8] = [
        0.022_935_322_010_529_22,
        0.063_092_092_629_978_55,
        0.104_790_010_322_250_2,
        0.140_653_259_715_525_9,
        0.169_004_726_639_267_9,
        0.190_350_578_064_785_4,
        0.204_432_940_075_298_9,
        0.209_482_141_084_727_8,
    ];
    // the Gauss weights of the odd-indexed nodes X[1], X[3], X[5], X[7]
    const WG: [f64; 4] = [
        0.129_484_966_168_869_7,
        0.279_705_391_489_276_7,
        0.381_830_050_505_118_9,
        0.417_959_183_673_469_4,
    ];
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let mut k = WK[7] * f(c);
    let mut g = WG[3] * f(c);
    for i in 0..7 {
        let s = f(c - h * X[i]) + f(c + h * X[i]);
        k += WK[i] * s;
        if i % 2 == 1 {
            g += WG[i / 2] * s;
        }
    }
    (k * h, g * h)
}
