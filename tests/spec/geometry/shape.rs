//! The triangle test is watertight (Woop, Benthin and Wald 2013): a ray through the shared edge
//! or the shared corner of a mesh's triangles hits at least one of them, a closed mesh seen from
//! inside has no hole, and away from edges the hit is Moller-Trumbore's to float error.
//! Book: "Scenes and geometry", Primitives.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use pathspace::geometry::shape::Triangle;
use pathspace::geometry::{Primitive, Ray};
use pathspace::scene::{Scene, SceneSource};

fn rng(seed: u64) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(seed)
}

fn unit(r: &mut Pcg64Mcg) -> Vec3 {
    loop {
        let v = Vec3::new(
            r.random_range(-1.0..1.0),
            r.random_range(-1.0..1.0),
            r.random_range(-1.0..1.0),
        );
        let l2 = v.length_squared();
        if l2 > 1e-4 && l2 <= 1.0 {
            return v / l2.sqrt();
        }
    }
}

/// Moller-Trumbore (1997), the test the watertight one replaced: here as the reference it must
/// agree with away from edges, and to show that the edge rays below do catch a leaky test.
/// Returns (t, b1, b2).
fn moller_trumbore(tri: &Triangle, ray: &Ray, t_max: f32) -> Option<(f32, f32, f32)> {
    let (e1, e2) = (tri.e1(), tri.e2());
    let pvec = ray.d.cross(e2);
    let det = e1.dot(pvec);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let tvec = ray.o - tri.p0;
    let b1 = tvec.dot(pvec) * inv;
    if !(0.0..=1.0).contains(&b1) {
        return None;
    }
    let qvec = tvec.cross(e1);
    let b2 = ray.d.dot(qvec) * inv;
    if b2 < 0.0 || b1 + b2 > 1.0 {
        return None;
    }
    let t = e2.dot(qvec) * inv;
    (t > 0.0 && t < t_max).then_some((t, b1, b2))
}

/// A value on the grid of multiples of 2^-10 in [-8, 8): 14 bits, so that a corner plus a
/// fraction i / 256 of an edge is exact in f32 (22 bits) and the edge points below are exact.
fn grid(r: &mut Pcg64Mcg) -> f32 {
    r.random_range(-8192..8192) as f32 / 1024.0
}

/// A point with coordinate `c` on axis `axis` and grid values on the two others.
fn on_plane(r: &mut Pcg64Mcg, axis: usize, c: f32) -> Vec3 {
    let mut p = Vec3::new(grid(r), grid(r), grid(r));
    p[axis] = c;
    p
}

/// `a + (i / 256) (b - a)`, asserted exact (computed again in f64).
fn exact_lerp(a: Vec3, b: Vec3, i: u32) -> Vec3 {
    let s = i as f32 / 256.0;
    let p = a + s * (b - a);
    for k in 0..3 {
        let exact = a[k] as f64 + (i as f64 / 256.0) * (b[k] as f64 - a[k] as f64);
        assert_eq!(p[k] as f64, exact, "the edge point is not exact in f32");
    }
    p
}

/// A triangle with the given winding (`flip` swaps two corners).
fn triangle(a: Vec3, b: Vec3, c: Vec3, flip: bool) -> Option<Triangle> {
    if flip {
        Triangle::new(a, c, b)
    } else {
        Triangle::new(a, b, c)
    }
}

/// Rays through `p` (an exact point of the mesh): along and against the plane's normal axis (so
/// the ray's line contains `p` exactly), and from random origins on either side aimed at `p`
/// (whose lines pass within rounding of it).
fn rays_through(r: &mut Pcg64Mcg, p: Vec3, axis: usize, n_oblique: usize) -> Vec<Ray> {
    let mut rays = Vec::with_capacity(2 + n_oblique);
    for s in [1.0f32, -1.0] {
        let mut d = Vec3::ZERO;
        d[axis] = s;
        rays.push(Ray::new(p - 3.0 * d, d));
    }
    for _ in 0..n_oblique {
        let mut o = p + 4.0 * unit(r);
        // keep the ray off grazing angles, where the mesh's plane is nearly edge-on
        let lift = 1.0 + 3.0 * r.random::<f32>();
        o[axis] = p[axis] + if r.random::<bool>() { lift } else { -lift };
        rays.push(Ray::new(o, (p - o).normalize()));
    }
    rays
}

