//! Surface scattering f_s of the local scattering equation (Pauly, Kollig, Keller 2000, eq. 2):
//! Lambertian (two-sided), mirror, smooth dielectric with Fresnel, a thin dielectric sheet, the
//! rough (GGX or Beckmann microfacet) conductor, dielectric and plastic (`conductor`,
//! `rough_dielectric`, `rough_plastic`, over `microfacet`), smooth plastic (`plastic`: a Dirac
//! coat over a diffuse base, the one model with a Dirac and a regular lobe), and the null
//! (index-matched) boundary that only separates media.
//!
//! Convention (see `conventions`): `wo` and `wi` point away from the surface point; `n` is the
//! geometric normal as the shape defines it (either side may be lit). Values are f_s itself,
//! without the cosine. Singular (delta) lobes return `value = weight * pdf / |cos wi|`, so that
//! `value * |cos wi| / pdf` is the path weight, as every regular lobe.
//!
//! Three questions, three helpers: does the material have a regular lobe
//! ([`Bsdf::has_regular_lobe`]: next-event estimation and connections may end there and see
//! `eval`/`pdf`, the regular part only), a Dirac lobe ([`Bsdf::has_dirac_lobe`]: some light
//! reaches it only by its own sampling), and did this sample take a Dirac
//! ([`Lobe::is_singular`]: the vertex is then a Dirac vertex, with a discrete probability, no
//! connection, and full weight for an emitter its ray hits). Plastic answers yes to all three.
//!
//! Book: "Surface scattering (eq. 2)" (`book/src/bsdf.md`); executable spec: `tests/bsdf.rs`.

use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

use crate::math::{warp, Frame};
use crate::spectrum::Rgb;

pub mod conductor;
pub mod microfacet;
pub mod plastic;
pub mod rough_dielectric;
pub mod rough_plastic;

pub use conductor::{ConductorFresnel, RoughConductor};
pub use microfacet::{Beckmann, Distribution, Ggx, Microfacet};
pub use plastic::Plastic;
pub use rough_dielectric::RoughDielectric;
pub use rough_plastic::RoughPlastic;

// ANCHOR: transport_mode
/// Which quantity a path carries: radiance (eye paths) or importance (light paths, the adjoint
/// BSDF f*_s). Only refraction differs (the eta^2 factor, Kristensen 2010 eq. 2.9).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    Radiance,
    Importance,
}
// ANCHOR_END: transport_mode

/// The scattering mode of a sampled direction (Pauly et al. sec. 5.2: perturbations keep modes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lobe {
    /// A smooth (regular) lobe with a density over solid angle.
    Regular,
    /// A Dirac reflection.
    SingularReflection,
    /// A Dirac transmission (refraction).
    SingularTransmission,
}

impl Lobe {
    /// True when this sampled lobe is a Dirac: the vertex that took it is a Dirac vertex (no
    /// connection, a discrete probability), whatever other lobes its material has.
    pub fn is_singular(self) -> bool {
        self != Lobe::Regular
    }
}

/// A sampled direction with the BSDF value and the density that produced it.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// f_s(wo, wi) (see the module note on singular lobes).
    pub value: Rgb,
    /// Solid-angle density for regular lobes, discrete probability for singular ones.
    pub pdf: f32,
    pub lobe: Lobe,
}

impl BsdfSample {
    /// value * |cos wi| / pdf: the factor the path throughput is multiplied by.
    #[inline]
    pub fn weight(&self, n: Vec3) -> Rgb {
        self.value * (self.wi.dot(n).abs() / self.pdf)
    }
}

/// The closed set of surface models.
#[derive(Clone, Debug, PartialEq)]
pub enum Bsdf {
    /// rho / pi on both sides, or on the normal's side only (`one_sided`).
    Lambert { albedo: Rgb, one_sided: bool },
    /// A perfect mirror with a constant reflectance (black behind the normal if `one_sided`).
    Mirror { reflectance: Rgb, one_sided: bool },
    /// A smooth dielectric interface; `ior` is inside (behind the normal) over outside.
    Dielectric { ior: f32 },
    /// A thin dielectric sheet (Mitsuba 3's `thindielectric`): `ior` is the sheet's index over
    /// the surrounding one. Light is reflected or passes straight through, with the sheet's
    /// internal reflections summed ([`thin_dielectric_reflectance`]); no refraction, no eta^2.
    ThinDielectric { ior: f32 },
    /// A GGX microfacet conductor (glossy reflection, two-sided unless `one_sided`).
    RoughConductor(RoughConductor),
    /// A GGX microfacet dielectric interface (glossy reflection and refraction).
    RoughDielectric(RoughDielectric),
    /// Smooth plastic: a Dirac coat reflection over a diffuse base (Mitsuba 3's `plastic`).
    Plastic(Plastic),
    /// A diffuse base under a rough dielectric coating (Mitsuba 3's `roughplastic`).
    RoughPlastic(RoughPlastic),
    /// An index-matched boundary: light passes unchanged. Never a scattering vertex.
    Null,
}

