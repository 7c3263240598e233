//! The traversal layout of the BVH: the binary tree of the SAH build collapsed into nodes of up
//! to four children, whose boxes are stored axis by axis ("structure of arrays") so that one
//! node's four slab tests run as four-lane vector operations. A binary tree of depth d becomes a
//! tree of about d / 2 levels; a ray loads half as many nodes and tests their children together.
//!
//! The box test is the binary tree's ([`Aabb::intersect`]), lane by lane, with the same
//! arithmetic and the same rule for a ray lying in a slab's plane (0 * inf = NaN at that slab
//! end: the ray is on the closed box's face, so that axis does not constrain it), so a child is
//! entered exactly when the binary traversal would test it, and closest hits stay bit for bit
//! the same. The rule costs selects; a ray whose inverse direction is finite cannot produce a
//! NaN, so it takes the same test without them ([`RayLanes`]).
//!
//! Where the processor has AVX2 the tree is collapsed into nodes of eight children instead
//! ([`Node8`]), tested as eight-lane operations, with the same arithmetic lane for lane: a
//! child's box passes or fails as it would in a four-wide node, so queries return the same hits.
//! Book: "Scenes and geometry".

use glam::{Vec3, Vec4};

use super::Aabb;

/// Children per node of the four-wide tree.
pub const WIDTH: usize = 4;
/// Children per node of the eight-wide tree.
pub const WIDTH8: usize = 8;

/// A node of a wide tree as [`collapse`] writes it and traversal reads it.
pub trait Wide: Copy {
    /// Children per node.
    const WIDTH: usize;
    /// The children's entry distances, child k's in lane k.
    type Near: std::ops::Index<usize, Output = f32>;
    fn empty() -> Self;
    fn set(&mut self, k: usize, b: Aabb, slot: Slot);
    /// Whether slot `k` holds a child.
    fn has(&self, k: usize) -> bool;
    fn slot(&self, k: usize) -> Slot;
    fn set_slot(&mut self, k: usize, slot: Slot);
    /// The box of child `k` (statistics only).
    fn child_bounds(&self, k: usize) -> Aabb;
}

/// A child: an interior node of the four-wide tree or a leaf, which [`collapse`] names by its
/// node in the binary tree (that node holds its run of primitive indices) and the BVH then by
/// its first block (`geometry::leaf`). One `u32`, the low bit
/// telling which, so that traversal stacks stay small (a stack is set up for every ray).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slot(pub u32);

/// What a [`Slot`] holds.
pub enum Child {
    /// A node of the four-wide tree.
    Node(usize),
    /// A leaf: its binary node, or its first block once the BVH has laid the leaves out.
    Leaf(usize),
}

impl Slot {
    fn node(index: u32) -> Self {
        Slot(index << 1)
    }

    pub fn leaf(index: usize) -> Self {
        Slot(((index as u32) << 1) | 1)
    }

    #[inline]
    pub fn child(self) -> Child {
        let i = (self.0 >> 1) as usize;
        if self.0 & 1 == 0 {
            Child::Node(i)
        } else {
            Child::Leaf(i)
        }
    }
}

/// Four children's boxes, axis by axis, and what each child is.
#[derive(Clone, Copy, Debug)]
pub struct Node4 {
    /// `min[axis]` holds the four children's lower bounds on that axis, `max[axis]` the upper.
    min: [Vec4; 3],
    max: [Vec4; 3],
    slots: [Slot; WIDTH],
    /// Bit k set when slot k holds a child.
    used: u32,
}

/// A node of the binary tree as the collapse sees it.
pub trait Binary {
    fn bounds(&self, node: usize) -> Aabb;
    /// `Some((left, right))` for an interior node, `None` for a leaf.
    fn children(&self, node: usize) -> Option<(usize, usize)>;
}

/// Collapses the binary tree under `root` into wide nodes (the root is node 0): a node takes
/// its binary children and keeps opening the interior one of largest surface area until it
/// has `N::WIDTH` children or only leaves.
pub fn collapse<N: Wide>(tree: &impl Binary, root: usize) -> Vec<N> {
    let mut nodes = Vec::new();
    match tree.children(root) {
        None => {
            // a single leaf: one node with one child
            let mut node = N::empty();
            node.set(0, tree.bounds(root), Slot::leaf(root));
            nodes.push(node);
        }
        Some(_) => {
            build(tree, root, &mut nodes);
        }
    }
    nodes
}

