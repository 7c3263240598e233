//! The rough dielectric: a GGX or Beckmann microsurface of smooth dielectric facets between the
//! outside (index 1) and the inside behind the normal (index `ior`), which reflects and
//! refracts (Walter et al. 2007, eqs. (20), (21)). GGX directions come from the visible normals
//! seen from `wo` (Heitz 2018) and the facet's Fresnel term chooses reflection or refraction, so
//! the weight is G1(wi) for reflection and (eta_o / eta_t)^2 G1(wi) (radiance) or G1(wi)
//! (importance) for refraction, the rough counterparts of the smooth dielectric's weights;
//! Beckmann's facets come from D(m) cos theta_m (`microfacet::Microfacet::sample`).
//!
//! Radiance and importance: the refraction BSDF is not symmetric. Walter's eq. (21) is the
//! radiance BSDF, with eta_o^2 of the side of `wo` (where the radiance goes) in its numerator;
//! the adjoint f*(wo, wi) = f(wi, wo) that light subpaths carry has eta_i^2 of `wi`'s side
//! instead, and no other change (the rest of eq. (21) is symmetric in the two directions). This
//! is the same (eta_o / eta_t)^2 as the smooth dielectric's, so BDPT's and MLT's light and
//! eye subpaths agree.

use glam::{Vec2, Vec3};

use super::microfacet::{
    describe_alpha, reflect_about, refract_about, shading_frame, Anisotropy, Distribution,
    Microfacet,
};
use super::{fresnel_dielectric, BsdfModel, BsdfSample, Lobe, Specular, TransportMode};
use crate::math::Frame;
use crate::spectrum::Rgb;

/// A rough dielectric interface: `ior` inside (behind the normal) over outside, the
/// distribution and its roughness `alpha`; `specular` scales the values of reflection and
/// refraction, not their densities (Mitsuba 3's `roughdielectric.cpp`, `eval` and `sample`).
#[derive(Clone, Debug, PartialEq)]
pub struct RoughDielectric {
    pub ior: f32,
    pub distribution: Distribution,
    pub alpha: f32,
    pub specular: Specular,
    /// `None`: isotropic; else `alpha` is Mitsuba's `alpha_u`, along the tangent.
    pub anisotropy: Option<Anisotropy>,
}

/// `wo`, `wi` in the frame of the normal on `wo`'s side, with the indices on `wo`'s side
/// (eta_o) and the other side (eta_t).
struct Local {
    lo: Vec3,
    li: Vec3,
    eta_o: f32,
    eta_t: f32,
}

/// The half vector of a pair and whether it is a reflection.
struct Half {
    m: Vec3,
    reflect: bool,
}

impl RoughDielectric {
    fn microfacet(&self) -> Microfacet {
        let alpha_v = self.anisotropy.map_or(self.alpha, |a| a.alpha_v);
        Microfacet::anisotropic(self.distribution, self.alpha, alpha_v)
    }

    /// The frame of `wo`'s side and the indices on both sides; `None` at a grazing `wo`.
    fn frame(&self, wo: Vec3, n: Vec3) -> Option<(Frame, f32, f32)> {
        let c = wo.dot(n);
        if c == 0.0 || !c.is_finite() {
            return None;
        }
        Some(if c > 0.0 {
            (shading_frame(self.anisotropy.as_ref(), n, n), 1.0, self.ior)
        } else {
            (
                shading_frame(self.anisotropy.as_ref(), n, -n),
                self.ior,
                1.0,
            )
        })
    }

    fn local(&self, wo: Vec3, wi: Vec3, n: Vec3) -> Option<Local> {
        let (frame, eta_o, eta_t) = self.frame(wo, n)?;
        let (lo, li) = (frame.to_local(wo), frame.to_local(wi));
        (lo.z > 0.0 && li.z != 0.0).then_some(Local {
            lo,
            li,
            eta_o,
            eta_t,
        })
    }

    /// The microfacet normal that turns `lo` into `li`, on the macro normal's side: the half
    /// vector of a reflection (Walter et al. 2007, eq. (13)), the generalized half vector
    /// -(eta_o lo + eta_t li) of a refraction (eq. (16)). `None` if it is degenerate or the
    /// directions see its back (the chi+ factors of eqs. (20), (21)).
    fn half(l: &Local) -> Option<Half> {
        let reflect = l.li.z > 0.0;
        let v = if reflect {
            l.lo + l.li
        } else {
            -(l.eta_o * l.lo + l.eta_t * l.li)
        };
        let m = v.normalize_or_zero();
        let m = if m.z < 0.0 { -m } else { m };
        if m.z <= 0.0 || l.lo.dot(m) <= 0.0 || l.li.dot(m) * l.li.z <= 0.0 {
            return None;
        }
        Some(Half { m, reflect })
    }

    /// The facet's Fresnel reflectance. For a refraction both cosines are known, and the
    /// amplitudes are formed from them directly: recomputing the refracted cosine as
    /// sqrt(1 - sin^2) would lose every digit of 1 - F near the critical angle, and f(wo, wi)
    /// and f(wi, wo) would then disagree there.
    fn fresnel(l: &Local, h: &Half) -> f32 {
        let eta = l.eta_t / l.eta_o;
        let c_o = l.lo.dot(h.m);
        if h.reflect {
            return fresnel_dielectric(c_o, eta);
        }
        let c_t = -l.li.dot(h.m);
        let r_par = (eta * c_o - c_t) / (eta * c_o + c_t);
        let r_perp = (c_o - eta * c_t) / (c_o + eta * c_t);
        // the mean of the two polarizations' reflectances
        (r_par.mul_add(r_par, r_perp * r_perp) / 2.0).min(1.0)
    }
}

