//! The BVH's leaves as traversal reads them: each leaf a run of blocks stored in the order the
//! four-wide tree names them, a block holding up to four primitives of the leaf, all of one
//! kind. A block of triangles carries their corners axis by axis ("structure of arrays"), so
//! that one watertight test runs on four triangles in four-lane vector operations, and a leaf
//! is read without going from the tree to the binary node to the index list to the primitive
//! (three dependent loads, the largest share of a ray's time on a million triangles). A block
//! of quads names its lanes in the tree's quad lanes ([`QuadLanes`]: origins, edges, normals
//! axis by axis), tested four at a time the same way. Other primitives keep their index only
//! and are tested one by one.
//!
//! The lanes repeat the scalar tests arithmetic operation for operation
//! ([`Triangle::intersect_range`](super::shape::Triangle::intersect_range) with its f64
//! fallback where an edge function rounds to 0; the quad arm of
//! [`Primitive::intersect_range`] with glam's `Vec3::dot` and `Vec3::cross` and
//! [`Quad::coordinates`](super::shape::Quad::coordinates)): the same products, differences and
//! sums in the same order, no fused multiply-add. So a lane's t and coordinates are the scalar
//! test's bit for bit, and the leaf's primitives are offered to the tie-break in the leaf's
//! order: closest hits are what the scalar leaf loop found. Book: "Scenes and geometry".

use glam::{Vec3, Vec4};

use super::shape::{edge_f64, RayShear};
use super::{Primitive, Ray};

/// Primitives per block.
pub const LANES: usize = 4;

/// What a block's lanes hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Triangles, their corners in the block ([`Block::hits`]).
    Triangles,
    /// Quads, their lanes in the tree's [`QuadLanes`] ([`QuadLanes::hits`]).
    Quads,
    /// Other primitives, tested one by one by index.
    Others,
}

impl Kind {
    fn of(prim: &Primitive) -> Kind {
        match prim {
            Primitive::Triangle(_) => Kind::Triangles,
            Primitive::Quad(_) => Kind::Quads,
            _ => Kind::Others,
        }
    }
}

/// Up to [`LANES`] primitives of one leaf, all of one [`Kind`].
#[derive(Clone, Copy, Debug)]
pub struct Block {
    /// `corners[c][axis]`: corner `c` (p0, p1, p2) of the lanes' triangles along `axis`;
    /// unused lanes repeat lane 0, blocks of other primitives leave it zero.
    corners: [[Vec4; 3]; 3],
    /// The primitives' indices in the scene, in the leaf's order; unused lanes repeat lane 0,
    /// so that a query may read every lane's flags without asking which are used.
    pub ids: [u32; LANES],
    /// A block of quads: the index of its [`QuadLanes`]; others 0.
    pub quads: u32,
    /// Lanes used, 1 to [`LANES`].
    pub lanes: u8,
    pub kind: Kind,
    /// Whether this block ends its leaf.
    pub last: bool,
}

