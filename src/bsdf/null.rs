//! The null (index-matched) boundary: light passes unchanged, so it only separates media.
//! Tracing skips it (`Bsdf::is_null`); it is never a scattering vertex, and answers no value, no
//! density and no sample.

use glam::{Vec2, Vec3};

use super::{BsdfModel, BsdfSample, TransportMode};
use crate::spectrum::Rgb;

/// An index-matched boundary: light passes unchanged. Never a scattering vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Null;

impl BsdfModel for Null {
    /// Never a scattering vertex.
    fn albedo(&self, _cos: f32) -> Rgb {
        Rgb::ZERO
    }

    fn describe(&self) -> String {
        "null (index-matched boundary)".into()
    }

    fn has_regular_lobe(&self) -> bool {
        false
    }
    fn has_dirac_lobe(&self) -> bool {
        false
    }
    /// All of the light passes (the boundary is skipped, not scattered at).
    fn transmits(&self) -> bool {
        true
    }
    fn one_sided(&self) -> bool {
        false
    }
    fn eval(&self, _wo: Vec3, _wi: Vec3, _n: Vec3, _mode: TransportMode) -> Rgb {
        Rgb::ZERO
    }
    fn pdf(&self, _wo: Vec3, _wi: Vec3, _n: Vec3) -> f32 {
        0.0
    }
    fn sample(
        &self,
        _wo: Vec3,
        _n: Vec3,
        _u: Vec2,
        _uc: f32,
        _mode: TransportMode,
    ) -> Option<BsdfSample> {
        None
    }
}