/// Writes the wide node for interior binary node `at` and, depth first, its subtrees;
/// returns its index.
fn build<N: Wide>(tree: &impl Binary, at: usize, nodes: &mut Vec<N>) -> u32 {
    let (l, r) = tree.children(at).expect("an interior node");
    let mut kids = vec![l, r];
    while kids.len() < N::WIDTH {
        let widest = kids
            .iter()
            .enumerate()
            .filter(|(_, &k)| tree.children(k).is_some())
            .max_by(|a, b| {
                let area = |k: usize| tree.bounds(k).surface_area();
                area(*a.1).total_cmp(&area(*b.1))
            })
            .map(|(i, _)| i);
        let Some(i) = widest else { break };
        let (cl, cr) = tree.children(kids[i]).expect("an interior node");
        kids[i] = cl;
        kids.insert(i + 1, cr);
    }
    let index = nodes.len();
    nodes.push(N::empty());
    for (k, &kid) in kids.iter().enumerate() {
        let slot = match tree.children(kid) {
            Some(_) => Slot::node(build(tree, kid, nodes)),
            None => Slot::leaf(kid),
        };
        nodes[index].set(k, tree.bounds(kid), slot);
    }
    index as u32
}

impl Wide for Node4 {
    const WIDTH: usize = WIDTH;
    type Near = Vec4;

    fn empty() -> Self {
        Node4 {
            min: [Vec4::INFINITY; 3],
            max: [Vec4::NEG_INFINITY; 3],
            slots: [Slot(0); WIDTH],
            used: 0,
        }
    }

    fn set(&mut self, k: usize, b: Aabb, slot: Slot) {
        for axis in 0..3 {
            self.min[axis][k] = b.min[axis];
            self.max[axis][k] = b.max[axis];
        }
        self.slots[k] = slot;
        self.used |= 1 << k;
    }

    #[inline]
    fn has(&self, k: usize) -> bool {
        self.used & (1 << k) != 0
    }

    #[inline]
    fn slot(&self, k: usize) -> Slot {
        self.slots[k]
    }

    fn set_slot(&mut self, k: usize, slot: Slot) {
        self.slots[k] = slot;
    }

    fn child_bounds(&self, k: usize) -> Aabb {
        let lane = |v: [f32; 3]| Vec3::from_array(v);
        Aabb {
            min: lane([0, 1, 2].map(|a| self.min[a][k])),
            max: lane([0, 1, 2].map(|a| self.max[a][k])),
        }
    }
}

impl Node4 {
    /// The slab test of the four children: a bit mask of the children the ray enters before
    /// `limit`, and their entry distances. Lane for lane the arithmetic of [`Aabb::intersect`],
    /// a ray lying in a slab's plane included ([`slab_on_face`]).
    #[inline]
    pub fn intersect(&self, ray: &RayLanes, limit: f32) -> (u32, Vec4) {
        if ray.finite {
            self.slabs::<true>(ray, limit)
        } else {
            self.slabs::<false>(ray, limit)
        }
    }

    /// The slab test; `FINITE`: the inverse direction is finite, so no slab end is NaN.
    #[inline]
    fn slabs<const FINITE: bool>(&self, ray: &RayLanes, limit: f32) -> (u32, Vec4) {
        let mut near = Vec4::ZERO;
        let mut far = Vec4::splat(limit);
        for axis in 0..3 {
            let (origin, inv) = (ray.o[axis], ray.inv_d[axis]);
            let t0 = (self.min[axis] - origin) * inv;
            let t1 = (self.max[axis] - origin) * inv;
            let (lo, hi) = if FINITE {
                (t0.min(t1), t0.max(t1))
            } else {
                slab_on_face(t0, t1)
            };
            near = near.max(lo);
            far = far.min(hi);
        }
        let enters = near.cmple(far * 1.000_000_4).bitmask() & self.used;
        (enters, near)
    }
}

