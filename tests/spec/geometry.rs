//! Geometry, executable: the BVH agrees with brute force, a query's interval (0, t_max) is open
//! at t_max, the coplanar tie-break rule holds in
//! either insertion order, spawned rays do not re-hit their own surface, spheres work from both
//! sides, disks are hit inside their ellipse only, and a box's faces point outwards. Book: "Scenes and geometry".

use crate::common;

use common::assert_close;
use common::stats::Family;
use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use pathspace::geometry::bvh::{LeafCost, Passage, SahCost, Width, TIE_EPSILON};
use pathspace::geometry::shape::{Cylinder, Quad, Sphere, Triangle};
use pathspace::geometry::{offset_origin, Aabb, Bvh, Disk, Hit, Primitive, Ray};
use pathspace::math::warp;
use pathspace::scene::{Scene, SceneSource};

mod shape;

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

fn point(r: &mut Pcg64Mcg, half: f32) -> Vec3 {
    Vec3::new(
        r.random_range(-half..half),
        r.random_range(-half..half),
        r.random_range(-half..half),
    )
}

/// A soup of `n` primitives in [-10, 10]^3: small and large triangles, quads, disks, spheres
/// and cylinders (their bounds, hit through the BVH as by brute force).
fn soup(r: &mut Pcg64Mcg, n: usize) -> Vec<Primitive> {
    let mut prims = Vec::with_capacity(n);
    while prims.len() < n {
        let c = point(r, 10.0);
        let size = if r.random::<f32>() < 0.1 { 5.0 } else { 0.8 };
        let p = match r.random_range(0..6) {
            0 | 1 => {
                Triangle::new(c, c + size * unit(r), c + size * unit(r)).map(Primitive::Triangle)
            }
            2 => Quad::new(c, size * unit(r), size * unit(r)).map(Primitive::Quad),
            3 => Disk::new(c, size * unit(r), size * unit(r)).map(Primitive::Disk),
            4 => Cylinder::new(
                c,
                c + size * unit(r),
                0.05 + 0.3 * size * r.random::<f32>(),
                false,
            )
            .map(Primitive::Cylinder),
            _ => Some(Primitive::Sphere(Sphere::new(
                c,
                0.1 + 0.5 * size * r.random::<f32>(),
            ))),
        };
        prims.extend(p);
    }
    prims
}

/// The closest hit by testing every primitive: (t, primitive).
fn brute_closest(prims: &[Primitive], ray: &Ray, t_max: f32) -> Option<(f32, u32)> {
    let mut best: Option<(f32, u32)> = None;
    for (i, p) in prims.iter().enumerate() {
        if let Some((t, _, _)) = p.intersect(ray, t_max) {
            if best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, i as u32));
            }
        }
    }
    best
}

/// A random ray: from inside the soup's bounds or from outside towards it.
fn random_ray(r: &mut Pcg64Mcg) -> Ray {
    if r.random::<bool>() {
        Ray::new(point(r, 12.0), unit(r))
    } else {
        let o = 30.0 * unit(r);
        Ray::new(o, (point(r, 8.0) - o).normalize())
    }
}

/// The BVH's closest hit against brute force's: the same distance, and the same primitive
/// unless another lies at an (almost) equal distance. True when there is a hit.
fn check_closest(
    bvh: &Bvh,
    prims: &[Primitive],
    opaque: &[bool],
    ray: &Ray,
    t_max: f32,
    what: &str,
) -> bool {
    let got = bvh
        .intersect(prims, opaque, ray, t_max)
        .map(|h| (h.t, h.prim));
    match (got, brute_closest(prims, ray, t_max)) {
        (None, None) => false,
        (Some((t, p)), Some((tw, pw))) => {
            assert!((t - tw).abs() <= 1e-5 * (1.0 + tw), "{what}: t {t} vs {tw}");
            assert!(
                p == pw || (t - tw).abs() <= TIE_EPSILON * (1.0 + tw),
                "{what}: {p} vs {pw}, {ray:?}"
            );
            true
        }
        (got, want) => {
            panic!("{what}: BVH {got:?}, brute force {want:?}, ray {ray:?} t_max {t_max}")
        }
    }
}

#[test]
fn closest_hit_equals_brute_force() {
    let mut r = rng(1);
    let mut hits = 0;
    for (scene, n) in [(0, 1), (1, 7), (2, 300), (3, 2000)] {
        let prims = soup(&mut r, n);
        let opaque = vec![true; prims.len()];
        let bvh = Bvh::build(&prims);
        for _ in 0..3000 {
            let ray = random_ray(&mut r);
            let t_max = if r.random::<f32>() < 0.3 {
                r.random_range(0.0..40.0)
            } else {
                f32::INFINITY
            };
            let what = format!("soup {scene}");
            hits += check_closest(&bvh, &prims, &opaque, &ray, t_max, &what) as usize;
        }
    }
    assert!(hits > 3000, "the test rays mostly miss ({hits} hits)");
}

/// The closest hit of an all-opaque scene by testing every primitive: the least (t, index)
/// (the tie-break's order when no null primitive competes), with the primitive's own point
/// and normal.
fn brute_exact(prims: &[Primitive], ray: &Ray, t_max: f32) -> Option<(f32, u32, Vec3, Vec3)> {
    let mut best: Option<(f32, u32, Vec3, Vec3)> = None;
    for (i, p) in prims.iter().enumerate() {
        if let Some((t, q, n)) = p.intersect(ray, t_max) {
            if best.is_none_or(|b| t < b.0) {
                best = Some((t, i as u32, q, n));
            }
        }
    }
    best
}

/// The BVH's hit is brute force's bit for bit: the same primitive, and the distance, point and
/// normal that primitive's own test gives, although the leaves test triangles four at a time
/// (`geometry::leaf`). Over the random soup (triangles in the same leaves as other kinds) and a
/// grid of triangles hit through its shared edges and corners, where edge functions vanish and
/// the test falls back to f64.
#[test]
fn hits_are_the_primitives_own_bit_for_bit() {
    let bits = |h: (f32, u32, Vec3, Vec3)| {
        let v = |p: Vec3| p.to_array().map(f32::to_bits);
        (h.0.to_bits(), h.1, v(h.2), v(h.3))
    };
    let mut r = rng(41);
    let mut grid = Vec::new();
    let corner =
        |i: usize, j: usize| Vec3::new(i as f32 / 8.0, 0.25 * (i % 3) as f32, j as f32 / 8.0);
    for i in 0..16 {
        for j in 0..16 {
            let (a, b, c, d) = (
                corner(i, j),
                corner(i + 1, j),
                corner(i + 1, j + 1),
                corner(i, j + 1),
            );
            grid.extend(
                [[a, b, c], [a, c, d]]
                    .map(|[p, q, s]| Triangle::new(p, q, s).map(Primitive::Triangle)),
            );
        }
    }
    let grid: Vec<Primitive> = grid.into_iter().flatten().collect();
    let mut checked = (0, 0);
    for (scene, prims) in [soup(&mut r, 600), grid].into_iter().enumerate() {
        let opaque = vec![true; prims.len()];
        let bvh = Bvh::build(&prims);
        for _ in 0..4000 {
            let ray = if scene == 0 {
                random_ray(&mut r)
            } else {
                // through a corner or the middle of an edge of the grid, from above
                let (i, j) = (r.random_range(1..32), r.random_range(1..32));
                let at = Vec3::new(i as f32 / 16.0, 0.0, j as f32 / 16.0);
                let at = at + Vec3::Y * 0.25 * ((i / 2) % 3) as f32 * ((i % 2 == 0) as u32 as f32);
                let o = at + Vec3::new(r.random_range(-1.0..1.0), 2.0, r.random_range(-1.0..1.0));
                Ray::new(o, (at - o).normalize())
            };
            let got = bvh.intersect(&prims, &opaque, &ray, f32::INFINITY);
            let got = got.map(|h| bits((h.t, h.prim, h.p, h.ng)));
            assert_eq!(
                got,
                brute_exact(&prims, &ray, f32::INFINITY).map(bits),
                "scene {scene}: {ray:?}"
            );
            if got.is_some() {
                if scene == 0 {
                    checked.0 += 1
                } else {
                    checked.1 += 1
                }
            }
        }
    }
    assert!(checked.0 > 1000 && checked.1 > 3000, "{checked:?} hits");
}