/// Appends leaf `ids` (in their order) to `blocks` as consecutive blocks, consecutive
/// triangles sharing blocks of four, and so consecutive quads (their lanes appended to
/// `quads`); returns the index of the first block.
pub fn lay_out(
    ids: &[u32],
    prims: &[Primitive],
    blocks: &mut Vec<Block>,
    quads: &mut Vec<QuadLanes>,
) -> u32 {
    let first = blocks.len();
    let kind = |i: u32| Kind::of(&prims[i as usize]);
    let mut rest = ids;
    while let Some(&head) = rest.first() {
        let run = rest
            .iter()
            .take(LANES)
            .take_while(|&&i| kind(i) == kind(head))
            .count();
        let mut block = Block {
            corners: [[Vec4::ZERO; 3]; 3],
            ids: [head; LANES],
            quads: 0,
            lanes: run as u8,
            kind: kind(head),
            last: false,
        };
        block.ids[..run].copy_from_slice(&rest[..run]);
        match block.kind {
            Kind::Triangles => block.corners = triangle_corners(&block.ids, prims),
            Kind::Quads => {
                block.quads = quads.len() as u32;
                quads.push(QuadLanes::new(&block.ids, prims));
            }
            Kind::Others => {}
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

/// The corners of triangles `ids` axis by axis, `[corner][axis][lane]`.
fn triangle_corners(ids: &[u32; LANES], prims: &[Primitive]) -> [[Vec4; 3]; 3] {
    let mut corners = [[Vec4::ZERO; 3]; 3];
    for (k, &i) in ids.iter().enumerate() {
        let Primitive::Triangle(t) = &prims[i as usize] else {
            unreachable!("a triangle block holds triangles only")
        };
        for (c, p) in [t.p0, t.p1, t.p2].into_iter().enumerate() {
            for axis in 0..3 {
                corners[c][axis][k] = p[axis];
            }
        }
    }
    corners
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
    /// Always inlined: out of line, its four-lane results went through memory, and the fog
    /// box's triangle rays were 3 to 15% slower (book: "Against Embree, ray for ray").
    #[inline(always)]
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

/// Four lanes of 3-D vectors, axis by axis.
type V = [Vec4; 3];

/// `p - q` lane by lane, as glam's `Vec3` subtraction.
#[inline(always)]
fn sub(p: &V, q: &V) -> V {
    [p[0] - q[0], p[1] - q[1], p[2] - q[2]]
}

/// glam's `Vec3::dot` lane by lane: `(x x' + y y') + z z'`.
#[inline(always)]
fn dot(p: &V, q: &V) -> Vec4 {
    p[0] * q[0] + p[1] * q[1] + p[2] * q[2]
}

/// glam's `Vec3::cross` lane by lane.
#[inline(always)]
fn cross(p: &V, q: &V) -> V {
    [
        p[1] * q[2] - q[1] * p[2],
        p[2] * q[0] - q[2] * p[0],
        p[0] * q[1] - q[0] * p[1],
    ]
}

/// Up to four quads axis by axis: origins, edges `u` and `v`, unit normals `n` and the
/// vectors `w` of [`Quad::coordinates`](super::shape::Quad::coordinates); unused lanes repeat
/// lane 0. Kept apart from the blocks (which a triangle block fills with its corners) so that
/// blocks stay 176 bytes.
#[derive(Clone, Copy, Debug)]
pub struct QuadLanes {
    origin: V,
    u: V,
    v: V,
    n: V,
    w: V,
}

impl QuadLanes {
    fn new(ids: &[u32; LANES], prims: &[Primitive]) -> Self {
        let mut lanes = [[Vec4::ZERO; 3]; 5];
        for (k, &i) in ids.iter().enumerate() {
            let Primitive::Quad(q) = &prims[i as usize] else {
                unreachable!("a quad block holds quads only")
            };
            for (f, x) in [q.origin, q.u, q.v, q.n, q.w].into_iter().enumerate() {
                for axis in 0..3 {
                    lanes[f][axis][k] = x[axis];
                }
            }
        }
        let [origin, u, v, n, w] = lanes;
        QuadLanes { origin, u, v, n, w }
    }

    /// The quad test of [`Primitive::intersect_range`] on the first `lanes` lanes: a bit mask
    /// of the lanes hit at t in (t_min, t_max), and each lane's t and coordinates (a, b). The
    /// scalar test's `denom == 0` needs no lane of its own: x / 0 is an infinity or NaN, never
    /// inside (t_min, t_max).
    #[inline(always)]
    pub fn hits(
        &self,
        ray: &QuadRay,
        lanes: u8,
        t_min: f32,
        t_max: f32,
    ) -> (u32, Vec4, Vec4, Vec4) {
        let z = Vec4::ZERO;
        let denom = dot(&self.n, &ray.d);
        let t = dot(&self.n, &sub(&self.origin, &ray.o)) / denom;
        let used = (1u32 << lanes) - 1;
        let front = (t.cmpgt(Vec4::splat(t_min)) & t.cmplt(Vec4::splat(t_max))).bitmask() & used;
        if front == 0 {
            // all behind the ray or past the best hit: no coordinates needed
            return (0, t, z, z);
        }
        let p = [0, 1, 2].map(|i| ray.o[i] + ray.d[i] * t);
        let rel = sub(&p, &self.origin);
        let a = dot(&self.w, &cross(&rel, &self.v));
        let b = dot(&self.w, &cross(&self.u, &rel));
        let inside = a.cmpge(z) & a.cmple(Vec4::ONE) & b.cmpge(z) & b.cmple(Vec4::ONE);
        (inside.bitmask() & front, t, a, b)
    }
}

/// A ray as the lanes of a quad block read it: origin and direction splatted.
pub struct QuadRay {
    o: V,
    d: V,
}

impl QuadRay {
    #[inline]
    pub fn new(ray: &Ray) -> Self {
        QuadRay {
            o: [0, 1, 2].map(|i| Vec4::splat(ray.o[i])),
            d: [0, 1, 2].map(|i| Vec4::splat(ray.d[i])),
        }
    }
}

/// The rays a query's blocks read, each set up only where the tree has blocks of its kind.
pub struct LaneRays {
    pub triangles: Option<TriangleRay>,
    pub quads: Option<QuadRay>,
}

impl LaneRays {
    #[inline]
    pub fn new(ray: &Ray, triangles: bool, quads: bool) -> Self {
        LaneRays {
            triangles: triangles.then(|| TriangleRay::new(ray)),
            quads: quads.then(|| QuadRay::new(ray)),
        }
    }
}

/// The lane test of `block` ([`Block::hits`], [`QuadLanes::hits`]) as (mask, t, coordinates),
/// the mask of the lanes hit at t > t_min; t < t_max is left to the caller (a quad block uses
/// it to skip its coordinates when no lane is in range). `None` for a block of other
/// primitives.
#[inline(always)]
pub fn hits(
    block: &Block,
    quads: &[QuadLanes],
    rays: &LaneRays,
    t_min: f32,
    t_max: f32,
) -> Option<(u32, Vec4, Vec4, Vec4)> {
    match (block.kind, &rays.triangles, &rays.quads) {
        (Kind::Triangles, Some(ray), _) => Some(block.hits(ray, t_min)),
        (Kind::Quads, _, Some(ray)) => {
            let lanes = &quads[block.quads as usize];
            Some(lanes.hits(ray, block.lanes, t_min, t_max))
        }
        _ => None,
    }
}

/// The hit point and normal of primitive `prim` of a lane at its coordinates (a triangle's
/// barycentrics, a quad's (a, b)), as [`Primitive::intersect_range`] computes them.
#[inline]
pub fn lane_point(prim: &Primitive, x: f32, y: f32) -> (Vec3, Vec3) {
    match prim {
        Primitive::Triangle(t) => (t.point(x, y), t.n),
        // reprojection onto the plane, as the scalar test
        Primitive::Quad(q) => (q.point(x, y), q.n),
        _ => unreachable!("lanes hold triangles and quads only"),
    }
}
