//! The Lambertian reflector: f_s = rho / pi for every pair of directions on one side, two-sided
//! (it reflects on whichever side `wo` is) unless `one_sided`. Sampled from the cosine-weighted
//! hemisphere on `wo`'s side, so the weight is rho.

use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

use super::{BsdfModel, BsdfSample, Lobe, TransportMode};
use crate::math::{warp, Frame};
use crate::spectrum::Rgb;

/// rho / pi on both sides, or on the normal's side only (`one_sided`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// rho, the reflectance.
    pub albedo: Rgb,
    /// Black behind the normal (see `Bsdf::black_behind`).
    pub one_sided: bool,
}

impl BsdfModel for Lambert {
    fn albedo(&self, _cos: f32) -> Rgb {
        self.albedo
    }

    fn describe(&self) -> String {
        format!("lambert, albedo {}", crate::spectrum::show(self.albedo))
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

    /// rho / pi when both directions are on one side (reflection only), else zero.
    fn eval(&self, wo: Vec3, wi: Vec3, n: Vec3, _mode: TransportMode) -> Rgb {
        if wo.dot(n) * wi.dot(n) > 0.0 {
            self.albedo * FRAC_1_PI
        } else {
            Rgb::ZERO
        }
    }

    /// Cosine-weighted on wo's side: |cos wi| / pi, zero across the surface.
    fn pdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        if wo.dot(n) * wi.dot(n) > 0.0 {
            wi.dot(n).abs() * FRAC_1_PI
        } else {
            0.0
        }
    }

    fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        u: Vec2,
        _uc: f32,
        _mode: TransportMode,
    ) -> Option<BsdfSample> {
        let nf = if wo.dot(n) > 0.0 { n } else { -n };
        let local = warp::cosine_hemisphere(u);
        if local.z <= 0.0 {
            return None;
        }
        let wi = Frame::from_normal(nf).to_world(local);
        Some(BsdfSample {
            wi,
            value: self.albedo * FRAC_1_PI,
            pdf: local.z * FRAC_1_PI,
            lobe: Lobe::Regular,
        })
    }
}