/// A scene of up to 8 walls is split to leaves of at most two, although the SAH prefers one
/// leaf (it counts rays entering the box from outside; the rays of a box of walls start inside
/// it), and its hits from inside are those of brute force.
#[test]
fn a_box_of_walls_is_split_and_hit_as_by_brute_force() {
    let c = Vec3::splat(-1.0);
    let (x, y, z) = (2.0 * Vec3::X, 2.0 * Vec3::Y, 2.0 * Vec3::Z);
    // the six faces of [-1, 1]^3 and two tiles on the floor and the back wall: 8 walls, which
    // the SAH alone would keep in one leaf
    let tile = |(o, u, v): (Vec3, Vec3, Vec3)| (o + 0.25 * (u + v), 0.5 * u, 0.5 * v);
    let faces = [
        (c, z, x),
        (c + y, x, z),
        (c, x, y),
        (c + z, y, x),
        (c, y, z),
        (c + x, z, y),
    ];
    let prims: Vec<Primitive> = faces
        .into_iter()
        .chain([faces[0], faces[2]].map(tile))
        .filter_map(|(o, u, v)| Quad::new(o, u, v).map(Primitive::Quad))
        .collect();
    assert_eq!(prims.len(), 8);
    let bvh = Bvh::build(&prims);
    // four leaves of two walls take seven binary nodes
    assert!(bvh.node_count() >= 7, "{} nodes", bvh.node_count());
    let opaque = vec![true; prims.len()];
    let mut r = rng(7);
    let mut hits = 0;
    for _ in 0..3000 {
        let ray = Ray::new(point(&mut r, 0.99), unit(&mut r));
        let t_max = r.random_range(0.0..3.0);
        hits += check_closest(&bvh, &prims, &opaque, &ray, t_max, "box") as usize;
    }
    assert!(hits > 500, "the test rays mostly miss ({hits} hits)");
}

#[test]
fn closest_hit_with_mixed_opacity_equals_brute_force() {
    // random primitives are never coplanar, so the opacity flags must not change the answer
    let mut r = rng(2);
    let prims = soup(&mut r, 500);
    let opaque: Vec<bool> = (0..prims.len()).map(|_| r.random()).collect();
    let bvh = Bvh::build(&prims);
    for _ in 0..3000 {
        let ray = random_ray(&mut r);
        let got = bvh
            .intersect(&prims, &opaque, &ray, f32::INFINITY)
            .map(|h| h.prim);
        let want = brute_closest(&prims, &ray, f32::INFINITY).map(|h| h.1);
        assert_eq!(got, want, "{ray:?}");
    }
}

#[test]
fn occluded_equals_brute_force() {
    let mut r = rng(3);
    let prims = soup(&mut r, 800);
    let bvh = Bvh::build(&prims);
    let mut blocked = 0;
    for round in 0..4000 {
        let blocks: Vec<bool> = if round % 2 == 0 {
            vec![true; prims.len()]
        } else {
            (0..prims.len()).map(|_| r.random::<f32>() < 0.5).collect()
        };
        let ray = random_ray(&mut r);
        let t_max = r.random_range(0.0..40.0);
        let want = prims
            .iter()
            .zip(&blocks)
            .any(|(p, &b)| b && p.intersect(&ray, t_max).is_some());
        assert_eq!(
            bvh.occluded(&prims, &blocks, &ray, t_max),
            want,
            "{ray:?} t_max {t_max}"
        );
        blocked += want as usize;
    }
    assert!(blocked > 500 && blocked < 3500, "{blocked} of 4000 blocked");
}

/// `Bvh::passage` is the any-hit query that also reports a crossed primitive that does not
/// block (a null boundary): blocked exactly when `occluded` is, else crossing exactly when such
/// a primitive lies in (0, t_max), in trees of both widths. A shadow ray reported clear is
/// taken as one medium segment, so a crossing missed here would be a boundary skipped.
#[test]
fn passage_equals_brute_force() {
    let mut r = rng(4);
    let prims = soup(&mut r, 800);
    let trees = [Width::Four, Width::Eight].map(|w| Bvh::build_with(&prims, |_| true, w));
    let mut seen = [0usize; 3];
    for _ in 0..4000 {
        let blocks: Vec<bool> = (0..prims.len()).map(|_| r.random::<f32>() < 0.2).collect();
        let ray = random_ray(&mut r);
        let t_max = r.random_range(0.0..40.0);
        let hit = |p: &Primitive| p.intersect(&ray, t_max).is_some();
        let (mut blocked, mut crossing) = (false, false);
        for (p, &b) in prims.iter().zip(&blocks) {
            if hit(p) {
                blocked |= b;
                crossing |= !b;
            }
        }
        let want = match (blocked, crossing) {
            (true, _) => Passage::Blocked,
            (false, true) => Passage::Crossing,
            (false, false) => Passage::Clear,
        };
        for bvh in &trees {
            let got = bvh.passage(&prims, &blocks, &ray, t_max);
            assert_eq!(got, want, "{:?} tree, {ray:?} t_max {t_max}", bvh.width());
            assert_eq!(bvh.occluded(&prims, &blocks, &ray, t_max), blocked);
        }
        seen[want as usize] += 1;
    }
    // each outcome is exercised
    assert!(
        seen.iter().all(|&k| k > 400),
        "blocked, crossing, clear: {seen:?}"
    );
}

#[test]
fn unbalanced_hierarchy_still_finds_every_hit() {
    // triangles at geometrically growing distances: binned SAH peels a few off per level, so
    // the tree is deeper than a balanced one; traversal must not lose any subtree
    let prims: Vec<Primitive> = (0..300)
        .map(|i| {
            let x = 1.1f32.powi(i);
            Primitive::Triangle(
                Triangle::new(
                    Vec3::new(x, -1.0, -1.0),
                    Vec3::new(x, 1.0, -1.0),
                    Vec3::new(x, 0.0, 1.0),
                )
                .unwrap(),
            )
        })
        .collect();
    let opaque = vec![true; prims.len()];
    let bvh = Bvh::build(&prims);
    assert!(bvh.depth() <= pathspace::geometry::bvh::MAX_DEPTH);
    for i in 0..300 {
        // a ray along -x starting just beyond triangle i must hit triangle i - 1
        let x = 1.1f32.powi(i) * 1.05;
        let ray = Ray::new(Vec3::new(x, 0.0, 0.0), Vec3::NEG_X);
        let want = brute_closest(&prims, &ray, f32::INFINITY).map(|h| h.1);
        assert_eq!(
            bvh.intersect(&prims, &opaque, &ray, f32::INFINITY)
                .map(|h| h.prim),
            want,
            "i = {i}"
        );
        assert_eq!(
            bvh.occluded(&prims, &opaque, &ray, f32::INFINITY),
            want.is_some(),
            "i = {i}"
        );
    }
}

/// A block of 8 x 8 rooms in miniature: one floor and one ceiling quad over all of them, a
/// large tilted triangle, disk and sphere, and many small primitives, so that the build splits
/// the large ones into several references each (early split clipping).
fn rooms_like(r: &mut Pcg64Mcg) -> Vec<Primitive> {
    let (x, z) = (Vec3::X * 32.0, Vec3::Z * 32.0);
    let mut prims = vec![
        Primitive::Quad(Quad::new(Vec3::ZERO, z, x).unwrap()),
        Primitive::Quad(Quad::new(Vec3::Y * 3.0, x, z).unwrap()),
        Primitive::Triangle(
            Triangle::new(
                Vec3::new(1.0, 0.5, 1.0),
                Vec3::new(31.0, 2.5, 3.0),
                Vec3::new(2.0, 1.5, 30.0),
            )
            .unwrap(),
        ),
        Primitive::Disk(
            Disk::new(
                Vec3::new(16.0, 1.5, 16.0),
                Vec3::new(9.0, 1.0, 0.0),
                Vec3::new(0.0, 0.5, 9.0),
            )
            .unwrap(),
        ),
        Primitive::Sphere(Sphere::new(Vec3::new(24.0, 1.5, 8.0), 4.0)),
    ];
    while prims.len() < 600 {
        let c = Vec3::new(
            r.random_range(0.0..32.0),
            r.random_range(0.0..3.0),
            r.random_range(0.0..32.0),
        );
        prims.extend(
            Triangle::new(c, c + 0.5 * unit(r), c + 0.5 * unit(r)).map(Primitive::Triangle),
        );
    }
    prims
}

/// A unit sphere of `cols` x `rows` longitude-latitude cells, two triangles each, its radius
/// displaced by a few percent: the million-triangle sphere of the Embree benchmark
/// (`examples/ray_sets`) in a smaller form, a dense mesh of thin triangles sharing edges.
fn displaced_sphere(cols: usize, rows: usize) -> Vec<Primitive> {
    let vertex = |i: usize, j: usize| {
        let (phi, theta) = (
            std::f32::consts::TAU * i as f32 / cols as f32,
            std::f32::consts::PI * j as f32 / rows as f32,
        );
        let radius = 1.0 + 0.03 * (7.0 * phi).sin() * (5.0 * theta).cos();
        radius
            * Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            )
    };
    let mut prims = Vec::new();
    for i in 0..cols {
        for j in 0..rows {
            let (a, b) = (vertex(i, j), vertex(i + 1, j));
            let (c, d) = (vertex(i + 1, j + 1), vertex(i, j + 1));
            for [p, q, s] in [[a, b, c], [a, c, d]] {
                prims.extend(Triangle::new(p, q, s).map(Primitive::Triangle));
            }
        }
    }
    prims
}