/// Tests every ray against every triangle: a miss of all of them is a leak; two hits must be at
/// the same distance to within rounding (the ray crosses the common edge or corner), a few ulps
/// of the largest distance from the origin to a corner, of which t is an interpolation. Returns
/// the number of leaks of Moller-Trumbore on the same rays.
fn assert_no_leak(tris: &[Triangle], rays: &[Ray], what: &str) -> usize {
    let mut mt_leaks = 0;
    for ray in rays {
        let hits: Vec<(f32, &Triangle)> = tris
            .iter()
            .filter_map(|t| Some((Primitive::Triangle(*t).intersect(ray, f32::INFINITY)?.0, t)))
            .collect();
        assert!(
            !hits.is_empty(),
            "{what}: {ray:?} passes between the triangles {tris:?}"
        );
        let reach = hits
            .iter()
            .flat_map(|(_, t)| [t.p0, t.p1, t.p2])
            .map(|p| (p - ray.o).length())
            .fold(0.0f32, f32::max);
        let (lo, hi) = hits.iter().fold((f32::MAX, 0.0f32), |(lo, hi), &(t, _)| {
            (lo.min(t), hi.max(t))
        });
        let tol = 16.0 * f32::EPSILON * reach;
        assert!(
            hi - lo <= tol,
            "{what}: {ray:?} hits at {lo} and {hi} (tol {tol})"
        );
        let mt_hits = tris
            .iter()
            .filter(|t| moller_trumbore(t, ray, f32::INFINITY).is_some())
            .count();
        mt_leaks += (mt_hits == 0) as usize;
    }
    mt_leaks
}

/// Along a coordinate axis, with corners and ray on the 2^-10 and 2^-18 grids, the frame is a
/// translation without rounding and the edge functions (in f64) are exact: the test then decides
/// exactly. A ray through a point on an edge or inside hits, a ray one grid step outside misses,
/// however close to 0 the edge function's f32 value rounds.
#[test]
fn axis_parallel_rays_decide_exactly() {
    let mut r = rng(16);
    let mut near_misses = 0;
    for _ in 0..2000 {
        let axis = r.random_range(0..3);
        let c = grid(&mut r);
        let corners = [0, 1, 2].map(|_| on_plane(&mut r, axis, c));
        let Some(tri) = Triangle::new(corners[0], corners[1], corners[2]) else {
            continue;
        };
        let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
        // the exact side of a point against each edge, in f64
        let inside = |p: Vec3| {
            let f = |a: Vec3, b: Vec3| {
                let (a, b, p) = (a.as_dvec3(), b.as_dvec3(), p.as_dvec3());
                (b[i] - a[i]) * (p[j] - a[j]) - (b[j] - a[j]) * (p[i] - a[i])
            };
            let e = [(0, 1), (1, 2), (2, 0)].map(|(a, b)| f(corners[a], corners[b]));
            e.iter().all(|&x| x >= 0.0) || e.iter().all(|&x| x <= 0.0)
        };
        for k in 0..3 {
            let (a, b) = (corners[k], corners[(k + 1) % 3]);
            for _ in 0..8 {
                let mut p = exact_lerp(a, b, r.random_range(1..256));
                let step = (1 << 18) as f32;
                p[i] += r.random_range(-2i32..=2) as f32 / step;
                p[j] += r.random_range(-2i32..=2) as f32 / step;
                let expected = inside(p);
                near_misses += !expected as usize;
                for ray in rays_through(&mut r, p, axis, 0) {
                    let hit = Primitive::Triangle(tri)
                        .intersect(&ray, f32::INFINITY)
                        .is_some();
                    assert_eq!(hit, expected, "{ray:?} through {p:?}, {tri:?}");
                }
            }
        }
    }
    assert!(near_misses > 10_000, "{near_misses} rays just outside");
}

