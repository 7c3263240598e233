//! The smooth conductor (Mitsuba 3's `conductor`): a Dirac reflection weighted by the exact
//! Fresnel reflectance of a complex index and a `specular` colour; and the rough conductor: a GGX or Beckmann microsurface of metal facets, reflection only,
//! two-sided like the mirror (it reflects on whichever side `wo` is). Walter et al. 2007, eq.
//! (20), with D and G1 of eqs. (33), (34) (GGX) or (25), (27) (Beckmann) and Smith's separable G
//! of eq. (23); GGX directions are sampled from the visible normals (Heitz 2018), which makes
//! the weight F G1(wi), Beckmann's from D(m) cos theta_m.
//!
//! Its Fresnel term is either Schlick's approximation about a reflectance colour (the
//! reflectance at normal incidence, the mirror's parameter) or the exact reflectance of a
//! conductor of complex index eta + i k per channel.

use glam::{Vec2, Vec3};

use super::microfacet::{
    describe_alpha, reflect_about, shading_frame, Anisotropy, Distribution, Microfacet,
};
use super::{BsdfModel, BsdfSample, Lobe, TransportMode};
use crate::math::Frame;
use crate::spectrum::Rgb;

/// The Fresnel reflectance of a conductor's facets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConductorFresnel {
    /// Schlick's approximation F = R0 + (1 - R0)(1 - cos)^5 with R0 the given colour.
    Schlick(Rgb),
    /// The exact unpolarized reflectance of complex index `eta` + i `k` (per channel) seen
    /// from index 1.
    Complex { eta: Rgb, k: Rgb },
}

impl ConductorFresnel {
    /// F at a facet seen at cosine `cos` (in [0, 1]).
    pub fn eval(&self, cos: f32) -> Rgb {
        let cos = cos.clamp(0.0, 1.0);
        match self {
            ConductorFresnel::Schlick(r0) => {
                let m = 1.0 - cos;
                let m5 = (m * m) * (m * m) * m;
                *r0 + (Rgb::ONE - *r0) * m5
            }
            ConductorFresnel::Complex { eta, k } => Rgb::new(
                fresnel_complex(cos, eta.x, k.x),
                fresnel_complex(cos, eta.y, k.y),
                fresnel_complex(cos, eta.z, k.z),
            ),
        }
    }
}

/// A complex number in f64 (the conductor's Fresnel loses digits in f32 near grazing angles).
#[derive(Clone, Copy, Debug)]
struct C(f64, f64);

impl C {
    fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
    fn sub(self, o: C) -> C {
        C(self.0 - o.0, self.1 - o.1)
    }
    fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    fn div(self, o: C) -> C {
        let d = o.0 * o.0 + o.1 * o.1;
        C(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
    fn norm2(self) -> f64 {
        self.0 * self.0 + self.1 * self.1
    }
    /// The principal square root (non-negative real part).
    fn sqrt(self) -> C {
        let r = self.norm2().sqrt();
        let re = (0.5 * (r + self.0)).max(0.0).sqrt();
        let im = (0.5 * (r - self.0)).max(0.0).sqrt();
        C(re, if self.1 < 0.0 { -im } else { im })
    }
}

/// Unpolarized Fresnel reflectance of a conductor of complex index eta + i k, seen from index
/// 1 at cosine `cos_i`: the dielectric's formulas (`fresnel_dielectric`) with a complex index,
/// whose refracted "cosine" sqrt(1 - sin^2 / (eta + i k)^2) is complex (Born and Wolf, sec.
/// 14.2); with k = 0 and eta > 1 it is the dielectric's reflectance.
pub fn fresnel_complex(cos_i: f32, eta: f32, k: f32) -> f32 {
    let c = cos_i.clamp(0.0, 1.0) as f64;
    let n = C(eta as f64, k as f64);
    let sin2 = C(1.0 - c * c, 0.0);
    let cos_t = C(1.0, 0.0).sub(sin2.div(n.mul(n))).sqrt();
    let ci = C(c, 0.0);
    let r_perp = ci.sub(n.mul(cos_t)).div(ci.add(n.mul(cos_t)));
    let r_par = n.mul(ci).sub(cos_t).div(n.mul(ci).add(cos_t));
    (0.5 * (r_perp.norm2() + r_par.norm2())) as f32
}

/// A smooth conductor (Mitsuba 3 documentation, plugin `conductor`): the mirror reflection with
/// weight `specular` F(cos) of the complex index `eta` + i `k` per channel (`eta` 0, `k` 1 is
/// Mitsuba's material `none`: F = 1, a perfect mirror).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conductor {
    pub eta: Rgb,
    pub k: Rgb,
    /// A colour scaling the Fresnel reflectance (Mitsuba's `specular_reflectance`).
    pub specular: Rgb,
    /// Black behind the normal (see `Bsdf::black_behind`).
    pub one_sided: bool,
}

impl Conductor {
    /// The fraction of light reflected at cosine `cos`: `specular` times the Fresnel term.
    pub fn reflectance(&self, cos: f32) -> Rgb {
        let fresnel = ConductorFresnel::Complex {
            eta: self.eta,
            k: self.k,
        };
        self.specular * fresnel.eval(cos)
    }
}

impl BsdfModel for Conductor {
    fn albedo(&self, cos: f32) -> Rgb {
        self.reflectance(cos)
    }

    fn describe(&self) -> String {
        let show = crate::spectrum::show;
        format!(
            "conductor, eta {}, k {}, specular {}",
            show(self.eta),
            show(self.k),
            show(self.specular)
        )
    }

