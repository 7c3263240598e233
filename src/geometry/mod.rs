//! Rays, primitives and the bounding volume hierarchy.
//! Book: "Scenes and geometry" (tests: `tests/spec/geometry.rs`, bench: `benches/bvh.rs`).

pub mod aabb;
pub mod bvh;
pub mod leaf;
pub mod pages;
pub mod shape;
pub mod wide;

pub use aabb::Aabb;
pub use bvh::Bvh;
pub use shape::{Cylinder, Disk, Hit, Primitive};

use glam::Vec3;

/// A ray `o + t d`, `d` of unit length.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub o: Vec3,
    pub d: Vec3,
}

impl Ray {
    pub fn new(o: Vec3, d: Vec3) -> Self {
        Ray { o, d }
    }

    /// The point at distance `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }
}

/// Relative size of the offset that lifts a spawned ray's origin off its surface. Intersection
/// points are reprojected onto their primitive and carry an error of a few ulps of their
/// coordinates; this is ~16 ulps, enough for quads, triangles and spheres (`tests/spec/geometry.rs`).
/// It is kept this small because the lift also moves the recorded vertex sideways from the
/// sampled direction: densities evaluated from vertex positions then differ from the sampler's
/// by about offset / edge length (measured by `tests/spec/path.rs`; 2e-5 gave 0.2% on edges of
/// a few centimetres).
pub const RAY_EPSILON: f32 = 2e-6;

// ANCHOR: offset_origin
/// The origin of a ray leaving a surface point `p` with geometric normal `ng` in direction `d`:
/// `p` pushed off the surface to the side `d` goes to, so the ray cannot hit the same surface
/// again. Moving along the normal (not along `d`) keeps grazing rays robust.
#[inline]
pub fn offset_origin(p: Vec3, ng: Vec3, d: Vec3) -> Vec3 {
    let scale = RAY_EPSILON * (1.0 + p.abs().max_element());
    if ng.dot(d) >= 0.0 {
        p + ng * scale
    } else {
        p - ng * scale
    }
}
// ANCHOR_END: offset_origin

/// Distance shortened for a shadow ray towards a surface point, so the target itself does not
/// count as an occluder.
#[inline]
pub fn shadow_distance(from: Vec3, to: Vec3) -> f32 {
    let d = (to - from).length();
    let scale = RAY_EPSILON * (1.0 + to.abs().max_element());
    (d - 2.0 * scale).max(0.0)
}
