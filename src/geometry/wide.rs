//! The traversal layout of the BVH: the binary tree of the SAH build collapsed into nodes of up
//! to four children, whose boxes are stored axis by axis ("structure of arrays") so that one
//! node's four slab tests run as four-lane vector operations. A binary tree of depth d becomes a
//! tree of about d / 2 levels; a ray loads half as many nodes and tests their children together.
//!
//! The box test is the binary tree's, lane by lane, with the same arithmetic and the same
//! NaN-ignoring `min`/`max` (a ray parallel to a slab whose plane holds its origin gives 0 * inf:
//! that axis does not constrain the interval), so a child is entered exactly when the binary
//! traversal would test it, and closest hits stay bit for bit the same. The NaN rule costs a
//! select per `min`/`max`; a ray whose inverse direction is finite cannot produce a NaN, so it
//! takes the same test without them ([`RayLanes`]).
//! Book: "Scenes and geometry".

use glam::{Vec3, Vec4};

use super::Aabb;

/// Children per node.
pub const WIDTH: usize = 4;

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
    pub slots: [Slot; WIDTH],
    /// Bit k set when slot k holds a child.
    used: u32,
}

/// A node of the binary tree as the collapse sees it.
pub trait Binary {
    fn bounds(&self, node: usize) -> Aabb;
    /// `Some((left, right))` for an interior node, `None` for a leaf.
    fn children(&self, node: usize) -> Option<(usize, usize)>;
}

/// Collapses the binary tree under `root` into four-wide nodes (the root is node 0): a node
/// takes its binary children and keeps opening the interior one of largest surface area until
/// it has four children or only leaves.
pub fn collapse(tree: &impl Binary, root: usize) -> Vec<Node4> {
    let mut nodes = Vec::new();
    match tree.children(root) {
        None => {
            // a single leaf: one node with one child
            let mut node = empty_node();
            set(&mut node, 0, tree.bounds(root), Slot::leaf(root));
            nodes.push(node);
        }
        Some(_) => {
            build(tree, root, &mut nodes);
        }
    }
    nodes
}

fn empty_node() -> Node4 {
    Node4 {
        min: [Vec4::INFINITY; 3],
        max: [Vec4::NEG_INFINITY; 3],
        slots: [Slot(0); WIDTH],
        used: 0,
    }
}

fn set(node: &mut Node4, k: usize, b: Aabb, slot: Slot) {
    for axis in 0..3 {
        node.min[axis][k] = b.min[axis];
        node.max[axis][k] = b.max[axis];
    }
    node.slots[k] = slot;
    node.used |= 1 << k;
}

/// Writes the four-wide node for interior binary node `at` and, depth first, its subtrees;
/// returns its index.
fn build(tree: &impl Binary, at: usize, nodes: &mut Vec<Node4>) -> u32 {
    let (l, r) = tree.children(at).expect("an interior node");
    let mut kids = vec![l, r];
    while kids.len() < WIDTH {
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
    nodes.push(empty_node());
    for (k, &kid) in kids.iter().enumerate() {
        let slot = match tree.children(kid) {
            Some(_) => Slot::node(build(tree, kid, nodes)),
            None => Slot::leaf(kid),
        };
        set(&mut nodes[index], k, tree.bounds(kid), slot);
    }
    index as u32
}

impl Node4 {
    /// Whether slot `k` holds a child.
    #[inline]
    pub fn has(&self, k: usize) -> bool {
        self.used & (1 << k) != 0
    }

    /// The slab test of the four children: a bit mask of the children the ray enters before
    /// `limit`, and their entry distances. Lane for lane the arithmetic of [`Aabb::intersect`],
    /// except for a ray lying in a slab's plane (0 * inf = NaN at a slab end): glam's `Vec3`
    /// `min`/`max` there return their second operand, these lanes the other (non-NaN) one.
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
        let (min, max) = if FINITE {
            (
                Vec4::min as fn(Vec4, Vec4) -> Vec4,
                Vec4::max as fn(Vec4, Vec4) -> Vec4,
            )
        } else {
            (
                min_num as fn(Vec4, Vec4) -> Vec4,
                max_num as fn(Vec4, Vec4) -> Vec4,
            )
        };
        let mut near = Vec4::ZERO;
        let mut far = Vec4::splat(limit);
        for axis in 0..3 {
            let (origin, inv) = (ray.o[axis], ray.inv_d[axis]);
            let t0 = (self.min[axis] - origin) * inv;
            let t1 = (self.max[axis] - origin) * inv;
            near = max(near, min(t0, t1));
            far = min(far, max(t0, t1));
        }
        let enters = near.cmple(far * 1.000_000_4).bitmask() & self.used;
        (enters, near)
    }
}

