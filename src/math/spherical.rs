//! Sampling by solid angle: a spherical triangle (Arvo 1995, "Stratified sampling of spherical
//! triangles", SIGGRAPH '95, sec. 3 and Fig. 2) and a parallelogram seen from a point, as the
//! two spherical triangles either side of a diagonal.
//!
//! Everything is computed in f64: Arvo's inversion subtracts angles of order one to get a
//! sub-area of order the solid angle, so f32 loses the small triangles that a meter seen from a
//! few metres away makes. Book: "Bidirectional path tracing", section "Light tracing and
//! irradiance meters"; executable spec: `tests/spec/math/warp.rs` (chi-square of the directions, the
//! density integrated over the parallelogram).

use glam::{DVec3, Vec2, Vec3};

/// The solid angle of the spherical triangle with unit vertices `a`, `b`, `c` (Van Oosterom and
/// Strackee 1983: tan(Omega / 2) = |a . (b x c)| / (1 + a.b + b.c + c.a)); `atan2` keeps it
/// exact for small triangles and right beyond a hemisphere's half.
pub fn spherical_triangle_area(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let num = a.dot(b.cross(c)).abs();
    let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
    2.0 * num.atan2(den)
}

/// The interior angle at `a` of the spherical triangle `a`, `b`, `c` (unit vectors): the angle
/// between the great arcs a-b and a-c, from their tangents at `a`.
fn vertex_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let tb = b - a * a.dot(b);
    let tc = c - a * a.dot(c);
    tb.cross(tc).length().atan2(tb.dot(tc))
}

/// The unit component of `x` orthogonal to the unit vector `a` (zero if `x` is along `a`).
fn orthonormal(x: DVec3, a: DVec3) -> DVec3 {
    (x - a * x.dot(a)).normalize_or_zero()
}

/// A direction uniformly distributed by solid angle in the spherical triangle with unit
/// vertices `a`, `b`, `c` and area `area` ([`spherical_triangle_area`]); density 1 / area.
///
/// Arvo 1995, Fig. 2: `u.x` fixes the sub-triangle `a b c'` of area `u.x * area` (c' on the arc
/// a-c), `u.y` the point on the arc from `b` to `c'`, uniform in the cosine to `b`.
pub fn sample_spherical_triangle(a: DVec3, b: DVec3, c: DVec3, area: f64, u: Vec2) -> DVec3 {
    let alpha = vertex_angle(a, b, c);
    let (sin_alpha, cos_alpha) = alpha.sin_cos();
    let cos_c = a.dot(b);
    let sub_area = u.x as f64 * area;
    let (s, t) = (sub_area - alpha).sin_cos();
    let uu = t - cos_alpha;
    let vv = s + sin_alpha * cos_c;
    // the cosine of the arc from a to c'
    let den = (vv * s + uu * t) * sin_alpha;
    let q = if den != 0.0 {
        (((vv * t - uu * s) * cos_alpha - vv) / den).clamp(-1.0, 1.0)
    } else {
        // a degenerate triangle (alpha = 0 or pi): c' = c
        a.dot(c)
    };
    let c_sub = a * q + orthonormal(c, a) * (1.0 - q * q).max(0.0).sqrt();
    let z = (1.0 - u.y as f64 * (1.0 - c_sub.dot(b))).clamp(-1.0, 1.0);
    (b * z + orthonormal(c_sub, b) * (1.0 - z * z).max(0.0).sqrt()).normalize()
}

/// A parallelogram `origin + a u + b v` (a, b in [0, 1]) as seen from the point `x`: the two
/// spherical triangles (p0, p1, p2) and (p0, p2, p3) of its corners' directions, which tile its
/// solid angle when `x` is off its plane (a convex polygon projects to a convex spherical one).
#[derive(Clone, Copy, Debug)]
pub struct SphericalParallelogram {
    x: DVec3,
    origin: DVec3,
    u: DVec3,
    v: DVec3,
    /// Unit directions from `x` to the corners origin, origin + u, origin + u + v, origin + v.
    corners: [DVec3; 4],
    /// Solid angles of the triangles (0, 1, 2) and (0, 2, 3).
    areas: [f64; 2],
}

