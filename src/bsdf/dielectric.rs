//! The smooth dielectric interface: Fresnel-weighted Dirac reflection and refraction (Snell's
//! law), reflection chosen with probability F so that both weights are 1 (times the eta^2 of
//! refracted radiance, Kristensen 2010 eq. 2.15).

use glam::{Vec2, Vec3};

use super::{fresnel_dielectric, reflect, BsdfModel, BsdfSample, Lobe, TransportMode};
use crate::spectrum::Rgb;

/// A smooth dielectric interface; `ior` is inside (behind the normal) over outside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    pub ior: f32,
}

impl BsdfModel for Dielectric {
    /// 1: the colour of what is seen through it is not its own.
    fn albedo(&self, _cos: f32) -> Rgb {
        Rgb::ONE
    }

    fn describe(&self) -> String {
        format!("dielectric, ior {}", self.ior)
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
                value: Rgb::splat(f / cos_i),
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
            value: Rgb::splat((1.0 - f) * scale / cos_t),
            pdf: 1.0 - f,
            lobe: Lobe::SingularTransmission,
        })
    }
    // ANCHOR_END: dielectric_sample
}
