//! Primitives: parallelograms ("quads"), triangles, spheres, (elliptic) disks and open
//! cylinders, with intersection and uniform
//! area sampling (area lights, irradiance meters and BDPT need points with an area density).

use glam::{Vec2, Vec3, Vec3Swizzles};

use super::{Aabb, Ray};
use crate::math::distribution::ONE_MINUS_EPSILON;
use crate::math::{warp, Frame};

/// A parallelogram `origin + a u + b v`, a, b in [0, 1]; geometric normal `normalize(u x v)`,
/// or its opposite once [`Quad::flipped`].
#[derive(Clone, Copy, Debug)]
pub struct Quad {
    pub origin: Vec3,
    pub u: Vec3,
    pub v: Vec3,
    /// Unit normal `normalize(u x v)` (negated when flipped).
    pub n: Vec3,
    /// `(u x v) / |u x v|^2`, for the barycentric coordinates of a hit (read by the quad
    /// lanes of `geometry::leaf` too).
    pub(super) w: Vec3,
    area: f32,
}

impl Quad {
    /// A parallelogram; `None` when `u` and `v` are parallel (zero area).
    pub fn new(origin: Vec3, u: Vec3, v: Vec3) -> Option<Self> {
        let (n, w, len) = plane_of(u, v)?;
        Some(Quad {
            origin,
            u,
            v,
            n,
            w,
            area: len,
        })
    }
}

impl Quad {
    /// The same quad with the opposite normal and the same coordinates (a, b): Mitsuba 3's
    /// `flip_normals` turns a `rectangle` around without changing its (u, v).
    pub fn flipped(self) -> Self {
        Quad { n: -self.n, ..self }
    }

    /// The coordinates (a, b) of `p` along `u` and `v`: `p = origin + a u + b v` when `p` lies
    /// in the quad's plane, and the quad is `[0, 1]^2`.
    #[inline]
    pub fn coordinates(&self, p: Vec3) -> (f32, f32) {
        let rel = p - self.origin;
        (self.w.dot(rel.cross(self.v)), self.w.dot(self.u.cross(rel)))
    }

    /// The point `origin + a u + b v` at coordinates (a, b): a hit reprojected onto the plane,
    /// or a sampled point.
    #[inline]
    pub fn point(&self, a: f32, b: f32) -> Vec3 {
        self.origin + a * self.u + b * self.v
    }

    /// The four corners.
    pub fn corners(&self) -> [Vec3; 4] {
        let o = self.origin;
        [o, o + self.u, o + self.u + self.v, o + self.v]
    }
}

/// The plane spanned by `u` and `v`: the unit normal `normalize(u x v)`, the vector
/// `(u x v) / |u x v|^2` that gives a point's coordinates along u and v, and `|u x v|`; `None`
/// when u and v are parallel.
fn plane_of(u: Vec3, v: Vec3) -> Option<(Vec3, Vec3, f32)> {
    let c = u.cross(v);
    let len2 = c.length_squared();
    if len2 <= 0.0 || !len2.is_finite() {
        return None;
    }
    Some((c / len2.sqrt(), c / len2, len2.sqrt()))
}

/// A triangle `p0 + b1 e1 + b2 e2` with `e1 = p1 - p0`, `e2 = p2 - p0`; geometric normal
/// `normalize(e1 x e2)`, or its opposite once [`Triangle::flipped`]. The corners are stored as
/// given (not as p0 plus edges, which rounds): triangles of a mesh that share a corner must see
/// the very same point, or the watertight test ([`Triangle::intersect_range`]) cannot close
/// their common edge.
#[derive(Clone, Copy, Debug)]
pub struct Triangle {
    pub p0: Vec3,
    pub p1: Vec3,
    pub p2: Vec3,
    pub n: Vec3,
    area: f32,
}

impl Triangle {
    /// A triangle; `None` when degenerate.
    pub fn new(p0: Vec3, p1: Vec3, p2: Vec3) -> Option<Self> {
        let c = (p1 - p0).cross(p2 - p0);
        let len = c.length();
        if len <= 0.0 || !len.is_finite() {
            return None;
        }
        Some(Triangle {
            p0,
            p1,
            p2,
            n: c / len,
            area: 0.5 * len,
        })
    }