impl BsdfModel for RoughDielectric {
    /// 1: the colour of what is seen through it is not its own.
    fn albedo(&self, _cos: f32) -> Rgb {
        Rgb::ONE
    }

    fn describe(&self) -> String {
        format!(
            "rough dielectric, ior {}, {} {}{}",
            self.ior,
            self.distribution.name(),
            describe_alpha(self.alpha, self.anisotropy.as_ref()),
            self.specular.describe()
        )
    }

    fn has_regular_lobe(&self) -> bool {
        true
    }
    fn has_dirac_lobe(&self) -> bool {
        false
    }
    fn transmits(&self) -> bool {
        true
    }
    fn one_sided(&self) -> bool {
        false
    }

    /// f_s(wo, wi) in `mode` (Walter et al. 2007, eq. (20) for reflection, eq. (21) for
    /// refraction, its eta_o^2 taken on the side the transported quantity leaves towards; see
    /// the module note).
    // ANCHOR: rough_dielectric_eval
    fn eval(&self, wo: Vec3, wi: Vec3, n: Vec3, mode: TransportMode) -> Rgb {
        let Some(l) = self.local(wo, wi, n) else {
            return Rgb::ZERO;
        };
        let Some(h) = Self::half(&l) else {
            return Rgb::ZERO;
        };
        let g = self.microfacet();
        let dg = g.d(h.m) * g.g(l.lo, l.li, h.m);
        let f = Self::fresnel(&l, &h);
        let (value, tint) = if h.reflect {
            (f * dg / (4.0 * l.lo.z * l.li.z), self.specular.reflectance)
        } else {
            let (co, ci) = (l.lo.dot(h.m), l.li.dot(h.m));
            let den = l.eta_o * co + l.eta_t * ci;
            // radiance leaves towards wo: eta_o^2; importance leaves towards wi: eta_t^2
            let eta2 = match mode {
                TransportMode::Radiance => l.eta_o * l.eta_o,
                TransportMode::Importance => l.eta_t * l.eta_t,
            };
            let v = (co * ci).abs() / (l.lo.z * l.li.z).abs() * eta2 * (1.0 - f) * dg / (den * den);
            (v, self.specular.transmittance)
        };
        if value.is_finite() && value > 0.0 {
            tint * value
        } else {
            Rgb::ZERO
        }
    }
    // ANCHOR_END: rough_dielectric_eval

    /// The density of `wi` under [`RoughDielectric::sample`]: the visible-normal density of
    /// the facet, times the probability of the lobe (F or 1 - F), times the Jacobian from
    /// facet normals to directions, 1 / (4 wo.m) for reflection (Walter et al. 2007, eq. (14))
    /// and eta_t^2 |wi.m| / (eta_o wo.m + eta_t wi.m)^2 for refraction (eq. (17)).
    // ANCHOR: rough_dielectric_pdf
    fn pdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        let Some(l) = self.local(wo, wi, n) else {
            return 0.0;
        };
        let Some(h) = Self::half(&l) else {
            return 0.0;
        };
        let f = Self::fresnel(&l, &h);
        let pm = self.microfacet().pdf(l.lo, h.m);
        let (co, ci) = (l.lo.dot(h.m), l.li.dot(h.m));
        let pdf = if h.reflect {
            f * pm / (4.0 * co)
        } else {
            let den = l.eta_o * co + l.eta_t * ci;
            (1.0 - f) * pm * l.eta_t * l.eta_t * ci.abs() / (den * den)
        };
        if pdf.is_finite() && pdf > 0.0 {
            pdf
        } else {
            0.0
        }
    }
    // ANCHOR_END: rough_dielectric_pdf

    /// A visible facet normal from `u`, then reflection with the facet's Fresnel probability
    /// (`uc` < F) or refraction through it; `None` when the direction leaves on the wrong side
    /// of the macro-surface (that mass is missing from the density).
    fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        u: Vec2,
        uc: f32,
        mode: TransportMode,
    ) -> Option<BsdfSample> {
        let (frame, eta_o, eta_t) = self.frame(wo, n)?;
        let lo = frame.to_local(wo);
        let m = self.microfacet().sample(lo, u);
        let f = fresnel_dielectric(lo.dot(m), eta_t / eta_o);
        let li = if uc < f {
            reflect_about(lo, m)
        } else {
            refract_about(lo, m, eta_o / eta_t)?
        };
        if li.z == 0.0 || (li.z > 0.0) != (uc < f) {
            return None;
        }
        // value and density from the pair itself, so that they equal eval and pdf exactly
        let wi = frame.to_world(li);
        let pdf = self.pdf(wo, wi, n);
        let value = self.eval(wo, wi, n, mode);
        (pdf > 0.0 && value != Rgb::ZERO).then_some(BsdfSample {
            wi,
            value,
            pdf,
            lobe: Lobe::Regular,
        })
    }
}