/// Fresnel reflectance of an unpolarized wave for a dielectric interface. `cos_i` is measured on
/// the side the light arrives from, `eta` = eta_transmitted / eta_incident.
// ANCHOR: fresnel
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    // ASSIGNMENT: fresnel
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0; // total internal reflection
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
    // END ASSIGNMENT
}
// ANCHOR_END: fresnel

/// Reflectance of a thin dielectric sheet of relative index `eta` at incidence cosine `cos_i`:
/// with R = F(cos_i) at each face and T = 1 - R, the light reflected after any number of
/// passes inside sums to R + T^2 R (1 + R^2 + R^4 + ...) = R + T^2 R / (1 - R^2) = 2R / (1 + R)
/// (the sheet's two faces are parallel, so every pass meets the same angle; Mitsuba 3's
/// `thindielectric` uses the same sum).
#[inline]
pub fn thin_dielectric_reflectance(cos_i: f32, eta: f32) -> f32 {
    let r = fresnel_dielectric(cos_i, eta);
    2.0 * r / (1.0 + r)
}

/// Mirror `w` about `n`.
#[inline]
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    2.0 * w.dot(n) * n - w
}

impl Bsdf {
    /// True for the null boundary, which is skipped by tracing rather than scattered at.
    pub fn is_null(&self) -> bool {
        matches!(self, Bsdf::Null)
    }

    /// True when the material has a regular lobe (a density over solid angle): next-event
    /// estimation and connections may end at it, and they see that lobe only. The match is
    /// exhaustive, so that a new model has to say which lobes it has.
    pub fn has_regular_lobe(&self) -> bool {
        match self {
            Bsdf::Mirror { .. }
            | Bsdf::Dielectric { .. }
            | Bsdf::ThinDielectric { .. }
            | Bsdf::Null => false,
            Bsdf::Lambert { .. }
            | Bsdf::RoughConductor(_)
            | Bsdf::RoughDielectric(_)
            | Bsdf::RoughPlastic(_)
            | Bsdf::Plastic(_) => true,
        }
    }

    /// True when the material has a Dirac lobe: some of its light is scattered into one
    /// direction, which no connection and no light sample can reach (only its own sampling).
    pub fn has_dirac_lobe(&self) -> bool {
        match self {
            Bsdf::Mirror { .. }
            | Bsdf::Dielectric { .. }
            | Bsdf::ThinDielectric { .. }
            | Bsdf::Plastic(_) => true,
            Bsdf::Lambert { .. }
            | Bsdf::RoughConductor(_)
            | Bsdf::RoughDielectric(_)
            | Bsdf::RoughPlastic(_) => false,
            Bsdf::Null => false,
        }
    }

    /// True when some light passes to the other side of the surface (the null boundary passes
    /// all of it); reflection-only models keep every path on the side it arrived from.
    pub fn transmits(&self) -> bool {
        match self {
            Bsdf::Dielectric { .. }
            | Bsdf::ThinDielectric { .. }
            | Bsdf::RoughDielectric(_)
            | Bsdf::Null => true,
            Bsdf::Lambert { .. }
            | Bsdf::Mirror { .. }
            | Bsdf::RoughConductor(_)
            | Bsdf::Plastic(_)
            | Bsdf::RoughPlastic(_) => false,
        }
    }

    /// True when every lobe is a Dirac (mirror, glass; the null boundary has none): every
    /// vertex on it is a Dirac vertex, whatever was sampled there.
    pub fn only_dirac_lobes(&self) -> bool {
        !self.has_regular_lobe()
    }

    /// True when `wo` sees the back of a one-sided opaque model, which is black there (Mitsuba
    /// 3's convention for `diffuse` and `conductor` without `twosided`): no value, no density,
    /// no sample. Reflection-only models keep `wo` and `wi` on one side, so `wo` decides.
    // ANCHOR: black_behind
    pub fn black_behind(&self, wo: Vec3, n: Vec3) -> bool {
        let one_sided = match self {
            Bsdf::Lambert { one_sided, .. } | Bsdf::Mirror { one_sided, .. } => *one_sided,
            Bsdf::RoughConductor(c) => c.one_sided,
            Bsdf::Plastic(p) => p.one_sided,
            Bsdf::RoughPlastic(p) => p.one_sided,
            Bsdf::Dielectric { .. }
            | Bsdf::ThinDielectric { .. }
            | Bsdf::RoughDielectric(_)
            | Bsdf::Null => false,
        };
        one_sided && wo.dot(n) <= 0.0
    }
    // ANCHOR_END: black_behind

    /// f_s(wo, wi): zero for singular lobes (a Dirac cannot be evaluated at a given direction);
    /// the regular lobe alone for a model with both.
    // ANCHOR: bsdf_eval
    pub fn eval(&self, wo: Vec3, wi: Vec3, n: Vec3, mode: TransportMode) -> Rgb {
        if self.black_behind(wo, n) {
            return Rgb::ZERO;
        }
        match self {
            Bsdf::Lambert { albedo, .. } => {
                // two-sided: reflection only, whichever side wo is on
                if wo.dot(n) * wi.dot(n) > 0.0 {
                    *albedo * FRAC_1_PI
                } else {
                    Rgb::ZERO
                }
            }
            Bsdf::RoughConductor(c) => c.eval(wo, wi, n),
            Bsdf::RoughDielectric(d) => d.eval(wo, wi, n, mode),
            Bsdf::Plastic(p) => p.eval(wo, wi, n),
            Bsdf::RoughPlastic(p) => p.eval(wo, wi, n),
            _ => Rgb::ZERO,
        }
    }
    // ANCHOR_END: bsdf_eval