    /// The same triangle with the opposite normal, its corners (and so its hits, barycentrics
    /// and (u, v)) unchanged: Mitsuba 3's `flip_normals` on a mesh negates the geometric and the
    /// shading normal only (`src/render/mesh.cpp`, `compute_surface_interaction`).
    pub fn flipped(self) -> Self {
        Triangle { n: -self.n, ..self }
    }

    /// The edge `p1 - p0`.
    #[inline]
    pub fn e1(&self) -> Vec3 {
        self.p1 - self.p0
    }

    /// The edge `p2 - p0`.
    #[inline]
    pub fn e2(&self) -> Vec3 {
        self.p2 - self.p0
    }

    // ANCHOR: watertight
    /// The intersection with `t` in (t_min, t_max), as (t, b1, b2): the hit is
    /// `p0 + b1 e1 + b2 e2`. Watertight (Woop, Benthin and Wald 2013, "Watertight Ray/Triangle
    /// Intersection", JCGT 2(1), sec. 3-4): the corners are moved into a frame where the ray is
    /// the +z axis through the origin, and the 2-D edge functions there decide inside or out.
    /// A corner's image depends only on the corner and the ray, and an edge's function is the
    /// same products in either direction, so the two triangles of a shared edge compute exactly
    /// opposite values: a ray through the edge is inside one of them or on the edge of both,
    /// never outside both. A function that rounds to 0 is recomputed in f64, where the product
    /// of two f32 is exact (the paper's fallback), so that 0 means the ray is really on the edge.
    #[inline]
    pub fn intersect_range(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
        let s = RayShear::new(ray);
        let [a, b, c] = s.apply([self.p0 - ray.o, self.p1 - ray.o, self.p2 - ray.o]);
        let (mut u, mut v, mut w) = (edge(c, b), edge(a, c), edge(b, a));
        if u == 0.0 || v == 0.0 || w == 0.0 {
            (u, v, w) = (edge_f64(c, b), edge_f64(a, c), edge_f64(b, a));
        }
        // both sides: outside when the signs differ (0 counts as either)
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 {
            return None;
        }
        let inv = 1.0 / det;
        // z in the frame is distance along the ray
        let t = (u * a.z + v * b.z + w * c.z) * s.sz * inv;
        if !(t > t_min && t < t_max) {
            return None;
        }
        Some((t, v * inv, w * inv))
    }
    // ANCHOR_END: watertight

    /// The point at barycentrics (b1, b2): `p0 + b1 e1 + b2 e2`.
    #[inline]
    pub fn point(&self, b1: f32, b2: f32) -> Vec3 {
        self.p0 + b1 * self.e1() + b2 * self.e2()
    }
}

/// The ray's frame of the watertight test (Woop et al. 2013, sec. 3): the axis `kz` where the
/// direction is largest becomes z, the other two follow it cyclically, and a shear maps the
/// direction to +z. (The paper also swaps x and y when d[kz] < 0 to keep the winding for
/// back-face culling; a two-sided test does not need it: the swap only negates every edge
/// function exactly.) The scale 1 / d[kz] that makes z the distance along the ray is applied
/// once, to the interpolated z of a hit. Leaves of triangles (`geometry::leaf`) set it up once
/// per ray.
pub struct RayShear {
    /// The axis that becomes z; x and y are the next two, cyclically.
    pub kz: usize,
    pub sx: f32,
    pub sy: f32,
    pub sz: f32,
}

impl RayShear {
    #[inline]
    pub fn new(ray: &Ray) -> Self {
        let ad = ray.d.abs();
        let kz = if ad.x > ad.y && ad.x > ad.z {
            0
        } else if ad.y > ad.z {
            1
        } else {
            2
        };
        let d = cyclic(ray.d, kz);
        let sz = 1.0 / d.z;
        RayShear {
            kz,
            sx: d.x * sz,
            sy: d.y * sz,
            sz,
        }
    }

    /// Points relative to the ray's origin in the ray's frame, z not yet scaled by `sz`.
    #[inline]
    fn apply(&self, ps: [Vec3; 3]) -> [Vec3; 3] {
        ps.map(|p| {
            let p = cyclic(p, self.kz);
            Vec3::new(p.x - self.sx * p.z, p.y - self.sy * p.z, p.z)
        })
    }
}