    fn has_regular_lobe(&self) -> bool {
        false
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

    /// Zero: a Dirac has no value at a given direction.
    fn eval(&self, _wo: Vec3, _wi: Vec3, _n: Vec3, _mode: TransportMode) -> Rgb {
        Rgb::ZERO
    }

    fn pdf(&self, _wo: Vec3, _wi: Vec3, _n: Vec3) -> f32 {
        0.0
    }

    /// The mirror direction with probability 1; the weight is the reflectance at `wo`'s cosine
    /// (the same at `wi`'s: reflection keeps the angle, so the value is reciprocal).
    fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        _u: Vec2,
        _uc: f32,
        _mode: TransportMode,
    ) -> Option<BsdfSample> {
        let s = super::mirror::mirror_reflection(wo, n, |cos| self.reflectance(cos));
        (s.value.is_finite() && s.value != Rgb::ZERO).then_some(s)
    }
}

/// A rough conductor: the distribution, its roughness `alpha` and its facets' Fresnel term.
#[derive(Clone, Debug, PartialEq)]
pub struct RoughConductor {
    pub distribution: Distribution,
    pub alpha: f32,
    pub fresnel: ConductorFresnel,
    /// A colour scaling the Fresnel term (Mitsuba's `specular_reflectance`, default 1).
    pub specular: Rgb,
    /// Black behind the normal (see `Bsdf::black_behind`).
    pub one_sided: bool,
    /// `None`: isotropic (`alpha` in every direction); else `alpha` is Mitsuba's `alpha_u`,
    /// along the tangent.
    pub anisotropy: Option<Anisotropy>,
}

impl RoughConductor {
    fn microfacet(&self) -> Microfacet {
        let alpha_v = self.anisotropy.map_or(self.alpha, |a| a.alpha_v);
        Microfacet::anisotropic(self.distribution, self.alpha, alpha_v)
    }

    /// The local frame whose +z is the normal on `wo`'s side ([`shading_frame`]).
    fn frame(&self, wo: Vec3, n: Vec3) -> Frame {
        let nf = if wo.dot(n) >= 0.0 { n } else { -n };
        shading_frame(self.anisotropy.as_ref(), n, nf)
    }

    /// `wo` and `wi` in the frame of the normal on `wo`'s side, or `None` when they do not lie
    /// on one side (the conductor does not transmit) or either is grazing.
    fn local(&self, wo: Vec3, wi: Vec3, n: Vec3) -> Option<(Frame, Vec3, Vec3)> {
        let frame = self.frame(wo, n);
        let (lo, li) = (frame.to_local(wo), frame.to_local(wi));
        (lo.z > 0.0 && li.z > 0.0).then_some((frame, lo, li))
    }
}

impl BsdfModel for RoughConductor {
    /// The Fresnel reflectance times `specular`.
    fn albedo(&self, cos: f32) -> Rgb {
        self.specular * self.fresnel.eval(cos)
    }

    fn describe(&self) -> String {
        let show = crate::spectrum::show;
        let base = match self.fresnel {
            ConductorFresnel::Schlick(r) => format!(
                "rough conductor, {} {}, reflectance {}",
                self.distribution.name(),
                describe_alpha(self.alpha, self.anisotropy.as_ref()),
                show(r)
            ),
            ConductorFresnel::Complex { eta, k } => format!(
                "rough conductor, {} {}, eta {}, k {}",
                self.distribution.name(),
                describe_alpha(self.alpha, self.anisotropy.as_ref()),
                show(eta),
                show(k)
            ),
        };
        if self.specular == Rgb::ONE {
            base
        } else {
            format!("{base}, specular {}", show(self.specular))
        }
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

    /// f_s = F(wo.m) D(m) G(wo, wi, m) / (4 cos_o cos_i), m the half vector (Walter et al.
    /// 2007, eq. (20)); reciprocal.
    // ANCHOR: conductor_eval
    fn eval(&self, wo: Vec3, wi: Vec3, n: Vec3, _mode: TransportMode) -> Rgb {
        let Some((_, lo, li)) = self.local(wo, wi, n) else {
            return Rgb::ZERO;
        };
        let m = (lo + li).normalize_or_zero();
        if m == Vec3::ZERO {
            return Rgb::ZERO;
        }
        let g = self.microfacet();
        let f = self.specular * self.fresnel.eval(lo.dot(m));
        let value = f * (g.d(m) * g.g(lo, li, m) / (4.0 * lo.z * li.z));
        if value.is_finite() {
            value
        } else {
            Rgb::ZERO
        }
    }
    // ANCHOR_END: conductor_eval

    /// The density of `wi` under [`RoughConductor::sample`]: the visible-normal density times the
    /// reflection's Jacobian 1 / (4 wo.m) (Walter et al. 2007, eq. (14)), = G1(wo) D(m) /
    /// (4 cos_o).
    fn pdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        let Some((_, lo, li)) = self.local(wo, wi, n) else {
            return 0.0;
        };
        let m = (lo + li).normalize_or_zero();
        let c = lo.dot(m);
        if c <= 0.0 {
            return 0.0;
        }
        let pdf = self.microfacet().pdf(lo, m) / (4.0 * c);
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    /// Reflects `wo` about a visible normal; `None` when the reflection points under the
    /// surface (the density then integrates to less than one by that mass).
    fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        u: Vec2,
        _uc: f32,
        mode: TransportMode,
    ) -> Option<BsdfSample> {
        let frame = self.frame(wo, n);
        let lo = frame.to_local(wo);
        if lo.z <= 0.0 {
            return None;
        }
        let m = self.microfacet().sample(lo, u);
        let li = reflect_about(lo, m);
        if li.z <= 0.0 {
            return None;
        }
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
