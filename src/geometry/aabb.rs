//! Axis-aligned bounding boxes.

use glam::Vec3;

use super::Ray;

/// An axis-aligned box; the empty box has `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Aabb::EMPTY
    }
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn from_points(points: &[Vec3]) -> Self {
        points.iter().fold(Aabb::EMPTY, |b, &p| b.grow(p))
    }

    #[inline]
    pub fn grow(self, p: Vec3) -> Self {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    #[inline]
    pub fn union(self, o: Aabb) -> Self {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    pub fn centroid(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    pub fn extent(&self) -> Vec3 {
        (self.max - self.min).max(Vec3::ZERO)
    }

    /// Surface area (the SAH cost of a node is proportional to it).
    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Slab test: the parametric interval of the ray inside the box, clipped to [0, t_max].
    /// A ray lying in a face's plane (a zero direction component, its origin on that bound)
    /// gives 0 x inf = NaN at that slab end: it is on the closed box's face, so that axis does
    /// not constrain it (`geometry::wide` keeps the same rule lane by lane).
    #[inline]
    pub fn intersect(&self, ray: &Ray, inv_d: Vec3, t_max: f32) -> Option<(f32, f32)> {
        let t0 = (self.min - ray.o) * inv_d;
        let t1 = (self.max - ray.o) * inv_d;
        let on_face = t0.is_nan_mask() | t1.is_nan_mask();
        let lo = Vec3::select(on_face, Vec3::NEG_INFINITY, t0.min(t1));
        let hi = Vec3::select(on_face, Vec3::INFINITY, t0.max(t1));
        let near = lo.max_element().max(0.0);
        let far = hi.min_element().min(t_max);
        // the 1 + 2 gamma(3) factor keeps the test conservative (pbrt's robust slab test)
        if near <= far * 1.000_000_4 {
            Some((near, far))
        } else {
            None
        }
    }
}
