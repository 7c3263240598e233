//! Smooth plastic: a diffuse base under a smooth dielectric coat, the closed form of Mitsuba
//! 3's `plastic` plugin (its documentation and `src/bsdfs/plastic.cpp`; the model goes back to
//! Weidlich and Wilkie 2007 and Mitsuba 0.5's `plastic`). Reflection only, on the normal's side
//! (`one_sided`, Mitsuba's convention) or on `wo`'s side (two-sided, Mitsuba's `twosided`).
//!
//! It has two lobes (Mitsuba's two components):
//! * the coat's **Dirac reflection**, F(cos_o, eta) R_s delta(wi - reflect(wo)) / |cos wi|, F
//!   the dielectric Fresnel reflectance seen from outside, R_s `specular`;
//! * the **diffuse base**, a regular lobe:
//!   f_d(wo, wi) = (1 - F(cos_o)) (1 - F(cos_i)) / eta^2 * rho / (1 - F_dr_int [rho]) / pi,
//!   where rho is `diffuse` and F_dr_int the diffuse Fresnel reflectance of the coat seen from
//!   inside (index ratio 1 / eta), times rho too when `nonlinear`. Light refracts in (1 - F_o),
//!   is scattered by the base, and escapes through (1 - F_i); the 1 / eta^2 is the radiance
//!   compression of refraction out of the denser coat. The light the coat reflects back inside
//!   (a fraction F_dr_int of a diffuse distribution) hits the base again: the geometric series
//!   sum_k (F_dr_int rho)^k = 1 / (1 - F_dr_int rho) of these internal bounces is the
//!   `nonlinear` form; the default divides by (1 - F_dr_int) instead, which keeps rho the
//!   colour the surface shows (Mitsuba's choice, so that textures keep their hue).
//!
//! `eval` and `pdf` are the diffuse lobe's alone (a Dirac has no value at a given direction).
//! `sample` picks the Dirac with probability P_s(wo) = F w / (F w + (1 - F)(1 - w)), w the
//! specular sampling weight mean(R_s) / (mean(rho) + mean(R_s)), as Mitsuba does; the regular
//! lobe's density is then (1 - P_s(wo)) cos_i / pi, which depends on `wo` through F: the
//! forward and reverse densities of one pair of directions differ, and integrators must take
//! `pdf(wo, wi)` and `pdf(wi, wo)` each for what it is. At a Dirac choice P_s(wo) = P_s(wi),
//! because both directions make the same angle with the normal.

use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

use super::{fresnel_dielectric, reflect, BsdfModel, BsdfSample, Lobe, TransportMode};
use crate::math::{warp, Frame};
use crate::spectrum::Rgb;

/// Mitsuba 3's default `int_ior` of `plastic`: its named index "polypropylene".
pub const DEFAULT_INT_IOR: f64 = 1.49;
/// Mitsuba 3's default `ext_ior`: its named index "air".
pub const DEFAULT_EXT_IOR: f64 = 1.000277;

/// The default coat index eta = int_ior / ext_ior, divided in f64 as the importer does.
pub fn default_eta() -> f32 {
    (DEFAULT_INT_IOR / DEFAULT_EXT_IOR) as f32
}

/// Smooth plastic (see the module note).
#[derive(Clone, Debug, PartialEq)]
pub struct Plastic {
    /// rho, the base's reflectance.
    pub diffuse: Rgb,
    /// R_s, the coat's reflectance factor.
    pub specular: Rgb,
    /// eta = int_ior / ext_ior, the coat's index relative to the outside.
    pub eta: f32,
    /// The internal bounces' series 1 / (1 - F_dr_int rho) instead of 1 / (1 - F_dr_int).
    pub nonlinear: bool,
    /// Black behind the normal (see `Bsdf::black_behind`).
    pub one_sided: bool,
}

/// The diffuse Fresnel reflectance F_dr(eta): the hemispherical average of the Fresnel
/// reflectance for light arriving from a diffuse distribution at an interface of relative index
/// eta, by the polynomial fits Mitsuba 3 uses (`fresnel_diffuse_reflectance` in its
/// `fresnel.h`): Egan and Hilgeman 1973 for eta < 1,
/// F_dr = -1.4399 eta^2 + 0.7099 eta + 0.6681 + 0.0636 / eta,
/// and d'Eon and Irving 2011 for eta >= 1, a quintic in 1 / eta:
/// F_dr = 0.919317 - 3.4793 x + 6.75335 x^2 - 7.80989 x^3 + 4.98554 x^4 - 1.36881 x^5.
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    if eta < 1.0 {
        -1.4399 * eta * eta + 0.7099 * eta + 0.6681 + 0.0636 / eta
    } else {
        let x = 1.0 / eta;
        let c = [0.919317, -3.4793, 6.75335, -7.80989, 4.98554, -1.36881f32];
        c.iter().rev().fold(0.0, |acc, &k| acc * x + k)
    }
}

/// The mean of a colour's channels (Mitsuba's `Texture::mean` of a constant RGB).
fn mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

