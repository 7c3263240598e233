//! BVH ray throughput: closest-hit and any-hit rays per second on one core, median of several
//! runs, on the fog box (12 primitives, rays from inside the box) and on a soup of 100k random
//! triangles (rays from inside the soup). A small harness instead of criterion: a dependency
//! fewer, and the median of a handful of runs is what a reader needs to compare two builds.
//!
//! Last, the triangle test alone against Moller-Trumbore (the test it replaced), alternating the
//! two run by run so that both see the same load, and the median of the per-run ratios.
//!
//! Run: `cargo bench --bench bvh`. Book: "Scenes and geometry".

use std::hint::black_box;
use std::time::Instant;

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use pathspace::geometry::shape::Triangle;
use pathspace::geometry::{Bvh, Primitive, Ray};
use pathspace::scene::{Scene, SceneSource};

/// Timed runs per measurement; the median is reported.
const RUNS: usize = 7;

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

/// Rays from random points inside [-half, half]^3 in random directions, with the distance to
/// a second random point as the any-hit range (a shadow ray's).
fn rays(r: &mut Pcg64Mcg, n: usize, half: f32) -> Vec<(Ray, f32)> {
    (0..n)
        .map(|_| {
            let o = point(r, half);
            if r.random::<bool>() {
                let to = point(r, half) - o;
                (Ray::new(o, to.normalize()), to.length())
            } else {
                (Ray::new(o, unit(r)), f32::INFINITY)
            }
        })
        .collect()
}

/// Median rays per second of `RUNS` passes over `rays`; `f` returns a count to keep the work.
fn measure(rays: &[(Ray, f32)], f: impl Fn(&Ray, f32) -> bool) -> (f64, f64) {
    let mut rates: Vec<f64> = (0..RUNS)
        .map(|_| {
            let start = Instant::now();
            let mut hits = 0usize;
            for (ray, t) in rays {
                hits += f(black_box(ray), *t) as usize;
            }
            black_box(hits);
            rays.len() as f64 / start.elapsed().as_secs_f64()
        })
        .collect();
    rates.sort_by(f64::total_cmp);
    let hit_fraction = rays.iter().filter(|(ray, t)| f(ray, *t)).count() as f64 / rays.len() as f64;
    (rates[RUNS / 2], hit_fraction)
}

fn report(name: &str, prims: &[Primitive], opaque: &[bool], bvh: &Bvh, rays: &[(Ray, f32)]) {
    let (closest, hit_c) = measure(rays, |ray, _| {
        bvh.intersect(prims, opaque, ray, f32::INFINITY).is_some()
    });
    let (any, hit_a) = measure(rays, |ray, t| bvh.occluded(prims, opaque, ray, t));
    println!(
        "{name:<28} {:>7} prims {:>7} nodes depth {:>2} | closest hit {:>7.2} Mrays/s ({:>3.0}% hit) | any hit {:>7.2} Mrays/s ({:>3.0}% blocked)",
        prims.len(),
        bvh.node_count(),
        bvh.depth(),
        closest * 1e-6,
        100.0 * hit_c,
        any * 1e-6,
        100.0 * hit_a
    );
}