    /// Solid-angle density with which [`Bsdf::sample`] produces `wi` (zero for singular lobes;
    /// for a model with both, the regular lobe's density times the probability of taking it).
    pub fn pdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        if self.black_behind(wo, n) {
            return 0.0;
        }
        match self {
            // cosine-weighted on wo's side: |cos wi| / pi, zero across the surface
            Bsdf::Lambert { .. } if wo.dot(n) * wi.dot(n) > 0.0 => wi.dot(n).abs() * FRAC_1_PI,
            Bsdf::RoughConductor(c) => c.pdf(wo, wi, n),
            Bsdf::RoughDielectric(d) => d.pdf(wo, wi, n),
            Bsdf::Plastic(p) => p.pdf(wo, wi, n),
            Bsdf::RoughPlastic(p) => p.pdf(wo, wi, n),
            _ => 0.0,
        }
    }

    /// Samples `wi` given `wo`. `None` when no direction can be produced.
    pub fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        u: Vec2,
        uc: f32,
        mode: TransportMode,
    ) -> Option<BsdfSample> {
        let cos_o = wo.dot(n);
        if cos_o == 0.0 || self.black_behind(wo, n) {
            return None;
        }
        // the normal on wo's side
        let nf = if cos_o > 0.0 { n } else { -n };
        match self {
            Bsdf::Lambert { albedo, .. } => {
                let local = warp::cosine_hemisphere(u);
                if local.z <= 0.0 {
                    return None;
                }
                let wi = Frame::from_normal(nf).to_world(local);
                Some(BsdfSample {
                    wi,
                    value: *albedo * FRAC_1_PI,
                    pdf: local.z * FRAC_1_PI,
                    lobe: Lobe::Regular,
                })
            }
            Bsdf::Mirror { reflectance, .. } => {
                let wi = reflect(wo, nf);
                let c = wi.dot(nf).abs();
                Some(BsdfSample {
                    wi,
                    value: *reflectance / c,
                    pdf: 1.0,
                    lobe: Lobe::SingularReflection,
                })
            }
            // ANCHOR: dielectric_sample
            Bsdf::Dielectric { ior } => {
                // eta = eta_i / eta_t for light going from wo's side into the other side
                let entering = cos_o > 0.0;
                let (eta_o, eta_t) = if entering { (1.0, *ior) } else { (*ior, 1.0) };
                let cos_i = cos_o.abs();
                let f = fresnel_dielectric(cos_i, eta_t / eta_o);
                if uc < f {
                    let wi = reflect(wo, nf);
                    Some(BsdfSample {
                        wi,
                        value: Rgb::splat(f / cos_i),
                        pdf: f,
                        lobe: Lobe::SingularReflection,
                    })
                } else {
                    let eta = eta_o / eta_t;
                    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
                    if sin2_t >= 1.0 {
                        return None;
                    }
                    let cos_t = (1.0 - sin2_t).sqrt();
                    let wi = -eta * wo + (eta * cos_i - cos_t) * nf;
                    let wi = wi.normalize();
                    // radiance over eta^2 is invariant across the interface, so the radiance
                    // reaching wo from wi's side is scaled by (eta_o / eta_t)^2 (Kristensen 2010
                    // eq. 2.15); importance and flux are not (its adjoint has no factor)
                    let scale = match mode {
                        TransportMode::Radiance => (eta_o / eta_t) * (eta_o / eta_t),
                        TransportMode::Importance => 1.0,
                    };
                    Some(BsdfSample {
                        wi,
                        value: Rgb::splat((1.0 - f) * scale / cos_t),
                        pdf: 1.0 - f,
                        lobe: Lobe::SingularTransmission,
                    })
                }
            }
            // ANCHOR_END: dielectric_sample
            Bsdf::ThinDielectric { ior } => {
                let cos_i = cos_o.abs();
                let r = thin_dielectric_reflectance(cos_i, *ior);
                let (wi, p, lobe) = if uc < r {
                    (reflect(wo, nf), r, Lobe::SingularReflection)
                } else {
                    // straight through: the sheet's two refractions cancel
                    (-wo, 1.0 - r, Lobe::SingularTransmission)
                };
                if p <= 0.0 {
                    return None;
                }
                Some(BsdfSample {
                    wi,
                    value: Rgb::splat(p / cos_i),
                    pdf: p,
                    lobe,
                })
            }
            Bsdf::RoughConductor(c) => c.sample(wo, n, u),
            Bsdf::RoughDielectric(d) => d.sample(wo, n, u, uc, mode),
            Bsdf::Plastic(p) => p.sample(wo, n, u, uc),
            Bsdf::RoughPlastic(p) => p.sample(wo, n, u, uc),
            Bsdf::Null => None,
        }
    }
}
