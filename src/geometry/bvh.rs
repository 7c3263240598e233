//! A bounding volume hierarchy built with the binned surface area heuristic (Wald 2007),
//! flattened depth-first so the left child follows its parent.
//!
//! Closest-hit queries break ties in favour of opaque primitives: where a null (index-matched)
//! medium boundary lies in the same plane as a wall, the wall is what the ray hits. Without that
//! rule a ray can cross the null face, be lifted off it and pass the wall: the light leak the
//! coplanar tests in `tests/geometry.rs` guard against.
//! Book: "Scenes and geometry".

use glam::Vec3;

use super::wide::{collapse, Binary, Child, Node4, Slot, WIDTH};
use super::{shape::Hit, Aabb, Primitive, Ray};

const BINS: usize = 12;
const MAX_LEAF: usize = 4;
/// Deepest level the build creates: below it everything left becomes one leaf. Traversal keeps
/// its to-do list in a fixed stack of this size, which therefore can never overflow (before
/// this limit, a push onto a full stack was silently dropped, losing a subtree).
pub const MAX_DEPTH: usize = 64;
/// SAH cost of one traversal step relative to one primitive test.
const TRAVERSAL_COST: f32 = 1.0;

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first index into `indices`; interior: index of the right child.
    offset: u32,
    /// Leaf: number of primitives (> 0); interior: 0.
    count: u32,
}

/// Entries of the traversal stack: a visit pops one entry and pushes at most `WIDTH`, once per
/// level of the four-wide tree, which is no deeper than the binary one.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

/// Levels of a four-wide tree that a query walks with the small stack [`SMALL_STACK`]: a stack
/// is set up (zeroed) for every ray, and 1.5 kB of it showed in the profile of small scenes.
const SHALLOW: usize = 8;
const SMALL_STACK: usize = (WIDTH - 1) * SHALLOW + 1;

/// The hierarchy over a slice of primitives (the primitives are not owned): the binary tree
/// of the build, and the four-wide tree traversal walks (`geometry::wide`).
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    indices: Vec<u32>,
    wide: Vec<Node4>,
    /// Levels of the four-wide tree (which stack size its queries need).
    wide_depth: usize,
}

impl Binary for Bvh {
    fn bounds(&self, node: usize) -> Aabb {
        self.nodes[node].bounds
    }

    fn children(&self, node: usize) -> Option<(usize, usize)> {
        let n = &self.nodes[node];
        (n.count == 0).then_some((node + 1, n.offset as usize))
    }
}

struct BuildItem {
    bounds: Aabb,
    centroid: Vec3,
    index: u32,
}

/// Relative distance within which two hits count as coplanar for the tie-break rule.
pub const TIE_EPSILON: f32 = 1e-5;

impl Bvh {
    /// Builds the hierarchy (O(n log n)).
    pub fn build(prims: &[Primitive]) -> Self {
        Self::build_over(prims, |_| true)
    }

    /// Builds the hierarchy over the primitives `keep` accepts; queries never see the others
    /// (indices still refer to the whole slice).
    pub fn build_over(prims: &[Primitive], keep: impl Fn(usize) -> bool) -> Self {
        let mut items: Vec<BuildItem> = prims
            .iter()
            .enumerate()
            .filter(|&(i, _)| keep(i))
            .map(|(i, p)| {
                let b = p.bounds();
                BuildItem {
                    bounds: b,
                    centroid: b.centroid(),
                    index: i as u32,
                }
            })
            .collect();
        let mut bvh = Bvh {
            nodes: Vec::with_capacity(2 * prims.len().max(1)),
            indices: Vec::with_capacity(prims.len()),
            wide: Vec::new(),
            wide_depth: 0,
        };
        if !items.is_empty() {
            bvh.build_recursive(&mut items, 1);
            bvh.wide = collapse(&bvh, 0);
            bvh.wide_depth = wide_depth(&bvh.wide, 0);
        }
        bvh
    }

