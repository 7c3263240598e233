//! The perfect mirror: a Dirac reflection with a constant reflectance R, two-sided unless
//! `one_sided`. Its value is R / |cos wi| with probability 1, so the weight is R.

use glam::{Vec2, Vec3};

use super::{reflect, BsdfModel, BsdfSample, Lobe, TransportMode};
use crate::spectrum::Rgb;

/// A perfect mirror with a constant reflectance (black behind the normal if `one_sided`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mirror {
    /// R, the fraction of light reflected.
    pub reflectance: Rgb,
    /// Black behind the normal (see `Bsdf::black_behind`).
    pub one_sided: bool,
}

impl BsdfModel for Mirror {
    fn albedo(&self, _cos: f32) -> Rgb {
        self.reflectance
    }

    fn describe(&self) -> String {
        format!(
            "mirror, reflectance {}",
            crate::spectrum::show(self.reflectance)
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

    fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        _u: Vec2,
        _uc: f32,
        _mode: TransportMode,
    ) -> Option<BsdfSample> {
        Some(mirror_reflection(wo, n, |_| self.reflectance))
    }
}

/// The mirror direction of `wo` about `n` (on `wo`'s side), drawn with probability 1, and its
/// weight `reflectance(cos) / cos` at `wo`'s cosine (the cosine the integrators multiply back;
/// reflection keeps the angle, so the value is reciprocal). Shared by [`Mirror`] and the
/// smooth conductor, whose reflectance is a Fresnel term of the angle.
pub(super) fn mirror_reflection(
    wo: Vec3,
    n: Vec3,
    reflectance: impl FnOnce(f32) -> Rgb,
) -> BsdfSample {
    let nf = if wo.dot(n) > 0.0 { n } else { -n };
    let wi = reflect(wo, nf);
    let c = wi.dot(nf).abs();
    BsdfSample {
        wi,
        value: reflectance(wo.dot(nf)) / c,
        pdf: 1.0,
        lobe: Lobe::SingularReflection,
    }
}