/// The eight-wide tree (AVX2, where the processor has it) answers every query with the
/// four-wide tree's hit bit for bit: the same t, primitive, point and normal (the barycentrics
/// the point is made of), and the same any-hit answer, over random rays (some along coordinate
/// planes and axes) and ranges in a random soup with null primitives (the tie-break's order), its null copies coplanar with its walls,
/// a room-like scene and a displaced sphere of 80,000 triangles. So does a tree built with the
/// other leaf cost than its size chooses (`LeafCost`), a tree of another shape.
#[test]
fn eight_wide_nodes_return_the_four_wide_hits_bit_for_bit() {
    let native = Width::native();
    let mut r = rng(88);
    let mut soup_with_copies = soup(&mut r, 800);
    let copies: Vec<Primitive> = soup_with_copies[..200].to_vec();
    soup_with_copies.extend(copies);
    let scenes = [
        soup(&mut r, 3000),
        soup_with_copies,
        rooms_like(&mut r),
        displaced_sphere(200, 200),
    ];
    let bits = |h: Option<Hit>| {
        h.map(|h| {
            let v = |p: Vec3| p.to_array().map(f32::to_bits);
            (h.t.to_bits(), h.prim, v(h.p), v(h.ng))
        })
    };
    let mut hits = [0usize; 4];
    for (scene, prims) in scenes.iter().enumerate() {
        let opaque: Vec<bool> = (0..prims.len()).map(|i| i % 5 != 3).collect();
        let four = Bvh::build_with(prims, |_| true, Width::Four);
        let eight = Bvh::build_with(prims, |_| true, Width::Eight);
        // the other leaf cost than the size chooses: another tree, the same hits
        let other_cost = match LeafCost::for_references(prims.len()) {
            LeafCost::PerBlock => LeafCost::PerReference,
            LeafCost::PerReference => LeafCost::PerBlock,
        };
        let recosted = Bvh::build_costing(prims, |_| true, Width::Four, other_cost);
        assert_eq!(four.width(), Width::Four);
        assert_eq!(
            eight.width(),
            native,
            "the widest nodes this processor runs"
        );
        for _ in 0..20_000 {
            let ray = match scene {
                2 => Ray::new(
                    Vec3::new(r.random_range(0.0..32.0), 1.5, r.random_range(0.0..32.0)),
                    unit(&mut r),
                ),
                3 if r.random::<bool>() => {
                    // from near the surface, as bounce and shadow rays leave it
                    Ray::new(unit(&mut r) * r.random_range(0.9f32..1.1), unit(&mut r))
                }
                3 => {
                    let o = 3.5 * unit(&mut r);
                    Ray::new(o, (0.8 * unit(&mut r) - o).normalize())
                }
                _ => random_ray(&mut r),
            };
            // a direction along a coordinate plane or axis: inverse components of +-inf, the
            // slab test's rule for a NaN slab end
            let ray = match r.random_range(0..8) {
                0 => Ray::new(
                    ray.o,
                    (ray.d * Vec3::new(0.0, 1.0, 1.0)).normalize_or(Vec3::Z),
                ),
                1 => Ray::new(ray.o, Vec3::X * ray.d.x.signum()),
                // from a corner of a primitive's box, on the planes of the boxes' slabs
                2 => {
                    let corner = prims[r.random_range(0..prims.len())].bounds().min;
                    let d = (ray.d * Vec3::new(1.0, 0.0, 1.0)).normalize_or(Vec3::X);
                    Ray::new(corner, d)
                }
                _ => ray,
            };
            let t_min = [0.0, 1e-4, r.random_range(0.0..2.0)][r.random_range(0..3)];
            let t_max = [f32::INFINITY, r.random_range(0.1..30.0)][r.random_range(0..2)];
            let h4 = four.intersect_range(prims, &opaque, &ray, t_min, t_max);
            let h8 = eight.intersect_range(prims, &opaque, &ray, t_min, t_max);
            let hc = recosted.intersect_range(prims, &opaque, &ray, t_min, t_max);
            hits[scene] += h4.is_some() as usize;
            assert_eq!(
                bits(h8),
                bits(h4),
                "scene {scene}: {ray:?} ({t_min}, {t_max})"
            );
            assert_eq!(bits(hc), bits(h4), "scene {scene}, {other_cost:?}: {ray:?}");
            let blocked = four.occluded(prims, &opaque, &ray, t_max);
            assert_eq!(
                eight.occluded(prims, &opaque, &ray, t_max),
                blocked,
                "scene {scene}: {ray:?} {t_max}"
            );
            assert_eq!(recosted.occluded(prims, &opaque, &ray, t_max), blocked);
        }
    }
    assert!(hits.iter().all(|&h| h > 5000), "hits per scene {hits:?}");
}

/// Costed per block, the SAH fills the leaves' blocks of four on a finely tessellated surface,
/// where costed per reference it stops at about two or three a leaf: the choice of
/// `Bvh::build` for large trees takes effect (the binary tree's node count is twice its leaves
/// less one).
#[test]
fn costing_leaves_per_block_fills_the_blocks() {
    let prims = displaced_sphere(200, 200);
    let per_leaf = |cost| {
        let bvh = Bvh::build_costing(&prims, |_| true, Width::Four, cost);
        bvh.reference_count() as f64 / bvh.node_count().div_ceil(2) as f64
    };
    let (block, reference) = (
        per_leaf(LeafCost::PerBlock),
        per_leaf(LeafCost::PerReference),
    );
    assert!(
        block > 5.0 && reference < 3.5,
        "references per leaf: {block} per block, {reference} per reference"
    );
}

/// `Bvh::sah_cost` is the statistic Embree prints with `verbose=2`: each node and each leaf
/// block counted once, weighted by the surface area of its box over the root's. Checked on
/// trees whose leaves are known: none, a lone triangle, two far pairs (leaves of two) and two far
/// clusters of eight costed per block (a leaf of two blocks each, so that blocks, not leaves,
/// are what the leaf term counts).
#[test]
fn sah_cost_weights_nodes_and_blocks_by_their_boxes() {
    let cluster = |c: Vec3, n: usize| -> Vec<Primitive> {
        (0..n)
            .map(|i| {
                let o = c + Vec3::new(0.01 * i as f32, 0.0, 0.0);
                let t = Triangle::new(o, o + 0.1 * Vec3::X, o + 0.1 * Vec3::Y).expect("a triangle");
                Primitive::Triangle(t)
            })
            .collect()
    };
    let area = |prims: &[Primitive]| {
        let b = prims.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds()));
        f64::from(b.surface_area())
    };
    // no primitives: no tree and no cost
    assert_eq!(Bvh::build(&[]).sah_cost(), SahCost::default());
    let one = Bvh::build(&cluster(Vec3::ZERO, 1)).sah_cost();
    assert_eq!(
        (one.nodes, one.leaves, one.leaf_count, one.block_count),
        (1.0, 1.0, 1, 1)
    );
    let cases = [Width::Four, Width::Eight].map(|w| [(w, 2, 1), (w, 8, 2)]);
    for (width, n, blocks) in cases.into_iter().flatten() {
        let (a, b) = (cluster(Vec3::ZERO, n), cluster(Vec3::splat(10.0), n));
        let all = [a.clone(), b.clone()].concat();
        let cost = Bvh::build_costing(&all, |_| true, width, LeafCost::PerBlock).sah_cost();
        let case = format!("{width:?}, {n} a cluster");
        let counts = (cost.leaf_count, cost.block_count);
        assert_eq!(counts, (2, 2 * blocks), "{case}");
        assert_close(&format!("{case}: the root node"), cost.nodes, 1.0, 1e-12);
        let leaves = (area(&a) + area(&b)) * blocks as f64 / area(&all);
        assert_close(&format!("{case}: the leaves"), cost.leaves, leaves, 1e-12);
    }
}

// ---- quad blocks ----

/// A quad for the block tests: random, axis-aligned on a grid (as walls are: zero components,
/// corners and edges exactly representable), or flipped.
fn block_quad(r: &mut Pcg64Mcg) -> Quad {
    let c = point(r, 3.0);
    let q = match r.random_range(0..3) {
        0 => Quad::new(c, 2.0 * unit(r), 2.0 * unit(r)),
        _ => {
            let grid = |x: f32| (4.0 * x).round() / 4.0;
            let axis = r.random_range(0..3);
            let e = |k: usize, len: f32| {
                let mut e = Vec3::ZERO;
                e[k] = len;
                e
            };
            let (u, v) = (
                e((axis + 1) % 3, grid(r.random_range(0.25..3.0))),
                e((axis + 2) % 3, grid(r.random_range(0.25..3.0))),
            );
            let (u, v) = if r.random::<bool>() { (u, v) } else { (v, u) };
            Quad::new(c.map(grid), u, v)
        }
    };
    let q = q.expect("a quad with area");
    if r.random::<bool>() {
        q.flipped()
    } else {
        q
    }
}

