//! A light's halo (its bounding sphere) and the path tracer's mixture of cones toward halos
//! with the phase function at medium vertices and with the BSDF's own sampling at surfaces
//! without a Dirac lobe (`[render] halo_cone`).
//!
//! Why (book: "Sampling toward lights", section "The scattering direction: a cone toward the
//! halo"): in fog around a lamp, a path of two or more scattering vertices gathers most of
//! its light at a vertex near the lamp, where the lamp's direct light is orders of magnitude
//! above its mean. The phase function sends a direction toward that region with the
//! probability of its solid angle over 4 pi. Mixing in, with probability `share` (the book's
//! epsilon), a direction uniform in the cone the halo subtends puts more vertices there and
//! bounds the weight of the paths that reach it; the vertex's own sampling keeps the rest, so
//! the density never falls below (1 - share) times its own (a defensive mixture). The cone's
//! light is the one next-event estimation would choose at the vertex, so the density is a
//! sum over the lights whose cone holds the direction, each with its selection probability.
//! The cost of every density grows with the number of lights: the option is for scenes with a
//! few lamps in fog, and it is off by default.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

use super::light_tree::{LightBounds, LightSelection};
use super::Scene;
use crate::math::{Frame, Sampler};

/// The halo of one light: a ball.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Halo {
    pub centre: Vec3,
    pub radius: f32,
}

/// The cone of directions from a point outside a halo into it.
#[derive(Clone, Copy, Debug)]
pub struct Cone {
    frame: Frame,
    cos_max: f32,
    /// 1 - cos_max, computed without cancellation for small cones.
    one_minus_cos: f32,
}

impl Cone {
    /// A direction uniform in the cone from `u`.
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let cos_t = 1.0 - u.x * self.one_minus_cos;
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let local = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
        self.frame.to_world(local).normalize()
    }

    /// The solid-angle density of `w` (unit) under [`Cone::sample`]: 1 / (2 pi (1 - cos_max))
    /// inside the cone, 0 outside.
    pub fn pdf(&self, w: Vec3) -> f32 {
        if w.dot(self.frame.n) >= self.cos_max {
            self.pdf_inside()
        } else {
            0.0
        }
    }

    /// The density of every direction inside the cone: one over its solid angle.
    pub fn pdf_inside(&self) -> f32 {
        1.0 / (2.0 * PI * self.one_minus_cos)
    }
}

impl Halo {
    /// The halo of a finite light with extent: the sphere around its bounding box (`None` for
    /// point and spot lights, which have no size to scale a halo by, and for lights at
    /// infinity). A sphere 0.7 times as large leaves the fog box more error, 1.4 times the
    /// same (book: the halo section).
    pub fn of(bounds: &LightBounds) -> Option<Halo> {
        let r = 0.5 * bounds.bounds.extent().length();
        if !(r > 0.0 && r.is_finite()) {
            return None;
        }
        Some(Halo {
            centre: bounds.bounds.centroid(),
            radius: r,
        })
    }

    /// The cone from `p` into the halo; `None` when `p` is inside it (every direction leads
    /// into the halo there: the phase function serves).
    pub fn cone(&self, p: Vec3) -> Option<Cone> {
        let to = self.centre - p;
        let (d2, r2) = (to.length_squared(), self.radius * self.radius);
        // the same test as `HaloMixture::pdf`'s, so both agree on which points are inside
        if d2.is_nan() || r2 >= d2 {
            return None;
        }
        let sin2 = r2 / d2;
        let cos_max = (1.0 - sin2).sqrt();
        Some(Cone {
            frame: Frame::from_normal(to / d2.sqrt()),
            cos_max,
            one_minus_cos: sin2 / (1.0 + cos_max),
        })
    }
}

