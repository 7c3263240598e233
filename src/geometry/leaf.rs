//! The BVH's leaves as traversal reads them: each leaf a run of blocks stored in the order the
//! four-wide tree names them, a block holding up to four primitives of the leaf. A block of
//! triangles carries their corners axis by axis ("structure of arrays"), so that one watertight
//! test runs on four triangles in four-lane vector operations, and a leaf is read without
//! going from the tree to the binary node to the index list to the primitive (three dependent
//! loads, the largest share of a ray's time on a million triangles). Other primitives keep
//! their index only and are tested as before.
//!
//! The lanes repeat [`Triangle::intersect_range`](super::shape::Triangle::intersect_range)'s arithmetic operation for operation (the
//! same products, differences and sums in the same order, no fused multiply-add, its f64
//! fallback where an edge function rounds to 0), so a lane's t and barycentrics are the scalar
//! test's bit for bit, and the leaf's primitives are offered to the tie-break in the leaf's
//! order: closest hits are what the scalar leaf loop found. Book: "Scenes and geometry".

use glam::{Vec3, Vec4};

use super::shape::{edge_f64, RayShear};
use super::{Primitive, Ray};

/// Primitives per block.
pub const LANES: usize = 4;

/// Up to [`LANES`] primitives of one leaf, all triangles or all others.
#[derive(Clone, Copy, Debug)]
pub struct Block {
    /// `corners[c][axis]`: corner `c` (p0, p1, p2) of the lanes' triangles along `axis`;
    /// unused lanes repeat lane 0, blocks of other primitives leave it zero.
    corners: [[Vec4; 3]; 3],
    /// The primitives' indices in the scene, in the leaf's order.
    pub ids: [u32; LANES],
    /// Lanes used, 1 to [`LANES`].
    pub lanes: u8,
    /// Whether the lanes hold triangles (tested here) or other primitives (by index).
    pub triangles: bool,
    /// Whether this block ends its leaf.
    pub last: bool,
}

/// Appends leaf `ids` (in their order) to `blocks` as consecutive blocks, consecutive
/// triangles sharing blocks of four; returns the index of the first.
pub fn lay_out(ids: &[u32], prims: &[Primitive], blocks: &mut Vec<Block>) -> u32 {
    let first = blocks.len();
    let triangle = |i: u32| match &prims[i as usize] {
        Primitive::Triangle(t) => Some(t),
        _ => None,
    };
    let mut rest = ids;
    while let Some(&head) = rest.first() {
        let kind = triangle(head).is_some();
        let run = rest
            .iter()
            .take(LANES)
            .take_while(|&&i| triangle(i).is_some() == kind)
            .count();
        let mut block = Block {
            corners: [[Vec4::ZERO; 3]; 3],
            ids: [head; LANES],
            lanes: run as u8,
            triangles: kind,
            last: false,
        };
        block.ids[..run].copy_from_slice(&rest[..run]);
        if kind {
            for (k, &i) in block.ids.iter().enumerate() {
                let t = triangle(i).expect("a triangle");
                for (c, p) in [t.p0, t.p1, t.p2].into_iter().enumerate() {
                    for axis in 0..3 {
                        block.corners[c][axis][k] = p[axis];
                    }
                }
            }
        }
        blocks.push(block);
        rest = &rest[run..];
    }
    let end = blocks.len();
    if let Some(b) = blocks[first..end].last_mut() {
        b.last = true;
    }
    first as u32
}

/// A ray as the lanes of a triangle block read it: its shear ([`RayShear`], set up once per
/// ray instead of once per triangle) and its origin, splatted in the frame's axis order.
pub struct TriangleRay {
    axes: [usize; 3],
    o: [Vec4; 3],
    sx: Vec4,
    sy: Vec4,
    sz: Vec4,
}

impl TriangleRay {
    #[inline]
    pub fn new(ray: &Ray) -> Self {
        let s = RayShear::new(ray);
        // the cyclic order that ends with kz (`shape::cyclic`)
        let axes = [(s.kz + 1) % 3, (s.kz + 2) % 3, s.kz];
        TriangleRay {
            axes,
            o: axes.map(|a| Vec4::splat(ray.o[a])),
            sx: Vec4::splat(s.sx),
            sy: Vec4::splat(s.sy),
            sz: Vec4::splat(s.sz),
        }
    }
}

/// Four lanes of 3-D points: x, y, z.
type Lanes3 = (Vec4, Vec4, Vec4);

impl Block {
    /// The watertight test of the block's triangles: a bit mask of the lanes hit at t > t_min,
    /// and each lane's t, b1 and b2 (as [`Triangle::intersect_range`](super::shape::Triangle::intersect_range) returns them).
    #[inline]
    pub fn hits(&self, ray: &TriangleRay, t_min: f32) -> (u32, Vec4, Vec4, Vec4) {
        let corner = |c: usize| -> Lanes3 {
            let p = &self.corners[c];
            let [x, y, z] = [0, 1, 2].map(|i| p[ray.axes[i]] - ray.o[i]);
            (x - ray.sx * z, y - ray.sy * z, z)
        };
        let (a, b, c) = (corner(0), corner(1), corner(2));
        let edge = |p: Lanes3, q: Lanes3| p.0 * q.1 - p.1 * q.0;
        let (mut u, mut v, mut w) = (edge(c, b), edge(a, c), edge(b, a));
        let used = (1u32 << self.lanes) - 1;
        let zero = (u.cmpeq(Vec4::ZERO) | v.cmpeq(Vec4::ZERO) | w.cmpeq(Vec4::ZERO)).bitmask();
        if zero & used != 0 {
            exact_edges(zero & used, [a, b, c], [&mut u, &mut v, &mut w]);
        }
        let z = Vec4::ZERO;
        let neg = u.cmplt(z) | v.cmplt(z) | w.cmplt(z);
        let pos = u.cmpgt(z) | v.cmpgt(z) | w.cmpgt(z);
        let det = u + v + w;
        let inv = Vec4::ONE / det;
        let t = (u * a.2 + v * b.2 + w * c.2) * ray.sz * inv;
        let inside = !(neg & pos).bitmask() & !det.cmpeq(z).bitmask();
        let mask = inside & t.cmpgt(Vec4::splat(t_min)).bitmask() & used;
        (mask, t, v * inv, w * inv)
    }
}

/// The edge functions of `lanes` recomputed in f64 ([`edge_f64`]), all three where one
/// rounded to 0, as the scalar test does.
#[cold]
fn exact_edges(lanes: u32, [a, b, c]: [Lanes3; 3], [u, v, w]: [&mut Vec4; 3]) {
    let point = |p: Lanes3, k: usize| Vec3::new(p.0[k], p.1[k], p.2[k]);
    for k in (0..LANES).filter(|k| lanes & (1 << k) != 0) {
        let (ak, bk, ck) = (point(a, k), point(b, k), point(c, k));
        u[k] = edge_f64(ck, bk);
        v[k] = edge_f64(ak, ck);
        w[k] = edge_f64(bk, ak);
    }
}

/// The hit point and normal of triangle `prim` at barycentrics (b1, b2), as
/// [`Primitive::intersect_range`] computes them.
#[inline]
pub fn triangle_point(prim: &Primitive, b1: f32, b2: f32) -> (Vec3, Vec3) {
    match prim {
        Primitive::Triangle(t) => (t.point(b1, b2), t.n),
        _ => unreachable!("a triangle block holds triangles only"),
    }
}