/// A ray at quad `q` from `o`-ish places: to a random point, a corner, a point of an edge,
/// in the quad's plane, along an edge's line, random, and with a direction component of
/// -0.0 or +0.0.
fn ray_at_quad(r: &mut Pcg64Mcg, q: &Quad) -> Ray {
    let at = |a: f32, b: f32| q.origin + a * q.u + b * q.v;
    let corner = |r: &mut Pcg64Mcg| [0.0, 1.0][r.random_range(0..2)];
    let o = point(r, 6.0);
    let ray = match r.random_range(0..7) {
        0 => Ray::new(o, (at(r.random(), r.random()) - o).normalize()),
        1 => Ray::new(o, (at(corner(r), corner(r)) - o).normalize()),
        2 => {
            let (a, b) = if r.random::<bool>() {
                (corner(r), r.random())
            } else {
                (r.random(), corner(r))
            };
            Ray::new(o, (at(a, b) - o).normalize())
        }
        3 => {
            // in the plane: denominators of 0 or a rounding error
            let p = at(r.random_range(-1.0..2.0), r.random_range(-1.0..2.0));
            let d = (r.random_range(-1.0..1.0) * q.u + r.random_range(-1.0..1.0) * q.v)
                .normalize_or(q.u.normalize());
            Ray::new(p, d)
        }
        4 => {
            // along the line of an edge, from before its start
            let (p, e) =
                [(q.origin, q.u), (q.origin, q.v), (at(1.0, 0.0), q.v)][r.random_range(0..3)];
            Ray::new(p - r.random_range(0.0..2.0) * e, e.normalize())
        }
        5 => Ray::new(o, unit(r)),
        _ => Ray::new(o, (at(r.random(), r.random()) - o).normalize()),
    };
    if r.random_range(0..4) == 0 {
        // a component of exactly -0.0 or +0.0 (an axis-aligned quad's plane then needs no rounding)
        let k = r.random_range(0..3);
        let zero = [0.0f32, -0.0][r.random_range(0..2)];
        let mut d = ray.d;
        d[k] = 0.0;
        if d.length_squared() == 0.0 {
            d[(k + 1) % 3] = -1.0;
        }
        let mut d = d.normalize();
        d[k] = zero;
        Ray::new(ray.o, d)
    } else {
        ray
    }
}

/// The bits of a hit (t, point, normal).
fn hit_bits(h: Option<(f32, Vec3, Vec3)>) -> Option<(u32, [u32; 3], [u32; 3])> {
    let v = |p: Vec3| p.to_array().map(f32::to_bits);
    h.map(|(t, p, n)| (t.to_bits(), v(p), v(n)))
}

/// Quad blocks (`geometry::leaf::QuadLanes`) answer lane by lane what the scalar quad test
/// (`Primitive::intersect_range`) answers, bit for bit: whether it hits in (t_min, t_max),
/// its t, and the point and normal made of the lane's (a, b). Over leaves that mix quads,
/// triangles and spheres (blocks keep the leaf's order, one kind each), random and
/// axis-aligned grid quads (flipped too), and rays at random points, corners, edges, in the
/// quad's plane, along its edges' lines, and with -0.0 direction components.
#[test]
fn quad_blocks_return_the_scalar_quad_test_bit_for_bit() {
    use pathspace::geometry::leaf::{self, Kind, LaneRays};
    let mut r = rng(4141);
    let mut checked = [0usize; 2];
    let mut mixed = 0;
    for _ in 0..300 {
        // one leaf: up to 9 primitives, mostly quads, with triangles and spheres between them
        let n = r.random_range(1..10);
        let prims: Vec<Primitive> = (0..n)
            .map(|_| match r.random_range(0..8) {
                0 => Primitive::Sphere(Sphere::new(point(&mut r, 3.0), 0.5)),
                1 => {
                    let c = point(&mut r, 3.0);
                    let t = Triangle::new(c, c + 2.0 * unit(&mut r), c + 2.0 * unit(&mut r));
                    Primitive::Triangle(t.expect("a triangle with area"))
                }
                _ => Primitive::Quad(block_quad(&mut r)),
            })
            .collect();
        let ids: Vec<u32> = (0..n as u32).collect();
        let (mut blocks, mut quads) = (Vec::new(), Vec::new());
        let first = leaf::lay_out(&ids, &prims, &mut blocks, &mut quads) as usize;
        let blocks = &blocks[first..];
        // the leaf's order, one kind per block, the last block marked
        let order: Vec<u32> = blocks
            .iter()
            .flat_map(|b| b.ids[..b.lanes as usize].to_vec())
            .collect();
        assert_eq!(order, ids);
        assert!(blocks
            .iter()
            .all(|b| b.ids[..b.lanes as usize]
                .iter()
                .all(|&i| match prims[i as usize] {
                    Primitive::Quad(_) => b.kind == Kind::Quads,
                    Primitive::Triangle(_) => b.kind == Kind::Triangles,
                    _ => b.kind == Kind::Others,
                })));
        assert!(
            blocks.last().is_some_and(|b| b.last) && blocks.iter().filter(|b| b.last).count() == 1
        );
        mixed += (blocks.len() > 1 && blocks.iter().any(|b| b.kind == Kind::Quads)) as usize;
        let targets = quads_of(&prims);
        for _ in 0..200 {
            let ray = match targets.len() {
                0 => Ray::new(point(&mut r, 6.0), unit(&mut r)),
                k => {
                    let target = targets[r.random_range(0..k)];
                    ray_at_quad(&mut r, &target)
                }
            };
            let t_min = [0.0, 1e-4, r.random_range(0.0..4.0)][r.random_range(0..3)];
            let t_max = [f32::INFINITY, r.random_range(0.1..10.0)][r.random_range(0..2)];
            let rays = LaneRays::new(&ray, true, true);
            for block in blocks {
                let Some((mask, t, x, y)) = leaf::hits(block, &quads, &rays, t_min, t_max) else {
                    assert_eq!(block.kind, Kind::Others);
                    continue;
                };
                assert_eq!(mask >> block.lanes, 0, "a hit in an unused lane");
                for (k, &i) in block.ids[..block.lanes as usize].iter().enumerate() {
                    let prim = &prims[i as usize];
                    let lane = (mask & (1 << k) != 0 && t[k] < t_max).then(|| {
                        let (p, n) = leaf::lane_point(prim, x[k], y[k]);
                        (t[k], p, n)
                    });
                    let want = prim.intersect_range(&ray, t_min, t_max);
                    assert_eq!(
                        hit_bits(lane),
                        hit_bits(want),
                        "lane {k} of {:?}: {prim:?}, {ray:?} ({t_min}, {t_max})",
                        block.kind
                    );
                    if want.is_some() {
                        checked[(block.kind == Kind::Quads) as usize] += 1;
                    }
                }
            }
        }
    }
    assert!(mixed > 100, "{mixed} leaves mix quads with other kinds");
    assert!(
        checked[1] > 10_000 && checked[0] > 200,
        "hits (triangles, quads) {checked:?}"
    );
}

/// The closest hit by testing every primitive with the tie-break rule (an opaque primitive
/// wins within [`TIE_EPSILON`], else the nearer, else the lower index), as (t, primitive,
/// point, normal); and any hit.
fn brute_tie(
    prims: &[Primitive],
    opaque: &[bool],
    ray: &Ray,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, u32, Vec3, Vec3)> {
    let mut best: Option<(f32, u32, Vec3, Vec3)> = None;
    for (i, p) in prims.iter().enumerate() {
        let Some((t, q, n)) = p.intersect_range(ray, t_min, t_max) else {
            continue;
        };
        let wins = best.is_none_or(|(tb, pb, _, _)| {
            let (oa, ob) = (opaque[i], opaque[pb as usize]);
            if (t - tb).abs() <= TIE_EPSILON * (1.0 + tb) && oa != ob {
                oa
            } else {
                t < tb || (t == tb && (i as u32) < pb)
            }
        });
        if wins {
            best = Some((t, i as u32, q, n));
        }
    }
    best
}