    /// Number of nodes of the binary tree (for statistics).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The primitive indices of leaf `leaf` of the binary tree.
    #[inline]
    fn leaf_indices(&self, leaf: usize) -> &[u32] {
        let n = &self.nodes[leaf];
        &self.indices[n.offset as usize..(n.offset + n.count) as usize]
    }

    /// Number of nodes of the four-wide tree traversal walks.
    pub fn wide_node_count(&self) -> usize {
        self.wide.len()
    }

    /// Depth of the deepest leaf (the root alone has depth 1).
    pub fn depth(&self) -> usize {
        fn walk(nodes: &[Node], i: usize) -> usize {
            let n = &nodes[i];
            if n.count > 0 {
                1
            } else {
                1 + walk(nodes, i + 1).max(walk(nodes, n.offset as usize))
            }
        }
        if self.nodes.is_empty() {
            0
        } else {
            walk(&self.nodes, 0)
        }
    }

    /// Bounds of everything.
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map(|n| n.bounds).unwrap_or(Aabb::EMPTY)
    }

    fn build_recursive(&mut self, items: &mut [BuildItem], depth: usize) -> usize {
        let bounds = items.iter().fold(Aabb::EMPTY, |b, it| b.union(it.bounds));
        let node_index = self.nodes.len();
        self.nodes.push(Node {
            bounds,
            offset: 0,
            count: 0,
        });
        let make_leaf = |bvh: &mut Bvh, items: &mut [BuildItem]| {
            let first = bvh.indices.len() as u32;
            bvh.indices.extend(items.iter().map(|it| it.index));
            bvh.nodes[node_index].offset = first;
            bvh.nodes[node_index].count = items.len() as u32;
            node_index
        };
        if items.len() <= MAX_LEAF || depth >= MAX_DEPTH {
            return make_leaf(self, items);
        }
        let cb = items.iter().fold(Aabb::EMPTY, |b, it| b.grow(it.centroid));
        let extent = cb.extent();
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        if extent[axis] <= 0.0 {
            // all centroids coincide: split in the middle of the list
            let mid = items.len() / 2;
            return self.split(node_index, items, mid, depth);
        }
        // ANCHOR: sah
        // binned SAH along the widest centroid axis
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_count = [0usize; BINS];
        let scale = BINS as f32 / extent[axis];
        let bin_of = |c: Vec3| (((c[axis] - cb.min[axis]) * scale) as usize).min(BINS - 1);
        for it in items.iter() {
            let b = bin_of(it.centroid);
            bin_bounds[b] = bin_bounds[b].union(it.bounds);
            bin_count[b] += 1;
        }
        let mut best = (f32::INFINITY, 0usize);
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc_b, mut acc_n) = (Aabb::EMPTY, 0usize);
        for i in (1..BINS).rev() {
            acc_b = acc_b.union(bin_bounds[i]);
            acc_n += bin_count[i];
            right_area[i] = acc_b.surface_area();
            right_count[i] = acc_n;
        }
        let (mut acc_b, mut acc_n) = (Aabb::EMPTY, 0usize);
        for i in 1..BINS {
            acc_b = acc_b.union(bin_bounds[i - 1]);
            acc_n += bin_count[i - 1];
            let cost = acc_b.surface_area() * acc_n as f32 + right_area[i] * right_count[i] as f32;
            if acc_n > 0 && right_count[i] > 0 && cost < best.0 {
                best = (cost, i);
            }
        }
        // ANCHOR_END: sah
        let leaf_cost = items.len() as f32;
        let split_cost = TRAVERSAL_COST + best.0 / bounds.surface_area().max(f32::MIN_POSITIVE);
        if best.0.is_infinite() || (split_cost >= leaf_cost && items.len() <= 4 * MAX_LEAF) {
            if best.0.is_infinite() {
                let mid = items.len() / 2;
                items.sort_by(|a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
                return self.split(node_index, items, mid, depth);
            }
            return make_leaf(self, items);
        }
        let mut mid = 0;
        for i in 0..items.len() {
            if bin_of(items[i].centroid) < best.1 {
                items.swap(i, mid);
                mid += 1;
            }
        }
        self.split(node_index, items, mid, depth)
    }

    fn split(
        &mut self,
        node_index: usize,
        items: &mut [BuildItem],
        mid: usize,
        depth: usize,
    ) -> usize {
        let (left, right) = items.split_at_mut(mid);
        self.build_recursive(left, depth + 1);
        let r = self.build_recursive(right, depth + 1);
        self.nodes[node_index].offset = r as u32;
        self.nodes[node_index].count = 0;
        node_index
    }

    /// The closest hit with t in (0, t_max). `opaque[i]` tells whether primitive `i` wins ties:
    /// among hits within [`TIE_EPSILON`] (relative) of each other an opaque one is returned.
    pub fn intersect(
        &self,
        prims: &[Primitive],
        opaque: &[bool],
        ray: &Ray,
        t_max: f32,
    ) -> Option<Hit> {
        self.intersect_range(prims, opaque, ray, 0.0, t_max)
    }

    /// [`Bvh::intersect`] restricted to t in (t_min, t_max).
    ///
    /// Traversal tests a node's four children together, stacks those the ray enters with
    /// their entry distances, the nearest on top, and checks each distance again when it is
    /// popped: a subtree the best hit so far has moved out of reach is dropped without touching
    /// its node.
    #[inline]
    pub fn intersect_range(
        &self,
        prims: &[Primitive],
        opaque: &[bool],
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        if self.wide_depth <= SHALLOW {
            self.intersect_with::<SMALL_STACK>(prims, opaque, ray, t_min, t_max)
        } else {
            self.intersect_with::<STACK>(prims, opaque, ray, t_min, t_max)
        }
    }

    /// [`Bvh::intersect_range`] with a stack of `N` entries (enough for the tree's depth).
    fn intersect_with<const N: usize>(
        &self,
        prims: &[Primitive],
        opaque: &[bool],
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        let inv_d = ray.d.recip();
        // hits this far past the best one still compete in the tie-break
        let reach = |t_best: f32| (t_best * (1.0 + TIE_EPSILON) + TIE_EPSILON).min(t_max);
        if self.nodes.is_empty() || self.nodes[0].bounds.intersect(ray, inv_d, t_max).is_none() {
            return None;
        }
        let mut best: Option<Hit> = None;
        let mut stack = [0u64; N];
        let mut sp = 0usize;
        let mut child = Child::Node(0);
        loop {
            match child {
                Child::Leaf(leaf) => {
                    for &pi in self.leaf_indices(leaf) {
                        let limit = reach(best.map_or(t_max, |b| b.t));
                        let prim = &prims[pi as usize];
                        if let Some((t, p, ng)) = prim.intersect_range(ray, t_min, limit) {
                            let candidate = Hit { t, p, ng, prim: pi };
                            if best.is_none_or(|b| closer(&candidate, &b, opaque)) {
                                best = Some(candidate);
                            }
                        }
                    }
                }
                Child::Node(i) => {
                    let limit = reach(best.map_or(t_max, |b| b.t));
                    sp = push_nearest_last(&mut stack, sp, &self.wide[i], ray, inv_d, limit);
                }
            }
            // the next stacked subtree the ray still enters before the best hit's reach (with
            // the slack of the box test)
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                let (next, t_near) = unpack(stack[sp]);
                if t_near <= reach(best.map_or(t_max, |b| b.t)) * 1.000_000_4 {
                    child = next.child();
                    break;
                }
            }
        }
    }

    /// Any hit with t in (0, t_max) among primitives for which `blocks` is true, the nearer
    /// children entered first as in [`Bvh::intersect_range`].
    #[inline]
    pub fn occluded(&self, prims: &[Primitive], blocks: &[bool], ray: &Ray, t_max: f32) -> bool {
        if self.wide_depth <= SHALLOW {
            self.occluded_with::<SMALL_STACK>(prims, blocks, ray, t_max)
        } else {
            self.occluded_with::<STACK>(prims, blocks, ray, t_max)
        }
    }

    /// [`Bvh::occluded`] with a stack of `N` entries (enough for the tree's depth).
    fn occluded_with<const N: usize>(
        &self,
        prims: &[Primitive],
        blocks: &[bool],
        ray: &Ray,
        t_max: f32,
    ) -> bool {
        let inv_d = ray.d.recip();
        if self.nodes.is_empty() || self.nodes[0].bounds.intersect(ray, inv_d, t_max).is_none() {
            return false;
        }
        let mut stack = [0u64; N];
        let mut sp = 0usize;
        let mut child = Child::Node(0);
        loop {
            match child {
                Child::Leaf(leaf) => {
                    for &pi in self.leaf_indices(leaf) {
                        if blocks[pi as usize] && prims[pi as usize].intersect(ray, t_max).is_some()
                        {
                            return true;
                        }
                    }
                }
                Child::Node(i) => {
                    sp = push_nearest_last(&mut stack, sp, &self.wide[i], ray, inv_d, t_max);
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            child = unpack(stack[sp]).0.child();
        }
    }
}

/// Pushes the children of `node` the ray enters before `limit` onto `stack` above `sp`, the
/// farthest first so that the nearest is popped next; returns the new
/// stack pointer. At most `WIDTH - 1` entries more than were popped to get here: cannot
/// overflow a stack of [`STACK`] entries, nor one of [`SMALL_STACK`] in a tree of at most
/// [`SHALLOW`] levels.
#[inline]
fn push_nearest_last<const N: usize>(
    stack: &mut [u64; N],
    mut sp: usize,
    node: &Node4,
    ray: &Ray,
    inv_d: Vec3,
    limit: f32,
) -> usize {
    let (enters, near) = node.intersect(ray.o, inv_d, limit);
    let mut entered = [(0.0f32, Slot(0)); WIDTH];
    let mut n = 0;
    for k in 0..WIDTH {
        if enters & (1 << k) != 0 {
            let t = near[k];
            // insertion by decreasing distance; of equal ones the later child is popped first
            let mut j = n;
            while j > 0 && entered[j - 1].0 < t {
                entered[j] = entered[j - 1];
                j -= 1;
            }
            entered[j] = (t, node.slots[k]);
            n += 1;
        }
    }
    for &(t, slot) in &entered[..n] {
        stack[sp] = u64::from(slot.0) | (u64::from(t.to_bits()) << 32);
        sp += 1;
    }
    sp
}

/// Levels of the four-wide tree under node `i` (a node whose children are all leaves: 1).
fn wide_depth(wide: &[Node4], i: usize) -> usize {
    let below = wide[i]
        .slots
        .iter()
        .zip(0..WIDTH)
        .filter(|&(_, k)| wide[i].has(k))
        .filter_map(|(slot, _)| match slot.child() {
            Child::Node(j) => Some(wide_depth(wide, j)),
            Child::Leaf(_) => None,
        })
        .max()
        .unwrap_or(0);
    1 + below
}

/// A stack entry: the child and its entry distance, packed in one word so that the stack a
/// query sets up is small.
#[inline]
fn unpack(entry: u64) -> (Slot, f32) {
    (Slot(entry as u32), f32::from_bits((entry >> 32) as u32))
}

// ANCHOR: tie_break
/// Whether hit `a` is the one to keep over `b`: the nearer, except that within
/// [`TIE_EPSILON`] (relative) an opaque primitive wins over a null one; among equals the lower
/// primitive index, so that the result does not depend on the order the hits were found in.
fn closer(a: &Hit, b: &Hit, opaque: &[bool]) -> bool {
    let (oa, ob) = (opaque[a.prim as usize], opaque[b.prim as usize]);
    let tie = (a.t - b.t).abs() <= TIE_EPSILON * (1.0 + b.t);
    if tie && oa != ob {
        return oa;
    }
    a.t < b.t || (a.t == b.t && a.prim < b.prim)
}
// ANCHOR_END: tie_break