impl Plastic {
    /// w = mean(R_s) / (mean(rho) + mean(R_s)): how strongly sampling favours the coat
    /// (Mitsuba's `m_specular_sampling_weight`); 1/2 for a black material.
    pub fn specular_sampling_weight(&self) -> f32 {
        let (d, s) = (mean(self.diffuse), mean(self.specular));
        if d + s > 0.0 {
            s / (d + s)
        } else {
            0.5
        }
    }

    /// P_s(wo): the probability that `sample` takes the Dirac lobe when coming from a direction
    /// at cosine `cos_o` (> 0) to the normal.
    pub fn specular_probability(&self, cos_o: f32) -> f32 {
        let f = fresnel_dielectric(cos_o, self.eta);
        let w = self.specular_sampling_weight();
        let (ps, pd) = (f * w, (1.0 - f) * (1.0 - w));
        if ps + pd > 0.0 {
            ps / (ps + pd)
        } else {
            0.0
        }
    }

    /// The internal bounces' factor rho / (1 - F_dr_int rho) (`nonlinear`) or
    /// rho / (1 - F_dr_int), F_dr_int the diffuse reflectance of the coat from inside.
    pub fn base_albedo(&self) -> Rgb {
        let fdr_int = fresnel_diffuse_reflectance(1.0 / self.eta);
        if self.nonlinear {
            self.diffuse / (Rgb::ONE - fdr_int * self.diffuse)
        } else {
            self.diffuse / (1.0 - fdr_int)
        }
    }

    /// The cosines of `wo` and `wi` to the normal on `wo`'s side, when both lie on it.
    fn cosines(wo: Vec3, wi: Vec3, n: Vec3) -> Option<(f32, f32)> {
        let (co, ci) = (wo.dot(n), wi.dot(n));
        (co * ci > 0.0).then_some((co.abs(), ci.abs()))
    }
}

impl BsdfModel for Plastic {
    fn albedo(&self, cos: f32) -> Rgb {
        super::coated_albedo(self.diffuse, self.specular, self.eta, cos)
    }

    fn describe(&self) -> String {
        format!(
            "plastic, diffuse {}, specular {}, ior {}{}",
            crate::spectrum::show(self.diffuse),
            crate::spectrum::show(self.specular),
            self.eta,
            if self.nonlinear { ", nonlinear" } else { "" }
        )
    }

    fn has_regular_lobe(&self) -> bool {
        true
    }
    fn has_dirac_lobe(&self) -> bool {
        true
    }
    fn transmits(&self) -> bool {
        false
    }
    fn one_sided(&self) -> bool {
        self.one_sided
    }

    /// The diffuse lobe f_d(wo, wi) (module note); symmetric in the two directions.
    // ANCHOR: plastic_eval
    fn eval(&self, wo: Vec3, wi: Vec3, n: Vec3, _mode: TransportMode) -> Rgb {
        let Some((co, ci)) = Self::cosines(wo, wi, n) else {
            return Rgb::ZERO;
        };
        let (fo, fi) = (
            fresnel_dielectric(co, self.eta),
            fresnel_dielectric(ci, self.eta),
        );
        self.base_albedo() * ((1.0 - fo) * (1.0 - fi) / (self.eta * self.eta) * FRAC_1_PI)
    }
    // ANCHOR_END: plastic_eval

    /// The density of `wi` under `sample` when the regular lobe is taken:
    /// (1 - P_s(wo)) cos_i / pi (zero across the surface).
    fn pdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        let Some((co, ci)) = Self::cosines(wo, wi, n) else {
            return 0.0;
        };
        (1.0 - self.specular_probability(co)) * ci * FRAC_1_PI
    }

    /// The Dirac reflection with probability P_s(wo) (value F R_s / cos, so that the weight is
    /// F R_s / P_s), else a cosine-distributed direction of the diffuse lobe.
    // ANCHOR: plastic_sample
    fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        u: Vec2,
        uc: f32,
        mode: TransportMode,
    ) -> Option<BsdfSample> {
        let cos_o = wo.dot(n);
        let nf = if cos_o > 0.0 { n } else { -n };
        let co = cos_o.abs();
        let p_s = self.specular_probability(co);
        if uc < p_s {
            let f = fresnel_dielectric(co, self.eta);
            return Some(BsdfSample {
                wi: reflect(wo, nf),
                value: self.specular * (f / co),
                pdf: p_s,
                lobe: Lobe::SingularReflection,
            });
        }
        let local = warp::cosine_hemisphere(u);
        if local.z <= 0.0 {
            return None;
        }
        let wi = Frame::from_normal(nf).to_world(local);
        let pdf = (1.0 - p_s) * local.z * FRAC_1_PI;
        (pdf > 0.0).then(|| BsdfSample {
            wi,
            value: self.eval(wo, wi, n, mode),
            pdf,
            lobe: Lobe::Regular,
        })
    }
    // ANCHOR_END: plastic_sample
}