/// Through the BVH of either width, scenes of quads (a fog box's walls with their null copies,
/// a cluster of grid and random quads among triangles and spheres, so that leaves mix them)
/// return the closest hit of the scalar tests with the tie-break, bit for bit, and the same
/// any-hit answer.
#[test]
fn bvh_over_quad_blocks_returns_the_scalar_hits_bit_for_bit() {
    let mut r = rng(4142);
    let fog = Scene::fog_box();
    let mut cluster: Vec<Primitive> = (0..400)
        .map(|_| match r.random_range(0..6) {
            0 => Primitive::Sphere(Sphere::new(point(&mut r, 3.0), 0.3)),
            1 => {
                let c = point(&mut r, 3.0);
                Primitive::Triangle(Triangle::new(c, c + unit(&mut r), c + unit(&mut r)).unwrap())
            }
            _ => Primitive::Quad(block_quad(&mut r)),
        })
        .collect();
    // null copies of some quads: exact ties the opaque one must win
    let copies: Vec<Primitive> = cluster.iter().step_by(7).copied().collect();
    cluster.extend(copies);
    let scenes = [fog.prims.clone(), cluster];
    let bits = |h: Option<(f32, u32, Vec3, Vec3)>| {
        let v = |p: Vec3| p.to_array().map(f32::to_bits);
        h.map(|(t, i, p, n)| (t.to_bits(), i, v(p), v(n)))
    };
    let mut hits = [0usize; 2];
    for (scene, prims) in scenes.iter().enumerate() {
        let opaque: Vec<bool> = match scene {
            0 => fog.prim_opaque.clone(),
            _ => (0..prims.len()).map(|i| i < 400).collect(),
        };
        let quads = quads_of(prims);
        for width in [Width::Four, Width::Eight] {
            let bvh = Bvh::build_with(prims, |_| true, width);
            for _ in 0..20_000 {
                let target = quads[r.random_range(0..quads.len())];
                let ray = ray_at_quad(&mut r, &target);
                let t_min = [0.0, 1e-4, r.random_range(0.0..2.0)][r.random_range(0..3)];
                let t_max = [f32::INFINITY, r.random_range(0.1..10.0)][r.random_range(0..2)];
                let got = bvh.intersect_range(prims, &opaque, &ray, t_min, t_max);
                let want = brute_tie(prims, &opaque, &ray, t_min, t_max);
                hits[scene] += want.is_some() as usize;
                assert_eq!(
                    bits(got.map(|h| (h.t, h.prim, h.p, h.ng))),
                    bits(want),
                    "scene {scene} {width:?}: {ray:?} ({t_min}, {t_max})"
                );
                let any = prims
                    .iter()
                    .zip(&opaque)
                    .any(|(p, &o)| o && p.intersect(&ray, t_max).is_some());
                assert_eq!(
                    bvh.occluded(prims, &opaque, &ray, t_max),
                    any,
                    "scene {scene} {width:?}: {ray:?} {t_max}"
                );
            }
        }
    }
    assert!(hits.iter().all(|&h| h > 10_000), "hits per scene {hits:?}");
}

/// Rays through a triangle's box face, edge or corner, where they meet the triangle's
/// axis-aligned edges and its corners: the slab test's exit distance carries rounding
/// error, so without its relative slack (`1.000_000_4` in `geometry::wide`) such a ray's
/// box test can fail although the triangle test hits. Both widths return brute force's hit
/// bit for bit on them.
/// Right triangles apart from each other (a leaf each), flat on a coordinate plane or tilted,
/// so that edges and corners lie on their boxes' faces.
fn triangles_on_their_boxes_faces() -> Vec<Primitive> {
    let mut prims = Vec::new();
    for (k, a) in [-6.0f32, -2.0, 2.0, 6.0].into_iter().enumerate() {
        let o = Vec3::new(a, 0.3 * a, 0.1 - 0.7 * a);
        let (u, v) = match k % 2 {
            0 => (Vec3::X * 1.3, Vec3::Y * 0.7),
            _ => (Vec3::new(0.9, 0.0, 0.0), Vec3::new(0.0, 1.1, 0.6)),
        };
        for [p, q, s] in [
            [o, o + u, o + v],
            [
                o + 4.0 * Vec3::Y,
                o + 4.0 * Vec3::Y + v,
                o + 4.0 * Vec3::Y + u,
            ],
        ] {
            prims.extend(Triangle::new(p, q, s).map(Primitive::Triangle));
        }
    }
    prims
}

#[test]
fn rays_grazing_a_childs_box_hit_what_brute_force_hits_in_either_width() {
    let prims = triangles_on_their_boxes_faces();
    let opaque = vec![true; prims.len()];
    let trees = [Width::Four, Width::Eight].map(|w| Bvh::build_with(&prims, |_| true, w));
    let bits = |h: Option<(f32, u32, Vec3, Vec3)>| {
        h.map(|(t, p, q, n)| {
            (
                t.to_bits(),
                p,
                q.to_array().map(f32::to_bits),
                n.to_array().map(f32::to_bits),
            )
        })
    };
    let mut r = rng(5);
    let mut hits = 0;
    for prim in &prims {
        let Primitive::Triangle(tri) = prim else {
            unreachable!()
        };
        let [p0, p1, p2] = [
            tri.point(0.0, 0.0),
            tri.point(1.0, 0.0),
            tri.point(0.0, 1.0),
        ];
        for i in 0..400 {
            // a point on an edge from p0 (axis-aligned) or a corner, or one ulp off an edge
            let s = (i % 20) as f32 / 20.0;
            let target = match i % 4 {
                0 => p0 + s * (p1 - p0),
                1 => p0 + s * (p2 - p0),
                2 => [p0, p1, p2][i % 3],
                _ => (p0 + s * (p1 - p0)).map(|x| f32::from_bits(x.to_bits() + 1)),
            };
            let o = target + r.random_range(0.5..6.0) * unit(&mut r);
            let ray = Ray::new(o, (target - o).normalize());
            let want = bits(brute_exact(&prims, &ray, f32::INFINITY));
            hits += want.is_some() as usize;
            for bvh in &trees {
                let got = bvh
                    .intersect(&prims, &opaque, &ray, f32::INFINITY)
                    .map(|h| (h.t, h.prim, h.p, h.ng));
                assert_eq!(bits(got), want, "{:?}: {ray:?}", bvh.width());
            }
        }
    }
    assert!(hits > 1000, "{hits} rays hit");
}

/// Rays lying in the plane of a box's face, along it (a direction component of +0 or -0, an
/// inverse of +inf or -inf), through a triangle's edge on that face: the slab ends on that axis
/// are 0 x inf = NaN and +-inf, and the axis must not constrain the ray (its origin is on the
/// closed box's face). Both widths return brute force's hit bit for bit.
#[test]
fn rays_along_a_boxs_face_hit_what_brute_force_hits_in_either_width() {
    let prims = triangles_on_their_boxes_faces();
    let opaque = vec![true; prims.len()];
    let trees = [Width::Four, Width::Eight].map(|w| Bvh::build_with(&prims, |_| true, w));
    let key = |h: Option<(f32, u32)>| h.map(|(t, p)| (t.to_bits(), p));
    let mut r = rng(6);
    let mut hits = 0;
    for prim in &prims {
        let Primitive::Triangle(tri) = prim else {
            unreachable!()
        };
        let p0 = tri.point(0.0, 0.0);
        // the triangle's edge along x from p0, on the plane y = p0.y of the triangle's box
        let p1 = [tri.point(1.0, 0.0), tri.point(0.0, 1.0)]
            .into_iter()
            .find(|p| p.y == p0.y && p.z == p0.z)
            .expect("an edge along x");
        for i in 0..200 {
            let target = p0 + ((i % 20) as f32 / 20.0) * (p1 - p0);
            let o = target + Vec3::new(r.random_range(-3.0..3.0), 0.0, r.random_range(2.0..6.0));
            let mut d = (target - o).normalize();
            assert_eq!(d.y, 0.0);
            d.y = if i % 2 == 0 { 0.0 } else { -0.0 };
            let ray = Ray::new(o, d);
            let want = brute_exact(&prims, &ray, f32::INFINITY).map(|h| (h.0, h.1));
            hits += want.is_some() as usize;
            for bvh in &trees {
                let got = bvh.intersect(&prims, &opaque, &ray, f32::INFINITY);
                let got = got.map(|h| (h.t, h.prim));
                assert_eq!(key(got), key(want), "{:?}: {ray:?}", bvh.width());
            }
        }
    }
    assert!(hits > 400, "{hits} rays hit");
}

