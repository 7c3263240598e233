//! The GGX (Trowbridge-Reitz) microfacet distribution with Smith masking, and the sampling of
//! its visible normals, shared by the rough conductor and the rough dielectric.
//!
//! Every function here works in a local frame whose +z is the macro-surface normal on the side
//! the sampled-from direction `wo` lies (`wo.z > 0`); microfacet normals `m` have `m.z > 0`.
//! Slopes are taken from the tangential components (x^2 + y^2) / z^2 rather than from
//! 1 - cos^2, because at small roughness the lobe is a few milliradians wide and 1 - cos^2 in
//! f32 would have no significant digit left.
//!
//! Masking-shadowing is Smith's separable form G = G1(wo) G1(wi) (Walter et al. 2007, eq. 23),
//! the form their reflection and refraction BSDFs are written with; the height-correlated form
//! is exact only for reflection in closed form (for refraction it needs a Beta function).
//!
//! Book: "Surface scattering (eq. 2)", section "Rough surfaces"; spec: `tests/microfacet.rs`.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// The smallest roughness a scene may ask for: below it the lobe is narrower than the angular
/// resolution of f32 directions after a few dot products (a few 1e-7 rad on a 1e-3 wide lobe is
/// already 1e-4 relative error in the slopes), so a smooth material must be used instead.
pub const ALPHA_MIN: f32 = 1e-3;
/// The largest roughness a scene may ask for: at alpha = 1 half of the facets are steeper than
/// 45 degrees, and the single-scattering model already drops 69% of the light at normal
/// incidence (the white furnace of `tests/microfacet.rs`); rougher surfaces would drop more.
pub const ALPHA_MAX: f32 = 1.0;

/// The isotropic GGX distribution with roughness `alpha` (the slope scale).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub alpha: f32,
}

impl Ggx {
    /// D(m): microfacet normals per unit solid angle and unit macro-surface area, projected
    /// (integral of D(m) m.z over the hemisphere is 1). Walter et al. 2007, eq. (33), written
    /// with the slopes x/z, y/z: D = 1 / (pi a^2 z^4 (1 + (x^2 + y^2) / (a^2 z^2))^2).
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        // z^4 (1 + t^2/a^2)^2 = (z^2 + (x^2 + y^2)/a^2)^2: no division by a small z
        let k = m.z * m.z + (m.x * m.x + m.y * m.y) / a2;
        1.0 / (PI * a2 * k * k)
    }

    /// Smith's Lambda(w) for GGX: (-1 + sqrt(1 + a^2 tan^2 theta)) / 2 (Heitz 2014, eq. 72; the
    /// G1 of Walter et al. 2007, eq. (34), is 1 / (1 + Lambda)). Infinite at grazing angles.
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z2 = w.z * w.z;
        if z2 == 0.0 {
            return f32::INFINITY;
        }
        let a2_tan2 = self.alpha * self.alpha * (w.x * w.x + w.y * w.y) / z2;
        // (sqrt(1 + x) - 1) / 2 = x / (2 (sqrt(1 + x) + 1)), without cancellation at small x
        a2_tan2 / (2.0 * ((1.0 + a2_tan2).sqrt() + 1.0))
    }

    /// G1(w, m): the fraction of microfacets with normal `m` visible from `w` (Walter et al.
    /// 2007, eq. (34)): zero when `w` sees the back of the facet or lies on the other side of
    /// the macro-surface than the facet faces (the chi+ factor of eq. (34)).
    pub fn g1(&self, w: Vec3, m: Vec3) -> f32 {
        if w.dot(m) * w.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// G(wo, wi, m) = G1(wo, m) G1(wi, m): Smith's separable masking-shadowing (Walter et al.
    /// 2007, eq. (23)).
    pub fn g(&self, wo: Vec3, wi: Vec3, m: Vec3) -> f32 {
        self.g1(wo, m) * self.g1(wi, m)
    }

    /// The density of visible normals seen from `wo` (wo.z > 0): G1(wo) max(0, wo.m) D(m) /
    /// wo.z (Heitz 2018, eq. 1), the density [`Ggx::sample_visible`] draws `m` with.
    pub fn pdf_visible(&self, wo: Vec3, m: Vec3) -> f32 {
        if wo.z <= 0.0 {
            return 0.0;
        }
        let c = wo.dot(m);
        if c <= 0.0 {
            return 0.0;
        }
        self.g1(wo, m) * c * self.d(m) / wo.z
    }

    /// A microfacet normal drawn from the visible normals seen from `wo` (wo.z > 0), by Heitz
    /// 2018 (JCGT 7(4), listing of sec. 2): stretch `wo` to the configuration where the
    /// microsurface is a hemisphere (alpha = 1), sample the projected disk of that hemisphere
    /// as seen from the stretched direction (a uniform disk, its far half squeezed by the
    /// projection), lift the point onto the hemisphere and unstretch the normal.
    // ANCHOR: sample_visible
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        // ASSIGNMENT: ggx_visible_normals
        let a = self.alpha;
        // stretched view direction (Heitz 2018, sec. 2, step 1)
        let vh = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
        // an orthonormal basis around it with t1 horizontal (step 2)
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        // a point of the unit disk; the half hidden behind the hemisphere's rim is squeezed
        // into the visible part by the factor (1 + vh.z) / 2 (step 3)
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        // onto the hemisphere (step 4), then back to the ellipsoid's normal (step 5)
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(1e-7)).normalize()
        // END ASSIGNMENT
    }
    // ANCHOR_END: sample_visible
}

/// Mirror reflection of `w` about the (unit) microfacet normal `m`.
#[inline]
pub fn reflect_about(w: Vec3, m: Vec3) -> Vec3 {
    2.0 * w.dot(m) * m - w
}

/// The direction refracted from `w` through a facet with normal `m` on `w`'s side (w.m > 0),
/// for eta = eta_w / eta_other; `None` under total internal reflection.
#[inline]
pub fn refract_about(w: Vec3, m: Vec3, eta: f32) -> Option<Vec3> {
    let cos_w = w.dot(m);
    let sin2_t = eta * eta * (1.0 - cos_w * cos_w).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-eta * w + (eta * cos_w - cos_t) * m).normalize())
}