/// One axis's interval where a slab end may be NaN: 0 x inf, a ray along the slab's plane (a
/// zero direction component) with its origin on it. Such a ray lies on the closed box's face,
/// so that axis does not constrain it: (-inf, inf), as [`Aabb::intersect`] takes it.
#[inline]
fn slab_on_face(t0: Vec4, t1: Vec4) -> (Vec4, Vec4) {
    let on_face = t0.is_nan_mask() | t1.is_nan_mask();
    (
        Vec4::select(on_face, Vec4::NEG_INFINITY, t0.min(t1)),
        Vec4::select(on_face, Vec4::INFINITY, t0.max(t1)),
    )
}

/// A ray as the four-lane slab tests read it: its origin and inverse direction splatted once
/// per query instead of once per node. When every component of the inverse direction is finite
/// no slab end can be NaN (NaN needs 0 * inf, and a box's bound minus the origin is finite), so
/// the plain lane `min`/`max` give exactly what [`slab_on_face`] gives, with no selects:
/// nearly every ray takes that path; one with an exactly zero direction component does not.
pub struct RayLanes {
    o: [Vec4; 3],
    inv_d: [Vec4; 3],
    finite: bool,
}

impl RayLanes {
    #[inline]
    pub fn new(o: Vec3, inv_d: Vec3) -> Self {
        RayLanes {
            o: [0, 1, 2].map(|a| Vec4::splat(o[a])),
            inv_d: [0, 1, 2].map(|a| Vec4::splat(inv_d[a])),
            finite: inv_d.is_finite(),
        }
    }
}

/// Eight children's boxes, axis by axis, and what each child is: the node of the tree
/// traversal walks where the processor has AVX2 (`Bvh`). Aligned to 32 bytes, so that an
/// axis's eight bounds are one aligned vector load.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub struct Node8 {
    min: [[f32; WIDTH8]; 3],
    max: [[f32; WIDTH8]; 3],
    slots: [Slot; WIDTH8],
    /// Bit k set when slot k holds a child.
    used: u32,
}

/// A ray as [`Node8`]'s slab test reads it (the lanes' broadcasts are the compiler's).
pub struct RayLanes8 {
    o: [f32; 3],
    inv_d: [f32; 3],
    finite: bool,
}

impl Wide for Node8 {
    const WIDTH: usize = WIDTH8;
    type Near = [f32; WIDTH8];

    fn empty() -> Self {
        Node8 {
            min: [[f32::INFINITY; WIDTH8]; 3],
            max: [[f32::NEG_INFINITY; WIDTH8]; 3],
            slots: [Slot(0); WIDTH8],
            used: 0,
        }
    }

    fn set(&mut self, k: usize, b: Aabb, slot: Slot) {
        for axis in 0..3 {
            self.min[axis][k] = b.min[axis];
            self.max[axis][k] = b.max[axis];
        }
        self.slots[k] = slot;
        self.used |= 1 << k;
    }

    #[inline]
    fn has(&self, k: usize) -> bool {
        self.used & (1 << k) != 0
    }

    #[inline]
    fn slot(&self, k: usize) -> Slot {
        self.slots[k]
    }

    fn set_slot(&mut self, k: usize, slot: Slot) {
        self.slots[k] = slot;
    }

    fn child_bounds(&self, k: usize) -> Aabb {
        let lane = |v: [f32; 3]| Vec3::from_array(v);
        Aabb {
            min: lane([0, 1, 2].map(|a| self.min[a][k])),
            max: lane([0, 1, 2].map(|a| self.max[a][k])),
        }
    }
}

impl RayLanes8 {
    #[inline]
    pub fn new(o: Vec3, inv_d: Vec3) -> Self {
        RayLanes8 {
            o: o.to_array(),
            inv_d: inv_d.to_array(),
            finite: inv_d.is_finite(),
        }
    }
}