/// `p`'s coordinates in the cyclic order that ends with axis `kz`.
#[inline]
fn cyclic(p: Vec3, kz: usize) -> Vec3 {
    match kz {
        0 => p.yzx(),
        1 => p.zxy(),
        _ => p,
    }
}

/// The 2-D edge function of the frame's points `p`, `q` (twice the signed area of the triangle
/// they make with the ray's axis); `edge(q, p)` is exactly `-edge(p, q)`.
#[inline]
fn edge(p: Vec3, q: Vec3) -> f32 {
    p.x * q.y - p.y * q.x
}

/// [`edge`] in f64, where the two products are exact.
#[inline]
pub fn edge_f64(p: Vec3, q: Vec3) -> f32 {
    (p.x as f64 * q.y as f64 - p.y as f64 * q.x as f64) as f32
}

impl Triangle {
    /// The barycentric coordinates (b1, b2) of a point `p` of the triangle's plane:
    /// `p = p0 + b1 e1 + b2 e2`.
    pub fn barycentric(&self, p: Vec3) -> (f32, f32) {
        let (r, e1, e2) = (p - self.p0, self.e1(), self.e2());
        let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let (r1, r2) = (r.dot(e1), r.dot(e2));
        let det = d11 * d22 - d12 * d12;
        ((d22 * r1 - d12 * r2) / det, (d11 * r2 - d12 * r1) / det)
    }

    /// The shading normal at `p` from the corner normals `n`: `n0 + b1 (n1 - n0) + b2 (n2 -
    /// n0)` normalized, as Mitsuba 3's meshes interpolate it; the geometric normal where that
    /// vanishes.
    pub fn shading_normal(&self, n: &[Vec3; 3], p: Vec3) -> Vec3 {
        let (b1, b2) = self.barycentric(p);
        let s = (n[0] + b1 * (n[1] - n[0]) + b2 * (n[2] - n[0])).normalize_or_zero();
        if s != Vec3::ZERO && s.is_finite() {
            s
        } else {
            self.n
        }
    }
}

/// An elliptic disk `center + a u + b v`, a^2 + b^2 <= 1 (Mitsuba's unit `disk` under an affine
/// map: `u`, `v` are the images of its x and y axes); geometric normal `normalize(u x v)`, or
/// its opposite once [`Disk::flipped`].
#[derive(Clone, Copy, Debug)]
pub struct Disk {
    pub center: Vec3,
    pub u: Vec3,
    pub v: Vec3,
    /// Unit normal `normalize(u x v)` (negated when flipped).
    pub n: Vec3,
    /// `(u x v) / |u x v|^2`, for the coordinates (a, b) of a hit, as for [`Quad`].
    w: Vec3,
    area: f32,
}

impl Disk {
    /// A disk; `None` when `u` and `v` are parallel (zero area).
    pub fn new(center: Vec3, u: Vec3, v: Vec3) -> Option<Self> {
        let (n, w, len) = plane_of(u, v)?;
        Some(Disk {
            center,
            u,
            v,
            n,
            w,
            area: std::f32::consts::PI * len,
        })
    }

    /// The same disk with the opposite normal and the same coordinates: Mitsuba 3's
    /// `flip_normals` mirrors the disk's local z only, so its (u, v) stay.
    pub fn flipped(self) -> Self {
        Disk { n: -self.n, ..self }
    }
}

/// A sphere; the geometric normal points outwards.
#[derive(Clone, Copy, Debug)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
    /// The sphere's own axes (x, y, z) as `s`, `t`, `n`, from which its (u, v) are measured:
    /// Mitsuba 3's `sphere` takes them from the rotation in its `to_world`.
    pub frame: Frame,
}

impl Sphere {
    /// A sphere with the world's axes as its own.
    pub fn new(center: Vec3, radius: f32) -> Self {
        let frame = Frame {
            s: Vec3::X,
            t: Vec3::Y,
            n: Vec3::Z,
        };
        Sphere {
            center,
            radius,
            frame,
        }
    }
}

