//! The thin dielectric sheet (Mitsuba 3's `thindielectric`): light is reflected or passes
//! straight through, with the sheet's internal reflections summed
//! ([`thin_dielectric_reflectance`]); no refraction, no eta^2. Both lobes are Dirac and both
//! weights are 1, times the [`Specular`] factors.

use glam::{Vec2, Vec3};

use super::{fresnel_dielectric, reflect, BsdfModel, BsdfSample, Lobe, Specular, TransportMode};
use crate::spectrum::Rgb;

/// A thin dielectric sheet: `ior` is the sheet's index over the surrounding one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinDielectric {
    pub ior: f32,
    pub specular: Specular,
}

impl ThinDielectric {
    /// A clear sheet of index `ior`.
    pub fn new(ior: f32) -> Self {
        ThinDielectric {
            ior,
            specular: Specular::ONE,
        }
    }
}

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

impl BsdfModel for ThinDielectric {
    /// 1: the colour of what is seen through it is not its own.
    fn albedo(&self, _cos: f32) -> Rgb {
        Rgb::ONE
    }

    fn describe(&self) -> String {
        format!(
            "thin dielectric, ior {}{}",
            self.ior,
            self.specular.describe()
        )
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

    /// Reflection with probability R' = [`thin_dielectric_reflectance`], else straight through.
    fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        _u: Vec2,
        uc: f32,
        _mode: TransportMode,
    ) -> Option<BsdfSample> {
        let cos_o = wo.dot(n);
        let nf = if cos_o > 0.0 { n } else { -n };
        let cos_i = cos_o.abs();
        let r = thin_dielectric_reflectance(cos_i, self.ior);
        let (wi, p, lobe, tint) = if uc < r {
            let tint = self.specular.reflectance;
            (reflect(wo, nf), r, Lobe::SingularReflection, tint)
        } else {
            // straight through: the sheet's two refractions cancel
            let tint = self.specular.transmittance;
            (-wo, 1.0 - r, Lobe::SingularTransmission, tint)
        };
        if p <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            value: tint * (p / cos_i),
            pdf: p,
            lobe,
        })
    }
}
