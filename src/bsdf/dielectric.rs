//! The smooth dielectric interface: Fresnel-weighted Dirac reflection and refraction (Snell's
//! law), reflection chosen with probability F so that both weights are 1 (times the eta^2 of
//! refracted radiance, Kristensen 2010 eq. 2.15), times the [`Specular`] factors.

use glam::{Vec2, Vec3};

use super::{fresnel_dielectric, reflect, BsdfModel, BsdfSample, Lobe, TransportMode};
use crate::spectrum::Rgb;

/// A smooth dielectric interface; `ior` is inside (behind the normal) over outside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    pub ior: f32,
    pub specular: Specular,
}

/// The colours that scale a dielectric's reflection and transmission (Mitsuba 3's
/// `specular_reflectance` and `specular_transmittance` of plugins `dielectric`,
/// `roughdielectric` and `thindielectric`, default 1): they multiply the value of the lobe
/// only, never its probability, which stays Fresnel's (`src/bsdfs/dielectric.cpp`), and they
/// are the same in both transport modes (a factor of the point, symmetric in the directions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Specular {
    pub reflectance: Rgb,
    pub transmittance: Rgb,
}

impl Specular {
    /// Mitsuba's default: clear glass.
    pub const ONE: Specular = Specular {
        reflectance: Rgb::ONE,
        transmittance: Rgb::ONE,
    };

    /// What `describe` adds: nothing for clear glass.
    pub fn describe(&self) -> String {
        let show = crate::spectrum::show;
        let mut s = String::new();
        if self.reflectance != Rgb::ONE {
            s += &format!(", specular reflectance {}", show(self.reflectance));
        }
        if self.transmittance != Rgb::ONE {
            s += &format!(", specular transmittance {}", show(self.transmittance));
        }
        s
    }
}

impl Dielectric {
    /// Clear glass of index `ior`.
    pub fn new(ior: f32) -> Self {
        Dielectric {
            ior,
            specular: Specular::ONE,
        }
    }
}

impl BsdfModel for Dielectric {
    /// 1: the colour of what is seen through it is not its own.
    fn albedo(&self, _cos: f32) -> Rgb {
        Rgb::ONE
    }

    fn describe(&self) -> String {
        format!("dielectric, ior {}{}", self.ior, self.specular.describe())
    }

    fn has_regular_lobe(&self) -> bool {
        false
    }
    fn has_dirac_lobe(&self) -> bool {
        true
    }
    fn transmits(&self) -> bool {
        true
    }
    fn one_sided(&self) -> bool {
        false
    }

    /// Zero: both lobes are Dirac.
    fn eval(&self, _wo: Vec3, _wi: Vec3, _n: Vec3, _mode: TransportMode) -> Rgb {
        Rgb::ZERO
    }

    fn pdf(&self, _wo: Vec3, _wi: Vec3, _n: Vec3) -> f32 {
        0.0
    }

    // ANCHOR: dielectric_sample
    fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        _u: Vec2,
        uc: f32,
        mode: TransportMode,
    ) -> Option<BsdfSample> {
        let cos_o = wo.dot(n);
        // the normal on wo's side
        let nf = if cos_o > 0.0 { n } else { -n };
        // eta = eta_i / eta_t for light going from wo's side into the other side
        let entering = cos_o > 0.0;
        let (eta_o, eta_t) = if entering {
            (1.0, self.ior)
        } else {
            (self.ior, 1.0)
        };
        let cos_i = cos_o.abs();
        let f = fresnel_dielectric(cos_i, eta_t / eta_o);
        if uc < f {
            let wi = reflect(wo, nf);
            return Some(BsdfSample {
                wi,
                value: self.specular.reflectance * (f / cos_i),
                pdf: f,
                lobe: Lobe::SingularReflection,
            });
        }
        let eta = eta_o / eta_t;
        let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
        if sin2_t >= 1.0 {
            return None;
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        let wi = -eta * wo + (eta * cos_i - cos_t) * nf;
        let wi = wi.normalize();
        // radiance over eta^2 is invariant across the interface, so the radiance reaching wo
        // from wi's side is scaled by (eta_o / eta_t)^2 (Kristensen 2010 eq. 2.15); importance
        // and flux are not (its adjoint has no factor)
        let scale = match mode {
            TransportMode::Radiance => (eta_o / eta_t) * (eta_o / eta_t),
            TransportMode::Importance => 1.0,
        };
        Some(BsdfSample {
            wi,
            value: self.specular.transmittance * ((1.0 - f) * scale / cos_t),
            pdf: 1.0 - f,
            lobe: Lobe::SingularTransmission,
        })
    }
    // ANCHOR_END: dielectric_sample
}