/// A direction sampled towards a parallelogram and the point it hits.
#[derive(Clone, Copy, Debug)]
pub struct ParallelogramSample {
    /// Unit direction from the reference point.
    pub wi: Vec3,
    /// The point of the parallelogram along `wi`.
    pub p: Vec3,
    /// Distance from the reference point to `p`.
    pub dist: f32,
    /// Solid-angle density of `wi`: 1 / solid angle.
    pub pdf_solid_angle: f32,
    /// The same density as an area density on the parallelogram: |n . wi| / (Omega dist^2).
    pub pdf_area: f32,
}

impl SphericalParallelogram {
    /// The parallelogram seen from `x`; `None` when `x` lies in its plane (no solid angle) or
    /// the corners are not distinct directions.
    pub fn new(x: Vec3, origin: Vec3, u: Vec3, v: Vec3) -> Option<Self> {
        let (x, o, u, v) = (x.as_dvec3(), origin.as_dvec3(), u.as_dvec3(), v.as_dvec3());
        let n = u.cross(v);
        if n.dot(o - x) == 0.0 || n == DVec3::ZERO {
            return None;
        }
        let corners = [o, o + u, o + u + v, o + v].map(|p| (p - x).normalize_or_zero());
        if corners.contains(&DVec3::ZERO) {
            return None;
        }
        let areas = [
            spherical_triangle_area(corners[0], corners[1], corners[2]),
            spherical_triangle_area(corners[0], corners[2], corners[3]),
        ];
        Some(SphericalParallelogram {
            x,
            origin: o,
            u,
            v,
            corners,
            areas,
        })
    }

    /// The triangle `p0 p1 p2` seen from `x`, as the first half (p0, p1, p2) of the
    /// parallelogram with corners p0, p1, p2 and p0 + p2 - p1, its second half given no solid
    /// angle: [`SphericalParallelogram::sample`] then draws from the triangle alone, and the
    /// point it returns lies in it. `None` as for [`SphericalParallelogram::new`].
    pub fn triangle(x: Vec3, p0: Vec3, p1: Vec3, p2: Vec3) -> Option<Self> {
        let mut view = Self::new(x, p0, p1 - p0, p2 - p1)?;
        view.areas[1] = 0.0;
        Some(view)
    }

    /// The solid angle the parallelogram subtends at the reference point.
    pub fn solid_angle(&self) -> f64 {
        self.areas[0] + self.areas[1]
    }

    /// A direction uniformly distributed by solid angle over the parallelogram, and the point
    /// it hits: `u.x` picks a triangle in proportion to its solid angle and is reused within it.
    pub fn sample(&self, u: Vec2) -> Option<ParallelogramSample> {
        let total = self.solid_angle();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let p_first = self.areas[0] / total;
        let ux = u.x as f64;
        let (tri, ux) = if ux < p_first {
            (0, ux / p_first)
        } else {
            (1, ((ux - p_first) / (1.0 - p_first)).min(1.0))
        };
        let [c0, c1, c2, c3] = self.corners;
        let (a, b, c) = if tri == 0 { (c0, c1, c2) } else { (c0, c2, c3) };
        let w =
            sample_spherical_triangle(a, b, c, self.areas[tri], Vec2::new(ux.min(1.0) as f32, u.y));
        // the plane of the parallelogram along w, in the barycentric coordinates (a, b)
        let n = self.u.cross(self.v);
        let cos = n.dot(w);
        let dist = n.dot(self.origin - self.x) / cos;
        if !(dist > 0.0 && dist.is_finite()) {
            return None;
        }
        let rel = self.x + w * dist - self.origin;
        let inv = 1.0 / n.length_squared();
        let ca = (rel.cross(self.v).dot(n) * inv).clamp(0.0, 1.0);
        let cb = (self.u.cross(rel).dot(n) * inv).clamp(0.0, 1.0);
        let p = self.origin + self.u * ca + self.v * cb;
        let cos_p = cos.abs() / n.length();
        Some(ParallelogramSample {
            wi: w.as_vec3(),
            p: p.as_vec3(),
            dist: dist as f32,
            pdf_solid_angle: (1.0 / total) as f32,
            pdf_area: (cos_p / (total * dist * dist)) as f32,
        })
    }
}