#[test]
fn large_primitives_split_into_several_references_are_hit_as_by_brute_force() {
    let mut r = rng(11);
    let prims = rooms_like(&mut r);
    let bvh = Bvh::build(&prims);
    // the five large primitives are referenced in several leaves each
    assert!(
        bvh.reference_count() >= prims.len() + 5,
        "{} references of {} primitives",
        bvh.reference_count(),
        prims.len()
    );
    let opaque: Vec<bool> = (0..prims.len()).map(|_| r.random()).collect();
    let (mut hits, mut blocked) = (0, 0);
    for i in 0..20_000 {
        // rays aimed at the lines where halving the 32 m quads cuts them (multiples of 0.5 m),
        // give or take a little, from inside the block and from above it
        let line =
            |r: &mut Pcg64Mcg| 0.5 * r.random_range(0..=64) as f32 + r.random_range(-0.02f32..0.02);
        let target = Vec3::new(
            line(&mut r),
            if r.random() { 0.0 } else { 3.0 },
            line(&mut r),
        );
        let o = if i % 3 == 0 {
            Vec3::new(16.0, 40.0, 16.0) + 10.0 * unit(&mut r)
        } else {
            Vec3::new(
                r.random_range(0.0..32.0),
                r.random_range(0.1..2.9),
                r.random_range(0.0..32.0),
            )
        };
        let ray = Ray::new(o, (target - o).normalize());
        let t_max = if i % 2 == 0 {
            f32::INFINITY
        } else {
            r.random_range(0.0..60.0)
        };
        hits += check_closest(&bvh, &prims, &opaque, &ray, t_max, "rooms") as usize;
        let any = brute_closest(&prims, &ray, t_max).is_some();
        assert_eq!(
            bvh.occluded(&prims, &vec![true; prims.len()], &ray, t_max),
            any,
            "{ray:?}"
        );
        blocked += any as usize;
    }
    assert!(
        hits > 10_000 && blocked > 10_000,
        "{hits} hits, {blocked} blocked"
    );
}

#[test]
fn empty_bvh_hits_nothing() {
    let bvh = Bvh::build(&[]);
    let ray = Ray::new(Vec3::ZERO, Vec3::X);
    assert!(bvh.intersect(&[], &[], &ray, f32::INFINITY).is_none());
    assert!(!bvh.occluded(&[], &[], &ray, f32::INFINITY));
}

/// A query's interval is open: a hit at exactly t_max is not in it, one a float step farther
/// out is, for the scalar test, the BVH's leaf lanes of triangles and of quads, and any-hit
/// queries, in either width.
#[test]
fn a_hit_at_exactly_t_max_lies_outside_the_query() {
    let triangle = Triangle::new(
        Vec3::new(0.0, 0.0, -2.0),
        Vec3::new(1.0, 0.0, -2.0),
        Vec3::new(0.0, 1.0, -2.0),
    );
    let quad = Quad::new(Vec3::new(-1.0, -1.0, -2.0), 2.0 * Vec3::X, 2.0 * Vec3::Y);
    let ray = Ray::new(Vec3::new(0.25, 0.25, 0.0), -Vec3::Z);
    let beyond = f32::from_bits(2.0f32.to_bits() + 1);
    for prim in [
        Primitive::Triangle(triangle.unwrap()),
        Primitive::Quad(quad.unwrap()),
    ] {
        // the hit's distance is exactly 2, so t_max = 2 is the edge case itself
        let t = prim.intersect(&ray, 3.0).map(|h| h.0);
        assert_eq!(t, Some(2.0), "{prim:?}");
        assert!(prim.intersect(&ray, 2.0).is_none(), "{prim:?}");
        let prims = [prim];
        for width in [Width::Four, Width::Eight] {
            let bvh = Bvh::build_with(&prims, |_| true, width);
            let at = |t_max| bvh.intersect(&prims, &[true], &ray, t_max).map(|h| h.t);
            assert_eq!(at(2.0), None, "{prim:?} {width:?}");
            assert_eq!(at(beyond), Some(2.0), "{prim:?} {width:?}");
            assert!(
                !bvh.occluded(&prims, &[true], &ray, 2.0),
                "{prim:?} {width:?}"
            );
            assert!(
                bvh.occluded(&prims, &[true], &ray, beyond),
                "{prim:?} {width:?}"
            );
        }
    }
}

// ---- the coplanar tie-break rule ----

