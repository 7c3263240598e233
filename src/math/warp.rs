//! Warps from the unit square to directions and points, each with its density.
//! Book: "Sampling toolbox"; executable spec: `tests/spec/math/warp.rs` (a chi-square test of every warp
//! against the density stated here).

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// 1 / (4 pi): the density of the uniform sphere.
pub const INV_FOUR_PI: f32 = 0.25 * FRAC_1_PI;

/// Uniform direction on the unit sphere; density `INV_FOUR_PI` (solid angle).
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// The inverse of [`uniform_sphere`]: the `u` that maps to the unit direction `w`.
pub fn uniform_sphere_inverse(w: Vec3) -> Vec2 {
    let mut phi = w.y.atan2(w.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    Vec2::new(0.5 * (1.0 - w.z), phi / (2.0 * PI))
}

/// Cosine-weighted direction on the +z hemisphere (Malley's method); density `cos / pi`.
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Density of [`cosine_hemisphere`] for a local direction.
#[inline]
pub fn cosine_hemisphere_pdf(local: Vec3) -> f32 {
    local.z.max(0.0) * FRAC_1_PI
}

/// Shirley-Chiu concentric map from the square to the unit disk (area preserving up to pi).
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, (PI / 4.0) * (o.y / o.x))
    } else {
        (o.y, PI / 2.0 - (PI / 4.0) * (o.x / o.y))
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// The inverse of [`concentric_disk`]: the `u` in [0, 1]^2 that maps to the point `d` of the
/// unit disk (the disk's point sampled on an emitter, for the adjoint image's cells).
pub fn concentric_disk_inverse(d: Vec2) -> Vec2 {
    let r = d.length();
    if r == 0.0 {
        return Vec2::splat(0.5);
    }
    // theta in (-pi/4, 7pi/4]: the square's four triangles, as `concentric_disk` splits them
    let mut theta = d.y.atan2(d.x);
    if theta < -PI / 4.0 {
        theta += 2.0 * PI;
    }
    let o = if theta < PI / 4.0 {
        Vec2::new(r, r * theta / (PI / 4.0))
    } else if theta < 3.0 * PI / 4.0 {
        Vec2::new(r * (PI / 2.0 - theta) / (PI / 4.0), r)
    } else if theta < 5.0 * PI / 4.0 {
        Vec2::new(-r, r * (PI - theta) / (PI / 4.0))
    } else {
        Vec2::new(-r * (3.0 * PI / 2.0 - theta) / (PI / 4.0), -r)
    };
    (o + Vec2::ONE) * 0.5
}

/// Uniform point on a triangle as two barycentrics (b0, b1), the third being 1 - b0 - b1
/// (Heitz 2019, "A low-distortion map between triangle and square", listing 1); density 2 on
/// {b0, b1 >= 0, b0 + b1 <= 1}.
// ANCHOR: uniform_triangle
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    // ASSIGNMENT: uniform_triangle
    let (mut b0, mut b1) = (u.x / 2.0, u.y / 2.0);
    // the offset is between the halved coordinates: with u.y - u.x instead, u = (0, 1) maps to
    // (0, 1.5), outside the triangle
    let offset = b1 - b0;
    if offset > 0.0 {
        b1 += offset;
    } else {
        b0 -= offset;
    }
    Vec2::new(b0, b1)
    // END ASSIGNMENT
}
// ANCHOR_END: uniform_triangle

/// The inverse of [`uniform_triangle`]: the `u` that maps to barycentrics (b0, b1).
pub fn uniform_triangle_inverse(b: Vec2) -> Vec2 {
    if b.y > b.x {
        // the offset > 0 branch: b0 = u.x / 2, b1 = u.y - u.x / 2
        Vec2::new(2.0 * b.x, b.y + b.x)
    } else {
        // b1 = u.y / 2, b0 = u.x - u.y / 2
        Vec2::new(b.x + b.y, 2.0 * b.y)
    }
}

/// Uniform direction inside a cone of half-angle `acos(cos_max)` around +z; density
/// `1 / (2 pi (1 - cos_max))`.
pub fn uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    let cos_t = 1.0 - u.x * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}