impl Node8 {
    /// [`Node4::intersect`] on eight children: the bit mask of those the ray enters before
    /// `limit`, and their entry distances. AVX2 (eight-lane) code, for the traversal that
    /// runs only where the processor has it (`Bvh`). Always inlined into that traversal, whose
    /// AVX2 it is then compiled with: as a function of its own (`#[target_feature]`) it was
    /// called once per node and returned its distances through memory, and the sphere's rays
    /// were 1 to 5% slower (book: "Against Embree, ray for ray").
    ///
    /// # Safety
    /// The processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(super) unsafe fn intersect_avx2(
        &self,
        ray: &RayLanes8,
        limit: f32,
    ) -> (u32, [f32; WIDTH8]) {
        use std::arch::x86_64::{_mm256_cmp_ps, _mm256_movemask_ps, _mm256_setr_ps, _CMP_LE_OQ};
        let (near, far) = if ray.finite {
            self.slabs::<true>(ray, limit)
        } else {
            self.slabs::<false>(ray, limit)
        };
        // the compare and its sign bits as one mask (`Vec4::cmple(..).bitmask()`'s eight-lane
        // form), which the compiler does not find in a loop over the lanes
        let v = |a: [f32; WIDTH8]| _mm256_setr_ps(a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7]);
        let enters = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(v(near), v(far))) as u32;
        (enters & self.used, near)
    }

    /// The slab test's entry distances and (slack included) exit distances on eight lanes,
    /// written lane by lane with the vector instructions' own rules ([`lane_min`],
    /// [`lane_max`]), so that it is [`Node4::intersect`]'s arithmetic whether the compiler
    /// keeps it scalar or makes it eight-lane.
    #[inline(always)]
    fn slabs<const FINITE: bool>(
        &self,
        ray: &RayLanes8,
        limit: f32,
    ) -> ([f32; WIDTH8], [f32; WIDTH8]) {
        let mut near = [0.0f32; WIDTH8];
        let mut far = [limit; WIDTH8];
        for axis in 0..3 {
            let (origin, inv) = (ray.o[axis], ray.inv_d[axis]);
            for k in 0..WIDTH8 {
                let t0 = (self.min[axis][k] - origin) * inv;
                let t1 = (self.max[axis][k] - origin) * inv;
                // a NaN end: the ray lies on the box's face, as in `slab_on_face`
                let (lo, hi) = if !FINITE && (t0.is_nan() || t1.is_nan()) {
                    (f32::NEG_INFINITY, f32::INFINITY)
                } else {
                    (lane_min(t0, t1), lane_max(t0, t1))
                };
                near[k] = lane_max(near[k], lo);
                far[k] = lane_min(far[k], hi);
            }
        }
        (near, far.map(|f| f * 1.000_000_4))
    }
}