/// An open cylinder (Mitsuba 3 documentation, plugin `cylinder`): the points at distance
/// `radius` from the segment `p0 + z axis`, z in [0, length], without caps; the normal points
/// away from the axis, towards it when `flip`.
#[derive(Clone, Copy, Debug)]
pub struct Cylinder {
    pub p0: Vec3,
    /// The unit direction from `p0` to the other end.
    pub axis: Vec3,
    pub length: f32,
    pub radius: f32,
    pub flip: bool,
    /// Two unit vectors completing `axis` to a right-handed frame: the angle phi of a point is
    /// measured from `x` towards `y`. By default Mitsuba 3's `Frame3f(axis)` (Duff et al.'s
    /// basis, as [`Frame::from_normal`]); an imported cylinder under a `to_world` takes the
    /// image of that frame's `s` ([`Cylinder::with_x_axis`]).
    x: Vec3,
    y: Vec3,
}

impl Cylinder {
    /// The cylinder from `p0` to `p1`; `None` when they coincide or the radius is not positive.
    pub fn new(p0: Vec3, p1: Vec3, radius: f32, flip: bool) -> Option<Self> {
        let d = p1 - p0;
        let length = d.length();
        if !(length > 0.0 && length.is_finite() && radius > 0.0 && radius.is_finite()) {
            return None;
        }
        let axis = d / length;
        let frame = Frame::from_normal(axis);
        Some(Cylinder {
            p0,
            axis,
            length,
            radius,
            flip,
            x: frame.s,
            y: frame.t,
        })
    }

    /// The same cylinder with phi measured from the direction `x`; `None` unless `x` is
    /// (within 1e-3 of its length) perpendicular to the axis. It is made exactly perpendicular
    /// (Gram-Schmidt), so an axis rounded to f32 keeps the frame orthonormal.
    pub fn with_x_axis(self, x: Vec3) -> Option<Self> {
        let len = x.length();
        let along = x.dot(self.axis);
        if !(len > 0.0 && len.is_finite() && along.abs() <= 1e-3 * len) {
            return None;
        }
        let x = (x - along * self.axis).normalize();
        let y = self.axis.cross(x);
        Some(Cylinder { x, y, ..self })
    }

    /// The point at height `z` along the axis and angle `phi`, and its unit normal.
    fn point(&self, z: f32, phi: f32) -> (Vec3, Vec3) {
        let radial = phi.cos() * self.x + phi.sin() * self.y;
        (
            self.p0 + z * self.axis + self.radius * radial,
            self.oriented(radial),
        )
    }

    /// The outward unit vector `radial`, flipped for a `flip`ped cylinder.
    fn oriented(&self, radial: Vec3) -> Vec3 {
        if self.flip {
            -radial
        } else {
            radial
        }
    }

    /// Mitsuba's surface coordinates of a point: (phi / 2 pi, z / length), phi in [0, 2 pi).
    pub fn uv(&self, p: Vec3) -> Vec2 {
        let rel = p - self.p0;
        let mut phi = rel.dot(self.y).atan2(rel.dot(self.x));
        if phi < 0.0 {
            phi += std::f32::consts::TAU;
        }
        Vec2::new(
            phi / std::f32::consts::TAU,
            rel.dot(self.axis) / self.length,
        )
    }

    /// The nearest hit with t in (t_min, t_max): the roots of |o_perp + t d_perp|^2 = r^2 (the
    /// ray's components perpendicular to the axis), solved in f64 with the cancellation-free
    /// quadratic; the near root when its height lies on the tube, else the far one (a ray from
    /// inside, or one passing over an open end).
    fn intersect_range(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, Vec3, Vec3)> {
        let a = self.axis.as_dvec3();
        let o = (ray.o - self.p0).as_dvec3();
        let d = ray.d.as_dvec3();
        let (op, dp) = (o - o.dot(a) * a, d - d.dot(a) * a);
        let qa = dp.length_squared();
        if qa == 0.0 {
            return None; // parallel to the axis
        }
        let r = self.radius as f64;
        let half_b = op.dot(dp);
        // discriminant / 4 as r^2 |d_perp|^2 - |o_perp x d_perp|^2: no cancellation of b^2 - ac
        let disc = r * r * qa - op.cross(dp).length_squared();
        if disc < 0.0 {
            return None;
        }
        let q = -(half_b + half_b.signum() * disc.sqrt());
        let c = op.length_squared() - r * r;
        let (mut t0, mut t1) = if q == 0.0 {
            (0.0, 0.0)
        } else {
            (c / q, q / qa)
        };
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        for t in [t0, t1] {
            let tf = t as f32;
            if !(tf > t_min && tf < t_max) {
                continue;
            }
            let z = o.dot(a) + t * d.dot(a);
            if !(0.0..=self.length as f64).contains(&z) {
                continue;
            }
            // reprojected onto the tube: the radial direction of the hit, at exactly `radius`
            let radial = (op + t * dp).normalize_or_zero().as_vec3();
            let p = self.p0 + (z as f32) * self.axis + self.radius * radial;
            return Some((tf, p, self.oriented(radial)));
        }
        None
    }
}

