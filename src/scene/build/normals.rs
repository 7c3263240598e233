//! Shading normals of a smooth mesh (`smooth_normals = true`): the file's vertex normals placed
//! by `to_world`, or, when the file has none, angle-weighted face normals per position, as
//! Mitsuba 3 computes them for a mesh without `face_normals` (`Mesh::compute_normals`, after
//! Thürmer and Wüthrich, "Computing vertex normals from polygonal facets", JGT 1998).

use glam::{Affine3A, Vec3};
use std::f32::consts::PI;

/// The angle between unit vectors `a` and `b`, accurate near 0 and pi (the half-chord form).
fn unit_angle(a: Vec3, b: Vec3) -> f32 {
    if a.dot(b) < 0.0 {
        PI - 2.0 * ((a + b).length() * 0.5).min(1.0).asin()
    } else {
        2.0 * ((a - b).length() * 0.5).min(1.0).asin()
    }
}

/// One unit normal per position: the unit normals of the non-degenerate triangles around it,
/// each weighted by the triangle's interior angle at that corner; a position no such triangle
/// touches gets +x (Mitsuba's placeholder; no triangle interpolates it).
pub(super) fn angle_weighted(pos: &[Vec3], idx: &[u32]) -> Vec<Vec3> {
    let mut acc = vec![Vec3::ZERO; pos.len()];
    for t in idx.chunks_exact(3) {
        let p = [pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]];
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let len2 = n.length_squared();
        if !(len2 > 0.0 && len2.is_finite()) {
            continue;
        }
        let n = n / len2.sqrt();
        for k in 0..3 {
            let a = (p[(k + 1) % 3] - p[k]).normalize();
            let b = (p[(k + 2) % 3] - p[k]).normalize();
            acc[t[k] as usize] += n * unit_angle(a, b);
        }
    }
    acc.into_iter()
        .map(|n| {
            let len2 = n.length_squared();
            if len2 > 0.0 {
                n / len2.sqrt()
            } else {
                Vec3::X
            }
        })
        .collect()
}

/// A file's normal placed by `place` (the inverse transpose of its linear part) and normalized;
/// `None` when it is not finite or has no length.
pub(super) fn placed(place: &Affine3A, n: Vec3) -> Option<Vec3> {
    let m = glam::Mat3::from(place.matrix3).inverse().transpose();
    let n = (m * n).normalize_or_zero();
    (n != Vec3::ZERO && n.is_finite()).then_some(n)
}
