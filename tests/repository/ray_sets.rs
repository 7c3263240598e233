//! The ray sets of the Embree comparison (`benches/embree/`, `examples/ray_sets/`): the files
//! read back as written, and pathspace's checksum of a set is the brute-force one over every
//! triangle, so the benchmark's two sides are compared on equal work. Book: "Measuring a
//! renderer: the tools".

#[path = "../../examples/ray_sets/format.rs"]
mod format;

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use format::{Checksum, Kind, RaySet};
use pathspace::geometry::{Bvh, Primitive, Ray};

use crate::common::cli::scratch;

fn point(r: &mut Pcg64Mcg) -> Vec3 {
    Vec3::new(
        r.random_range(-1.0..1.0),
        r.random_range(-1.0..1.0),
        r.random_range(-1.0..1.0),
    )
}

/// Small triangles scattered in [-1, 1]^3, none degenerate.
fn soup(r: &mut Pcg64Mcg, n: usize) -> Vec<[Vec3; 3]> {
    let mut tris = Vec::new();
    while tris.len() < n {
        let c = point(r);
        let t = [c, c + 0.3 * point(r), c + 0.3 * point(r)];
        if format::primitives(&[t]).is_ok() {
            tris.push(t);
        }
    }
    tris
}

/// Rays between random points: closest-hit ones unbounded or to the point, any-hit ones to it.
fn rays(r: &mut Pcg64Mcg, kind: Kind, n: usize) -> RaySet {
    let rays = (0..n)
        .map(|_| {
            let (o, to) = (point(r), point(r));
            let d = (to - o).normalize();
            let bounded = kind == Kind::Any || r.random::<bool>();
            let t_max = if bounded {
                (to - o).length()
            } else {
                f32::INFINITY
            };
            (Ray::new(o, d), t_max)
        })
        .collect();
    RaySet { kind, rays }
}

/// The checksum by testing every triangle for every ray, written apart from `format::trace`.
fn brute_force(prims: &[Primitive], set: &RaySet) -> Checksum {
    let mut sum = Checksum::default();
    for (ray, t_max) in &set.rays {
        let nearest = prims
            .iter()
            .filter_map(|p| p.intersect(ray, *t_max).map(|h| h.0))
            .min_by(f32::total_cmp);
        if let Some(t) = nearest {
            sum.hits += 1;
            sum.sum_t += if set.kind == Kind::Any { *t_max } else { t } as f64;
        }
    }
    sum
}

#[test]
fn files_read_back_as_written_and_refuse_a_short_file() {
    let dir = scratch("ray_sets", "round_trip");
    let mut r = Pcg64Mcg::seed_from_u64(3);
    let tris = soup(&mut r, 50);
    format::write_triangles(&dir.join("s.tri"), &tris).unwrap();
    assert_eq!(format::read_triangles(&dir.join("s.tri")).unwrap(), tris);
    for kind in [Kind::Closest, Kind::Any] {
        let set = rays(&mut r, kind, 100);
        let path = dir.join("s.rays");
        format::write_rays(&path, &set).unwrap();
        let back = format::read_rays(&path).unwrap();
        assert_eq!(back.kind, kind);
        let bits = |s: &RaySet| -> Vec<[u32; 7]> {
            let b = |v: Vec3| v.to_array().map(f32::to_bits);
            s.rays
                .iter()
                .map(|(ray, t)| {
                    let (o, d) = (b(ray.o), b(ray.d));
                    [o[0], o[1], o[2], d[0], d[1], d[2], t.to_bits()]
                })
                .collect()
        };
        assert_eq!(bits(&back), bits(&set));
        // a record cut short is an error naming the file, not a shorter set
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 4]).unwrap();
        let err = format::read_rays(&path).unwrap_err().to_string();
        assert!(err.contains("s.rays"), "{err}");
    }
}

#[test]
fn pathspace_checksum_is_brute_force_over_every_triangle() {
    let mut r = Pcg64Mcg::seed_from_u64(5);
    let prims = format::primitives(&soup(&mut r, 300)).unwrap();
    let opaque = vec![true; prims.len()];
    let bvh = Bvh::build(&prims);
    for kind in [Kind::Closest, Kind::Any] {
        let set = rays(&mut r, kind, 2000);
        let ours = format::trace(&bvh, &prims, &opaque, &set);
        // both hits and misses, or the sum would not tell a lost ray
        assert!(
            ours.hits > 100 && ours.hits < 1900,
            "{}: {ours:?}",
            kind.name()
        );
        // the same primitives' distances in the same order: equal to the bit
        assert_eq!(ours, brute_force(&prims, &set), "{}", kind.name());
    }
}
