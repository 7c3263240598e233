//! Null faces that no ray can cross, left out of the BVH. A null boundary drawn exactly on an
//! opaque wall (the fog box's medium box on its five walls, the rooms' medium box on their floor
//! and ceiling) is only ever reached at the wall: from either side the wall wins the coplanar
//! tie (`geometry::bvh`), and a wall that only reflects sends every path back to the side it
//! came from, in the medium it was in. Such a face changes no path, yet every query that
//! reaches the wall also tests it. The face stays in `Scene::prims`, where `Scene::medium_at`
//! still finds the boundary.
//! Book: "Scenes and geometry", section "Null faces on walls".

use std::collections::HashMap;

use crate::geometry::shape::Quad;
use crate::geometry::Primitive;
use crate::scene::ShapeInfo;

/// Distance from the wall's plane (relative to the scene's scale) and slack of the wall's
/// coordinates within which a face's corner counts as lying on the wall.
const ON_WALL: f32 = 1e-6;
/// Walls examined per null face: bounds the build's cost on pathological scenes (a face not
/// examined stays in the BVH, which is always correct, only slower).
const MAX_CANDIDATES: usize = 64;

/// A plane, quantized: the normal with its largest component made positive, and the offset
/// along it relative to the scene's scale. Coplanar quads share a key unless they straddle a
/// rounding boundary, and then the face merely stays in the BVH.
type PlaneKey = (i32, i32, i32, i64);

fn plane_key(q: &Quad, scale: f32) -> PlaneKey {
    let n = q.n;
    let largest = if n.x.abs() >= n.y.abs() && n.x.abs() >= n.z.abs() {
        n.x
    } else if n.y.abs() >= n.z.abs() {
        n.y
    } else {
        n.z
    };
    let n = if largest < 0.0 { -n } else { n };
    let d = n.dot(q.origin) / scale;
    let q3 = |x: f32| (x * 1e3).round() as i32;
    (q3(n.x), q3(n.y), q3(n.z), (d * 1e4).round() as i64)
}

/// A wall that can hide a null face: not null, and transmitting nothing (an emitter without a
/// material absorbs everything it is hit by).
fn is_wall(shape: &ShapeInfo) -> bool {
    shape.bsdf.as_ref().is_none_or(|b| !b.transmits())
}

/// True when `wall` covers all of `face` (both parallelograms, so the corners decide).
fn covers(wall: &Quad, face: &Quad, scale: f32) -> bool {
    let slack = -ON_WALL..=1.0 + ON_WALL;
    wall.n.dot(face.n).abs() >= 1.0 - ON_WALL
        && face.corners().iter().all(|&c| {
            let (a, b) = wall.coordinates(c);
            wall.n.dot(c - wall.origin).abs() <= ON_WALL * scale
                && slack.contains(&a)
                && slack.contains(&b)
        })
}

/// For each primitive, whether queries must see it: false only for a null quad that one
/// coplanar wall quad covers whole. Without `emitter_walls` no emitter shape counts as a wall
/// (for `Scene::camera_bvh`, where the camera's rays pass through emitters).
pub(super) fn crossable(
    prims: &[Primitive],
    prim_shape: &[u32],
    shapes: &[ShapeInfo],
    emitter_walls: bool,
) -> Vec<bool> {
    let scale = prims
        .iter()
        .map(|p| {
            let b = p.bounds();
            b.min.abs().max(b.max.abs()).max_element()
        })
        .fold(1e-3_f32, f32::max);
    let quad = |i: usize| match &prims[i] {
        Primitive::Quad(q) => Some(q),
        _ => None,
    };
    let shape = |i: usize| &shapes[prim_shape[i] as usize];
    let mut walls: HashMap<PlaneKey, Vec<usize>> = HashMap::new();
    for i in 0..prims.len() {
        let wall = is_wall(shape(i)) && (emitter_walls || shape(i).light.is_none());
        if let Some(q) = quad(i).filter(|_| wall) {
            walls.entry(plane_key(q, scale)).or_default().push(i);
        }
    }
    (0..prims.len())
        .map(|i| {
            let Some(face) = quad(i).filter(|_| shape(i).is_null()) else {
                return true;
            };
            let hidden = walls.get(&plane_key(face, scale)).is_some_and(|ws| {
                ws.iter()
                    .take(MAX_CANDIDATES)
                    .any(|&w| covers(quad(w).unwrap(), face, scale))
            });
            !hidden
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn quad(o: [f32; 3], u: [f32; 3], v: [f32; 3]) -> Quad {
        Quad::new(Vec3::from(o), Vec3::from(u), Vec3::from(v)).unwrap()
    }

    #[test]
    fn a_wall_covers_a_face_written_the_other_way_round() {
        let wall = quad([-1.0, -1.0, -1.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]);
        let face = quad([-1.0, -1.0, -1.0], [0.0, 0.0, 2.0], [0.0, 2.0, 0.0]);
        assert!(covers(&wall, &face, 1.0));
        assert_eq!(plane_key(&wall, 1.0), plane_key(&face, 1.0));
        // a face larger than the wall, or beside it, or off its plane, is not covered
        let larger = quad([-1.0, -1.0, -1.0], [0.0, 2.1, 0.0], [0.0, 0.0, 2.0]);
        let beside = quad([-1.0, 1.5, -1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        let off = quad([-0.999, -1.0, -1.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]);
        let tilted = quad([-1.0, -1.0, -1.0], [0.01, 2.0, 0.0], [0.0, 0.0, 2.0]);
        for f in [larger, beside, off, tilted] {
            assert!(!covers(&wall, &f, 1.0), "{f:?}");
        }
    }
}