/// The closed set of primitive kinds (an enum: the BVH stores them inline, no virtual calls).
#[derive(Clone, Copy, Debug)]
pub enum Primitive {
    Quad(Quad),
    Triangle(Triangle),
    Sphere(Sphere),
    Disk(Disk),
    Cylinder(Cylinder),
}

/// A ray-primitive intersection.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Distance along the ray.
    pub t: f32,
    /// The hit point, reprojected onto the primitive.
    pub p: Vec3,
    /// Unit geometric normal, as the primitive defines it (never flipped towards the ray).
    pub ng: Vec3,
    /// Index of the primitive in the scene.
    pub prim: u32,
}

impl Primitive {
    pub fn bounds(&self) -> Aabb {
        match self {
            Primitive::Quad(q) => Aabb::from_points(&[
                q.origin,
                q.origin + q.u,
                q.origin + q.v,
                q.origin + q.u + q.v,
            ]),
            Primitive::Triangle(t) => Aabb::from_points(&[t.p0, t.p1, t.p2]),
            Primitive::Sphere(s) => Aabb {
                min: s.center - Vec3::splat(s.radius),
                max: s.center + Vec3::splat(s.radius),
            },
            Primitive::Disk(d) => {
                // the ellipse's extent along axis i is sqrt(u_i^2 + v_i^2)
                let r = Vec3::from_array((d.u * d.u + d.v * d.v).to_array().map(f32::sqrt));
                Aabb {
                    min: d.center - r,
                    max: d.center + r,
                }
            }
            Primitive::Cylinder(c) => {
                // the two end circles bound it; a circle of radius r normal to the unit axis a
                // extends r sqrt(1 - a_i^2) along axis i
                let e = c.radius
                    * Vec3::from_array(
                        (Vec3::ONE - c.axis * c.axis)
                            .max(Vec3::ZERO)
                            .to_array()
                            .map(f32::sqrt),
                    );
                let p1 = c.p0 + c.length * c.axis;
                Aabb {
                    min: c.p0.min(p1) - e,
                    max: c.p0.max(p1) + e,
                }
            }
        }
    }

    pub fn area(&self) -> f32 {
        match self {
            Primitive::Quad(q) => q.area,
            Primitive::Triangle(t) => t.area,
            Primitive::Sphere(s) => 4.0 * std::f32::consts::PI * s.radius * s.radius,
            Primitive::Disk(d) => d.area,
            Primitive::Cylinder(c) => std::f32::consts::TAU * c.radius * c.length,
        }
    }

    /// The nearest intersection with `t` in (0, t_max), as (t, point, normal).
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<(f32, Vec3, Vec3)> {
        self.intersect_range(ray, 0.0, t_max)
    }

