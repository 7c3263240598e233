//! Virtual sensors: irradiance meters. They neither block nor scatter light; a meter measures
//! the mean irradiance E = (1/A) int_A int_{H+} L(x, w) cos(theta) dw dA over a parallelogram,
//! on the side its normal normalize(u x v) points to.

use glam::Vec3;

use crate::geometry::shape::Quad;

#[derive(Clone, Debug)]
pub struct IrradianceMeter {
    pub name: String,
    pub quad: Quad,
    /// Medium the meter sits in.
    pub medium: Option<u32>,
}

impl IrradianceMeter {
    pub fn normal(&self) -> Vec3 {
        self.quad.n
    }
}