#[test]
fn opaque_wins_a_coplanar_tie_in_either_order() {
    let mut r = rng(4);
    // an opaque wall and a null boundary in the plane z = -1, written differently (other origin,
    // other edge vectors, other winding) so the two computed distances differ by rounding
    let wall = Primitive::Quad(
        Quad::new(
            Vec3::new(-1.0, -1.0, -1.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        )
        .unwrap(),
    );
    let null = Primitive::Quad(
        Quad::new(
            Vec3::new(-3.0, -3.0, -1.0),
            Vec3::new(0.0, 6.0, 0.0),
            Vec3::new(6.0, 0.0, 0.0),
        )
        .unwrap(),
    );
    let clutter = soup(&mut r, 60)
        .into_iter()
        .map(|p| match p {
            // keep the clutter out of the way of the rays (all of it above z = 2)
            Primitive::Cylinder(c) => Primitive::Cylinder(
                Cylinder::new(
                    c.p0 + 25.0 * Vec3::Z,
                    c.p0 + c.length * c.axis + 25.0 * Vec3::Z,
                    c.radius,
                    c.flip,
                )
                .unwrap(),
            ),
            Primitive::Sphere(s) => Primitive::Sphere(Sphere {
                center: s.center + Vec3::new(0.0, 0.0, 25.0),
                ..s
            }),
            Primitive::Triangle(t) => Primitive::Triangle(
                Triangle::new(
                    t.p0 + 25.0 * Vec3::Z,
                    t.p1 + 25.0 * Vec3::Z,
                    t.p2 + 25.0 * Vec3::Z,
                )
                .unwrap(),
            ),
            Primitive::Quad(q) => {
                Primitive::Quad(Quad::new(q.origin + 25.0 * Vec3::Z, q.u, q.v).unwrap())
            }
            Primitive::Disk(d) => {
                Primitive::Disk(Disk::new(d.center + 25.0 * Vec3::Z, d.u, d.v).unwrap())
            }
        })
        .collect::<Vec<_>>();
    for wall_first in [true, false] {
        for with_clutter in [false, true] {
            let mut prims = if wall_first {
                vec![wall, null]
            } else {
                vec![null, wall]
            };
            let mut opaque = if wall_first {
                vec![true, false]
            } else {
                vec![false, true]
            };
            if with_clutter {
                // the two quads may end up in different leaves
                prims.splice(1..1, clutter.iter().copied());
                opaque.splice(1..1, clutter.iter().map(|_| true));
            }
            let wall_index = if wall_first {
                0
            } else {
                prims.len() as u32 - 1
            };
            let bvh = Bvh::build(&prims);
            for _ in 0..2000 {
                let target = Vec3::new(
                    r.random_range(-0.99..0.99),
                    r.random_range(-0.99..0.99),
                    -1.0,
                );
                let o = Vec3::new(
                    r.random_range(-2.0..2.0),
                    r.random_range(-2.0..2.0),
                    r.random_range(-0.5..2.0),
                );
                let ray = Ray::new(o, (target - o).normalize());
                let hit = bvh
                    .intersect(&prims, &opaque, &ray, f32::INFINITY)
                    .expect("the wall is in the way");
                assert_eq!(
                    hit.prim, wall_index,
                    "wall_first {wall_first}, clutter {with_clutter}, {ray:?}"
                );
            }
        }
    }
}

#[test]
fn fog_box_rays_stop_at_the_walls_not_at_the_null_boundary() {
    // the shipped scene: the fog's null box is coplanar with five walls
    let scene = Scene::fog_box();
    let mut r = rng(5);
    let mut walls = 0;
    for _ in 0..20000 {
        let ray = Ray::new(point(&mut r, 0.95), unit(&mut r));
        let Some(hit) = scene.intersect(&ray, f32::INFINITY) else {
            continue;
        };
        if scene.shape_of(&hit).is_null() {
            // only through the open face (z = +1) may the ray meet the boundary itself
            assert!((hit.p.z - 1.0).abs() < 1e-4, "null face hit at {:?}", hit.p);
        } else {
            walls += 1;
        }
    }
    assert!(walls > 10000);
}

// ---- spawned rays ----

fn primitives_for_offsets(r: &mut Pcg64Mcg) -> Vec<Primitive> {
    let mut prims = Vec::new();
    for scale in [0.01f32, 1.0, 100.0] {
        for _ in 0..10 {
            let c = point(r, 2.0 * scale) + Vec3::splat(scale);
            prims.push(Primitive::Quad(
                Quad::new(c, scale * unit(r), scale * unit(r)).unwrap(),
            ));
            prims.push(Primitive::Triangle(
                Triangle::new(c, c + scale * unit(r), c + scale * unit(r)).unwrap(),
            ));
            prims.push(Primitive::Sphere(Sphere::new(
                c,
                scale * r.random_range(0.2..1.0),
            )));
        }
    }
    prims
}

#[test]
fn offset_rays_do_not_rehit_their_own_surface() {
    let mut r = rng(6);
    for prim in primitives_for_offsets(&mut r) {
        for _ in 0..200 {
            // a surface point as a ray finds it (reprojected), not as sampling places it
            let (target, _) = prim.sample_area(glam::Vec2::new(r.random(), r.random()));
            let o = target + 3.0 * prim.bounds().extent().length().max(1e-3) * unit(&mut r);
            let Some((_, p, ng)) =
                prim.intersect(&Ray::new(o, (target - o).normalize()), f32::INFINITY)
            else {
                continue;
            };
            for _ in 0..20 {
                let d = unit(&mut r);
                let ray = Ray::new(offset_origin(p, ng, d), d);
                match (prim, prim.intersect(&ray, f32::INFINITY)) {
                    (_, None) => {}
                    (Primitive::Sphere(s), Some((t, _, _))) => {
                        // going in, the ray must cross the chord 2 r |cos| to the far side, not
                        // stop at once (the offset lengthens the chord a little, by up to
                        // offset / |cos| for grazing rays)
                        let chord = 2.0 * s.radius * d.dot(ng).abs();
                        assert!(
                            d.dot(ng) < 0.0,
                            "a ray leaving a sphere hit it again at t = {t}"
                        );
                        assert!(t >= 0.5 * chord, "t {t}, chord {chord}, {s:?}");
                    }
                    (_, Some((t, q, _))) => {
                        panic!("{prim:?} re-hit at t = {t} ({q:?}) from {p:?} along {d:?}")
                    }
                }
            }
        }
    }
}

// ---- spheres ----

#[test]
fn sphere_from_outside_and_inside() {
    let s = Primitive::Sphere(Sphere::new(Vec3::new(1.0, 2.0, 3.0), 2.0));
    // from outside, towards the centre: the near side, normal facing the ray
    let (t, p, n) = s
        .intersect(
            &Ray::new(Vec3::new(1.0, 2.0, 10.0), Vec3::NEG_Z),
            f32::INFINITY,
        )
        .unwrap();
    assert!(
        (t - 5.0).abs() < 1e-5
            && (p - Vec3::new(1.0, 2.0, 5.0)).length() < 1e-5
            && n.abs_diff_eq(Vec3::Z, 1e-6)
    );
    // from outside, away from it, or passing beside it: nothing
    assert!(s
        .intersect(&Ray::new(Vec3::new(1.0, 2.0, 10.0), Vec3::Z), f32::INFINITY)
        .is_none());
    assert!(s
        .intersect(
            &Ray::new(Vec3::new(1.0, 4.5, 10.0), Vec3::NEG_Z),
            f32::INFINITY
        )
        .is_none());
    // t_max shorter than the distance: nothing
    assert!(s
        .intersect(&Ray::new(Vec3::new(1.0, 2.0, 10.0), Vec3::NEG_Z), 4.9)
        .is_none());
    // from the centre: the far side at t = radius, normal outwards (along the ray)
    let mut r = rng(7);
    for _ in 0..1000 {
        let d = unit(&mut r);
        let o = Vec3::new(1.0, 2.0, 3.0) + 1.5 * point(&mut r, 0.5);
        let (t, p, n) = s
            .intersect(&Ray::new(o, d), f32::INFINITY)
            .expect("from inside a ray always leaves");
        assert!(t > 0.0 && ((p - Vec3::new(1.0, 2.0, 3.0)).length() - 2.0).abs() < 1e-5);
        assert!(
            n.dot(d) > 0.0,
            "leaving, the outward normal faces along the ray"
        );
        assert!((o + t * d - p).length() < 1e-4);
    }
}

// ---- disks ----

/// An elliptic disk is hit where a^2 + b^2 <= 1 in its axes' coordinates and nowhere else, at
/// the plane's distance, with the normal u x v; its sampled points lie on it (a ray aimed at
/// one hits it there), and its area is pi |u x v|.
#[test]
fn disk_is_hit_inside_its_ellipse_only() {
    let (c, u, v) = (
        Vec3::new(0.5, -1.0, 2.0),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.0, 0.6, 0.8),
    );
    let disk = Primitive::Disk(Disk::new(c, u, v).unwrap());
    let n = u.cross(v).normalize();
    assert!((disk.area() - std::f32::consts::PI * u.cross(v).length()).abs() < 1e-5);
    let mut r = rng(11);
    for _ in 0..4000 {
        let (a, b) = (r.random_range(-1.3..1.3f32), r.random_range(-1.3..1.3f32));
        let target = c + a * u + b * v;
        let o = target + 3.0 * n + 0.5 * unit(&mut r);
        let d = (target - o).normalize();
        let hit = disk.intersect(&Ray::new(o, d), f32::INFINITY);
        let rho2 = a * a + b * b;
        if (rho2 - 1.0).abs() < 1e-3 {
            continue; // the rim: either answer is within rounding
        }
        match hit {
            Some((t, p, ng)) => {
                assert!(rho2 < 1.0, "hit outside the ellipse at {a}, {b}");
                assert!((p - target).length() < 1e-4 && (t - (target - o).length()).abs() < 1e-4);
                assert!(ng.abs_diff_eq(n, 1e-6));
            }
            None => assert!(rho2 > 1.0, "missed inside the ellipse at {a}, {b}"),
        }
    }
    // sampled points are on the disk: a ray from above hits each where it was sampled
    for _ in 0..1000 {
        let (p, ng) = disk.sample_area(glam::Vec2::new(r.random(), r.random()));
        let o = p + 2.0 * n;
        let (_, q, _) = disk
            .intersect(&Ray::new(o, -n), f32::INFINITY)
            .expect("a sampled point is on the disk");
        assert!((q - p).length() < 1e-4 && ng.abs_diff_eq(n, 1e-6));
    }
}

// ---- boxes ----

#[test]
fn box_faces_point_outwards() {
    let text = "[[shapes]]\ntype = \"box\"\nmin = [-1.0, -2.0, 0.5]\nmax = [3.0, 1.0, 2.0]\nmaterial = \"null\"\n\
                \n[[sensors]]\ntype = \"irradiance_meter\"\nname = \"m\"\norigin = [9, 9, 9]\nu = [1, 0, 0]\nv = [0, 1, 0]\n";
    let scene = Scene::load(&SceneSource::embedded("box.toml", text)).unwrap();
    assert_eq!(scene.prims.len(), 6);
    let centre = Vec3::new(1.0, -0.5, 1.25);
    let mut normals = Vec::new();
    for p in &scene.prims {
        let Primitive::Quad(q) = p else {
            panic!("a box is made of quads")
        };
        let face_centre = q.origin + 0.5 * (q.u + q.v);
        assert!(
            (face_centre - centre).dot(q.n) > 0.0,
            "face at {face_centre:?} has normal {:?}",
            q.n
        );
        // axis aligned
        assert!((q.n.abs().max_element() - 1.0).abs() < 1e-6);
        normals.push(q.n);
    }
    for axis in [
        Vec3::X,
        Vec3::Y,
        Vec3::Z,
        Vec3::NEG_X,
        Vec3::NEG_Y,
        Vec3::NEG_Z,
    ] {
        assert!(
            normals.iter().any(|n| n.abs_diff_eq(axis, 1e-6)),
            "no face with normal {axis:?}"
        );
    }
}

/// Exactly coincident primitives of one opacity hit at exactly one distance: the lowest index
/// wins, whichever leaf the traversal enters first (the result never depends on the order of
/// the tree, so a faster traversal keeps every image bit for bit).
#[test]
fn an_exact_tie_goes_to_the_lowest_index_in_any_traversal_order() {
    let mut r = rng(5);
    let quad = || {
        Primitive::Quad(
            Quad::new(
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(0.0, 2.0, 0.0),
            )
            .unwrap(),
        )
    };
    // more copies than a leaf holds, so they land in several leaves
    let prims: Vec<Primitive> = (0..9).map(|_| quad()).collect();
    let opaque = vec![true; prims.len()];
    let bvh = Bvh::build(&prims);
    assert!(bvh.node_count() > 1, "the copies share one leaf");
    for _ in 0..500 {
        let o = Vec3::new(
            r.random_range(-0.9..0.9),
            r.random_range(-0.9..0.9),
            if r.random() { 3.0 } else { -3.0 },
        );
        let to = Vec3::new(r.random_range(-0.9..0.9), r.random_range(-0.9..0.9), 0.0);
        let ray = Ray::new(o, (to - o).normalize());
        let hit = bvh.intersect(&prims, &opaque, &ray, f32::INFINITY).unwrap();
        assert_eq!(hit.prim, 0, "ray {ray:?}");
    }
}

// ---- cylinders ----

/// Cylinders of several sizes and directions, outward and flipped.
fn cylinders() -> Vec<Cylinder> {
    vec![
        Cylinder::new(Vec3::ZERO, Vec3::Z, 1.0, false).unwrap(),
        Cylinder::new(
            Vec3::new(0.5, -1.0, 2.0),
            Vec3::new(1.5, 1.0, 1.0),
            0.3,
            false,
        )
        .unwrap(),
        Cylinder::new(
            Vec3::new(-2.0, 0.0, 1.0),
            Vec3::new(-2.0, 4.0, 1.0),
            2.5,
            true,
        )
        .unwrap(),
        Cylinder::new(
            Vec3::new(3.0, 3.0, -1.0),
            Vec3::new(-1.0, 2.0, 0.5),
            0.05,
            true,
        )
        .unwrap(),
    ]
}