    /// The nearest intersection with `t` in (t_min, t_max). Continuing a ray past a null
    /// boundary with `t_min` (instead of re-spawning it from an offset origin) keeps the medium
    /// segments contiguous, so no optical depth is lost at the crossing.
    #[inline]
    pub fn intersect_range(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, Vec3, Vec3)> {
        match self {
            Primitive::Quad(q) => {
                let denom = q.n.dot(ray.d);
                if denom == 0.0 {
                    return None;
                }
                let t = q.n.dot(q.origin - ray.o) / denom;
                if !(t > t_min && t < t_max) {
                    return None;
                }
                let (a, b) = q.coordinates(ray.at(t));
                if !(0.0..=1.0).contains(&a) || !(0.0..=1.0).contains(&b) {
                    return None;
                }
                // reprojection onto the plane removes the error t carries along the ray
                Some((t, q.point(a, b), q.n))
            }
            Primitive::Triangle(tri) => {
                let (t, b1, b2) = tri.intersect_range(ray, t_min, t_max)?;
                Some((t, tri.point(b1, b2), tri.n))
            }
            Primitive::Sphere(s) => {
                // numerically stable quadratic on the offset from the centre
                let oc = ray.o - s.center;
                let b = oc.dot(ray.d);
                let c = oc.length_squared() - s.radius * s.radius;
                // discriminant via the distance of the centre from the ray line (stable)
                let perp = oc - b * ray.d;
                let disc = s.radius * s.radius - perp.length_squared();
                if disc < 0.0 {
                    return None;
                }
                let sq = disc.sqrt();
                let q = if b > 0.0 { -b - sq } else { -b + sq };
                let (mut t0, mut t1) = (c / q, q);
                if t0 > t1 {
                    std::mem::swap(&mut t0, &mut t1);
                }
                let t = if t0 > t_min { t0 } else { t1 };
                if !(t > t_min && t < t_max && t.is_finite()) {
                    return None;
                }
                let n = (ray.at(t) - s.center).normalize();
                Some((t, s.center + n * s.radius, n))
            }
            Primitive::Disk(d) => {
                let denom = d.n.dot(ray.d);
                if denom == 0.0 {
                    return None;
                }
                let t = d.n.dot(d.center - ray.o) / denom;
                if !(t > t_min && t < t_max) {
                    return None;
                }
                let rel = ray.at(t) - d.center;
                let a = d.w.dot(rel.cross(d.v));
                let b = d.w.dot(d.u.cross(rel));
                if a * a + b * b > 1.0 {
                    return None;
                }
                Some((t, d.center + a * d.u + b * d.v, d.n))
            }
            Primitive::Cylinder(c) => c.intersect_range(ray, t_min, t_max),
        }
    }

    /// A point uniformly distributed by area, with its unit geometric normal; density 1 / area.
    pub fn sample_area(&self, u: Vec2) -> (Vec3, Vec3) {
        match self {
            Primitive::Quad(q) => (q.point(u.x, u.y), q.n),
            Primitive::Triangle(t) => {
                let b = warp::uniform_triangle(u);
                (t.p0 + b.x * t.e1() + b.y * t.e2(), t.n)
            }
            Primitive::Sphere(s) => {
                let n = warp::uniform_sphere(u);
                (s.center + n * s.radius, n)
            }
            Primitive::Disk(d) => {
                // an affine map keeps the unit disk's uniform density uniform
                let p = warp::concentric_disk(u);
                (d.center + p.x * d.u + p.y * d.v, d.n)
            }
            // height and angle uniform: the tube unrolls to a rectangle (as Mitsuba samples it)
            Primitive::Cylinder(c) => c.point(u.x * c.length, std::f32::consts::TAU * u.y),
        }
    }

    /// The inverse of [`Primitive::sample_area`]: the `u` in [0, 1)^2 that samples point `p` (a
    /// point on the primitive; others are projected onto its plane or sphere). The adjoint image
    /// needs it to find the cell of a light point an eye path hit (Kristensen 2010, sec. 5.3.1).
    pub fn sample_area_inverse(&self, p: Vec3) -> Vec2 {
        let clamp = |u: Vec2| u.clamp(Vec2::ZERO, Vec2::splat(ONE_MINUS_EPSILON));
        match self {
            Primitive::Quad(q) => {
                let (a, b) = plane_coordinates(p - q.origin, q.u, q.v);
                clamp(Vec2::new(a, b))
            }
            Primitive::Triangle(t) => {
                let (b0, b1) = plane_coordinates(p - t.p0, t.e1(), t.e2());
                clamp(warp::uniform_triangle_inverse(Vec2::new(b0, b1)))
            }
            Primitive::Sphere(s) => {
                let n = (p - s.center).normalize_or_zero();
                clamp(warp::uniform_sphere_inverse(n))
            }
            Primitive::Disk(d) => {
                let (a, b) = plane_coordinates(p - d.center, d.u, d.v);
                clamp(warp::concentric_disk_inverse(Vec2::new(a, b)))
            }
            Primitive::Cylinder(c) => {
                let uv = c.uv(p);
                clamp(Vec2::new(uv.y, uv.x))
            }
        }
    }
}