/// Quads split along a diagonal into two triangles (random size, axis, winding of each
/// triangle, the fourth corner sometimes out of the plane): rays through exact points of the
/// diagonal and through its two shared corners hit one of the triangles or both at one distance.
#[test]
fn rays_through_the_shared_edge_of_a_split_quad_never_pass_between() {
    let mut r = rng(11);
    let mut mt_leaks = 0;
    let mut rays_tested = 0;
    for mesh in 0..300 {
        let axis = r.random_range(0..3);
        let c = grid(&mut r);
        let (p00, p11) = (on_plane(&mut r, axis, c), on_plane(&mut r, axis, c));
        let mut p10 = on_plane(&mut r, axis, c);
        let p01 = on_plane(&mut r, axis, c);
        if mesh % 3 == 0 {
            p10[axis] += 0.5; // a non-planar quad still shares its diagonal exactly
        }
        // the two triangles on either side of the diagonal p00-p11
        let side = |p: Vec3| {
            let (d, q) = (p11 - p00, p - p00);
            let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
            d[i] * q[j] - d[j] * q[i]
        };
        if side(p10) * side(p01) >= 0.0 {
            continue; // not a convex split quad
        }
        let tris = [
            triangle(p00, p10, p11, r.random()),
            triangle(p00, p11, p01, r.random()),
        ];
        let [Some(a), Some(b)] = tris else { continue };
        let mut rays = Vec::new();
        for i in 1..256 {
            if i % 16 == 0 || r.random::<f32>() < 0.1 {
                let p = exact_lerp(p00, p11, i);
                let through = rays_through(&mut r, p, axis, 4);
                // a fold seen edge-on is a silhouette, which a ray may pass by
                rays.extend(
                    through
                        .into_iter()
                        .filter(|ray| crosses(ray.d, p11 - p00, p10 - p00, p01 - p00)),
                );
            }
        }
        rays_tested += rays.len();
        mt_leaks += assert_no_leak(&[a, b], &rays, &format!("split quad {mesh}"));
    }
    assert!(rays_tested > 10_000, "{rays_tested} rays");
    // the rays are sharp enough to find the gap Moller-Trumbore leaves on an edge
    assert!(mt_leaks > 0, "no ray leaks through Moller-Trumbore either");
}

/// Whether a ray in direction `d` crosses the surface at the common edge `e` of two triangles
/// whose third corners are `a` and `b` (relative to the edge's start): seen along the ray, the
/// two lie on opposite sides of the edge (f64, exact for these small grid values).
fn crosses(d: Vec3, e: Vec3, a: Vec3, b: Vec3) -> bool {
    let f = |v: Vec3| v.as_dvec3();
    let side = |c: Vec3| f(e).cross(f(c)).dot(f(d));
    side(a) * side(b) < 0.0
}

/// A planar fan of triangles around one corner (random axis, ring and winding of each
/// triangle): rays through the centre and through exact points of the spokes hit.
#[test]
fn rays_through_the_shared_corner_of_a_fan_never_pass_between() {
    let mut r = rng(12);
    let mut mt_leaks = 0;
    for fan in 0..100 {
        let axis = r.random_range(0..3);
        let c = grid(&mut r);
        let centre = on_plane(&mut r, axis, c);
        // four or more, so that no gap between corners reaches half a turn
        let n = r.random_range(4..12);
        let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
        // corners at increasing angles around the centre, on the 2^-10 grid
        let ring: Vec<Vec3> = (0..n)
            .map(|k| {
                let angle = std::f32::consts::TAU * (k as f32 + r.random::<f32>() * 0.8) / n as f32;
                let radius = r.random_range(0.5f32..4.0);
                let mut p = centre;
                p[i] += (radius * angle.cos() * 1024.0).round() / 1024.0;
                p[j] += (radius * angle.sin() * 1024.0).round() / 1024.0;
                p
            })
            .collect();
        let tris: Vec<Triangle> = (0..n)
            .filter_map(|k| triangle(centre, ring[k], ring[(k + 1) % n], r.random()))
            .collect();
        assert_eq!(tris.len(), n, "fan {fan}: a degenerate triangle");
        let mut rays = rays_through(&mut r, centre, axis, 64);
        for corner in &ring {
            for step in [1, 7, 64, 128, 200] {
                rays.extend(rays_through(
                    &mut r,
                    exact_lerp(centre, *corner, step),
                    axis,
                    4,
                ));
            }
        }
        mt_leaks += assert_no_leak(&tris, &rays, &format!("fan {fan}"));
    }
    assert!(mt_leaks > 0, "no ray leaks through Moller-Trumbore either");
}