/// The path tracer's direction sampling at medium vertices and at surfaces without a Dirac
/// lobe: with probability `share` the cone toward the halo of a light chosen as next-event
/// estimation chooses it, else (and when the vertex is inside that halo) the vertex's own
/// sampling (the phase function, the BSDF).
#[derive(Clone, Debug)]
pub struct HaloMixture {
    /// The halo of each light of the scene, by index.
    halos: Vec<Option<Halo>>,
    share: f32,
}

impl HaloMixture {
    /// The mixture for `scene` with cone probability `share` (in [0, 1)); `None` when it would
    /// be the vertices' own sampling alone (share 0, or no light has a halo).
    pub fn new(scene: &Scene, share: f32) -> Option<HaloMixture> {
        let halos: Vec<Option<Halo>> = scene
            .lights
            .iter()
            .map(|l| LightBounds::of(l, &scene.prims, 1.0).and_then(|b| Halo::of(&b)))
            .collect();
        (share > 0.0 && halos.iter().any(Option::is_some)).then_some(HaloMixture { halos, share })
    }

    /// The halo of light `l`.
    pub fn halo(&self, l: usize) -> Option<Halo> {
        self.halos.get(l).copied().flatten()
    }

    /// The first choice of a direction at point `p` (surface normal `n`, `None` in a medium):
    /// with probability `share` a direction uniform in the cone toward the halo of a light
    /// chosen by `selection` (`Ok`), else (and when `p` is inside that halo) the two numbers
    /// with which the vertex's own sampling draws it (`Err`). Its density is
    /// [`HaloMixture::pdf`].
    pub fn draw(
        &self,
        scene: &Scene,
        selection: &LightSelection,
        (p, n): (Vec3, Option<Vec3>),
        sampler: &mut Sampler,
    ) -> Result<Vec3, Vec2> {
        let (u_mix, u) = (sampler.next_f32(), sampler.next_2d());
        let cone = (u_mix < self.share)
            .then(|| selection.sample(scene, p, n, u_mix / self.share))
            .flatten()
            .and_then(|(l, _, _)| self.halo(l)?.cone(p));
        match cone {
            Some(cone) => Ok(cone.sample(u)),
            None => Err(u),
        }
    }

    /// The density of `wi` at `p` (surface normal `n`) where the vertex's own sampling has
    /// density `own`: (1 - share) own + share (P_in own + sum of P(l) c_l(wi) over the lights
    /// whose halo does not hold p), where P(l) is the selection's probability of light l at
    /// p, P_in that of the lights whose halo holds p or which have none, and c_l the cone's
    /// density. The selection's probability is asked for only where it counts: lights
    /// without a halo, halos that hold p, cones that hold `wi`.
    #[inline]
    pub fn pdf(
        &self,
        scene: &Scene,
        selection: &LightSelection,
        (p, n): (Vec3, Option<Vec3>),
        own: f32,
        wi: Vec3,
    ) -> f32 {
        // one light: its probability is 1 wherever p is
        let pmf = |l: usize| match self.halos.len() {
            1 => 1.0,
            _ => selection.pmf(scene, p, n, l as u32),
        };
        let (mut p_in, mut cones) = (0.0, 0.0);
        for (l, halo) in self.halos.iter().enumerate() {
            let Some(halo) = halo else {
                p_in += pmf(l);
                continue;
            };
            let to = halo.centre - p;
            let (d2, r2) = (to.length_squared(), halo.radius * halo.radius);
            if d2.is_nan() || r2 >= d2 {
                p_in += pmf(l);
                continue;
            }
            // wi in the cone: cos(wi, to) >= cos_max, that is (wi . to)^2 >= d^2 - r^2; the
            // cone's density 1 / (2 pi (1 - cos_max)) is (1 + cos_max) d^2 / (2 pi r^2)
            let t = wi.dot(to);
            if t > 0.0 && t * t >= d2 - r2 {
                let c = (d2 + (d2 * (d2 - r2)).sqrt()) / (2.0 * PI * r2);
                cones += pmf(l) * c;
            }
        }
        (1.0 - self.share + self.share * p_in) * own + self.share * cones
    }
}