fn main() {
    let mut r = Pcg64Mcg::seed_from_u64(7);
    println!("BVH throughput, one thread, median of {RUNS} runs (rays per second per core)");

    let scene = Scene::fog_box();
    let fog_rays = rays(&mut r, 1_000_000, 0.99);
    report(
        "fog box (rays inside)",
        &scene.prims,
        &scene.prim_opaque,
        &scene.bvh,
        &fog_rays,
    );

    // Pauly et al.'s Fig. 8 with 100 rooms: walls with doorways, furniture, 100 lights;
    // rays from anywhere in the 40 x 3 x 40 block of rooms
    let source = SceneSource::embedded("rooms", &pathspace::cli::rooms::rooms_scene(10));
    let rooms = Scene::load(&source).expect("the 100-room scene loads");
    let b = rooms.bvh.bounds();
    let room_rays: Vec<(Ray, f32)> = rays(&mut r, 1_000_000, 1.0)
        .into_iter()
        .map(|(ray, t)| {
            let o = b.min + (ray.o * 0.5 + 0.5) * (b.max - b.min) * 0.999;
            let t = if t.is_finite() {
                t * (b.max - b.min).length()
            } else {
                t
            };
            (Ray::new(o, ray.d), t)
        })
        .collect();
    report(
        "100 rooms (rays inside)",
        &rooms.prims,
        &rooms.prim_opaque,
        &rooms.bvh,
        &room_rays,
    );

    let n = 100_000;
    let prims: Vec<Primitive> = std::iter::repeat_with(|| {
        let c = point(&mut r, 1.0);
        Triangle::new(c, c + 0.02 * unit(&mut r), c + 0.02 * unit(&mut r)).map(Primitive::Triangle)
    })
    .flatten()
    .take(n)
    .collect();
    let opaque = vec![true; prims.len()];
    let start = Instant::now();
    let bvh = Bvh::build(&prims);
    let build = start.elapsed().as_secs_f64();
    let soup_rays = rays(&mut r, 200_000, 1.0);
    report("100k triangle soup", &prims, &opaque, &bvh, &soup_rays);
    println!("(100k-triangle BVH built in {:.0} ms)", build * 1e3);
    triangle_test(&mut r);
}

/// Moller-Trumbore (1997), the triangle test before the watertight one, for the ratio below.
fn moller_trumbore(tri: &Triangle, ray: &Ray, t_max: f32) -> Option<(f32, Vec3, Vec3)> {
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
    if !(t > 0.0 && t < t_max) {
        return None;
    }
    Some((t, tri.p0 + b1 * e1 + b2 * e2, tri.n))
}

/// Ray-triangle tests per second, the watertight test (`Primitive::intersect`) and
/// Moller-Trumbore on the same pairs (a ray aimed near its triangle: about half hit).
fn triangle_test(r: &mut Pcg64Mcg) {
    let pairs: Vec<(Ray, Triangle)> = std::iter::repeat_with(|| {
        let c = point(r, 1.0);
        let tri = Triangle::new(c, c + 0.3 * unit(r), c + 0.3 * unit(r))?;
        let o = point(r, 2.0);
        let target = c + 0.1 * (unit(r) + unit(r));
        Some((Ray::new(o, (target - o).normalize()), tri))
    })
    .flatten()
    .take(1_000_000)
    .collect();
    let time = |f: &dyn Fn(&Ray, &Triangle) -> bool| {
        let start = Instant::now();
        let hits = pairs
            .iter()
            .filter(|(ray, tri)| f(black_box(ray), black_box(tri)))
            .count();
        black_box(hits);
        pairs.len() as f64 / start.elapsed().as_secs_f64()
    };
    let watertight = |ray: &Ray, tri: &Triangle| {
        Primitive::Triangle(*tri)
            .intersect(ray, f32::INFINITY)
            .is_some()
    };
    let reference = |ray: &Ray, tri: &Triangle| moller_trumbore(tri, ray, f32::INFINITY).is_some();
    let mut runs: Vec<(f64, f64)> = (0..RUNS)
        .map(|_| (time(&watertight), time(&reference)))
        .collect();
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let ratio = median(&mut runs.iter().map(|(w, m)| w / m).collect());
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let w = runs[RUNS / 2].0;
    runs.sort_by(|a, b| a.1.total_cmp(&b.1));
    let m = runs[RUNS / 2].1;
    println!(
        "triangle test alone: watertight {:.1} M tests/s, Moller-Trumbore {:.1} M tests/s, \
         ratio {ratio:.2} (median of per-run ratios)",
        w * 1e-6,
        m * 1e-6
    );
}