/// Coordinates (a, b) of `d = a u + b v` in the plane of `u`, `v` (least squares).
fn plane_coordinates(d: Vec3, u: Vec3, v: Vec3) -> (f32, f32) {
    let (uu, uv, vv) = (u.dot(u) as f64, u.dot(v) as f64, v.dot(v) as f64);
    let (du, dv) = (d.dot(u) as f64, d.dot(v) as f64);
    let det = uu * vv - uv * uv;
    if det <= 0.0 {
        return (0.0, 0.0);
    }
    (
        ((du * vv - dv * uv) / det) as f32,
        ((dv * uu - du * uv) / det) as f32,
    )
}

impl Primitive {
    /// The surface coordinates (u, v) of a point `p` on the primitive, as Mitsuba 3 defines them
    /// for its shapes (`src/shapes/*.cpp`, `compute_surface_interaction`): a quad's coordinates
    /// (a, b) along its edges (Mitsuba's `rectangle`: ((x + 1) / 2, (y + 1) / 2)); a disk's
    /// (r, phi / 2 pi) in its own axes, phi in [0, 2 pi), whichever way its normal points; a
    /// sphere's (phi / 2 pi, theta / pi) about its centre in its own `frame`, theta from its
    /// z, phi from its x towards its y in [0, 2 pi); a triangle's
    /// barycentric (b1, b2), which a mesh's texture coordinates then interpolate. Computed from
    /// the hit point when a texture asks, so untextured scenes never pay for it. A cylinder's is
    /// (phi / 2 pi, height / length), phi about its axis from its `x` towards its `y`.
    pub fn uv(&self, p: Vec3) -> Vec2 {
        use std::f32::consts::{FRAC_1_PI, TAU};
        match self {
            Primitive::Quad(q) => {
                let (a, b) = q.coordinates(p);
                Vec2::new(a, b)
            }
            Primitive::Triangle(t) => {
                let (b1, b2) = plane_coordinates(p - t.p0, t.e1(), t.e2());
                Vec2::new(b1, b2)
            }
            Primitive::Sphere(s) => {
                let l = s.frame.to_local((p - s.center) / s.radius);
                let theta = l.z.clamp(-1.0, 1.0).acos();
                let mut phi = l.y.atan2(l.x);
                if phi < 0.0 {
                    phi += TAU;
                }
                Vec2::new(phi / TAU, theta * FRAC_1_PI)
            }
            Primitive::Disk(d) => {
                let rel = p - d.center;
                let (a, b) = (d.w.dot(rel.cross(d.v)), d.w.dot(d.u.cross(rel)));
                let mut v = b.atan2(a) / TAU;
                if v < 0.0 {
                    v += 1.0;
                }
                Vec2::new((a * a + b * b).sqrt(), v)
            }
            Primitive::Cylinder(c) => c.uv(p),
        }
    }

    /// dp/du at `p`: the derivative of the point along [`Primitive::uv`]'s u, as Mitsuba 3's
    /// shapes give it (`compute_surface_interaction`), the first axis of their shading frame
    /// and the direction of an anisotropic roughness's `alpha_u`. A quad's edge `u`; a
    /// triangle's `p1 - p0` (the barycentric parametrization; a mesh's texture coordinates
    /// are `scene::UvMap`'s); a sphere's and a cylinder's 2 pi times the tangent of the
    /// circle of latitude (zero at a sphere's poles); a disk's radial direction (zero at its
    /// centre). Only its direction is used, against the shading normal.
    pub fn dp_du(&self, p: Vec3) -> Vec3 {
        use std::f32::consts::TAU;
        match self {
            Primitive::Quad(q) => q.u,
            Primitive::Triangle(t) => t.e1(),
            Primitive::Sphere(s) => {
                let l = s.frame.to_local(p - s.center);
                TAU * (-l.y * s.frame.s + l.x * s.frame.t)
            }
            Primitive::Disk(d) => {
                let rel = p - d.center;
                let (a, b) = (d.w.dot(rel.cross(d.v)), d.w.dot(d.u.cross(rel)));
                let r = (a * a + b * b).sqrt();
                if r == 0.0 {
                    return Vec3::ZERO;
                }
                (a * d.u + b * d.v) / r
            }
            Primitive::Cylinder(c) => {
                let rel = p - c.p0;
                TAU * (-rel.dot(c.y) * c.x + rel.dot(c.x) * c.y)
            }
        }
    }
}