/// A unit icosahedron subdivided `levels` times, its corners pushed out to the unit sphere and
/// shared between triangles by index (so shared corners are the same floats).
fn sphere_mesh(levels: u32) -> Vec<Triangle> {
    let g = (1.0 + 5f32.sqrt()) / 2.0;
    let mut pos: Vec<Vec3> = [
        (-1.0, g, 0.0),
        (1.0, g, 0.0),
        (-1.0, -g, 0.0),
        (1.0, -g, 0.0),
        (0.0, -1.0, g),
        (0.0, 1.0, g),
        (0.0, -1.0, -g),
        (0.0, 1.0, -g),
        (g, 0.0, -1.0),
        (g, 0.0, 1.0),
        (-g, 0.0, -1.0),
        (-g, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut midpoint = |a: usize, b: usize, pos: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                pos.push(((pos[a] + pos[b]) / 2.0).normalize());
                pos.len() - 1
            })
        };
        faces = faces
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (
                    midpoint(a, b, &mut pos),
                    midpoint(b, c, &mut pos),
                    midpoint(c, a, &mut pos),
                );
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    faces
        .iter()
        .map(|&[a, b, c]| Triangle::new(pos[a], pos[b], pos[c]).unwrap())
        .collect()
}

/// Directions from `centre` towards every corner, towards points at several fractions along
/// every edge, and a fixed set of random ones.
fn probe_directions(tris: &[Triangle], centre: Vec3, r: &mut Pcg64Mcg, random: usize) -> Vec<Vec3> {
    let mut dirs = Vec::new();
    for t in tris {
        for (a, b) in [(t.p0, t.p1), (t.p1, t.p2), (t.p2, t.p0)] {
            for s in [0.0, 1.0 / 3.0, 0.5, 0.9] {
                dirs.push((a + s * (b - a) - centre).normalize());
            }
        }
    }
    dirs.extend((0..random).map(|_| unit(r)));
    dirs
}

/// A closed triangle mesh seen from inside: every ray from the centre hits (by brute force, and
/// through the BVH, where the hit must be a triangle of the mesh) -- towards every corner, along
/// every edge and in 20000 random directions.
#[test]
fn a_closed_sphere_mesh_has_no_hole_seen_from_inside() {
    let mut r = rng(13);
    for (levels, centre) in [(2, Vec3::ZERO), (3, Vec3::new(0.1, -0.2, 0.05))] {
        let tris = sphere_mesh(levels);
        let dirs = probe_directions(&tris, centre, &mut r, 20_000);
        let rays: Vec<Ray> = dirs.iter().map(|&d| Ray::new(centre, d)).collect();
        for ray in &rays {
            let hit = tris.iter().any(|t| {
                Primitive::Triangle(*t)
                    .intersect(ray, f32::INFINITY)
                    .is_some()
            });
            assert!(hit, "sphere mesh, {levels} levels: {ray:?} leaks");
        }
    }
}