/// A ray as the four-lane slab tests read it: its origin and inverse direction splatted once
/// per query instead of once per node. When every component of the inverse direction is finite
/// no slab end can be NaN (NaN needs 0 * inf, and a box's bound minus the origin is finite), so
/// the plain lane `min`/`max` give exactly what the NaN-ignoring ones give, with no selects:
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

/// `f32::min` lane by lane: a NaN operand yields the other one. `Vec4::min` already returns
/// `b` where `a` is NaN (the vector `min` instruction returns its second operand when either is
/// NaN, and glam's scalar fallback is `f32::min`), so only a NaN `b` needs the select; one
/// select instead of two is a measured part of the BDPT and path tracer speed-up
/// (book: "Measuring a renderer", "Where the time goes").
#[inline]
fn min_num(a: Vec4, b: Vec4) -> Vec4 {
    Vec4::select(b.is_nan_mask(), a, a.min(b))
}

/// `f32::max` lane by lane, NaN operands ignored as by [`min_num`].
#[inline]
fn max_num(a: Vec4, b: Vec4) -> Vec4 {
    Vec4::select(b.is_nan_mask(), a, a.max(b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `f32::min` / `f32::max` lane by lane, written out: the rule the one-select forms keep.
    fn reference(a: Vec4, b: Vec4, max: bool) -> Vec4 {
        let f = |x: f32, y: f32| if max { x.max(y) } else { x.min(y) };
        Vec4::new(f(a.x, b.x), f(a.y, b.y), f(a.z, b.z), f(a.w, b.w))
    }

    /// The slab test's NaN-aware min/max against `f32::min`/`max`, on the slab ends a ray meets
    /// where the NaN rule matters: flat boxes, origins on their planes, direction components of
    /// +0 and -0 (inverse +-inf), so that 0 * inf is either end of a slab, or both.
    #[test]
    fn lane_min_and_max_ignore_nan_operands_as_f32_min_and_max_do() {
        let coords = [-1.0f32, 0.0, 1.0];
        let dirs = [-1.0f32, -0.0, 0.0, 0.5];
        let (mut checked, mut nan) = (0, 0);
        for (lo, hi, o, d) in slab_cases(&coords, &dirs) {
            let inv = 1.0 / d;
            let t0 = Vec4::new((lo - o) * inv, 0.5, f32::NAN, 1.0);
            let t1 = Vec4::new((hi - o) * inv, f32::NAN, 2.0, f32::NAN);
            for (a, b) in [(t0, t1), (t1, t0)] {
                for (got, max) in [(min_num(a, b), false), (max_num(a, b), true)] {
                    let want = reference(a, b, max);
                    for k in 0..WIDTH {
                        let same = got[k].to_bits() == want[k].to_bits()
                            || (got[k].is_nan() && want[k].is_nan());
                        assert!(same, "lane {k} of {a} and {b}: {} not {}", got[k], want[k]);
                        nan += usize::from(a[k].is_nan() || b[k].is_nan());
                        checked += 1;
                    }
                }
            }
        }
        assert!(
            checked > 1000 && nan > 300,
            "{checked} lanes, {nan} with a NaN"
        );
    }

    /// The select-free slab test that rays with a finite inverse direction take gives the
    /// NaN-ignoring test's mask and entry distances bit for bit, on boxes whose planes hold the
    /// origin (a slab end of exactly 0) and on direction components so small that the inverse
    /// overflows to infinity in the product; a zero component takes the NaN-ignoring test.
    #[test]
    fn the_finite_ray_slab_test_is_the_nan_ignoring_one() {
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
