//! The ray-set files of the Embree comparison (`benches/embree/`), read by both sides, and
//! pathspace's side of the trace with its checksum.
//!
//! All numbers little-endian; a file is its 8-byte magic, a header, then fixed-size records:
//!
//! | file | header | record |
//! |---|---|---|
//! | `SCENE.tri` | `PSTRI001`, u64 n | 9 f32: the corners p0, p1, p2 (never degenerate) |
//! | `SCENE.SET.rays` | `PSRAY001`, u32 kind (0 closest hit, 1 any hit), u32 0, u64 n | 8 f32: origin xyz, t_min (0), direction xyz (unit), t_max (may be +inf) |
//!
//! A closest-hit ray counts a hit at the nearest t in (t_min, t_max); an any-hit (shadow) ray
//! is blocked by any hit in that range. The checksum of a set is the number of hits and the sum
//! of the hit distances in f64 (for any-hit rays, the sum of the blocked rays' t_max).

use std::fs;
use std::io::{self, Write};
use std::path::Path;

use glam::Vec3;
use pathspace::geometry::shape::Triangle;
use pathspace::geometry::{Bvh, Primitive, Ray};

pub const TRI_MAGIC: &[u8; 8] = b"PSTRI001";
pub const RAY_MAGIC: &[u8; 8] = b"PSRAY001";
/// Bytes of one ray record.
pub const RAY_RECORD: usize = 32;
/// Bytes of one triangle record.
pub const TRI_RECORD: usize = 36;

/// Which query a ray set asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// The nearest hit before t_max (camera and bounce rays).
    Closest = 0,
    /// Whether anything lies before t_max (shadow rays).
    Any = 1,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Closest => "closest",
            Kind::Any => "any",
        }
    }
}

/// A ray set: its query and its rays with their t_max.
#[derive(Clone, Debug)]
pub struct RaySet {
    pub kind: Kind,
    pub rays: Vec<(Ray, f32)>,
}

/// Number of hits and sum of hit distances (t_max of the blocked rays for any-hit sets).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Checksum {
    pub hits: u64,
    pub sum_t: f64,
}

fn bad(path: &Path, what: &str) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!("{}: {what}", path.display()),
    )
}

fn f32s(bytes: &[u8]) -> impl Iterator<Item = f32> + '_ {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
}

fn put(out: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// The body of a file after its magic and header, checked to hold exactly `n` records.
fn body<'a>(
    path: &Path,
    bytes: &'a [u8],
    magic: &[u8; 8],
    header: usize,
    record: usize,
) -> io::Result<(&'a [u8], u64)> {
    if bytes.len() < header || &bytes[..8] != magic {
        return Err(bad(path, "not a ray-set file (magic)"));
    }
    let n = u64::from_le_bytes(bytes[header - 8..header].try_into().unwrap());
    let expected = (n as u128) * record as u128 + header as u128;
    if expected != bytes.len() as u128 {
        return Err(bad(path, &format!("{n} records do not fill the file")));
    }
    Ok((&bytes[header..], n))
}

pub fn write_triangles(path: &Path, tris: &[[Vec3; 3]]) -> io::Result<()> {
    let mut out = Vec::with_capacity(16 + tris.len() * TRI_RECORD);
    out.extend_from_slice(TRI_MAGIC);
    out.extend_from_slice(&(tris.len() as u64).to_le_bytes());
    for t in tris {
        for p in t {
            put(&mut out, &p.to_array());
        }
    }
    fs::File::create(path)?.write_all(&out)
}

pub fn read_triangles(path: &Path) -> io::Result<Vec<[Vec3; 3]>> {
    let bytes = fs::read(path)?;
    let (body, _) = body(path, &bytes, TRI_MAGIC, 16, TRI_RECORD)?;
    let v: Vec<f32> = f32s(body).collect();
    Ok(v.chunks_exact(9)
        .map(|c| {
            [
                Vec3::new(c[0], c[1], c[2]),
                Vec3::new(c[3], c[4], c[5]),
                Vec3::new(c[6], c[7], c[8]),
            ]
        })
        .collect())
}

pub fn write_rays(path: &Path, set: &RaySet) -> io::Result<()> {
    let mut out = Vec::with_capacity(24 + set.rays.len() * RAY_RECORD);
    out.extend_from_slice(RAY_MAGIC);
    out.extend_from_slice(&(set.kind as u32).to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(set.rays.len() as u64).to_le_bytes());
    for (ray, t_max) in &set.rays {
        let (o, d) = (ray.o, ray.d);
        put(&mut out, &[o.x, o.y, o.z, 0.0, d.x, d.y, d.z, *t_max]);
    }
    fs::File::create(path)?.write_all(&out)
}

pub fn read_rays(path: &Path) -> io::Result<RaySet> {
    let bytes = fs::read(path)?;
    let (body, _) = body(path, &bytes, RAY_MAGIC, 24, RAY_RECORD)?;
    let kind = match u32::from_le_bytes(bytes[8..12].try_into().unwrap()) {
        0 => Kind::Closest,
        1 => Kind::Any,
        k => return Err(bad(path, &format!("unknown ray kind {k}"))),
    };
    let v: Vec<f32> = f32s(body).collect();
    let rays = v
        .chunks_exact(8)
        .map(|c| {
            let ray = Ray::new(Vec3::new(c[0], c[1], c[2]), Vec3::new(c[4], c[5], c[6]));
            (ray, c[7])
        })
        .collect();
    Ok(RaySet { kind, rays })
}

/// The triangles as pathspace primitives, index for index; an error names a degenerate one
/// (it would drop out of pathspace's BVH but not Embree's, and the two would trace different
/// geometry).
pub fn primitives(tris: &[[Vec3; 3]]) -> Result<Vec<Primitive>, String> {
    tris.iter()
        .enumerate()
        .map(|(i, [a, b, c])| {
            Triangle::new(*a, *b, *c)
                .map(Primitive::Triangle)
                .ok_or_else(|| format!("triangle {i} is degenerate"))
        })
        .collect()
}

/// One ray of a set through pathspace's BVH: `Some(t)` for a hit (t_max for a blocked any-hit
/// ray).
#[inline]
pub fn trace_one(
    bvh: &Bvh,
    prims: &[Primitive],
    opaque: &[bool],
    kind: Kind,
    ray: &Ray,
    t_max: f32,
) -> Option<f32> {
    match kind {
        Kind::Closest => bvh.intersect(prims, opaque, ray, t_max).map(|h| h.t),
        Kind::Any => bvh.occluded(prims, opaque, ray, t_max).then_some(t_max),
    }
}

/// The checksum of a set traced through pathspace's BVH over `prims` (all opaque).
pub fn trace(bvh: &Bvh, prims: &[Primitive], opaque: &[bool], set: &RaySet) -> Checksum {
    let mut sum = Checksum::default();
    for (ray, t_max) in &set.rays {
        if let Some(t) = trace_one(bvh, prims, opaque, set.kind, ray, *t_max) {
            sum.hits += 1;
            sum.sum_t += t as f64;
        }
    }
    sum
}