/// The same for the closed cube of `tests/fixtures/cube.obj`, read by the scene's OBJ reader
/// (which splits its corners along the edges: the copies must still be equal), scaled into the
/// fog box, and traced through the scene's BVH.
#[test]
fn the_cube_fixture_has_no_hole_seen_from_inside() {
    let fog = include_str!("../../../scenes/fog-box.toml");
    let mesh = "[[shapes]]\ntype = \"mesh\"\nobj = \"tests/fixtures/cube.obj\"\n\
                material = \"white\"\n\
                to_world = [[0.5, 0, 0, 0.0], [0, 0.5, 0, 0.0], [0, 0, 0.5, 0.0]]\n";
    // the tests run in the crate's directory, the embedded scene's base
    let source = SceneSource::embedded("fog-box-with-cube.toml", &format!("{fog}\n{mesh}"));
    let scene = Scene::load(&source).expect("the scene loads");
    let tris: Vec<Triangle> = scene
        .prims
        .iter()
        .filter_map(|p| match p {
            Primitive::Triangle(t) => Some(*t),
            _ => None,
        })
        .collect();
    assert_eq!(tris.len(), 12);
    let mut r = rng(14);
    for centre in [Vec3::ZERO, Vec3::new(0.25, -0.125, 0.0625)] {
        for d in probe_directions(&tris, centre, &mut r, 20_000) {
            let ray = Ray::new(centre, d);
            let hit = scene.intersect(&ray, f32::INFINITY).expect("a hit");
            assert!(
                matches!(scene.prims[hit.prim as usize], Primitive::Triangle(_)),
                "{ray:?} leaks out of the cube to {:?}",
                hit.p
            );
        }
    }
}

/// Away from the edges the watertight test finds Moller-Trumbore's hit: the same distance and
/// barycentrics to within the rounding both make, a first-order bound of a few ulps scaled by
/// the sizes involved and by the conditioning (incidence and the triangle's shape).
#[test]
fn away_from_edges_the_hit_is_moller_trumbores() {
    let mut r = rng(15);
    let mut compared = 0;
    for _ in 0..100_000 {
        let p0 = 4.0 * unit(&mut r);
        let tri = Triangle::new(p0, p0 + 2.0 * unit(&mut r), p0 + 2.0 * unit(&mut r));
        let Some(tri) = tri else { continue };
        let o = 8.0 * unit(&mut r);
        let ray = Ray::new(o, (p0 + 0.7 * unit(&mut r) - o).normalize());
        let cos = tri.n.dot(ray.d).abs();
        let (e1, e2) = (tri.e1(), tri.e2());
        let cross = e1.cross(e2).length();
        let (reference, new) = (
            moller_trumbore(&tri, &ray, f32::INFINITY),
            Primitive::Triangle(tri)
                .intersect(&ray, f32::INFINITY)
                .map(|(t, _, _)| t),
        );
        let Some((t, b1, b2)) = reference else {
            // a miss must be a clear miss or a near-edge case
            if let Some(t) = new {
                let p = ray.at(t);
                let near = [(tri.p0, tri.p1), (tri.p1, tri.p2), (tri.p2, tri.p0)]
                    .iter()
                    .map(|&(a, b)| distance_to_segment(p, a, b))
                    .fold(f32::MAX, f32::min);
                assert!(
                    near < 1e-4 * (1.0 + t) / cos,
                    "{ray:?}: a hit far from the edges"
                );
            }
            continue;
        };
        let edge_margin = b1.min(b2).min(1.0 - b1 - b2);
        if edge_margin < 1e-3 || cos < 0.05 {
            continue;
        }
        compared += 1;
        let (tw, b1w, b2w) = tri
            .intersect_range(&ray, 0.0, f32::INFINITY)
            .unwrap_or_else(|| panic!("{ray:?}: a clear hit missed"));
        assert_eq!(new, Some(tw));
        let scale = (o - p0).length() + e1.length() + e2.length();
        let t_tol = 32.0 * f32::EPSILON * scale / cos;
        let b_tol = 32.0 * f32::EPSILON * scale * (e1.length() + e2.length()) / (cross * cos);
        assert!((tw - t).abs() <= t_tol, "t {tw} vs {t} (tol {t_tol})");
        assert!(
            (b1w - b1).abs() <= b_tol && (b2w - b2).abs() <= b_tol,
            "({b1w}, {b2w}) vs ({b1}, {b2}) (tol {b_tol})"
        );
    }
    assert!(compared > 5_000, "{compared} hits compared");
}

fn distance_to_segment(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let s = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    (a + s * ab - p).length()
}