/// One lane of the vector `min` (`minps`, which `Vec4::min` is): `b` unless `a < b`, so `b`
/// where either is NaN.
#[inline(always)]
fn lane_min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// One lane of the vector `max` (`maxps`): `b` unless `a > b`.
#[inline(always)]
fn lane_max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exact interval of the line o + t d inside the closed slab [lo, hi], from the real
    /// numbers' rules: a zero direction is inside everywhere or nowhere.
    fn exact_interval(lo: f32, hi: f32, o: f32, d: f32) -> Option<(f64, f64)> {
        let (lo, hi, o, d) = (lo as f64, hi as f64, o as f64, d as f64);
        if d == 0.0 {
            return (lo <= o && o <= hi).then_some((f64::NEG_INFINITY, f64::INFINITY));
        }
        let (a, b) = ((lo - o) / d, (hi - o) / d);
        Some((a.min(b), a.max(b)))
    }

    /// The slab test on the slab ends a ray meets where 0 x inf = NaN can occur: flat boxes,
    /// origins on their planes, direction components of +0 and -0 (inverse +-inf). Each lane
    /// of the four-wide test, and each of the eight-wide one, enters the box exactly when the
    /// line's exact interval on that axis is not empty; where it is (-inf, inf), the ray lies
    /// on the closed box's face and must not be refused.
    #[test]
    fn a_ray_along_a_boxs_face_enters_the_closed_box() {
        let coords = [-1.0f32, 0.0, 1.0];
        let dirs = [-1.0f32, -0.0, 0.0, 0.5];
        let (mut checked, mut on_face) = (0, 0);
        for (lo, hi, o, d) in slab_cases(&coords, &dirs) {
            let want = exact_interval(lo, hi, o, d);
            // the slab on the x axis, the others wide open around the origin
            let mut node4 = Node4::empty();
            let mut node8 = Node8::empty();
            let b = Aabb {
                min: Vec3::new(lo, -5.0, -5.0),
                max: Vec3::new(hi, 5.0, 5.0),
            };
            node4.set(0, b, Slot(0));
            node8.set(0, b, Slot(0));
            let inv_d = Vec3::new(d, 0.6, 0.8).recip();
            let o3 = Vec3::new(o, 0.0, 0.0);
            let (m4, _) = node4.intersect(&RayLanes::new(o3, inv_d), f32::INFINITY);
            let (n8, f8) = node8.slabs::<false>(&RayLanes8::new(o3, inv_d), f32::INFINITY);
            let enters = want.is_some_and(|(_, b)| b >= 0.0);
            assert_eq!(
                m4 & 1 == 1,
                enters,
                "four-wide: slab [{lo}, {hi}], o {o}, d {d}"
            );
            assert_eq!(
                n8[0] <= f8[0],
                enters,
                "eight-wide: slab [{lo}, {hi}], o {o}, d {d}"
            );
            let ray = crate::geometry::Ray {
                o: o3,
                d: inv_d.recip(),
            };
            assert_eq!(
                b.intersect(&ray, inv_d, f32::INFINITY).is_some(),
                enters,
                "Aabb"
            );
            on_face += usize::from(d == 0.0 && (o == lo || o == hi));
            checked += 1;
        }
        assert!(
            checked == 72 && on_face == 18,
            "{checked} cases, {on_face} on a face"
        );
    }

    /// The select-free slab test that rays with a finite inverse direction take gives the
    /// general test's mask and entry distances bit for bit, on boxes whose planes hold the
    /// origin (a slab end of exactly 0) and on direction components so small that the inverse
    /// overflows to infinity in the product; a zero component takes the general test.
    #[test]
    fn the_finite_ray_slab_test_is_the_general_one() {
        let c = [-2.0f32, -1.0, 0.0, 0.5, 1.0, 3.0];
        let d = [-1.0f32, -0.3, -1e-38, 1e-38, 0.2, 0.7, 1.0];
        let (mut checked, mut overflows) = (0, 0);
        for (i, &lo) in c.iter().enumerate() {
            let hi = c[(i + 2) % c.len()].max(lo);
            let node = Node4 {
                min: [
                    Vec4::new(lo, -1.0, lo, 0.0),
                    Vec4::new(-1.0, lo, 0.0, lo),
                    Vec4::splat(lo),
                ],
                max: [
                    Vec4::new(hi, 1.0, hi, 0.0),
                    Vec4::new(1.0, hi, 0.0, hi),
                    Vec4::splat(hi),
                ],
                slots: [Slot(0); WIDTH],
                used: 0b1111,
            };
            for &o in &c {
                for (&dx, &dy) in d.iter().zip(d.iter().rev()) {
                    let inv_d = Vec3::new(dx, dy, 0.4).recip();
                    let ray = RayLanes::new(Vec3::new(o, 0.0, o), inv_d);
                    assert!(ray.finite);
                    overflows += (dx.abs() < 1e-37) as usize;
                    for limit in [0.5, f32::INFINITY] {
                        let (m1, n1) = node.slabs::<true>(&ray, limit);
                        let (m0, n0) = node.slabs::<false>(&ray, limit);
                        assert_eq!(m1, m0, "{lo} {hi} {o} {dx} {dy}");
                        let bits = |v: Vec4| v.to_array().map(f32::to_bits);
                        assert_eq!(bits(n1), bits(n0), "{lo} {hi} {o} {dx} {dy}");
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 200 && overflows > 20);
        // an inverse of 1e38 times a slab end 5 away (box end 3, origin -2) overflows
        assert_eq!(
            (Vec4::splat(5.0) * Vec4::splat(1e-38f32.recip())).x,
            f32::INFINITY
        );
        assert!(!RayLanes::new(Vec3::ZERO, Vec3::new(0.0, 1.0, 1.0).recip()).finite);
    }

    /// Every (box low end, box high end, origin, direction) from the given values.
    fn slab_cases(c: &[f32], d: &[f32]) -> Vec<(f32, f32, f32, f32)> {
        let mut out = Vec::new();
        for &lo in c {
            for &hi in c.iter().filter(|&&h| h >= lo) {
                for &o in c {
                    for &dd in d {
                        out.push((lo, hi, o, dd));
                    }
                }
            }
        }
        out
    }
}
