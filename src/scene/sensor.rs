//! Virtual sensors: irradiance meters. They neither block nor scatter light; a meter measures
//! the mean irradiance E = (1/A) int_A int_{H+} L(x, w) cos(theta) dw dA over a parallelogram,
//! on the side its normal normalize(u x v) points to.

use glam::{Vec2, Vec3};

use crate::geometry::shape::Quad;
use crate::geometry::{Primitive, Ray};
use crate::math::spherical::SphericalParallelogram;

/// Below this solid angle (steradians) a meter seen from a point is sampled by area instead of
/// by solid angle. The choice depends on the point alone, so either way the estimate is
/// unbiased. Area sampling is then nearly ideal: a unit meter subtending 1e-6 sr is about 1000
/// away (face on), where cos / d^2 varies by under 0.1% over it; the spherical triangles' f64
/// arithmetic (relative error about 1e-16 / Omega) would still be exact to 1e-10.
pub const MIN_SOLID_ANGLE: f64 = 1e-6;

#[derive(Clone, Debug)]
pub struct IrradianceMeter {
    pub name: String,
    pub quad: Quad,
    /// Medium the meter sits in.
    pub medium: Option<u32>,
}

/// A point of a meter sampled for a connection from a point `x`.
#[derive(Clone, Copy, Debug)]
pub struct MeterPoint {
    pub p: Vec3,
    /// Area density of `p`.
    pub pdf_area: f32,
    /// The same density as a density of the direction from `x`: 1 / Omega when sampled by
    /// solid angle (exactly, whatever the distance), pdf_area d^2 / |cos| when by area.
    pub pdf_solid_angle: f32,
}

/// A meter as seen from a point `x` in front of it: how connections from `x` sample it.
#[derive(Clone, Copy, Debug)]
pub struct MeterConnection {
    x: Vec3,
    quad: Quad,
    /// The meter's spherical parallelogram at `x` when it is sampled by solid angle.
    solid: Option<SphericalParallelogram>,
}

impl IrradianceMeter {
    pub fn normal(&self) -> Vec3 {
        self.quad.n
    }

    /// The connections from `x` to the meter (light tracing): points uniform in the solid angle
    /// the meter subtends at `x` (its two spherical triangles, Arvo 1995), or uniform by area
    /// when that solid angle is below [`MIN_SOLID_ANGLE`]. `None` when `x` is not in front of
    /// the meter (it cannot see the side the meter measures).
    pub fn connection_from(&self, x: Vec3) -> Option<MeterConnection> {
        let q = self.quad;
        if (x - q.origin).dot(q.n) <= 0.0 {
            return None;
        }
        let solid = SphericalParallelogram::new(x, q.origin, q.u, q.v)
            .filter(|sp| sp.solid_angle() >= MIN_SOLID_ANGLE);
        Some(MeterConnection { x, quad: q, solid })
    }

    /// A point of the meter for a connection from `x` ([`IrradianceMeter::connection_from`]).
    pub fn sample_point_from(&self, x: Vec3, u: Vec2) -> Option<MeterPoint> {
        self.connection_from(x)?.sample(u)
    }
}

impl MeterConnection {
    /// The solid angle the meter subtends, when it is sampled by solid angle.
    pub fn solid_angle(&self) -> Option<f64> {
        self.solid.map(|sp| sp.solid_angle())
    }

    fn area(&self) -> f32 {
        Primitive::Quad(self.quad).area()
    }

    /// A point of the meter with its densities.
    pub fn sample(&self, u: Vec2) -> Option<MeterPoint> {
        match &self.solid {
            Some(sp) => {
                let s = sp.sample(u)?;
                Some(MeterPoint {
                    p: s.p,
                    pdf_area: s.pdf_area,
                    pdf_solid_angle: s.pdf_solid_angle,
                })
            }
            None => {
                let (p, _) = Primitive::Quad(self.quad).sample_area(u);
                Some(MeterPoint {
                    p,
                    pdf_area: 1.0 / self.area(),
                    pdf_solid_angle: self.pdf_solid_angle(p),
                })
            }
        }
    }

    /// The density of [`MeterConnection::sample`] for the direction from `x` to the meter
    /// point `p`, per solid angle at `x`.
    pub fn pdf_solid_angle(&self, p: Vec3) -> f32 {
        match &self.solid {
            Some(sp) => (1.0 / sp.solid_angle()) as f32,
            None => {
                let d = p - self.x;
                let d2 = d.length_squared();
                let cos = self.quad.n.dot(d).abs() / d2.sqrt();
                if cos > 0.0 {
                    d2 / (cos * self.area())
                } else {
                    0.0
                }
            }
        }
    }

    /// The density of [`MeterConnection::sample`] for the meter point `p`, per area.
    pub fn pdf_area(&self, p: Vec3) -> f32 {
        match &self.solid {
            Some(sp) => {
                let d = p - self.x;
                let d2 = d.length_squared();
                let cos = self.quad.n.dot(d).abs() / d2.sqrt();
                (cos as f64 / (sp.solid_angle() * d2 as f64)) as f32
            }
            None => 1.0 / self.area(),
        }
    }

    /// The meter point the ray from `x` along the unit direction `w` crosses, if any.
    pub fn hit(&self, w: Vec3) -> Option<Vec3> {
        Primitive::Quad(self.quad)
            .intersect(&Ray::new(self.x, w), f32::INFINITY)
            .map(|(_, p, _)| p)
    }
}
