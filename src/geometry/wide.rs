//! The traversal layout of the BVH: the binary tree of the SAH build collapsed into nodes of up
//! to four children, whose boxes are stored axis by axis ("structure of arrays") so that one
//! node's four slab tests run as four-lane vector operations. A binary tree of depth d becomes a
//! tree of about d / 2 levels; a ray loads half as many nodes and tests their children together.
//!
//! The box test is the binary tree's, lane by lane, with the same arithmetic and the same
//! NaN-ignoring `min`/`max` (a ray parallel to a slab whose plane holds its origin gives 0 * inf:
//! that axis does not constrain the interval), so a child is entered exactly when the binary
//! traversal would test it, and closest hits stay bit for bit the same.
//! Book: "Scenes and geometry".

use glam::{Vec3, Vec4};

use super::Aabb;

/// Children per node.
pub const WIDTH: usize = 4;

/// A child: an interior node of the four-wide tree or a leaf, which is named by its node in
/// the binary tree (that node holds its run of primitive indices). One `u32`, the low bit
/// telling which, so that traversal stacks stay small (a stack is set up for every ray).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slot(pub u32);

/// What a [`Slot`] holds.
pub enum Child {
    /// A node of the four-wide tree.
    Node(usize),
    /// The binary tree's leaf node.
    Leaf(usize),
}

impl Slot {
    fn node(index: u32) -> Self {
        Slot(index << 1)
    }

    fn leaf(binary_node: usize) -> Self {
        Slot(((binary_node as u32) << 1) | 1)
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
    /// The slab test of the four children: a bit mask of the children the ray enters before
    /// `limit`, and their entry distances. Lane for lane the arithmetic of [`Aabb::intersect`].
    #[inline]
    pub fn intersect(&self, o: Vec3, inv_d: Vec3, limit: f32) -> (u32, Vec4) {
        let mut near = Vec4::ZERO;
        let mut far = Vec4::splat(limit);
        for axis in 0..3 {
            let (origin, inv) = (Vec4::splat(o[axis]), Vec4::splat(inv_d[axis]));
            let t0 = (self.min[axis] - origin) * inv;
            let t1 = (self.max[axis] - origin) * inv;
            near = max_num(near, min_num(t0, t1));
            far = min_num(far, max_num(t0, t1));
        }
        let enters = near.cmple(far * 1.000_000_4).bitmask() & self.used;
        (enters, near)
    }
}

/// `f32::min` lane by lane: a NaN operand yields the other one (vector `min` instructions
/// return their second operand instead, whichever is NaN).
#[inline]
fn min_num(a: Vec4, b: Vec4) -> Vec4 {
    let m = Vec4::select(a.is_nan_mask(), b, a.min(b));
    Vec4::select(b.is_nan_mask(), a, m)
}

/// `f32::max` lane by lane, NaN operands ignored as by [`min_num`].
#[inline]
fn max_num(a: Vec4, b: Vec4) -> Vec4 {
    let m = Vec4::select(a.is_nan_mask(), b, a.max(b));
    Vec4::select(b.is_nan_mask(), a, m)
}