/// The nearest t in (0, inf) with |q(t) - p0 - (q(t) - p0).a a| = r and 0 <= (q(t) - p0).a <=
/// L, from the textbook quadratic in f64 on the full 3-D offset (not the code's formulation),
/// with `None` also when the answer sits within `slack` of an open end or of tangency, where f32
/// rounding may decide either way.
fn reference_hit(c: &Cylinder, ray: &Ray) -> Option<Option<f64>> {
    let (a, p0) = (c.axis.as_dvec3(), c.p0.as_dvec3());
    let (o, d) = (ray.o.as_dvec3() - p0, ray.d.as_dvec3());
    let perp = |v: glam::DVec3| v - v.dot(a) * a;
    let (op, dp) = (perp(o), perp(d));
    let (qa, qb, qc) = (
        dp.dot(dp),
        2.0 * op.dot(dp),
        op.dot(op) - (c.radius as f64).powi(2),
    );
    let disc = qb * qb - 4.0 * qa * qc;
    let slack = 1e-3;
    if qa < 1e-9 || disc.abs() < slack * (qb * qb + 4.0 * qa * qc.abs()) {
        return None;
    }
    if disc < 0.0 {
        return Some(None);
    }
    let mut roots = [
        (-qb - disc.sqrt()) / (2.0 * qa),
        (-qb + disc.sqrt()) / (2.0 * qa),
    ];
    roots.sort_by(f64::total_cmp);
    for t in roots {
        let z = o.dot(a) + t * d.dot(a);
        let len = c.length as f64;
        if t.abs() < slack || (z.abs() < slack * len) || ((z - len).abs() < slack * len) {
            return None;
        }
        if t > 0.0 && (0.0..=len).contains(&z) {
            return Some(Some(t));
        }
    }
    Some(None)
}

/// Every ray (from outside, from inside the tube, through the open ends) hits a cylinder where
/// the textbook quadratic says, at the nearest root on the tube (the far one when the near
/// one is behind the origin or beyond an end): the hit lies on the implicit surface (distance
/// radius from the axis, height in [0, L]) and its normal is the unit radial direction, inwards
/// when flipped.
#[test]
fn cylinder_hits_are_the_nearest_root_on_the_implicit_surface() {
    let mut r = rng(41);
    let (mut hits, mut far, mut checked) = (0, 0, 0);
    for c in cylinders() {
        let prim = Primitive::Cylinder(c);
        let centre = c.p0 + 0.5 * c.length * c.axis;
        for _ in 0..20_000 {
            // origins around the cylinder, a third of them inside the tube
            let o = if r.random_range(0.0..1.0) < 0.33 {
                let (p, _) = prim.sample_area(Vec2::new(r.random(), r.random()));
                centre + r.random_range(0.0f32..0.95) * (p - centre)
            } else {
                centre + (c.length + c.radius) * point(&mut r, 1.5)
            };
            let ray = Ray::new(o, unit(&mut r));
            let Some(expected) = reference_hit(&c, &ray) else {
                continue;
            };
            checked += 1;
            let got = prim.intersect(&ray, f32::INFINITY);
            match (expected, got) {
                (None, None) => {}
                (Some(t), Some((tg, p, n))) => {
                    hits += 1;
                    let rel = p - c.p0;
                    let z = rel.dot(c.axis);
                    let radial = rel - z * c.axis;
                    assert!(
                        (tg as f64 - t).abs() <= 1e-4 * (1.0 + t),
                        "t {tg} vs {t} for {ray:?}, {c:?}"
                    );
                    assert!(
                        (radial.length() - c.radius).abs() <= 1e-5 * (1.0 + p.abs().max_element())
                    );
                    assert!((-1e-5..=c.length + 1e-5).contains(&z), "height {z}");
                    let out = radial.normalize();
                    let want = if c.flip { -out } else { out };
                    assert!(n.abs_diff_eq(want, 1e-5), "normal {n} vs {want}");
                    assert!((ray.at(tg) - p).length() <= 1e-4 * (1.0 + tg));
                    if (o - c.p0 - (o - c.p0).dot(c.axis) * c.axis).length() < c.radius {
                        far += 1;
                    }
                }
                (e, g) => panic!("expected {e:?}, got {g:?} for {ray:?}, {c:?}"),
            }
        }
    }
    // the sample covered hits from inside (the far root) and misses
    assert!(
        hits > 10_000 && far > 3_000 && checked > 70_000,
        "{hits} {far} {checked}"
    );
}

/// Cauchy-Crofton: isotropic random lines meeting a ball of radius R cross a surface inside
/// it A / (2 pi R^2) times on average, so counting every crossing (each root) of lines
/// estimates the area 2 pi r L the light sampler's density 1 / A assumes.
#[test]
fn cylinder_area_is_what_random_lines_cross() {
    let mut fam = Family::new("geometry: cylinder area by Crofton's formula");
    let mut r = rng(5);
    for c in cylinders() {
        let prim = Primitive::Cylinder(c);
        let centre = c.p0 + 0.5 * c.length * c.axis;
        let big = 0.5 * c.length + c.radius + 0.01;
        let n = 200_000u64;
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let d = unit(&mut r);
            let f = pathspace::math::Frame::from_normal(d);
            let disk = warp::concentric_disk(Vec2::new(r.random(), r.random())) * big;
            let o = centre + disk.x * f.s + disk.y * f.t - 2.0 * big * d;
            let ray = Ray::new(o, d);
            let mut count = 0.0;
            let mut t_min = 0.0;
            while let Some((t, _, _)) = prim.intersect_range(&ray, t_min, f32::INFINITY) {
                count += 1.0;
                t_min = t * (1.0 + 1e-6);
            }
            sum += count;
            sum2 += count * count;
        }
        let mean = sum / n as f64;
        let var = sum2 / n as f64 - mean * mean;
        let scale = 2.0 * std::f64::consts::PI * (big as f64).powi(2);
        fam.samples_are(
            &format!("area of {c:?}"),
            mean * scale,
            var * scale * scale,
            n,
            prim.area() as f64,
        );
        let closed = std::f64::consts::TAU * c.radius as f64 * c.length as f64;
        assert_close("area", prim.area() as f64, closed, 1e-6);
    }
    fam.finish();
}

/// Area sampling: every point lies on the tube with its radial normal (inwards when flipped),
/// inside the bounds; height and angle are uniform (the unrolled tube is a rectangle, so the
/// density 1 / A is uniform); `sample_area_inverse` gives back the sample.
#[test]
fn cylinder_samples_are_uniform_on_the_tube() {
    let mut fam = Family::new("geometry: cylinder area sampling");
    let mut r = rng(9);
    for c in cylinders() {
        let prim = Primitive::Cylinder(c);
        let bounds = prim.bounds();
        let (mut heights, mut angles) = (Vec::new(), Vec::new());
        for _ in 0..20_000 {
            let u = Vec2::new(r.random(), r.random());
            let (p, n) = prim.sample_area(u);
            let rel = p - c.p0;
            let z = rel.dot(c.axis);
            let radial = rel - z * c.axis;
            assert!((radial.length() - c.radius).abs() <= 1e-5 * (1.0 + p.abs().max_element()));
            let want = if c.flip {
                -radial.normalize()
            } else {
                radial.normalize()
            };
            // the normal from the position carries its rounding over the radius
            let tol = 1e-5 * (1.0 + p.abs().max_element() / c.radius);
            assert!(n.abs_diff_eq(want, tol), "{n} vs {want}");
            assert!(
                (p.cmpge(bounds.min - 1e-5).all() && p.cmple(bounds.max + 1e-5).all()),
                "{p} outside {bounds:?}"
            );
            let back = prim.sample_area_inverse(p);
            assert!(
                (back - u).abs().max_element() < 1e-4 || (back.y - u.y).abs() > 0.999,
                "{u} -> {back}"
            );
            heights.push((z / c.length) as f64);
            let uv = c.uv(p);
            angles.push(uv.x as f64);
        }
        fam.ks(&format!("height of {c:?}"), &mut heights, |x| {
            x.clamp(0.0, 1.0)
        });
        fam.ks(&format!("angle of {c:?}"), &mut angles, |x| {
            x.clamp(0.0, 1.0)
        });
    }
    fam.finish();
}

/// The quads among `prims`, in order.
fn quads_of(prims: &[Primitive]) -> Vec<Quad> {
    prims
        .iter()
        .filter_map(|p| match p {
            Primitive::Quad(q) => Some(*q),
            _ => None,
        })
        .collect()
}
