//! Equiangular sampling of a distance along a ray toward a point (Kulla and Fajardo 2012,
//! "Importance sampling techniques for path tracing in participating media", EGSR 2012).
//!
//! Single scattering from a point light at distance `h` from the ray's line falls off as
//! 1 / (h^2 + (t - delta)^2), where `delta` is the ray parameter of the foot of the
//! perpendicular. Sampling t with exactly that density makes the angle under which the point
//! sees the ray uniform: with theta(t) = atan((t - delta) / h), theta is uniform on
//! [theta(a), theta(b)] and
//!
//! p(t) = h / ((theta(b) - theta(a)) (h^2 + (t - delta)^2)) on [a, b].
//!
//! Book: "Sampling toward lights", section "Equiangular distances"; executable spec:
//! `tests/spec/medium/equiangular.rs`.

use glam::Vec3;

/// The line of a ray as seen from a point: the foot of the perpendicular and its length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Equiangular {
    /// Ray parameter of the point of the line closest to the light point.
    pub delta: f32,
    /// Distance of the light point from the line (h > 0).
    pub h: f32,
}

impl Equiangular {
    /// The geometry of the line `o + t d` (unit `d`) seen from `y`; `None` when `y` lies on the
    /// line (h = 0: the density would be a Dirac at delta, so the strategy is not used).
    pub fn new(o: Vec3, d: Vec3, y: Vec3) -> Option<Self> {
        let to = y - o;
        let delta = to.dot(d);
        let h = (to - d * delta).length();
        (h > 0.0 && h.is_finite() && delta.is_finite()).then_some(Equiangular { delta, h })
    }

    /// theta(t) = atan((t - delta) / h), the angle between the perpendicular and the direction
    /// from the light point to the ray's point at t (pi/2 at t = infinity).
    #[inline]
    pub fn angle(&self, t: f32) -> f32 {
        ((t - self.delta) / self.h).atan()
    }

    /// d theta / dt = h / (h^2 + (t - delta)^2): the density before normalization.
    #[inline]
    pub fn angular_rate(&self, t: f32) -> f32 {
        let x = t - self.delta;
        self.h / (self.h * self.h + x * x)
    }

    /// The t in [a, b] whose angle lies the fraction `u` of the way from theta(a) to
    /// theta(b): theta uniform (Kulla and Fajardo 2012, the inverse of the angle's CDF).
    // ANCHOR: equiangular_sample
    #[inline]
    pub fn sample(&self, a: f32, b: f32, u: f32) -> f32 {
        self.sample_between((a, self.angle(a)), (b, self.angle(b)), u)
    }

    /// [`Equiangular::sample`] with the ends' angles `ta` = theta(a) and `tb` = theta(b) already
    /// known (a caller that summed them need not take the arc tangents again).
    #[inline]
    pub fn sample_between(&self, (a, ta): (f32, f32), (b, tb): (f32, f32), u: f32) -> f32 {
        let theta = ta + u * (tb - ta);
        // f32's pi/2 lies above the true one, where tan changes sign: the ends are the ends
        if theta >= std::f32::consts::FRAC_PI_2 {
            return b;
        }
        if theta <= -std::f32::consts::FRAC_PI_2 {
            return a;
        }
        (self.delta + self.h * theta.tan()).clamp(a, b)
    }

    /// The density of [`Equiangular::sample`] at t in [a, b]:
    /// h / ((theta(b) - theta(a)) (h^2 + (t - delta)^2)); 0 outside.
    #[inline]
    pub fn pdf(&self, a: f32, b: f32, t: f32) -> f32 {
        if !(a..=b).contains(&t) {
            return 0.0;
        }
        let span = self.angle(b) - self.angle(a);
        if span <= 0.0 {
            return 0.0;
        }
        self.angular_rate(t) / span
    }
    // ANCHOR_END: equiangular_sample
}
